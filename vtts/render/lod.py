"""Fewer triangles where the image cannot show them: a head's meshes simplified for small frames.

On Mesa's software rasterizer a frame costs about the same for every triangle drawn, visible
or not, however few pixels it covers: cybatt has 15,896 triangles over about 18,000 pixels at
352×288, and drawing them is most of a ``vtts say`` frame. At that size most of the face's
triangles are smaller than a pixel, so a mesh with a third of them draws the same image up to
a fraction of a pixel.

The simplification keeps the model's own vertices: it only chooses which triangles over them
are drawn (half-edge collapses, Garland and Heckbert's quadric error metric), so the vertex
buffer, the deformation, the normals (computed on the full mesh) and the texture coordinates
stay the model's, and one animated vertex buffer serves both. Its error is measured in every
pose of a set that spans what the model does (visemes, expressions, the jaw and the eyelids):
a collapse is taken only while the moved vertex stays within the tolerance of every plane it
has absorbed in each pose, so that a cheek flat at rest is simplified and a lip that folds when
it smiles is not. Vertices on an edge of the mesh (the lips' and eyelids' openings, the seams
where texture coordinates or normals split a vertex) never move, so no crack opens.

:func:`progressive_mesh` orders the collapses once per mesh (seconds for a head, see
docs/rendering.md; kept as arrays by :func:`save` and :func:`load`: shipped with the bundled
heads, else in the user's cache, see :func:`vtts.render.renderer.progressive`);
:func:`simplified_faces` then gives the triangles for any tolerance, a prefix of that order,
cheaply enough for every change of view.
"""

from __future__ import annotations

import heapq
import os
from dataclasses import dataclass

import numpy as np

#: A collapse must keep every triangle it changes facing the way it faced (the cosine of the
#: angle between the old and the new normal, in every pose, at least this).
MIN_NORMAL_COSINE = 0.2


@dataclass(frozen=True)
class Collapses:
    """The half-edge collapses of a mesh in the order they were made: ``pairs`` ``(C, 2)
    int32``, vertex ``pairs[k, 0]`` merged into vertex ``pairs[k, 1]``; ``errors`` ``(C,)
    float32``: the largest error (model units) of the mesh after the first ``k + 1`` collapses,
    non-decreasing."""

    pairs: np.ndarray
    errors: np.ndarray


def save(path: str | os.PathLike[str], collapses: Collapses) -> None:
    """Write ``collapses`` to ``path`` as two arrays (``.npz``, no pickles), complete or not at
    all."""
    from vtts.atomic import atomic_path

    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, pairs=collapses.pairs, errors=collapses.errors)


def load(path: str | os.PathLike[str], n_vertices: int) -> Collapses | None:
    """The collapses :func:`save` wrote to ``path``, or None when the file cannot be read or
    does not fit a mesh of ``n_vertices`` (vertex numbers outside it, errors that decrease)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            pairs, errors = data["pairs"], data["errors"]
    except (OSError, ValueError, KeyError):
        return None
    if (
        pairs.dtype == np.int32 and pairs.ndim == 2 and pairs.shape[1] == 2
        and errors.dtype == np.float32 and errors.shape == (len(pairs),)
        and (pairs.size == 0 or (pairs.min() >= 0 and pairs.max() < n_vertices))
        and np.all(np.diff(errors) >= 0)
    ):  # fmt: skip
        return Collapses(pairs, errors)
    return None


def _plane_quadrics(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Each face's plane in each pose as a quadric ``(T, P, 4, 4)`` (the squared distance of a
    point to the plane: ``h Kᵀ h`` for ``h = (x, y, z, 1)``). ``positions`` ``(P, V, 3)``."""
    a, b, c = (positions[:, faces[:, i]] for i in range(3))
    n = np.cross(b - a, c - a)
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    n = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    plane = np.concatenate([n, -np.sum(n * a, axis=-1, keepdims=True)], axis=-1)  # (P, T, 4)
    plane = plane.transpose(1, 0, 2)
    return plane[..., :, None] * plane[..., None, :]


