"""Fitting the generic head's shape and pose to a photo's landmarks.

Unknowns: the head's pose in the photo's camera (a rotation and a translation), Candide's shape
units ``alpha`` and a per-control-point refinement ``delta``; the control points are
``generic + Σ alpha_k · unit_k + delta`` and every ``FACE`` vertex follows through the fixed
subdivision matrix (Eisert & Girod, Equation 1). The camera is a pinhole with its principal
point at the photo's centre and a known focal length (:func:`focal_length`).

The fit minimizes, by Levenberg–Marquardt in three stages (pose; pose and shape units; all),

    Σ_j w_j |π(R · M_j c + t) − l_j|² / σ_px²                      landmark reprojection
  + |alpha|² / σ_α²                                                 shape units stay plausible
  + |delta_xy|² / σ_xy² + |delta_z|² / σ_z²                         refinement stays small
  + |L delta|² / σ_L² + |delta − mirror(delta)|² / σ_sym²           smooth and nearly symmetric

One photo cannot tell depth: the priors keep the head's profile close to the generic head's
(``σ_z`` is a tenth of ``σ_xy``, and the shape units that move the face in depth are held
tight) while the landmarks move what the camera sees. The landmark residuals go through a
soft-L1 loss, solved as iteratively reweighted least squares (:func:`levenberg_marquardt`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from vtts.errors import FitError
from vtts.fit.expression import ONE_WAY as ONE_WAY_FACTOR
from vtts.fit.expression import ExpressionBasis
from vtts.fit.generic import GenericHead, LandmarkMap
from vtts.fit.landmarks import EYE_CORNERS as LANDMARK_EYE_CORNERS
from vtts.render.camera import Camera
from vtts.vrml import rotation_matrix

#: Default focal length as a 35 mm-equivalent (mm) when the photo has no EXIF focal length: a
#: normal portrait lens.
DEFAULT_FOCAL_35MM = 50.0
#: The 35 mm-equivalent focal lengths (mm) a fit takes: a fisheye to a long telephoto. Beyond
#: them the camera is nothing a photo of a face was taken with (and the fit's numbers break down).
MIN_FOCAL_35MM, MAX_FOCAL_35MM = 8.0, 2000.0
#: The diagonal of the 35 mm frame (mm).
FRAME_DIAGONAL_35MM = math.hypot(36.0, 24.0)

#: Prior widths, in model units (the generic face is about 1.2 units wide) and shape-unit units.
SIGMA_ALPHA = 1.0
#: Shape units that move the face in depth (``… z-extension``, ``… z-position``) are as good as
#: unobservable in one photo, and the landmarks' bias on turned faces drives them far: a tighter
#: prior.
SIGMA_ALPHA_DEPTH = 0.05
SIGMA_XY = 0.03
SIGMA_Z = 0.003
SIGMA_LAPLACE = 0.01
SIGMA_SYMMETRY = 0.01
#: The landmark noise as a fraction of the photo's eye distance.
SIGMA_PX_OF_EYES = 0.02
#: Weight of the landmarks on the face's silhouette (the detector places them on the outline,
#: which moves over the surface as the head turns).
OVAL_WEIGHT = 0.3
#: A landmark whose mapped position wandered this far over the views (model units) counts half.
SPREAD_SCALE = 0.02
#: Residuals beyond this many σ count less and less (soft L1).
ROBUST_SCALE = 2.0
#: Iterations per stage.
MAX_ITERATIONS = 40
#: Past this yaw (radians) the far side's outline landmarks are left out.
OVAL_YAW_LIMIT = math.radians(8)


def focal_length(size: tuple[int, int], focal_35mm: float | None = None) -> float:
    """Focal length in pixels of a photo of ``size`` (W, H) taken with a lens of ``focal_35mm``
    (35 mm-equivalent; :data:`DEFAULT_FOCAL_35MM` when None), scaled by the diagonals."""
    f35 = DEFAULT_FOCAL_35MM if focal_35mm is None else float(focal_35mm)
    if not MIN_FOCAL_35MM <= f35 <= MAX_FOCAL_35MM:  # NaN too
        raise FitError(f"the focal length is a 35 mm-equivalent of {MIN_FOCAL_35MM:g} to "
                       f"{MAX_FOCAL_35MM:g} mm, got {f35:g}")  # fmt: skip
    return f35 / FRAME_DIAGONAL_35MM * math.hypot(*size)


@dataclass
class ShapeFit:
    """The outcome of :func:`fit_shape`.

    control     ``(c, 3)`` fitted control points (model units)
    alpha       ``(k,)`` shape-unit weights
    rotation    ``(3, 3)`` model → camera rotation (OpenGL camera: looking along −z, y up)
    translation ``(3,)`` model → camera translation (model units)
    focal       focal length (pixels); the principal point is the photo's centre
    size        the photo's (W, H)
    residual    ``(n,)`` reprojection error of each mapped landmark (pixels)
    used        ``(n,)`` bool: the landmarks the last stage weighed
    expression  ``{FAP number: value}`` the photo's expression (the generic head's FAPU
                units; empty when none was fitted): ``control`` is the neutral face without it
    """

    control: np.ndarray
    alpha: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    focal: float
    size: tuple[int, int]
    residual: np.ndarray
    used: np.ndarray
    expression: dict[int, float] = field(default_factory=dict)

    @property
    def camera(self) -> Camera:
        """The photo's camera in the model's (world) frame: a placed :class:`Camera`."""
        w, h = self.size
        pose = np.eye(4)
        pose[:3, :3] = self.rotation.T
        pose[:3, 3] = -self.rotation.T @ self.translation
        depth = float(self.translation[2])
        return Camera(self.focal, self.focal, w / 2, h / 2, pose,
                      znear=max(abs(depth) / 50, 1e-3), zfar=abs(depth) * 20 + 10)  # fmt: skip

    @property
    def yaw(self) -> float:
        """The head's turn about the vertical axis seen from the camera (radians, + = the
        head's left towards the camera)."""
        return yaw_of(self.rotation)


