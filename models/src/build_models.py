"""Rebuild the bundled heads: ``make models``.

usage: python models/src/build_models.py [--out DIR] [--work DIR] [NAME ...]

For each personality the modeler (``modeler.py``) writes the neutral scene and one deformed
export per MIAP phase into ``WORK/NAME/`` (``neutral.wrl``, ``close_t_l_eyelid@512.wrl``, …),
``texture.py`` paints ``NAME-face.png``, and the ADI — the real ``adi build`` command — turns the
exports into ``NAME.adt``. The neutral scene becomes ``NAME.wrl``. Everything is seeded, so a
rebuild gives byte-identical files (a test checks the committed ones against a rebuild).

Defaults: ``--out models`` (the repository's) and ``--work build/models``.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))
sys.dont_write_bytecode = True  # models/ ships in the wheel: keep __pycache__ out of it

from candide import read_wfm  # noqa: E402
from modeler import Head, SceneWriter, exports  # noqa: E402
from personalities import PERSONALITIES  # noqa: E402
from texture import paint_atlas  # noqa: E402

#: Displacements at or below this (model units; the face is about 2 units tall) are left out of
#: the tables: the exports are rounded to 1e-5, and 1e-4 is a hundredth of a pixel at 352 x 288.
TOLERANCE = 1e-4

CREDIT = (
    "Built on Candide-3 by Jorgen Ahlberg, Image Coding Group, Linkoping University "
    "(models/README.md)"
)


def adi_command() -> list[str]:
    """The ``adi`` console script of this Python environment."""
    exe = Path(sys.executable).with_name("adi")
    if exe.is_file():
        return [str(exe)]
    return [sys.executable, "-c", "import sys; from adt_tools.cli import main; sys.exit(main())"]


def build(name: str, out: Path, work: Path, *, quiet: bool = False) -> None:
    person = PERSONALITIES[name]
    t0 = time.perf_counter()
    head = Head(read_wfm(), person)
    folder = work / name
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    texture = f"{name}-face.png"
    paint_atlas(head).save(out / texture, optimize=True)
    world_info = [
        (f"{name}: {person.title}", [CREDIT]),
        ("vtts:TemporalDefinitionTables", person.temporal),
        ("vtts:FeaturePoints", [f"{k} {node} {v}" for k, node, v in head.feature_points()]),
    ]
    writer = SceneWriter(head, texture, world_info)
    neutral = folder / "neutral.wrl"
    neutral.write_text(writer.text(writer.neutral, "neutral (models/src/modeler.py)"))
    files = []
    for label, state in exports(head):
        path = folder / f"{label}.wrl"
        path.write_text(writer.text(head.realize(state), f"{label} (models/src/modeler.py)"))
        files.append(path)
    t1 = time.perf_counter()
    cmd = [*adi_command(), "build", str(neutral), *map(str, files), "-o", str(out / f"{name}.adt"),
           "--tolerance", repr(TOLERANCE)]  # fmt: skip
    subprocess.run(cmd, check=True, capture_output=quiet)
    shutil.copyfile(neutral, out / f"{name}.wrl")
    if not quiet:
        print(
            f"{name}: {len(files)} exports in {t1 - t0:.1f} s, adi build in "
            f"{time.perf_counter() - t1:.1f} s"
        )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*", default=sorted(PERSONALITIES), metavar="NAME")
    ap.add_argument("--out", type=Path, default=ROOT / "models")
    ap.add_argument("--work", type=Path, default=ROOT / "build" / "models")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.names:
        build(name, args.out, args.work, quiet=args.quiet)
    return 0


if __name__ == "__main__":
    sys.exit(main())
