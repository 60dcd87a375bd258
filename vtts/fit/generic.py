"""The generic head a photo is fitted with: a bundled head seen as Candide's control points.

Every bundled head's ``FACE`` is Candide-3 refined by one fixed matrix (Eisert & Girod, Equation
1: ``face = S @ control``), so the head is described by its 96 used control points and Candide's
shape units move it as they move Candide. The fit changes the control points, never the topology:
vertex i of the fitted ``FACE`` is the same point of the face as vertex i of every bundled head.

Where a landmark of the detector lies on the face is a fixed point of ``FACE`` given by three
vertices and barycentric weights (``vtts/data/fit/face_landmarks.tsv``, made by
``models/src/landmark_map.py`` from renderings of the bundled heads), so landmark positions are
linear in the control points: ``landmarks3d = M @ control``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np
import scipy.sparse as sp

from vtts.errors import ModelError
from vtts.face import FaceModel, load_model
from vtts.fit.candide import read_wfm, refined_face
from vtts.resources import package_data

#: The personalities ``adi fit`` can start from (their temporal tables and generic shape).
PERSONALITIES = ("cybatt", "lotta")

#: Candide's inner lip vertices pair up across the midline by lip, not by position (81 = 83 and
#: 82 = 84 in space on a closed mouth).
_TWINS = {81: 82, 82: 81, 83: 84, 84: 83}

#: Where the landmark table lives inside the package.
LANDMARK_TABLE = "fit/face_landmarks.tsv"


@dataclass(frozen=True)
class LandmarkMap:
    """Where each detector landmark lies on ``FACE``.

    landmark   ``(n,)`` detector landmark numbers (MediaPipe's 468-point mesh)
    vertices   ``(n, 3)`` ``FACE`` vertex indices of the triangle it lies in
    weights    ``(n, 3)`` barycentric weights (rows sum to 1)
    group      ``(n,)`` str: ``oval`` (on the face's silhouette: view dependent) or ``inner``
    spread     ``(n,)`` how far the landmark wandered over the views it was mapped from (model
               units): how much to trust it
    """

    landmark: np.ndarray
    vertices: np.ndarray
    weights: np.ndarray
    group: np.ndarray
    spread: np.ndarray

    def matrix(self, n_vertices: int) -> sp.csr_matrix:
        """``(n, n_vertices)``: the landmarks' 3-D points are ``matrix @ face_points``."""
        rows = np.repeat(np.arange(len(self.landmark)), 3)
        return sp.csr_matrix(
            (self.weights.ravel(), (rows, self.vertices.ravel())),
            shape=(len(self.landmark), n_vertices),
        )


@cache
def landmark_map() -> LandmarkMap:
    """The shipped landmark table (see the module docstring)."""
    path = package_data(LANDMARK_TABLE)
    rows = [
        ln.split()
        for ln in path.read_text(encoding="utf-8").splitlines()
        if ln.strip() and not ln.startswith("#")
    ]
    return LandmarkMap(
        landmark=np.array([int(r[0]) for r in rows], dtype=np.int64),
        vertices=np.array([[int(x) for x in r[1:4]] for r in rows], dtype=np.int64),
        weights=np.array([[float(x) for x in r[4:7]] for r in rows]),
        group=np.array([r[7] for r in rows]),
        spread=np.array([float(r[8]) for r in rows]),
    )


@dataclass(frozen=True)
class GenericHead:
    """A bundled head as the fit's starting point.

    model        the bundled :class:`~vtts.face.FaceModel` (its scene, tables, temporal tables)
    used         ``(c,)`` the Candide vertices ``FACE`` is made of (c = 96)
    S            ``(p, c)`` sparse: ``FACE = S @ control`` (p = 5150)
    control      ``(c, 3)`` the head's own control points (model units)
    shape_units  ``(k, c, 3)`` Candide's shape units (displacement per unit), k = 38
    unit_names   ``(k,)`` their names
    laplacian    ``(c, c)`` sparse graph Laplacian of Candide's triangles (smoothness)
    mirror       ``(c,)`` the index of each control point's mirror image across the midline
    """

    model: FaceModel
    used: np.ndarray
    S: sp.csr_matrix
    control: np.ndarray
    shape_units: np.ndarray
    unit_names: tuple[str, ...]
    laplacian: sp.csr_matrix
    mirror: np.ndarray

    @property
    def face(self) -> np.ndarray:
        """``(p, 3)`` the neutral ``FACE`` points."""
        return self.model.neutral_points("FACE")

    def face_points(self, control: np.ndarray) -> np.ndarray:
        """``(p, 3)`` ``FACE`` for control points ``(c, 3)``."""
        return np.asarray(self.S @ control)


@cache
def generic_head(personality: str = "cybatt") -> GenericHead:
    """The bundled head ``personality`` (one of :data:`PERSONALITIES`) as a :class:`GenericHead`."""
    if personality not in PERSONALITIES:
        raise ModelError(
            f"--personality must be one of {', '.join(PERSONALITIES)}, got {personality!r}"
        )
    model = load_model(personality)
    rf = refined_face()
    candide = read_wfm()
    face = model.neutral_points("FACE")
    if face.shape[0] != rf.S.shape[0]:
        raise ModelError(
            f"{personality}: FACE has {face.shape[0]} points, the refined Candide face "
            f"{rf.S.shape[0]}: not a head built on Candide-3"
        )
    used = np.flatnonzero(np.asarray(abs(rf.S).sum(axis=0)).ravel() > 0)
    S = rf.S[:, used].tocsr()
    # the head's own control points: S has full column rank, and the written FACE is S @ control
    # rounded to 1e-5, so least squares recovers them to that rounding
    control = np.stack(
        [sp.linalg.lsqr(S, face[:, k], atol=1e-12, btol=1e-12)[0] for k in range(3)], axis=1
    )
    units = sorted(candide.shape_units)
    shape_units = np.stack([candide.shape_units[u].displacement[used] for u in units])
    # graph Laplacian over Candide's edges between used vertices
    index = {int(v): i for i, v in enumerate(used)}
    edges = set()
    for tri in candide.faces:
        for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
            if int(a) in index and int(b) in index:
                i, j = index[int(a)], index[int(b)]
                edges.add((min(i, j), max(i, j)))
    e = np.array(sorted(edges))
    n = len(used)
    adj = sp.csr_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                        shape=(n, n))  # fmt: skip
    deg = np.asarray(adj.sum(axis=1)).ravel()
    laplacian = (sp.identity(n) - sp.diags(1 / deg) @ adj).tocsr()
    flipped = control * [-1, 1, 1]
    dist = np.linalg.norm(control[:, None, :] - flipped[None, :, :], axis=2)
    mirror = np.argmin(dist, axis=1)
    for a, b in _TWINS.items():  # coincident inner lip contours: position cannot tell
        mirror[index[a]] = index[b]
    return GenericHead(model, used, S, control, shape_units, tuple(units), laplacian, mirror)
