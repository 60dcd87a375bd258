"""Face landmarks from a photograph, offline: the first step of fitting a head to a photo.

One small interface, :class:`LandmarkDetector` (``detect(image) -> list[Face]``), and one
implementation, :class:`MediaPipeDetector`: MediaPipe's BlazeFace short-range detector and its
468-point face mesh model (both Apache-2.0, shipped in ``vtts/data/landmarks/``) run on
``ai-edge-litert``. Nothing is downloaded; the models are found through :mod:`vtts.resources`.

Coordinates: x right, y down, in image pixels, continuous, with the origin at the top-left corner
of the top-left pixel, so the centre of pixel ``image[i, j]`` is ``(j + 0.5, i + 0.5)``. Under
this convention a horizontal flip maps ``x`` to ``W - x`` exactly.

Landmark indices are MediaPipe's. "Right" and "left" are the subject's: the right eye (33 outer
corner, 133 inner corner) appears on the image's left in an unmirrored photo.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from PIL import Image

from vtts.errors import FitError, VttsWarning
from vtts.resources import package_data

# ---------------------------------------------------------------------------------------------
# Named landmark groups. The indices and their order come from MediaPipe's connection sets
# (mediapipe/python/solutions/face_mesh_connections.py: FACEMESH_RIGHT_EYE, FACEMESH_LIPS, ...),
# chained into closed contours. Right and left groups list corresponding points at the same
# positions, so that zipping them gives the face's mirror pairs.

RIGHT_EYE = (33, 7, 163, 144, 145, 153, 154, 155, 133, 173, 157, 158, 159, 160, 161, 246)
"""Right eye contour (closed): outer corner 33, lower lid, inner corner 133, upper lid."""
LEFT_EYE = (263, 249, 390, 373, 374, 380, 381, 382, 362, 398, 384, 385, 386, 387, 388, 466)
"""Left eye contour (closed): outer corner 263, lower lid, inner corner 362, upper lid."""
RIGHT_EYEBROW = (70, 63, 105, 66, 107, 55, 65, 52, 53, 46)
"""Right brow contour (closed): upper edge from the outer end, then the lower edge back."""
LEFT_EYEBROW = (300, 293, 334, 296, 336, 285, 295, 282, 283, 276)
"""Left brow contour (closed), in the same order as :data:`RIGHT_EYEBROW`."""
LIPS_OUTER = (
    61, 146, 91, 181, 84, 17, 314, 405, 321, 375,
    291, 409, 270, 269, 267, 0, 37, 39, 40, 185,
)  # fmt: skip
"""Outer lip contour (closed): right corner 61, lower lip, left corner 291, upper lip (0 top)."""
LIPS_INNER = (
    78, 95, 88, 178, 87, 14, 317, 402, 318, 324,
    308, 415, 310, 311, 312, 13, 82, 81, 80, 191,
)  # fmt: skip
"""Inner lip contour (closed): right corner 78, lower lip (14), left corner 308, upper lip (13)."""
FACE_OVAL = (
    10, 338, 297, 332, 284, 251, 389, 356, 454, 323, 361, 288, 397, 365, 379, 378, 400, 377,
    152, 148, 176, 149, 150, 136, 172, 58, 132, 93, 234, 127, 162, 21, 54, 103, 67, 109,
)  # fmt: skip
"""Face oval (closed): forehead top 10, down the left side to the chin 152, up the right side."""
NOSE_TIP = 1
"""The tip of the nose (MediaPipe's ``noseTip``)."""

EYE_CORNERS = {"right_outer": 33, "right_inner": 133, "left_inner": 362, "left_outer": 263}
"""The four eye corners; left to right in an unmirrored photo: 33, 133, 362, 263."""


def eye_centres(landmarks: np.ndarray) -> np.ndarray:
    """``(2, 2)`` float64: the right and the left eye's centres, the midpoints of each eye's
    corners (:data:`EYE_CORNERS`) of ``landmarks (468, ≥2)`` (pixels)."""
    pts = np.asarray(landmarks, np.float64)[:, :2]
    return np.stack([pts[[33, 133]].mean(axis=0), pts[[362, 263]].mean(axis=0)])


def eye_distance(landmarks: np.ndarray) -> float:
    """The distance between the eyes' centres (:func:`eye_centres`) of ``landmarks (468, ≥2)``
    (pixels)."""
    right, left = eye_centres(landmarks)
    return float(np.linalg.norm(right - left))


LANDMARK_GROUPS: dict[str, tuple[int, ...]] = {
    "right_eye": RIGHT_EYE,
    "left_eye": LEFT_EYE,
    "right_eyebrow": RIGHT_EYEBROW,
    "left_eyebrow": LEFT_EYEBROW,
    "lips_outer": LIPS_OUTER,
    "lips_inner": LIPS_INNER,
    "face_oval": FACE_OVAL,
    "nose_tip": (NOSE_TIP,),
}
"""Every named group by name, as index tuples into :attr:`Face.landmarks`."""


def _mirror_pairs() -> tuple[tuple[int, int], ...]:
    pairs = set(zip(RIGHT_EYE, LEFT_EYE, strict=True))
    pairs |= set(zip(RIGHT_EYEBROW, LEFT_EYEBROW, strict=True))
    # The lips and the oval are symmetric in themselves, about the midline points at positions
    # 5/15 of the lips (lower, upper lip centre) and 0/18 of the oval (forehead top, chin).
    for loop, axis in ((LIPS_OUTER, 5), (LIPS_INNER, 5), (FACE_OVAL, 0)):
        n = len(loop)
        half = n // 2
        pairs |= {(loop[(axis + k) % n], loop[(axis - k) % n]) for k in range(1, half)}
        pairs |= {(loop[axis], loop[axis]), (loop[(axis + half) % n], loop[(axis + half) % n])}
    pairs.add((NOSE_TIP, NOSE_TIP))
    return tuple(sorted((min(a, b), max(a, b)) for a, b in pairs))


MIRROR_PAIRS = _mirror_pairs()
"""``(i, j)`` pairs of landmarks that swap under a left-right mirror of the face (``i == j`` on
the midline), for every point of the named groups: a mirrored photo's landmark ``j`` lies where
the original's landmark ``i`` lies, reflected."""

N_LANDMARKS = 468


@dataclass
class Face:
    """One face found in an image; every coordinate in image pixels (see the module docstring).

    ``box``: ``(x0, y0, x1, y1)`` the detector's face box. ``score``: the detector's confidence
    in [0, 1]. ``keypoints``: ``(6, 2) float64`` the detector's right eye, left eye, nose tip,
    mouth centre, right ear tragion, left ear tragion. ``landmarks``: ``(468, 3) float64`` the
    face mesh, x and y in image pixels, z the relative depth in the same pixel scale (smaller is
    nearer the camera, roughly zero at the face's centre plane). ``presence``: the mesh model's
    confidence in [0, 1] that its crop holds a face.
    """

    box: tuple[float, float, float, float]
    score: float
    keypoints: np.ndarray
    landmarks: np.ndarray
    presence: float

    @property
    def size(self) -> float:
        """The box's longer side in pixels."""
        x0, y0, x1, y1 = self.box
        return max(x1 - x0, y1 - y0)

    def group(self, name: str) -> np.ndarray:
        """``(n, 2) float64`` the x, y of a named landmark group (see :data:`LANDMARK_GROUPS`)."""
        try:
            indices = LANDMARK_GROUPS[name]
        except KeyError:
            raise FitError(
                f"unknown landmark group {name!r}, expected one of {sorted(LANDMARK_GROUPS)}"
            ) from None
        return self.landmarks[list(indices), :2]


class LandmarkDetector(Protocol):
    """Anything that finds faces and their 468 MediaPipe-indexed landmarks in an RGB image."""

    def detect(self, image: np.ndarray) -> list[Face]:
        """Faces in ``image`` (``(H, W, 3) uint8`` RGB), the largest first; empty when none."""
        ...


def check_image(image: np.ndarray) -> np.ndarray:
    """``image`` as a C-contiguous ``(H, W, 3) uint8`` array, or :class:`FitError`."""
    if not isinstance(image, np.ndarray):
        raise FitError(f"image must be a numpy array, got {type(image).__name__}")
    if image.ndim != 3 or image.shape[2] != 3:
        raise FitError(f"image must be (H, W, 3) RGB, got shape {image.shape}")
    if image.dtype != np.uint8:
        raise FitError(f"image must be uint8, got {image.dtype}")
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise FitError(f"image must not be empty, got shape {image.shape}")
    return np.ascontiguousarray(image)


# ---------------------------------------------------------------------------------------------
# BlazeFace short range: 896 anchors, 2 per cell on the 16x16 stride-8 grid, then 6 per cell on
# one 8x8 stride-16 grid (the model's three stride-16 layers merged), each ordered row, column,
# anchor. A wrong order still finds small faces (stride-8 anchors) and breaks on large ones.

DETECTOR_SIZE = 128
MESH_SIZE = 192
CROP_SCALE = 1.5  # the mesh crop's side over the face box's longer side, as MediaPipe
IOU_THRESHOLD = 0.3
RECROP_DEGREES = 10.0  # eyes tilted more than this in the mesh crop: crop again from the mesh
STRONG_ROLL_DEGREES = 30.0  # beyond this roll, crop again until the crop turns less than ...
RECROP_STRONG_DEGREES = 2.0  # ... this
MAX_RECROPS = 4
#: Where the whole image shows no face: the detector run again over overlapping squares of a
#: half, then a third of the image's longer side (a small face in a large photo).
TILINGS = (2, 3)


def _anchors() -> np.ndarray:
    grids = []
    for cells, per_cell in ((16, 2), (8, 6)):
        centres = (np.arange(cells) + 0.5) / cells
        cy, cx = np.meshgrid(centres, centres, indexing="ij")
        xy = np.stack([cx.ravel(), cy.ravel()], axis=1)
        grids.append(np.repeat(xy, per_cell, axis=0))
    return np.concatenate(grids)


_ANCHORS = _anchors()  # (896, 2) anchor centres in [0, 1]


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-np.clip(x, -100.0, 100.0)))


