"""Visemes classified frame by frame from the sound: a small network trained on synthetic speech.

Each 10 ms frame (frame ``k`` spans ``[k, k + 1) * FRAME_S`` s, its 25 ms window centred on the
frame's middle, as :func:`vtts.speech.energy.energy_frames`) gets :data:`N_MELS` log-mel band
levels (dB) at 16 kHz. They are made independent of the recording's level and channel: floored
at :data:`FLOOR_DB` below the loud frames (their 90th percentile), then each band's mean over the
audible frames (within :data:`AUDIBLE_DB` of the loud ones) subtracted, with one more feature,
the frame's level against the loud frames. The features of the frames at :data:`OFFSETS` around
each frame are stacked (the ends repeat the first and last frame) and a multilayer perceptron
(ReLU hidden layers, softmax out) gives the frame's probability of each of the 15 visemes; where
the file holds several such networks (the same data, other seeds: an ensemble), their log
probabilities are averaged and normalized again (the geometric mean of their probabilities).
A recording's features are made with the mel filters' edges scaled by each of :data:`WARPS`
(vocal tract length normalisation, no retraining), with the band levels as they are and with
each band's noise floor subtracted, and those the network is surest of are kept
(:meth:`VisemeClassifier.warped_log_posteriors`). :func:`smooth` then finds the likeliest
viseme sequence in which each viseme lasts at least its minimum number of frames and every
change costs a penalty (Viterbi over a chain of states per viseme).

The weights, the feature standardization and the smoothing's parameters are one ``.npz`` file,
``vtts/data/viseme_classifier.npz``, made by ``scripts/train_viseme_classifier.py`` (seeded:
the same file from the same packages) from espeak-ng's and festival's speech of generated
sentences with their exact phone times. Inference is numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from vtts.errors import SpeechError

__all__ = [
    "N_MELS",
    "OFFSETS",
    "RATE",
    "WARPS",
    "Network",
    "VisemeClassifier",
    "entropies",
    "frame_features",
    "load_classifier",
    "noise_subtracted",
    "smooth",
    "warped_features",
]

#: Rate of the audio the features are made from, Hz.
RATE = 16000
#: Frame step and analysis window, samples at :data:`RATE` (10 ms and 25 ms).
HOP = 160
WINDOW = 400
N_FFT = 512
#: Mel bands between :data:`FMIN` and :data:`FMAX` Hz.
N_MELS = 40
FMIN = 60.0
FMAX = 7600.0
#: Band levels are floored this many dB below the loud frames' level.
FLOOR_DB = 70.0
#: Frames within this many dB of the loud frames give the band means.
AUDIBLE_DB = 35.0
#: Frames (relative to the one classified) whose features are stacked.
OFFSETS = (-12, -8, -5, -3, -2, -1, 0, 1, 2, 3, 5, 8, 12)
#: Frequency warps tried on each recording (vocal tract length normalisation): the mel bands'
#: edges scaled by each; the warp whose network is surest (its mean top probability over the
#: audible frames) is taken when it beats the unwarped features' by at least
#: :data:`WARP_MARGIN` — a voice with shorter or longer vocal tract than the training voices'
#: (a child's, a high woman's) is heard as one of theirs.
WARPS = (0.88, 0.94, 1.0, 1.06, 1.12)
WARP_MARGIN = 0.03
#: Noise taken out of the band levels (:func:`noise_subtracted`): each band's power at this
#: percentile of the frames (its noise floor) is subtracted, leaving at least NOISE_KEEP of it;
#: the features so made are kept where the network is surer of them by DENOISE_MARGIN.
NOISE_PERCENTILE = 10.0
NOISE_KEEP = 0.3
DENOISE_MARGIN = 0.01
#: Frames over which the network's entropy is averaged for the other recognizer's weight
#: (:meth:`VisemeClassifier.evidence_weights`).
ENTROPY_FRAMES = 11
#: Frames per block of inference (bounded memory for long files).
BLOCK = 4096
#: The product's weights, a file of the package's data.
WEIGHTS = "viseme_classifier.npz"


def _mel_filters(warp: float = 1.0) -> np.ndarray:
    """``(N_MELS, N_FFT // 2 + 1)`` float32 triangular filters on the HTK mel scale, their
    edges (Hz) times ``warp`` (above 1: each band hears higher frequencies, as the training
    voices' band would a higher voice's)."""
    mel = lambda f: 2595.0 * np.log10(1.0 + f / 700.0)  # noqa: E731
    hz = lambda m: 700.0 * (10.0 ** (m / 2595.0) - 1.0)  # noqa: E731
    edges = warp * hz(np.linspace(mel(FMIN), mel(FMAX), N_MELS + 2))
    freqs = np.fft.rfftfreq(N_FFT, 1.0 / RATE)
    out = np.zeros((N_MELS, freqs.size), np.float32)
    for i in range(N_MELS):
        lo, mid, hi = edges[i : i + 3]
        up = (freqs - lo) / (mid - lo)
        down = (hi - freqs) / (hi - mid)
        out[i] = np.maximum(0.0, np.minimum(up, down))
    return out


@cache
def _filters(warps: tuple[float, ...]) -> np.ndarray:
    """``(len(warps) * N_MELS, N_FFT // 2 + 1)`` the filters of each warp, one after another."""
    return np.concatenate([_mel_filters(w) for w in warps])


@cache
def _window() -> np.ndarray:
    return np.hanning(WINDOW).astype(np.float32)


def band_levels(
    samples: np.ndarray, warps: tuple[float, ...] = (1.0,)
) -> tuple[np.ndarray, np.ndarray]:
    """Per 10 ms frame of ``(n,)`` float32 samples at :data:`RATE` in [-1, 1]: ``(len(warps),
    frames, N_MELS)`` float32 band levels (dB) of the filters of each warp
    (:func:`_mel_filters`; one spectrum for all) and ``(frames,)`` float32 frame level (dB);
    ``ceil(n / HOP)`` frames, computed in blocks."""
    x = np.asarray(samples, np.float32)
    filters, window = _filters(tuple(warps)), _window()
    n_frames = -(-len(x) // HOP)
    padded = np.pad(x, (WINDOW // 2 - HOP // 2, WINDOW))
    bands = np.empty((n_frames, len(warps) * N_MELS), np.float32)
    level = np.empty(n_frames, np.float32)
    for a in range(0, n_frames, BLOCK):
        b = min(a + BLOCK, n_frames)
        idx = (np.arange(a, b) * HOP)[:, None] + np.arange(WINDOW)[None, :]
        spec = np.abs(np.fft.rfft(padded[idx] * window, N_FFT)) ** 2
        bands[a:b] = 10.0 * np.log10(spec @ filters.T + 1e-10)
        level[a:b] = 10.0 * np.log10(spec.sum(axis=1) + 1e-10)
    return bands.reshape(n_frames, len(warps), N_MELS).transpose(1, 0, 2), level


def noise_subtracted(bands: np.ndarray) -> np.ndarray:
    """Band levels ``(..., frames, N_MELS)`` dB with each band's noise taken out: its power at
    the :data:`NOISE_PERCENTILE` th percentile of the frames subtracted from every frame's,
    keeping at least :data:`NOISE_KEEP` of that noise power (spectral subtraction)."""
    power = 10.0 ** (bands.astype(np.float64) / 10.0)
    noise = np.percentile(power, NOISE_PERCENTILE, axis=-2, keepdims=True)
    clean = np.maximum(power - noise, NOISE_KEEP * noise)
    return (10.0 * np.log10(clean + 1e-10)).astype(np.float32)


def _features(bands: np.ndarray, level: np.ndarray) -> np.ndarray:
    """``(w, frames, N_MELS + 1)`` features from ``(w, frames, N_MELS)`` band levels and
    ``(frames,)`` frame levels (dB; see the module docstring)."""
    w = bands.shape[0]
    if level.size == 0:
        return np.zeros((w, 0, N_MELS + 1), np.float32)
    loud = float(np.percentile(level, 90))
    bands = np.maximum(bands, loud - FLOOR_DB - 10.0 * np.log10(N_MELS))
    level = np.maximum(level, loud - FLOOR_DB)
    audible = level > loud - AUDIBLE_DB
    mean = bands[:, audible].mean(axis=1) if np.any(audible) else bands.mean(axis=1)
    rel = np.broadcast_to((level - loud)[None, :, None], (w, level.size, 1))
    return np.concatenate([bands - mean[:, None, :], rel], axis=2).astype(np.float32)


def warped_features(
    samples: np.ndarray, warps: tuple[float, ...], denoise: bool = False
) -> np.ndarray:
    """``(len(warps), frames, N_MELS + 1)`` float32 :func:`frame_features` of ``(n,)`` samples
    with the mel filters of each warp (:func:`_mel_filters`); ``denoise``: the band levels
    :func:`noise_subtracted` first."""
    bands, level = band_levels(samples, warps)
    return _features(noise_subtracted(bands) if denoise else bands, level)


def frame_features(samples: np.ndarray, warp: float = 1.0) -> np.ndarray:
    """``(frames, N_MELS + 1)`` float32 features of ``(n,)`` samples at :data:`RATE` (see the
    module docstring): band levels less their mean over the audible frames, and the frame's
    level against the loud frames, dB; ``warp``: of the mel filters (:func:`_mel_filters`)."""
    return warped_features(samples, (warp,))[0]


def stack(features: np.ndarray, a: int, b: int) -> np.ndarray:
    """``(b - a, len(OFFSETS) * d)`` the features of frames ``a..b`` with their neighbours at
    :data:`OFFSETS` (indices clipped to the ends)."""
    n = features.shape[0]
    rows = np.clip(np.arange(a, b)[:, None] + np.asarray(OFFSETS)[None, :], 0, n - 1)
    return features[rows].reshape(b - a, -1)


@dataclass(frozen=True)
class Network:
    """One trained perceptron.

    mean, scale   ``(d,)`` float32 standardization of the stacked features
    weights       per layer ``(d_in, d_out)`` float32; ``biases`` per layer ``(d_out,)``
    """

    mean: np.ndarray
    scale: np.ndarray
    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]

    def scores(self, stacked: np.ndarray) -> np.ndarray:
        """``(frames, 15)`` float32 output scores (before the softmax) of :func:`stack`'s
        ``(frames, d)`` stacked features."""
        h = (stacked - self.mean) / self.scale
        for k, (w, c) in enumerate(zip(self.weights, self.biases, strict=True)):
            h = h @ w + c
            if k < len(self.weights) - 1:
                np.maximum(h, 0.0, out=h)
        return h

    def log_posteriors(self, features: np.ndarray) -> np.ndarray:
        """``(frames, 15)`` float32 log probabilities of each viseme from :func:`frame_features`
        ``(frames, d)``."""
        return _log_posteriors((self,), features)


def _log_posteriors(networks: tuple[Network, ...], features: np.ndarray) -> np.ndarray:
    """``(frames, 15)`` float32 log probabilities from ``(frames, d)`` features: the network's,
    or the normalized mean of several networks' (an ensemble), in blocks of :data:`BLOCK`
    frames, each block's features stacked once for all the networks."""
    n = features.shape[0]
    out = np.empty((n, 15), np.float32)
    for a in range(0, n, BLOCK):
        b = min(a + BLOCK, n)
        stacked = stack(features, a, b)
        each = [_normalized(net.scores(stacked)) for net in networks]
        out[a:b] = each[0] if len(each) == 1 else _normalized(np.mean(each, axis=0))
    return out


def _normalized(scores: np.ndarray) -> np.ndarray:
    """``(frames, 15)`` scores as log probabilities (log-softmax per frame)."""
    h = scores - scores.max(axis=1, keepdims=True)
    return h - np.log(np.exp(h).sum(axis=1, keepdims=True))


@dataclass(frozen=True)
class VisemeClassifier:
    """The trained network and its smoothing (see the module docstring).

    networks      the trained :class:`Network` s (one, or several of an ensemble)
    log_prior     ``(15,)`` float32 log share of each viseme in the training frames
    prior_weight  how much of the log prior is taken from the log posteriors (scaled
                  likelihoods: 1 removes it whole)
    min_frames    ``(15,)`` int, the fewest frames a viseme lasts
    switch        the cost of a change of viseme, in log probability
    bias          ``(15,)`` float32 added to each viseme's score (log probability)
    boost         ``(15,)`` float32 added to each viseme's score times the network's
                  probability of it: a lower threshold where the network hears the viseme
                  (p b m: a closure it is fairly sure of is kept against the other
                  recognizer's evidence)
    evidence      what a viseme another recognizer gives a frame adds to that viseme's score
                  there (PocketSphinx's, :func:`vtts.speech.recognize.recognize`), plus
    evidence_per_nat  times the entropy (nats) of the network's probabilities, averaged over
                  the :data:`ENTROPY_FRAMES` frames around: the other recognizer weighs more
                  where the network is unsure (natural speech, noise), less where it is sure
    """

    networks: tuple[Network, ...]
    log_prior: np.ndarray
    prior_weight: float
    min_frames: np.ndarray
    switch: float
    bias: np.ndarray
    boost: np.ndarray
    evidence: float
    evidence_per_nat: float

    def log_posteriors(self, features: np.ndarray) -> np.ndarray:
        """``(frames, 15)`` float32 log probabilities of each viseme from :func:`frame_features`
        ``(frames, d)``: the network's, or the normalized mean of the ensemble's."""
        return _log_posteriors(self.networks, features)

    def warped_log_posteriors(self, samples: np.ndarray) -> tuple[np.ndarray, float, bool]:
        """``(ceil(n / HOP), 15)`` float32 log probabilities of ``(n,)`` float32 samples at
        :data:`RATE` from the features the network is surest of — its mean top probability
        over the audible frames (within :data:`AUDIBLE_DB` of the loud ones): of the warps of
        :data:`WARPS`, one that beats the unwarped features by at least :data:`WARP_MARGIN`
        (else unwarped), and of the band levels as they are or :func:`noise_subtracted`, the
        latter where they beat the former by at least :data:`DENOISE_MARGIN`; and the warp and
        whether the noise was subtracted."""
        bands, level = band_levels(samples, WARPS)
        log_p, warp, sure = self._surest(_features(bands, level))
        clean_log_p, clean_warp, clean_sure = self._surest(
            _features(noise_subtracted(bands), level)
        )
        if clean_sure >= sure + DENOISE_MARGIN:
            return clean_log_p, clean_warp, True
        return log_p, warp, False

    def _surest(self, features: np.ndarray) -> tuple[np.ndarray, float, float]:
        """Of ``(len(WARPS), frames, d)`` features, the warp's log probabilities ``(frames,
        15)`` the network is surest of (by :data:`WARP_MARGIN` over the unwarped), the warp and
        the mean top probability over the audible frames (0 where none is audible)."""
        plain = WARPS.index(1.0)
        audible = features[plain, :, -1] > -AUDIBLE_DB
        best, best_log_p = 1.0, self.log_posteriors(features[plain])
        if not np.any(audible):
            return best_log_p, best, 0.0
        plain_sure = float(np.exp(best_log_p[audible].max(axis=1)).mean())
        best_sure = plain_sure
        for warp, f in zip(WARPS, features, strict=True):
            if warp == 1.0:
                continue
            log_p = self.log_posteriors(f)
            sure = float(np.exp(log_p[audible].max(axis=1)).mean())
            if sure >= plain_sure + WARP_MARGIN and sure > best_sure:
                best, best_log_p, best_sure = warp, log_p, sure
        return best_log_p, best, best_sure

    def visemes(self, samples: np.ndarray, other: np.ndarray | None = None) -> np.ndarray:
        """``(ceil(n / HOP),)`` int8 smoothed visemes of ``(n,)`` float32 samples at
        :data:`RATE` (their features warped as :meth:`warped_log_posteriors` chooses);
        ``other``: as :meth:`smoothed`'s."""
        return self.smoothed(self.warped_log_posteriors(samples)[0], other)

    def smoothed(
        self, log_p: np.ndarray, other: np.ndarray | None = None, evidence: float | None = None
    ) -> np.ndarray:
        """``(frames,)`` int8 visemes smoothed (:func:`smooth`) from the network's ``(frames,
        15)`` log probabilities; ``other``: ``(frames,)`` int visemes another recognizer gave
        the frames (each adds :meth:`evidence_weights` to its viseme's score, with
        ``evidence`` in place of :attr:`evidence` when given)."""
        scores = log_p + self.bias - self.prior_weight * self.log_prior
        scores += self.boost * np.exp(log_p)
        if other is not None:
            m = min(other.size, scores.shape[0])
            weights = self.evidence_weights(log_p, evidence)[:m]
            scores[np.arange(m), np.asarray(other[:m], int)] += weights
        return smooth(scores, self.min_frames, self.switch)

    def evidence_weights(self, log_p: np.ndarray, evidence: float | None = None) -> np.ndarray:
        """``(frames,)`` what another recognizer's viseme adds to a frame's score:
        :attr:`evidence` (or ``evidence``) plus :attr:`evidence_per_nat` times the entropy
        (nats) of the network's probabilities from ``(frames, 15)`` ``log_p``, averaged over
        the :data:`ENTROPY_FRAMES` frames around each."""
        from scipy.ndimage import uniform_filter1d

        entropy = entropies(log_p)
        if entropy.size:
            entropy = uniform_filter1d(entropy, ENTROPY_FRAMES)
        base = self.evidence if evidence is None else evidence
        return base + self.evidence_per_nat * entropy


def entropies(log_p: np.ndarray) -> np.ndarray:
    """``(frames,)`` the entropy (nats) of each frame's probabilities, from ``(frames, 15)``
    log probabilities."""
    return -(np.exp(log_p) * log_p).sum(axis=1)


def smooth(scores: np.ndarray, min_frames: np.ndarray, switch: float) -> np.ndarray:
    """The viseme sequence ``(frames,)`` int8 maximizing the sum of ``scores`` ``(frames, 15)``
    (log likelihoods) less ``switch`` per change, each viseme ``v`` lasting at least
    ``min_frames[v]`` frames (the first and last runs may be shorter): Viterbi over a chain of
    ``min_frames[v]`` states per viseme, the last looping."""
    n, k = scores.shape
    if n == 0:
        return np.zeros(0, np.int8)
    m = np.maximum(np.asarray(min_frames, int), 1)
    owner = np.repeat(np.arange(k), m)  # the viseme of each state
    first = np.concatenate([[0], np.cumsum(m)[:-1]])
    last = first + m - 1
    s = owner.size
    inner = np.setdiff1d(np.arange(s), first)  # states entered from the state before
    delta = np.full(s, -np.inf)
    delta[first] = scores[0]
    delta[last] = scores[0]  # the first run may be short
    back = np.zeros((n, s), np.int32)
    idx = np.arange(s)
    sc = scores.astype(np.float64)
    for t in range(1, n):
        ends = delta[last]
        order = np.argsort(ends)
        best, second = order[-1], order[-2]
        # entering v from the best end of another viseme
        src = np.where(np.arange(k) == best, last[second], last[best])
        new = np.empty(s)
        bp = idx.copy()
        new[first] = delta[src] - switch
        bp[first] = src
        new[inner] = delta[inner - 1]
        bp[inner] = inner - 1
        stay = delta[last] >= new[last]
        new[last] = np.where(stay, delta[last], new[last])
        bp[last] = np.where(stay, last, bp[last])
        delta = new + sc[t, owner]
        back[t] = bp
    # the last run may be short: end in any state
    state = int(np.argmax(delta))
    out = np.empty(n, np.int8)
    for t in range(n - 1, -1, -1):
        out[t] = owner[state]
        state = back[t, state]
    return out


@cache
def load_classifier(path: Path | None = None) -> VisemeClassifier:
    """The classifier in ``path`` (``vtts/data/viseme_classifier.npz`` by default);
    :class:`SpeechError` naming the file when it is missing or not one."""
    if path is None:
        from vtts.resources import package_data

        path = package_data(WEIGHTS)
    try:
        with np.load(path) as z:
            layers = int(z["layers"])
            count = int(z["networks"]) if "networks" in z.files else 1

            def network(j: int) -> Network:
                key = "" if j == 0 else f"n{j}_"  # the first network's keys are unprefixed
                return Network(
                    mean=z[f"{key}mean"].astype(np.float32),
                    scale=z[f"{key}scale"].astype(np.float32),
                    weights=tuple(z[f"{key}w{i}"].astype(np.float32) for i in range(layers)),
                    biases=tuple(z[f"{key}b{i}"].astype(np.float32) for i in range(layers)),
                )

            return VisemeClassifier(
                networks=tuple(network(j) for j in range(count)),
                log_prior=z["log_prior"].astype(np.float32),
                prior_weight=float(z["prior_weight"]),
                min_frames=z["min_frames"].astype(int),
                switch=float(z["switch"]),
                bias=z["bias"].astype(np.float32),
                boost=z["boost"].astype(np.float32),
                evidence=float(z["evidence"]),
                evidence_per_nat=float(z["evidence_per_nat"]),
            )
    except (OSError, KeyError, ValueError) as e:
        raise SpeechError(f"{path}: not a viseme classifier's weights ({e})") from None
