"""Estimating FAPs from video by analysis by synthesis (Eisert & Girod 1998).

For every camera frame I(n) the model is rendered with the current estimate, and the parameter
change that carries the synthetic image onto the camera frame is solved for in the least-squares
sense over all face pixels. Each pixel gives, per color channel, the optical-flow constraint
(Equation 10) with the image motion written as a linear function of the parameter changes
(Equations 14–15, 16): the pixel's 3D point moves by ``T · ΔFAP`` (Equation 9), where T combines
the model's per-vertex motion (:mod:`vtts.analysis.geometry`) with the pixel's barycentric
coordinates in the triangle it shows (:mod:`vtts.analysis.raster`), and the depth comes from the
model. Because the estimate is always made between the camera frame and the model rendered with
the current parameters — never between two camera frames — errors do not accumulate.

A three-level pyramid (88×72, 176×144, 352×288 for CIF: moving-average subsampling, then a
Gaussian filter on both images) handles large motion; pixels whose displacement estimate
(Equation 17) exceeds the level's threshold G (5 → 0.5 pixels) are dropped as outliers; after
each solve the model is rendered again with the new parameters.

Beyond the paper, the camera frame is modelled as ``gain · synthetic + offset`` per color channel,
with gain and offset estimated along with the FAPs, so that a change of light does not read as
motion. And the eyelids (:data:`~vtts.analysis.unknowns.EYELIDS`), whose thin edges change the
rendered image in whole pixels where the optical-flow model expects a smooth change, are refined
at the end on the rendered image itself: a search over integer FAP values for the best match
around the eye.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import binary_erosion, gaussian_filter

from vtts.analysis.geometry import HeadGeometry
from vtts.analysis.raster import TriangleIndexBuffer, ray_barycentrics
from vtts.analysis.result import TRANSLATION, Analysis, FrameEstimate
from vtts.analysis.unknowns import (  # noqa: F401
    DEFAULT_UNKNOWNS,
    ESTIMABLE,
    EYELIDS,
    TABLE1_FAPS,
)
from vtts.errors import VttsError
from vtts.face import N_PARAMS, FaceModel
from vtts.render.camera import Camera
from vtts.render.renderer import FaceRenderer

#: Pixels next to the model's outline left out of the estimation.
EDGE = 2

#: Residuals beyond this many gray levels count as this many in the match energy (robust).
TRUNCATE = 10.0

#: Rec. 601 luminance weights (Equation 18 is on luminance).
LUMA = np.array([0.299, 0.587, 0.114])

#: Steps (FAP units) of the search that refines FAPs on the rendered image, largest first, and
#: how many times in a row each may be taken (so the search stays within ±60 units).
REFINE_STEPS = (8, 4, 2, 1)
REFINE_MOVES = 4

#: Pixels around the image of what a refined FAP moves that its match is measured over.
REFINE_MARGIN = 4


@dataclass
class Level:
    """One level of the pyramid: subsampling ``factor``, outlier threshold ``g`` (pixels of
    that level), linear solves ``iterations`` (each followed by a new rendering), ``limit``, the
    most (pixels of that level) one solve may move the image of any unknown, and ``support``,
    the fewest pixels an unknown must move to be estimated at that level (an eyelid covers a
    handful of pixels at 88×72 and is held until a finer level resolves it)."""

    factor: int
    g: float
    iterations: int
    limit: float = 2.0
    support: int = 0


#: The paper's pyramid: 88×72 → 352×288 for CIF, G from 5 to 0.5.
PYRAMID = (
    Level(4, 5.0, 2, support=40),
    Level(2, 1.6, 2, support=4),
    Level(1, 0.5, 8),
)


class Estimator:
    """Tracks one model through a sequence of frames of ``size`` (W, H).

    ``camera`` is the camera of the video (default: the framing ``vtts render`` uses for this
    model and size). ``unknowns`` are FAP numbers and ``"tx"``, ``"ty"``, ``"tz"``.
    ``illumination`` estimates a gain and offset per color channel. ``sigma`` is the Gaussian
    filter (pixels of each level) applied to both images before the gradients. ``refine``: the
    FAPs that, when they are unknowns, are refined after the pyramid by a search over integer
    values on the rendered image (:meth:`_refine`).
    """

    def __init__(
        self,
        model: FaceModel,
        *,
        size: tuple[int, int] = (352, 288),
        camera: Camera | None = None,
        unknowns: Sequence[int | str] = DEFAULT_UNKNOWNS,
        pyramid: Sequence[Level] = PYRAMID,
        illumination: bool = True,
        sigma: float = 0.6,
        tolerance: float = 0.05,
        refine: Iterable[int] = EYELIDS,
    ) -> None:
        self.unknowns = _check_unknowns(unknowns)
        wanted = set(refine)
        self.refined = tuple(u for u in self.unknowns if u in wanted)
        self.model = model
        self.size = (int(size[0]), int(size[1]))
        self.pyramid = tuple(pyramid)
        self.illumination = illumination
        self.sigma = sigma
        self.tolerance = tolerance
        w, h = self.size
        # one renderer for every view (pyramid levels, refinement windows): the GL context holds
        # one scene at a time, and changing scenes uploads every mesh and texture again
        self._renderer = FaceRenderer(model, size=self.size, camera=camera)
        self.camera = self._renderer.camera
        # pyramid factor -> (camera, image size, supersampling)
        self._views: dict[int, tuple[Camera, tuple[int, int], int]] = {
            1: (self.camera, self.size, 1)
        }
        for lv in self.pyramid:
            f = lv.factor
            if f in self._views:
                continue
            lsize = (w // f, h // f)
            if min(lsize) < 16:
                raise VttsError(f"a {w}x{h} video is too small for a pyramid level of 1/{f}")
            # supersampled by the level's factor, the synthetic image is subsampled exactly as
            # the camera frame is (a moving average over the same full-size pixels)
            self._views[f] = (_scaled(self.camera, f), lsize, min(f, 4))
        self._root = self._renderer.scene.get_pose(self._renderer.instances[0].root)
        self.geometry = HeadGeometry(model, self.unknowns, self._root)
        self._ids = TriangleIndexBuffer(
            self.geometry.faces, self.geometry.culled, self.geometry.n_vertices
        )
        self._last_step: _Step | None = None
        self.params = np.zeros(N_PARAMS)
        self.translation = np.zeros(3)
        self.gain = np.ones(3)
        self.offset = np.zeros(3)

    # ---- rendering -----------------------------------------------------------------------------

    def render(self, factor: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """The model at the current estimate at pyramid ``factor``: the image ``(h, w, 3)
        float32`` (0–255, before gain and offset) and triangle indices ``(h, w)`` (−1: none)."""
        cam, lsize, ss = self._views[factor]
        image = self._synthesize(cam, lsize, ss)
        ids = self._ids.draw(self.geometry.positions(self.params, self.translation), cam, lsize)
        return image, ids

    def _synthesize(self, camera: Camera, size: tuple[int, int], supersample: int) -> np.ndarray:
        """The image ``(h, w, 3) float32`` of the model at the current estimate through
        ``camera`` at ``size``, rendered ``supersample`` times larger and averaged down."""
        renderer = self._renderer
        renderer.set_view(camera, size, supersample)
        root = self._root.copy()
        root[:3, 3] += self.translation
        renderer.scene.set_pose(renderer.instances[0].root, root)
        pose = self.geometry.pose(self.params)
        return renderer.render(self.params, poses=[pose]).astype(np.float32)

    def reconstruct(self) -> np.ndarray:
        """The synthetic frame ``(H, W, 3) uint8`` at full size with gain and offset applied."""
        image, _ = self.render(1)
        return np.clip(np.round(image * self.gain + self.offset), 0, 255).astype(np.uint8)

    # ---- estimation ----------------------------------------------------------------------------

    def estimate(self, frame: np.ndarray, index: int = 0, time: float = 0.0) -> FrameEstimate:
        """Update the estimate to the camera ``frame`` ``(H, W, 3) uint8`` and return it."""
        frame = np.asarray(frame)
        w, h = self.size
        if frame.shape != (h, w, 3):
            raise VttsError(f"frame {index} is {frame.shape}, expected ({h}, {w}, 3)")
        full = frame.astype(np.float32)
        pyramid: dict[int, np.ndarray] = {}
        solves = 0
        for lv in self.pyramid:
            if lv.factor not in pyramid:
                pyramid[lv.factor] = _smooth(_subsample(full, lv.factor), self.sigma)
            camera_image = pyramid[lv.factor]
            self._last_step = None  # energies of different levels do not compare
            for _ in range(lv.iterations):
                step = self._solve(camera_image, lv)
                solves += 1
                if step < self.tolerance:
                    break
        # the estimate as a FAP stream carries it: integer FAPs
        params = self.params.copy()
        for u in self.unknowns:
            if not isinstance(u, str):
                params[u - 1] = np.round(params[u - 1]) + 0.0  # no negative zeros
        kept, self.params = self.params, params
        try:
            for fap in self.refined:
                self._refine(full, fap)
            image, ids = self.render(1)
        finally:
            for fap in self.refined:
                kept[fap - 1] = self.params[fap - 1]
            params, self.params = self.params, kept
        synth = np.clip(np.round(image * self.gain + self.offset), 0, 255)
        mask = ids >= 0
        return FrameEstimate(
            index=index,
            time=time,
            params=params,
            translation=self.translation.copy(),
            gain=self.gain.copy(),
            offset=self.offset.copy(),
            psnr=face_psnr(full, synth, mask),
            face_pixels=int(mask.sum()),
            iterations=solves,
        )

    def _solve(self, camera_image: np.ndarray, lv: Level) -> float:
        """One Gauss–Newton step at one level; returns the largest parameter change relative
        to each unknown's scale (FAPU: 1, translation: 1e-4 model units)."""
        cam = self._views[lv.factor][0]
        image, ids = self.render(lv.factor)
        raw = _smooth(image, self.sigma)
        synth = raw * self.gain.astype(np.float32) + self.offset.astype(np.float32)
        # pixels within the model's outline: at the outline the synthetic background (which a
        # camera never shows) and antialiasing would read as motion
        rows, cols = np.nonzero(binary_erosion(ids >= 0, iterations=EDGE))
        if rows.size < 4 * len(self.unknowns):
            raise VttsError(
                f"the model covers only {rows.size} pixels at 1/{lv.factor} size: it is out of "
                "view (check --camera and the first frame)"
            )
        r_p = camera_image[rows, cols] - synth[rows, cols]  # (n, 3)
        # a step that made the match worse is taken back by half (at most three times in a row)
        # before the next linear solve: the linear model can be wrong where shading or
        # occlusion, not texture motion, dominates what an unknown does to the image
        energy = float(np.mean(np.minimum((r_p @ LUMA) ** 2, TRUNCATE**2)))
        last = self._last_step
        if last is not None and energy > last.energy and last.halvings < 3:
            half = last.delta / 2
            self._apply(-half)
            self._last_step = _Step(last.energy, half, last.halvings + 1)
            return self._step_size(half)
        gy_p, gx_p = _gradients_at(camera_image, synth, rows, cols)
        # Equation 17 on luminance: drop pixels whose displacement estimate exceeds G
        ry, gxy, gyy = r_p @ LUMA, gx_p @ LUMA, gy_p @ LUMA
        d = np.abs(ry) / np.sqrt(gxy * gxy + gyy * gyy + 1e-6)
        keep = d <= lv.g
        rows, cols = rows[keep], cols[keep]
        gx_p, gy_p, r_p = gx_p[keep], gy_p[keep], r_p[keep]
        s_p = raw[rows, cols]
        tri = ids[rows, cols]
        pix = np.stack([cols + 0.5, rows + 0.5], axis=1)
        positions = self.geometry.positions(self.params, self.translation)
        verts = self.geometry.faces[tri]  # (N, 3)
        lam, pc = ray_barycentrics(pix, cam, positions[verts])
        uniq, inverse = np.unique(verts, return_inverse=True)
        jac = self.geometry.jacobian(self.params, self.translation, uniq)  # (U, 3, K) world
        jac = np.einsum("ab,ubk->uak", np.linalg.inv(cam.pose)[:3, :3], jac)  # camera axes
        # single precision from here on: the image terms carry no more than that
        jac = jac.astype(np.float32)
        lam = lam.astype(np.float32)
        tc = np.einsum("nm,nmak->nak", lam, jac[inverse.reshape(verts.shape)])  # (N, 3, K)
        depth = (-pc[:, 2:3]).astype(np.float32)  # distance along the view axis, > 0
        x_rel = (pix[:, 0:1] - cam.cx).astype(np.float32)
        y_rel = (cam.cy - pix[:, 1:2]).astype(np.float32)
        du = (np.float32(cam.fx) * tc[:, 0] + x_rel * tc[:, 2]) / depth  # (N, K) px per unit
        dv = -(np.float32(cam.fy) * tc[:, 1] + y_rel * tc[:, 2]) / depth
        n, k = du.shape
        # an unknown whose motion covers too few pixels at this level is held
        speed = np.hypot(du, dv)
        support = (speed > 0.2 * speed.max(axis=0, initial=0.0)).sum(axis=0)
        held = support < lv.support
        du[:, held] = 0.0
        dv[:, held] = 0.0
        extra = 6 if self.illumination else 0
        a = np.zeros((n, 3, k + extra), dtype=np.float32)
        a[:, :, :k] = -(gx_p[:, :, None] * du[:, None, :] + gy_p[:, :, None] * dv[:, None, :])
        if self.illumination:
            for c in range(3):
                a[:, c, k + c] = s_p[:, c]  # d/dgain of gain·S + offset
                a[:, c, k + 3 + c] = 1.0
        a = a.reshape(3 * n, k + extra)
        b = r_p.reshape(-1)
        delta = _least_squares(a, b)
        # the linearization holds for small motion: no unknown may move any of its pixels
        # further than the level's step limit in one solve
        if k:
            reach = speed.max(axis=0, initial=0.0) * np.abs(delta[:k])  # held columns: delta 0
            delta[:k] *= np.minimum(1.0, lv.limit / np.maximum(reach, 1e-12))
        self._apply(delta)
        self._last_step = _Step(energy, delta, 0)
        return self._step_size(delta)

    def _refine(self, frame: np.ndarray, fap: int) -> None:
        """Refine the (integer) value of ``fap`` on the rendered image: a pattern search with
        the steps of :data:`REFINE_STEPS`, each taken (up or down, at most
        :data:`REFINE_MOVES` times in a row) while it improves the luminance match (sum of
        squared differences after gain and offset) with the camera ``frame`` ``(H, W, 3)
        float32`` over the pixels where the FAP's motion shows.

        The Gauss–Newton steps converge slowly on the eyelids and can stop tens of units off:
        the rendered edge of an eyelid moves in whole pixels, which the optical-flow model
        (smooth image, sub-pixel motion) does not describe. The rendered image does."""
        window = self._window(fap)
        if window is None:
            return
        ys, xs = window
        c = self.camera
        view = (
            replace(c, cx=c.cx - xs.start, cy=c.cy - ys.start),
            (xs.stop - xs.start, ys.stop - ys.start),
            1,
        )
        target = frame[ys, xs]

        def mismatch() -> float:
            synth = self._synthesize(*view) * self.gain + self.offset
            return float(np.sum(((synth - target) @ LUMA) ** 2))

        best = mismatch()
        i = fap - 1
        for step in REFINE_STEPS:
            for _ in range(REFINE_MOVES):
                for change in (step, -step):
                    self.params[i] += change
                    value = mismatch()
                    if value < best:
                        best = value
                        break
                    self.params[i] -= change
                else:
                    break  # neither way is better: the next, smaller step

    def _window(self, fap: int) -> tuple[slice, slice] | None:
        """The rows and columns of the full-size image where ``fap``'s motion shows: the box
        around the vertices it moves (at the current estimate, opened and closed by 100 units),
        widened by :data:`REFINE_MARGIN`. None when it moves nothing in view."""
        probe = self.params.copy()
        probe[fap - 1] -= 100.0
        lo = self.geometry.positions(probe, self.translation)
        probe[fap - 1] += 200.0
        hi = self.geometry.positions(probe, self.translation)
        moved = np.any(np.abs(hi - lo) > 0, axis=1)
        if not moved.any():
            return None
        w, h = self.size
        xy = self.camera.project(np.concatenate([lo[moved], hi[moved]]))
        x0, y0 = np.floor(xy.min(axis=0)).astype(int) - REFINE_MARGIN
        x1, y1 = np.ceil(xy.max(axis=0)).astype(int) + REFINE_MARGIN
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        if x1 <= x0 or y1 <= y0:
            return None
        # whole blocks of 16 pixels: never smaller than the renderer's smallest image
        cols = _blocks(x0, x1, w)
        rows = _blocks(y0, y1, h)
        return slice(*rows), slice(*cols)

    def _apply(self, delta: np.ndarray) -> None:
        """Add a change of the unknowns (then gains and offsets, if estimated)."""
        k = len(self.unknowns)
        for j, u in enumerate(self.unknowns):
            if isinstance(u, str):
                self.translation[TRANSLATION.index(u)] += delta[j]
            else:
                self.params[u - 1] += delta[j]
        if self.illumination:
            self.gain += delta[k : k + 3]
            self.offset += delta[k + 3 : k + 6]

    def _step_size(self, delta: np.ndarray) -> float:
        """The largest change of an unknown relative to its scale (FAPU: 1, translation: 1e-4
        model units)."""
        k = len(self.unknowns)
        scale = np.array([1e-4 if isinstance(u, str) else 1.0 for u in self.unknowns])
        return float(np.max(np.abs(delta[:k]) / scale))


