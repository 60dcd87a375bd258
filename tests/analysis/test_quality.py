"""The decoder's view and the face PSNR of Equation 18 (``vtts.analysis.quality``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vtts.analysis.quality import (
    coverage,
    decoded_frames,
    face_psnr_rgb,
    sequence_psnr,
    side_by_side,
    stream_psnr,
)
from vtts.fap.stream import FapStream

SIZE = (176, 144)


def _stream(n: int, jaw: float = 0.0, tx: float = 0.0) -> FapStream:
    values = np.zeros((n, 68))
    mask = np.zeros((n, 68), bool)
    values[:, 2] = jaw
    mask[:, 2] = True
    translation = np.zeros((n, 3))
    translation[:, 0] = tx
    return FapStream(12.5, "q", values, mask, translation=translation)


def test_face_psnr_is_over_the_rgb_samples_of_the_mask():
    a = np.zeros((4, 4, 3))
    b = a.copy()
    b[0, 0] = (10, 0, 0)  # one sample off by 10 among the 3 of each of 2 masked pixels
    mask = np.zeros((4, 4), bool)
    mask[0, :2] = True
    assert face_psnr_rgb(a, b, mask) == pytest.approx(10 * math.log10(255**2 / (100 / 6)))
    assert face_psnr_rgb(a, a, mask) == math.inf
    assert math.isnan(face_psnr_rgb(a, b, np.zeros((4, 4), bool)))


def test_coverage_is_the_opaque_alpha_shrunk():
    rgba = np.zeros((9, 9, 4), np.uint8)
    rgba[1:8, 1:8, 3] = 255
    rgba[1, 1, 3] = 128  # a mixed outline pixel is not covered
    assert coverage(rgba, shrink=0).sum() == 48
    assert coverage(rgba, shrink=2).sum() == 9  # the 3x3 core


def test_mean_psnr_is_that_of_the_mean_squared_error():
    assert sequence_psnr(np.array([20.0, 20.0])) == pytest.approx(20.0)
    assert sequence_psnr(np.array([10.0, 30.0, np.nan])) == pytest.approx(
        10 * math.log10(2 / (0.1 + 0.001))
    )


def test_the_decoders_view_reproduces_itself_and_sees_a_moved_head():
    from vtts.face import load_model

    model = load_model("cybatt")
    still = _stream(2)
    frames = [rgba[..., :3] for rgba in decoded_frames(still, model, SIZE, viewpoint=None)]
    assert np.isinf(stream_psnr(frames, still, model, video_fps=12.5, viewpoint=None)).all()
    moved = _stream(2, jaw=300, tx=100)  # 100 ES units: about a tenth of the eye distance
    psnr = stream_psnr(frames, moved, model, video_fps=12.5, viewpoint=None)
    assert (psnr < 30).all(), psnr
    # at 25 fps the stream's frame i is compared with camera frame 2i; beyond the video: NaN
    psnr = stream_psnr(frames, still, model, video_fps=25.0, viewpoint=None)
    assert np.isinf(psnr[0]) and np.isnan(psnr[1])


def test_side_by_side_shows_camera_model_and_difference():
    frame = np.full((4, 5, 3), 100, np.uint8)
    rgba = np.zeros((4, 5, 4), np.uint8)
    rgba[:2, :, :3] = 90
    rgba[:2, :, 3] = 255
    row = side_by_side(frame, rgba)
    assert row.shape == (4, 15, 3)
    assert (row[:, :5] == 100).all()
    assert (row[:2, 5:10] == 90).all() and (row[2:, 5:10] == 128).all()  # grey where no model
    assert (row[:2, 10:] == 40).all() and (row[2:, 10:] == 0).all()  # |100 - 90| x 4
