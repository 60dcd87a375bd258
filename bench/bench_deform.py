"""Deformation engine speed: one FAP frame to posed vertices for a 10,000-vertex model.

The model is generated here: one IndexedFaceSet of 10,000 points and tables for every MIAP the
engine knows — 66 low-level FAPs (two intervals each, bidirectional), 14 visemes and 6
expressions (two phases each) — each moving a seeded random region of 300–1,500 points, plus
Transform tables for the head and eye rotations. Three kinds of frame are timed:

- "all MIAPs active": every parameter non-zero (the worst case the issue names);
- "speaking": 17 FAPs, two visemes and one expression active (what ``vtts say`` produces);
- "neutral": nothing active.

Target (issue 3): under 0.5 ms per frame with all tables. Median of 2,000 frames.
"""

from __future__ import annotations

import time

import numpy as np

BENCH = "deform"
TARGET_MS = 0.5
FRAMES = 2000


def build_model(n_points: int = 10_000, seed: int = 7):
    from vtts.face import Adt, AnimationTables, DeformationEngine, MeshTable, TransformTable
    from vtts.face.miap import all_miaps

    rng = np.random.default_rng(seed)
    points = rng.normal(size=(n_points, 3))
    tables = AnimationTables()
    nnz = 0
    for miap in all_miaps():
        size = int(rng.integers(300, 1500))
        verts = np.sort(rng.choice(n_points, size=size, replace=False))
        if miap.kind == "fap":
            borders = [-1024.0, 0.0, 512.0, 1024.0]
        else:
            borders = [0.0, 0.5, 1.0]
        disp = rng.normal(size=(len(borders) - 1, size, 3)) * 1e-4
        nnz += disp.size
        adt = Adt(miap, meshes=[MeshTable("FACE", borders, verts, disp)])
        if miap.kind == "fap" and miap.number in (23, 24, 25, 26, 48, 49, 50):
            adt.transforms.append(TransformTable("HEAD", "rotation", [0, 1, 0, 0], [1e-5]))
        tables.add(adt)
    neutral_t = {
        "HEAD": {
            "rotation": np.array([0, 1, 0, 0.0]),
            "translation": np.zeros(3),
            "scale": np.ones(3),
        }
    }
    return DeformationEngine(tables, {"FACE": points}, neutral_t), nnz


def frames(kind: str, n: int, rng) -> np.ndarray:
    from vtts.face import N_PARAMS
    from vtts.face.miap import all_miaps

    p = np.zeros((n, N_PARAMS))
    if kind == "all MIAPs active":
        for m in all_miaps():
            p[:, m.index] = rng.uniform(-800, 800, n) if m.kind == "fap" else rng.uniform(0, 1, n)
    elif kind == "speaking":
        faps = [3, 4, 5, 6, 7, 12, 13, 31, 32, 33, 34, 48, 49, 50, 19, 20, 23]
        for f in faps:
            p[:, f - 1] = rng.uniform(-300, 300, n)
        p[:, 68 + 3] = rng.uniform(0, 1, n)
        p[:, 68 + 7] = 1 - p[:, 68 + 3]
        p[:, 83 + 1] = 0.6
    return p


def run() -> list[dict]:
    engine, nnz = build_model()
    rng = np.random.default_rng(1)
    rows = []
    for kind in ("all MIAPs active", "speaking", "neutral"):
        params = frames(kind, FRAMES, rng)
        for p in params[:50]:  # warm up
            engine.deform(p)
        times = np.empty(FRAMES)
        for i, p in enumerate(params):
            t0 = time.perf_counter()
            engine.deform(p)
            times[i] = time.perf_counter() - t0
        ms = float(np.median(times) * 1e3)
        rows.append(
            {
                "benchmark": "deform 10k-vertex model",
                "case": f"{kind} (86 MIAPs, {nnz / 1e6:.1f}M table entries)",
                "value": round(ms, 4),
                "unit": "ms/frame",
                "target": f"< {TARGET_MS} ms",
                "ok": ms < TARGET_MS,
            }
        )
    return rows
