"""The teeth where the photo shows them: a smile's upper teeth placed from the photo's mouth.

The generic heads' teeth sit where the modeler put them: the upper row's tips at the neutral
lips' line. People differ, and in a smile that shows the teeth the upper lip rises off them:
the photo's open mouth is filled with teeth where the model — lips fitted to the photo's lips,
teeth where they were — shows its dark cavity (the fitted expression moves the lips and the
jaw, never the upper teeth). So where the photo's open mouth shows teeth (bright, pale pixels
inside the inner lip contour: :func:`teeth_mask`), the upper row moves up or down until its
tips meet the lower edge of the photo's upper teeth at the photo's view, and widens to span
the opening between the inner lip corners (:func:`place_teeth`); the photo paints both rows
where it shows them (:func:`vtts.fit.photo.fit_photo`). The lower row stays with the jaw: in
a smile it hides behind the lower lip, and moved with the upper row it would bare the tongue
between them. The neutral head's lips close over the teeth; speaking, it shows its upper teeth
as the photo's person does, lower or higher under the lip.
"""

from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw

from vtts.fit.landmarks import LIPS_INNER
from vtts.render.camera import Camera
from vtts.vrml import Scene

#: The teeth rows (the photo paints both where it shows them), and the one that is moved.
TEETH = ("UPPER_TEETH", "LOWER_TEETH")
UPPER = "UPPER_TEETH"
#: The share of the inner lip contour's area that must show teeth for the teeth to be placed.
LEAST_TEETH = 0.2
#: The middle share of the mouth's width over which the upper teeth's lower edge is measured
#: (the front teeth: towards the corners the row curves back and up).
MIDDLE = 0.4
#: How far the upper teeth may move (model units; the face is about 1.2 wide, a front tooth
#: about 0.09 long).
MOST = 0.12
#: The upper row is widened (never narrowed) to span the opening between the inner lip
#: corners at the photo's view, by at most this factor (the mouth's cavity is not much wider).
WIDEST = 1.2


def teeth_mask(photo: np.ndarray, landmarks: np.ndarray) -> np.ndarray | None:
    """``(H, W) bool``: the pixels of ``photo (H, W, 3) uint8`` inside the inner lip contour of
    ``landmarks (468, ≥2)`` (pixels) that show teeth — brighter and paler than the lips around
    the opening — or None when the mouth is shut or shows few teeth (less than
    :data:`LEAST_TEETH` of the opening)."""
    h, w = photo.shape[:2]
    pts = np.asarray(landmarks, np.float64)[list(LIPS_INNER), :2] - 0.5
    im = Image.new("L", (w, h), 0)
    ImageDraw.Draw(im).polygon([tuple(p) for p in pts], fill=1)
    inner = np.asarray(im, bool)
    if inner.sum() < 12:
        return None
    # the lips: a ring around the opening, a few pixels wide
    ring_img = Image.new("L", (w, h), 0)
    width = max(2, round(0.15 * float(np.ptp(pts[:, 1]) + 1)))
    ImageDraw.Draw(ring_img).line([*map(tuple, pts), tuple(pts[0])], fill=1, width=2 * width + 1)
    ring = np.asarray(ring_img, bool) & ~inner
    rgb = photo.astype(np.float64) / 255.0
    lum = rgb @ np.array([0.2126, 0.7152, 0.0722])
    sat = (rgb.max(axis=2) - rgb.min(axis=2)) / np.maximum(rgb.max(axis=2), 1e-6)
    if not ring.any():
        return None
    teeth = inner & (lum > np.median(lum[ring])) & (sat < np.median(sat[ring]))
    if teeth.sum() < LEAST_TEETH * inner.sum():
        return None
    return teeth


def _points(scene: Scene, name: str) -> np.ndarray:
    return np.asarray(scene.node(name).expand()["coord"].expand()["point"], np.float64)


def place_teeth(scene: Scene, camera: Camera, photo: np.ndarray,
                landmarks: np.ndarray) -> float | None:  # fmt: skip
    """Move the upper teeth of ``scene`` (fitted, neutral; changed in place) up or down so
    that, seen by ``camera`` (the photo's, in the model's frame), their tips meet the lower edge
    of the upper teeth ``photo (H, W, 3) uint8`` shows (:func:`teeth_mask` of the face's
    ``landmarks (468, ≥2)``, pixels), by at most :data:`MOST`, and widen them (by at most
    :data:`WIDEST`) to span the photo's opening between the inner lip corners. Returns the
    shift (model units, + up), or None where the photo shows no teeth or the head has none."""
    if not all(n in scene.defs for n in TEETH):
        return None
    teeth = teeth_mask(photo, landmarks)
    if teeth is None:
        return None
    pts = np.asarray(landmarks, np.float64)[list(LIPS_INNER), :2]
    left, right = float(pts[:, 0].min()), float(pts[:, 0].max())
    mid, half = (left + right) / 2, MIDDLE * (right - left) / 2
    cols = np.arange(int(np.ceil(mid - half)), int(np.floor(mid + half)) + 1)
    cols = cols[(cols >= 0) & (cols < teeth.shape[1])]
    edges = [np.flatnonzero(teeth[:, c]).max() + 1.0 for c in cols if teeth[:, c].any()]
    if len(edges) < max(2, len(cols) // 2):
        return None
    want = float(np.median(edges))  # the pixel row below the photo's upper teeth
    upper = _points(scene, UPPER)
    xy = camera.project(upper)
    near = np.abs(xy[:, 0] - mid) <= half
    if not near.any():
        return None
    tip = upper[near][np.argmax(xy[near, 1])]
    now = float(camera.project(tip[None])[0, 1])
    step = 0.01
    per_unit = (float(camera.project((tip + [0.0, step, 0.0])[None])[0, 1]) - now) / step
    if per_unit >= 0:
        return None
    shift = float(np.clip((want - now) / per_unit, -MOST, MOST))
    moved = upper + [0.0, shift, 0.0]
    # as wide as the opening between the inner lip corners: a smile shows teeth to its corners
    widen = float(np.clip((right - left) / max(float(np.ptp(xy[:, 0])), 1e-9), 1.0, WIDEST))
    middle = (moved[:, 0].min() + moved[:, 0].max()) / 2
    moved[:, 0] = middle + (moved[:, 0] - middle) * widen
    node = scene.node(UPPER).expand()["coord"].expand()
    node.fields["point"] = np.round(moved, 6) + 0.0
    return shift
