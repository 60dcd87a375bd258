"""``python -m vtts.cli``: the ``vtts`` command."""

from vtts.cli import run

run()
