"""The ``vtts`` command: a thin layer that parses arguments, calls the library (:mod:`vtts.api`)
and prints what it returns.

One module per command (its sub-parser and its ``cmd_*`` function: :mod:`~vtts.cli.check`,
:mod:`~vtts.cli.info`, :mod:`~vtts.cli.pose`, :mod:`~vtts.cli.render`, :mod:`~vtts.cli.play`,
:mod:`~vtts.cli.say`, :mod:`~vtts.cli.voices`, :mod:`~vtts.cli.analyze`, :mod:`~vtts.cli.coding`
(``encode``, ``decode``), :mod:`~vtts.cli.models`, :mod:`~vtts.cli.batch`,
:mod:`~vtts.cli.serve`), the option groups they share once (:mod:`~vtts.cli.options`), and the
parser, :func:`main`, :func:`execute` and the console script's :func:`run` in one place
(``_main``).
"""

from vtts.cli._main import build_parser, execute, main, run

__all__ = ["build_parser", "execute", "main", "run"]
