"""``vtts voices [LANGUAGE]``: every installed voice of every speech engine."""

from __future__ import annotations

import argparse
import sys

from vtts.messages import echo
from vtts.speech.engine import ENGINES


def add_parser(sub) -> None:
    vo = sub.add_parser(
        "voices", help="list the installed voices of every speech engine (espeak-ng, festival, …)"
    )
    vo.add_argument("language", nargs="?", help="only voices of this language (e.g. en, en-us)")
    vo.add_argument("--engine", choices=tuple(ENGINES), help="only this engine's voices")
    vo.set_defaults(func=cmd_voices)


def cmd_voices(args: argparse.Namespace) -> int:
    """List the voices (:func:`vtts.speech.engine.installed_voices`): engine, name (what
    ``--voice`` takes), language, sample rate, licence and a description."""
    from vtts.speech.engine import installed_voices

    engines = [args.engine] if args.engine else list(ENGINES)
    found, missing = installed_voices(engines)
    if args.language:
        found = [v for v in found if v.speaks(args.language)]
    for name, why in missing.items():
        echo(f"note: {name}: {why}", file=sys.stderr)
    if not found:
        what = f" for language '{args.language}'" if args.language else ""
        echo(
            f"error: no voice{what} in {', '.join(engines)} (vtts voices lists them all)",
            file=sys.stderr,
        )
        return 1
    rows = [
        (v.engine, v.name, v.language, f"{v.rate} Hz" if v.rate else "-", v.licence, v.description)
        for v in found
    ]
    head = ("engine", "voice", "language", "rate", "licence", "")
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(5)]
    for r in [head, *rows]:
        line = "  ".join(c.ljust(w) for c, w in zip(r[:5], widths, strict=True))
        echo(f"{line}  {r[5]}".rstrip())
    return 0
