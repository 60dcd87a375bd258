"""The hair as a shell: the fitted head's skull grown or shrunk to the photo's hair silhouette.

The generic heads' ``HAIR`` is a skull with a painted cap. A photo shows how far the hair
reaches around the face — a bob, a fringe of curls, hair flat to the skull — through the
person's silhouette (:mod:`vtts.fit.segment`). Seen from the photo's camera, each direction
``φ`` around the skull's projected centre has a radius at which the photo's person ends and one
at which the fitted head's drawing ends (its projected points); their ratio ``s(φ)``, smoothed
around the circle and bounded (:data:`SCALE_RANGE`), scales every ``HAIR`` point's offset from
the skull's centre, in depth as much as across, so that the hair keeps its volume when the head
turns: a point's scale is that of the direction in which the photo sees it. Directions from
the ears' height down meet the shoulders, not hair: there the scale fades to 1. Points on and
near the face's border keep their place (the seam with ``FACE`` stays closed): the scale fades
in over :data:`SEAM` model units from it.

Ears go with the skull beside them. An ear whose drawing falls mostly outside the photo's
person is one the photo does not show (hidden by the hair, or a narrower head): it is folded
away (its points onto one point: no triangle left to draw); one inside is painted by the photo
like the rest — with hair where hair covers it.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from vtts.errors import VttsWarning
from vtts.render.camera import Camera
from vtts.vrml import Scene

#: The skull's part, and the ears that sit on it.
HAIR = "HAIR"
EARS = ("L_EAR", "R_EAR")
#: Directions around the skull's projected centre.
BINS = 180
#: How far a direction's scale may go: hair flat on the skull to a large hairdo.
SCALE_RANGE = (0.8, 1.6)
#: Smoothing of the scale around the circle (radians).
SMOOTH = math.radians(8.0)
#: Directions more than this (radians) from the head's up, in the picture, scale fully; beyond
#: :data:`DOWN` they keep the generic skull (there the shoulders and the neck are).
SIDE, DOWN = math.radians(80.0), math.radians(110.0)
#: Model units (the face is about 1.2 wide) over which the scale fades in from the face's border.
SEAM = 0.25
#: Share of an ear's projected points that must lie on the photo's person for it to be kept: an
#: ear drawn partly over the background is one the photo does not show where the head puts it.
EAR_SHOWN = 0.85
#: How far the shell's silhouette stays inside the photo's person: a share of its radius, at
#: least some pixels (hair's edge is ragged and the renderer's edge pixels mix in the background).
INSET_SHARE, INSET_PX = 0.04, 2.0
#: Probability from which a pixel counts as the person.
PERSON = 0.5


@dataclass
class HairShell:
    """What :func:`fit_hair_shell` did.

    scale   ``(BINS,)`` the scale of each direction (1 where unchanged)
    centre  ``(3,)`` the skull's centre (model units)
    capped  True where the photo's silhouette reached beyond :data:`SCALE_RANGE` above the head
    ears    ``{ear: bool}`` whether each ear was kept
    """

    scale: np.ndarray
    centre: np.ndarray
    capped: bool
    ears: dict[str, bool]


def _points(scene: Scene, name: str) -> np.ndarray:
    return np.asarray(scene.node(name).expand()["coord"].expand()["point"], np.float64)


def _set_points(scene: Scene, name: str, points: np.ndarray) -> None:
    scene.node(name).expand()["coord"].expand().fields["point"] = np.round(points, 6) + 0.0


def _angles(xy: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = xy - centre
    return np.arctan2(d[:, 1], d[:, 0]), np.hypot(d[:, 0], d[:, 1])


def silhouette_radius(person: np.ndarray, centre: np.ndarray, start: np.ndarray,
                      stop: np.ndarray) -> np.ndarray:  # fmt: skip
    """``(BINS,)`` pixels from ``centre (2,)`` to where the person ends in each direction of
    ``person (H, W) bool``: the first pixel off the person from ``start (BINS,)`` outward, at
    most ``stop (BINS,)``."""
    h, w = person.shape
    phi = (np.arange(BINS) + 0.5) / BINS * 2 * math.pi - math.pi
    steps = np.arange(0.0, float(stop.max()) + 1.0, 1.0)
    x = centre[0] + np.cos(phi)[:, None] * steps[None]
    y = centre[1] + np.sin(phi)[:, None] * steps[None]
    inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    on = np.zeros(x.shape, bool)
    on[inside] = person[y[inside].astype(int), x[inside].astype(int)]
    off = ~on & (steps[None] >= start[:, None])
    first = np.where(off.any(axis=1), off.argmax(axis=1), len(steps) - 1)
    return np.minimum(steps[first], stop)


def fit_hair_shell(scene: Scene, camera: Camera, person: np.ndarray) -> HairShell | None:
    """Grow or shrink the ``HAIR`` of ``scene`` (fitted, changed in place) to the photo's
    silhouette, and move or fold away its ears (see the module docstring). ``camera`` is the
    photo's (in the model's frame); ``person (H, W)`` the probability that a pixel shows the
    person (:func:`vtts.fit.segment.person_probability`). None where the head has no
    ``HAIR``."""
    if HAIR not in scene.defs or "FACE" not in scene.defs:
        return None
    hair = _points(scene, HAIR)
    face = _points(scene, "FACE")
    mask = ndimage.binary_opening(person >= PERSON, iterations=2)
    lo, hi = hair.min(axis=0), hair.max(axis=0)
    centre3 = np.array([float(hair[:, 0].mean()), (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2])
    c = camera.project(centre3[None])[0]
    top = camera.project((centre3 + [0.0, 1.0, 0.0])[None])[0]
    up = math.atan2(top[1] - c[1], top[0] - c[0])
    drawn = np.vstack([hair, face, *(_points(scene, e) for e in EARS if e in scene.defs)])
    phi_d, r_d = _angles(camera.project(drawn), c)
    bins = np.clip(((phi_d + math.pi) / (2 * math.pi) * BINS).astype(int), 0, BINS - 1)
    model_r = np.zeros(BINS)
    np.maximum.at(model_r, bins, r_d)
    model_r = ndimage.maximum_filter1d(model_r, 3, mode="wrap")
    model_r = np.maximum(model_r, 1.0)
    photo_r = silhouette_radius(mask, c, 0.5 * model_r, SCALE_RANGE[1] * 1.2 * model_r)
    # inside the edge: the renderer's edge pixels mix in the background the photo shows there,
    # and the smooth shell cannot follow a ragged outline
    photo_r = np.maximum(photo_r - np.maximum(INSET_SHARE * photo_r, INSET_PX), 1.0)
    raw = photo_r / model_r
    capped = False
    phi = (np.arange(BINS) + 0.5) / BINS * 2 * math.pi - math.pi
    away = np.abs((phi - up + math.pi) % (2 * math.pi) - math.pi)  # from the head's up
    t = np.clip((DOWN - away) / (DOWN - SIDE), 0.0, 1.0)
    weight = t * t * (3 - 2 * t)
    if np.any((raw > SCALE_RANGE[1] * 1.15) & (away < math.radians(30))):
        capped = True
        warnings.warn(
            VttsWarning(
                "the photo's head reaches far above the skull (a hat or a tall hairdo?): the "
                f"hair is kept within {SCALE_RANGE[1]:g} times the skull; a hat is not modelled"
            ),
            stacklevel=2,
        )
    s = np.clip(raw, *SCALE_RANGE)
    s = 1.0 + weight * (s - 1.0)
    sigma = SMOOTH / (2 * math.pi / BINS)
    s = ndimage.gaussian_filter1d(s, sigma, mode="wrap")
    # the seam: HAIR points on FACE's border (and near it) keep their place
    face_tree = cKDTree(face)
    near, _ = face_tree.query(hair, distance_upper_bound=1e-4)
    seam = hair[np.isfinite(near)]
    fade = np.ones(len(hair))
    if len(seam):
        d, _ = cKDTree(seam).query(hair)
        u = np.clip(d / SEAM, 0.0, 1.0)
        fade = u * u * (3 - 2 * u)
    phi_h, _ = _angles(camera.project(hair), c)
    s_h = np.interp(phi_h, phi, s, period=2 * math.pi)
    moved = hair + ((s_h - 1.0) * fade)[:, None] * (hair - centre3)
    _set_points(scene, HAIR, moved)
    ears = {}
    h, w = person.shape
    hair_tree = cKDTree(hair)
    for name in EARS:
        if name not in scene.defs:
            continue
        ear = _points(scene, name)
        _, k = hair_tree.query(ear.mean(axis=0))
        ear = ear + (moved[k] - hair[k])
        xy = camera.project(ear)
        col = np.clip(xy[:, 0].astype(int), 0, w - 1)
        row = np.clip(xy[:, 1].astype(int), 0, h - 1)
        inside = (xy[:, 0] >= 0) & (xy[:, 0] < w) & (xy[:, 1] >= 0) & (xy[:, 1] < h)
        shown = float(np.mean(inside & mask[row, col]))
        ears[name] = shown >= EAR_SHOWN
        if not ears[name]:
            ear = np.repeat(ear.mean(axis=0)[None], len(ear), axis=0)
        _set_points(scene, name, ear)
    return HairShell(s, centre3, capped, ears)
