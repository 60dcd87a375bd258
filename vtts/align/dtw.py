"""Dynamic time warping in bounded memory: a corridor DTW, refined from coarse to fine.

The local cost of matching reference frame ``i`` with recording frame ``j`` is the Euclidean
distance of their feature vectors. The accumulated cost obeys the usual recurrence with the
three steps (1, 0), (0, 1), (1, 1)::

    D[i, j] = c[i, j] + min(D[i-1, j-1], D[i-1, j], D[i, j-1])

Only a corridor of cells is ever stored: row ``i`` holds the columns ``lo[i] ≤ j < hi[i]``. A row
is computed in one vectorized step although ``D[i, j]`` depends on ``D[i, j-1]`` of the same row:
with ``A[j] = c[i, j] + min(D[i-1, j-1], D[i-1, j])`` and ``S`` the running sum of ``c[i, ·]``
along the row, ``D[i, j] = S[j] + min_{k ≤ j}(A[k] − S[k])`` — a cumulative minimum.

The corridor comes from the same alignment at half the resolution (both sequences averaged in
pairs), widened by ``radius`` frames, recursively, down to a size whose full matrix is small
(the approach of FastDTW, Salvador & Chan 2007). Memory and time are then proportional to
``(n + m) × radius`` instead of ``n × m``: 10 minutes at 10 ms frames is 60,000 rows of a few
hundred cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Cells of a full cost matrix computed without a corridor (about 16 MB of float32).
FULL_CELLS = 4_000_000
#: Frames added on each side of the projected coarse path.
RADIUS = 24


def local_costs(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``(k,)`` Euclidean distances of one ``(d,)`` frame ``x`` to ``(k, d)`` frames ``y``."""
    diff = y - x
    return np.sqrt(np.einsum("ij,ij->i", diff, diff))


@dataclass(frozen=True)
class Pauses:
    """Where the recording may pause although the reference does not: a reference frame with
    ``rows[i]`` (a word boundary) matched with a recording frame with ``cols[j]`` (silence)
    costs at most ``cost``, so that the path can rest on that boundary for a whole pause."""

    rows: np.ndarray
    cols: np.ndarray
    cost: float

    def halved(self) -> Pauses:
        return Pauses(_halve_mask(self.rows), _halve_mask(self.cols), self.cost)


def _halve_mask(mask: np.ndarray) -> np.ndarray:
    n = len(mask) // 2 * 2
    half = mask[:n:2] | mask[1:n:2]
    return np.append(half, mask[n:]) if len(mask) % 2 else half


def corridor_dtw(
    x: np.ndarray,
    y: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    pauses: Pauses | None = None,
) -> tuple[np.ndarray, float]:
    """The optimal warping path of ``(n, d)`` reference frames ``x`` against ``(m, d)``
    recording frames ``y`` within the corridor ``lo[i] ≤ j < hi[i]``.

    ``lo`` and ``hi`` are ``(n,)`` int arrays, both non-decreasing, with ``lo[0] == 0``,
    ``hi[-1] == m`` and ``lo[i] ≤ hi[i-1]`` (consecutive rows touch). Returns the path as
    ``(k, 2)`` int pairs ``(i, j)`` from ``(0, 0)`` to ``(n-1, m-1)``, and its total cost.
    """
    n, m = len(x), len(y)
    # the rows side by side in one flat array: a wide spot (a long pause) costs only itself
    offsets = np.concatenate([[0], np.cumsum(hi - lo)])
    acc = np.empty(int(offsets[-1]), dtype=np.float64)
    for i in range(n):
        a, b = int(lo[i]), int(hi[i])
        c = local_costs(x[i], y[a:b]).astype(np.float64)
        if pauses is not None and pauses.rows[i]:
            c = np.where(pauses.cols[a:b], np.minimum(c, pauses.cost), c)
        s = np.cumsum(c)
        row = acc[offsets[i] : offsets[i + 1]]
        if i == 0:
            row[:] = s
            continue
        pa, pb = int(lo[i - 1]), int(hi[i - 1])
        prev = np.full(b - a + 1, np.inf)  # D[i-1, a-1 .. b-1]
        s0, s1 = max(pa, a - 1), min(pb, b)
        if s1 > s0:
            prev[s0 - (a - 1) : s1 - (a - 1)] = acc[
                offsets[i - 1] + s0 - pa : offsets[i - 1] + s1 - pa
            ]
        best = np.minimum(prev[1:], prev[:-1]) + c  # A[j]
        row[:] = s + np.minimum.accumulate(best - s)
    total = float(acc[offsets[n - 1] + m - 1 - int(lo[n - 1])])
    return _backtrack(acc, offsets, lo, hi), total


