"""How far the mouth leads or lags the sound: the measure ``make bench`` (lipsync) reports.

A mouth signal per frame (how open it is: the lip gap of a timeline's frames, or the darkness of
the mouth region of rendered frames) is cross-correlated with the speech's RMS over each frame's
display interval ``[i / fps, (i + 1) / fps)``; the lag of the peak, in frames, is positive when
the mouth comes after the sound (frame ``i + lag`` shows the opening the sound of frame ``i``
has) and negative when it leads. Speech wants it at 0 or −1: the lips and jaw move before the
sound they shape.
"""

from __future__ import annotations

import numpy as np

from vtts.face.miap import N_PARAMS

__all__ = ["lip_gap", "lip_gaps", "peak_lag", "rms_per_frame"]


def rms_per_frame(audio: np.ndarray, rate: int, fps: float, n: int) -> np.ndarray:
    """``(n,)`` RMS of ``audio`` (samples at ``rate`` Hz) over each frame's display interval."""
    x = np.asarray(audio, dtype=np.float64)
    if x.ndim > 1:
        x = x.mean(axis=1)
    edges = np.round(np.arange(n + 1) / fps * rate).astype(np.int64).clip(0, x.size)
    squares = np.concatenate([[0.0], np.cumsum(x * x)])
    counts = np.diff(edges)
    sums = squares[edges[1:]] - squares[edges[:-1]]
    return np.sqrt(np.where(counts > 0, sums / np.maximum(counts, 1), 0.0))


def correlations(mouth: np.ndarray, rms: np.ndarray, max_lag: int) -> dict[int, float]:
    """Normalized cross-correlation of ``mouth`` with ``rms`` (same length) at each lag in
    ``-max_lag … max_lag`` frames (positive: the mouth after the sound)."""
    m = np.asarray(mouth, dtype=np.float64)
    r = np.asarray(rms, dtype=np.float64)
    n = min(m.size, r.size)
    m = m[:n] - m[:n].mean()
    r = r[:n] - r[:n].mean()
    m /= max(float(m.std()), 1e-12)
    r /= max(float(r.std()), 1e-12)
    out = {}
    for k in range(-max_lag, max_lag + 1):
        a, b = (m[k:], r[: n - k]) if k >= 0 else (m[: n + k], r[-k:])
        out[k] = float(np.mean(a * b)) if a.size else 0.0
    return out


def peak_lag(mouth: np.ndarray, rms: np.ndarray, max_lag: int = 5) -> int:
    """The lag (frames) where :func:`correlations` peaks."""
    c = correlations(mouth, rms, max_lag)
    return max(c, key=lambda k: c[k])


def lip_gap(model, params: np.ndarray) -> float:
    """Vertical distance between the inner lip midpoints (feature points 2.2 and 2.3) of
    ``model`` deformed by ``params``, in model units."""
    fp = model.tables.feature_points
    pose = model.engine.deform(params)
    (nu, vu), (nl, vl) = fp["2.2"], fp["2.3"]
    up = pose.points.get(nu, model.neutral_points(nu))[vu]
    lo = pose.points.get(nl, model.neutral_points(nl))[vl]
    return float(up[1] - lo[1])


def lip_gaps(model, params: np.ndarray) -> np.ndarray:
    """:func:`lip_gap` of every frame of ``params (n, N_PARAMS)``."""
    params = np.asarray(params, dtype=np.float64).reshape(-1, N_PARAMS)
    return np.array([lip_gap(model, p) for p in params])
