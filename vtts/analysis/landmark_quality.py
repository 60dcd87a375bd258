"""How well a decoded head lies on the person it was analyzed from, measured with the landmark
model: Equation 18 over the camera face's oval, and the geometry error of the landmarks.

The whole-head figure of :mod:`vtts.analysis.quality` (RGB over the pixels the decoded model
covers) depends on the model's outline and texture and leaves out the pixels the model misses.
The two measures here are the paper's and one that does not depend on texture:

* **Equation 18** (Eisert & Girod): the PSNR of luminance (``Y = 0.299 R + 0.587 G + 0.114
  B``) "in the facial area" — here the camera face's oval (:func:`oval_mask`: MediaPipe's
  face-oval landmark ring filled on the camera frame) — between the camera frame and the
  decoded frame laid over it (:func:`lay_over`: the decoder's RGBA rendering composited with
  its alpha over the camera frame, so that pixels the model does not cover are the camera's
  own and a head that misses the face is charged for it).
* **Geometry**: the landmark model run on that composite and on the camera frame; the mean
  distance of the eye, brow, lip and oval landmarks (:data:`MEASURED`) in % of the camera
  face's eye distance (:func:`geometry_error`). A composite where the tracked face is not found
  is **lost** (:func:`tracked_face`).

:func:`measure_frame` gives both for one frame. Landmark coordinates are the landmark model's
(:mod:`vtts.fit.landmarks`): x right, y down, in pixels, the centre of pixel ``[i, j]`` at
``(j + 0.5, i + 0.5)``.

>>> camera = camera_landmarks(frame)            # (468, 3) or None
>>> m = measure_frame(frame, rgba, camera)      # FrameMeasure(eq18_db=..., geometry_pct=...)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vtts.errors import AnalysisError
from vtts.fit.landmarks import (
    FACE_OVAL,
    LEFT_EYE,
    LEFT_EYEBROW,
    LIPS_INNER,
    LIPS_OUTER,
    RIGHT_EYE,
    RIGHT_EYEBROW,
    LandmarkDetector,
    detect_faces,
)

#: Luminance weights of R, G and B (ITU-R BT.601), as Equation 18 takes them.
LUMA = np.array([0.299, 0.587, 0.114])

#: The landmarks the geometry error averages over: MediaPipe's FACEMESH_RIGHT_EYE, LEFT_EYE,
#: RIGHT_EYEBROW, LEFT_EYEBROW, LIPS (outer and inner contour) and FACE_OVAL sets, 128 points,
#: each once.
MEASURED: tuple[int, ...] = tuple(sorted({*RIGHT_EYE, *LEFT_EYE, *RIGHT_EYEBROW, *LEFT_EYEBROW,
                                          *LIPS_OUTER, *LIPS_INNER, *FACE_OVAL}))  # fmt: skip


@dataclass(frozen=True)
class FrameMeasure:
    """The two measures of one frame.

    ``eq18_db``: Equation 18 (dB; ``inf`` where the composite equals the camera frame over the
    oval; NaN without a camera face). ``geometry_pct``: the geometry error in % of the eye
    distance (NaN without a camera face, or when lost). ``camera_face``: whether the landmark
    model found the face on the camera frame (frames without one are left out of both
    measures). ``lost``: the camera face was found but the composite's was not (or not the
    tracked one). ``covered``: the share (0–1) of the oval's pixels the decoded model covers
    fully (alpha 255; NaN without a camera face): Equation 18 counts the pixels it leaves
    uncovered as the camera's own, so read it with this beside it. ``camera`` and
    ``composite``: the ``(468, 3)`` landmarks found (None where none), for drawing.
    """

    eq18_db: float
    geometry_pct: float
    camera_face: bool
    lost: bool
    covered: float = math.nan
    camera: np.ndarray | None = None
    composite: np.ndarray | None = None

    @property
    def measured(self) -> bool:
        """Whether the frame has a geometry error (a camera face, not lost)."""
        return self.camera_face and not self.lost


def _check_landmarks(landmarks: np.ndarray, what: str = "landmarks") -> np.ndarray:
    points = np.asarray(landmarks, np.float64)
    if points.ndim != 2 or points.shape[0] <= max(MEASURED) or points.shape[1] < 2:
        raise AnalysisError(f"{what} must be (468, 2 or 3) MediaPipe landmarks, "
                            f"got shape {points.shape}")  # fmt: skip
    return points


def _check_rgb(image: np.ndarray, what: str, channels: tuple[int, ...] = (3, 4)) -> np.ndarray:
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] not in channels:
        kinds = " or ".join(str(c) for c in channels)
        raise AnalysisError(f"{what} must be (H, W, {kinds}), got shape {image.shape}")
    return image


def oval_mask(landmarks: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """The ``(H, W) bool`` mask of the face oval of ``landmarks`` (``(468, ≥2)`` pixels) in an
    image of ``size`` (W, H): the pixels whose centre lies inside the polygon of MediaPipe's
    face-oval ring (:data:`~vtts.fit.landmarks.FACE_OVAL`, 36 points in ring order)."""
    from matplotlib.path import Path as Polygon

    ring = _check_landmarks(landmarks)[list(FACE_OVAL), :2]
    w, h = size
    mask = np.zeros((h, w), bool)
    # only the ring's bounding box is tested, pixel centres at (j + 0.5, i + 0.5)
    x0, y0 = np.clip(np.floor(ring.min(axis=0)).astype(int), 0, (w, h))
    x1, y1 = np.clip(np.ceil(ring.max(axis=0)).astype(int), 0, (w, h))
    if x1 <= x0 or y1 <= y0:
        return mask
    ys, xs = np.mgrid[y0:y1, x0:x1]
    centres = np.column_stack([xs.ravel() + 0.5, ys.ravel() + 0.5])
    inside = Polygon(ring, closed=False).contains_points(centres)
    mask[y0:y1, x0:x1] = inside.reshape(ys.shape)
    return mask


def luminance(image: np.ndarray) -> np.ndarray:
    """The ``(H, W) float64`` luminance ``0.299 R + 0.587 G + 0.114 B`` (0–255) of an ``(H, W,
    ≥3)`` RGB(A) image."""
    return np.asarray(image, np.float64)[..., :3] @ LUMA


def lay_over(frame: np.ndarray, rgba: np.ndarray) -> np.ndarray:
    """The decoder's ``(H, W, 4) uint8`` RGBA rendering composited with its alpha over the
    camera ``frame`` ``(H, W, 3)``: ``(H, W, 3) uint8``, the camera's own pixels where the
    model does not cover them."""
    frame = _check_rgb(frame, "the camera frame")
    rgba = _check_rgb(rgba, "the decoded frame", (4,))
    if frame.shape[:2] != rgba.shape[:2]:
        raise AnalysisError(
            f"the decoded frame is {rgba.shape[1]}x{rgba.shape[0]}, the camera frame "
            f"{frame.shape[1]}x{frame.shape[0]}: they must agree"
        )
    alpha = rgba[..., 3:4].astype(np.float32) / 255.0
    out = rgba[..., :3].astype(np.float32) * alpha + frame[..., :3].astype(np.float32) * (1 - alpha)
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


def oval_psnr(frame: np.ndarray, other: np.ndarray, mask: np.ndarray) -> float:
    """Equation 18: the PSNR (dB) of the luminance of ``other`` against the camera ``frame``
    (both ``(H, W, ≥3)``, 0–255) over the ``(H, W)`` ``mask`` (:func:`oval_mask`); ``inf``
    where they agree, NaN for an empty mask."""
    mask = np.asarray(mask, bool)
    if not mask.any():
        return float("nan")
    diff = luminance(np.asarray(frame)[mask]) - luminance(np.asarray(other)[mask])
    mse = float(np.mean(diff**2))
    return float("inf") if mse == 0 else 10 * math.log10(255.0**2 / mse)


def eye_distance(landmarks: np.ndarray) -> float:
    """The distance (pixels) between the centres of the two eyes' landmark contours."""
    points = _check_landmarks(landmarks)
    right = points[list(RIGHT_EYE), :2].mean(axis=0)
    left = points[list(LEFT_EYE), :2].mean(axis=0)
    return float(np.linalg.norm(left - right))


