"""The eyes in detail: MediaPipe's iris model on a crop around each eye.

The face mesh (:mod:`vtts.fit.landmarks`) places the eyelids coarsely and says nothing of where
the eyes look. MediaPipe's iris landmark model (Apache-2.0, shipped as
``vtts/data/landmarks/iris_landmark.tflite``) looks at a 64 × 64 crop of one eye and gives 71
points of the eye's contour and its surroundings (the lids, four halos around them, the lower
edge of the brow) and 5 of the iris: its centre, then four on its edge. :class:`IrisModel` runs
it on both eyes of a face whose mesh is known (``eyes(image, landmarks) -> Eyes``).

The crop is MediaPipe's (``iris_landmark_landmarks_to_roi``, ``iris_landmark_cpu``): a square
centred between the eye's two corners (33 and 133 for the subject's right eye, 362 and 263 for
the left), of side :data:`CROP_SCALE` times the longer side of the corners' bounding box,
turned by the angle of the line from the first corner to the second; the part outside the image
repeats the border pixels. The model knows one eye: the crop of the subject's left eye is
mirrored left-right before the model and its points mirrored back.

Coordinates are those of :mod:`vtts.fit.landmarks`: x right, y down, image pixels, a pixel's
centre at +0.5; "right" and "left" are the subject's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from PIL import Image

from vtts.errors import FitError
from vtts.fit.landmarks import N_LANDMARKS, Crop, check_image, warp, without_litert_banner
from vtts.resources import package_data

#: The model's input side (pixels).
EYE_SIZE = 64
#: The crop's side over the longer side of the bounding box of the eye's corners (MediaPipe's
#: ``scale_x``/``scale_y``).
CROP_SCALE = 2.3
#: Each eye's corners as the crop takes them: (first, second) face-mesh landmarks; the crop's
#: x axis points from the first to the second.
EYE_CORNERS = {"right": (33, 133), "left": (362, 263)}
#: Points of the model's eye contour and of its iris.
N_CONTOUR = 71
N_IRIS = 5

#: The face-mesh landmark at each of the 71 contour points, per eye (MediaPipe's
#: ``update_face_landmarks_calculator``): the lower lid from the outer corner to the inner one
#: (0–8), the upper lid back without the corners (9–15), then halos around the eye (16–46), the
#: brow's lower edge (47–52), a fifth halo (53–61) and the brow's upper edge (62–70).
CONTOUR_LANDMARKS: dict[str, tuple[int, ...]] = {
    "right": (
        33, 7, 163, 144, 145, 153, 154, 155, 133, 246, 161, 160, 159, 158, 157, 173,
        130, 25, 110, 24, 23, 22, 26, 112, 243, 247, 30, 29, 27, 28, 56, 190,
        226, 31, 228, 229, 230, 231, 232, 233, 244, 113, 225, 224, 223, 222, 221, 189,
        35, 124, 46, 53, 52, 65, 143, 111, 117, 118, 119, 120, 121, 128, 245,
        156, 70, 63, 105, 66, 107, 55, 193,
    ),
    "left": (
        263, 249, 390, 373, 374, 380, 381, 382, 362, 466, 388, 387, 386, 385, 384, 398,
        359, 255, 339, 254, 253, 252, 256, 341, 463, 467, 260, 259, 257, 258, 286, 414,
        446, 261, 448, 449, 450, 451, 452, 453, 464, 342, 445, 444, 443, 442, 441, 413,
        265, 353, 276, 283, 282, 295, 372, 340, 346, 347, 348, 349, 350, 357, 465,
        383, 300, 293, 334, 296, 336, 285, 417,
    ),
}  # fmt: skip
#: Contour points of the lid margins: the lower lid (outer corner to inner), the upper lid
#: (outer to inner, without the corners).
LOWER_LID = tuple(range(0, 9))
UPPER_LID = tuple(range(9, 16))
#: Contour points of each lid's middle (face-mesh 145/159 on the right eye, 374/386 on the left).
LOWER_MIDDLE = 4
UPPER_MIDDLE = 12


@dataclass(frozen=True)
class Eye:
    """One eye as the iris model sees it; every coordinate in image pixels.

    ``iris``: ``(5, 3)`` the iris centre, then four points on its edge (x, y, and a relative
    depth z in the same pixel scale). ``contour``: ``(71, 3)`` the eye's contour points, indexed
    as :data:`CONTOUR_LANDMARKS` (the first 16 are the lid margins). ``crop``: the square the
    model looked at. ``in_image``: the fraction of the crop inside the image (the model has no
    confidence output of its own; a crop partly outside sees replicated border pixels).
    """

    iris: np.ndarray
    contour: np.ndarray
    crop: Crop
    in_image: float

    @property
    def centre(self) -> np.ndarray:
        """``(2,)`` the iris centre (x, y): where the pupil is."""
        return self.iris[0, :2]

    @property
    def radius(self) -> float:
        """The iris radius (pixels): the mean distance of its edge points from its centre."""
        return float(np.linalg.norm(self.iris[1:, :2] - self.iris[0, :2], axis=1).mean())

    @property
    def lids(self) -> np.ndarray:
        """``(16, 2)`` the lid margins: the lower lid outer corner to inner corner, then the upper
        lid back from the inner side to the outer (contour points 0–15)."""
        return self.contour[:16, :2]

    @property
    def opening(self) -> float:
        """The distance (pixels) between the middles of the upper and lower lids."""
        upper, lower = self.contour[UPPER_MIDDLE, :2], self.contour[LOWER_MIDDLE, :2]
        return float(np.linalg.norm(upper - lower))

    @property
    def visible(self) -> float:
        """How much of the iris the lids leave open: :attr:`opening` over the iris diameter, at
        most 1. Near 0 the eye is closed and the model still places an iris, on the lid line:
        its centre then says little of the gaze."""
        return min(self.opening / (2 * self.radius), 1.0) if self.radius > 0 else 0.0

    @property
    def width(self) -> float:
        """The distance (pixels) between the eye's corners (contour points 0 and 8)."""
        return float(np.linalg.norm(self.contour[0, :2] - self.contour[8, :2]))


