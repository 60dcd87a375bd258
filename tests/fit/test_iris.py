"""MediaPipe's iris model on the eyes of a face mesh (vtts.fit.iris)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from matplotlib.path import Path as Polygon
from PIL import Image

from vtts.errors import FitError
from vtts.fit import iris as ir
from vtts.fit.landmarks import LEFT_EYE, MIRROR_PAIRS, RIGHT_EYE, MediaPipeDetector
from vtts.resources import package_data

PHOTOS = Path(__file__).parents[1] / "data" / "photos"
NAMES = ["akiyo_frame0", "astronaut"]
MESH_EYES = {"right": RIGHT_EYE, "left": LEFT_EYE}


def load(name: str) -> np.ndarray:
    return np.asarray(Image.open(PHOTOS / f"{name}.png").convert("RGB"))


@pytest.fixture(scope="module")
def detector() -> MediaPipeDetector:
    return MediaPipeDetector()


@pytest.fixture(scope="module")
def model() -> ir.IrisModel:
    return ir.IrisModel()


@pytest.fixture(scope="module")
def faces(detector) -> dict[str, np.ndarray]:
    """The face mesh of each photo."""
    return {name: detector.detect(load(name))[0].landmarks for name in NAMES}


@pytest.fixture(scope="module")
def eyes(model, faces) -> dict[str, ir.Eyes]:
    return {name: model.eyes(load(name), faces[name]) for name in NAMES}


def test_the_model_ships_with_the_package():
    path = package_data("landmarks/iris_landmark.tflite")
    assert path.is_file() and path.stat().st_size > 1_000_000
    assert path.parent.joinpath("LICENSE").is_file()


def test_the_contour_map_is_the_mesh_eyes_mirrored():
    right, left = ir.CONTOUR_LANDMARKS["right"], ir.CONTOUR_LANDMARKS["left"]
    assert len(right) == len(left) == ir.N_CONTOUR
    assert len(set(right) | set(left)) == 2 * ir.N_CONTOUR
    # the 16 lid points are the mesh's eye contours, and pair up as the mesh's mirror pairs
    assert set(right[:16]) == set(RIGHT_EYE) and set(left[:16]) == set(LEFT_EYE)
    pairs = set(MIRROR_PAIRS)
    assert all((min(a, b), max(a, b)) in pairs for a, b in zip(right[:16], left[:16], strict=True))
    assert right[ir.UPPER_MIDDLE] == 159 and right[ir.LOWER_MIDDLE] == 145
    assert left[ir.UPPER_MIDDLE] == 386 and left[ir.LOWER_MIDDLE] == 374


def test_the_crop_is_mediapipes():
    landmarks = np.zeros((468, 2))
    landmarks[33], landmarks[133] = (100.0, 50.0), (120.0, 56.0)
    crop = ir.eye_crop(landmarks, "right")
    np.testing.assert_allclose(crop.centre, [110.0, 53.0])
    assert crop.size == pytest.approx(2.3 * 20.0)  # the corners' bounding box's longer side
    assert crop.angle == pytest.approx(math.atan2(6.0, 20.0))
    landmarks[362], landmarks[263] = (200.0, 60.0), (203.0, 40.0)  # steep: the height counts
    crop = ir.eye_crop(landmarks, "left")
    assert crop.size == pytest.approx(2.3 * 20.0)
    assert crop.angle == pytest.approx(math.atan2(-20.0, 3.0))


@pytest.mark.parametrize("name", NAMES)
def test_iris_centres_lie_in_the_eyes(faces, eyes, name):
    landmarks = faces[name]
    for side, eye in eyes[name]:
        assert eye.iris.shape == (5, 3) and eye.contour.shape == (71, 3)
        assert eye.in_image == 1.0
        # inside the lids the model draws, and the mesh's eye contour
        assert Polygon(eye.lids).contains_point(eye.centre)
        mesh_eye = landmarks[list(MESH_EYES[side]), :2]
        assert Polygon(mesh_eye).contains_point(eye.centre)
        # within a few pixels of the mesh eye's centre; a plausible iris
        assert np.linalg.norm(eye.centre - mesh_eye.mean(axis=0)) < 3.0
        assert 0.12 < eye.radius / eye.width < 0.35
        assert eye.visible > 0.5
        # the model's lids where the mesh has them
        lids = landmarks[list(ir.CONTOUR_LANDMARKS[side][:16]), :2]
        assert np.median(np.linalg.norm(eye.lids - lids, axis=1)) < 0.1 * eye.width


def test_a_mirrored_frame_gives_mirrored_eyes(detector, model, eyes):
    image = load("akiyo_frame0")
    width = image.shape[1]
    flipped = np.ascontiguousarray(image[:, ::-1])
    mirrored = model.eyes(flipped, detector.detect(flipped)[0].landmarks)
    for side, other in (("right", "left"), ("left", "right")):
        a, b = getattr(eyes["akiyo_frame0"], side), getattr(mirrored, other)
        back = b.iris[:, :2] * [-1, 1] + [width, 0]
        assert np.abs(back[0] - a.centre).max() < 1.0
        assert np.abs(b.contour[:16, :2] * [-1, 1] + [width, 0] - a.lids).max() < 1.5


@pytest.mark.parametrize("turns", [1, 3])
def test_a_turned_frame_gives_turned_eyes(model, faces, eyes, turns):
    """The crop turns with the eye corners: the same landmarks turned give the same eyes."""
    image = load("akiyo_frame0")
    landmarks = faces["akiyo_frame0"][:, :2].copy()
    expected = {side: eye.iris[:, :2].copy() for side, eye in eyes["akiyo_frame0"]}
    height, width = image.shape[:2]
    for _ in range(turns):  # np.rot90 turns counter-clockwise: (x, y) -> (y, W - x)
        landmarks = np.stack([landmarks[:, 1], width - landmarks[:, 0]], axis=1)
        expected = {s: np.stack([p[:, 1], width - p[:, 0]], axis=1) for s, p in expected.items()}
        height, width = width, height
    turned = model.eyes(np.ascontiguousarray(np.rot90(image, turns)), landmarks)
    for side, eye in turned:
        assert np.linalg.norm(eye.iris[:, :2] - expected[side], axis=1).max() < 0.75


def test_refined_landmarks_take_the_eyes(faces, eyes):
    landmarks = faces["akiyo_frame0"]
    refined = eyes["akiyo_frame0"].refined(landmarks)
    assert refined.shape == landmarks.shape
    changed = np.flatnonzero((refined != landmarks).any(axis=1))
    seen = set(ir.CONTOUR_LANDMARKS["right"]) | set(ir.CONTOUR_LANDMARKS["left"])
    assert set(changed) <= seen and len(changed) > 100
    np.testing.assert_array_equal(refined[145, :2], eyes["akiyo_frame0"].right.contour[4, :2])


def test_an_eye_at_the_border_sees_the_border_repeated(model, faces):
    """Half the face out of the frame: the crop repeats the edge pixels, as MediaPipe's."""
    image = load("akiyo_frame0")
    landmarks = faces["akiyo_frame0"].copy()
    cut = int(landmarks[133, 0])  # the right eye's crop reaches well past this column
    eyes = model.eyes(np.ascontiguousarray(image[:, cut:]), landmarks - [cut, 0, 0])
    assert 0.0 < eyes.right.in_image < 0.7 and eyes.left.in_image == 1.0
    assert np.isfinite(eyes.right.iris).all()


@pytest.mark.parametrize(
    ("image", "landmarks", "message"),
    [
        (np.zeros((64, 64, 3), np.float32), np.zeros((468, 2)), "uint8"),
        (np.zeros((64, 64), np.uint8), np.zeros((468, 2)), r"\(H, W, 3\)"),
        ("photo.png", np.zeros((468, 2)), "numpy array"),
        (np.zeros((64, 64, 3), np.uint8), np.zeros((468, 1)), r"got shape \(468, 1\)"),
        (np.zeros((64, 64, 3), np.uint8), np.zeros((478, 3)), r"got shape \(478, 3\)"),
        (np.zeros((64, 64, 3), np.uint8), [[0.0, 0.0]] * 468, "numpy array"),
        (np.zeros((64, 64, 3), np.uint8), np.zeros((468, 2), bool), "numbers"),
        (np.zeros((64, 64, 3), np.uint8), np.full((468, 2), np.nan), "finite"),
        (np.zeros((64, 64, 3), np.uint8), np.ones((468, 2)), "right eye's corners coincide"),
    ],
)
def test_bad_input_is_a_fit_error(model, image, landmarks, message):
    with pytest.raises(FitError, match=message):
        model.eyes(image, landmarks)
