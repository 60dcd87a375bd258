"""The teeth where the photo shows them: a smile's upper teeth placed from the photo's mouth.

The generic heads' teeth sit where the modeler put them: the upper row's tips at the neutral
lips' line. People differ, and in a smile that shows the teeth the upper lip rises off them:
the photo's open mouth is filled with teeth where the model — lips fitted to the photo's lips,
teeth where they were — shows its dark cavity (the fitted expression moves the lips and the
jaw, never the upper teeth). So where the photo's open mouth shows teeth (bright, pale pixels
inside the inner lip contour: :func:`teeth_mask`), the upper row moves up or down until its
tips meet the lower edge of the photo's upper teeth at the photo's view, and widens to span the
opening between the inner lip corners and a little beyond (:data:`BEYOND`: the row's ends curve
back behind the corners; :func:`place_teeth`) — each point of it only as far as it stays behind
the skin wherever it was behind it, at rest, in the photo's expression and in a broad smile,
seen from the front and turned (:func:`behind_skin`: widened freely, the row's ends poked
through the skin under the lips' corners, thin lines there in a turned smile); the photo paints
both rows where it shows them (:func:`vtts.fit.photo.fit_photo`). The lower row stays with the
jaw: in a smile it hides behind the lower lip, and moved with the upper row it would bare the
tongue between them. The neutral head's lips close over the teeth; speaking, it shows its upper
teeth as the photo's person does, lower or higher under the lip.
"""

from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw

from vtts.face import FaceModel
from vtts.fit.landmarks import LIPS_INNER
from vtts.render.camera import Camera
from vtts.vrml import Scene
from vtts.vrml.geometry import triangulate

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
#: The upper row is widened (never narrowed) until, at the photo's view, it spans this share of
#: the opening between the inner lip corners: its ends curve back and away, so a row only as wide
#: as the opening leaves the dark cavity showing at the lips' corners where the photo's smile
#: shows teeth or the lips' shade there (docs/fitting.md, "The astronaut's face").
BEYOND = 1.25
#: The most the upper row is widened (the mouth's cavity is not much wider).
WIDEST = 1.5
#: The directions (degrees of yaw, the head seen from the front) along which a point of the
#: widened row must stay behind the skin wherever it was behind it before (:func:`in_front`).
YAWS = (-30.0, 0.0, 30.0)
#: How far around the widened row (model units, in x and y) the skin's triangles are looked at.
REACH = 0.2
#: The poses besides the neutral and the photo's own expression in which the widened row must
#: stay behind the skin (:func:`skins`): a broad smile and an open "A:" stretch the lips'
#: corners the most (the contact sheet's, docs/fitting.md).
POSES = ({"expressions": {"joy": 1.0}}, {"visemes": {10: 1.0}})
#: How many widening factors are tried, evenly from none to the full widening: each point of
#: the row goes up to the last at which it stays behind the skin (:func:`behind_skin`).
STEPS = 6


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


def in_front(points: np.ndarray, skin: np.ndarray, triangles: np.ndarray,
             yaws=YAWS) -> np.ndarray:  # fmt: skip
    """``(n,) bool``: which of ``points (n, 3)`` lie in front of the skin — the surface of
    ``skin (p, 3)`` points and ``triangles (m, 3)`` — seen from one of ``yaws`` (degrees; the
    model's +z faces the viewer, looked at along parallel rays): the ray towards the viewer
    meets no skin, the ray away from it does. A tooth there pokes through the skin."""
    return _in_front(points, _views(skin[triangles], yaws))


def _views(corners: np.ndarray, yaws) -> list[tuple]:
    """The skin's triangles ``corners (m, 3, 3)`` seen from each of ``yaws`` (degrees): the
    view's rotation (depth along its third axis, towards the viewer), the turned triangles and
    their boxes across the view, sorted by the boxes' left edges."""
    out = []
    for yaw in np.radians(yaws):
        c, s = np.cos(yaw), np.sin(yaw)
        rot = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
        t = corners @ rot.T
        lo, hi = t[..., :2].min(axis=1), t[..., :2].max(axis=1)
        order = np.argsort(lo[:, 0])
        out.append((rot, t[order], lo[order], hi[order]))
    return out


def _in_front(points: np.ndarray, views: list[tuple]) -> np.ndarray:
    """:func:`in_front` of ``points (n, 3)`` for the skin's :func:`_views`."""
    out = np.zeros(len(points), bool)
    for rot, t, lo, hi in views:
        p = points @ rot.T
        # the pairs whose triangle's box holds the point (the boxes sorted by their left
        # edges: only those that start left of the point), then the point in the triangle
        upto = np.searchsorted(lo[:, 0], p[:, 0], side="right")
        cand = np.arange(upto.max())
        i, j = np.nonzero((cand[None] < upto[:, None]) & (hi[None, : len(cand), 0] >= p[:, None, 0])
                          & (lo[None, : len(cand), 1] <= p[:, None, 1])
                          & (hi[None, : len(cand), 1] >= p[:, None, 1]))  # fmt: skip
        a, b, q = t[j, 0], t[j, 1], t[j, 2]
        x = p[i]
        e1, e2, r = b[:, :2] - a[:, :2], q[:, :2] - a[:, :2], x[:, :2] - a[:, :2]
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        ok = np.abs(det) > 1e-15
        det = np.where(ok, det, 1.0)
        v = (r[:, 0] * e2[:, 1] - r[:, 1] * e2[:, 0]) / det
        w = (e1[:, 0] * r[:, 1] - e1[:, 1] * r[:, 0]) / det
        inside = ok & (v >= 0) & (w >= 0) & (v + w <= 1)
        depth = a[:, 2] + v * (b[:, 2] - a[:, 2]) + w * (q[:, 2] - a[:, 2])
        ahead = np.bincount(i[inside & (depth > x[:, 2])], minlength=len(points)) > 0
        behind = np.bincount(i[inside & (depth < x[:, 2])], minlength=len(points)) > 0
        out |= ~ahead & behind
    return out