@dataclass(frozen=True)
class Eyes:
    """Both eyes of a face: ``right`` and ``left`` are the subject's."""

    right: Eye
    left: Eye

    def __iter__(self):
        yield from (("right", self.right), ("left", self.left))

    def refined(self, landmarks: np.ndarray) -> np.ndarray:
        """A copy of the face mesh ``landmarks`` ``(468, k)`` (k ≥ 2) with the 142 points the
        iris model sees around the eyes (:data:`CONTOUR_LANDMARKS`) taken from it, as
        MediaPipe's iris tracking refines the mesh (x, y; and z where k ≥ 3)."""
        out = np.array(landmarks, dtype=np.float64, copy=True)
        k = min(out.shape[1], 3)
        for name, eye in self:
            out[list(CONTOUR_LANDMARKS[name]), :k] = eye.contour[:, :k]
        return out


def eye_crop(landmarks: np.ndarray, eye: str) -> Crop:
    """The square MediaPipe crops ``eye`` (``"right"`` or ``"left"``) with, from the face mesh
    ``landmarks`` ``(468, ≥2)`` (image pixels): see the module docstring."""
    first, second = (np.asarray(landmarks[i, :2], np.float64) for i in EYE_CORNERS[eye])
    d = second - first
    side = CROP_SCALE * float(max(abs(d[0]), abs(d[1])))
    return Crop((first + second) / 2, side, math.atan2(d[1], d[0]))


def _window(image: np.ndarray, crop: Crop) -> tuple[np.ndarray, float]:
    """The ``crop`` of ``image`` ``(H, W, 3) uint8`` at :data:`EYE_SIZE` (``(64, 64, 3)
    uint8``), the border pixels repeated outside the image, and the fraction of the crop's
    bounding square inside the image."""
    h, w = image.shape[:2]
    reach = crop.size * (abs(math.cos(crop.angle)) + abs(math.sin(crop.angle))) / 2 + 2
    x0, y0 = (math.floor(c - reach) for c in crop.centre)
    x1, y1 = (math.ceil(c + reach) for c in crop.centre)
    rows = np.clip(np.arange(y0, y1), 0, h - 1)
    cols = np.clip(np.arange(x0, x1), 0, w - 1)
    region = image[rows[:, None], cols[None, :]]
    inside = (min(x1, w) - max(x0, 0)) * (min(y1, h) - max(y0, 0))
    fraction = max(inside, 0) / float((x1 - x0) * (y1 - y0))
    local = Crop(crop.centre - (x0, y0), crop.size, crop.angle)
    return np.asarray(warp(Image.fromarray(region), local, EYE_SIZE)), fraction


