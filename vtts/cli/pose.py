"""``vtts pose`` and ``vtts render``: one pose of a model as VRML97, or of models as a PNG."""

from __future__ import annotations

import argparse

from vtts.cli.options import add_models, add_pose, add_url_root, add_view


def add_parser(sub) -> None:
    po = sub.add_parser("pose", help="write a model posed by FAPs, visemes and expressions")
    po.add_argument("--model", required=True, help="bundled model name or .wrl path")
    add_url_root(po)
    add_pose(po)
    po.add_argument("-o", "--output", required=True, help="output .wrl")
    po.set_defaults(func=cmd_pose)


def add_render_parser(sub) -> None:
    r = sub.add_parser("render", help="render one pose to a PNG")
    add_models(r)
    add_pose(r)
    add_view(r)
    r.add_argument("-o", "--output", required=True, help="output .png")
    r.set_defaults(func=cmd_render)


def pose_request(args: argparse.Namespace) -> dict:
    """The :class:`vtts.api.options.PoseRequest` fields of a command's arguments."""
    return {"fap": args.fap, "viseme": args.viseme, "expression": args.expression}


def cmd_pose(args: argparse.Namespace) -> int:
    from vtts.api.pose import PoseOptions, pose

    written = pose(PoseOptions(model=args.model, output=args.output, **pose_request(args)))
    print(f"wrote {written}")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from vtts.api.render import RenderOptions, render
    from vtts.cli.options import view_options

    options = RenderOptions(
        model=args.model, output=args.output, **pose_request(args), **view_options(args)
    )
    still = render(options)
    print(f"wrote {args.output} ({still.frame.shape[1]}x{still.frame.shape[0]})")
    return 0
