"""The texture of a head made for a video: what the tracked frames show, on average.

A head that ``vtts analyze --model auto`` makes for a video is textured with one frame, the
anchor (:mod:`vtts.analysis.anchor`): rendered at that frame's pose it gives the frame back, but
every other frame differs from it where the person's appearance changed and no parameter of the
stream can follow — the eyes looking down in the anchor and at the camera elsewhere, the eyelids,
the teeth behind the lips, the light on a turned cheek. The decoder draws the texture the coder
chose for every frame, so the texture that makes the summed squared error over the sequence
smallest, for the tracked geometry, is the mean of what the frames show at each texel.

After the track, :func:`mean_texture` renders the model at each frame's estimate, finds each
covered pixel's point on the surface (its triangle and barycentric coordinates, as the estimator
does) and so its place in the texture, and adds the camera pixel there with bilinear weights; the
new texel is the weighted mean, and texels seen too little keep some of the anchor's color
(:data:`MIN_WEIGHT`). Pixels next to the model's outline (:data:`SHRINK`) mix background in and
are left out. The texture is still sent once, before the stream (the paper's model is too); it
only needs the whole video first, so ``vtts analyze`` makes it for a video file, not for frames
on a pipe.

Measured with ``bench/bench_real_video.py`` (every second frame, the decoded stream's face
PSNR): see ``docs/analysis.md``. Tracking again with the mean texture gained nothing there, so
the track is made once.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

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
    texture = np.asarray(texture)
    if texture.ndim != 3 or texture.shape[2] < 3:
        raise AnalysisError(f"a texture is an (H, W, 3) image, got shape {texture.shape}")
    th, tw = texture.shape[:2]
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
    weight = np.zeros(bh * bw)
    sums = np.zeros((3, bh * bw))
    wanted = {fe.index: fe for fe in estimates if not np.isnan(fe.psnr)}
    last = max(wanted, default=-1)
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
        colors = frame[pixels[:, 0], pixels[:, 1], :3].astype(np.float64)
        for dx, dy, w in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)),
                          (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):  # fmt: skip
            at = (np.clip(y0 + dy - y_lo, 0, bh - 1) * bw
                  + np.clip(x0 + dx - x_lo, 0, bw - 1))  # fmt: skip
            weight += np.bincount(at, w, minlength=bh * bw)
            for c in range(3):
                sums[c] += np.bincount(at, w * colors[:, c], minlength=bh * bw)
    mean = sums / np.maximum(weight, 1e-12)
    share = np.clip(weight / MIN_WEIGHT, 0.0, 1.0)
    out = texture.copy()
    box = out[y_lo : y_lo + bh, x_lo : x_lo + bw, :3]
    old = box.reshape(-1, 3).T.astype(np.float64)
    new = share * mean + (1.0 - share) * old
    box[...] = np.clip(np.round(new.T.reshape(bh, bw, 3)), 0, 255).astype(np.uint8)
    return out


def retexture(tracked: Tracked, frames: Iterable[np.ndarray], size: tuple[int, int]) -> FaceModel:
    """Replace the frame texture of the head ``tracked`` fitted to a video (its
    ``-frame.png``, :func:`vtts.fit.photo.frame_texture_name`, among ``tracked.fitted``) by
    :func:`mean_texture` of the video's ``frames`` (from frame 0, ``size`` (W, H)) at the
    track's estimates, and return the head loaded again. The file is replaced whole (written
    to a temporary name first)."""
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
    new = mean_texture(tracked.model, analysis.camera, size, analysis.frames, frames, texture)
    with atomic_path(path) as tmp:
        Image.fromarray(new).save(tmp, format="PNG", compress_level=3)
    return load_model(str(tracked.fitted[0]))
