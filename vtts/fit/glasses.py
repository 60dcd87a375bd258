"""Glasses on a photo: told from the bridge that crosses the nose between the eyes.

A frame's bridge is a thin line across the top of the nose, at about the height of the eyes;
bare skin there is smooth (the nose's root), and what crosses it otherwise — the brows' inner
ends, a fringe — lies higher. So the photo is sampled in the face's own frame (the line through
the eyes' centres across, its normal down, the eye distance ``e`` as the unit): a band
``±`` :data:`BAND` ``e`` wide centred between the eyes, from :data:`SPAN` above the eyes' line
to below it, averaged across into one profile down the nose. A line across the band is a narrow
ridge (dark or light: metal, plastic and clear rims) in that profile: the profile's value less
its neighbours :data:`SCALE` ``e`` above and below, where it stands out of both on the same
side (an edge, such as a fringe's, stands out of neither). Its largest size within
:data:`SEARCH`, over the profile's median one (the skin's own texture and the photo's noise),
is the score; a frame's bridge scores 5–130, bare skin under 4 (docs/fitting.md, "Glasses").

A fitted head models the glasses' frame as a part of its own and not their lenses:
:func:`vtts.fit.photo.fit_photo` warns when the photo shows them, and keeps their frame off the
skin. The frame's pixels (:func:`rim_mask`) are thin
lines, dark or light, around the eyes: where a pixel stands out of its neighbourhood (a grey
closing or opening :data:`SCALE` ``e`` wide), inside the face's oval and off the eyes and the
brows, in runs longer than a crease or the skin's grain; and, since a clear rim's contrast
fades along it, each lens's rim is also followed as a smooth closed ring around its eye
(:func:`rim_ring`). Those pixels are filled from the skin around them (:func:`without_rims`)
before the texture is painted: turned, the head shows no frame on the cheeks and the nose. The
lenses' tint and reflections stay, and so does what the frame hid. The frame itself becomes a
thin shape in front of the eyes, textured with the photo's frame pixels (:func:`glasses_part`,
:func:`add_glasses`), which turns with the head.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from PIL import Image, ImageDraw
from scipy import ndimage

from vtts.fit.landmarks import (
    FACE_OVAL,
    LEFT_EYE,
    LEFT_EYEBROW,
    RIGHT_EYE,
    RIGHT_EYEBROW,
    eye_centres,
)
from vtts.render.camera import Camera
from vtts.vrml import Scene, parse

#: The band's half width across the face (eye distances).
BAND = 0.07
#: The profile's span down the face, from above the eyes' line (negative) to below (eye
#: distances), and where within it a bridge is looked for (the brows and a fringe lie above).
SPAN, SEARCH = (-0.45, 0.15), (-0.28, 0.08)
#: The ridge's scale: how far above and below a line its neighbours are (eye distances).
SCALE = 0.03
#: Samples down the profile.
SAMPLES = 60
#: The median ridge size below which a profile counts as this smooth (grey levels): a flat,
#: noiseless photo's ridges are not compared against nothing.
FLOOR = 0.3
#: From this score (a ridge's size over the profile's median) the photo shows glasses, and
#: the ridge must be at least :data:`LEAST` grey levels.
GLASSES, LEAST = 4.5, 3.0


def _frame(landmarks: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The face's frame: the eyes' midpoint, the unit vector across (towards the face's left),
    the one down, and the eye distance (pixels)."""
    right, left = eye_centres(landmarks)
    e = float(np.linalg.norm(left - right))
    across = (left - right) / max(e, 1e-9)
    down = np.array([-across[1], across[0]])
    if down[1] < 0:
        down = -down
    return (right + left) / 2, across, down, e


def _grey(image: np.ndarray) -> np.ndarray:
    return np.asarray(Image.fromarray(np.asarray(image, np.uint8)).convert("L"), np.float64)


