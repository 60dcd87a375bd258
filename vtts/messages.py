"""How the command-line tools (``vtts``, ``adi``) show the library's errors and warnings: one
line each, ``FILE:LINE:COL: error: MESSAGE`` or ``… warning: …``, never a traceback."""

from __future__ import annotations

import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, NoReturn, TextIO

if TYPE_CHECKING:
    import argparse

from vtts.errors import VttsError, VttsWarning


def print_error(e: VttsError, default_file: str | None = None) -> None:
    """Print ``e`` as ``FILE:LINE:COL: error: MESSAGE`` (and its context lines) on stderr;
    ``default_file`` names the file when the error does not."""
    if default_file and not e.file:
        e.file = default_file
    loc = e.location()
    head = f"{loc}: error: {e.message}" if loc else f"error: {e.message}"
    print(printable(head), file=sys.stderr)
    if e.context:
        print("\n".join(printable(line) for line in e.context.split("\n")), file=sys.stderr)


def echo(*values: object, sep: str = " ", file: TextIO | None = None) -> None:
    """``print`` for the command line's messages: what they quote of the user's input (file
    names, option values, a file's own text) has its control characters escaped line by line
    (:func:`printable`), so that no message can drive the terminal."""
    text = sep.join(str(v) for v in values)
    print("\n".join(printable(line) for line in text.split("\n")), file=file or sys.stdout)


def argument_parser(**kwargs: Any) -> argparse.ArgumentParser:
    """The parser of ``vtts`` and ``adi`` (``argparse.ArgumentParser(**kwargs)``; their
    subcommands' parsers are of the same class), with two differences from argparse's:

    - its errors quote the arguments (``unrecognized arguments: …``) with their control
      characters escaped, as every other message does;
    - an option given ``--`` as its value (``--size=--``) takes that value. Python 3.11's argparse
      strips the ``--`` and hands the command an empty list without calling the option's type,
      so the command met a list where it checks a string (a traceback, or a value silently
      ignored); now the type and the choices judge ``'--'`` as any other value.

    argparse is imported here, so that the library (``vtts.say`` …) runs without it."""
    import argparse

    class CommandParser(argparse.ArgumentParser):
        def error(self, message: str) -> NoReturn:
            super().error(printable(message))

        # argparse has no public hook for an option's raw strings: _get_values is where the
        # ``--`` is dropped
        def _get_values(self, action: argparse.Action, arg_strings: list[str]) -> object:
            if action.option_strings and arg_strings == ["--"] and action.nargs in (None, "?"):
                value = self._get_value(action, "--")
                self._check_value(action, value)
                return value
            return super()._get_values(action, arg_strings)

    return CommandParser(**kwargs)


def printable(text: str) -> str:
    """``text`` with control characters escaped (``\\x1b``), so that an input's bytes quoted
    in a message cannot drive the terminal."""
    return "".join(
        c if c.isprintable() or c == "\t" else c.encode("unicode_escape").decode("ascii")
        for c in str(text)
    )


@contextmanager
def reported_warnings(file: str | None = None) -> Iterator[None]:
    """Print library warnings as ``FILE:LINE:COL: warning: MESSAGE`` lines; ``file`` names the
    input a warning is about where the library did not (a photo the fit was given as pixels)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield
        finally:
            for w in caught:
                msg = w.message
                if isinstance(msg, VttsWarning):
                    where = msg.file if msg.file is not None else file
                    parts = [str(p) for p in (where, msg.line, msg.column) if p is not None]
                    loc = ":".join(parts)
                    text = f"{loc + ': ' if loc else ''}warning: {msg.message}"
                    print(printable(text), file=sys.stderr)
                else:
                    print(printable(f"warning: {msg}"), file=sys.stderr)
