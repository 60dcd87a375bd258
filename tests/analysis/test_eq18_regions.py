"""scripts/eq18_regions.py: Equation 18's error split by region of the face and by kind
(docs/analysis.md, "Where Equation 18's error lies")."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ..scripts import load_script

eq18_regions = load_script("scripts/eq18_regions.py")

PHOTO = Path(__file__).parents[1] / "data" / "photos" / "akiyo_frame0.png"


@pytest.fixture(scope="module")
def face():
    from vtts.analysis.landmark_quality import camera_landmarks

    frame = np.asarray(Image.open(PHOTO).convert("RGB"))
    landmarks = camera_landmarks(frame)
    assert landmarks is not None
    return frame, landmarks


def _opaque(image: np.ndarray) -> np.ndarray:
    return np.concatenate([image, np.full(image.shape[:2] + (1,), 255, np.uint8)], axis=2)


def test_the_regions_split_the_oval(face):
    from vtts.analysis.landmark_quality import oval_mask

    frame, landmarks = face
    h, w = frame.shape[:2]
    parts = eq18_regions.regions(landmarks, (w, h))
    assert tuple(parts) == eq18_regions.REGIONS
    stacked = np.stack(list(parts.values())).astype(int)
    assert stacked.sum(0).max() == 1  # disjoint
    assert np.array_equal(stacked.sum(0).astype(bool), oval_mask(landmarks, (w, h)))
    assert all(m.any() for m in parts.values())


def test_an_error_in_the_mouth_alone_is_the_mouths(face):
    frame, landmarks = face
    h, w = frame.shape[:2]
    mouth = eq18_regions.regions(landmarks, (w, h))["mouth"]
    decoded = frame.copy()
    decoded[mouth] = 255 - decoded[mouth]
    tally = eq18_regions.Tally()
    tally.add(0, frame, _opaque(decoded), landmarks)
    result = tally.result(anchor=0)
    assert result["regions"]["mouth"]["error_pct"] == 100.0
    assert result["regions"]["mouth"]["oval_if_perfect_db"] is None  # no error left: inf
    assert result["regions"]["eyes"]["error_pct"] == 0.0
    assert result["anchor_frame"]["index"] == 0


def test_a_change_of_light_is_smooth_and_the_oracle_light_removes_it(face):
    frame, landmarks = face
    darker = np.clip(frame.astype(np.int16) - 20, 0, 255).astype(np.uint8)
    tally = eq18_regions.Tally()
    tally.add(0, frame, _opaque(darker), landmarks)
    result = tally.result()
    assert result["smooth_pct"] > 90
    assert result["eq18_pooled_db"] < 23
    assert result["oracle_light_db"] is None or result["oracle_light_db"] > 40


def test_a_blurred_texture_is_less_sharp_than_the_camera(face):
    from scipy import ndimage

    frame, landmarks = face
    blurred = ndimage.gaussian_filter(frame.astype(np.float64), (1.0, 1.0, 0))
    same, soft = eq18_regions.Tally(), eq18_regions.Tally()
    same.add(0, frame, _opaque(frame), landmarks)
    soft.add(0, frame, _opaque(np.round(blurred).astype(np.uint8)), landmarks)
    assert same.result()["sharpness_decoded_over_camera"] == pytest.approx(1.0)
    assert same.result()["eq18_pooled_db"] is None  # no error at all
    assert soft.result()["sharpness_decoded_over_camera"] < 0.6