def _ridges(profile: np.ndarray, k: int) -> np.ndarray:
    """For the inner samples ``p(i)`` of ``profile``: how far ``p(i)`` stands out of both its
    neighbours ``p(i ± k)`` on the same side (a line, dark or light), the smaller of the two
    differences; 0 where it lies between them (an edge, a slope)."""
    p = profile[k:-k]
    above, below = p - profile[: -2 * k], p - profile[2 * k :]
    return np.where(above * below > 0, np.minimum(np.abs(above), np.abs(below)), 0.0)


def glasses_score(image: np.ndarray, landmarks: np.ndarray) -> float:
    """How plainly ``image (H, W, 3) uint8`` shows a glasses frame's bridge between the eyes of
    the face whose ``landmarks (468, ≥2)`` (pixels) are given (see the module docstring):
    under 4 for bare skin, from :data:`GLASSES` for glasses; 0 for a face too small to tell."""
    centre, across, down, e = _frame(landmarks)
    step = (SPAN[1] - SPAN[0]) * e / (SAMPLES - 1)
    k = round(SCALE * e / step)
    if e < 12 or k < 1:
        return 0.0
    v = np.linspace(*SPAN, SAMPLES) * e
    u = np.linspace(-BAND, BAND, 7) * e
    pts = centre + u[None, :, None] * across + v[:, None, None] * down
    grey = _grey(image)
    profile = ndimage.map_coordinates(grey, [pts[..., 1], pts[..., 0]], order=1, mode="nearest")
    profile = profile.mean(axis=1)
    r = _ridges(profile, k)
    # the skin's texture and the photo's noise: the profile's median bend at that scale
    bend = np.abs(profile[k:-k] - 0.5 * (profile[: -2 * k] + profile[2 * k :]))
    vv = v[k:-k] / e
    inside = (vv >= SEARCH[0]) & (vv <= SEARCH[1])
    peak = float(r[inside].max())
    if peak < LEAST:
        return 0.0
    return peak / max(float(np.median(bend)), FLOOR)


def wears_glasses(image: np.ndarray, landmarks: np.ndarray) -> bool:
    """Whether the face of ``landmarks`` in ``image`` wears glasses (:func:`glasses_score`)."""
    return glasses_score(image, landmarks) >= GLASSES


#: Where a frame's rims are looked for, in the face's frame (eye distances from the eyes'
#: midpoint): across, and from above the eyes' line to below it. Within it, the eyes and the
#: brows (:data:`KEEP_OUT` beyond their contours) and whatever lies outside the face's oval
#: are not a frame.
REGION_ACROSS, REGION_DOWN = 1.25, (-0.4, 0.55)
KEEP_OUT = 0.05
#: A rim's pixel stands out of its neighbourhood (a grey closing or opening :data:`SCALE` ``e``
#: wide) by this many robust standard deviations of the region's values, and at least
#: :data:`LEAST` grey levels.
RIM_SIGMAS = 4.0
#: Weaker line pixels (this many robust standard deviations) count where they join a rim's
#: pixel: a rim's contrast varies along it (reflections, the lens's edge over skin or eye).
WEAK_SIGMAS = 2.0
#: A frame's line is long: a connected run of rim pixels shorter than this (eye distances,
#: its longer side) is the skin's texture or a crease.
RIM_LENGTH = 0.25
#: Each lens's rim is also looked for as a ring around its eye (:func:`rim_ring`): between
#: these radii (eye distances), in this many directions, moving at most this many radius
#: samples (about a pixel each) from one direction to the next; kept where it follows line
#: pixels (:data:`WEAK_SIGMAS`) over this share of the directions.
RIM_RADII = (0.22, 0.8)
RIM_DIRECTIONS, RIM_STEP = 96, 1
RIM_SHOWN = 0.5
#: The harmonics of the smooth curve a rim's radius follows around the eye, and how close
#: (a share of the radii searched) the ring stays to it.
HARMONICS, NEAR_CURVE = 2, 0.06
#: Pixels the frame's mask is grown by: the photo's blur and the rims' faint edges.
GROW = 1


