"""Boundary refinement: a Viterbi pass of the phone sequence over the recording, with models of
the recording's own voice.

After the warping, the recording's frames under each phone are a (rough) sample of how *this*
voice says it. Each phone becomes three states (onset, middle, offset; a pause one), and each
state a mean feature vector: the mean of the recording's frames the current alignment gives it
over every occurrence of the same phoneme, shrunk towards the mean of its viseme class when it
has few frames. With one diagonal variance for all, the cost of a frame in a state is its
squared Mahalanobis distance to the mean. The best left-to-right path through the states,
every state at least one frame, each within :data:`WINDOW` s of where the warping put its phone,
gives new boundaries; the models are re-estimated from them and the pass repeated.

The recursion runs over states, each a vectorized step over its window of frames (as the rows
of :mod:`vtts.align.dtw`): ``D[s, t] = c[s, t] + min(D[s, t-1], D[s-1, t-1])`` is
``S[t] + min_{k ≤ t}(D[s-1, k-1] + c[s, k] − S[k])`` with ``S`` the running sum of ``c[s, ·]``;
the ``k`` of the minimum is where state ``s`` was entered.
"""

from __future__ import annotations

import numpy as np

from vtts.align.features import mfcc
from vtts.speech.phonemes import PAUSES, Phone

#: Frame step, s.
HOP = 0.005
#: How far a phone may move from where the warping put it, s.
WINDOW = 0.06
#: Passes of re-estimation and Viterbi.
PASSES = 2
#: Weight of the viseme class's mean against a phoneme's own frames, in frames.
SHRINK = 8.0
#: States of a phone (a pause has one).
STATES = 3


def refine_phones(
    phones: list[Phone], samples: np.ndarray, rate: int, duration: float, *, passes: int = PASSES
) -> list[Phone]:
    """Better boundaries for ``phones`` (covering ``(n,)`` float ``samples`` at ``rate`` Hz from
    0 to ``duration`` s); the phones, their order and visemes stay. See the module docstring."""
    x = mfcc(samples, rate, HOP)
    n = len(x)
    is_pause = np.array([p.phoneme in PAUSES for p in phones])
    per = np.where(is_pause, 1, STATES)
    owner = np.repeat(np.arange(len(phones)), per)  # phone of each state
    sub = np.concatenate([np.arange(k) for k in per])  # its place in the phone
    label = _labels(phones, owner, sub)
    klass = np.array(
        [(phones[k].viseme or 0) * STATES + s for k, s in zip(owner, sub, strict=True)]
    )
    bounds = _to_frames([p.start for p in phones], n)
    win = max(1, round(WINDOW / HOP))
    for _ in range(passes):
        state_start = _split(bounds, per, n)
        means, inv_var = _models(x, state_start, label, klass)
        lo, hi = _windows(bounds, per, owner, win, n)
        found = _viterbi(x, means, inv_var, lo, hi)
        if found is None:
            break
        bounds = found[np.searchsorted(owner, np.arange(len(phones)))]
    starts = bounds * HOP
    starts[0] = 0.0
    starts = np.minimum(starts, duration)
    ends = np.append(starts[1:], duration)
    return [
        Phone(float(s), float(e), p.phoneme, p.viseme, p.ipa)
        for p, s, e in zip(phones, starts, ends, strict=True)
    ]


def _labels(phones: list[Phone], owner: np.ndarray, sub: np.ndarray) -> np.ndarray:
    names: dict[tuple[str, int], int] = {}
    out = np.empty(len(owner), np.int64)
    for i, (k, s) in enumerate(zip(owner, sub, strict=True)):
        p = phones[k]
        key = ("_", 0) if p.phoneme in PAUSES else (p.phoneme, int(s))
        out[i] = names.setdefault(key, len(names))
    return out


def _to_frames(times: list[float], n: int) -> np.ndarray:
    f = np.round(np.asarray(times) / HOP).astype(np.int64)
    f = np.clip(np.maximum.accumulate(f), 0, n)
    f[0] = 0
    return f


