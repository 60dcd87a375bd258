"""How far the mouth leads or lags the sound: the measure ``make bench`` (lipsync) reports.

A mouth signal per frame (how open it is: the lip gap of a timeline's frames, or the darkness of
the mouth region of rendered frames) is cross-correlated with the speech's RMS over each frame's
display interval ``[i / fps, (i + 1) / fps)``; the lag of the peak, in frames, is positive when
the mouth comes after the sound (frame ``i + lag`` shows the opening the sound of frame ``i``
has) and negative when it leads. Speech wants it at 0 or −1: the lips and jaw move before the
sound they shape.

The bilabials' closures are judged against the speech itself (:func:`lip_closures`): where the
engine's own audio has the lips shut for each p, b and m, found from the sound alone — the
engine's phones only say which bilabial to look for and roughly where.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vtts.face.miap import N_PARAMS

__all__ = ["LipClosure", "high_band_db", "lip_closures", "lip_gap", "lip_gaps", "peak_lag",
           "rms_per_frame"]  # fmt: skip

#: The band whose energy tells a closure (Hz and up): with the lips shut, a stop is silent and a
#: nasal's sound leaves through the nose, which damps everything above the first formant.
HIGH_BAND_HZ = 1000.0
#: The step of :func:`high_band_db`, s.
BAND_STEP = 0.0025


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


# ---- bilabial closures in the audio -------------------------------------------------------------


@dataclass(frozen=True)
class LipClosure:
    """Where the audio has the lips shut for a run of adjacent bilabial phones (``m b`` is one
    closure): phones ``first`` … ``last`` (indices), from ``onset`` to ``release`` (s)."""

    first: int
    last: int
    onset: float
    release: float

    @property
    def centre(self) -> float:
        return 0.5 * (self.onset + self.release)


def high_band_db(audio: np.ndarray, rate: int, window: float = 0.02) -> np.ndarray:
    """``(n,)`` energy of ``audio`` above :data:`HIGH_BAND_HZ` in dB, every :data:`BAND_STEP` s
    (sample ``k`` at ``k * BAND_STEP``), over Hann windows of ``window`` s centred there (a
    zero-phase filter: no delay); floored 50 dB below its loudest."""
    from scipy.signal import butter, sosfiltfilt

    x = np.asarray(audio, dtype=np.float64)
    if x.ndim > 1:
        x = x.mean(axis=1)
    y = sosfiltfilt(butter(4, HIGH_BAND_HZ, "highpass", fs=rate, output="sos"), x)
    w = np.hanning(max(int(window * rate), 3))
    e = np.convolve(y * y, w / w.sum(), mode="same")[:: max(int(round(BAND_STEP * rate)), 1)]
    db = 10.0 * np.log10(e + 1e-12)
    return np.maximum(db, db.max() - 50.0)


def _is_nasal(label: str) -> bool:
    return label.lower().lstrip("'ˈˌ").startswith(("m", "em"))


def lip_closures(audio: np.ndarray, rate: int, phones) -> list[LipClosure]:
    """The lips' closure of every run of adjacent bilabial phones (viseme 1) of ``phones`` (with
    ``start``, ``end``, ``viseme``, ``phoneme``; in ``audio``'s clock, s), from the sound.

    Acoustic landmarks in the energy above 1 kHz (:func:`high_band_db`), its rate of rise over
    20 ms: the **release** is its steepest rise from the last phone's start (20 ms before a
    stop's, whose burst may lead its label; 15 ms after a nasal's, which starts with its murmur)
    to 30 ms after its end; the **onset** its steepest fall between 100 ms before the first
    phone (not before the phone before it starts: a stop's closure is often in the phone before)
    and the release, with the energy floored 25 dB under the neighbourhood's loudest so that the
    fall into a nasal counts as much as the fall into silence (``m b``: the lips shut at the m).
    After a pause the onset cannot be heard: the closure is taken as the 50 ms before the
    release."""
    e = high_band_db(audio, rate)
    lag = max(int(round(0.01 / BAND_STEP)), 1)
    rise = np.zeros(e.size)
    rise[lag:-lag] = e[2 * lag :] - e[: -2 * lag]

    def at(t: float) -> int:
        return int(np.clip(round(t / BAND_STEP), 0, e.size - 1))

    out = []
    i = 0
    while i < len(phones):
        if phones[i].viseme != 1:
            i += 1
            continue
        j = i
        while j + 1 < len(phones) and phones[j + 1].viseme == 1:
            j += 1
        first, last = phones[i], phones[j]
        before = phones[i - 1] if i else None
        k0 = at(max(first.start - 0.1, before.start if before else 0.0))
        k1 = at(last.end + 0.03) + 1
        r0 = min(max(at(last.start + (0.015 if _is_nasal(last.phoneme) else -0.02)), k0), k1 - 1)
        release = r0 + int(np.argmax(rise[r0:k1]))
        if before is None or before.viseme == 0:
            onset_t = release * BAND_STEP - 0.05
        else:
            ref = e[at(first.start - 0.15) : at(last.end + 0.08) + 1].max()
            floored = np.maximum(e, ref - 25.0)
            fall = np.zeros(e.size)
            fall[lag:-lag] = floored[2 * lag :] - floored[: -2 * lag]
            onset_t = (k0 + int(np.argmin(fall[k0 : release + 1]))) * BAND_STEP
        out.append(LipClosure(i, j, onset_t, release * BAND_STEP))
        i = j + 1
    return out
