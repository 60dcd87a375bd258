"""Mouth shapes from the voice's energy and spectrum alone: the fallback of recognized speech.

Where no phone is recognized in audible sound (music, noise, a language the recognizer does not
know, a sound it takes for silence) the face must still not freeze over it. Each 10 ms frame is
classed by its loudness against the sound's loud frames and its noise floor, and by how much of
its energy lies above :data:`HISS_HZ`:

- not audible (within :data:`ABOVE_FLOOR_DB` of a quiet floor, or :data:`RANGE_DB` below the
  loud frames, or under :data:`SILENT_DBFS`): viseme 0;
- mostly high frequencies (a hiss: s, sh, f, a cymbal): viseme 7 (s z, the teeth together);
- otherwise open by loudness: viseme 10 (A:, wide) within :data:`WIDE_DB` of the loud frames,
  11 (e, half) within :data:`HALF_DB`, else 12 (I, slightly).

That is what cheap lip-sync does (the mouth follows the level); ``bench/bench_lipsync_audio.py``
measures it as the energy-only baseline against the recognizer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FRAME_S", "EnergyFrames", "Levels", "energy_frames", "energy_visemes", "levels"]

#: Frame step, s (the recognizer's too).
FRAME_S = 0.010
#: Analysis window, s.
WINDOW_S = 0.025
#: A frame is audible within this many dB of the loud frames (their 90th percentile) …
RANGE_DB = 35.0
#: … and this many dB above the noise floor (the quiet frames' 5th percentile), unless the
#: sound is steady — its loud frames within STEADY_DB of its floor — and louder than
#: LOUD_FLOOR_DBFS: then the floor is the sound itself (music), not a room …
ABOVE_FLOOR_DB = 8.0
STEADY_DB = 15.0
LOUD_FLOOR_DBFS = -35.0
#: … and above this level, dB relative to a full-scale sine's power (digital silence and dither).
SILENT_DBFS = -70.0
#: Wide open within this many dB of the loud frames, half open within HALF_DB.
WIDE_DB = 8.0
HALF_DB = 18.0
#: A frame is a hiss when more than HISS_SHARE of its energy lies above HISS_HZ.
HISS_HZ = 3500.0
HISS_SHARE = 0.5
#: Frames per block when computing frame features (bounded memory for long files).
_BLOCK_FRAMES = 6000


@dataclass(frozen=True)
class EnergyFrames:
    """Per 10 ms frame ``k`` (spanning ``[k, k + 1) * FRAME_S`` s): ``db`` ``(n,)`` float32
    power in dB relative to full scale (a full-scale sine is 0 dB) and ``hiss`` ``(n,)``
    float32, the share 0–1 of the frame's power above :data:`HISS_HZ`."""

    db: np.ndarray
    hiss: np.ndarray


@dataclass(frozen=True)
class Levels:
    """What the frames are judged against, dB: ``loud`` (the loud frames' level) and ``floor``
    (the noise floor)."""

    loud: float
    floor: float

    @property
    def steady(self) -> bool:
        """The sound is steady and loud (music, loud noise): its loud frames within
        :data:`STEADY_DB` of its floor, the floor above :data:`LOUD_FLOOR_DBFS`."""
        return self.loud - self.floor < STEADY_DB and self.floor > LOUD_FLOOR_DBFS

    @property
    def audible(self) -> float:
        """The level above which a frame is audible, dB."""
        floor = SILENT_DBFS if self.steady else self.floor + ABOVE_FLOOR_DB
        return max(self.loud - RANGE_DB, floor, SILENT_DBFS)


def energy_frames(samples: np.ndarray, rate: int) -> EnergyFrames:
    """:class:`EnergyFrames` of ``(n,)`` float samples in [-1, 1] at ``rate`` Hz: one frame per
    :data:`FRAME_S` (``ceil(n / (rate * FRAME_S))`` of them; frame ``k`` spans ``[k, k + 1) *
    FRAME_S``), each a Hann-windowed :data:`WINDOW_S` centred on its frame's middle (zeros
    beyond the ends); computed in blocks, so memory stays bounded for long files."""
    x = np.asarray(samples, dtype=np.float32)
    hop = max(int(round(rate * FRAME_S)), 1)
    win = max(int(round(rate * WINDOW_S)), 2)
    n_frames = -(-len(x) // hop)
    n_fft = 1 << int(np.ceil(np.log2(win)))
    window = np.hanning(win).astype(np.float32)
    freqs = np.fft.rfftfreq(n_fft, 1.0 / rate)
    high = freqs >= HISS_HZ
    # a full-scale sine's mean power through the window is 0 dB
    norm = 0.5 * float(np.sum(window**2)) * n_fft / 2
    padded = np.pad(x, (max(win // 2 - hop // 2, 0), win))
    db = np.empty(n_frames, np.float32)
    hiss = np.empty(n_frames, np.float32)
    for a in range(0, n_frames, _BLOCK_FRAMES):
        b = min(a + _BLOCK_FRAMES, n_frames)
        idx = (np.arange(a, b) * hop)[:, None] + np.arange(win)[None, :]
        spec = np.abs(np.fft.rfft(padded[idx] * window, n_fft)) ** 2
        total = spec.sum(axis=1)
        db[a:b] = 10.0 * np.log10(total / norm + 1e-12)
        hiss[a:b] = spec[:, high].sum(axis=1) / np.maximum(total, 1e-20)
    return EnergyFrames(db, hiss)


def levels(db: np.ndarray) -> Levels:
    """The :class:`Levels` of a whole sound from its frames' ``(n,)`` dB."""
    if db.size == 0:
        return Levels(SILENT_DBFS, SILENT_DBFS)
    loud, floor = np.percentile(db, [90, 5])
    return Levels(float(loud), float(floor))


def energy_visemes(frames: EnergyFrames, lv: Levels | None = None) -> np.ndarray:
    """``(n,)`` int8 viseme per frame (0, 7, 10, 11 or 12; see the module docstring), judged
    against ``lv`` (None: the frames' own :func:`levels`). Runs shorter than three frames take
    their neighbours' viseme, so the mouth does not flicker."""
    lv = levels(frames.db) if lv is None else lv
    db = frames.db
    vis = np.full(db.shape, 12, np.int8)
    vis[db > lv.loud - HALF_DB] = 11
    vis[db > lv.loud - WIDE_DB] = 10
    vis[frames.hiss > HISS_SHARE] = 7
    vis[db <= lv.audible] = 0
    return _steady(vis)


def _steady(vis: np.ndarray, shortest: int = 3) -> np.ndarray:
    """``vis`` with runs shorter than ``shortest`` frames given the viseme of the run before
    (the first run: of the run after)."""
    if vis.size == 0:
        return vis
    out = vis.copy()
    edges = np.flatnonzero(np.diff(out)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [out.size]])
    for s, e in zip(starts, ends, strict=True):
        if e - s < shortest:
            if s > 0:
                out[s:e] = out[s - 1]
            elif e < out.size:
                out[s:e] = out[e]
    return out
