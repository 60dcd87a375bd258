"""Rendering speed: deform + render + encode, and the real-time factor of ``vtts play``.

The head is generated here (``bench/_generated/head10k.wrl`` + ``.adt``): the Candide-3 sample
face refined by three levels of Loop subdivision (11,776 triangles), with seeded tables for 40
FAPs, 6 expressions and head rotations — what a bundled head carries. Until the bundled heads
exist (issue 5) this stands in for them.

Cases (issue 4): frames per second of deform + render + H.264 encode at 352x288 and 640x480
(target: at least 60 fps at 352x288 on the project's 2-core machines), and the real-time factor
of ``vtts play`` (the command, end to end, as a subprocess) on a 10 s FAP stream at 30 Hz.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

BENCH = "render"
ROOT = Path(__file__).resolve().parents[1]
GENERATED = ROOT / "bench" / "_generated"
TARGET_FPS = 60.0
FRAMES = 150


def head_model() -> Path:
    """Write (once) and return the 11,776-triangle benchmark head."""
    import trimesh

    from vtts.face import Adt, AnimationTables, MeshTable, Miap, TransformTable, write_adt
    from vtts.vrml import read, triangulate

    out = GENERATED / "head10k.wrl"
    if out.is_file() and out.with_suffix(".adt").is_file():
        return out
    GENERATED.mkdir(parents=True, exist_ok=True)
    base = read(ROOT / "samples" / "candide3.wrl")
    tm = triangulate(base.node("FACE_MESH"))
    verts, faces = trimesh.remesh.subdivide_loop(tm.positions, tm.faces, iterations=3)
    points = ",\n".join(" ".join(f"{v:.6f}" for v in p) for p in verts)
    index = "\n".join(f"{a} {b} {c} -1" for a, b, c in faces)
    text = f"""#VRML V2.0 utf8
DEF HEAD Transform {{ children [
  Shape {{
    appearance Appearance {{ material Material {{ diffuseColor 0.85 0.65 0.55 }} }}
    geometry DEF FACE IndexedFaceSet {{
      coord Coordinate {{ point [ {points} ] }}
      coordIndex [ {index} ]
      creaseAngle 3
    }}
  }}
] }}
"""
    rng = np.random.default_rng(5)
    tables = AnimationTables()
    n = len(verts)
    for number in [*range(3, 23), *range(31, 43), *range(51, 59)]:
        centre = verts[rng.integers(n)]
        near = np.flatnonzero(np.linalg.norm(verts - centre, axis=1) < 0.35)
        disp = rng.normal(size=(2, near.size, 3)) * 4e-6
        tables.add(
            Adt(Miap("fap", number), meshes=[MeshTable("FACE", [-1024, 0, 1024], near, disp)])
        )
    for e in range(1, 7):
        near = np.flatnonzero(rng.random(n) < 0.3)
        tables.add(
            Adt(
                Miap("expression", e),
                meshes=[
                    MeshTable("FACE", [0, 0.5, 1], near, rng.normal(size=(2, near.size, 3)) * 0.002)
                ],
            )
        )
    for number, axis in ((48, [1, 0, 0]), (49, [0, 1, 0]), (50, [0, 0, 1])):
        tables.add(
            Adt(
                Miap("fap", number),
                transforms=[TransformTable("HEAD", "rotation", [*axis, 0], [1e-5])],
            )
        )
    tmp = out.with_suffix(".tmp")
    tmp.write_text(text)
    write_adt(tables, out.with_suffix(".adt"))
    os.replace(tmp, out)
    return out


def stream(seconds: float, path: Path) -> Path:
    """A seeded 30 Hz FAP stream moving the tabled FAPs smoothly."""
    from vtts.fap import FapStream, write_fap

    n = int(seconds * 30)
    t = np.arange(n) / 30
    values = np.zeros((n, 68))
    mask = np.zeros((n, 68), dtype=bool)
    rng = np.random.default_rng(2)
    for k in [*range(3, 23), *range(31, 43), 48, 49, 50]:
        f, ph = rng.uniform(0.2, 2), rng.uniform(0, 6)
        amp = 8000 if k >= 48 else 500
        values[:, k - 1] = np.round(amp * np.sin(2 * np.pi * f * t + ph))
        mask[:, k - 1] = True
    write_fap(FapStream(30.0, "bench", values, mask), path)
    return path


def _fps(size: tuple[int, int], model, encode: bool) -> float:
    from vtts.render import FaceRenderer, VideoWriter

    rng = np.random.default_rng(1)
    params = np.zeros((FRAMES, 90))
    params[:, 2:22] = rng.uniform(-500, 500, (FRAMES, 20))
    params[:, 47:50] = rng.uniform(-8000, 8000, (FRAMES, 3))
    params[:, 84] = np.linspace(0, 1, FRAMES)
    with tempfile.TemporaryDirectory() as d, FaceRenderer(model, size=size) as r:
        r.render(params[0])
        t0 = time.perf_counter()
        # as vtts play and say do: the next frame's geometry is prepared while one rasterizes
        if encode:
            with VideoWriter(Path(d) / "b.mp4", 30, r.size) as w:
                for frame in r.frames(list(params)):
                    w.write(frame)
        else:
            for _ in r.frames(list(params)):
                pass
        return FRAMES / (time.perf_counter() - t0)


def run() -> list[dict]:
    from vtts.face import load_model

    path = head_model()
    model = load_model(path)
    tris = model.scene.triangle_count()
    rows = []
    for size in ((352, 288), (640, 480)):
        for encode in (False, True):
            fps = _fps(size, model, encode)
            what = "deform+render+encode" if encode else "deform+render"
            target = size == (352, 288) and encode
            rows.append(
                {
                    "benchmark": f"{what} {tris} triangles",
                    "case": f"{size[0]}x{size[1]}",
                    "value": round(fps, 1),
                    "unit": "frames/s",
                    "target": f">= {TARGET_FPS:g}" if target else "",
                    "ok": fps >= TARGET_FPS if target else None,
                }
            )
    with tempfile.TemporaryDirectory() as d:
        fap = stream(10.0, Path(d) / "ten.fap")
        vtts = Path(sys.executable).with_name("vtts")
        t0 = time.perf_counter()
        subprocess.run(
            [
                str(vtts),
                "play",
                str(fap),
                "--model",
                str(path),
                "-o",
                str(Path(d) / "ten.mp4"),
                "--quiet",
            ],
            check=True,
            capture_output=True,
        )
        wall = time.perf_counter() - t0
    rows.append(
        {
            "benchmark": "vtts play (end to end)",
            "case": f"10 s stream at 30 Hz, {tris} triangles, 352x288, startup included",
            "value": round(10.0 / wall, 2),
            "unit": "x real time",
            "target": "",
            "ok": None,
        }
    )
    t0 = time.perf_counter()
    subprocess.run([str(vtts), "models"], check=True, capture_output=True)
    rows.append(
        {
            "benchmark": "vtts startup",
            "case": "python + imports (pyrender, trimesh) + vtts models",
            "value": round(time.perf_counter() - t0, 2),
            "unit": "s",
            "target": "",
            "ok": None,
        }
    )
    return rows
