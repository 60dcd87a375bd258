"""The neck of a head made for a video: ended at the collar, and (optionally) turning less than
the head.

**Ended at the collar.** The generic neck reaches well below the chin; made for a video
(:func:`vtts.fit.with_frame`) it would take what the frame shows there as its texture — a
collar, a bow tie — and turn it with the head over clothes that stay put. :func:`collar_row`
finds, from the head drawn at the frame's view, the first row from which down the neck shows
no skin (the face's own skin the reference), and :func:`cut_neck` moves the neck's rings below
that row up onto it.

**Weighed down.** In the generic heads the neck hangs inside the head's rotation Transforms
(``HEAD_YAW`` ⊃ ``HEAD_PITCH`` ⊃ ``HEAD_ROLL``, all pivoting at the top of the spine), so every
nod of the model swings the whole neck over the person's collar. A person's head turns on the
neck: the top of the neck goes with the skull, the bottom stays with the shoulders.

:func:`free_neck` takes the ``NECK`` Shape out of the head's Transforms (to the top level of
the scene, where it stands as it did at the neutral pose: the head Transforms are the identity
there) and gives it Animation Definition Tables for the head rotation FAPs 48–50 instead: each
neck vertex turns about the FAP's own pivot and axis (the Transform's ``center`` and
``rotation`` axis) by ``w · angle``, with a weight ``w`` that is 1 at and above the pivot (the
top of the spine, inside the skull) and falls smoothly to 0 at the neck's lowest point (the
collar); see :func:`neck_weights`. A rotation is not linear in its angle, so each table
samples it at :data:`BORDERS` (every 0.1 rad over ±0.8 rad; the chord of a 0.1 rad arc is off
it by r·0.1²/8, below a thousandth of the head's size at the neck's radius) and is linear
between; beyond ±0.8 rad the outer intervals extend. The tables are MPEG-4's own way of saying
how a FAP moves vertices, so the written model carries the neck's motion to any decoder
(``vtts play OUT.fbs --model OUT-model.wrl``).

Several rotations at once add their displacements (the tables superimpose linearly, as MPEG-4
defines them), while the head's Transforms compose: at the top of the neck the two differ by
the product of the angles times the radius (0.1 × 0.05 rad × 0.6 units ≈ 0.003 units, a
fifth of a pixel for Akiyo's CIF face), and the neck's top lies inside the skull.

The head *translation* (the coded stream's, not a FAP) still moves the whole model, the neck
with it. Since the estimator trades the head's pitch against its translation, a neck that holds
still under the pitch but moves with the translation fits a real collar no better than one that
turns with the head by much: measured on Akiyo and Carphone, the gain is no larger than the
difference between two runs, so it is not in the default path
(:data:`vtts.fit.photo.FREE_NECK`; docs/analysis.md has the figures).
"""

from __future__ import annotations

import numpy as np

from vtts.errors import FitError
from vtts.face.adt import AnimationTables, MeshTable
from vtts.face.miap import Miap
from vtts.vrml import Scene

#: The neck's IndexedFaceSet.
NECK = "NECK"
#: The head rotation FAPs and the Transform each one turns.
HEAD_ROTATIONS = {48: "HEAD_PITCH", 49: "HEAD_YAW", 50: "HEAD_ROLL"}
#: Interval borders of the neck's tables (AU = 1e-5 rad): every 0.1 rad over ±0.8 rad.
BORDERS = np.arange(-80_000.0, 80_001.0, 10_000.0)


def smoothstep(t: np.ndarray) -> np.ndarray:
    """``3t² − 2t³`` of ``t`` clipped to [0, 1]: 0 and 1 at the ends, flat at both."""
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def neck_weights(points: np.ndarray, pivot_y: float) -> np.ndarray:
    """``(p,)`` how much of the head's rotation each neck point ``points (p, 3)`` (model units,
    y up) follows: 1 at and above ``pivot_y`` (the top of the spine), 0 at the neck's lowest
    point, :func:`smoothstep` in height between."""
    y = np.asarray(points, np.float64)[:, 1]
    bottom = float(y.min())
    if pivot_y <= bottom:
        raise FitError(
            f"the head rotation's pivot (y = {pivot_y:g}) is not above the neck's lowest point "
            f"(y = {bottom:g}): the neck cannot be weighed down from it"
        )
    return smoothstep((y - bottom) / (pivot_y - bottom))


def rotation_table(points: np.ndarray, weights: np.ndarray, centre: np.ndarray,
                   axis: np.ndarray, per_unit: float,
                   borders: np.ndarray = BORDERS) -> np.ndarray:  # fmt: skip
    """``(n, p, 3)`` displacement per unit of each interval between ``borders (n+1,)`` (MIAP
    units) of ``points (p, 3)`` turned about the line through ``centre (3,)`` along ``axis
    (3,)`` by ``weights (p,)`` times the angle, ``per_unit`` rad a unit (the Transform table's
    unit; its sign gives the direction): the chords of the turned points' arcs."""
    k = np.asarray(axis, np.float64)
    k = k / np.linalg.norm(k)
    rel = np.asarray(points, np.float64) - centre
    angle = np.asarray(borders, np.float64)[:, None, None] * per_unit * weights[None, :, None]
    # Rodrigues: r cos a + (k × r) sin a + k (k · r)(1 − cos a)
    cross = np.cross(k, rel)[None]
    along = (rel @ k)[None, :, None] * k
    turned = rel * np.cos(angle) + cross * np.sin(angle) + along * (1 - np.cos(angle))
    at = turned - rel  # (n+1, p, 3) displacement at each border
    return (at[1:] - at[:-1]) / np.diff(borders)[:, None, None]