def _iou(box: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    x0 = np.maximum(box[0], boxes[:, 0])
    y0 = np.maximum(box[1], boxes[:, 1])
    x1 = np.minimum(box[2], boxes[:, 2])
    y1 = np.minimum(box[3], boxes[:, 3])
    inter = np.clip(x1 - x0, 0, None) * np.clip(y1 - y0, 0, None)
    area = (box[2] - box[0]) * (box[3] - box[1])
    areas = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
    return inter / np.maximum(area + areas - inter, 1e-12)


def _suppress(found: list) -> list:
    """Detections from overlapping tiles without the repeats: the best-scoring of each group of
    boxes overlapping by more than :data:`IOU_THRESHOLD`."""
    found = sorted(found, key=lambda f: -f[1])
    kept: list = []
    for f in found:
        if not kept or (_iou(f[0], np.array([k[0] for k in kept])) <= IOU_THRESHOLD).all():
            kept.append(f)
    return kept


def decode_detections(
    regressors: np.ndarray, logits: np.ndarray, min_score: float
) -> list[tuple[np.ndarray, float, np.ndarray]]:
    """BlazeFace outputs to faces in the detector's unit square.

    ``regressors``: ``(896, 16)``; ``logits``: ``(896,)``. Returns ``(box (4,), score,
    keypoints (6, 2))`` per face, ``box`` as ``x0, y0, x1, y1`` in [0, 1] of the 128-px input,
    after weighted non-maximum suppression (overlapping detections averaged by score).
    """
    scores = _sigmoid(logits.astype(np.float64))
    keep = np.flatnonzero(scores >= min_score)
    if keep.size == 0:
        return []
    raw = regressors[keep].astype(np.float64) / DETECTOR_SIZE
    anchors = _ANCHORS[keep]
    centre = raw[:, 0:2] + anchors
    half = raw[:, 2:4] / 2
    boxes = np.concatenate([centre - half, centre + half], axis=1)
    keypoints = raw[:, 4:16].reshape(-1, 6, 2) + anchors[:, None, :]
    scores = scores[keep]

    faces = []
    remaining = np.argsort(-scores, kind="stable")
    while remaining.size:
        best = remaining[0]
        overlap = _iou(boxes[best], boxes[remaining]) > IOU_THRESHOLD
        group = remaining[overlap]
        weights = scores[group] / scores[group].sum()
        box = weights @ boxes[group]
        kps = np.tensordot(weights, keypoints[group], axes=1)
        faces.append((box, float(scores[best]), kps))
        remaining = remaining[~overlap]
    return faces


@dataclass(frozen=True)
class Crop:
    """A square, rotated window of the image: ``centre`` (x, y) and ``size`` in pixels, ``angle``
    in radians (the crop's x axis is the image's rotated by ``angle``, clockwise on screen)."""

    centre: np.ndarray
    size: float
    angle: float

    def to_image(self, points: np.ndarray) -> np.ndarray:
        """``(n, 2)`` crop coordinates in [0, 1] to image pixels."""
        c, s = math.cos(self.angle), math.sin(self.angle)
        rotation = np.array([[c, -s], [s, c]])
        return self.centre + ((points - 0.5) * self.size) @ rotation.T


def _crop_from_points(points: np.ndarray, angle: float) -> Crop:
    """The crop around ``points`` ``(n, 2)`` as seen rotated by ``-angle``, 1.5 x its longer
    side: MediaPipe's crop from the previous landmarks, but with the box taken in the rotated
    frame so that a strongly rolled face is not cropped too large."""
    c, s = math.cos(angle), math.sin(angle)
    rotation = np.array([[c, -s], [s, c]])
    local = points @ rotation  # rotate by -angle
    lo, hi = local.min(axis=0), local.max(axis=0)
    centre = rotation @ ((lo + hi) / 2)
    return Crop(centre, CROP_SCALE * float(np.max(hi - lo)), angle)


def _eye_angle(right: np.ndarray, left: np.ndarray) -> float:
    # The subject's right eye is on the image's left: the vector right -> left points along +x
    # for an upright face, so its direction is the face's roll (image y down).
    d = left - right
    return math.atan2(d[1], d[0])


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


class MediaPipeDetector:
    """MediaPipe's BlazeFace short-range detector plus its 468-point face mesh, on LiteRT.

    ``threads``: CPU threads of each interpreter. ``min_score``: the least detector confidence
    kept. ``min_presence``: the least face-mesh presence kept (a detection whose crop the mesh
    model does not take for a face is dropped). The two interpreters are built once and reused;
    a detector is not thread-safe (make one per thread).
    """

    def __init__(self, threads: int = 2, min_score: float = 0.5, min_presence: float = 0.5):
        from ai_edge_litert.interpreter import Interpreter

        self.min_score = float(min_score)
        self.min_presence = float(min_presence)
        with without_litert_banner():
            self._detector = Interpreter(
                model_path=str(package_data("landmarks/face_detection_short_range.tflite")),
                num_threads=threads,
            )
            self._mesh = Interpreter(
                model_path=str(package_data("landmarks/face_landmark.tflite")), num_threads=threads
            )
            self._detector_io = self._io(self._detector, (16, 1))
            self._mesh_io = self._io(self._mesh, (1404, 1))

    @staticmethod
    def _io(interpreter, last_dims: tuple[int, int]) -> tuple[int, int, int]:
        """Input index and the two outputs' indices, told apart by their last dimension (the
        tensor names differ between exports of the same model)."""
        interpreter.allocate_tensors()
        (inp,) = interpreter.get_input_details()
        by_dim = {int(d["shape"][-1]): d["index"] for d in interpreter.get_output_details()}
        return inp["index"], by_dim[last_dims[0]], by_dim[last_dims[1]]

    def detect(self, image: np.ndarray) -> list[Face]:
        """Faces in ``image`` (``(H, W, 3) uint8`` RGB), the largest face (by its landmarks) first.

        Raises :class:`FitError` for anything but an ``(H, W, 3) uint8`` array; an image without
        a face gives an empty list.
        """
        image = check_image(image)
        picture = Image.fromarray(image)
        faces = []
        for box, score, keypoints in self._detect_boxes(picture):
            face = self._mesh_face(picture, box, score, keypoints)
            if face is not None:
                faces.append(face)
        # largest first, by the mesh's extent: the detector's boxes are coarse (two faces 15 %
        # apart in size can get boxes the other way round)
        faces.sort(key=lambda f: -float(np.ptp(f.landmarks[:, 0]) * np.ptp(f.landmarks[:, 1])))
        return faces

    def follow(self, image: np.ndarray, landmarks: np.ndarray) -> Face | None:
        """The face mesh on the crop that ``landmarks`` ``(468, ≥2)`` give — the last frame's,
        or where an estimate expects them — as MediaPipe tracks a face from one video frame to
        the next: no detector pass. None when the mesh model does not see a face there (its
        presence under ``min_presence``). The face's ``box`` is its landmarks' extent, its
        ``score`` the presence, its ``keypoints`` taken from the landmarks."""
        image = check_image(image)
        points = np.asarray(landmarks, dtype=np.float64)[:, :2]
        if points.shape != (N_LANDMARKS, 2) or not np.isfinite(points).all():
            raise FitError(f"landmarks to follow must be ({N_LANDMARKS}, 2) finite pixels, "
                           f"got shape {np.shape(landmarks)}")  # fmt: skip
        crop = _crop_from_points(points, _eye_angle(points[33], points[263]))
        found, presence = self._mesh_landmarks(Image.fromarray(image), crop)
        if presence < self.min_presence:
            return None
        xy = found[:, :2]
        keypoints = np.stack([
            xy[[33, 133]].mean(0), xy[[362, 263]].mean(0), xy[NOSE_TIP], xy[[13, 14]].mean(0),
            xy[234], xy[454],
        ])  # fmt: skip
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        box = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
        return Face(box=box, score=presence, keypoints=keypoints, landmarks=found,
                    presence=presence)  # fmt: skip

    def _detect_boxes(self, picture: Image.Image):
        """Detections in image pixels: the image letterboxed (centred, black borders) into a
        square, scaled to 128 px and mapped to [-1, 1]. Where that finds no face, overlapping
        squares of a half, then a third of the image's side (:data:`TILINGS`): the detector
        looks at 128 pixels, where a face a fifth of a large photo's width is too small to
        find."""
        w, h = picture.size
        side = float(max(w, h))
        found = list(self._detect_in(picture, Crop(np.array([w / 2, h / 2]), side, 0.0)))
        for n in TILINGS:
            if found or side / n < DETECTOR_SIZE:
                break
            tile = side / n
            # tiles overlapping by half: a face up to half a tile lies whole in one of them
            xs = np.linspace(tile / 2, max(w - tile / 2, tile / 2), max(2 * round(w / tile) - 1, 1))
            ys = np.linspace(tile / 2, max(h - tile / 2, tile / 2), max(2 * round(h / tile) - 1, 1))
            for y in ys:
                for x in xs:
                    found += self._detect_in(picture, Crop(np.array([x, y]), tile, 0.0))
            found = _suppress(found)
        yield from found

    def _detect_in(self, picture: Image.Image, window: Crop):
        """Detections in the square ``window`` of ``picture``, in image pixels."""
        small = warp(picture, window, DETECTOR_SIZE)
        tensor = np.asarray(small, dtype=np.float32)[None] * (2 / 255) - 1
        inp, regressors, logits = self._detector_io
        self._detector.set_tensor(inp, tensor)
        self._detector.invoke()
        found = decode_detections(
            self._detector.get_tensor(regressors)[0],
            self._detector.get_tensor(logits)[0, :, 0],
            self.min_score,
        )
        corner = window.centre - window.size / 2
        return [(box * window.size + np.tile(corner, 2), score, keypoints * window.size + corner)
                for box, score, keypoints in found]  # fmt: skip

    def _mesh_face(
        self, picture: Image.Image, box: np.ndarray, score: float, keypoints: np.ndarray
    ) -> Face | None:
        angle = _eye_angle(keypoints[0], keypoints[1])
        centre = (box[:2] + box[2:]) / 2
        crop = Crop(centre, CROP_SCALE * float(np.max(box[2:] - box[:2])), angle)
        landmarks, presence = self._mesh_landmarks(picture, crop)
        # The detector's eye keypoints are coarse, worst on strongly rolled faces (60-90 degrees),
        # and the mesh model pulls its answer towards an upright crop: crop again from the mesh's
        # own eye corners, as MediaPipe does from one video frame to the next, until the crop
        # stops turning (each pass closes about two thirds of the remaining angle).
        for _ in range(MAX_RECROPS):
            roll = _eye_angle(landmarks[33, :2], landmarks[263, :2])
            strong = abs(_wrap(roll)) > math.radians(STRONG_ROLL_DEGREES)
            tolerance = RECROP_STRONG_DEGREES if strong else RECROP_DEGREES
            if abs(_wrap(roll - crop.angle)) <= math.radians(tolerance):
                break
            crop = _crop_from_points(landmarks[:, :2], roll)
            landmarks, presence = self._mesh_landmarks(picture, crop)
        if presence < self.min_presence:
            return None
        return Face(
            box=tuple(float(v) for v in box),
            score=score,
            keypoints=keypoints,
            landmarks=landmarks,
            presence=presence,
        )

    def _mesh_landmarks(self, picture: Image.Image, crop: Crop) -> tuple[np.ndarray, float]:
        """The mesh model on ``crop``: ``(468, 3)`` landmarks in image pixels, and presence."""
        window = warp(picture, crop, MESH_SIZE)
        tensor = np.asarray(window, dtype=np.float32)[None] * (1 / 255)
        inp, points, logit = self._mesh_io
        self._mesh.set_tensor(inp, tensor)
        self._mesh.invoke()
        raw = self._mesh.get_tensor(points).reshape(N_LANDMARKS, 3).astype(np.float64)
        presence = float(_sigmoid(self._mesh.get_tensor(logit).reshape(())))
        landmarks = np.empty_like(raw)
        landmarks[:, :2] = crop.to_image(raw[:, :2] / MESH_SIZE)
        landmarks[:, 2] = raw[:, 2] * (crop.size / MESH_SIZE)
        return landmarks, presence


def warp(picture: Image.Image, crop: Crop, out: int) -> Image.Image:
    """The rotated square ``crop`` of ``picture`` resampled to ``out`` x ``out``, black outside
    the image.

    Each output pixel is the mean of 2 x 2 nearest samples (Pillow's nearest transform at twice
    the size, then halved): as smooth as bilinear sampling and, here, a fifth of the time of
    Pillow's bilinear transform. A crop much larger than the output is first box-filtered down
    by an integer factor, so that neither stage aliases.
    """
    factor = int(crop.size / (2 * out))
    origin = np.zeros(2)
    if factor >= 2:
        reach = crop.size * math.sqrt(0.5) + factor
        x0, y0 = np.floor(crop.centre - reach).astype(int)
        x1, y1 = np.ceil(crop.centre + reach).astype(int)
        w, h = picture.size
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        if x1 - x0 >= factor and y1 - y0 >= factor:
            picture = picture.crop((x0, y0, x1, y1)).reduce(factor)
            origin = np.array([x0, y0], dtype=np.float64)
        else:
            factor = 1
    else:
        factor = 1
    # Pillow maps output pixel centres (u + 0.5, v + 0.5) to input coordinates and samples the
    # pixel that contains them: the same half-pixel convention as ours. Reduce maps pixel
    # [i k, (i + 1) k) to pixel i, so reduced coordinates are ours divided by k.
    c, s = math.cos(crop.angle), math.sin(crop.angle)
    step = crop.size / (2 * out) / factor
    corner = (crop.to_image(np.zeros((1, 2)))[0] - origin) / factor
    return picture.transform(
        (2 * out, 2 * out),
        Image.Transform.AFFINE,
        (c * step, -s * step, corner[0], s * step, c * step, corner[1]),
        resample=Image.Resampling.NEAREST,
        fillcolor=(0, 0, 0),
    ).reduce(2)


_BANNER = "INFO: Created TensorFlow Lite XNNPACK delegate for CPU."


@contextmanager
def without_litert_banner() -> Iterator[None]:
    """LiteRT's C++ library prints an INFO line on the process's stderr when it builds its first
    interpreter, past Python's ``sys.stderr``; the CLI's output should carry only vtts's own
    lines. Everything else written there meanwhile is passed on."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no usable stderr: nothing to hide
        yield
        return
    with tempfile.TemporaryFile() as capture:
        os.dup2(capture.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            capture.seek(0)
            lines = capture.read().decode(errors="replace").splitlines(keepends=True)
            rest = "".join(line for line in lines if not line.startswith(_BANNER))
            if rest:
                sys.stderr.write(rest)


_default: MediaPipeDetector | None = None


def default_detector() -> MediaPipeDetector:
    """The shared :class:`MediaPipeDetector`, built on first use."""
    global _default
    if _default is None:
        _default = MediaPipeDetector()
    return _default


def choose_face(
    faces: list[Face],
    face: int | None,
    where: str,
    doing: str,
    error: type[Exception] = FitError,
    stacklevel: int = 3,
) -> Face:
    """The face ``face`` (1 = the largest) of ``faces`` (largest first, not empty); with None
    the largest, and a warning when there are several. ``where`` names the picture in messages
    (``"the photo"``), ``doing`` what is done with the face (``"fitting"``); a ``face`` out of
    range raises ``error``."""
    if face is not None and not 1 <= face <= len(faces):
        raise error(
            f"--face {face}: {where} shows {len(faces)} face(s), numbered 1–{len(faces)} from "
            "the largest"
        )
    if face is None and len(faces) > 1:
        warnings.warn(
            VttsWarning(
                f"{where} shows {len(faces)} faces: {doing} the largest (choose another with "
                "--face N, 1 = largest)"
            ),
            stacklevel=stacklevel,
        )
    return faces[(face or 1) - 1]


def detect_faces(image: np.ndarray, detector: LandmarkDetector | None = None) -> list[Face]:
    """Faces in ``image`` (``(H, W, 3) uint8`` RGB), the largest first, with ``detector`` or the
    shared MediaPipe one."""
    return (detector or default_detector()).detect(image)
