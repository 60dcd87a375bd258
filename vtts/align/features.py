"""Spectral features for alignment: log-mel cepstra (MFCC) with deltas, cepstral mean normalized.

Why these, and why by hand over SciPy rather than librosa: the features are a few lines of
NumPy over ``scipy.fft`` (librosa would bring numba, llvmlite and scikit-learn, and a second of
JIT start-up, for a mel filter bank and a DCT); the audio is resampled by
``scipy.signal.resample_poly`` (``vtts.speech.audio.resample_in_blocks``).

- Both signals are analysed at one rate, :data:`ANALYSIS_RATE` (or the recording's, when it is
  lower: a telephone recording has nothing above 4 kHz, so the reference must not either).
- Log-mel energies have a floor :data:`FLOOR_DB` below the utterance's loudest frame: espeak-ng's
  pauses are digital zeros, a room's are not, and both must look alike.
- Cepstral mean and variance normalization over the utterance removes most of what the channel
  and the speaker's average spectrum add (the espeak-ng reference and a human voice differ most
  there); deltas add the local direction of change, which boundaries are made of.
"""

from __future__ import annotations

from functools import cache

import numpy as np
from scipy.fft import dct, rfft

#: Rate the features are computed at, Hz (a recording below it is analysed at its own rate).
ANALYSIS_RATE = 16000
#: Lowest recording rate accepted, Hz: below it there is too little of speech's spectrum.
MIN_RATE = 8000
#: Floor of the log-mel energies below the utterance's loudest frame, dB.
FLOOR_DB = 60.0
N_MELS = 26
N_CEPS = 13
WINDOW_S = 0.025


@cache
def mel_filters(rate: int, n_fft: int, n_mels: int = N_MELS) -> np.ndarray:
    """``(n_mels, n_fft // 2 + 1)`` triangular filters, equally spaced on the mel scale from
    60 Hz to 0.95 × Nyquist (HTK's mel: 2595 log10(1 + f / 700))."""

    def mel(f):
        return 2595.0 * np.log10(1.0 + np.asarray(f) / 700.0)

    def hz(m):
        return 700.0 * (10.0 ** (np.asarray(m) / 2595.0) - 1.0)

    edges = hz(np.linspace(mel(60.0), mel(0.95 * rate / 2), n_mels + 2))
    bins = np.fft.rfftfreq(n_fft, 1.0 / rate)
    lo, mid, hi = edges[:-2, None], edges[1:-1, None], edges[2:, None]
    up = (bins - lo) / (mid - lo)
    down = (hi - bins) / (hi - mid)
    return np.maximum(0.0, np.minimum(up, down)).astype(np.float32)