def rotvec_matrix(v: np.ndarray) -> np.ndarray:
    """``(3, 3)`` rotation of the rotation vector ``v (3,)`` (axis × angle, radians)."""
    return rotation_matrix(np.r_[v, np.linalg.norm(v)])


def yaw_of(rotation: np.ndarray) -> float:
    """The turn about the vertical axis (radians) of ``rotation (3, 3)`` read as yaw, then pitch,
    then roll (R = R_y · R_x · R_z)."""
    return math.atan2(rotation[0, 2], rotation[2, 2])


def project(points: np.ndarray, rotation: np.ndarray, t: np.ndarray, f: float, cx: float,
            cy: float) -> np.ndarray:  # fmt: skip
    """Pixel coordinates ``(n, 2)`` of model points ``(n, 3)`` (X right, Y down)."""
    p = points @ rotation.T + t
    z = -p[:, 2]
    return np.stack([cx + f * p[:, 0] / z, cy - f * p[:, 1] / z], axis=1)


def fit_shape(
    head: GenericHead,
    lmap: LandmarkMap,
    landmarks: np.ndarray,
    size: tuple[int, int],
    focal: float,
    *,
    refine: bool = True,
    expression: ExpressionBasis | None = None,
) -> ShapeFit:
    """Fit ``head`` to detected ``landmarks`` ``(468, 2+)`` (pixels) of a photo of ``size``.

    ``lmap`` says where each landmark lies on ``FACE``; ``focal`` is in pixels. ``refine=False``
    stops after the shape units (no per-control-point refinement). Landmarks are weighed by how
    steadily they were mapped (:attr:`LandmarkMap.spread`) and through a robust loss, so a few
    that the detector puts elsewhere on this face than on the bundled heads do not pull the
    shape. With ``expression`` (:func:`vtts.fit.expression.expression_basis`) the photo's
    expression is fitted along with the shape units and the refinement, and kept apart from the
    neutral shape (:attr:`ShapeFit.expression`)."""
    w, h = size
    cx, cy = w / 2, h / 2
    M = np.asarray((lmap.matrix(head.S.shape[0]) @ head.S).todense())  # (n, c)
    target = np.asarray(landmarks, dtype=np.float64)[lmap.landmark, :2]
    oval = lmap.group == "oval"
    trust = np.where(oval, OVAL_WEIGHT, 1.0) / (1.0 + (lmap.spread / SPREAD_SCALE) ** 2)
    eyes = _eye_distance_px(target, lmap)
    sigma_px = SIGMA_PX_OF_EYES * eyes
    c0 = head.control
    n_c = len(c0)
    units = head.shape_units.reshape(len(head.shape_units), -1).T  # (3c, k)
    k = units.shape[1]
    sigma_alpha = np.array(
        [SIGMA_ALPHA_DEPTH if " z-" in name else SIGMA_ALPHA for name in head.unit_names]
    )
    lap = head.laplacian.toarray()
    # the priors are linear in delta: their rows of the Jacobian are constant
    eye3 = np.eye(3 * n_c)
    sym = (eye3 - _mirror_matrix(head.mirror)) / SIGMA_SYMMETRY
    smooth = np.kron(lap, np.eye(3)) / SIGMA_LAPLACE
    small = np.diag(np.tile([1 / SIGMA_XY, 1 / SIGMA_XY, 1 / SIGMA_Z], n_c))
    prior_delta = np.vstack([small, smooth, sym])
    e = 0 if expression is None else len(expression.faps)

    # initial pose: facing the camera, at the distance that gives the photo's eye distance
    model_pts = M @ c0
    depth = focal * _eye_distance_model(model_pts, lmap) / eyes
    centre_px = target[~oval].mean(axis=0)
    centre_m = model_pts[~oval].mean(axis=0)
    t0 = np.array([
        (centre_px[0] - cx) * depth / focal - centre_m[0],
        -(centre_px[1] - cy) * depth / focal - centre_m[1],
        -depth - centre_m[2],
    ])  # fmt: skip

    def split(x: np.ndarray, stage: int):
        alpha = x[6 : 6 + k] if stage >= 2 else np.zeros(k)
        f = x[6 + k : 6 + k + e] if stage >= 2 else np.zeros(e)
        delta = x[6 + k + e :] if stage >= 3 else np.zeros(3 * n_c)
        return x[:3], x[3:6], alpha, f, delta

    def expression_prior(f):
        """The expression values' prior residuals ``(e,)`` and their slopes."""
        scale = np.where(expression.one_way & (f < 0), ONE_WAY_FACTOR, 1.0) * expression.sigma
        return f / scale, 1.0 / scale

    def landmark_terms(rotvec, t, alpha, f, delta, wts):
        """Weighted reprojection residuals ``(2n,)`` and their derivatives by the model
        points' camera coordinates ``(n, 2, 3)``."""
        rot = rotvec_matrix(rotvec)
        c = (c0.ravel() + units @ alpha + delta).reshape(n_c, 3)
        pts = M @ c
        if e:
            pts = pts + expression.displacement(f)
        p = pts @ rot.T + t
        z = -p[:, 2]
        uv = np.stack([cx + focal * p[:, 0] / z, cy - focal * p[:, 1] / z], axis=1)
        s = np.sqrt(wts) / sigma_px
        r = ((uv - target) * s[:, None]).ravel()
        d = np.zeros((len(p), 2, 3))
        d[:, 0, 0] = focal / z
        d[:, 0, 2] = focal * p[:, 0] / z**2
        d[:, 1, 1] = -focal / z
        d[:, 1, 2] = -focal * p[:, 1] / z**2
        return r, d * s[:, None, None], rot, p

    def residuals(x, stage, wts):
        rotvec, t, alpha, f, delta = split(x, stage)
        r, _, _, _ = landmark_terms(rotvec, t, alpha, f, delta, wts)
        out = [r]
        if stage >= 2:
            out.append(alpha / sigma_alpha)
            if e:
                out.append(expression_prior(f)[0])
        if stage >= 3:
            out.append(prior_delta @ delta)
        return np.concatenate(out)

    def jacobian(x, stage, wts):
        rotvec, t, alpha, f, delta = split(x, stage)
        r, d, rot, p = landmark_terms(rotvec, t, alpha, f, delta, wts)
        n = len(p)
        ke = (k + e) if stage >= 2 else 0
        cols = 6 + ke + (3 * n_c if stage >= 3 else 0)
        rows = 2 * n + ke + (prior_delta.shape[0] if stage >= 3 else 0)
        jac = np.zeros((rows, cols))
        # rotation: numerically (three columns); translation: d(uv)/dp
        for a in range(3):
            step = np.zeros(3)
            step[a] = 1e-6
            moved = landmark_terms(rotvec + step, t, alpha, f, delta, wts)[0]
            jac[: 2 * n, a] = (moved - r) / 1e-6
        jac[: 2 * n, 3:6] = d.reshape(2 * n, 3)
        if stage >= 2:
            # d(uv_j)/d(c_m) = M[j, m] · d_j @ R  →  (2n, 3c)
            dr = d @ rot  # (n, 2, 3)
            dc = np.einsum("jm,jab->jamb", M, dr).reshape(2 * n, 3 * n_c)
            jac[: 2 * n, 6 : 6 + k] = dc @ units
            jac[2 * n : 2 * n + k, 6 : 6 + k] = np.diag(1 / sigma_alpha)
            if e:
                # d(uv_j)/d(f_i) = d_j @ R @ slope_i,j
                de = np.einsum("jab,ijb->jai", dr, expression.slopes(f)).reshape(2 * n, e)
                jac[: 2 * n, 6 + k : 6 + k + e] = de
                jac[2 * n + k : 2 * n + k + e, 6 + k : 6 + k + e] = np.diag(expression_prior(f)[1])
            if stage >= 3:
                jac[: 2 * n, 6 + k + e :] = dc
                jac[2 * n + k + e :, 6 + k + e :] = prior_delta
        return jac

    def solve(x, stage, wts):
        n2 = 2 * len(target)
        return levenberg_marquardt(lambda v: residuals(v, stage, wts),
                                   lambda v: jacobian(v, stage, wts), x, n2)  # fmt: skip

    # stage 1: the pose alone, on the inner landmarks
    x = solve(np.r_[np.zeros(3), t0], 1, np.where(oval, 0.0, trust))
    # stage 2: pose and shape units, the outline too (its far side dropped on a turned head)
    x = solve(np.r_[x, np.zeros(k + e)], 2, _weights(trust, oval, target, x[:3]))
    stage = 2
    wts = _weights(trust, oval, target, x[:3])
    if refine:
        x = solve(np.r_[x, np.zeros(3 * n_c)], 3, wts)
        stage = 3
    rotvec, t, alpha, f, delta = split(x, stage)
    c = (c0.ravel() + units @ alpha + delta).reshape(n_c, 3)
    rot = rotvec_matrix(rotvec)
    pts = M @ c + (expression.displacement(f) if e else 0.0)
    err = np.linalg.norm(project(pts, rot, t, focal, cx, cy) - target, axis=1)
    faps = {} if not e else {int(n): float(v) for n, v in zip(expression.faps, f, strict=True)}
    return ShapeFit(c, alpha, rot, t, focal, (w, h), err, wts > 0, faps)