def free_neck(scene: Scene, tables: AnimationTables, borders: np.ndarray = BORDERS) -> None:
    """Take the ``NECK`` Shape of ``scene`` out of the head's rotation Transforms and give it
    tables for FAPs 48–50 in ``tables`` (both changed in place), as the module docstring
    describes. The head Transforms must be at their neutral (zero) angles."""
    if NECK not in scene.defs:
        raise FitError(f"the head has no {NECK} IndexedFaceSet to free from the head's rotation")
    neck = scene.node(NECK).expand()
    found = None
    for shape, _, path in scene.shapes():
        geom = shape["geometry"]
        if geom is not None and geom.expand() is neck:
            found = (shape, path)
            break
    if found is None or not found[1]:
        raise FitError(f"{NECK} is not drawn inside the head's Transforms")
    shape, path = found
    parent = path[-1]
    for node in path:
        if node.type_name == "Transform":
            angle = float(np.asarray(node["rotation"], np.float64)[3])
            moved = np.any(np.asarray(node["translation"]) != 0) or np.any(
                np.asarray(node["scale"]) != 1
            )
            if angle != 0 or moved:
                raise FitError(f"the head Transform {node.name} is not at its neutral pose")
    parent.fields["children"] = [c for c in parent["children"] if c is not shape]
    at = next((i + 1 for i, s in enumerate(scene.statements) if s is path[0]),
              len(scene.statements))  # fmt: skip
    scene.statements.insert(at, shape)
    points = np.asarray(neck["coord"].expand()["point"], np.float64)
    pitch = scene.node(HEAD_ROTATIONS[48]).expand()
    weights = neck_weights(points, float(np.asarray(pitch["center"], np.float64)[1]))
    moving = np.flatnonzero(weights > 0)
    for number, transform in HEAD_ROTATIONS.items():
        adt = tables.adts.get(Miap("fap", number))
        if adt is None:
            raise FitError(f"the head has no table for FAP {number}")
        node = scene.node(transform).expand()
        table = next((t for t in adt.transforms if t.node == transform and t.field == "rotation"),
                     None)  # fmt: skip
        if table is None:
            raise FitError(f"FAP {number} has no table that turns the head Transform {transform}")
        centre = np.asarray(node["center"], np.float64)
        axis, per_unit = table.neutral[:3], float(table.unit[0])
        slopes = rotation_table(points[moving], weights[moving], centre, axis, per_unit, borders)
        adt.meshes = [m for m in adt.meshes if m.node != NECK]
        adt.meshes.append(MeshTable(NECK, np.asarray(borders, np.float64), moving,
                                    np.round(slopes, 12) + 0.0))  # fmt: skip


# ---- the neck's bottom: where the frame stops showing skin ------------------------------------

#: How far (standard deviations of the face's skin) a pixel's chroma may lie from the face's
#: skin and still count as skin.
SKIN_SIGMAS = 3.0
#: The share of a row's neck pixels that must be skin for the row to show neck.
SKIN_SHARE = 0.5
#: Rows of the neck that show no skin, one after the other, that end it (a collar, a scarf, a
#: bow tie), as a share of the neck's height in the frame; at least :data:`MIN_COLLAR_ROWS`.
COLLAR_SHARE = 0.1
MIN_COLLAR_ROWS = 3
#: A neck with skin on fewer than this share of its pixels (and no run of rows that show it) is
#: covered from under the chin; one with more, but in no row on half of it (a neck in shadow
#: in a grey photo), is left whole.
COVERED_SHARE = 0.1
#: Points in each ring of the generic heads' neck.
RING_POINTS = 32


def skin_chroma(rgb: np.ndarray) -> np.ndarray:
    """``(..., 2)`` chroma of ``rgb (..., 3)`` (0–255) that does not change with brightness: the
    red and green shares of the sum (a small constant in the sum keeps the darkest pixels from
    scattering), so that the shadow under the chin reads as skin, as it is."""
    rgb = np.asarray(rgb, np.float64)
    total = rgb.sum(axis=-1, keepdims=True) + 10.0
    return 255.0 * rgb[..., :2] / total


