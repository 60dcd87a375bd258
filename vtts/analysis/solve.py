"""The image pyramid's preparation and the least-squares solve of the estimator
(:mod:`vtts.analysis.estimator`) that the tracker (:mod:`vtts.analysis.tracker`) shares, so that
both compute the same numbers to the bit: subsampling and smoothing, image gradients at face
pixels, the normal equations of the optical-flow constraints, and their solution."""

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
    if image.dtype == np.uint8 and image.ndim == 3 and factor <= 16:
        # the blocks' sums in integers: exact, as float32's are (the same numbers), and faster
        # than converting the whole image first
        total = np.zeros((h, w, *image.shape[2:]), np.uint16)
        for i in range(factor):
            for j in range(factor):
                total += image[i : h * factor : factor, j : w * factor : factor]
        return total.astype(np.float32) * np.float32(1.0 / (factor * factor))
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


def gradients_at(
    a: np.ndarray,
    b: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    gain: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Central differences ``(d/dY, d/dX)``, each ``(n, C)``, of the mean of the ``(H, W, C)``
    images ``a`` and ``gain · b`` (``gain`` ``(C,)``, default 1; an offset added to ``b`` would
    not change them) at the pixels ``rows``, ``cols`` (one-sided at the border), as
    ``np.gradient`` computes them over the whole image."""
    h, w = a.shape[:2]
    up, down = np.maximum(rows - 1, 0), np.minimum(rows + 1, h - 1)
    left, right = np.maximum(cols - 1, 0), np.minimum(cols + 1, w - 1)
    if gain is None:
        dy = (a[down, cols] + b[down, cols]) - (a[up, cols] + b[up, cols])
        dx = (a[rows, right] + b[rows, right]) - (a[rows, left] + b[rows, left])
    else:
        dy = (a[down, cols] - a[up, cols]) + (b[down, cols] - b[up, cols]) * gain
        dx = (a[rows, right] - a[rows, left]) + (b[rows, right] - b[rows, left]) * gain
    sy = (0.5 / (down - up)).astype(a.dtype)[:, None]
    sx = (0.5 / (right - left)).astype(a.dtype)[:, None]
    return dy * sy, dx * sx


def normal_equations(
    du: np.ndarray,
    dv: np.ndarray,
    gx: np.ndarray,
    gy: np.ndarray,
    r: np.ndarray,
    s: np.ndarray | None,
    weights: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The normal equations ``(AᵀA, Aᵀb)`` (float64) of the per-pixel, per-channel equations
    ``−(gx_c·du + gy_c·dv)·Δ + s_c·Δgain_c + Δoffset_c = r_c`` (Equation 10 with the image
    motion of Equations 14–16, and the light model when ``s`` is given).

    ``du``, ``dv`` ``(N, K)``: image motion (pixels per unit) of each unknown at each pixel;
    ``gx``, ``gy``, ``r``, ``s`` ``(N, 3)``: gradients, residual and synthetic color per
    channel. Unknowns: the K, then the gains and offsets of the 3 channels. A is never formed:
    its 3N rows reduce per pixel to the 2×2 matrix of the gradients summed over the channels,
    so every product is an (N × K)ᵀ(N × K) one. ``weights`` ``(N,)``: each pixel's weight in
    the least-squares sum (default 1)."""
    du = du.astype(np.float64)
    dv = dv.astype(np.float64)
    gx = gx.astype(np.float64)
    gy = gy.astype(np.float64)
    r = r.astype(np.float64)
    # a pixel's rows scaled by √w: the offsets' coefficient 1 becomes √w too
    one = np.ones(len(r)) if weights is None else np.sqrt(weights.astype(np.float64))
    if weights is not None:
        gx, gy, r = gx * one[:, None], gy * one[:, None], r * one[:, None]
    k = du.shape[1]
    m = k + (6 if s is not None else 0)
    ata = np.zeros((m, m))
    atb = np.zeros(m)
    gxx, gxy, gyy = (gx * gx).sum(1), (gx * gy).sum(1), (gy * gy).sum(1)
    cross = (du * gxy[:, None]).T @ dv
    ata[:k, :k] = (du * gxx[:, None]).T @ du + cross + cross.T + (dv * gyy[:, None]).T @ dv
    atb[:k] = -(du.T @ (gx * r).sum(1) + dv.T @ (gy * r).sum(1))
    if s is not None:
        s = s.astype(np.float64) * one[:, None]
        for c in range(3):
            g, o = k + c, k + 3 + c  # the channel's gain and offset
            ata[:k, g] = -(du.T @ (gx[:, c] * s[:, c]) + dv.T @ (gy[:, c] * s[:, c]))
            ata[:k, o] = -(du.T @ (gx[:, c] * one) + dv.T @ (gy[:, c] * one))
            ata[g, g] = s[:, c] @ s[:, c]
            ata[g, o] = s[:, c] @ one
            ata[o, o] = one @ one
            atb[g] = s[:, c] @ r[:, c]
            atb[o] = r[:, c] @ one
        upper = np.triu_indices(m, 1)
        ata[upper[::-1]] = ata[upper]
    return ata, atb


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
