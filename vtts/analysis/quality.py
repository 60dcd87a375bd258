"""How well a stream reproduces the camera video: the decoder's view and the face PSNR.

A model-based coder is judged where the paper judges it (Eisert & Girod, Equation 18 and
Figure 15): the decoder renders the model with the decoded parameters, through the video's
camera, and the PSNR over RGB between that rendering and the camera frame is taken over the
pixels the model covers — its coverage (the alpha of a rendering with a transparent background),
shrunk by :data:`SHRINK` pixels so that the outline's mixed pixels do not count. Nothing the
encoder knows and the stream does not carry (the light correction of the analysis) is used.

>>> psnr = stream_psnr(frames, stream, model)      # (n,) dB, one per frame of the stream
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

import numpy as np
from scipy.ndimage import binary_erosion

from vtts.errors import AnalysisError
from vtts.face import FaceModel
from vtts.fap.stream import FapStream
from vtts.render.camera import Camera

#: Pixels the model's coverage is shrunk by before the face PSNR is taken.
SHRINK = 2
#: The Viewpoint through which a fitted head sees its video (``adi fit``'s).
VIEWPOINT = "photo"


def face_psnr_rgb(frame: np.ndarray, decoded: np.ndarray, mask: np.ndarray) -> float:
    """PSNR (dB) over the R, G and B samples of the ``(H, W)`` ``mask`` between two ``(H, W,
    ≥3)`` images (0–255): Equation 18 of the paper; ``inf`` when they agree, NaN when the mask
    is empty."""
    if not mask.any():
        return float("nan")
    a = np.asarray(frame, np.float64)[..., :3][mask]
    diff = a - np.asarray(decoded, np.float64)[..., :3][mask]
    mse = float(np.mean(diff**2))
    return float("inf") if mse == 0 else 10 * math.log10(255.0**2 / mse)


def coverage(rgba: np.ndarray, shrink: int = SHRINK) -> np.ndarray:
    """The ``(H, W)`` mask of pixels a transparent-background rendering ``rgba`` covers fully,
    shrunk by ``shrink`` pixels."""
    mask = np.asarray(rgba)[..., 3] == 255
    return binary_erosion(mask, iterations=shrink) if shrink else mask


def decoded_frames(
    stream: FapStream,
    model: FaceModel,
    size: tuple[int, int],
    viewpoint: str | None = VIEWPOINT,
    camera: Camera | None = None,
) -> Iterator[np.ndarray]:
    """The decoder's view: ``model`` rendered with each frame of ``stream`` (its FAPs and head
    translation) at ``size`` (W, H) through the model's ``viewpoint``, or ``camera`` (the
    renderer's world, as :attr:`Analysis.camera`), or the default framing when both are None,
    as ``(H, W, 4) uint8`` RGBA over a transparent background."""
    from vtts.animate.fapstream import head_roots, stream_params
    from vtts.render import FaceRenderer

    if camera is not None:
        viewpoint = None
    params = stream_params(stream, model.tables.adts).params
    with FaceRenderer(
        model, size=size, viewpoint=viewpoint, camera=camera, background="transparent"
    ) as r:
        roots = None
        if stream.translation is not None:
            roots = head_roots(r.model_matrix(0), stream.translation, model.fapu)
        for i in range(stream.n_frames):
            r.apply(r.prepare(params[i], roots=None if roots is None else [roots[i]]))
            yield r.render()


def stream_psnr(
    frames: Sequence[np.ndarray],
    stream: FapStream,
    model: FaceModel,
    *,
    video_fps: float,
    viewpoint: str | None = VIEWPOINT,
) -> np.ndarray:
    """Face PSNR (dB, RGB, :func:`face_psnr_rgb` over :func:`coverage`) of each frame of
    ``stream`` against the camera frame at its time: ``frames[round(t · video_fps)]`` for the
    stream's frame at time ``t``. ``(stream.n_frames,)``; frames beyond the video are NaN."""
    if not frames:
        raise AnalysisError("no camera frames to compare with")
    h, w = np.asarray(frames[0]).shape[:2]
    out = np.full(stream.n_frames, np.nan)
    for i, rgba in enumerate(decoded_frames(stream, model, (w, h), viewpoint)):
        k = round(i / stream.fps * video_fps)
        if k < len(frames):
            out[i] = face_psnr_rgb(frames[k], rgba, coverage(rgba))
    return out


def side_by_side(frame: np.ndarray, rgba: np.ndarray, gain: float = 4.0) -> np.ndarray:
    """One frame of ``side-by-side.mp4``: the camera ``frame`` ``(H, W, 3)``, the decoder's
    view ``rgba`` ``(H, W, 4)`` over mid-grey, and their absolute difference over the model's
    coverage, amplified ``gain`` times (black elsewhere): ``(H, 3W, 3) uint8``."""
    frame = np.asarray(frame, np.float32)[..., :3]
    alpha = rgba[..., 3:4].astype(np.float32) / 255.0
    model = rgba[..., :3].astype(np.float32) * alpha + 128.0 * (1 - alpha)
    diff = np.abs(frame - model) * gain * (rgba[..., 3:4] == 255)
    row = np.concatenate([frame, model, diff], axis=1)
    return np.clip(np.round(row), 0, 255).astype(np.uint8)


def sequence_psnr(psnr: np.ndarray) -> float:
    """The PSNR of the mean squared error over frames (dB), the usual figure for a sequence;
    frames with NaN are left out."""
    p = np.asarray(psnr, np.float64)
    p = p[~np.isnan(p)]
    if p.size == 0:
        return float("nan")
    mse = np.mean(255.0**2 / 10 ** (p / 10))
    return float("inf") if mse == 0 else 10 * math.log10(255.0**2 / mse)
