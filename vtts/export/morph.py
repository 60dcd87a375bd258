"""The spatial ADTs of a model as glTF morph targets, exactly.

The deformation engine (:mod:`vtts.face.deform`) keeps one column of a sparse matrix ``A`` per
(MIAP, IndexedFaceSet, interval): the interval's displacement per unit. For a MIAP value ``f`` the
column's weight is ``w = clip(f, lo, hi) − clip(0, lo, hi)`` (the first and last intervals extend
to ∓∞) and the posed points are ``neutral + A @ w``. Each column becomes one morph target, scaled
by its interval's length so that its weight is the progress through the interval:

    target_c = A[:, c] · (to_c − from_c)        weight_c(f) = w_c(f) / (to_c − from_c)

``from_c`` is the interval's border nearer to 0 (``clip(0, lo, hi)``), ``to_c`` the other one as
the table gives it, so a weight runs from 0 (the value has not reached the interval) to 1 (it
has passed it), beyond 1 or below 0 only where vtts extrapolates the first or last interval.
``neutral + Σ_c weight_c · target_c`` is then vtts's deformation to float32 rounding.

glTF vertices of an IndexedFaceSet: vertex ``i`` is Coordinate point ``i`` for ``i < p`` (a point
no face uses is kept, so the numbering holds); the copies made where normals, texture
coordinates or colors differ between the faces around a point (seams) come after, from ``p`` on.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from vtts.errors import FapError
from vtts.face.miap import Miap
from vtts.fap import fap
from vtts.mesh import incidence, vertex_normals
from vtts.vrml import TriangleMesh

#: Normal deltas of a morph target smaller than this (in every component) are left out. Summing
#: per-target normal changes is itself an approximation (on cybatt's FACE over the 13 s demo:
#: 0.50° mean, 0.85° at the 90th percentile from the exact normals, against 3.4° and 7.6° with
#: the neutral normals); leaving out changes below 0.01 moves that to 0.54° and 0.87° and takes
#: a quarter of the normal data (a third of a megabyte) out of the file.
NORMAL_TOLERANCE = 1e-2

_FAP_LABEL = re.compile(r"FAP([0-9]{1,2})_(\w+)")


def target_label(miap: Miap) -> str:
    """The MIAP as morph target names begin: ``FAP3_open_jaw``, ``viseme3``, ``joy``."""
    if miap.kind == "fap":
        return f"FAP{miap.number}_{miap.name}"
    if miap.kind == "viseme":
        return f"viseme{miap.number}"
    return miap.name


def target_name(miap: Miap, interval: int) -> str:
    """``FAP3_open_jaw#0``: the morph target of ``interval`` (0-based, in border order) of the
    MIAP's table."""
    return f"{target_label(miap)}#{interval}"


def parse_target_name(name: str) -> tuple[Miap, int]:
    """The MIAP and interval number of a :func:`target_name`; raises :class:`FapError` for
    anything else."""
    label, sep, k = name.rpartition("#")
    if not sep or not k.isascii() or not k.isdigit() or len(k) > 6:
        raise FapError(f"morph target {name!r} is not named MIAP#INTERVAL (e.g. FAP3_open_jaw#0)")
    m = _FAP_LABEL.fullmatch(label)
    if m:
        miap = Miap("fap", fap(int(m[1])).number)
        if miap.number < 3 or m[2].lower() != miap.name:
            raise FapError(f"morph target {name!r}: FAP {m[1]} is {miap.name}, not {m[2]}")
        return miap, int(k)
    try:
        return Miap.parse(label), int(k)
    except ValueError as e:
        raise FapError(f"morph target {name!r}: {e}") from None


# ---- vertices ------------------------------------------------------------------------------------


@dataclass(eq=False)
class VertexLayout:
    """The glTF vertices of one IndexedFaceSet (see the module's docstring); ``n_points`` is its
    Coordinate point count ``p``.

    source  ``(V,) int64``  the :class:`~vtts.vrml.TriangleMesh` vertex each glTF vertex is
            (−1: a point no face uses)
    point   ``(V,) int64``  the Coordinate point of each glTF vertex (``point[:p] == arange(p)``)
    faces   ``(m, 3) int64`` the triangles in glTF vertex numbers
    """

    source: np.ndarray
    point: np.ndarray
    faces: np.ndarray
    n_points: int


def vertex_layout(tm: TriangleMesh, n_points: int) -> VertexLayout:
    """Points first, seam copies after: see the module's docstring. ``n_points`` is the
    IndexedFaceSet's Coordinate point count ``p``."""
    coord = tm.coord_index
    n = coord.size
    first = np.full(n_points, -1, dtype=np.int64)
    # the first output vertex of each point stands for it (reversed: the lowest index wins)
    first[coord[::-1]] = np.arange(n)[::-1]
    is_first = np.zeros(n, dtype=bool)
    is_first[first[first >= 0]] = True
    extras = np.flatnonzero(~is_first)
    source = np.concatenate([first, extras])
    point = np.concatenate([np.arange(n_points), coord[extras]])
    number = np.empty(n, dtype=np.int64)  # tm vertex -> glTF vertex
    used = first >= 0
    number[first[used]] = np.flatnonzero(used)
    number[extras] = n_points + np.arange(extras.size)
    return VertexLayout(source, point, number[tm.faces], n_points)