@dataclass
class _Step:
    """The last change made at a level: the match before it (``energy``), the change, and how
    often it has been halved."""

    energy: float
    delta: np.ndarray
    halvings: int


def analyze(
    frames: Iterable[np.ndarray],
    model: FaceModel,
    *,
    fps: float,
    step: int = 1,
    camera: Camera | None = None,
    unknowns: Sequence[int | str] = DEFAULT_UNKNOWNS,
    progress: Callable[[int], None] | None = None,
    **options,
) -> Analysis:
    """Estimate the parameters of every ``step``-th frame of ``frames`` (each ``(H, W, 3)
    uint8`` RGB, all the same size) of a video at ``fps`` frames per second. ``options`` go to
    :class:`Estimator`. ``progress`` is called with the frame index after each estimate."""
    if not (math.isfinite(fps) and fps > 0):
        raise VttsError(f"fps must be a positive number, got {fps}")
    if step < 1:
        raise VttsError(f"step must be at least 1, got {step}")
    estimator: Estimator | None = None
    out: list[FrameEstimate] = []
    for i, frame in enumerate(frames):
        if i % step:
            continue
        if estimator is None:
            h, w = frame.shape[:2]
            estimator = Estimator(model, size=(w, h), camera=camera, unknowns=unknowns, **options)
        out.append(estimator.estimate(frame, i, i / fps))
        if progress is not None:
            progress(i)
    if estimator is None:
        raise VttsError("the video has no frames")
    return Analysis(out, estimator.unknowns, fps / step, estimator.camera, model.name)