def geometry_error(reference: np.ndarray, landmarks: np.ndarray) -> float:
    """The mean distance of the :data:`MEASURED` landmarks (eyes, brows, lips, oval) of
    ``landmarks`` from those of ``reference`` (both ``(468, ≥2)`` pixels), in % of the
    ``reference``'s :func:`eye_distance`."""
    ref = _check_landmarks(reference, "the reference landmarks")
    other = _check_landmarks(landmarks)
    d = np.linalg.norm(other[list(MEASURED), :2] - ref[list(MEASURED), :2], axis=1)
    scale = eye_distance(ref)
    if not scale > 0:
        raise AnalysisError("the reference landmarks' eyes coincide: no eye distance to scale by")
    return float(100.0 * d.mean() / scale)


def camera_landmarks(
    frame: np.ndarray, detector: LandmarkDetector | None = None
) -> np.ndarray | None:
    """The ``(468, 3)`` landmarks of the largest face on the camera ``frame`` (``(H, W, 3)
    uint8``; the face ``vtts analyze`` tracks by default), or None where none is found."""
    faces = detect_faces(np.ascontiguousarray(frame), detector)
    return faces[0].landmarks if faces else None


def tracked_face(faces: list, camera: np.ndarray):
    """Among ``faces`` (:class:`~vtts.fit.landmarks.Face`) found on a composite, the one
    nearest (mean :data:`MEASURED` landmark distance) the ``camera`` face's landmarks, when the
    centre of its measured landmarks lies inside the camera face's oval; else None (not the
    tracked face: another person, or a head far from the face)."""
    from matplotlib.path import Path as Polygon

    if not faces:
        return None
    ref = _check_landmarks(camera, "the camera landmarks")[list(MEASURED), :2]
    nearest = min(faces, key=lambda f: float(
        np.linalg.norm(f.landmarks[list(MEASURED), :2] - ref, axis=1).mean()))  # fmt: skip
    centre = nearest.landmarks[list(MEASURED), :2].mean(axis=0)
    oval = Polygon(np.asarray(camera, np.float64)[list(FACE_OVAL), :2], closed=False)
    return nearest if oval.contains_point(centre) else None