def rim_ring(score: np.ndarray, centre: np.ndarray, e: float) -> np.ndarray | None:
    """The likeliest rim around an eye: ``(RIM_DIRECTIONS, 2)`` pixels (x, y), a point per
    direction around ``centre (2,)``, through ``score (H, W)`` (how plainly each pixel shows a
    line), ``e`` the eye distance (pixels); None where it does not follow lines over at least
    :data:`RIM_SHOWN` of the directions. The closed path of the largest total score that moves
    at most :data:`RIM_STEP` samples outward or inward from one direction to the next; then its
    radius fitted by the circle's first :data:`HARMONICS` (the tenth of directions off it most,
    three times, left out: where it strayed to a crease) and the path found again within
    :data:`NEAR_CURVE` of that smooth curve."""
    n_r = max(int(round((RIM_RADII[1] - RIM_RADII[0]) * e)), 8)  # about a pixel apart
    radii = np.linspace(RIM_RADII[0] * e, RIM_RADII[1] * e, n_r)
    theta = np.arange(RIM_DIRECTIONS) / RIM_DIRECTIONS * 2 * np.pi
    x = centre[0] + np.cos(theta)[:, None] * radii[None]
    y = centre[1] + np.sin(theta)[:, None] * radii[None]
    cost = ndimage.map_coordinates(score, [y - 0.5, x - 0.5], order=1, mode="constant")
    path = _circular_path(cost, np.zeros(cost.shape, bool))
    basis = np.stack([np.ones_like(theta)] + [f(m * theta) for m in range(1, HARMONICS + 1)
                                             for f in (np.cos, np.sin)], 1)  # fmt: skip
    keep = np.ones(RIM_DIRECTIONS, bool)
    for _ in range(3):
        coef, *_ = np.linalg.lstsq(basis[keep], path[keep].astype(float), rcond=None)
        off = np.abs(basis @ coef - path)
        keep = off <= np.quantile(off, 0.9)
    far = np.abs(np.arange(n_r)[None] - (basis @ coef)[:, None]) > NEAR_CURVE * n_r
    path = _circular_path(cost, far)
    if np.mean(cost[np.arange(RIM_DIRECTIONS), path] >= WEAK_SIGMAS) < RIM_SHOWN:
        return None
    r = radii[path]
    return np.stack([centre[0] + np.cos(theta) * r, centre[1] + np.sin(theta) * r], 1)


def _circular_path(cost: np.ndarray, barred: np.ndarray) -> np.ndarray:
    """``(D,)`` the index (along axis 1 of ``cost (D, R)``) of the closed path around the
    ``D`` directions of the largest total cost, moving at most :data:`RIM_STEP` per direction
    and never onto ``barred (D, R)``: dynamic programming around the circle twice, the second
    lap's path (whose start the first lap settled)."""
    d, n = cost.shape
    c = np.concatenate([np.where(barred, -1e9, cost)] * 2)
    score = c[0].copy()
    back = np.zeros(c.shape, np.int64)
    # each sample's reachable predecessors, (n, 2 RIM_STEP + 1)
    near = np.clip(np.arange(n)[:, None] + np.arange(-RIM_STEP, RIM_STEP + 1)[None], 0, n - 1)
    rows = np.arange(n)
    for i in range(1, len(c)):
        k = np.argmax(score[near], axis=1)
        back[i] = near[rows, k]
        score = score[back[i]] + c[i]
    path = np.zeros(len(c), np.int64)
    path[-1] = int(np.argmax(score))
    for i in range(len(c) - 1, 0, -1):
        path[i - 1] = back[i, path[i]]
    return path[d:]


