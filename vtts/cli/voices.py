"""``vtts voices [LANGUAGE]``: espeak-ng's voices."""

from __future__ import annotations

import argparse
import sys

from vtts.messages import echo


def add_parser(sub) -> None:
    vo = sub.add_parser("voices", help="list espeak-ng voices")
    vo.add_argument("language", nargs="?", help="only voices of this language (e.g. en)")
    vo.set_defaults(func=cmd_voices)


def cmd_voices(args: argparse.Namespace) -> int:
    """List espeak-ng's voices."""
    from vtts.speech.tts import voices

    found = voices(args.language)
    if not found:
        echo(
            f"error: espeak-ng has no voice for language '{args.language}' "
            "(vtts voices lists them all)",
            file=sys.stderr,
        )
        return 1
    for v in found:
        echo(f"{v.name:24s} {v.language:8s} {v.identifier}")
    return 0
