"""``vtts check FILE...``: ``OK FILE (summary)`` or ``FILE:LINE:COL: error: MESSAGE`` for each."""

from __future__ import annotations

import argparse
import sys

from vtts.cli.options import add_lenient, add_url_root
from vtts.errors import VttsError
from vtts.messages import echo, print_error, reported_warnings


def add_parser(sub) -> None:
    c = sub.add_parser("check", help="validate .wrl, .adt, .fap and .fbs files")
    c.add_argument("files", nargs="+", metavar="FILE")
    add_lenient(c)
    add_url_root(c)
    c.set_defaults(func=cmd_check)


def cmd_check(args: argparse.Namespace) -> int:
    """Check files (:func:`vtts.api.check.check_file`), one line each; 1 when any is bad."""
    from vtts.api.check import CheckError, check_file

    failed = 0
    for name in args.files:
        try:
            with reported_warnings():
                summary = check_file(name, lenient=args.lenient)
        except CheckError as e:
            echo(f"{name}: error: {e.message}", file=sys.stderr)
            failed += 1
            continue
        except VttsError as e:
            print_error(e, name)
            failed += 1
            continue
        echo(f"OK {name} ({summary})")
    return 1 if failed else 0