def face_psnr(frame: np.ndarray, synthetic: np.ndarray, mask: np.ndarray) -> float:
    """Luminance PSNR (dB) of two ``(H, W, 3)`` images (0–255) over the ``(H, W)`` ``mask``;
    ``inf`` when they agree there exactly."""
    if not mask.any():
        return float("nan")
    diff = (np.asarray(frame, np.float64) - np.asarray(synthetic, np.float64)) @ LUMA
    mse = float(np.mean(diff[mask] ** 2))
    return float("inf") if mse == 0 else 10 * math.log10(255.0**2 / mse)


# ---- helpers -----------------------------------------------------------------------------------


def _check_unknowns(unknowns: Sequence[int | str]) -> tuple[int | str, ...]:
    out: list[int | str] = []
    for u in unknowns:
        if isinstance(u, str):
            if u not in TRANSLATION:
                raise VttsError(f"unknown {u!r}: the non-FAP unknowns are tx, ty and tz")
        elif not (isinstance(u, int | np.integer) and int(u) in ESTIMABLE):
            raise VttsError(
                f"FAP {u!r} cannot be estimated: FAPs {ESTIMABLE[0]}–{ESTIMABLE[-1]} can"
            )
        else:
            u = int(u)
        if u in out:
            raise VttsError(f"{u} is listed twice among the unknowns")
        out.append(u)
    if not out:
        raise VttsError("nothing to estimate: the list of unknowns is empty")
    return tuple(out)


