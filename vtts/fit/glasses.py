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

A fitted head does not model glasses: :func:`vtts.fit.photo.fit_photo` warns when the photo
shows them (their frame is then painted on the skin: finding the whole rim — thin, clear
plastic or metal, broken by reflections — well enough to keep it off is not done).
"""

from __future__ import annotations

import numpy as np
from PIL import Image
from scipy import ndimage

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
    pts = np.asarray(landmarks, np.float64)[:, :2]
    right, left = pts[[33, 133]].mean(axis=0), pts[[362, 263]].mean(axis=0)
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