def levenberg_marquardt(
    residuals, jacobian, x: np.ndarray, n_robust: int, *, iterations: int = 0
) -> np.ndarray:
    """Minimize ``Σ ρ(r_i²) `` by Levenberg–Marquardt on iteratively reweighted normal
    equations: the first ``n_robust`` residuals (the landmarks, in σ units, x and y of a landmark
    side by side) go through the soft-L1 loss ρ(z) = 2(√(1 + z/s²) − 1)·s², the others (the
    priors) are plain squares. Stops when a step changes the cost by less than 1e-7 of it."""
    iterations = iterations or MAX_ITERATIONS

    def weights(r):
        w = np.ones_like(r)
        pair = r[:n_robust].reshape(-1, 2)
        z = (pair**2).sum(axis=1) / ROBUST_SCALE**2
        w[:n_robust] = np.repeat(1 / np.sqrt(1 + z), 2)
        return w

    def cost(r):
        pair = r[:n_robust].reshape(-1, 2)
        z = (pair**2).sum(axis=1) / ROBUST_SCALE**2
        return 2 * ROBUST_SCALE**2 * (np.sqrt(1 + z) - 1).sum() + (r[n_robust:] ** 2).sum()

    r = residuals(x)
    c = cost(r)
    lam = 1e-3
    for _ in range(iterations):
        jac = jacobian(x)
        w = weights(r)
        jw = jac * w[:, None]
        a = jw.T @ jac
        g = jw.T @ r
        diag = np.diag(a).copy()
        improved = False
        while lam < 1e10:
            step = np.linalg.solve(a + lam * np.diag(np.maximum(diag, 1e-9)), -g)
            r_new = residuals(x + step)
            c_new = cost(r_new)
            if c_new < c:
                improved = True
                break
            lam *= 10
        if not improved:
            break
        done = c - c_new < 1e-7 * c
        x, r, c = x + step, r_new, c_new
        lam = max(lam / 10, 1e-9)
        if done:
            break
    return x