def log_mel(samples: np.ndarray, rate: int, hop: float, window: float = WINDOW_S) -> np.ndarray:
    """``(n_frames, N_MELS)`` float32 log-mel energies (dB-like, floored :data:`FLOOR_DB` below
    the loudest frame) of ``(n,)`` samples at ``rate`` Hz, one frame every ``hop`` s, frame
    ``k`` centred on ``k * hop``."""
    x = np.asarray(samples, dtype=np.float32)
    step = max(1, round(hop * rate))
    win = round(window * rate)
    n_fft = 1 << (win - 1).bit_length()
    n_frames = max(1, int(np.ceil(len(x) / step)))
    padded = np.pad(x, (win // 2, win // 2 + n_frames * step + 1 - len(x)))
    window = np.hamming(win).astype(np.float32)
    out = np.empty((n_frames, N_MELS), np.float32)
    fb = mel_filters(rate, n_fft)
    block = 4096  # frames per block: bounded memory on long audio
    for b in range(0, n_frames, block):
        idx = np.arange(b, min(b + block, n_frames))[:, None] * step + np.arange(win)[None, :]
        spec = np.abs(rfft(padded[idx] * window, n=n_fft, axis=1)) ** 2
        out[b : b + len(idx)] = spec.astype(np.float32) @ fb.T
    db = 10.0 * np.log10(np.maximum(out, 1e-10))
    np.maximum(db, db.max() - FLOOR_DB, out=db)
    return db


def deltas(x: np.ndarray, width: int = 2) -> np.ndarray:
    """``(n, d)`` regression deltas of ``(n, d)`` features over ±``width`` frames."""
    n = len(x)
    padded = np.pad(x, ((width, width), (0, 0)), mode="edge")
    num = sum(
        k * (padded[width + k : width + k + n] - padded[width - k : width - k + n])
        for k in range(1, width + 1)
    )
    return (num / (2 * sum(k * k for k in range(1, width + 1)))).astype(np.float32)


def mfcc(samples: np.ndarray, rate: int, hop: float, *, with_deltas: bool = True) -> np.ndarray:
    """``(n_frames, 2 * N_CEPS)`` (or ``N_CEPS`` without deltas) float32 features: cepstra
    c0–c12 of the log-mel energies, mean and variance normalized over the utterance, then their
    deltas. Frame ``k`` is centred on ``k * hop`` s."""
    return cepstra(log_mel(samples, rate, hop), with_deltas=with_deltas)


def cepstra(db: np.ndarray, *, with_deltas: bool = True) -> np.ndarray:
    """:func:`mfcc` of ``(n_frames, N_MELS)`` log-mel energies already computed."""
    ceps = dct(db, type=2, norm="ortho", axis=1)[:, :N_CEPS]
    ceps = normalize(ceps)
    if not with_deltas:
        return ceps
    return np.hstack([ceps, normalize(deltas(ceps))])


def normalize(x: np.ndarray) -> np.ndarray:
    """``(n, d)`` features less their mean, divided by their standard deviation (per column)."""
    x = np.asarray(x, dtype=np.float32)
    return ((x - x.mean(axis=0)) / (x.std(axis=0) + 1e-6)).astype(np.float32)


#: Fraction of the speech frames that must be voiced for a recording to have a pitch (speech:
#: 0.5-0.8; white and coloured noise: under 0.1).
MIN_VOICED = 0.2


def median_f0(samples: np.ndarray, rate: int, speech: np.ndarray, hop: float) -> float | None:
    """Median fundamental frequency (Hz) of the voiced frames among ``speech`` (``(n_frames,)``
    bool at ``hop`` s), by the peak of the normalized autocorrelation of 40 ms windows within
    70–400 Hz; None when fewer than :data:`MIN_VOICED` of them are voiced (a peak above 0.5)."""
    x = np.asarray(samples, dtype=np.float32)
    step = round(hop * rate)
    win = round(0.04 * rate)
    frames = np.flatnonzero(speech)
    if len(frames) > 400:  # a sample of the speech is enough for a median
        frames = frames[:: len(frames) // 400]
    starts = frames * step - win // 2
    starts = starts[(starts >= 0) & (starts + win <= len(x))]
    if len(starts) < 5:
        return None
    seg = x[starts[:, None] + np.arange(win)[None, :]]
    seg = seg - seg.mean(axis=1, keepdims=True)
    spec = rfft(seg, n=2 * win, axis=1)
    ac = np.fft.irfft(np.abs(spec) ** 2, axis=1)[:, :win]
    ac /= np.maximum(ac[:, :1], 1e-12)
    lo, hi = int(rate / 400), int(rate / 70)
    lag = lo + np.argmax(ac[:, lo:hi], axis=1)
    peak = ac[np.arange(len(lag)), lag]
    # a peak, not the slope of a noise's autocorrelation falling from lag 0 (coloured noise)
    dip = np.array([ac[k, lo : lag[k] + 1].min() for k in range(len(lag))])
    voiced = (peak > 0.5) & (lag > lo) & (peak - dip > 0.1)
    if voiced.sum() < max(5, MIN_VOICED * len(voiced)):
        return None
    return float(np.median(rate / lag[voiced]))
