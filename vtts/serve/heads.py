"""A head as ``vtts serve`` serves it: the model, its glTF for the page, and the tables the page
needs to pose it from the streamed parameter values (:class:`ServedHead`)."""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class ServedHead:
    """One model a server offers.

    name     the name sessions open it by (the model's)
    model    the :class:`~vtts.face.FaceModel`
    glb      its glTF (binary, neutral, with the ``vtts`` camera of a 352×288 view), bytes
    params   ``(K,) int64``: the parameter indices (:mod:`vtts.face.miap`) whose values each
             face frame carries, in that order: those the model's tables animate
    rig      what the page poses the glTF with (JSON): ``miaps`` (morph target label →
             parameter index) and ``transforms`` (each animated Transform field's table)
    """

    name: str
    model: object
    glb: bytes
    params: np.ndarray
    rig: dict = field(default_factory=dict)


def served_head(model, fps: float = 30.0) -> ServedHead:
    """The :class:`ServedHead` of a loaded ``model``."""
    from vtts.export.gltf import write_gltf
    from vtts.export.morph import target_label
    from vtts.face.miap import N_PARAMS

    engine = model.engine
    used: set[int] = set()
    for block in engine.meshes.values():
        used.update(int(p) for p in block.param)
    transforms = []
    for (node, fld), t in engine.transforms.items():
        used.update(int(p) for p in t.param)
        entry = {
            "node": node,
            "field": fld,
            "neutral": [float(v) for v in t.neutral],
            "param": [int(p) for p in t.param],
        }
        if fld == "rotation":
            axes = t.axes if t.axes is not None else np.tile(t.neutral[:3], (len(t.param), 1))
            entry["unit"] = [float(u) for u in np.asarray(t.unit).reshape(-1)]
            entry["axes"] = [[float(a) for a in axis] for axis in axes]
        else:
            entry["unit"] = [[float(u) for u in row] for row in np.asarray(t.unit).reshape(-1, 3)]
        transforms.append(entry)
    miaps = {target_label(adt.miap): int(adt.miap.index) for adt in model.tables.adts.values()}
    fd, tmp = tempfile.mkstemp(prefix="vtts-serve-", suffix=".glb")
    os.close(fd)
    try:
        write_gltf(tmp, [model], np.zeros((1, N_PARAMS)), fps)
        glb = Path(tmp).read_bytes()
    finally:
        Path(tmp).unlink(missing_ok=True)
    rig = {"miaps": miaps, "transforms": transforms}
    return ServedHead(model.name, model, glb, np.array(sorted(used), dtype=np.int64), rig)
