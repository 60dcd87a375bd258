"""The ``adi`` command (Animation Definition Interface): building and inspecting ADTs.

``adi build NEUTRAL.wrl DEFORMED... -o OUT`` compares deformed exports with the neutral model and
writes the tables (a ``.adt`` file, or with ``--embed`` the neutral scene with FaceDefTables);
``adi fit PHOTO -o OUT.wrl`` makes a personalized head from one photograph;
``adi import AVATAR.glb -o OUT.wrl`` makes one from an ARKit-blendshape glTF avatar;
``adi show FILE`` summarizes the tables of a ``.adt`` or a model ``.wrl``. Input errors are printed
as ``FILE:LINE:COL: error: MESSAGE`` with exit status 1, never a traceback. See ``docs/adi.md``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

from vtts import __version__
from vtts.errors import VttsError
from vtts.messages import argument_parser, echo, print_error, reported_warnings


def cmd_build(args: argparse.Namespace) -> int:
    """Build tables from the neutral model and its deformed exports and write them."""
    from adt_tools.build import build, summary
    from vtts.face import embed_tables, write_adt
    from vtts.vrml import write

    out = Path(args.output)
    suffix = out.suffix.lower()
    if args.embed and suffix != ".wrl":
        echo(
            f"{out}: error: --embed writes a .wrl (the neutral scene with FaceDefTables), "
            f"not a '{out.suffix}'",
            file=sys.stderr,
        )
        return 1
    if not args.embed and suffix != ".adt":
        hint = "; pass --embed to write the tables into a .wrl" if suffix == ".wrl" else ""
        echo(f"{out}: error: the output is a .adt file{hint}", file=sys.stderr)
        return 1
    if args.tolerance < 0:
        echo(f"error: --tolerance must not be negative, got {args.tolerance:g}", file=sys.stderr)
        return 1
    from vtts.atomic import check_outputs

    check_outputs([out], [args.neutral, *args.deformed])
    with reported_warnings():
        neutral, tables = build(
            args.neutral, args.deformed, tolerance=args.tolerance, node=args.node
        )
        if args.embed:
            write(
                embed_tables(neutral, tables),
                out,
                comment=f"animation tables built by adi {__version__}",
            )
            if out.with_suffix(".adt").is_file():
                echo(
                    f"{out}: warning: {out.with_suffix('.adt').name} lies beside it; a model's "
                    "tables must come from one place, so loading it will fail until one is "
                    "removed",
                    file=sys.stderr,
                )
        else:
            write_adt(tables, out)
    echo(f"wrote {out}: {summary(tables)}")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    """Summarize the tables of a ``.adt`` file or a model ``.wrl``."""
    from adt_tools.show import show

    with reported_warnings():
        lines = show(args.file)
    echo("\n".join(lines))
    return 0


def _wrl_output(output: str, beside: str) -> Path | None:
    """``-o`` of a command that writes a model: a ``.wrl`` file in an existing folder (its .adt
    and ``beside`` go next to it), or None after printing why not."""
    out = Path(output)
    if out.suffix.lower() != ".wrl":
        echo(f"{out}: error: the output is a .wrl file (its .adt and {beside} go beside it)",
              file=sys.stderr)  # fmt: skip
        return None
    if out.is_dir():
        echo(f"{out}: error: is a folder; name the .wrl to write", file=sys.stderr)
        return None
    if not out.parent.is_dir():
        echo(f"{out.parent}: error: no such folder for the output", file=sys.stderr)
        return None
    return out


def cmd_import(args: argparse.Namespace) -> int:
    """Import an ARKit-blendshape glTF avatar as a personalized model (.wrl + .adt + textures)."""
    import time

    from vtts.atomic import check_outputs
    from vtts.avatar.importer import import_avatar
    from vtts.face import load_model

    t0 = time.perf_counter()
    out = _wrl_output(args.output, "textures")
    if out is None:
        return 1
    check_outputs([out, out.with_suffix(".adt")], [args.avatar])
    with reported_warnings():
        avatar = import_avatar(args.avatar)
        # a .gltf's own buffers and images beside it must survive too (me-tex0.png)
        check_outputs(avatar.outputs(out), [args.avatar, *avatar.sources])
        files = avatar.write(out)
        model = load_model(out)  # what every vtts command will load: checked here
    kinds = {"fap": 0, "viseme": 0, "expression": 0}
    for m in model.miaps:
        kinds[m.kind] += 1
    fapu = "FAPUs measured" if model.fapu is not None else "no FAPUs (feature points not found)"
    echo(f"wrote {', '.join(str(p) for p in files)}: {len(avatar.found)} ARKit/Oculus targets "
          f"-> {kinds['fap']} FAPs, {kinds['viseme']} visemes, {kinds['expression']} "
          f"expressions; eyes: {', '.join(avatar.eyes) or 'none'}; {fapu}; "
          f"in {time.perf_counter() - t0:.1f} s")  # fmt: skip
    return 0


def _unwritable(folder: Path) -> str | None:
    """Why no file can be made in ``folder`` (None: one can, or the folder is yet to be made).
    Tried with a file removed at once: permissions alone do not tell (root, read-only mounts)."""
    import tempfile

    if not folder.is_dir():
        return None
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".adi-probe-"):
            pass
    except OSError as e:
        return e.strerror or str(e)
    return None


def cmd_fit(args: argparse.Namespace) -> int:
    """Fit a personalized head to a photograph and write it (with a report on request)."""
    import time

    from vtts.api.options import check_not_stdout
    from vtts.errors import FitError
    from vtts.face import load_model
    from vtts.fit import fit_photo, load_photo
    from vtts.fit.report import write_report

    t0 = time.perf_counter()
    out = _wrl_output(args.output, "texture")
    if out is None:
        return 1
    check_not_stdout(args)
    if args.report and Path(args.report).exists() and not Path(args.report).is_dir():
        echo(f"{args.report}: error: --report names a folder, and this is a file",
              file=sys.stderr)  # fmt: skip
        return 1
    from vtts.fit.shape import MAX_FOCAL_35MM, MIN_FOCAL_35MM

    if args.focal is not None and not MIN_FOCAL_35MM <= args.focal <= MAX_FOCAL_35MM:
        echo(f"error: --focal is a 35 mm-equivalent focal length of {MIN_FOCAL_35MM:g} to "
             f"{MAX_FOCAL_35MM:g} mm, got {args.focal:g}", file=sys.stderr)  # fmt: skip
        return 1
    # the outputs and the report's files must not replace the photo (me-face.png -o
    # me.wrl would, --report shots on shots/landmarks.png too), each other, links or anything
    # but plain files
    from vtts.atomic import check_outputs
    from vtts.fit.report import REPORT_FILES

    photo = Path(args.photo)
    outputs = [out, out.with_suffix(".adt"), out.with_name(f"{out.stem}-face.png"),
               out.with_name(f"{out.stem}-photo.png"),
               out.with_name(f"{out.stem}-glasses.png")]  # fmt: skip
    report = [Path(args.report) / name for name in REPORT_FILES] if args.report else []
    for target in (*outputs, *report):
        if target.exists() and photo.exists() and os.path.samefile(target, photo):
            option = "-o" if target in outputs else "--report"
            echo(f"{target}: error: adi fit would write this over its photo; choose another "
                 f"{option}", file=sys.stderr)  # fmt: skip
            return 1
    check_outputs([*outputs, *report], [photo])
    # now, not after a fit of seconds: and naming the user's file, not its temporary .part
    for folder in [out.parent, *([Path(args.report)] if args.report else [])]:
        problem = _unwritable(folder)
        if problem:
            echo(f"{out if folder == out.parent else folder}: error: cannot write in "
                 f"{folder}: {problem}", file=sys.stderr)  # fmt: skip
            return 1
    name = args.name or out.stem
    with reported_warnings():
        try:
            # the fit sees pixels: its warnings (glasses, several faces …) name the photo here
            with reported_warnings(file=str(args.photo)):
                image, exif_focal = load_photo(args.photo)
                head = fit_photo(image, personality=args.personality, face=args.face,
                                 focal_35mm=args.focal or exif_focal, name=name)  # fmt: skip
        except FitError as e:
            if not e.file and not str(e.message).startswith(str(args.photo)):
                e.file = str(args.photo)
            raise
        files = head.write(out)
    total = time.perf_counter() - t0
    shape = head.shape
    echo(f"wrote {', '.join(str(p) for p in files)}: {name} fitted to {len(shape.used)} "
          f"landmarks (median error {np.median(shape.residual):.2f} px), personality "
          f"{args.personality}, in {total:.1f} s")  # fmt: skip
    if args.report:
        model = load_model(out)
        figs = write_report(args.report, model, head, head.photo, files)
        psnr = figs["psnr_db"]
        echo(f"report in {args.report}: face PSNR {psnr['face']:.1f} dB (skin "
              f"{psnr['skin']:.1f} dB), landmark error "
              f"{figs['reprojection_percent_of_eye_distance']['median']:.1f} % of the eye "
              "distance (median)")  # fmt: skip
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argument_parser(
        prog="adi",
        description="Animation Definition Interface: build and inspect Animation Definition "
        "Tables (ADTs) of personalized face models.",
    )
    p.add_argument("--version", action="version", version=f"adi {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    b = sub.add_parser(
        "build",
        help="make tables from a neutral model and deformed exports of it",
        description="Compare each deformed export with the neutral model and write the tables. "
        "A deformed file names its MIAP and amplitude in a WorldInfo info string "
        "('miap 19 1024', 'miap viseme 3 1', 'miap joy 1') or in its file name "
        "(close_t_l_eyelid@1024.wrl, 19@-512.wrl, viseme3@1.wrl, joy@0.5.obj). Deformed files "
        "are .wrl, .obj, .ply, or .glb/.gltf (whose morph targets named after MIAPs each give a "
        "pose).",
    )
    b.add_argument("neutral", metavar="NEUTRAL.wrl", help="the neutral model")
    b.add_argument("deformed", nargs="+", metavar="DEFORMED", help="deformed exports")
    b.add_argument(
        "-o",
        "--output",
        required=True,
        metavar="OUT",
        help="the .adt to write (a .wrl with --embed)",
    )
    b.add_argument(
        "--embed",
        action="store_true",
        help="write the neutral scene with the tables as FaceDefTables nodes",
    )
    b.add_argument(
        "--tolerance",
        type=float,
        default=1e-6,
        metavar="T",
        help="vertices moving less than T (model units) are left out (default: %(default)g)",
    )
    b.add_argument(
        "--node",
        metavar="NAME",
        help="the IndexedFaceSet (DEF name) that OBJ/PLY/glTF meshes map onto "
        "(default: the only one with the same number of points)",
    )
    b.set_defaults(func=cmd_build)

    f = sub.add_parser(
        "fit",
        help="a personalized head from one photograph",
        description="Fit the generic head to the face in a photo: landmarks, pose, camera and "
        "shape, the photo as its texture, and the animation tables carried over. Writes "
        "OUT.wrl (with the photo's camera as DEF photo Viewpoint), OUT.adt, OUT-face.png, "
        "OUT-photo.png (the photo as fitted) and, where the photo shows glasses, "
        "OUT-glasses.png (their frame's texture); vtts render --model OUT.wrl --viewpoint photo "
        "--size WxH renders it over the photo, --background photo into it (a talking photo).",
    )
    f.add_argument("photo", metavar="PHOTO", help="a photo (PNG, JPEG, ...) showing a face")
    f.add_argument("-o", "--output", required=True, metavar="OUT.wrl", help="the model to write")
    f.add_argument("--name", help="the model's name (default: OUT's file name)")
    f.add_argument(
        "--personality",
        choices=("cybatt", "lotta"),
        default="cybatt",
        help="whose generic head, animation tables and temporal habits to start from "
        "(default: %(default)s)",
    )
    f.add_argument(
        "--face", type=int, metavar="N", help="fit face N of several (1 = the largest, the default)"
    )
    f.add_argument(
        "--focal",
        type=float,
        metavar="MM",
        help="the lens as a 35 mm-equivalent focal length (default: from EXIF, else 50)",
    )
    f.add_argument(
        "--report",
        metavar="DIR",
        help="write landmarks, overlay and turned views and the figures here",
    )
    f.set_defaults(func=cmd_fit)

    i = sub.add_parser(
        "import",
        help="a personalized model from an ARKit-blendshape glTF avatar",
        description="Turn a glTF avatar (.glb/.gltf) with ARKit blendshapes (and Oculus visemes) "
        "as morph targets into a personalized model: its meshes, textures and node tree become "
        "OUT.wrl, its targets the tables in OUT.adt (each FAP, viseme and expression through "
        "the recipe table, docs/avatars.md), eye meshes rotating Transforms, and the FAPUs are "
        "measured on the mesh. Textures are written beside as OUT-texN.png/.jpg.",
    )
    i.add_argument("avatar", metavar="AVATAR", help="the .glb or .gltf avatar")
    i.add_argument("-o", "--output", required=True, metavar="OUT.wrl", help="the model to write")
    i.set_defaults(func=cmd_import)

    s = sub.add_parser("show", help="summarize the tables of a .adt or a model .wrl")
    s.add_argument("file", metavar="FILE")
    s.set_defaults(func=cmd_show)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except VttsError as e:
        print_error(e)
        return 1
    except BrokenPipeError:  # `adi show … | head`: not an error worth a traceback
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except OSError as e:
        where = f"{e.filename}: " if e.filename else ""
        echo(f"{where}error: {e.strerror or e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        echo("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