def neck_rings(points: np.ndarray) -> np.ndarray:
    """The neck's ``points (p, 3)`` as rings ``(R, n, 3)``, bottom to top, the k-th point of
    every ring on the same line down the neck: the generic heads' neck is rings of
    :data:`RING_POINTS` points, the lowest first (``models/src/modeler.py``), which the fit's
    warp tilts a little and :func:`cut_neck` may have moved onto one another. Raises
    :class:`~vtts.errors.FitError` for a neck made otherwise. The rings are a copy."""
    points = np.array(points, np.float64)
    if len(points) >= 2 * RING_POINTS and len(points) % RING_POINTS == 0:
        rings = points.reshape(-1, RING_POINTS, 3)
        heights = rings[..., 1].mean(axis=1)
        if np.all(np.diff(heights) >= 0) and heights[-1] > heights[0]:
            return rings
    raise FitError(
        f"the neck's {len(points)} points are not rings of {RING_POINTS}, the lowest first: "
        "it cannot be cut at the collar"
    )


def collar_row(photo: np.ndarray, neck: np.ndarray, face: np.ndarray) -> int | None:
    """The first row of ``photo (H, W, 3) uint8`` from which down the neck shows no skin, or
    None where it shows skin to its bottom (or never): ``neck`` and ``face`` ``(H, W) bool``
    are the pixels where the head's neck and face are drawn at the photo's view.

    The face's pixels give the skin's chroma (:func:`skin_chroma`; median and covariance of
    the pixels within 2.5 median distances, so that lips, brows and eyes do not count); a
    neck pixel is skin within :data:`SKIN_SIGMAS` of it. A row shows neck where
    :data:`SKIN_SHARE` of its neck pixels are skin; from the first run of such rows down (as
    many rows as :data:`COLLAR_SHARE` of the neck's height, at least :data:`MIN_COLLAR_ROWS`),
    the neck ends at the first run of rows as long that are not (rows of fewer than 3 neck
    pixels count as neither). A neck that shows no such run of skin at all, and skin on fewer
    than :data:`COVERED_SHARE` of its pixels, is covered from under the chin (a high collar, a
    scarf): it ends at the first run of rows that are not skin."""
    skin = skin_chroma(photo[face])
    if len(skin) < 10 or not neck.any():
        return None
    centre = np.median(skin, axis=0)
    distance = np.linalg.norm(skin - centre, axis=1)
    inliers = skin[distance <= 2.5 * max(float(np.median(distance)), 1e-6)]
    cov = np.cov(inliers.T) + np.eye(2) * 1e-3
    d = skin_chroma(photo[neck]) - centre
    is_skin = np.einsum("ni,ij,nj->n", d, np.linalg.inv(cov), d) <= SKIN_SIGMAS**2
    rows = np.nonzero(neck)[0]
    top, bottom = int(rows.min()), int(rows.max())
    count = np.bincount(rows - top, minlength=bottom - top + 1)
    shown = np.bincount(rows - top, weights=is_skin, minlength=bottom - top + 1)
    share = shown / np.maximum(count, 1)
    skin_row = share >= SKIN_SHARE
    bare = ~skin_row & (count >= 3)  # a row of a pixel or two decides nothing
    run = max(MIN_COLLAR_ROWS, int(np.ceil(COLLAR_SHARE * (bottom - top + 1))))
    windows = np.lib.stride_tricks.sliding_window_view
    if len(share) < run:
        return None
    starts = np.flatnonzero(windows(skin_row, run).all(axis=1))  # the neck seen for a while
    ends = np.flatnonzero(windows(bare, run).all(axis=1))
    if starts.size == 0:  # no skin under the chin: covered from the top, or nothing to tell
        covered = is_skin.mean() < COVERED_SHARE and ends.size
        return top + int(ends[0]) if covered else None
    ends = ends[ends > starts[0]]
    return top + int(ends[0]) if ends.size else None


def cut_neck(scene: Scene, camera, row: float) -> float | None:
    """Shorten the ``NECK`` of ``scene`` (changed in place) to end at the frame's ``row`` as
    ``camera`` (the photo's, in the model's frame) sees it: the lowest ring becomes the one
    whose side facing the camera reaches down to that row, and the rings below it are moved
    up onto it (their triangles then have no area). Returns the neck's new bottom height
    (model units), or None where the row lies below the neck."""
    ifs = scene.node(NECK).expand()
    coord = ifs["coord"].expand()
    rings = neck_rings(coord["point"])
    eye = camera.pose[:3, 3]
    lowest = np.empty(len(rings))  # image row of each ring's lowest point the camera sees
    for r, ring in enumerate(rings):
        out = ring - ring.mean(axis=0)
        facing = np.einsum("ij,ij->i", out[:, [0, 2]], (eye - ring)[:, [0, 2]]) > 0
        lowest[r] = camera.project(ring[facing] if facing.any() else ring)[:, 1].max()
    if np.any(np.diff(lowest) > 0) or row >= lowest[0]:
        return None
    at = float(np.interp(row, lowest[::-1], np.arange(len(rings))[::-1]))  # from the bottom
    low = min(int(np.floor(at)), len(rings) - 2)
    s = at - low
    edge = np.round(rings[low] * (1 - s) + rings[low + 1] * s, 6) + 0.0
    rings[: low + 1] = edge
    coord.fields["point"] = rings.reshape(-1, 3)
    return float(edge[:, 1].mean())
