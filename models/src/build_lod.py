"""Make the bundled heads' progressive meshes (``models/lod/*.npz``): the order in which
``vtts say`` and ``vtts play`` leave out triangles that a small frame cannot show
(:mod:`vtts.render.lod`). Shipped so that a head's first video does not wait for them; a
model that changes gets new ones (their names are digests of what they are made from), and
``tests/render/test_lod.py`` checks that every bundled head has its own.

Run by ``make models`` after the heads are built; ``python models/src/build_lod.py`` alone
remakes them for the heads as they are.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from vtts.face import bundled_models, load_model  # noqa: E402
from vtts.render import FaceRenderer  # noqa: E402
from vtts.render.lod import save  # noqa: E402
from vtts.render.renderer import lod_key, make_progressive  # noqa: E402


def main() -> None:
    folder = ROOT / "models" / "lod"
    folder.mkdir(exist_ok=True)
    made = set()
    for name in bundled_models():
        with FaceRenderer(load_model(name)) as r:
            for inst in r.instances:
                for am in inst.meshes:
                    file, positions, faces = lod_key(inst, am)
                    save(folder / file, make_progressive(positions, faces))
                    made.add(file)
                    print(f"{name} {am.name}: {folder / file}")
    for old in folder.glob("*.npz"):
        if old.name not in made:
            old.unlink()


if __name__ == "__main__":
    main()
