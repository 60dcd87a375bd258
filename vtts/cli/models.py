"""``vtts models``: the bundled models."""

from __future__ import annotations

import argparse

from vtts.messages import echo


def add_parser(sub) -> None:
    ms = sub.add_parser("models", help="list the bundled models")
    ms.set_defaults(func=cmd_models)


def cmd_models(args: argparse.Namespace) -> int:
    """List the bundled models (:func:`vtts.api.models.models`)."""
    from vtts.api.models import models

    found = models()
    if not found:
        echo("no bundled models")
        return 0
    for b in found:
        if b.error is not None:
            echo(f"{b.name:12s} broken: {b.error.message}")
            continue
        m = b.model
        echo(
            f"{b.name:12s} {len(m.tables.adts):3d} MIAPs {m.scene.triangle_count():7d} triangles  "
            f"{m.path}"
        )
    return 0