def _mirror_matrix(mirror: np.ndarray) -> np.ndarray:
    """``(3c, 3c)``: flattened control points → their mirror images' (x negated)."""
    n = len(mirror)
    out = np.zeros((3 * n, 3 * n))
    for i, m in enumerate(mirror):
        for a, sign in enumerate((-1.0, 1.0, 1.0)):
            out[3 * i + a, 3 * m + a] = sign
    return out


def _weights(weight, oval, target, rotvec) -> np.ndarray:
    """Landmark weights for a pose: the outline's far side drops out when the head turns."""
    wts = weight.copy()
    yaw = yaw_of(rotvec_matrix(rotvec))
    if abs(yaw) > OVAL_YAW_LIMIT:
        mid = np.median(target[:, 0])
        # a positive yaw turns the nose towards the image's right and the head's left side
        # (on the image's right) away from the camera
        far = target[:, 0] > mid if yaw > 0 else target[:, 0] < mid
        wts[oval & far] = 0.0
    return wts


#: MediaPipe face-mesh landmarks of the eye corners (outer, inner) of each eye.
EYE_CORNERS = (
    (LANDMARK_EYE_CORNERS["right_outer"], LANDMARK_EYE_CORNERS["right_inner"]),
    (LANDMARK_EYE_CORNERS["left_outer"], LANDMARK_EYE_CORNERS["left_inner"]),
)


def _eye_centres(points: np.ndarray, lmap: LandmarkMap) -> np.ndarray:
    where = {int(j): i for i, j in enumerate(lmap.landmark)}
    return np.array([points[[where[a], where[b]]].mean(axis=0) for a, b in EYE_CORNERS])


def _eye_distance_px(target: np.ndarray, lmap: LandmarkMap) -> float:
    e = _eye_centres(target, lmap)
    return float(np.linalg.norm(e[0] - e[1]))


def _eye_distance_model(points: np.ndarray, lmap: LandmarkMap) -> float:
    e = _eye_centres(points, lmap)
    return float(np.linalg.norm(e[0] - e[1]))
