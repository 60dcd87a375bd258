"""The deformation engine: one parameter vector in, the posed geometry of the model out.

Every (MIAP, IndexedFaceSet, interval) of the tables becomes one column of a sparse matrix ``A``
of shape ``(3p, C)`` per IndexedFaceSet (p points): the interval's displacement per unit. For a
parameter vector, each column's weight is how much of its interval lies between 0 and the MIAP's
value (:func:`vtts.face.adt.interval_weights`), so the posed points are

    points = neutral + (A @ w).reshape(p, 3)

which is the integral of the piecewise-constant slopes of every MIAP, superimposed linearly.
When few MIAPs are active (the usual case while speaking) only their columns are gathered.

Transforms: a rotation keeps its axis and adds ``f · unit`` to the angle per MIAP (rotations about
different axes, possible only around a zero neutral angle, are composed in MIAP order);
translation and scale add ``f · unit``.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from vtts.face.adt import AnimationTables
from vtts.face.miap import N_PARAMS

if TYPE_CHECKING:  # imported where the tables are compiled: `vtts check` never needs it
    import scipy.sparse as sp


@dataclass
class Pose:
    """The posed geometry of a model.

    points      IndexedFaceSet DEF name → ``(p, 3) float64`` Coordinate points (model units)
    transforms  Transform DEF name → {field name → value}: rotation ``(4,)`` axis + angle (rad),
                translation and scale ``(3,)``
    """

    points: dict[str, np.ndarray] = field(default_factory=dict)
    transforms: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)


def _row_slice(m: sp.csr_matrix, start: int, stop: int) -> sp.csr_matrix:
    """Rows ``start:stop`` of ``m``, sharing its arrays (``m[start:stop]`` copies them)."""
    import scipy.sparse as sp

    a, b = m.indptr[start], m.indptr[stop]
    return sp.csr_matrix(
        (m.data[a:b], m.indices[a:b], m.indptr[start : stop + 1] - a),
        shape=(stop - start, m.shape[1]),
    )


@dataclass
class _MeshBlock:
    neutral: np.ndarray  # (p, 3)
    csr: sp.csr_matrix  # (3p, C)
    csc: sp.csc_matrix
    param: np.ndarray  # (C,) parameter index of each column
    lo: np.ndarray  # (C,) interval lower border (-inf for the first)
    hi: np.ndarray  # (C,)
    at_zero: np.ndarray  # (C,) clip(0, lo, hi): the weight offset
    halves: tuple[sp.csr_matrix, sp.csr_matrix] | None = None  # row halves of csr, when large
    # (C,) the column's interval number in its MIAP's table for this IndexedFaceSet, and
    # (C, 2) that interval's borders as the table gives them (finite, unlike lo and hi)
    interval: np.ndarray | None = None
    borders: np.ndarray | None = None


@dataclass
class _TransformBlock:
    neutral: np.ndarray
    param: np.ndarray  # (k,)
    unit: np.ndarray  # (k,) for rotations (signed along the reference axis), (k, 3) otherwise
    axes: np.ndarray | None = None  # (k, 3) unit axes of rotations, None when all parallel


class DeformationEngine:
    """Compiled tables of one model.

    ``neutral_points``: IndexedFaceSet DEF name → ``(p, 3)`` neutral Coordinate points;
    ``neutral_transforms``: Transform DEF name → {field: neutral value}.
    """

    #: Below this fraction of active columns, gather columns instead of a full product.
    GATHER_BELOW = 0.25
    #: Table entries above which the full product runs in two threads.
    SPLIT_ABOVE = 300_000

    def __init__(
        self,
        tables: AnimationTables,
        neutral_points: dict[str, np.ndarray],
        neutral_transforms: dict[str, dict[str, np.ndarray]],
    ) -> None:
        self.meshes: dict[str, _MeshBlock] = {}
        #: the entries of the last active columns gathered from each mesh's table, by id of its
        #: block: (the columns, their lengths, the entries' rows and values)
        self._gathered: dict[int, tuple[bytes, np.ndarray, np.ndarray, np.ndarray]] = {}
        self.transforms: dict[tuple[str, str], _TransformBlock] = {}
        self._compile_meshes(tables, neutral_points)
        self._compile_transforms(tables, neutral_transforms)

    def _compile_meshes(self, tables: AnimationTables, neutral_points) -> None:
        import scipy.sparse as sp

        # each (MIAP, IndexedFaceSet, interval) is one column; its rows are the coordinates of
        # the table's vertices, so the column-major matrix is the tables' arrays laid end to end
        cols: dict[str, list] = {}
        xyz = np.arange(3)
        for adt in tables.adts.values():
            pi = adt.miap.index
            for m in adt.meshes:
                entry = cols.setdefault(m.node, [])
                rows = (3 * m.vertices[:, None] + xyz).reshape(-1)
                n = m.borders.size - 1
                for k in range(n):
                    lo = -np.inf if k == 0 else m.borders[k]
                    hi = np.inf if k == n - 1 else m.borders[k + 1]
                    entry.append((pi, lo, hi, rows, m.displacements[k].reshape(-1), k,
                                  m.borders[k], m.borders[k + 1]))  # fmt: skip
        for name, entries in cols.items():
            neutral = np.asarray(neutral_points[name], dtype=np.float64)
            nrows = 3 * neutral.shape[0]
            shape = (nrows, len(entries))
            sizes = np.array([e[3].size for e in entries], dtype=np.int64)
            indptr = np.zeros(len(entries) + 1, dtype=np.int64)
            np.cumsum(sizes, out=indptr[1:])
            index = np.int32 if max(nrows, int(indptr[-1])) < 2**31 else np.int64
            csc = sp.csc_matrix(
                (
                    np.concatenate([e[4] for e in entries]),
                    np.concatenate([e[3] for e in entries]).astype(index),
                    indptr.astype(index),
                ),
                shape=shape,
            )
            csr = csc.tocsr()
            halves = None
            if csr.nnz >= self.SPLIT_ABOVE:
                h = (nrows // 6) * 3
                halves = (_row_slice(csr, 0, h), _row_slice(csr, h, nrows))
            lo = np.array([e[1] for e in entries])
            hi = np.array([e[2] for e in entries])
            self.meshes[name] = _MeshBlock(
                neutral=neutral,
                halves=halves,
                csr=csr,
                csc=csc,
                param=np.array([e[0] for e in entries], dtype=np.int64),
                lo=lo,
                hi=hi,
                at_zero=np.clip(0.0, lo, hi),
                interval=np.array([e[5] for e in entries], dtype=np.int64),
                borders=np.array([e[6:8] for e in entries], dtype=np.float64).reshape(-1, 2),
            )

    def _compile_transforms(self, tables: AnimationTables, neutral_transforms) -> None:
        groups: dict[tuple[str, str], list] = {}
        for adt in tables.adts.values():
            for t in adt.transforms:
                groups.setdefault((t.node, t.field), []).append((adt.miap.index, t))
        for (node, fld), entries in groups.items():
            neutral = np.asarray(neutral_transforms[node][fld], dtype=np.float64)
            param = np.array([pi for pi, _ in entries], dtype=np.int64)
            if fld != "rotation":
                unit = np.array([t.unit for _, t in entries]).reshape(-1, 3)
                self.transforms[(node, fld)] = _TransformBlock(neutral, param, unit)
                continue
            axes = np.array([t.neutral[:3] / np.linalg.norm(t.neutral[:3]) for _, t in entries])
            units = np.array([t.unit[0] for _, t in entries])
            ref_norm = np.linalg.norm(neutral[:3])
            # a zero angle is the identity about any axis: then the tables' axis is the reference
            ref = neutral[:3] / ref_norm if ref_norm > 0 and neutral[3] != 0 else axes[0]
            dots = axes @ ref
            if np.allclose(np.abs(dots), 1.0, atol=1e-9):
                block = _TransformBlock(np.r_[ref, neutral[3]], param, units * np.sign(dots))
            else:
                block = _TransformBlock(neutral, param, units, axes)
            self.transforms[(node, fld)] = block

    # ---- evaluation ---------------------------------------------------------------------------

    def deform(self, params: np.ndarray) -> Pose:
        """The :class:`Pose` for a ``(N_PARAMS,)`` parameter vector
        (see :mod:`vtts.face.miap`)."""
        params = np.asarray(params, dtype=np.float64)
        return Pose(points=self.points(params), transforms=self.transform_values(params))

    def points(self, params: np.ndarray) -> dict[str, np.ndarray]:
        """The posed Coordinate points of every IndexedFaceSet for a ``(N_PARAMS,)`` parameter
        vector (:attr:`Pose.points`, without the Transforms): DEF name → ``(p, 3) float64``."""
        params = np.asarray(params, dtype=np.float64)
        if params.shape != (N_PARAMS,):
            raise ValueError(f"parameter vector must have shape ({N_PARAMS},), got {params.shape}")
        return {
            name: b.neutral + self.displacement(b, params).reshape(-1, 3)
            for name, b in self.meshes.items()
        }

    def points_many(self, params: np.ndarray) -> dict[str, np.ndarray]:
        """The posed Coordinate points of every IndexedFaceSet for each row of ``params``
        ``(T, N_PARAMS)``: DEF name → ``(T, p, 3) float64``, row ``t`` the same numbers as
        ``deform(params[t]).points`` (one sparse product per IndexedFaceSet for all T rows,
        which sums each point's terms in the same order as the frame-by-frame paths)."""
        params = np.asarray(params, dtype=np.float64)
        if params.ndim != 2 or params.shape[1] != N_PARAMS:
            raise ValueError(f"parameters must have shape (T, {N_PARAMS}), got {params.shape}")
        out = {}
        for name, b in self.meshes.items():
            w = _weights(b, params[:, b.param])  # (T, C)
            moved = (b.csr @ np.ascontiguousarray(w.T)).T  # (T, 3p)
            out[name] = b.neutral + moved.reshape(len(params), -1, 3)
        return out

    def transform_tracks(self, params: np.ndarray) -> dict[tuple[str, str], np.ndarray]:
        """The animated Transform fields for each row of ``params`` ``(T, N_PARAMS)``:
        (DEF name, field) → ``(T, 4)`` rotations (axis, angle in rad) or ``(T, 3)`` translations
        and scales, as :meth:`transform_values` gives them frame by frame."""
        params = np.asarray(params, dtype=np.float64)
        out: dict[tuple[str, str], np.ndarray] = {}
        for (node, fld), t in self.transforms.items():
            f = params[:, t.param]
            if fld != "rotation":
                out[(node, fld)] = t.neutral + f @ t.unit
            elif t.axes is None:
                axis = np.broadcast_to(t.neutral[:3], (len(f), 3))
                out[(node, fld)] = np.c_[axis, t.neutral[3] + f @ t.unit]
            else:
                out[(node, fld)] = np.array([_transform_value(t, fld, p) for p in params])
        return out

    def transform_values(
        self, params: np.ndarray, names: Collection[str] | None = None
    ) -> dict[str, dict[str, np.ndarray]]:
        """The animated Transform fields for a ``(N_PARAMS,)`` parameter vector, as
        :attr:`Pose.transforms` has them (without deforming any mesh): ``{DEF name: {field:
        value}}``, only for the Transforms named in ``names`` when given."""
        out: dict[str, dict[str, np.ndarray]] = {}
        for (node, fld), t in self.transforms.items():
            if names is None or node in names:
                out.setdefault(node, {})[fld] = _transform_value(t, fld, params)
        return out

    def displacement(self, b: _MeshBlock, params: np.ndarray) -> np.ndarray:
        w = _weights(b, params[b.param])
        active = np.flatnonzero(w)
        if active.size == 0:
            return np.zeros(b.csr.shape[0])
        if active.size >= self.GATHER_BELOW * w.size:
            if b.halves is None:
                return b.csr @ w
            # large tables: the two halves of the rows in two threads (scipy releases the GIL)
            top, bottom = b.halves
            upper = _pool().submit(top.__matmul__, w)
            lower = bottom @ w
            return np.concatenate([upper.result(), lower])
        key = active.tobytes()
        kept = self._gathered.get(id(b))
        if kept is None or kept[0] != key:  # the active columns' entries (a pose's stay active)
            ptr, ind, val = b.csc.indptr, b.csc.indices, b.csc.data
            starts, ends = ptr[active], ptr[active + 1]
            lengths = ends - starts
            idx = np.repeat(starts - np.cumsum(lengths) + lengths, lengths)
            idx += np.arange(lengths.sum())
            kept = self._gathered[id(b)] = (key, lengths, ind[idx], val[idx])
        _, lengths, rows, values = kept
        weights = np.repeat(w[active], lengths) * values
        return np.bincount(rows, weights=weights, minlength=b.csr.shape[0])


def _weights(b: _MeshBlock, values: np.ndarray) -> np.ndarray:
    """Each column's weight for its MIAP's ``values`` (``(…, C)``): how much of the column's
    interval lies between 0 and the value (:func:`vtts.face.adt.interval_weights`)."""
    return np.clip(values, b.lo, b.hi) - b.at_zero


_POOL = None


def _pool():
    """One worker thread shared by every engine (the caller's thread does the other half)."""
    global _POOL
    if _POOL is None:
        from concurrent.futures import ThreadPoolExecutor

        _POOL = ThreadPoolExecutor(max_workers=1, thread_name_prefix="vtts-deform")
    return _POOL


def _transform_value(t: _TransformBlock, fld: str, params: np.ndarray) -> np.ndarray:
    f = params[t.param]
    if fld != "rotation":
        return t.neutral + f @ t.unit
    if t.axes is None:
        return np.r_[t.neutral[:3], t.neutral[3] + float(f @ t.unit)]
    q = _quat(t.neutral[:3], t.neutral[3])
    for axis, angle in zip(t.axes, f * t.unit, strict=True):
        if angle:
            q = _qmul(q, _quat(axis, angle))
    return _axis_angle(q)


def _quat(axis: np.ndarray, angle: float) -> np.ndarray:
    n = np.linalg.norm(axis)
    if n == 0:
        return np.array([1.0, 0, 0, 0])
    s = np.sin(angle / 2) / n
    return np.array([np.cos(angle / 2), axis[0] * s, axis[1] * s, axis[2] * s])


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def _axis_angle(q: np.ndarray) -> np.ndarray:
    w = np.clip(q[0], -1.0, 1.0)
    angle = 2 * np.arccos(w)
    s = np.sqrt(max(1 - w * w, 0.0))
    if s < 1e-12:
        return np.array([0.0, 0.0, 1.0, 0.0])
    return np.r_[q[1:] / s, angle]
