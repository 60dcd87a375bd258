"""The texture of a head made for a video: what the tracked frames show.

A head that ``vtts analyze --model auto`` makes for a video is textured with one frame, the
anchor (:mod:`vtts.analysis.anchor`): rendered at that frame's pose it gives the frame back, but
every other frame differs from it where the person's appearance changed and no parameter of the
stream can follow — the eyes looking down in the anchor and at the camera elsewhere, the eyelids,
the teeth behind the lips, the light on a turned cheek. The decoder draws the texture the coder
chose for every frame, so the texture should be what the frames show, for the tracked geometry.

After the track, :func:`mean_texture` renders the model at each frame's estimate, finds each
covered pixel's point on the surface (its triangle and barycentric coordinates, as the estimator
does) and so its place in the texture, and adds the camera pixel there with bilinear weights; the
new texel is the weighted mean, and texels seen too little keep some of the anchor's color
(:data:`MIN_WEIGHT`). Pixels next to the model's outline (:data:`SHRINK`) mix background in and
are left out. :func:`robust_texture`, the one :func:`retexture` (``vtts analyze``) writes, solves
instead for the texels that the decoder's bilinear sampling renders closest to the frames (least
squares over all of them at once: the mean blurs twice, once splatting the pixels and once
sampling the texels), then again with each pixel weighted down by how far it lies from that
solution, so that the texture is what most frames show — open eyes where the person blinks now
and then, a closed mouth where it opens — rather than a blend of them. The texture is still sent
once, before the stream (the paper's model is too); it only needs the whole video first (read
twice), so ``vtts analyze`` makes it for a video file, not for frames on a pipe.

Measured with ``bench/bench_people.py`` and ``bench/bench_real_video.py``: see
``docs/analysis.md``. Tracking again with the mean texture gained nothing there, so the track is
made once.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from PIL import Image

from vtts.analysis.estimator import Estimator
from vtts.analysis.result import FrameEstimate
from vtts.analysis.track import Tracked
from vtts.errors import AnalysisError
from vtts.face import FaceModel, load_model
from vtts.fit.frame import FRAME_PARTS
from vtts.render.camera import Camera

#: Texels whose summed weight is below this keep a share of their old color (1 − weight / this).
MIN_WEIGHT = 3.0
#: Pixels along the model's outline left out (they mix the background in).
SHRINK = 2
#: How strongly :func:`robust_texture` holds each texel to the frames' mean there (in the units
#: of a frame's summed bilinear weight on it: about 1 a frame that shows it).
PRIOR = 0.3
#: The color distance (RGB, 0–255) at which :func:`robust_texture` halves a pixel's weight.
OUTLIER = 15.0
#: The conjugate-gradient solve of :func:`robust_texture`: relative tolerance and most steps.
CG_TOLERANCE = 1e-4
CG_ITERATIONS = 300


@dataclass
class _Box:
    """The texels a head's textured parts can show: rows ``y0 .. y0 + h``, columns ``x0 .. x0 +
    w`` of the texture (``n = h · w`` texels, numbered row by row)."""

    y0: int
    x0: int
    h: int
    w: int

    @property
    def n(self) -> int:
        return self.h * self.w


def _check(texture: np.ndarray) -> np.ndarray:
    texture = np.asarray(texture)
    if texture.ndim != 3 or texture.shape[2] < 3:
        raise AnalysisError(f"a texture is an (H, W, 3) image, got shape {texture.shape}")
    return texture


def _samples(
    model: FaceModel,
    camera: Camera,
    size: tuple[int, int],
    estimates: Sequence[FrameEstimate],
    frames: Iterable[np.ndarray],
    texture_shape: tuple[int, ...],
    parts: Sequence[str],
) -> tuple[_Box, Iterator[tuple[int, np.ndarray, np.ndarray, np.ndarray]]]:
    """Where the tracked frames' pixels fall in the texture: the box of texels the ``parts``
    can show, and per estimated frame ``(index, at, weights, colors)`` — for each of the ``n``
    covered pixels (less :data:`SHRINK` along the outline) the 4 texels of the box its surface
    point lies between ``at`` ``(4, n)`` int, their bilinear weights ``(4, n)`` (summing to
    1) and the camera pixel ``colors`` ``(n, 3)`` float, 0–255."""
    th, tw = texture_shape[:2]
    estimator = Estimator(model, size=size, camera=camera, unknowns=("tx",))
    geometry = estimator.geometry
    uv = np.zeros((geometry.n_vertices, 2))
    textured = np.zeros(len(geometry.faces), dtype=bool)
    for s in geometry.shapes:
        if s.node.name in parts and s.mesh.texcoords is not None:
            uv[s.first_vertex : s.first_vertex + len(s.mesh.positions)] = s.mesh.texcoords
            textured[s.first_face : s.first_face + len(s.mesh.faces)] = True
    if not textured.any():
        raise AnalysisError(f"{model.name}: none of its parts {', '.join(parts)} is textured")
    # the texels the parts can show: the box around their texture coordinates (a video's
    # texture is the frame's size; the head covers a part of it)
    corners = uv[np.unique(geometry.faces[textured])]
    xs, ys = corners[:, 0] * tw - 0.5, (1.0 - corners[:, 1]) * th - 0.5
    x_lo = min(max(int(np.floor(xs.min())), 0), tw - 1)
    y_lo = min(max(int(np.floor(ys.min())), 0), th - 1)
    bw = min(max(int(np.floor(xs.max())) + 2 - x_lo, 1), tw - x_lo)
    bh = min(max(int(np.floor(ys.max())) + 2 - y_lo, 1), th - y_lo)
    box = _Box(y_lo, x_lo, bh, bw)
    wanted = {fe.index: fe for fe in estimates if not np.isnan(fe.psnr)}
    last = max(wanted, default=-1)

    def each() -> Iterator[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
        for index, frame in enumerate(frames):
            if index > last:
                break
            fe = wanted.get(index)
            if fe is None:
                continue
            frame = np.asarray(frame)
            if frame.shape[:2] != (size[1], size[0]):
                raise AnalysisError(f"frame {index} is {frame.shape[1]}x{frame.shape[0]}, the "
                                    f"analysis's video {size[0]}x{size[1]}")  # fmt: skip
            estimator.params, estimator.translation = fe.params.copy(), fe.translation.copy()
            pixels, tri, lam = estimator.surface(SHRINK)
            keep = textured[tri]
            pixels, tri, lam = pixels[keep], tri[keep], lam[keep]
            t = np.einsum("nm,nmk->nk", lam, uv[geometry.faces[tri]])
            # texel coordinates with texel centres at integers (u = x / W_tex, v = 1 − y / H_tex)
            x, y = t[:, 0] * tw - 0.5, (1.0 - t[:, 1]) * th - 0.5
            x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
            fx, fy = x - x0, y - y0
            at = np.empty((4, len(x)), np.int64)
            weights = np.empty((4, len(x)))
            for k, (dx, dy, w) in enumerate(((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)),
                                             (0, 1, (1 - fx) * fy), (1, 1, fx * fy))):  # fmt: skip
                at[k] = (np.clip(y0 + dy - y_lo, 0, bh - 1) * bw
                         + np.clip(x0 + dx - x_lo, 0, bw - 1))  # fmt: skip
                weights[k] = w
            yield index, at, weights, frame[pixels[:, 0], pixels[:, 1], :3].astype(np.float64)

    return box, each()


def _blend(texture: np.ndarray, box: _Box, new: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """``texture`` with the box's texels ``new`` ``(3, n)``, where their summed ``weight``
    ``(n,)`` is below :data:`MIN_WEIGHT` keeping a share of the old color."""
    share = np.clip(weight / MIN_WEIGHT, 0.0, 1.0)
    out = texture.copy()
    view = out[box.y0 : box.y0 + box.h, box.x0 : box.x0 + box.w, :3]
    old = view.reshape(-1, 3).T.astype(np.float64)
    mixed = share * new + (1.0 - share) * old
    view[...] = np.clip(np.round(mixed.T.reshape(box.h, box.w, 3)), 0, 255).astype(np.uint8)
    return out


def mean_texture(
    model: FaceModel,
    camera: Camera,
    size: tuple[int, int],
    estimates: Sequence[FrameEstimate],
    frames: Iterable[np.ndarray],
    texture: np.ndarray,
    parts: Sequence[str] = FRAME_PARTS,
) -> np.ndarray:
    """The texture of ``model``'s ``parts`` (the IndexedFaceSets that share ``texture``) that
    the tracked frames show on average.

    ``camera`` and ``size`` (W, H) are the analysis's (:attr:`Analysis.camera`, the video's
    size); ``estimates`` the track's estimates in frame order (those with a NaN PSNR, held
    frames, are skipped); ``frames`` the video's frames from frame 0, each ``(H, W, 3) uint8``
    (read as far as the last estimate); ``texture`` ``(H_tex, W_tex, 3) uint8`` the parts'
    texture now. Returns the new texture, same shape and type."""
    texture = _check(texture)
    box, samples = _samples(model, camera, size, estimates, frames, texture.shape, parts)
    weight = np.zeros(box.n)
    sums = np.zeros((3, box.n))
    for _, at, weights, colors in samples:
        for k in range(4):
            weight += np.bincount(at[k], weights[k], minlength=box.n)
            for c in range(3):
                sums[c] += np.bincount(at[k], weights[k] * colors[:, c], minlength=box.n)
    return _blend(texture, box, sums / np.maximum(weight, 1e-12), weight)


def robust_texture(
    model: FaceModel,
    camera: Camera,
    size: tuple[int, int],
    estimates: Sequence[FrameEstimate],
    frames: Sequence[np.ndarray] | Callable[[], Iterable[np.ndarray]],
    texture: np.ndarray,
    parts: Sequence[str] = FRAME_PARTS,
) -> np.ndarray:
    """The texture of ``model``'s ``parts`` that the decoder, sampling it bilinearly, renders
    closest to the typical tracked frame: least squares over every frame's pixels, solved for
    the texels together (:data:`PRIOR` pulls each toward :func:`mean_texture`'s value), then
    solved again with each pixel weighted by how far it lies from that first solution
    (Cauchy's weight, scale :data:`OUTLIER`), so that a blink, a mouth opened wide or a hand
    passing over the face pull the texture less than what most frames show.

    Arguments as :func:`mean_texture`'s, but ``frames`` is read twice: a sequence of frames,
    or a function that gives an iterable of them from frame 0 each time it is called (as
    :meth:`vtts.analysis.video.Video.frames`). Returns the new texture, ``(H_tex, W_tex, 3)
    uint8``."""
    from scipy.sparse import coo_matrix, diags
    from scipy.sparse.linalg import cg

    texture = _check(texture)
    if isinstance(frames, Iterator):
        raise AnalysisError("the texture reads the frames twice: give a sequence of frames or a "
                            "function that gives them anew, not an iterator")  # fmt: skip

    def passes():
        return _samples(model, camera, size, estimates,
                        frames() if callable(frames) else frames, texture.shape, parts)  # fmt: skip

    def normal(box: _Box, samples, fit: np.ndarray | None):
        """``AᵀWA`` (n, n) sparse, ``AᵀWb`` (3, n) and the summed weights (n,)."""
        n = box.n
        bands = np.zeros(9 * n)  # texel a with texel a + dy · w + dx, dx and dy in −1..1
        weight = np.zeros(n)
        rhs = np.zeros((3, n))
        for _, at, weights, colors in samples:
            down = weights
            if fit is not None:
                r2 = np.sum((colors - np.einsum("kn,knc->nc", weights, fit[at])) ** 2, axis=1)
                down = weights * (OUTLIER**2 / (OUTLIER**2 + r2))
            ay, ax = np.divmod(at, box.w)
            flat = at.ravel()
            weight += np.bincount(flat, down.ravel(), minlength=n)
            for c in range(3):
                rhs[c] += np.bincount(flat, (down * colors[:, c]).ravel(), minlength=n)
            codes = (at[:, None] * 9 + (ay[None] - ay[:, None] + 1) * 3
                     + (ax[None] - ax[:, None] + 1))  # fmt: skip
            bands += np.bincount(codes.ravel(), (down[:, None] * weights[None]).ravel(),
                                 minlength=9 * n)  # fmt: skip
        bands = bands.reshape(n, 9)
        rows, offs = np.nonzero(bands)
        cols = rows + (offs // 3 - 1) * box.w + (offs % 3 - 1)
        return coo_matrix((bands[rows, offs], (rows, cols)), shape=(n, n)).tocsr(), rhs, weight

    def solve(box: _Box, ata, rhs: np.ndarray, weight: np.ndarray) -> np.ndarray:
        """The texels ``(3, n)``: ``(AᵀWA + PRIOR) t = AᵀWb + PRIOR · t₀``, ``t₀`` the mean."""
        start = _blend(texture, box, rhs / np.maximum(weight, 1e-12), weight)
        start = start[box.y0 : box.y0 + box.h, box.x0 : box.x0 + box.w, :3]
        start = start.reshape(-1, 3).T.astype(np.float64)
        lhs = (ata + diags(np.full(box.n, PRIOR))).tocsr()
        jacobi = diags(1.0 / (ata.diagonal() + PRIOR))
        out = np.empty((3, box.n))
        for c in range(3):
            out[c], _ = cg(lhs, rhs[c] + PRIOR * start[c], x0=start[c], M=jacobi,
                           rtol=CG_TOLERANCE, maxiter=CG_ITERATIONS)  # fmt: skip
        return out

    box, samples = passes()
    first = solve(box, *normal(box, samples, None))
    box, samples = passes()
    ata, rhs, weight = normal(box, samples, np.ascontiguousarray(first.T))
    new = solve(box, ata, rhs, weight)
    # texels no frame showed keep their color (the prior alone held them)
    return _blend(texture, box, new, np.where(weight > 0, MIN_WEIGHT, 0.0))


def retexture(
    tracked: Tracked,
    frames: Sequence[np.ndarray] | Callable[[], Iterable[np.ndarray]],
    size: tuple[int, int],
) -> FaceModel:
    """Replace the frame texture of the head ``tracked`` fitted to a video (its
    ``-frame.png``, :func:`vtts.fit.photo.frame_texture_name`, among ``tracked.fitted``) by
    :func:`robust_texture` of the video's ``frames`` (a sequence from frame 0, or a function
    giving them from frame 0 anew, as :meth:`~vtts.analysis.video.Video.frames`; ``size`` (W,
    H)) at the track's estimates, and return the head loaded again. The file is replaced whole
    (written to a temporary name first)."""
    from vtts.atomic import atomic_path
    from vtts.fit.photo import frame_texture_name

    if not tracked.fitted:
        raise AnalysisError("only a head fitted to the video has a frame texture to replace")
    name = frame_texture_name(tracked.fitted[0])
    path = next((p for p in tracked.fitted if p.name == name), None)
    if path is None:
        raise AnalysisError(f"{tracked.model.name}: the fitted head has no {name}")
    with Image.open(path) as im:
        texture = np.asarray(im.convert("RGB"))
    analysis = tracked.analysis
    new = robust_texture(tracked.model, analysis.camera, size, analysis.frames, frames, texture)
    with atomic_path(path) as tmp:
        Image.fromarray(new).save(tmp, format="PNG", compress_level=3)
    return load_model(str(tracked.fitted[0]))