def measure_frame(
    frame: np.ndarray,
    rgba: np.ndarray,
    camera: np.ndarray | None,
    detector: LandmarkDetector | None = None,
) -> FrameMeasure:
    """Equation 18 and the geometry error of one decoded frame: ``rgba`` ``(H, W, 4) uint8``
    (the decoder's rendering) laid over the camera ``frame`` ``(H, W, 3) uint8``, against it.
    ``camera``: the camera face's ``(468, ≥2)`` landmarks (:func:`camera_landmarks`; None: no
    camera face, the frame is not measured). ``detector``: the landmark model (None: the
    shared MediaPipe one)."""
    if camera is None:
        return FrameMeasure(math.nan, math.nan, camera_face=False, lost=False)
    frame = _check_rgb(frame, "the camera frame", (3,))
    over = lay_over(frame, rgba)
    h, w = frame.shape[:2]
    oval = oval_mask(camera, (w, h))
    eq18 = oval_psnr(frame, over, oval)
    covered = float((np.asarray(rgba)[..., 3][oval] == 255).mean()) if oval.any() else math.nan
    found = tracked_face(detect_faces(over, detector), camera)
    if found is None:
        return FrameMeasure(eq18, math.nan, camera_face=True, lost=True, covered=covered,
                            camera=camera)  # fmt: skip
    return FrameMeasure(eq18, geometry_error(camera, found.landmarks), camera_face=True,
                        lost=False, covered=covered, camera=camera,
                        composite=found.landmarks)  # fmt: skip
