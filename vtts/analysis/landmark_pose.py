"""The head's pose from facial landmarks: where the estimator starts on a real video.

Analysis by synthesis refines a pose it is given; on a camera video nobody gives it one. The
landmarks of the face (:mod:`vtts.fit.landmarks`, MediaPipe's 468-point mesh) at the MPEG-4
feature points a model defines that move little with the face's own FAPs (pupils 3.5/3.6, the
nose 9.15, the outer lip middles 8.1/8.2 and corners 8.3/8.4, the chin 2.1) say where those
points are in the image; :func:`landmark_pose` finds the head rotation (FAPs 48–50) and
translation (``tx``, ``ty``, ``tz``) that project the model's feature points there, by
Gauss–Newton on the reprojection error with the estimator's own geometry and camera, the
rotation held near where it started (:data:`ROTATION_SIGMA`). The estimator uses it for the
first frame of a given model and to re-initialize a track that was lost.
"""

from __future__ import annotations

import numpy as np

from vtts.analysis.result import TRANSLATION
from vtts.errors import AnalysisError

#: MPEG-4 feature point → the MediaPipe face-mesh landmarks whose mean lies on it (the face's
#: own left and right: 3.5 is the left pupil, MediaPipe's "left eye" is the subject's left).
FEATURE_LANDMARKS: dict[str, tuple[int, ...]] = {
    "3.5": (263, 362, 386, 374),  # left pupil: the eye's corners and lid midpoints
    "3.6": (33, 133, 159, 145),  # right pupil
    "9.15": (2,),  # bottom of the nose, middle
    "8.3": (291,),  # left mouth corner
    "8.4": (61,),  # right mouth corner
    "8.1": (0,),  # upper lip, outer middle
    "8.2": (17,),  # lower lip, outer middle
    "2.1": (152,),  # chin
}

#: The unknowns the landmarks decide: head rotation and translation.
POSE_UNKNOWNS: tuple[int | str, ...] = (48, 49, 50, *TRANSLATION)

#: Fewest feature points with landmarks needed to place a head.
MIN_POINTS = 4

#: How far (AU) a head rotation may move from where it started at the cost of one pixel of
#: reprojection error: the feature points lie nearly in a plane, and a head pitched about the
#: neck and moved back projects them almost as one that did neither, so the landmarks alone
#: leave the rotation loose by several degrees.
ROTATION_SIGMA = 2000.0


def feature_vertices(geometry, feature_points: dict[str, tuple[str, int]]) -> dict[str, int]:
    """The estimator's vertex index (into ``geometry.positions``) of each feature point the
    model defines and :data:`FEATURE_LANDMARKS` has landmarks for."""
    by_name = {s.node.name: s for s in geometry.shapes if s.node.name}
    out = {}
    for point, (node, vertex) in feature_points.items():
        shape = by_name.get(node)
        if point not in FEATURE_LANDMARKS or shape is None:
            continue
        hits = np.flatnonzero(shape.mesh.coord_index == vertex)
        if hits.size:
            out[point] = shape.first_vertex + int(hits[0])
    return out


def project(points: np.ndarray, camera) -> tuple[np.ndarray, np.ndarray]:
    """``points`` ``(n, 3)`` (world) in ``camera``'s image ``(n, 2)`` pixels (x right, y down;
    a pixel's centre at +0.5), and their coordinates in the camera's frame ``(n, 3)``."""
    pose = np.asarray(camera.pose, np.float64)
    pc = (points - pose[:3, 3]) @ pose[:3, :3]
    d = -pc[:, 2]
    xy = np.stack([camera.cx + camera.fx * pc[:, 0] / d, camera.cy - camera.fy * pc[:, 1] / d], 1)
    return xy, pc


def projection_jacobian(
    points: np.ndarray, motion: np.ndarray, camera
) -> tuple[np.ndarray, np.ndarray]:
    """Where ``points`` ``(n, 3)`` (world) fall in ``camera``'s image ``(n, 2)``, and how they
    move there per unit of each unknown ``(2n, K)`` (rows x0, y0, x1, …), given their world
    motion ``motion`` ``(n, 3, K)`` (:meth:`HeadGeometry.jacobian`)."""
    xy, pc = project(points, camera)
    local = np.einsum("ab,nbk->nak", np.asarray(camera.pose)[:3, :3].T, motion)
    d = -pc[:, 2:3]
    dx = camera.fx * (local[:, 0] / d + pc[:, 0:1] * local[:, 2] / d**2)
    dy = -camera.fy * (local[:, 1] / d + pc[:, 1:2] * local[:, 2] / d**2)
    return xy, np.stack([dx, dy], 1).reshape(-1, motion.shape[2])


