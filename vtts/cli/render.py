"""``vtts render``: one pose of one or more models as a PNG."""

from __future__ import annotations

import argparse

from vtts.cli.options import add_models, add_pose, add_view, pose_options, view_options
from vtts.messages import echo


def add_parser(sub) -> None:
    r = sub.add_parser("render", help="render one pose to a PNG")
    add_models(r)
    add_pose(r)
    add_view(r)
    r.add_argument("-o", "--output", required=True, help="output .png")
    r.set_defaults(func=cmd_render)


def cmd_render(args: argparse.Namespace) -> int:
    from vtts.api.render import RenderOptions, render

    options = RenderOptions(
        model=args.model, output=args.output, **pose_options(args), **view_options(args)
    )
    still = render(options)
    echo(f"wrote {args.output} ({still.frame.shape[1]}x{still.frame.shape[0]})")
    return 0
