"""Avatar import (``adi import``): the time to import an ARKit-blendshape avatar, and how closely
the import animates like the head it came from.

The avatar is the bundled ``cybatt`` written as an ARKit-blendshape ``.glb`` by
:func:`vtts.export.avatar.write_arkit_avatar`: its face mesh has 5,150 vertices and 51 morph
targets (the ARKit shapes its tables can show and the 14 Oculus visemes; the 52nd target of the
file, ``tongueOut``, moves only the tongue), plus hair, mouth, teeth, tongue and eyeballs. The
import is timed in process (:func:`vtts.avatar.importer.import_avatar` and writing
``.wrl``/``.adt``/texture; median of three) and as the command ``adi import`` (startup and the
check that loads the result included; median of three).

The round trip: ``vtts say`` of a short sentence without autonomous motion on cybatt and on the
import, the same frames compared (PSNR over the whole frame; frames at rest are identical, so the
worst frame is the figure that matters) at 352×288.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

BENCH = "avatar_import"
RUNS = 3
TEXT = "Hello, nice to meet you. How are you today?"


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(((a.astype(np.float64) - b) ** 2).mean())
    return 99.0 if mse == 0 else float(10 * np.log10(255**2 / mse))


def run() -> list[dict]:
    import pygltflib
    from PIL import Image

    from vtts.avatar.importer import import_avatar
    from vtts.export.avatar import write_arkit_avatar
    from vtts.face import load_model

    rows = []
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        glb = write_arkit_avatar(folder / "cybatt-arkit.glb", load_model("cybatt"))
        doc = pygltflib.GLTF2.load(str(glb))
        face = next(m for m in doc.meshes if m.name == "FACE")
        n_targets = len(face.primitives[0].targets)
        n_vertices = doc.accessors[face.primitives[0].attributes.POSITION].count
        case = (
            f"cybatt as an ARKit avatar: FACE {n_vertices} glTF vertices, {n_targets} "
            f"targets; {len(doc.meshes)} meshes, {glb.stat().st_size / 1e6:.1f} MB"
        )
        times = []
        for k in range(RUNS):
            t0 = time.perf_counter()
            import_avatar(glb).write(folder / f"lib{k}.wrl")
            times.append(time.perf_counter() - t0)
        rows.append({
            "benchmark": "avatar import: time (library)",
            "case": f"{case}; median of {RUNS} ({min(times):.2f}–{max(times):.2f})",
            "value": round(statistics.median(times), 3), "unit": "s", "target": "", "ok": None,
        })  # fmt: skip
        adi = Path(sys.executable).with_name("adi")
        walls = []
        for _ in range(RUNS):
            t0 = time.perf_counter()
            subprocess.run([str(adi), "import", str(glb), "-o", str(folder / "cli.wrl")],
                           check=True, capture_output=True)  # fmt: skip
            walls.append(time.perf_counter() - t0)
        rows.append({
            "benchmark": "avatar import: adi import",
            "case": f"the same file, startup and loading the result included, median of {RUNS} "
                    f"({min(walls):.2f}–{max(walls):.2f})",
            "value": round(statistics.median(walls), 3), "unit": "s", "target": "", "ok": None,
        })  # fmt: skip
        vtts = Path(sys.executable).with_name("vtts")
        frames = {}
        for name, model in (("original", "cybatt"), ("imported", str(folder / "cli.wrl"))):
            out = folder / name
            subprocess.run(
                [
                    str(vtts),
                    "say",
                    TEXT,
                    "--model",
                    model,
                    "--no-autonomous",
                    "--png-dir",
                    str(out),
                    "--quiet",
                ],
                check=True,
                capture_output=True,
            )
            frames[name] = [np.asarray(Image.open(p)) for p in sorted(out.glob("*.png"))]
        psnr = [_psnr(a, b) for a, b in zip(frames["original"], frames["imported"], strict=True)]
        moving = [p for p in psnr if p < 99]
        rows.append({
            "benchmark": "avatar import: round-trip PSNR",
            "case": f"vtts say {TEXT!r} --no-autonomous at 352x288 on cybatt and its import, "
                    f"worst of {len(psnr)} frames ({len(moving)} differ; their mean "
                    f"{statistics.mean(moving) if moving else 99:.1f} dB)",
            "value": round(min(psnr), 2), "unit": "dB", "target": "", "ok": None,
        })  # fmt: skip
    return rows


if __name__ == "__main__":  # pragma: no cover
    for row in run():
        print(row)
