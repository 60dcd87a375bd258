"""``adi show``: a readable summary of a model's Animation Definition Tables.

For each MIAP (key and name): the IndexedFaceSets it moves with their vertex counts, intervals
and interval borders, and the Transform fields it moves with their neutral value and change per
unit; then the temporal tables and feature points when the model has them.
"""

from __future__ import annotations

import os
from pathlib import Path

from vtts.errors import AdtError
from vtts.face import AnimationTables, MeshTable, TransformTable, load_model, read_adt
from vtts.vrml.fields import format_number


def _nums(values) -> str:
    return " ".join(format_number(float(v)) for v in values)


def _plural(n: int, noun: str, plural: str | None = None) -> str:
    return f"{n} {noun if n == 1 else (plural or noun + 's')}"


def describe_mesh(m: MeshTable, points: int | None = None) -> str:
    """``IndexedFaceSet FACE: 6 of 113 vertices, 2 intervals, borders 0 512 1024``."""
    n = m.vertices.size
    verts = (
        f"{n} of {_plural(points, 'vertex', 'vertices')}"
        if points is not None
        else (_plural(n, "vertex", "vertices"))
    )
    return (
        f"IndexedFaceSet {m.node}: {verts}, {_plural(m.borders.size - 1, 'interval')}, "
        f"borders {_nums(m.borders)}"
    )


def describe_transform(t: TransformTable) -> str:
    """``Transform HEAD: rotation about 1 0 0 from 0 rad, 1e-05 rad per unit``."""
    if t.field == "rotation":
        return (
            f"Transform {t.node}: rotation about {_nums(t.neutral[:3])} from "
            f"{format_number(t.neutral[3])} rad, {format_number(t.unit[0])} rad per unit"
        )
    return f"Transform {t.node}: {t.field} from {_nums(t.neutral)}, {_nums(t.unit)} per unit"


def describe_tables(
    tables: AnimationTables, point_counts: dict[str, int] | None = None
) -> list[str]:
    """The summary lines of ``tables``; ``point_counts`` (IndexedFaceSet DEF name → number of
    points) adds the size of each animated mesh when the scene is known."""
    counts = point_counts or {}
    kinds = {"fap": 0, "viseme": 0, "expression": 0}
    for miap in tables.adts:
        kinds[miap.kind] += 1
    meshes, transforms = tables.mesh_nodes(), tables.transform_nodes()
    head = (
        f"{_plural(len(tables.adts), 'MIAP')} ({_plural(kinds['fap'], 'FAP')}, "
        f"{_plural(kinds['viseme'], 'viseme')}, {_plural(kinds['expression'], 'expression')}); "
        f"{_plural(len(meshes), 'IndexedFaceSet')}"
        + (f" ({', '.join(meshes)})" if meshes else "")
        + f", {_plural(len(transforms), 'Transform')}"
        + (f" ({', '.join(transforms)})" if transforms else "")
    )
    out = [head]
    for adt in tables.adts.values():
        out.append(f"MIAP {adt.miap}")
        for m in adt.meshes:
            out.append("  " + describe_mesh(m, counts.get(m.node)))
        for t in adt.transforms:
            out.append("  " + describe_transform(t))
        if not adt.meshes and not adt.transforms:
            out.append("  (moves nothing)")
    if tables.temporal:
        out.append("temporal tables:")
        out += ["  " + line for line in tables.temporal.lines()]
    if tables.feature_points:
        out.append(f"feature points ({len(tables.feature_points)}):")
        out += [f"  {p} {node} {v}" for p, (node, v) in tables.feature_points.items()]
    return out


def show(path: str | os.PathLike[str]) -> list[str]:
    """The ``adi show`` lines for a ``.adt`` file or a model ``.wrl`` (tables embedded or in a
    sidecar ``.adt``); the first line names the file."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".adt":
        tables = read_adt(p)
        lines = describe_tables(tables)
    elif suffix == ".wrl":
        if not p.is_file():
            raise AdtError("no such file", file=str(p))
        model = load_model(p)
        counts = {n: len(model.neutral_points(n)) for n in model.tables.mesh_nodes()}
        lines = describe_tables(model.tables, counts)
        if not model.tables:
            lines = ["no animation tables (neither FaceDefTables nor a sidecar .adt)"]
    else:
        raise AdtError(f"unknown file type '{p.suffix}' (adi shows .adt and .wrl)", file=str(p))
    return [f"{p}: {lines[0]}", *lines[1:]]
