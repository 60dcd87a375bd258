"""Face landmarks from photographs: MediaPipe's detector and face mesh on LiteRT."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from vtts.errors import FitError, VttsError
from vtts.fit import landmarks as lm
from vtts.fit.landmarks import (
    LANDMARK_GROUPS,
    MIRROR_PAIRS,
    Face,
    MediaPipeDetector,
    default_detector,
    detect_faces,
)

PHOTOS = Path(__file__).parents[1] / "data" / "photos"
NAMES = ["akiyo_frame0", "astronaut"]


def load(name: str) -> np.ndarray:
    return np.asarray(Image.open(PHOTOS / f"{name}.png").convert("RGB"))


@pytest.fixture(scope="module")
def detector() -> MediaPipeDetector:
    return MediaPipeDetector()


@pytest.fixture(scope="module")
def reference(detector) -> dict[str, Face]:
    """The one face of each photo as found upright and unchanged."""
    return {name: detector.detect(load(name))[0] for name in NAMES}


@pytest.mark.parametrize("name", NAMES)
def test_one_confident_face_per_photo(detector, name):
    faces = detector.detect(load(name))
    assert len(faces) == 1
    (face,) = faces
    assert face.score > 0.8 and face.presence > 0.9
    assert face.landmarks.shape == (468, 3) and face.landmarks.dtype == np.float64
    assert face.keypoints.shape == (6, 2)
    assert len(face.box) == 4 and all(isinstance(v, float) for v in face.box)


@pytest.mark.parametrize("name", NAMES)
def test_landmarks_lie_in_the_face_box(reference, name):
    face = reference[name]
    x0, y0, x1, y1 = face.box
    margin = 0.15 * face.size  # the mesh reaches the forehead, above the detector's box
    xy = face.landmarks[:, :2]
    assert (xy >= [x0 - margin, y0 - margin]).all() and (xy <= [x1 + margin, y1 + margin]).all()
    features = list(lm.RIGHT_EYE + lm.LEFT_EYE + lm.LIPS_OUTER) + [lm.NOSE_TIP]
    inner = face.landmarks[features, :2]
    assert (inner > [x0, y0]).all() and (inner < [x1, y1]).all()


@pytest.mark.parametrize("name", NAMES)
def test_eye_corners_order_and_distance(reference, name):
    face = reference[name]
    x = face.landmarks[:, 0]
    # The subject's right eye is on the image's left: 33 outer, 133 inner, then 362, 263.
    assert x[33] < x[133] < x[362] < x[263]
    eyes = np.linalg.norm(face.landmarks[263, :2] - face.landmarks[33, :2])
    assert 0.45 * face.size < eyes < 0.85 * face.size
    y = face.landmarks[:, 1]
    assert max(y[33], y[263]) < y[lm.NOSE_TIP] < y[13] < y[14] < y[152]


@pytest.mark.parametrize("name", NAMES)
def test_mirrored_photo_gives_mirrored_landmarks(detector, reference, name):
    image = load(name)
    width = image.shape[1]
    (flipped,) = detector.detect(np.ascontiguousarray(image[:, ::-1]))
    pairs = np.array(MIRROR_PAIRS)
    a = np.r_[pairs[:, 0], pairs[:, 1]]
    b = np.r_[pairs[:, 1], pairs[:, 0]]
    original = reference[name].landmarks[a, :2]
    mirrored = flipped.landmarks[b, :2] * [-1, 1] + [width, 0]
    assert np.abs(mirrored - original).max() < 3.0
    # Pixel centres at +0.5 make the flip x -> W - x exactly; W - 1 - x would show as a
    # 1-pixel bias.
    assert abs((mirrored - original)[:, 0].mean()) < 0.6


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("turns", [1, 3])
def test_rotated_photo_gives_rotated_landmarks(detector, reference, name, turns):
    image = load(name)
    (rotated,) = detector.detect(np.ascontiguousarray(np.rot90(image, turns)))
    expected = reference[name].landmarks[:, :2]
    height, width = image.shape[:2]
    for _ in range(turns):  # np.rot90 turns counter-clockwise: (x, y) -> (y, W - x)
        expected = np.stack([expected[:, 1], width - expected[:, 0]], axis=1)
        height, width = width, height
    error = np.linalg.norm(rotated.landmarks[:, :2] - expected, axis=1)
    assert error.max() < 4.0 and error.mean() < 1.5


def test_two_faces_largest_first(detector, reference):
    photo = Image.open(PHOTOS / "akiyo_frame0.png").convert("RGB")
    canvas = Image.new("RGB", (560, 420), (90, 110, 130))
    canvas.paste(photo.resize((246, 202)), (300, 210))  # 0.7 x, pasted first on purpose
    canvas.paste(photo, (0, 0))
    faces = detector.detect(np.asarray(canvas))
    assert len(faces) == 2
    big, small = faces
    assert big.size > small.size
    expected = reference["akiyo_frame0"].landmarks[:, :2]
    assert np.abs(big.landmarks[:, :2] - expected).max() < 3.0
    eyes = [33, 133, 362, 263, lm.NOSE_TIP]
    scaled = (small.landmarks[eyes, :2] - [300, 210]) / [246 / 352, 202 / 288]
    assert np.abs(scaled - expected[eyes]).max() < 4.0


@pytest.mark.parametrize(
    "window", [(slice(40, None), slice(200, None)), (slice(80, 170), slice(None))]
)
def test_face_at_the_border(detector, reference, window):
    rows, cols = window
    image = np.ascontiguousarray(load("astronaut")[window])
    (face,) = detector.detect(image)
    offset = [cols.start or 0, rows.start or 0]
    eyes = [33, 133, 362, 263]
    expected = reference["astronaut"].landmarks[eyes, :2]
    assert np.abs(face.landmarks[eyes, :2] + offset - expected).max() < 4.0


@pytest.mark.parametrize(
    "image",
    [
        np.zeros((200, 300, 3), np.uint8),
        np.full((120, 90, 3), 128, np.uint8),
        np.random.default_rng(0).integers(0, 256, (240, 320, 3), dtype=np.uint8),
        np.zeros((1, 1, 3), np.uint8),
    ],
    ids=["black", "gray", "noise", "1x1"],
)
def test_no_face(detector, image):
    assert detector.detect(image) == []


def test_tiny_photo_gives_no_face(detector):
    tiny = Image.open(PHOTOS / "akiyo_frame0.png").convert("RGB").resize((16, 16))
    assert detector.detect(np.asarray(tiny)) == []


@pytest.mark.parametrize(
    "image",
    [
        np.zeros((64, 64), np.uint8),
        np.zeros((64, 64, 4), np.uint8),
        np.zeros((64, 64, 3), np.float32),
        np.zeros((0, 64, 3), np.uint8),
        [[[0, 0, 0]]],
    ],
    ids=["gray", "rgba", "float", "empty", "list"],
)
def test_bad_image_raises(detector, image):
    with pytest.raises(FitError) as info:
        detector.detect(image)
    assert isinstance(info.value, VttsError)


def test_detect_faces_uses_one_shared_detector(reference):
    assert default_detector() is default_detector()
    (face,) = detect_faces(load("akiyo_frame0"))
    np.testing.assert_allclose(face.landmarks, reference["akiyo_frame0"].landmarks, atol=1e-6)


def test_detect_faces_with_another_detector():
    class Fixed:
        def detect(self, image):
            return ["a face"]

    assert detect_faces(np.zeros((8, 8, 3), np.uint8), Fixed()) == ["a face"]


def test_landmark_groups_and_mirror_pairs():
    for name, indices in LANDMARK_GROUPS.items():
        assert all(0 <= i < lm.N_LANDMARKS for i in indices), name
        assert len(set(indices)) == len(indices), name
    assert len(lm.RIGHT_EYE) == len(lm.LEFT_EYE)
    assert len(lm.RIGHT_EYEBROW) == len(lm.LEFT_EYEBROW)
    flat = [i for pair in MIRROR_PAIRS for i in set(pair)]
    assert len(flat) == len(set(flat))  # each landmark has one mirror partner
    assert set(flat) == {i for indices in LANDMARK_GROUPS.values() for i in indices}
    assert (33, 263) in MIRROR_PAIRS and (61, 291) in MIRROR_PAIRS and (152, 152) in MIRROR_PAIRS


def test_face_group(reference):
    face = reference["akiyo_frame0"]
    assert face.group("lips_outer").shape == (len(lm.LIPS_OUTER), 2)
    with pytest.raises(FitError, match="unknown landmark group 'mouth'"):
        face.group("mouth")


@pytest.mark.parametrize("angle", [0.0, np.pi / 2])
def test_sampling_puts_pixel_centres_at_half(angle):
    image = np.zeros((40, 40, 3), np.uint8)
    image[10, 20] = 255
    crop = lm.Crop(np.array([20.5, 10.5]), 3.0, angle)
    window = np.asarray(lm.warp(Image.fromarray(image), crop, 3))
    expected = np.zeros((3, 3, 3), np.uint8)
    expected[1, 1] = 255
    np.testing.assert_array_equal(window, expected)


def test_building_a_detector_prints_nothing():
    code = "from vtts.fit.landmarks import MediaPipeDetector; MediaPipeDetector()"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stderr == "" and r.stdout == ""


def _small_face(face_px: float, where=(0, 0), side: int = 1024) -> np.ndarray:
    """The astronaut photo (a face 92 pixels wide in 512) scaled so that its face is
    ``face_px`` wide, on a grey ``side``² canvas at ``where``."""
    photo = Image.open(Path(__file__).parents[1] / "data" / "photos" / "astronaut.png")
    k = face_px / 92.0
    scaled = photo.convert("RGB").resize((round(512 * k), round(512 * k)))
    canvas = Image.new("RGB", (side, side), (200, 200, 200))
    canvas.paste(scaled, where)
    return np.asarray(canvas)


@pytest.mark.parametrize("face_px", [40, 74, 100, 150, 200])
@pytest.mark.parametrize("where", [(0, 0), (400, 450)])
def test_a_small_face_in_a_large_photo_is_found(face_px, where):
    """Faces under about a tenth of a 1024² photo were not found: the detector sees the whole
    photo at 128 pixels. Overlapping tiles find them."""
    faces = detect_faces(_small_face(face_px, where))
    assert len(faces) == 1
    width = float(np.ptp(faces[0].landmarks[:, 0]))
    assert width == pytest.approx(face_px, rel=0.15)


def test_tiles_find_no_face_where_there_is_none():
    assert detect_faces(np.full((1024, 1024, 3), 200, np.uint8)) == []
