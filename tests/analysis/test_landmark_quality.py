"""Equation 18 over the face oval and the landmarks' geometry error
(``vtts.analysis.landmark_quality``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from vtts.analysis.landmark_quality import (
    MEASURED,
    camera_landmarks,
    eye_distance,
    geometry_error,
    lay_over,
    luminance,
    measure_frame,
    oval_mask,
    oval_psnr,
)
from vtts.errors import AnalysisError
from vtts.fit.landmarks import FACE_OVAL, MediaPipeDetector

PHOTO = Path(__file__).parents[1] / "data" / "photos" / "akiyo_frame0.png"


@pytest.fixture(scope="module")
def detector() -> MediaPipeDetector:
    return MediaPipeDetector()


@pytest.fixture(scope="module")
def akiyo(detector) -> tuple[np.ndarray, np.ndarray]:
    """Akiyo's first frame and the landmarks of her face on it."""
    frame = np.asarray(Image.open(PHOTO).convert("RGB"))
    landmarks = camera_landmarks(frame, detector)
    assert landmarks is not None
    return frame, landmarks


def _ring(points: np.ndarray) -> np.ndarray:
    """(468, 2) landmarks with ``points`` spread along the face-oval ring (the rest at its
    first point)."""
    landmarks = np.repeat(points[:1], 468, axis=0).astype(np.float64)
    at = np.linspace(0, len(points), len(FACE_OVAL), endpoint=False)
    for k, index in enumerate(FACE_OVAL):  # the ring walks the polygon's edges in order
        i = int(at[k])
        a, b = points[i], points[(i + 1) % len(points)]
        landmarks[index] = a + (at[k] - i) * (b - a)
    return landmarks


def test_oval_mask_is_the_pixels_whose_centres_lie_inside():
    # a rectangle x 2–8, y 3–7 (pixel edges): columns 2–7, rows 3–6
    rect = _ring(np.array([[2.0, 3.0], [8.0, 3.0], [8.0, 7.0], [2.0, 7.0]]))
    mask = oval_mask(rect, (12, 10))
    expected = np.zeros((10, 12), bool)
    expected[3:7, 2:8] = True
    np.testing.assert_array_equal(mask, expected)
    # a triangle: as many pixels as its area, within its outline's length; cut at the border
    tri = _ring(np.array([[10.0, 5.0], [70.0, 15.0], [25.0, 55.0]]))
    area = 0.5 * abs((70 - 10) * (55 - 5) - (25 - 10) * (15 - 5))
    assert abs(oval_mask(tri, (80, 60)).sum() - area) < 0.5 * 170
    assert oval_mask(tri - 40.0, (80, 60)).sum() < area / 2
    assert not oval_mask(tri + 200.0, (80, 60)).any()


def test_the_oval_ring_encloses_the_face(akiyo):
    """The ring order of FACE_OVAL: on a real face the polygon does not cross itself, so its
    mask has the ring's (shoelace) area and holds the eyes, nose and mouth."""
    frame, landmarks = akiyo
    h, w = frame.shape[:2]
    mask = oval_mask(landmarks, (w, h))
    x, y = landmarks[list(FACE_OVAL), 0], landmarks[list(FACE_OVAL), 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1)))
    assert mask.sum() == pytest.approx(area, rel=0.03)
    for index in (33, 263, 1, 13, 14):  # eye corners, nose tip, lips
        j, i = np.floor(landmarks[index, :2]).astype(int)
        assert mask[i, j]


def test_equation_18_is_luminance_psnr_over_the_mask():
    rng = np.random.default_rng(1)
    frame = rng.integers(20, 200, (6, 7, 3)).astype(np.uint8)
    mask = np.zeros((6, 7), bool)
    mask[1:5, 2:6] = True
    assert oval_psnr(frame, frame, mask) == math.inf
    # a uniform offset of 10 in R, G and B is one of 10 in Y: 20 log10(255 / 10)
    assert oval_psnr(frame, frame + 10, mask) == pytest.approx(20 * math.log10(25.5))
    # colour that keeps the luminance costs nothing; pixels outside the mask neither
    other = frame.astype(np.float64)
    other[..., 0] += 0.587 * 10
    other[..., 1] -= 0.299 * 10
    other[~mask] = 0
    assert oval_psnr(frame, other, mask) > 200
    assert math.isnan(oval_psnr(frame, frame, np.zeros((6, 7), bool)))
    np.testing.assert_allclose(luminance(np.full((1, 1, 3), 100.0)), 100.0)


def test_the_decoded_frame_is_laid_over_by_its_alpha():
    frame = np.full((2, 3, 3), 100, np.uint8)
    rgba = np.zeros((2, 3, 4), np.uint8)
    rgba[..., :3] = 200
    rgba[0, 0, 3] = 255
    rgba[0, 1, 3] = 51  # a fifth covered
    out = lay_over(frame, rgba)
    assert out[0, 0].tolist() == [200] * 3
    assert out[0, 1].tolist() == [120] * 3
    assert (out[1] == 100).all()
    with pytest.raises(AnalysisError, match="must agree"):
        lay_over(frame, rgba[:1])


def test_geometry_error_is_mean_distance_in_eye_distances(akiyo):
    _, landmarks = akiyo
    assert len(MEASURED) == 128
    assert geometry_error(landmarks, landmarks) == 0.0
    moved = landmarks.copy()
    moved[:, 0] += 0.1 * eye_distance(landmarks)
    assert geometry_error(landmarks, moved) == pytest.approx(10.0)
    with pytest.raises(AnalysisError, match="468"):
        geometry_error(landmarks, landmarks[:100])


def test_measures_of_an_identical_and_a_shifted_frame(akiyo, detector):
    frame, landmarks = akiyo
    h, w = frame.shape[:2]
    transparent = np.zeros((h, w, 4), np.uint8)
    same = measure_frame(frame, transparent, landmarks, detector)
    assert same.measured and same.eq18_db == math.inf and same.geometry_pct == 0.0
    assert same.covered == 0.0
    # the whole frame moved 6 pixels right, opaque: every landmark moves by about 6 pixels
    shift = 6
    moved = np.concatenate([np.repeat(frame[:, :1], shift, axis=1), frame[:, :-shift]], axis=1)
    rgba = np.concatenate([moved, np.full((h, w, 1), 255, np.uint8)], axis=2)
    m = measure_frame(frame, rgba, landmarks, detector)
    assert m.measured and m.covered == 1.0
    assert m.geometry_pct == pytest.approx(100 * shift / eye_distance(landmarks), rel=0.15)
    assert 12 < m.eq18_db < 25
    # no camera face: not measured; a head nowhere near the face: lost
    assert not measure_frame(frame, rgba, None, detector).camera_face
    far = landmarks.copy()
    far[:, :2] = far[:, :2] * 0.2  # a small face in the top-left corner
    lost = measure_frame(frame, transparent, far, detector)
    assert lost.lost and math.isnan(lost.geometry_pct)
