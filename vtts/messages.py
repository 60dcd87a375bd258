"""How the command-line tools (``vtts``, ``adi``) show the library's errors and warnings: one
line each, ``FILE:LINE:COL: error: MESSAGE`` or ``… warning: …``, never a traceback."""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

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


def printable(text: str) -> str:
    """``text`` with control characters escaped (``\\x1b``), so that an input's bytes quoted
    in a message cannot drive the terminal."""
    return "".join(
        c if c.isprintable() or c == "\t" else c.encode("unicode_escape").decode("ascii")
        for c in str(text)
    )


@contextmanager
def reported_warnings() -> Iterator[None]:
    """Print library warnings as ``FILE:LINE:COL: warning: MESSAGE`` lines."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield
        finally:
            for w in caught:
                msg = w.message
                if isinstance(msg, VttsWarning):
                    parts = [str(p) for p in (msg.file, msg.line, msg.column) if p is not None]
                    loc = ":".join(parts)
                    text = f"{loc + ': ' if loc else ''}warning: {msg.message}"
                    print(printable(text), file=sys.stderr)
                else:
                    print(printable(f"warning: {msg}"), file=sys.stderr)


class CommandParser(argparse.ArgumentParser):
    """The parser of ``vtts`` and ``adi`` (their subcommands' too): argparse's, except that an
    option given ``--`` as its value (``--size=--``) takes that value. Python 3.11's argparse
    strips the ``--`` and hands the command an empty list without calling the option's type, so
    the command met a list where it checks a string (a traceback, or a value silently ignored);
    now the type and the choices judge ``'--'`` as any other value."""

    def _get_values(self, action: argparse.Action, arg_strings: list[str]) -> object:
        if action.option_strings and arg_strings == ["--"] and action.nargs in (None, "?"):
            value = self._get_value(action, "--")
            self._check_value(action, value)
            return value
        return super()._get_values(action, arg_strings)
