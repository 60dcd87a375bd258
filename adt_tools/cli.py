"""The ``adi`` command (Animation Definition Interface): building and inspecting ADTs.

``adi build NEUTRAL.wrl DEFORMED... -o OUT`` compares deformed exports with the neutral model and
writes the tables (a ``.adt`` file, or with ``--embed`` the neutral scene with FaceDefTables);
``adi show FILE`` summarizes the tables of a ``.adt`` or a model ``.wrl``. Input errors are printed
as ``FILE:LINE:COL: error: MESSAGE`` with exit status 1, never a traceback. See ``docs/adi.md``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from vtts import __version__
from vtts.cli import _print_error, _reported_warnings
from vtts.errors import VttsError


def cmd_build(args: argparse.Namespace) -> int:
    """Build tables from the neutral model and its deformed exports and write them."""
    from adt_tools.build import build, summary
    from vtts.face import embed_tables, write_adt
    from vtts.vrml import write

    out = Path(args.output)
    suffix = out.suffix.lower()
    if args.embed and suffix != ".wrl":
        print(f"{out}: error: --embed writes a .wrl (the neutral scene with FaceDefTables), "
              f"not a '{out.suffix}'", file=sys.stderr)
        return 1
    if not args.embed and suffix != ".adt":
        hint = "; pass --embed to write the tables into a .wrl" if suffix == ".wrl" else ""
        print(f"{out}: error: the output is a .adt file{hint}", file=sys.stderr)
        return 1
    if args.tolerance < 0:
        print(f"error: --tolerance must not be negative, got {args.tolerance:g}", file=sys.stderr)
        return 1
    with _reported_warnings():
        neutral, tables = build(
            args.neutral, args.deformed, tolerance=args.tolerance, node=args.node
        )
        if args.embed:
            write(embed_tables(neutral, tables), out,
                  comment=f"animation tables built by adi {__version__}")
            if out.with_suffix(".adt").is_file():
                print(f"{out}: warning: {out.with_suffix('.adt').name} lies beside it; a model's "
                      "tables must come from one place, so loading it will fail until one is "
                      "removed", file=sys.stderr)
        else:
            write_adt(tables, out)
    print(f"wrote {out}: {summary(tables)}")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    """Summarize the tables of a ``.adt`` file or a model ``.wrl``."""
    from adt_tools.show import show

    with _reported_warnings():
        lines = show(args.file)
    print("\n".join(lines))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
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
    b.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="the .adt to write (a .wrl with --embed)")
    b.add_argument("--embed", action="store_true",
                   help="write the neutral scene with the tables as FaceDefTables nodes")
    b.add_argument("--tolerance", type=float, default=1e-6, metavar="T",
                   help="vertices moving less than T (model units) are left out "
                   "(default: %(default)g)")
    b.add_argument("--node", metavar="NAME",
                   help="the IndexedFaceSet (DEF name) that OBJ/PLY/glTF meshes map onto "
                   "(default: the only one with the same number of points)")
    b.set_defaults(func=cmd_build)

    s = sub.add_parser("show", help="summarize the tables of a .adt or a model .wrl")
    s.add_argument("file", metavar="FILE")
    s.set_defaults(func=cmd_show)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except VttsError as e:
        _print_error(e)
        return 1
    except BrokenPipeError:  # `adi show … | head`: not an error worth a traceback
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except OSError as e:
        where = f"{e.filename}: " if e.filename else ""
        print(f"{where}error: {e.strerror or e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