def progressive_mesh(positions: np.ndarray, faces: np.ndarray, *, max_error: float) -> Collapses:
    """The collapses that simplify ``faces`` ``(T, 3)`` over the vertices ``positions``
    ``(P, V, 3)`` (the same vertices in P poses; ``(V, 3)`` for one), cheapest first, until
    the next one would move the surface by more than ``max_error`` (model units) in some pose.

    Only vertices inside the mesh are removed: a vertex on an edge used by one triangle (a
    border: a hole, a seam) or by more than two stays, and a collapse must keep the mesh a
    manifold (the link condition) and no triangle may flip or become degenerate in any pose."""
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim == 2:
        pos = pos[None]
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    n_poses, n_vertices = pos.shape[:2]
    empty = Collapses(np.zeros((0, 2), np.int32), np.zeros(0, np.float32))
    if len(faces) == 0:
        return empty
    homog = np.concatenate([pos, np.ones((n_poses, n_vertices, 1))], axis=-1)  # (P, V, 4)
    face_q = _plane_quadrics(pos, faces)
    quadric = np.zeros((n_vertices, n_poses, 4, 4))
    for i in range(3):
        np.add.at(quadric, faces[:, i], face_q)

    # edges: how many faces use each; vertices on a border or a non-manifold edge stay put
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    uniq, counts = np.unique(edges, axis=0, return_counts=True)
    locked = np.zeros(n_vertices, bool)
    locked[uniq[counts != 2].ravel()] = True
    used = np.zeros(n_vertices, bool)
    used[faces.ravel()] = True

    faces = faces.copy()
    alive = np.ones(len(faces), bool)
    vertex_faces: list[set[int]] = [set() for _ in range(n_vertices)]
    for f, tri in enumerate(faces):
        for v in tri:
            vertex_faces[v].add(f)
    neighbours: list[set[int]] = [set() for _ in range(n_vertices)]
    for a, b in uniq:
        neighbours[a].add(int(b))
        neighbours[b].add(int(a))
    version = np.zeros(n_vertices, np.int64)
    removed = np.zeros(n_vertices, bool)

    def costs(us: np.ndarray, vs: np.ndarray) -> np.ndarray:
        """Squared error of merging each ``us[i]`` into ``vs[i]``: the worst pose's sum of
        squared distances of ``vs[i]`` to the planes ``us[i]`` holds."""
        h = homog[:, vs].transpose(1, 0, 2)  # (E, P, 4)
        return np.einsum("epi,epij,epj->ep", h, quadric[us], h).max(axis=1)

    heap: list[tuple[float, int, int, int]] = []

    def push(us, vs) -> None:
        """Queue the merges of ``us[i]`` into ``vs[i]`` (those of removable vertices)."""
        us = np.asarray(us, dtype=np.int64)
        vs = np.asarray(vs, dtype=np.int64)
        ok = ~(locked[us] | removed[us])
        us, vs = us[ok], vs[ok]
        if us.size == 0:
            return
        for u, v, cost, stamp in zip(
            us.tolist(), vs.tolist(), costs(us, vs).tolist(), version[us].tolist(), strict=True
        ):
            heapq.heappush(heap, (cost, u, v, stamp))

    directed = np.concatenate([uniq, uniq[:, ::-1]])
    push(directed[:, 0], directed[:, 1])

    def valid(u: int, v: int) -> bool:
        shared = [f for f in vertex_faces[u] if v in faces[f]]
        if len(shared) != 2:
            return False
        opposite = {int(w) for f in shared for w in faces[f] if w != u and w != v}
        if neighbours[u] & neighbours[v] != opposite:
            return False  # merging would pinch the mesh (the link condition)
        moved = [f for f in vertex_faces[u] if v not in faces[f]]
        if not moved:
            return False
        tri = faces[moved]
        new = np.where(tri == u, v, tri)
        p = pos[:, tri]
        q = pos[:, new]
        n_old = _cross(p[:, :, 1] - p[:, :, 0], p[:, :, 2] - p[:, :, 0])
        n_new = _cross(q[:, :, 1] - q[:, :, 0], q[:, :, 2] - q[:, :, 0])
        old_len = np.sqrt(np.einsum("...i,...i->...", n_old, n_old))
        new_len = np.sqrt(np.einsum("...i,...i->...", n_new, n_new))
        if np.any(new_len <= 1e-12 * np.maximum(old_len, 1e-300)):
            return False
        cosine = np.einsum("...i,...i->...", n_old, n_new) / np.maximum(old_len * new_len, 1e-300)
        return bool(np.all(cosine >= MIN_NORMAL_COSINE))

    limit = float(max_error) ** 2
    pairs: list[tuple[int, int]] = []
    errors: list[float] = []
    worst = 0.0
    while heap:
        cost, u, v, stamp = heapq.heappop(heap)
        if cost > limit:
            break
        if removed[u] or removed[v] or stamp != version[u] or v not in neighbours[u]:
            continue
        if not valid(u, v):
            continue
        # merge u into v: its triangles around the edge vanish, the others take v
        for f in list(vertex_faces[u]):
            tri = faces[f]
            if v in tri:
                alive[f] = False
                for w in tri:
                    if w != u:
                        vertex_faces[w].discard(f)
            else:
                tri[tri == u] = v
                vertex_faces[v].add(f)
        vertex_faces[u].clear()
        for w in neighbours[u]:
            neighbours[w].discard(u)
            if w != v:
                neighbours[w].add(v)
                neighbours[v].add(w)
        neighbours[u].clear()
        removed[u] = True
        quadric[v] += quadric[u]
        worst = max(worst, float(np.sqrt(max(cost, 0.0))))
        pairs.append((u, v))
        errors.append(worst)
        version[v] += 1
        # v's merges cost more now (its quadric grew); a neighbour's keep their costs (their
        # validity is checked when popped), but the one into v may be new
        ring = list(neighbours[v])
        push([v] * len(ring) + ring, ring + [v] * len(ring))
    if not pairs:
        return empty
    return Collapses(np.asarray(pairs, np.int32), np.asarray(errors, np.float32))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` over the last axis (3), without its checks (this runs for every collapse)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def simplified_faces(faces: np.ndarray, collapses: Collapses, error: float) -> np.ndarray:
    """The triangles ``(T', 3)`` (same dtype as ``faces``) left of ``faces`` ``(T, 3)`` after
    every collapse whose error is within ``error`` (model units): each vertex replaced by the
    one it was merged into, the triangles that lost a corner dropped, the order kept."""
    faces = np.asarray(faces)
    k = int(np.searchsorted(collapses.errors, error, side="right"))
    if k == 0:
        return faces
    n = int(max(faces.max(initial=-1), collapses.pairs[:k].max(initial=-1))) + 1
    target = np.arange(n)
    target[collapses.pairs[:k, 0]] = collapses.pairs[:k, 1]
    while True:  # follow chains of merges to their end
        nxt = target[target]
        if np.array_equal(nxt, target):
            break
        target = nxt
    out = target[faces]
    keep = (out[:, 0] != out[:, 1]) & (out[:, 1] != out[:, 2]) & (out[:, 0] != out[:, 2])
    return out[keep].astype(faces.dtype, copy=False)


def present(ids: np.ndarray, n: int) -> np.ndarray:
    """The distinct values of ``ids`` (whole numbers in ``0..n-1``), ascending: the vertices a
    simplified mesh's triangles use. ``np.unique``'s answer without its look for masked arrays,
    which imports ``numpy.ma`` (a cost at every ``vtts say``'s start-up that
    :mod:`vtts.deferred` puts off)."""
    return np.flatnonzero(np.bincount(ids.ravel(), minlength=n))