def gather(values: np.ndarray, layout: VertexLayout, fill: float | np.ndarray = 0.0) -> np.ndarray:
    """``values`` ``(n, k)`` of the TriangleMesh's vertices in glTF vertex order ``(V, k)``,
    ``fill`` for unused points."""
    out = np.empty((layout.source.size, values.shape[1]), dtype=values.dtype)
    ok = layout.source >= 0
    out[ok] = values[layout.source[ok]]
    out[~ok] = fill
    return out


def unit_normals(positions: np.ndarray, faces: np.ndarray, incidence: sp.csr_matrix) -> np.ndarray:
    """Area-weighted unit vertex normals ``(V, 3)`` as the renderer computes them for animated
    meshes (:func:`vtts.mesh.vertex_normals`), +z where a vertex has none (no face, or only
    degenerate ones: glTF wants unit normals)."""
    n = vertex_normals(positions, faces, incidence)
    n[~(np.abs(n).sum(axis=1) > 0)] = (0.0, 0.0, 1.0)
    return n


# ---- targets -------------------------------------------------------------------------------------


@dataclass(eq=False)
class MorphTargets:
    """The morph targets of one IndexedFaceSet: one per column of its engine block.

    names      target names (:func:`target_name`), in column order
    param      ``(C,) int64`` parameter-vector index of each target's MIAP
    lo, hi     ``(C,) float64`` the engine's interval bounds (±inf at the ends)
    start      ``(C,) float64`` the border nearer 0 (``from``), in the MIAP's units
    end        ``(C,) float64`` the other border (``to``)
    positions  per target ``(indices (k,) int64, deltas (k, 3) float64)``: the glTF vertices it
               moves and by how much at weight 1 (model units)
    normals    per target the same for unit normals (None: not computed)
    """

    names: list[str]
    param: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    start: np.ndarray
    end: np.ndarray
    positions: list[tuple[np.ndarray, np.ndarray]]
    normals: list[tuple[np.ndarray, np.ndarray]] | None

    def weights(self, params: np.ndarray) -> np.ndarray:
        """``(T, C) float64`` target weights for parameter vectors ``(T, N_PARAMS)``."""
        f = np.asarray(params, dtype=np.float64)[:, self.param]
        return (np.clip(f, self.lo, self.hi) - self.start) / (self.end - self.start)


def morph_targets(
    block,
    miaps: dict[int, Miap],
    layout: VertexLayout,
    *,
    normals: bool = True,
) -> MorphTargets:
    """The morph targets of an engine block (``model.engine.meshes[name]``) on the glTF vertices
    of ``layout``; ``miaps`` maps parameter index → MIAP. With ``normals``, each target also
    carries the change of the unit vertex normals it makes, taken where it begins: along one
    MIAP's intervals in order from 0 outwards, so that one MIAP alone gets exact normals at every
    border, and several MIAPs at once the sum of their changes (renormalized by the viewer)."""
    start = block.at_zero
    b0, b1 = block.borders[:, 0], block.borders[:, 1]
    end = np.where(b0 >= 0, b1, b0)  # the border away from 0
    span = end - start
    rows = (3 * layout.point[:, None] + np.arange(3)).reshape(-1)
    a = block.csr[rows].tocsc()  # (3V, C): the columns on the glTF vertices
    positions = []
    for c in range(a.shape[1]):
        r = a.indices[a.indptr[c] : a.indptr[c + 1]]
        v = a.data[a.indptr[c] : a.indptr[c + 1]]
        verts, inv = np.unique(r // 3, return_inverse=True)
        d = np.zeros((verts.size, 3))
        d[inv, r % 3] = v * span[c]
        keep = np.abs(d).max(axis=1) > 0 if d.size else np.zeros(0, dtype=bool)
        positions.append((verts[keep], d[keep]))
    names = [
        target_name(miaps[int(p)], int(k)) for p, k in zip(block.param, block.interval, strict=True)
    ]
    target_normals = None
    if normals:
        target_normals = _normal_deltas(block, layout, positions, start, np.sign(span))
    return MorphTargets(
        names, block.param.copy(), block.lo, block.hi, start, end, positions, target_normals
    )


def _normal_deltas(
    block, layout: VertexLayout, positions: list, start: np.ndarray, side: np.ndarray
) -> list:
    neutral = block.neutral[layout.point]
    inc = incidence(layout.faces, neutral.shape[0])
    out: list = [None] * len(positions)
    # each MIAP's intervals on each side of 0, from 0 outwards: a target's normal change is taken
    # from where the intervals before it leave the mesh
    order = np.lexsort((np.abs(start), side, block.param))
    prev_key = None
    offset = np.zeros_like(neutral)
    before = None
    for c in order:
        key = (int(block.param[c]), float(side[c]))
        if key != prev_key:
            offset[:] = 0.0
            before = unit_normals(neutral, layout.faces, inc)
            prev_key = key
        idx, d = positions[c]
        offset[idx] += d
        after = unit_normals(neutral + offset, layout.faces, inc)
        delta = after - before
        keep = np.flatnonzero(np.abs(delta).max(axis=1) > NORMAL_TOLERANCE)
        out[c] = (keep, delta[keep])
        before = after
    return out