def rim_mask(image: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    """``(H, W) bool``: the pixels of ``image (H, W, 3) uint8`` that show a glasses frame on the
    face of ``landmarks (468, ≥2)`` (pixels): thin lines, dark or light (metal, plastic and
    clear rims), around the eyes, inside the face's oval and off the eyes and brows, in long
    connected runs (see the constants above), grown by a pixel (the photo's blur). Call it for
    a photo that shows glasses (:func:`wears_glasses`): a bare face has some lines there too
    (creases, the nose's edges), and those would be taken. Empty for a face too small to
    tell."""
    h, w = image.shape[:2]
    centre, across, down, e = _frame(landmarks)
    if e < 12:
        return np.zeros((h, w), bool)
    pts = np.asarray(landmarks, np.float64)[:, :2]
    grey = _grey(image)
    side = 2 * max(1, round(SCALE * e)) + 1
    line = np.maximum(ndimage.grey_closing(grey, size=(side, side)) - grey,
                      grey - ndimage.grey_opening(grey, size=(side, side)))  # fmt: skip
    yy, xx = np.mgrid[:h, :w]
    rel = np.stack([xx + 0.5 - centre[0], yy + 0.5 - centre[1]], -1)
    u, v = rel @ across / e, rel @ down / e
    region = (np.abs(u) <= REGION_ACROSS) & (v >= REGION_DOWN[0]) & (v <= REGION_DOWN[1])
    face = Image.new("L", (w, h), 0)
    ImageDraw.Draw(face).polygon([tuple(p) for p in pts[list(FACE_OVAL)] - 0.5], fill=1)
    out = Image.new("L", (w, h), 0)
    draw = ImageDraw.Draw(out)
    grow = max(1, round(KEEP_OUT * e))
    for contour in (LEFT_EYE, RIGHT_EYE, LEFT_EYEBROW, RIGHT_EYEBROW):
        poly = [tuple(p) for p in pts[list(contour)] - 0.5]
        draw.polygon(poly, fill=1, outline=1, width=grow)
        draw.line([*poly, poly[0]], fill=1, width=2 * grow + 1)
    region &= np.asarray(face, bool) & ~np.asarray(out, bool)
    if not region.any():
        return np.zeros((h, w), bool)
    values = line[region]
    med = float(np.median(values))
    spread = 1.4826 * float(np.median(np.abs(values - med)))
    # hysteresis: the runs of weaker line pixels that hold a strong one
    strong = region & (line >= max(med + RIM_SIGMAS * max(spread, FLOOR), LEAST))
    weak = region & (line >= max(med + WEAK_SIGMAS * max(spread, FLOOR), LEAST))
    labels, n = ndimage.label(weak, structure=np.ones((3, 3), bool))
    if n == 0:
        return weak
    held = np.zeros(n + 1, bool)
    held[np.unique(labels[strong])] = True
    long = np.zeros(n + 1, bool)
    for k, box in enumerate(ndimage.find_objects(labels), start=1):
        long[k] = max(box[0].stop - box[0].start, box[1].stop - box[1].start) >= RIM_LENGTH * e
    long[0] = False
    rims = (long & held)[labels]
    # each lens's rim as a closed curve around its eye, where the runs above leave gaps (a clear
    # rim's contrast fades along it): the likeliest smooth ring of line pixels
    score = np.clip((line - med) / max(spread, FLOOR), 0.0, 10.0) * region
    for eye in eye_centres(landmarks):
        ring = rim_ring(score, eye, e)
        if ring is None:
            continue
        draw = Image.new("L", (w, h), 0)
        ImageDraw.Draw(draw).line([*map(tuple, ring - 0.5), tuple(ring[0] - 0.5)], fill=1,
                                  width=side)  # fmt: skip
        rims |= np.asarray(draw, bool) & weak
    return ndimage.binary_dilation(rims, iterations=GROW)


def without_rims(image: np.ndarray, rims: np.ndarray) -> np.ndarray:
    """``image (H, W, 3) uint8`` with the pixels of ``rims (H, W) bool`` (:func:`rim_mask`)
    filled from the pixels around them (pull-push interpolation,
    :func:`vtts.fit.texture.pull_push`, over the rims' box and a margin): the skin the frame
    hides, as the skin beside it shows, so that the texture takes no frame. A copy."""
    from vtts.fit.texture import pull_push

    out = np.array(image, np.uint8, copy=True)
    if not rims.any():
        return out
    rows, cols = np.nonzero(rims)
    margin = 8
    r0, r1 = max(rows.min() - margin, 0), min(rows.max() + margin + 1, rims.shape[0])
    c0, c1 = max(cols.min() - margin, 0), min(cols.max() + margin + 1, rims.shape[1])
    hole = rims[r0:r1, c0:c1]
    filled = pull_push(out[r0:r1, c0:c1].astype(np.float32), (~hole).astype(np.float32))
    out[r0:r1, c0:c1][hole] = np.clip(filled[hole] + 0.5, 0, 255).astype(np.uint8)
    return out


# ---- the frame as a part of the head ----------------------------------------------------------

#: The glasses' part: its IndexedFaceSet, its Appearance and its texture (an RGBA image of its
#: own beside the atlas: the photo's frame pixels, transparent elsewhere).
PART, APPEARANCE, TEXTURE = "GLASSES", "GLASSES_LOOK", "GLASSES_TEXTURE"
#: The Transform the part hangs under: it turns and nods with the head, not with the jaw or
#: the lids.
PARENT = "HEAD_ROLL"
#: The part's grid cells (photo pixels, square): a cell is kept where it holds a rim pixel.
CELL = 2
#: How far the frame stands in front of the skin beneath it, at least (eye distances; the eye
#: distance is about 6.3 cm: 0.05 is 3 mm), and how far its front bends back at one eye
#: distance to either side of the bridge (a frame's front follows the face's curve a little).
CLEAR, WRAP = 0.05, 0.08
#: Beyond this (eye distances to either side of the bridge: a frame's hinges) what the photo
#: shows of the frame is its temples' arms, which run back towards the ears: there the surface
#: falls back this much in depth per unit across.
HINGE, TEMPLE = 1.15, 2.0


@dataclass
class GlassesPart:
    """The glasses' frame as a part of the head (:func:`glasses_part`).

    points     ``(n, 3)`` its vertices (model units, the head's frame)
    texcoords  ``(n, 2)`` each vertex's texture coordinate in :attr:`texture`
    quads      ``(m, 4)`` its faces, vertex indices counter-clockwise seen from the camera
    texture    ``(h, w, 4) uint8`` RGBA: the photo's frame pixels, alpha 0 elsewhere
    """

    points: np.ndarray
    texcoords: np.ndarray
    quads: np.ndarray
    texture: np.ndarray


def glasses_part(photo: np.ndarray, rims: np.ndarray, camera: Camera, face: np.ndarray,
                 landmarks: np.ndarray, depth: np.ndarray | None = None
                 ) -> GlassesPart | None:  # fmt: skip
    """The frame that ``photo (H, W, 3) uint8`` shows at ``rims (H, W) bool`` (:func:`rim_mask`)
    as a thin shape in front of the eyes of the fitted head whose neutral skin is ``face (p,
    3)`` (``FACE``'s points, model units), seen by ``camera`` (the photo's, in the model's
    frame; the head faces +z): the grid of :data:`CELL`-pixel cells that hold a rim pixel,
    each vertex lifted along its pixel's ray to the depth of the bridge over the nose (the
    skin's depth between the eyes ``landmarks (468, ≥2)``, pixels, and :data:`CLEAR` in front
    of it), bent back by :data:`WRAP` towards the sides, falling back by :data:`TEMPLE` beyond
    the :data:`HINGE` (the temples' arms) and never closer than :data:`CLEAR` to the skin
    beneath — nor to whatever else the photo's view shows there (hair, an ear), where ``depth
    (H, W)`` gives its distance from the camera (:func:`vtts.fit.texture.depth_map`); textured
    with the photo's pixels there (alpha: the rims), so that at the photo's view it draws the
    frame as the photo shows it. None where no rim was found."""
    from scipy.interpolate import LinearNDInterpolator

    from vtts.fit.texture import pull_push

    h, w = rims.shape
    if not rims.any():
        return None
    rows, cols = np.nonzero(rims)
    x0, x1 = max(int(cols.min()) - CELL, 0), min(int(cols.max()) + 2 * CELL, w)
    y0, y1 = max(int(rows.min()) - CELL, 0), min(int(rows.max()) + 2 * CELL, h)
    x0, y0 = x0 - x0 % CELL, y0 - y0 % CELL
    nx, ny = -(-(x1 - x0) // CELL), -(-(y1 - y0) // CELL)
    box = np.zeros((ny * CELL, nx * CELL), bool)
    part = rims[y0 : y0 + ny * CELL, x0 : x0 + nx * CELL]
    box[: part.shape[0], : part.shape[1]] = part
    kept = box.reshape(ny, CELL, nx, CELL).any(axis=(1, 3))
    cy, cx = np.nonzero(kept)
    # the cells' corners, numbered once: (ny + 1, nx + 1) grid
    corners = np.stack([cy * (nx + 1) + cx, cy * (nx + 1) + cx + 1,
                        (cy + 1) * (nx + 1) + cx + 1, (cy + 1) * (nx + 1) + cx], 1)  # fmt: skip
    used, quads = np.unique(corners, return_inverse=True)
    quads = quads.reshape(-1, 4)
    px = np.stack([x0 + (used % (nx + 1)) * CELL, y0 + (used // (nx + 1)) * CELL], 1).astype(float)
    # each pixel's ray in the model's frame
    origin, d = camera.pose[:3, 3], _ray(camera, px)
    # the skin beneath: the face's points interpolated over where the photo sees them
    xy = camera.project(face)
    pad = 0.25 * max(x1 - x0, y1 - y0)  # the skin around the box (the triangulation's time)
    near = (
        (xy[:, 0] > x0 - pad)
        & (xy[:, 0] < x1 + pad)
        & (xy[:, 1] > y0 - pad)
        & (xy[:, 1] < y1 + pad)
    )
    skin = LinearNDInterpolator(xy[near], face[near, 2])
    centre = _frame(landmarks)[0]
    bridge = np.asarray(skin(centre[None]), float)[0]
    e = _model_distance(camera, landmarks, skin)
    if not (np.isfinite(bridge) and np.isfinite(e) and e > 0):
        return None
    below = np.asarray(skin(px), float)
    below = np.where(np.isfinite(below), below, -np.inf)
    # the bridge's point on its ray gives the part's middle across
    ray = _ray(camera, centre[None])[0]
    mid_x = origin[0] + (bridge - origin[2]) / ray[2] * ray[0]
    z = bridge + CLEAR * e
    for _ in range(4):  # the bend depends on x, which depends on the depth: a few times
        t = (z - origin[2]) / d[:, 2]
        u = np.abs(origin[0] + t * d[:, 0] - mid_x) / e
        front = bridge + CLEAR * e - WRAP * e * u**2 - TEMPLE * e * np.maximum(u - HINGE, 0.0)
        z = np.maximum(front, below + CLEAR * e)
    t = (z - origin[2]) / d[:, 2]
    if depth is not None:
        # in front of what the photo's view shows at each corner's pixels (the nearest of them)
        near_px = ndimage.minimum_filter(depth, size=3, mode="nearest")
        col = np.clip(px[:, 0].astype(int), 0, w - 1)
        row = np.clip(px[:, 1].astype(int), 0, h - 1)
        t = np.minimum(t, (near_px[row, col] - CLEAR * e) / np.linalg.norm(d, axis=1))
    points = origin + t[:, None] * d
    # the texture: the photo over the box, a power of two on each side (texels on pixels)
    tw = 1 << max(nx * CELL - 1, 1).bit_length()
    th = 1 << max(ny * CELL - 1, 1).bit_length()
    crop = np.zeros((th, tw, 3), np.float32)
    alpha = np.zeros((th, tw), bool)
    src = photo[y0 : min(y0 + th, h), x0 : min(x0 + tw, w)]
    crop[: src.shape[0], : src.shape[1]] = src
    alpha[: src.shape[0], : src.shape[1]] = rims[y0 : y0 + src.shape[0], x0 : x0 + src.shape[1]]
    # the texels around the frame take its colours (the texture's filtering mixes them in)
    filled = pull_push(crop, alpha.astype(np.float32))
    rgb = np.where(alpha[..., None], crop, filled)
    texture = np.dstack([np.clip(rgb + 0.5, 0, 255).astype(np.uint8),
                         np.where(alpha, 255, 0).astype(np.uint8)])  # fmt: skip
    texcoords = np.stack([(px[:, 0] - x0) / tw, 1.0 - (px[:, 1] - y0) / th], 1)
    # counter-clockwise seen from the camera: the image's rows run down
    quads = quads[:, ::-1]
    return GlassesPart(points, texcoords, quads, texture)


def _ray(camera: Camera, px: np.ndarray) -> np.ndarray:
    """``(n, 3)`` the directions (model frame) of the rays through pixels ``px (n, 2)``."""
    d = np.stack([(px[:, 0] - camera.cx) / camera.fx, -(px[:, 1] - camera.cy) / camera.fy,
                  -np.ones(len(px))], 1)  # fmt: skip
    return d @ camera.pose[:3, :3].T


def _model_distance(camera: Camera, landmarks: np.ndarray, skin) -> float:
    """The eye distance in model units: the eyes' centres lifted onto the skin's depth."""
    eyes = eye_centres(landmarks)
    z = np.asarray(skin(eyes), float)
    if not np.isfinite(z).all():
        return float("nan")
    d = _ray(camera, eyes)
    origin = camera.pose[:3, 3]
    p = origin + ((z - origin[2]) / d[:, 2])[:, None] * d
    return float(np.linalg.norm(p[0] - p[1]))


def add_glasses(scene: Scene, part: GlassesPart, url: str) -> None:
    """Put ``part`` into ``scene`` (changed in place) as ``DEF GLASSES`` IndexedFaceSet under
    the head's :data:`PARENT` Transform, drawn from both sides, unlit (an Appearance without a
    Material: the photo's pixels as they are), with its texture ``DEF GLASSES_TEXTURE``
    ImageTexture at ``url`` (an RGBA image: where its alpha is under the renderer's
    :data:`~vtts.render.scene.ALPHA_CUTOFF` the part is not drawn)."""
    text = (
        "#VRML V2.0 utf8\nShape {\n"
        f"  appearance DEF {APPEARANCE} Appearance {{\n"
        f'    texture DEF {TEXTURE} ImageTexture {{ url "{url}" repeatS FALSE repeatT FALSE }}\n'
        "  }\n"
        f"  geometry DEF {PART} IndexedFaceSet {{\n    solid FALSE\n    creaseAngle 0\n"
        "    coord Coordinate { point [ 0 0 0 ] }\n"
        "    texCoord TextureCoordinate { point [ 0 0 ] }\n"
        "    coordIndex [ 0 0 0 -1 ]\n  }\n}\n"
    )
    parsed = parse(text)
    shape = parsed.roots[0]
    ifs = shape["geometry"].expand()
    ifs["coord"].expand().fields["point"] = np.round(part.points, 6) + 0.0
    ifs["texCoord"].expand().fields["point"] = np.round(part.texcoords, 6) + 0.0
    ifs.fields["coordIndex"] = (
        np.c_[part.quads, -np.ones(len(part.quads), int)].ravel().astype(np.int32)
    )
    if PART in scene.defs:
        raise ValueError(f"the scene has a {PART} already")
    scene.node(PARENT).expand().fields["children"].append(shape)
    for name in (PART, APPEARANCE, TEXTURE):
        scene.defs[name] = parsed.defs[name]