def _backtrack(acc: np.ndarray, offsets: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    n = len(lo)
    i, j = n - 1, int(hi[n - 1]) - 1
    path = [(i, j)]
    inf = np.inf
    lo_l, hi_l, off_l = lo.tolist(), hi.tolist(), offsets.tolist()

    def at(r: int, col: int) -> float:
        if r < 0 or col < lo_l[r] or col >= hi_l[r]:
            return inf
        return acc[off_l[r] + col - lo_l[r]]

    while i > 0 or j > 0:
        diag, up, left = at(i - 1, j - 1), at(i - 1, j), at(i, j - 1)
        if diag <= up and diag <= left:
            i, j = i - 1, j - 1
        elif up <= left:
            i -= 1
        else:
            j -= 1
        path.append((i, j))
    return np.array(path[::-1], dtype=np.int64)


def _halve(x: np.ndarray) -> np.ndarray:
    n = len(x) // 2 * 2
    half = 0.5 * (x[:n:2] + x[1:n:2])
    return np.vstack([half, x[n:]]) if len(x) % 2 else half


def _corridor_from(path: np.ndarray, n: int, m: int, radius: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``[lo, hi)`` of the fine corridor around a coarse ``path`` (each coarse cell covers
    2 × 2 fine cells), widened by ``radius`` and made monotone and connected."""
    lo = np.full(n, m, dtype=np.int64)
    hi = np.zeros(n, dtype=np.int64)
    for di in (0, 1):
        rows = np.minimum(2 * path[:, 0] + di, n - 1)
        np.minimum.at(lo, rows, 2 * path[:, 1])
        np.maximum.at(hi, rows, np.minimum(2 * path[:, 1] + 2, m))
    lo = np.maximum(lo - radius, 0)
    hi = np.minimum(hi + radius, m)
    # every row touched; make both bounds non-decreasing and consecutive rows overlap
    lo = np.minimum.accumulate(lo[::-1])[::-1]
    hi = np.maximum.accumulate(hi)
    lo[0], hi[-1] = 0, m
    lo[1:] = np.minimum(lo[1:], hi[:-1])
    return lo, hi


def dtw_path(
    x: np.ndarray,
    y: np.ndarray,
    *,
    radius: int = RADIUS,
    band: float | None = None,
    pauses: Pauses | None = None,
) -> tuple[np.ndarray, float]:
    """Warping path ``(k, 2)`` of ``(n, d)`` frames ``x`` against ``(m, d)`` frames ``y`` and its
    cost, in memory proportional to ``(n + m) × radius`` (see the module docstring).

    ``band``: at the coarsest level, keep only cells within this fraction of the longer length
    of the diagonal of the length ratio (a Sakoe–Chiba band); ``None`` keeps them all.
    """
    n, m = len(x), len(y)
    if n * m <= FULL_CELLS or min(n, m) < 4 * radius:
        lo, hi = _band(n, m, band)
        return corridor_dtw(x, y, lo, hi, pauses)
    half = pauses.halved() if pauses is not None else None
    coarse, _ = dtw_path(_halve(x), _halve(y), radius=radius, band=band, pauses=half)
    lo, hi = _corridor_from(coarse, n, m, radius)
    return corridor_dtw(x, y, lo, hi, pauses)


def _band(n: int, m: int, band: float | None) -> tuple[np.ndarray, np.ndarray]:
    if band is None:
        return np.zeros(n, np.int64), np.full(n, m, np.int64)
    half = max(int(band * max(n, m)), 2)
    centre = np.arange(n) * (m - 1) / max(n - 1, 1)
    lo = np.clip(np.floor(centre - half), 0, m).astype(np.int64)
    hi = np.clip(np.ceil(centre + half) + 1, 0, m).astype(np.int64)
    lo[0], hi[-1] = 0, m
    lo[1:] = np.minimum(lo[1:], hi[:-1])
    return lo, hi
