"""The image pyramid's preparation and the least-squares step that the estimator
(:mod:`vtts.analysis.estimator`) and the tracker (:mod:`vtts.analysis.tracker`) share, so that
both compute the same numbers to the bit."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter

#: The Gaussian filter's reach in standard deviations (its radius: ``int(SMOOTH_REACH · σ + 0.5)``
#: pixels).
SMOOTH_REACH = 2.0


def subsample(image: np.ndarray, factor: int) -> np.ndarray:
    """Moving-average subsampling of ``(H, W, C)`` by ``factor`` to ``float32`` (edges that do
    not fill a block are dropped)."""
    if factor == 1:
        return image.astype(np.float32, copy=False)
    h, w = image.shape[0] // factor, image.shape[1] // factor
    x = image[: h * factor, : w * factor].astype(np.float32)
    x = x.reshape(h, factor, w * factor, -1).sum(axis=1)  # rows of each block
    x = x.reshape(h, w, factor, -1).sum(axis=2)  # then columns
    return x * np.float32(1.0 / (factor * factor))


def smooth(image: np.ndarray, sigma: float) -> np.ndarray:
    """``(H, W, C)`` filtered with a Gaussian of ``sigma`` pixels along both image axes (not
    across channels; borders repeat the edge pixels); ``sigma <= 0``: the image itself."""
    if sigma <= 0:
        return image
    return gaussian_filter(image, sigma=(sigma, sigma, 0), mode="nearest", truncate=SMOOTH_REACH)


def least_squares(ata: np.ndarray, atb: np.ndarray) -> np.ndarray:
    """Solve the normal equations ``ata x = atb`` with column scaling and a whisper of
    damping, so that unknowns the pixels say nothing about stay put."""
    d = np.sqrt(np.diag(ata))
    big = d.max() if d.size else 1.0
    ok = d > 1e-9 * big
    x = np.zeros(ata.shape[0])
    if not ok.any():
        return x
    s = 1.0 / d[ok]
    m = ata[np.ix_(ok, ok)] * s[:, None] * s[None, :]
    m[np.diag_indices_from(m)] += 1e-9
    x[ok] = s * np.linalg.solve(m, atb[ok] * s)
    return x