def _targets(estimator, landmarks: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """The estimator's vertex indices ``(n,)`` of the model's feature points that have
    landmarks, where the ``landmarks`` put them ``(n, 2)``, and n."""
    vertices = feature_vertices(estimator.geometry, estimator.model.tables.feature_points)
    names = sorted(vertices)
    index = np.array([vertices[p] for p in names], dtype=np.int64)
    target = np.array([landmarks[list(FEATURE_LANDMARKS[p]), :2].mean(0) for p in names])
    return index, target.reshape(-1, 2), len(names)


def placement_error(estimator, landmarks: np.ndarray) -> float | None:
    """The median distance (pixels) between where ``estimator``'s current estimate puts the
    model's feature points and the ``landmarks`` ``(468, ≥2)``; None when the model defines
    fewer than :data:`MIN_POINTS` of them."""
    index, target, n = _targets(estimator, landmarks)
    if n < MIN_POINTS:
        return None
    positions = estimator.geometry.positions(estimator.params, estimator.translation)
    xy, _ = project(positions[index], estimator.camera)
    return float(np.median(np.linalg.norm(xy - target, axis=1)))


def landmark_pose(estimator, landmarks: np.ndarray, iterations: int = 30) -> float:
    """Set ``estimator``'s head rotation and translation (those of :data:`POSE_UNKNOWNS` it
    estimates) so that the model's feature points project onto ``landmarks`` ``(468, ≥2)``
    (image pixels). The face's other parameters are kept. Returns the remaining median
    reprojection error (pixels). Raises :class:`~vtts.errors.AnalysisError` when the model has
    too few feature points or no pose unknowns."""
    geometry = estimator.geometry
    index, target, n = _targets(estimator, landmarks)
    if n < MIN_POINTS:
        raise AnalysisError(
            f"the model {estimator.model.name} defines {n} of the feature points "
            f"that place a head from landmarks ({', '.join(FEATURE_LANDMARKS)}); it needs "
            f"{MIN_POINTS}"
        )
    columns = [k for k, u in enumerate(estimator.unknowns) if u in POSE_UNKNOWNS]
    if not columns:
        raise AnalysisError("no head rotation or translation among the unknowns to place")
    camera = estimator.camera
    rotations = [k for k in columns if not isinstance(estimator.unknowns[k], str)]
    start = estimator.params.copy()

    def prior() -> np.ndarray:  # (len(columns),) in pixels; 0 for the translations
        out = np.zeros(len(columns))
        for j, k in enumerate(columns):
            if k in rotations:
                u = estimator.unknowns[k]
                out[j] = (estimator.params[u - 1] - start[u - 1]) / ROTATION_SIGMA
        return out

    def cost() -> float:
        return _reprojection(estimator, index, target, camera) + float(prior() @ prior())

    damping = 1e-3
    error = cost()
    weights = np.array([1.0 / ROTATION_SIGMA if k in rotations else 0.0 for k in columns])
    for _ in range(iterations):
        params, translation = estimator.params, estimator.translation
        world = geometry.jacobian(params, translation, index)[:, :, columns]  # (n, 3, k)
        points = geometry.positions(params, translation)[index]
        xy, image = projection_jacobian(points, world, camera)
        residual = np.concatenate([(target - xy).reshape(-1), -prior()])
        jac = np.vstack([image, np.diag(weights)])
        scale = np.linalg.norm(jac, axis=0)
        scale[scale == 0] = 1.0
        js = jac / scale
        ata = js.T @ js
        step = np.linalg.solve(ata + damping * np.diag(np.diag(ata) + 1e-9), js.T @ residual)
        step /= scale
        kept = params.copy(), translation.copy()
        _apply(estimator, columns, step)
        new = cost()
        if new < error:
            converged = error - new < 1e-4 * error
            error, damping = new, max(damping / 10, 1e-7)
            if converged:
                break
        else:
            estimator.params[:], estimator.translation[:] = kept
            damping *= 10
            if damping > 1e6:
                break
    return placement_error(estimator, landmarks)  # type: ignore[return-value]


def _reprojection(estimator, index: np.ndarray, target: np.ndarray, camera) -> float:
    xy, pc = project(
        estimator.geometry.positions(estimator.params, estimator.translation)[index], camera
    )
    if (pc[:, 2] >= 0).any():
        return float("inf")  # behind the camera
    return float(((xy - target) ** 2).sum())


def _apply(estimator, columns: list[int], step: np.ndarray) -> None:
    for k, value in zip(columns, step, strict=True):
        u = estimator.unknowns[k]
        if isinstance(u, str):
            estimator.translation[TRANSLATION.index(u)] += value
        else:
            estimator.params[u - 1] += value
