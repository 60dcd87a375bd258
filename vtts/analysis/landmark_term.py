"""Landmarks every frame: the face mesh's points as absolute observations in the least squares.

Analysis by synthesis sees only how the rendered model differs from the camera frame, which says
how to move from where the estimate is, never where the face is: errors the photometric match
cannot see (a slow slide of the head across a smooth cheek, a turn traded against a shift) add
up from frame to frame until the track is lost. The face mesh model (:mod:`vtts.fit.landmarks`)
says where the face is in every frame. Each of its landmarks lies at a fixed point of the
model's mesh (:func:`landmark_points`: the fitted and bundled heads' ``FACE`` by the shipped
landmark table, :func:`vtts.fit.generic.landmark_map`; any other model by its MPEG-4 feature
points), so its reprojection through the estimate is a residual in pixels, linear in the
unknowns' change by the same Jacobian the photometric terms use (Equations 14–15 on the
vertices' motion, :meth:`HeadGeometry.jacobian`). :class:`LandmarkSystem` adds these residuals
to a solve's normal equations beside the paper's optical-flow terms.

Weights. A landmark ``l`` whose position the mesh model gives to within σ_l pixels enters with
weight ``weight / σ_l²`` in the units of the photometric rows (gray levels² per pixel of the
frame): ``weight`` (:data:`LANDMARK_WEIGHT`) is how many gray levels² of one pixel's photometric
residual a landmark one σ off is worth. σ_l combines the model's own scatter (a share of its
crop, :data:`CROP_SIGMA`) with how well the landmark is known to sit on the mesh (the table's
``spread``, model units, seen at the landmark's depth). Landmarks on the face's outline
(the table's ``oval`` group: the silhouette moves over the surface as the head turns) are left
out. A landmark whose residual is beyond :data:`HUBER` σ weighs less, as Huber's M-estimator has
it: a hand over the mouth or a model that does not fit there pulls with a bounded force.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vtts.analysis.landmark_pose import FEATURE_LANDMARKS, feature_vertices, projection_jacobian
from vtts.analysis.result import TRANSLATION
from vtts.fit.landmarks import (
    CROP_SCALE,
    LEFT_EYE,
    LEFT_EYEBROW,
    LIPS_INNER,
    LIPS_OUTER,
    MESH_SIZE,
    RIGHT_EYE,
    RIGHT_EYEBROW,
)

#: The landmarks observed on a mapped ``FACE``: the eyes' and brows' contours, the inner and
#: outer lips, the nose's ridge and base, the cheeks and the chin above the jaw's outline — the
#: face's features, which its FAPs move, and the rigid parts that fix the pose. The face mesh's
#: 468 are dense and their errors correlated; these cost a quarter of the time.
OBSERVED: tuple[int, ...] = (
    *RIGHT_EYE, *LEFT_EYE, *RIGHT_EYEBROW, *LEFT_EYEBROW, *LIPS_OUTER, *LIPS_INNER,
    1, 2, 4, 5, 6, 8, 9, 98, 168, 195, 197, 327,  # nose: ridge, tip, base
    36, 50, 117, 205, 266, 280, 346, 425,  # cheeks
    175, 199, 200,  # chin
)  # fmt: skip
#: The face mesh's landmarks on the lids (the eyes' contours but their corners): with the iris
#: model's eyes, the lids are observed from those instead (:func:`eye_rows`).
EYE_LIDS: tuple[int, ...] = tuple(
    i for i in (*RIGHT_EYE, *LEFT_EYE) if i not in (33, 133, 362, 263)
)
#: The iris model's input side (pixels).
IRIS_SIZE = 64
#: The face mesh model's landmark count.
N_LANDMARKS = 468
#: How many gray levels² of one full-size pixel's photometric residual a landmark one σ off
#: outweighs (see the module docstring).
LANDMARK_WEIGHT = 400.0
#: The face mesh model's scatter (σ, pixels of its 192-pixel crop).
CROP_SIGMA = 1.0
#: Residuals beyond this many σ weigh less (Huber).
HUBER = 3.0


@dataclass(frozen=True)
class LandmarkPoints:
    """Where detector landmarks lie on a model, as the estimator's vertices.

    targets    ``(n, 468)`` each observation's landmark as the mean of detector landmarks (one
               landmark each for a mapped ``FACE``; the feature points' landmark groups else)
    vertices   ``(n, 3)`` estimator vertex indices (into ``HeadGeometry.positions``)
    weights    ``(n, 3)`` barycentric weights (rows sum to 1)
    spread     ``(n,)`` how well each is known to sit there (model units)
    landmark   ``(n,)`` the detector landmark of each (a mapped ``FACE``), or None
    """

    targets: np.ndarray
    vertices: np.ndarray
    weights: np.ndarray
    spread: np.ndarray
    landmark: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.vertices)


def landmark_points(geometry, feature_points: dict[str, tuple[str, int]]) -> LandmarkPoints:
    """The observations a model offers: a ``FACE`` built on Candide-3 (every bundled and fitted
    head) by the shipped landmark table, those of :data:`OBSERVED`; any other model by the
    MPEG-4 feature points it defines (:data:`~vtts.analysis.landmark_pose.FEATURE_LANDMARKS`)."""
    from vtts.fit.generic import landmark_map

    table = landmark_map()
    face = next((s for s in geometry.shapes if s.node.name == "FACE"), None)
    corner: np.ndarray | None = None
    if face is not None and int(face.mesh.coord_index.max()) + 1 > int(table.vertices.max()):
        # the estimator's vertex of each FACE point: its first corner
        order = np.argsort(face.mesh.coord_index, kind="stable")
        firsts = np.searchsorted(face.mesh.coord_index[order], np.arange(table.vertices.max() + 1))
        corner = face.first_vertex + order[firsts]
    if corner is not None:
        keep = (table.group != "oval") & np.isin(table.landmark, OBSERVED)
        n = int(keep.sum())
        targets = np.zeros((n, N_LANDMARKS))
        targets[np.arange(n), table.landmark[keep]] = 1.0
        return LandmarkPoints(targets, corner[table.vertices[keep]], table.weights[keep],
                              table.spread[keep], table.landmark[keep])  # fmt: skip
    found = feature_vertices(geometry, feature_points)
    names = sorted(found)
    targets = np.zeros((len(names), N_LANDMARKS))
    for i, name in enumerate(names):
        group = list(FEATURE_LANDMARKS[name])
        targets[i, group] = 1.0 / len(group)
    vertices = np.array([[found[p]] * 3 for p in names], dtype=np.int64).reshape(-1, 3)
    weights = np.tile([1.0, 0.0, 0.0], (len(names), 1))
    return LandmarkPoints(targets, vertices, weights, np.zeros(len(names)))


@dataclass
class LandmarkSystem:
    """One frame's observations, linearized where the estimate was when they were asked for.

    xy0        ``(n, 2)`` where the model puts the observed points at ``values0`` (pixels)
    jacobian   ``(2n, K)`` their image motion per unit of each unknown (rows x0, y0, x1, …)
    target     ``(n, 2)`` where the landmarks put them (pixels)
    sigma      ``(n,)`` each observation's σ (pixels)
    values0    ``(K,)`` the unknowns' values at the linearization
    across     ``(n, 2)`` for an observation of one direction only, that unit direction (an
               eyelid point seen across its eye); zeros for one of both
    weight     :data:`LANDMARK_WEIGHT`
    """

    xy0: np.ndarray
    jacobian: np.ndarray
    target: np.ndarray
    sigma: np.ndarray
    values0: np.ndarray
    across: np.ndarray | None = None
    weight: float = LANDMARK_WEIGHT

    def __post_init__(self) -> None:
        n = len(self.xy0)
        if self.across is None:
            self.across = np.zeros((n, 2))
        # each observation's 2x2 projection: the identity, or onto its one direction
        one = np.einsum("na,nb->nab", self.across, self.across)
        both = np.linalg.norm(self.across, axis=1) == 0
        one[both] = np.eye(2)
        self._project = one

    def residual(self, values: np.ndarray) -> np.ndarray:
        """``(n, 2)`` target minus where the points lie at the unknowns' ``values`` ``(K,)``
        (moved linearly from the linearization), projected onto the directions observed."""
        moved = self.xy0 + (self.jacobian @ (values - self.values0)).reshape(-1, 2)
        return np.einsum("nab,nb->na", self._project, self.target - moved)

    def moved(self, values: np.ndarray) -> float:
        """How far (pixels) the unknowns' ``values`` ``(K,)`` move the points from the
        linearization: the most any moves."""
        return self.shift(values - self.values0)

    def shift(self, change: np.ndarray) -> float:
        """How far (pixels) a ``change`` ``(K,)`` of the unknowns moves the points (linearly):
        the most any moves."""
        return largest_move(self.jacobian, change)

    def error(self, values: np.ndarray) -> float:
        """The median distance (pixels) between the points and their landmarks."""
        return float(np.median(np.linalg.norm(self.residual(values), axis=1)))

    def _weights(self, r: np.ndarray) -> np.ndarray:
        """Each observation's weight ``(n,)`` at residuals ``r`` ``(n, 2)`` (Huber's beyond
        :data:`HUBER` σ)."""
        distance = np.linalg.norm(r, axis=1) / self.sigma
        return self.weight * np.minimum(1.0, HUBER / np.maximum(distance, 1e-12)) / self.sigma**2

    def total_weight(self) -> float:
        """The observations' weights summed at the linearization (per pixel²)."""
        return float(self._weights(self.residual(self.values0)).sum())

    def cost(self, values: np.ndarray, factor: float = 1.0, density: float = 1.0) -> float:
        """The term's weighted sum of squares at the unknowns' ``values`` in the units of
        :meth:`normal_equations`."""
        r = self.residual(values)
        return float(density * (self._weights(r) * (r * r).sum(1)).sum()) / factor**2

    def normal_equations(
        self, values: np.ndarray, factor: float = 1.0, density: float = 1.0,
        held: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """The term's ``(JᵀWJ, JᵀWr)`` ``(K, K)``, ``(K,)`` at the unknowns' ``values``, in the
        units of a solve on a pyramid level of ``factor`` (its pixels ``factor`` full-size
        ones) with ``density`` photometric rows per pixel (the tracking mode's samples, every
        second pixel each way: a quarter); ``held`` ``(K,)`` bool columns are left out."""
        r = self.residual(values)
        w = density * self._weights(r)
        jac = self.jacobian.reshape(len(r), 2, -1) / factor
        if held is not None and held.any():
            jac = jac.copy()
            jac[:, :, held] = 0.0
        seen = np.einsum("nab,nbk->nak", self._project, jac) * w[:, None, None]
        ata = np.einsum("nak,nal->kl", jac, seen)
        atb = np.einsum("nak,na->k", seen, r / factor)
        return ata, atb


@dataclass(frozen=True)
class Projection:
    """Where a model's observed points lie in the image, linearized at the unknowns'
    ``values0`` ``(K,)``: ``xy0`` ``(n, 2)`` pixels and ``jacobian`` ``(2n, K)`` as in
    :class:`LandmarkSystem`; ``spread_px`` ``(n,)`` each landmark's spread seen at its depth
    (pixels; 0 for the eyes' points); ``eyes``: whether the rows are the face mesh's without its
    lid landmarks followed by the eyes' (:func:`eye_rows`), else the face mesh's alone."""

    xy0: np.ndarray
    jacobian: np.ndarray
    values0: np.ndarray
    spread_px: np.ndarray
    eyes: bool

    def moved(self, values: np.ndarray) -> float:
        """How far (pixels) the unknowns' ``values`` move the points from the linearization."""
        return largest_move(self.jacobian, values - self.values0)


def largest_move(jacobian: np.ndarray, change: np.ndarray) -> float:
    """How far (pixels) the points whose image motion is ``jacobian`` ``(2n, K)`` move for a
    ``change`` ``(K,)`` of the unknowns: the most any moves."""
    step = (jacobian @ change).reshape(-1, 2)
    return float(np.sqrt((step * step).sum(1).max(initial=0.0)))


def project_points(estimator, points: LandmarkPoints, values: np.ndarray,
                   eye_points=None) -> Projection:  # fmt: skip
    """The :class:`Projection` of ``points`` at ``estimator``'s current parameters (the
    unknowns' ``values`` ``(K,)``); with the model's ``eye_points``
    (:func:`vtts.analysis.eyes.eye_points`), the face mesh's lid landmarks left out and the
    pupils and lid points added."""
    keep = _kept(points, eye_points is not None)
    xy, jac, world = _project(estimator, points.vertices[keep], points.weights[keep])
    depth = _depth(estimator, world)
    spread_px = points.spread[keep] * estimator.camera.fx / np.maximum(depth, 1e-9)
    if eye_points is not None:
        xy_p, jac_p = eye_points.pupils.project(estimator)
        xy_l, jac_l = eye_points.lids.project(estimator)
        xy = np.concatenate([xy, xy_p, xy_l])
        jac = np.concatenate([jac, jac_p, jac_l])
        spread_px = np.concatenate([spread_px, np.zeros(len(xy_p) + len(xy_l))])
    values0 = np.asarray(values, np.float64).copy()
    return Projection(xy, jac, values0, spread_px, eye_points is not None)


def observed(projection: Projection, points: LandmarkPoints, landmarks: np.ndarray,
             crop_size: float, eyes=None, eye_points=None) -> LandmarkSystem:  # fmt: skip
    """One frame's :class:`LandmarkSystem` on ``projection``: the detector's ``landmarks``
    ``(468, ≥2)`` image pixels, found in a crop of ``crop_size`` pixels; with the iris model's
    ``eyes`` (:class:`~vtts.fit.iris.Eyes` in the same pixels; ``projection`` made with the
    model's ``eye_points``), the pupils and the lids across the eyes (:func:`eye_rows`)."""
    keep = _kept(points, projection.eyes)
    target = points.targets[keep] @ np.asarray(landmarks, np.float64)[:, :2]
    n = len(target)
    crop_px = CROP_SIGMA * crop_size / MESH_SIZE
    sigma = np.sqrt(crop_px**2 + projection.spread_px[:n] ** 2)
    across = np.zeros((n, 2))
    if projection.eyes:
        rows = eye_rows(eye_points, eyes)
        target = np.concatenate([target, rows[0]])
        sigma = np.concatenate([sigma, rows[1]])
        across = np.concatenate([across, rows[2]])
    return LandmarkSystem(projection.xy0, projection.jacobian, target, sigma, projection.values0,
                          across)  # fmt: skip


def linearize(estimator, points: LandmarkPoints, landmarks: np.ndarray, crop_size: float,
              values: np.ndarray, eyes=None, eye_points=None) -> LandmarkSystem:  # fmt: skip
    """The observations' term of ``estimator`` linearized at its current parameters (the
    unknowns' ``values`` ``(K,)``): :func:`project_points`, then :func:`observed`."""
    both = eyes is not None and eye_points is not None
    projection = project_points(estimator, points, values, eye_points if both else None)
    return observed(projection, points, landmarks, crop_size, eyes, eye_points)


def _kept(points: LandmarkPoints, eyes: bool) -> np.ndarray:
    """Which of ``points`` are observed: all, or without the lids' when the eyes are."""
    if eyes and points.landmark is not None:
        return ~np.isin(points.landmark, EYE_LIDS)
    return np.ones(len(points), dtype=bool)


def eye_rows(points, eyes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The eyes' observations (:mod:`vtts.analysis.eyes`) of the model's ``points``
    (:func:`vtts.analysis.eyes.eye_points`: its pupils, then its lid points) by the iris
    model's ``eyes``: each pupil where the iris centre is, its σ grown as the lids hide the
    iris (σ / √visible), and each lid point where the lid contour crosses it, across the eye
    only. Returns ``target (m, 2)`` pixels, ``sigma (m,)`` and ``across (m, 2)``."""
    pupils, lids = points.targets(eyes)
    by_eye = dict(eyes)
    crop = {name: CROP_SIGMA * eye.crop.size / IRIS_SIZE for name, eye in eyes}
    seen = [max(by_eye[n.split()[1]].visible, 1e-3) for n in points.pupils.names]
    sigma_p = np.array([crop[n.split()[1]] for n in points.pupils.names]) / np.sqrt(seen)
    sigma_l = np.array([crop[n.split()[1]] for n in points.lids.names])
    return (
        np.concatenate([pupils, lids]).reshape(-1, 2),
        np.concatenate([sigma_p, sigma_l]).reshape(-1),
        np.concatenate([np.zeros((len(pupils), 2)), points.lid_normals(eyes)]).reshape(-1, 2),
    )


def _project(estimator, vertices: np.ndarray, weights: np.ndarray):
    """Where points given as barycentric combinations of the estimator's ``vertices`` ``(n,
    3)`` (``weights`` ``(n, 3)``) lie in its image ``(n, 2)``, their image motion per unit
    of each unknown ``(2n, K)``, and where they lie in the world ``(n, 3)``."""
    geometry = estimator.geometry
    params, translation = estimator.params, estimator.translation
    uniq, inverse = np.unique(vertices, return_inverse=True)
    inverse = inverse.reshape(vertices.shape)
    world = geometry.positions_of(params, translation, uniq)
    motion = geometry.jacobian(params, translation, uniq)  # (U, 3, K)
    p = np.einsum("nm,nma->na", weights, world[inverse])
    dp = np.einsum("nm,nmak->nak", weights, motion[inverse])
    return (*projection_jacobian(p, dp, estimator.camera), p)


def _depth(estimator, p: np.ndarray) -> np.ndarray:
    """``(n,)`` the world points ``p`` ``(n, 3)``' distance from ``estimator``'s camera along
    its axis (model units)."""
    pose = np.asarray(estimator.camera.pose)
    return np.abs((p - pose[:3, 3]) @ pose[:3, 2])


def crop_side(face) -> float:
    """The side (pixels) of the crop the mesh model saw ``face`` (a
    :class:`~vtts.fit.landmarks.Face`) in: :data:`~vtts.fit.landmarks.CROP_SCALE` times its
    landmarks' extent."""
    xy = np.asarray(face.landmarks, np.float64)[:, :2]
    return CROP_SCALE * float(np.ptp(xy, axis=0).max())


def unknown_values(estimator) -> np.ndarray:
    """The unknowns' current values ``(K,)`` (FAP units, model units of the translation)."""
    return np.array([
        estimator.translation[TRANSLATION.index(u)] if isinstance(u, str)
        else estimator.params[u - 1]
        for u in estimator.unknowns
    ])  # fmt: skip