def _check_landmarks(landmarks: np.ndarray) -> np.ndarray:
    if not isinstance(landmarks, np.ndarray):
        raise FitError(f"face landmarks must be a numpy array, got {type(landmarks).__name__}")
    if landmarks.ndim != 2 or landmarks.shape[0] != N_LANDMARKS or landmarks.shape[1] < 2:
        raise FitError(
            f"face landmarks must be ({N_LANDMARKS}, 2) or ({N_LANDMARKS}, 3), got shape "
            f"{landmarks.shape}"
        )
    if not np.issubdtype(landmarks.dtype, np.floating) and not np.issubdtype(
        landmarks.dtype, np.integer
    ):
        raise FitError(f"face landmarks must be numbers, got {landmarks.dtype}")
    corners = landmarks[[i for pair in EYE_CORNERS.values() for i in pair], :2]
    if not np.isfinite(corners).all():
        raise FitError("face landmarks: the eye corners (33, 133, 362, 263) must be finite")
    return landmarks.astype(np.float64, copy=False)


class IrisModel:
    """MediaPipe's iris landmark model on LiteRT; ``threads``: CPU threads of the interpreter
    (the model is small: a second thread costs more CPU time than it saves wall time). Not
    thread-safe (make one per thread)."""

    def __init__(self, threads: int = 1):
        from ai_edge_litert.interpreter import Interpreter

        with without_litert_banner():
            self._interpreter = Interpreter(
                model_path=str(package_data("landmarks/iris_landmark.tflite")),
                num_threads=threads,
            )
            self._interpreter.allocate_tensors()
        (inp,) = self._interpreter.get_input_details()
        by_size = {int(d["shape"][-1]): d["index"] for d in self._interpreter.get_output_details()}
        self._input = inp["index"]
        self._contour = by_size[3 * N_CONTOUR]
        self._iris = by_size[3 * N_IRIS]

    def eyes(self, image: np.ndarray, landmarks: np.ndarray) -> Eyes:
        """Both eyes of the face whose mesh ``landmarks`` ``(468, 2 or 3)`` (image pixels, as
        :class:`~vtts.fit.landmarks.Face` gives them) lie on ``image`` ``(H, W, 3) uint8`` RGB.

        Raises :class:`FitError` for an image that is not ``(H, W, 3) uint8``, landmarks of
        another shape or with eye corners that are not finite, and eye corners that coincide.
        """
        image = check_image(image)
        landmarks = _check_landmarks(landmarks)
        found = {}
        for name in EYE_CORNERS:
            crop = eye_crop(landmarks, name)
            if not crop.size > 0:
                raise FitError(f"face landmarks: the {name} eye's corners coincide")
            found[name] = self.eye(image, crop, mirrored=name == "left")
        return Eyes(**found)

    def eye(self, image: np.ndarray, crop: Crop, mirrored: bool = False) -> Eye:
        """The model on the square ``crop`` of ``image`` ``(H, W, 3) uint8`` (checked by
        :meth:`eyes`), the crop mirrored left-right first when ``mirrored`` (a subject's left
        eye)."""
        window, fraction = _window(image, crop)
        if mirrored:
            window = window[:, ::-1]
        tensor = np.ascontiguousarray(window, dtype=np.float32)[None] * (1 / 255)
        self._interpreter.set_tensor(self._input, tensor)
        self._interpreter.invoke()
        contour = self._interpreter.get_tensor(self._contour).reshape(N_CONTOUR, 3)
        iris = self._interpreter.get_tensor(self._iris).reshape(N_IRIS, 3)
        return Eye(
            iris=_to_image(iris, crop, mirrored),
            contour=_to_image(contour, crop, mirrored),
            crop=crop,
            in_image=fraction,
        )


def _to_image(points: np.ndarray, crop: Crop, mirrored: bool) -> np.ndarray:
    """The model's points ``(n, 3)`` (crop pixels) in image pixels ``(n, 3)``."""
    raw = points.astype(np.float64)
    if mirrored:
        raw[:, 0] = EYE_SIZE - raw[:, 0]
    out = np.empty_like(raw)
    out[:, :2] = crop.to_image(raw[:, :2] / EYE_SIZE)
    out[:, 2] = raw[:, 2] * (crop.size / EYE_SIZE)
    return out
