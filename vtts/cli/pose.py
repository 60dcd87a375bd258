"""``vtts pose``: a model posed by FAPs, visemes and expressions, as plain VRML97."""

from __future__ import annotations

import argparse

from vtts.cli.options import add_pose, add_url_root, pose_options
from vtts.messages import echo


def add_parser(sub) -> None:
    po = sub.add_parser("pose", help="write a model posed by FAPs, visemes and expressions")
    po.add_argument("--model", required=True, help="bundled model name or .wrl path")
    add_url_root(po)
    add_pose(po)
    po.add_argument("-o", "--output", required=True, help="output .wrl")
    po.set_defaults(func=cmd_pose)


def cmd_pose(args: argparse.Namespace) -> int:
    from vtts.api.pose import PoseOptions, pose

    pose(PoseOptions(model=args.model, output=args.output, **pose_options(args)))
    echo(f"wrote {args.output}")
    return 0
