"""The option groups several commands share (the heads, a pose, the view, the web player,
another engine's curves, ``--detail``), each added once, and the argparse types whose errors
are usage errors (exit status 2)."""

from __future__ import annotations

import argparse
import math

LENIENT_HELP = (
    "load VRML that other browsers accept (unknown nodes and fields, misplaced nodes, "
    "X3D statements, urls out of the folder), each with a warning"
)


def seed_type(text: str) -> int:
    """A ``--seed``: a whole number 0 to 2**63 - 1 (numpy's generators take no negative seed)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 0 <= value < 2**63:
        raise argparse.ArgumentTypeError(f"{value} must be within 0 to 2**63 - 1")
    return value


def detail_type(text: str) -> float:
    """``--detail``'s value: a distance in pixels from 0 to 100."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0 <= value <= 100:  # NaN too
        raise argparse.ArgumentTypeError(f"a distance in pixels from 0 to 100, got {text!r}")
    return value


def positive_type(text: str) -> float:
    """A positive finite number (``encode --rate``, ``--quantizer``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def add_lenient(p: argparse.ArgumentParser) -> None:
    p.add_argument("--lenient", action="store_true", help=LENIENT_HELP)


def add_url_root(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--url-root",
        action="append",
        metavar="DIR",
        help="a folder (besides the model's own) whose files the model's urls may name, such as "
        "a shared textures/ folder (repeat for several; adds to $VTTS_URL_ROOT)",
    )


def add_models(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--model",
        action="append",
        required=True,
        help="bundled model name or .wrl path (repeat for several heads)",
    )
    add_url_root(p)


def add_pose(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--fap",
        action="append",
        metavar="N=V,...",
        help="FAP values in FAP units, by number or name (19=512,open_jaw=300)",
    )
    p.add_argument(
        "--viseme",
        action="append",
        metavar="V[=W]",
        help="viseme number or phoneme with an optional weight 0-1 (7 or 7=0.5)",
    )
    p.add_argument(
        "--expression",
        action="append",
        metavar="NAME[=W]",
        help="expression with an optional weight 0-1 (joy=0.8)",
    )


def add_web(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--web",
        metavar="DIR",
        help="also (or only) write a web player into this folder: index.html, the animation as "
        ".glb, the audio and three.js; serve it with python -m http.server -d DIR",
    )


def add_curves(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--curves-out",
        metavar="FILE",
        help="also write the animation as another engine's curves (JSON, see --curves)",
    )
    p.add_argument(
        "--curves",
        metavar="FORMAT",
        help="format of --curves-out: arkit (52 blendshape weights per frame, the default), "
        "oculus (15 viseme weights per frame), azure (viseme events), talkinghead",
    )


def add_view(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--size",
        help="WIDTHxHEIGHT in pixels (default 352x288; with --background photo the photo's size)",
    )
    p.add_argument(
        "--camera",
        metavar="FX,FY,X0,Y0",
        help="pinhole camera of Eisert-Girod Eq. 3 in pixels (default: frame the heads)",
    )
    p.add_argument(
        "--viewpoint",
        metavar="NAME",
        help="look through the Viewpoint DEFed as NAME in the (first) model's scene",
    )
    p.add_argument(
        "--background",
        metavar="COLOR",
        help="a color name (black, white, gray, green, blue, ...), #rrggbb or r,g,b in 0-1; "
        "or transparent: RGBA PNGs whose alpha is the heads' coverage; or photo: a fitted head "
        "drawn into the photo it was fitted to (a talking photo; --viewpoint photo)",
    )
    p.add_argument(
        "--layout",
        choices=("row", "room"),
        default="row",
        help="several heads side by side, or side by side in a simple room",
    )


def add_detail(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--detail",
        type=detail_type,
        metavar="PX",
        help="draw fewer triangles where the heads' surface moves by less than PX pixels of "
        "the video (default half a pixel, vtts.render.DETAIL_PX; 0: every triangle)",
    )


def view_options(args: argparse.Namespace) -> dict:
    """The :class:`vtts.api.options.View` fields of a command's arguments."""
    return {
        "size": args.size,
        "camera": args.camera,
        "viewpoint": args.viewpoint,
        "background": args.background,
        "layout": args.layout,
        "detail": getattr(args, "detail", None),
    }


def pose_options(args: argparse.Namespace) -> dict:
    """The :class:`vtts.api.options.PoseRequest` fields of a command's arguments."""
    return {"fap": args.fap, "viseme": args.viseme, "expression": args.expression}


def curves_options(args: argparse.Namespace) -> dict:
    """The :class:`vtts.api.options.Curves` fields of a command's arguments."""
    return {"curves_out": args.curves_out, "curves": args.curves}
