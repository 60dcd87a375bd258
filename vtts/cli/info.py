"""``vtts info FILE``: a scene graph and what a model can do, or what a ``.fbs`` holds."""

from __future__ import annotations

import argparse

from vtts.cli.options import add_lenient, add_url_root
from vtts.errors import VttsError
from vtts.messages import echo, print_error, reported_warnings


def add_parser(sub) -> None:
    i = sub.add_parser(
        "info", help="describe a scene graph and what a model can do, or a .fbs bitstream"
    )
    i.add_argument("file", metavar="FILE")
    add_lenient(i)
    add_url_root(i)
    i.set_defaults(func=cmd_info)


def cmd_info(args: argparse.Namespace) -> int:
    """Print :func:`vtts.api.info.info` of the file."""
    from vtts.api.info import info

    try:
        with reported_warnings():
            found = info(args.file, lenient=args.lenient)
    except VttsError as e:
        print_error(e, args.file)
        return 1
    echo(f"{args.file}:" if found.title is None else f"{found.path}: {found.title}")
    for line in found.lines:
        echo("  " + line)
    if found.model_name is not None:
        echo(f"model {found.model_name}:")
        for line in found.model_lines:
            echo("  " + line)
    return 0