def _scaled(camera: Camera, factor: int) -> Camera:
    """The camera of an image subsampled by ``factor`` (pixel edges at integers)."""
    return replace(
        camera,
        fx=camera.fx / factor,
        fy=camera.fy / factor,
        cx=camera.cx / factor,
        cy=camera.cy / factor,
    )


def _blocks(lo: int, hi: int, n: int, block: int = 16) -> tuple[int, int]:
    """``[lo, hi)`` widened to a multiple of ``block`` (at most ``n``) that stays within
    ``[0, n)``."""
    size = min(n, -(-(hi - lo) // block) * block)
    start = min(max(0, lo - (size - (hi - lo)) // 2), n - size)
    return start, start + size


def _subsample(image: np.ndarray, factor: int) -> np.ndarray:
    """Moving-average subsampling of ``(H, W, C)`` by ``factor`` (edges that do not fill a
    block are dropped)."""
    if factor == 1:
        return image
    h, w, c = image.shape[0] // factor, image.shape[1] // factor, image.shape[2]
    blocks = image[: h * factor, : w * factor].reshape(h, factor, w, factor, c)
    return blocks.mean(axis=(1, 3), dtype=np.float32)


def _smooth(image: np.ndarray, sigma: float) -> np.ndarray:
    if sigma <= 0:
        return image
    return gaussian_filter(image, sigma=(sigma, sigma, 0), mode="nearest", truncate=2.0)


def _gradients_at(
    a: np.ndarray, b: np.ndarray, rows: np.ndarray, cols: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Central differences ``(d/dY, d/dX)``, each ``(n, C)``, of the mean of the ``(H, W, C)``
    images ``a`` and ``b`` at the pixels ``rows``, ``cols`` (one-sided at the border), as
    ``np.gradient`` computes them over the whole image."""
    h, w = a.shape[:2]
    up, down = np.maximum(rows - 1, 0), np.minimum(rows + 1, h - 1)
    left, right = np.maximum(cols - 1, 0), np.minimum(cols + 1, w - 1)
    dy = (a[down, cols] + b[down, cols]) - (a[up, cols] + b[up, cols])
    dx = (a[rows, right] + b[rows, right]) - (a[rows, left] + b[rows, left])
    sy = (0.5 / (down - up)).astype(a.dtype)[:, None]
    sx = (0.5 / (right - left)).astype(a.dtype)[:, None]
    return dy * sy, dx * sx


def _least_squares(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``a x ≈ b`` through the normal equations with column scaling and a whisper of
    damping, so that unknowns the pixels say nothing about stay put."""
    a = a.astype(np.float64, copy=False)
    b = b.astype(np.float64, copy=False)
    ata = a.T @ a
    atb = a.T @ b
    d = np.sqrt(np.diag(ata))
    big = d.max() if d.size else 1.0
    ok = d > 1e-9 * big
    x = np.zeros(a.shape[1])
    if not ok.any():
        return x
    s = 1.0 / d[ok]
    m = ata[np.ix_(ok, ok)] * s[:, None] * s[None, :]
    m[np.diag_indices_from(m)] += 1e-9
    x[ok] = s * np.linalg.solve(m, atb[ok] * s)
    return x