def behind_skin(points: np.ndarray, middle: float, widen: float, skin_poses,
                triangles: np.ndarray) -> np.ndarray:  # fmt: skip
    """``points (n, 3)`` spread in x about ``middle`` by up to ``widen``, each as far as it
    stays behind the skin (:func:`in_front`) in every one of ``skin_poses`` (``(p, 3)`` skin
    points in the poses the row is seen in; ``triangles (m, 3)``) where it was behind it
    unspread; the spread keeps the points' order across each side of the row (a point is spread
    no farther than any point beyond it on its side)."""
    u = points[:, 0] - middle
    # the skin's triangles near the row spread widest (the views turn it by up to 30°)
    lo = points.min(axis=0) - [abs(widen - 1.0) * np.abs(u).max() + REACH, REACH, 0.0]
    hi = points.max(axis=0) + [abs(widen - 1.0) * np.abs(u).max() + REACH, REACH, 0.0]
    near = np.zeros(len(triangles), bool)
    for s in skin_poses:
        t = s[triangles]
        near |= np.all((t.max(axis=1)[:, :2] >= lo[:2]) & (t.min(axis=1)[:, :2] <= hi[:2]), axis=1)
    views = [_views(s[triangles[near]], YAWS) for s in skin_poses]
    allowed, alive = np.ones(len(points)), np.ones(len(points), bool)
    before = [_in_front(points, v) for v in views]
    for f in np.linspace(1.0, widen, STEPS)[1:]:
        moved = points.copy()
        moved[:, 0] = middle + u * f
        ok = np.ones(len(points), bool)
        for v, was in zip(views, before, strict=True):
            ok &= ~(_in_front(moved, v) & ~was)
        alive &= ok
        allowed = np.where(alive, f, allowed)
    # on each side, no point spread beyond where a point farther out goes
    reach = np.abs(u) * allowed
    for side in (u < 0, u >= 0):
        at = np.flatnonzero(side)[np.argsort(-np.abs(u[side]))]
        reach[at] = np.minimum.accumulate(reach[at]) if len(at) else reach[at]
    out = points.copy()
    out[:, 0] = middle + np.sign(u) * np.maximum(reach, np.abs(u))
    return out


def skins(model: FaceModel, expression: dict[int, float]) -> tuple[list[np.ndarray], np.ndarray]:
    """The skin (``FACE``) of ``model`` in the poses the upper row must stay behind it — the
    neutral, the photo's ``expression`` ``{FAP: value}`` and :data:`POSES` — as ``(p, 3)``
    points each, and its triangles ``(m, 3)`` (point indices)."""
    mesh = triangulate(model.scene.node("FACE"))
    triangles = np.asarray(mesh.coord_index)[np.asarray(mesh.faces)]
    neutral = model.neutral_points("FACE")
    poses = [model.deform(expression), *(model.deform(**p) for p in POSES)]
    return [neutral, *(p.points.get("FACE", neutral) for p in poses)], triangles


def _points(scene: Scene, name: str) -> np.ndarray:
    return np.asarray(scene.node(name).expand()["coord"].expand()["point"], np.float64)


def place_teeth(scene: Scene, camera: Camera, photo: np.ndarray, landmarks: np.ndarray,
                skin_poses: list[np.ndarray], triangles: np.ndarray) -> float | None:  # fmt: skip
    """Move the upper teeth of ``scene`` (fitted, neutral; changed in place) up or down so
    that, seen by ``camera`` (the photo's, in the model's frame), their tips meet the lower edge
    of the upper teeth ``photo (H, W, 3) uint8`` shows (:func:`teeth_mask` of the face's
    ``landmarks (468, ≥2)``, pixels), by at most :data:`MOST`, and widen them (by at most
    :data:`WIDEST`) to span :data:`BEYOND` of the photo's opening between the inner lip
    corners, each point only as far as it stays behind the head's skin (``skin_poses`` and
    ``triangles``: :func:`skins`; :func:`behind_skin`). Returns the shift (model units,
    + up), or None where the photo shows no teeth or the head has none."""
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
    # beyond the opening between the inner lip corners: a smile shows teeth to its corners
    wide = BEYOND * (right - left) / max(float(np.ptp(xy[:, 0])), 1e-9)
    widen = float(np.clip(wide, 1.0, WIDEST))
    middle = (moved[:, 0].min() + moved[:, 0].max()) / 2
    moved = behind_skin(moved, middle, widen, skin_poses, triangles)
    node = scene.node(UPPER).expand()["coord"].expand()
    node.fields["point"] = np.round(moved, 6) + 0.0
    return shift