def _split(bounds: np.ndarray, per: np.ndarray, n: int) -> np.ndarray:
    """Start frame of every state: each phone's frames shared evenly by its states."""
    ends = np.append(bounds[1:], n)
    out = []
    for b, e, k in zip(bounds, ends, per, strict=True):
        out.extend(b + (e - b) * np.arange(k) / k)
    return np.round(np.array(out)).astype(np.int64)


def _models(x, state_start, label, klass):
    """Mean ``(n_states, d)`` of every state (by label, shrunk to its class) and the inverse of
    the pooled diagonal variance ``(d,)``."""
    n, d = x.shape
    n_states = len(state_start)
    frame_state = np.repeat(np.arange(n_states), np.diff(np.append(state_start, n)).clip(0))
    frame_state = frame_state[:n]
    cs = np.zeros((n_states, d))
    np.add.at(cs, frame_state, x[: len(frame_state)])
    cnt = np.bincount(frame_state, minlength=n_states).astype(float)

    def pooled(keys):
        s = np.zeros((keys.max() + 1, d))
        c = np.zeros(keys.max() + 1)
        np.add.at(s, keys, cs)
        np.add.at(c, keys, cnt)
        return s, c

    ls, lc = pooled(label)
    ks, kc = pooled(klass)
    kmean = ks / np.maximum(kc, 1e-9)[:, None]
    kmean[kc == 0] = 0.0
    means = (ls[label] + SHRINK * kmean[klass]) / (lc[label] + SHRINK)[:, None]
    resid = x[: len(frame_state)] - means[frame_state]
    var = (resid**2).mean(axis=0) + 1e-3
    return means.astype(np.float32), (1.0 / var).astype(np.float32)


def _windows(bounds, per, owner, win, n):
    """Frames ``[lo, hi)`` each state may occupy: its phone's frames widened by ``win``."""
    ends = np.append(bounds[1:], n)
    lo = np.maximum(bounds[owner] - win, 0)
    hi = np.minimum(ends[owner] + win, n)
    # a state needs room for itself and the states before/after it
    idx = np.arange(len(owner))
    lo = np.maximum(np.minimum(lo, n - (len(owner) - idx)), 0)
    lo = np.maximum.accumulate(np.minimum(lo, idx * 0 + lo))
    hi = np.minimum.accumulate(np.maximum(hi, idx + 1)[::-1])[::-1]
    hi = np.maximum(hi, lo + 1)
    lo[0], hi[-1] = 0, n
    return lo, hi


def _viterbi(x, means, inv_var, lo, hi):
    """Start frame of each state on the best path, or None when the windows allow none."""
    n_states = len(means)
    prev_d = None
    prev_lo = prev_hi = 0
    entries = []
    for s in range(n_states):
        a, b = int(lo[s]), int(hi[s])
        diff = x[a:b] - means[s]
        c = (diff * diff) @ inv_var
        cs = np.cumsum(c, dtype=np.float64)
        if s == 0:
            d = cs.copy()
            entry = np.zeros(b - a, np.int64)
        else:
            # D[s-1, t-1] for t in [a, b)
            come = np.full(b - a, np.inf)
            t0, t1 = max(a, prev_lo + 1), min(b, prev_hi + 1)
            if t1 > t0:
                come[t0 - a : t1 - a] = prev_d[t0 - 1 - prev_lo : t1 - 1 - prev_lo]
            vals = come + c - cs
            run = np.minimum.accumulate(vals)
            d = cs + run
            pos = np.where(vals <= run, np.arange(b - a), 0)
            entry = a + np.maximum.accumulate(pos)
        entries.append((a, entry))
        prev_d, prev_lo, prev_hi = d, a, b
    n = len(x)
    if prev_hi != n or not np.isfinite(prev_d[-1]):
        return None
    starts = np.empty(n_states, np.int64)
    t = n - 1
    for s in range(n_states - 1, -1, -1):
        a, entry = entries[s]
        if not a <= t < a + len(entry):
            return None
        starts[s] = entry[t - a]
        t = starts[s] - 1
    if starts[0] != 0:
        return None
    return starts
