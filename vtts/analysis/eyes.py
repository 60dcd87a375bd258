"""What the eyes show of a head: points of the model whose image positions the iris model
(:mod:`vtts.fit.iris`) observes, as the estimator's geometry predicts them.

**Gaze.** The bundled heads and every head fitted from them model each eye as an eyeball mesh
(``L_EYEBALL``, ``R_EYEBALL``) under two Transforms about the eyeball's centre that FAPs 23–26
turn (``L_EYE_YAW`` 23, ``R_EYE_YAW`` 24, ``L_EYE_PITCH`` 25, ``R_EYE_PITCH`` 26; FAPs 27/28 push
the eyeballs along ``L_EYE``/``R_EYE``). Their MPEG-4 feature points 3.5 (left pupil) and 3.6
(right pupil) are vertex 0 of each eyeball: its front pole, the middle of the iris. The iris
model's iris centre is an observation of that point (:data:`PUPILS`).

**Lids.** FAPs 19–22 close the upper and lower lids by the ``FACE`` mesh's tables. The face
mesh's lid landmarks lie on ``FACE`` where ``vtts/data/fit/face_landmarks.tsv`` puts them
(:func:`vtts.fit.generic.landmark_map`), and there the lid FAPs move them by 90–100 % of their
largest motion (:func:`lid_points` gives each point's motion per unit); the iris model's lid
contour points are the same landmarks (:data:`vtts.fit.iris.CONTOUR_LANDMARKS`), seen more
closely. :data:`LID_LANDMARKS` observes the middle three points of each lid margin; the
difference of the upper and lower rows of one eye is its opening.

Each observed point is a barycentric combination of the estimator's vertices
(:class:`SurfacePoints`); :meth:`SurfacePoints.project` gives where the current estimate puts
them in the image and how they move there per unit of each unknown, through
:meth:`~vtts.analysis.geometry.HeadGeometry.jacobian` and
:func:`~vtts.analysis.landmark_pose.projection_jacobian`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vtts.analysis.landmark_pose import projection_jacobian
from vtts.errors import AnalysisError
from vtts.face import N_PARAMS, FaceModel
from vtts.fit.generic import landmark_map
from vtts.fit.iris import CONTOUR_LANDMARKS, Eyes

#: Each eye's pupil: the MPEG-4 feature point on its eyeball (the subject's right and left).
PUPILS = {"right": "3.6", "left": "3.5"}
#: The FAPs that turn each eyeball: (yaw, pitch).
GAZE_FAPS = {"right": (24, 26), "left": (23, 25)}
#: The FAP that closes each lid: (eye, lid) -> FAP.
LID_FAPS = {("right", "upper"): 20, ("right", "lower"): 22,
            ("left", "upper"): 19, ("left", "lower"): 21}  # fmt: skip
#: The face-mesh landmarks observed on each lid: the middle three of its margin, outer to inner
#: (the middle one is MPEG-4's 3.1–3.4 eyelid point).
LID_LANDMARKS = {
    ("right", "upper"): (160, 159, 158),
    ("right", "lower"): (144, 145, 153),
    ("left", "upper"): (387, 386, 385),
    ("left", "lower"): (373, 374, 380),
}
#: Points of ``FACE`` on every head built on Candide-3 (the bundled heads and every head
#: fitted from them): the topology the landmark table is made for.
FACE_POINTS = 5150


@dataclass(frozen=True)
class LidPoints:
    """Where the lid landmarks lie on a model's ``FACE`` mesh, one row per point.

    eye        ``(n,)`` str ``"right"`` or ``"left"`` (the subject's)
    lid        ``(n,)`` str ``"upper"`` or ``"lower"``
    fap        ``(n,)`` the FAP that closes that lid (:data:`LID_FAPS`)
    landmark   ``(n,)`` the face-mesh landmark observed there
    contour    ``(n,)`` the same point's index in the iris model's eye contour
    vertices   ``(n, 3)`` ``FACE`` point indices of the triangle it lies in
    weights    ``(n, 3)`` barycentric weights (rows sum to 1)
    motion     ``(n, 3)`` how the point moves per unit of its FAP from the neutral face, in
               ``FACE``'s own coordinates (model units; y up): the lids' tables at the point
    """

    eye: np.ndarray
    lid: np.ndarray
    fap: np.ndarray
    landmark: np.ndarray
    contour: np.ndarray
    vertices: np.ndarray
    weights: np.ndarray
    motion: np.ndarray


def lid_points(model: FaceModel) -> LidPoints | None:
    """The points of :data:`LID_LANDMARKS` on ``model``'s ``FACE``; None when the model has no
    animated IndexedFaceSet ``FACE`` of :data:`FACE_POINTS` points (a head not built on
    Candide-3, where the landmark table does not apply)."""
    engine = model.engine
    if "FACE" not in engine.meshes or engine.meshes["FACE"].neutral.shape[0] != FACE_POINTS:
        return None
    table = landmark_map()
    row = {int(lm): i for i, lm in enumerate(table.landmark)}
    rows = []
    for (eye, lid), landmarks in LID_LANDMARKS.items():
        contour = CONTOUR_LANDMARKS[eye]
        for lm in landmarks:
            rows.append((eye, lid, LID_FAPS[eye, lid], lm, contour.index(lm), row[lm]))
    at = np.array([r[5] for r in rows])
    vertices = table.vertices[at]
    weights = table.weights[at]
    faps = np.array([r[2] for r in rows])
    motion = np.zeros((len(rows), 3))
    neutral = engine.points(np.zeros(N_PARAMS))["FACE"]
    for fap in np.unique(faps):
        params = np.zeros(N_PARAMS)
        params[fap - 1] = 1.0
        moved = engine.points(params)["FACE"] - neutral
        mine = faps == fap
        motion[mine] = np.einsum("nk,nkd->nd", weights[mine], moved[vertices[mine]])
    return LidPoints(
        eye=np.array([r[0] for r in rows]),
        lid=np.array([r[1] for r in rows]),
        fap=faps,
        landmark=np.array([r[3] for r in rows]),
        contour=np.array([r[4] for r in rows]),
        vertices=vertices,
        weights=weights,
        motion=motion,
    )


@dataclass(frozen=True)
class SurfacePoints:
    """Points on the model's surface as an estimator sees them: each a barycentric combination
    of the estimator's vertices (indices into ``geometry.positions``).

    names      ``(n,)`` str, what each point is (``"pupil right"``, ``"upper right 159"``)
    vertices   ``(n, 3)`` estimator vertex indices
    weights    ``(n, 3)`` their weights (rows sum to 1)
    """

    names: tuple[str, ...]
    vertices: np.ndarray
    weights: np.ndarray

    def __len__(self) -> int:
        return len(self.names)

    def positions(self, geometry, params: np.ndarray, translation: np.ndarray) -> np.ndarray:
        """``(n, 3)`` world positions for ``params`` and the head ``translation``."""
        points = geometry.positions_of(params, translation, self.vertices)
        return np.einsum("nk,nkd->nd", self.weights, points)

    def motion(self, geometry, params: np.ndarray, translation: np.ndarray) -> np.ndarray:
        """``(n, 3, K)`` world motion per unit of each of ``geometry``'s unknowns."""
        n = len(self.names)
        jac = geometry.jacobian(params, translation, self.vertices.reshape(-1))
        return np.einsum("nk,nkdu->ndu", self.weights, jac.reshape(n, 3, 3, -1))

    def project(self, estimator) -> tuple[np.ndarray, np.ndarray]:
        """Where ``estimator``'s current estimate puts the points in its camera's image ``(n, 2)``
        (pixels), and how they move there per unit of each unknown ``(2n, K)`` (rows x0, y0,
        x1, …; the columns of ``estimator.unknowns``)."""
        geometry, params, translation = estimator.geometry, estimator.params, estimator.translation
        if not len(self):
            return np.zeros((0, 2)), np.zeros((0, len(estimator.unknowns)))
        return projection_jacobian(
            self.positions(geometry, params, translation),
            self.motion(geometry, params, translation),
            estimator.camera,
        )


@dataclass(frozen=True)
class EyePoints:
    """The points of a head the eyes observe (:func:`eye_points`).

    pupils     the pupils the model defines (names ``"pupil right"``, ``"pupil left"``)
    lids       the lid points (:data:`LID_LANDMARKS`; empty for a head not built on Candide-3)
    lid_rows   where on the model each lid point lies (:class:`LidPoints`), or None
    """

    pupils: SurfacePoints
    lids: SurfacePoints
    lid_rows: LidPoints | None

    def targets(self, eyes: Eyes) -> tuple[np.ndarray, np.ndarray]:
        """Where ``eyes`` (the iris model's) put the pupils ``(p, 2)`` and the lid points
        ``(l, 2)``, in the order of :attr:`pupils` and :attr:`lids` (image pixels)."""
        by_eye = dict(eyes)
        pupils = np.array([by_eye[n.split()[1]].centre for n in self.pupils.names]).reshape(-1, 2)
        if self.lid_rows is None:
            return pupils, np.zeros((0, 2))
        rows = zip(self.lid_rows.eye, self.lid_rows.contour, strict=True)
        lids = np.array([by_eye[e].contour[c, :2] for e, c in rows]).reshape(-1, 2)
        return pupils, lids

    def lid_normals(self, eyes: Eyes) -> np.ndarray:
        """``(l, 2)`` for each lid point, the unit image direction across its eye (perpendicular
        to the line between the eye's corners, pointing from the upper lid to the lower): the
        direction in which a lid point is observed. Along the lid the iris model's contour
        points are not the same points of the lid as the face mesh's landmarks (they lie up to
        a tenth of the eye's width apart there), so only the lid's position across the eye, or
        the difference of an upper and a lower row (the opening), is an observation."""
        if self.lid_rows is None:
            return np.zeros((0, 2))
        normals = {}
        for name, eye in eyes:
            outer, inner = eye.contour[0, :2], eye.contour[8, :2]
            along = (inner - outer) if name == "right" else (outer - inner)  # image x, roughly
            along = along / max(float(np.linalg.norm(along)), 1e-9)
            normals[name] = np.array([-along[1], along[0]])  # image y, roughly: down
        return np.array([normals[e] for e in self.lid_rows.eye]).reshape(-1, 2)


def mesh_vertex(geometry, node: str, point: int) -> int | None:
    """The estimator's vertex index of point ``point`` of the IndexedFaceSet named ``node``
    (its Coordinate index), or None where the geometry has no such point."""
    for shape in geometry.shapes:
        if shape.node.name == node:
            hits = np.flatnonzero(shape.mesh.coord_index == point)
            if hits.size:
                return shape.first_vertex + int(hits[0])
    return None


def pupil_vertices(geometry, feature_points: dict[str, tuple[str, int]]) -> dict[str, int]:
    """``{"right": vertex, "left": vertex}``: the estimator's vertex index (into
    ``geometry.positions``) of each pupil the model defines (``feature_points``: the tables'
    MPEG-4 feature points, name -> (IndexedFaceSet, point))."""
    out = {}
    for eye, point in PUPILS.items():
        if point in feature_points:
            vertex = mesh_vertex(geometry, *feature_points[point])
            if vertex is not None:
                out[eye] = vertex
    return out


def eye_points(estimator) -> EyePoints:
    """The pupils and lid points of ``estimator``'s model as its geometry's vertices."""
    geometry, model = estimator.geometry, estimator.model
    pupils = pupil_vertices(geometry, model.tables.feature_points)
    pupil_points = SurfacePoints(
        tuple(f"pupil {eye}" for eye in pupils),
        np.array([[v, v, v] for v in pupils.values()], dtype=np.int64).reshape(-1, 3),
        np.tile([1.0, 0.0, 0.0], (len(pupils), 1)),
    )
    rows = lid_points(model)
    face = next((s for s in geometry.shapes if s.node.name == "FACE"), None)
    if rows is None or face is None:
        empty = SurfacePoints((), np.zeros((0, 3), np.int64), np.zeros((0, 3)))
        return EyePoints(pupil_points, empty, None)
    first = np.full(FACE_POINTS, -1, dtype=np.int64)  # FACE point -> its first vertex
    corners = face.mesh.coord_index
    order = np.arange(len(corners))[::-1]  # the first hit of each point written last
    first[corners[order]] = order
    if (first[rows.vertices] < 0).any():
        raise AnalysisError(
            f"the model {model.name}: FACE points under the lid landmarks are in no triangle"
        )
    vertices = first[rows.vertices] + face.first_vertex
    names = tuple(f"{lid} {eye} {lm}" for eye, lid, lm in zip(rows.eye, rows.lid, rows.landmark,
                                                              strict=True))  # fmt: skip
    return EyePoints(pupil_points, SurfacePoints(names, vertices, rows.weights.copy()), rows)
