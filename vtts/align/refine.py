"""Boundary refinement: a Viterbi pass of the phone sequence over the recording, with models of
the recording's own voice.

After the warping, the recording's frames under each phone are a (rough) sample of how *this*
voice says it. Each phone becomes three states (onset, middle, offset; a pause one), and each
state a mean feature vector: the mean of the recording's frames the current alignment gives it
over every occurrence of the same phoneme, shrunk towards the mean of its viseme class when it
has few frames. With one diagonal variance for all, the cost of a frame in a state is its
squared Mahalanobis distance to the mean. The best left-to-right path through the states,
every state at least one frame, each within :data:`WINDOW` s of where the warping put its phone,
gives new boundaries; the models are re-estimated from them and the pass repeated. Pauses are
optional states (the aligner puts an empty one at every word boundary, where a speaker may
pause): the path may skip one, and takes it for at least :data:`MIN_PAUSE` s (shorter silences
are the closures of stops, which belong to the stop). Consecutive pauses are one state.

The recursion runs over states, each a vectorized step over its window of frames (as the rows
of :mod:`vtts.align.dtw`): ``D[s, t] = c[s, t] + min(D[s, t-1], D[s-1, t-1])`` is
``S[t] + min_{k ≤ t}(D[s-1, k-1] + c[s, k] − S[k])`` with ``S`` the running sum of ``c[s, ·]``;
the ``k`` of the minimum is where state ``s`` was entered.
"""

from __future__ import annotations

import numpy as np

from vtts.align.features import cepstra
from vtts.speech.phonemes import PAUSES, Phone

#: How far a phone may move from where the warping put it, s.
WINDOW = 0.06
#: Passes of re-estimation and Viterbi.
PASSES = 2
#: Weight of the viseme class's mean against a phoneme's own frames, in frames.
SHRINK = 8.0
#: Shortest pause, s: a stop's closure is silent too, and belongs to the stop.
MIN_PAUSE = 0.08
#: States of a phone (a pause has one).
STATES = 3


def refine_phones(
    phones: list[Phone],
    db: np.ndarray,
    hop: float,
    duration: float,
    *,
    passes: int | None = None,
) -> list[Phone]:
    """Better boundaries for ``phones`` (covering the recording from 0 to ``duration`` s), given
    its ``(n_frames, N_MELS)`` log-mel energies ``db`` every ``hop`` s (frame ``k`` centred on
    ``k * hop``); the phones, their order and visemes stay. See the module docstring."""
    # consecutive pauses (espeak-ng ends with two) are one optional state
    keep = [k for k, p in enumerate(phones) if not (k and _pause(p) and _pause(phones[k - 1]))]
    starts = _refined_starts([phones[k] for k in keep], cepstra(db), hop, passes)
    full = np.empty(len(phones))
    for j, k in enumerate(keep):
        full[k] = starts[j]
        # the pauses merged into phone k are empty, at the end of it
        stop = keep[j + 1] if j + 1 < len(keep) else len(phones)
        full[k + 1 : stop] = starts[j + 1] if j + 1 < len(keep) else duration
    full = np.minimum(np.maximum.accumulate(full), duration)
    full[0] = 0.0
    ends = np.append(full[1:], duration)
    return [
        Phone(float(s), float(e), p.phoneme, p.viseme, p.ipa)
        for p, s, e in zip(phones, full, ends, strict=True)
    ]


def _pause(p: Phone) -> bool:
    return p.phoneme in PAUSES


def _refined_starts(phones: list[Phone], x: np.ndarray, hop: float, passes: int | None):
    """``(n_phones,)`` start (s) of each phone after the passes over ``(n, d)`` features ``x``
    every ``hop`` s; see :func:`refine_phones`."""
    n = len(x)
    is_pause = np.array([p.phoneme in PAUSES for p in phones])
    per = np.where(is_pause, 1, STATES)
    owner = np.repeat(np.arange(len(phones)), per)  # phone of each state
    sub = np.concatenate([np.arange(k) for k in per])  # its place in the phone
    label = _labels(phones, owner, sub)
    klass = np.array(
        [(phones[k].viseme or 0) * STATES + s for k, s in zip(owner, sub, strict=True)]
    )
    bounds = _to_frames([p.start for p in phones], n, hop)
    win = max(1, round(WINDOW / hop))
    for _ in range(PASSES if passes is None else passes):
        state_start = _split(bounds, per, n)
        means, inv_var = _models(x, state_start, label, klass)
        lo, hi = _windows(bounds, per, owner, win, n)
        shortest = np.where(is_pause[owner], max(1, round(MIN_PAUSE / hop)), 1)
        found = _viterbi(x, means, inv_var, lo, hi, is_pause[owner], shortest)
        if found is None:
            break
        bounds = found[np.searchsorted(owner, np.arange(len(phones)))]
    return bounds * hop


def _labels(phones: list[Phone], owner: np.ndarray, sub: np.ndarray) -> np.ndarray:
    names: dict[tuple[str, int], int] = {}
    out = np.empty(len(owner), np.int64)
    for i, (k, s) in enumerate(zip(owner, sub, strict=True)):
        p = phones[k]
        key = ("_", 0) if p.phoneme in PAUSES else (p.phoneme, int(s))
        out[i] = names.setdefault(key, len(names))
    return out


def _to_frames(times: list[float], n: int, hop: float) -> np.ndarray:
    f = np.round(np.asarray(times) / hop).astype(np.int64)
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
    lo = np.maximum.accumulate(np.minimum(lo, n - (len(owner) - idx)).clip(0))
    hi = np.minimum.accumulate(np.maximum(hi, idx + 1)[::-1])[::-1]
    hi = np.maximum(hi, lo + 1)
    lo[0], hi[-1] = 0, n
    return lo, hi


def _viterbi(x, means, inv_var, lo, hi, optional, min_frames):
    """Start frame of each state on the best path (a skipped optional state starts where the
    next one does), or None when the windows allow no path."""
    n_states, n = len(means), len(x)
    # D of the two previous states (a virtual state -1 ends at frame -1 with cost 0)
    prev = [(np.zeros(1), -1, 0), None]  # (D over [a, b), a, b) of state s-1 and s-2
    prev_skippable = [False, False]
    entries = []
    for s in range(n_states):
        a, b = int(lo[s]), int(hi[s])
        diff = x[a:b] - means[s]
        c = (diff * diff) @ inv_var
        cs = np.cumsum(c, dtype=np.float64)
        come = _ended_before(prev[0], a, b)
        skip = np.zeros(b - a, bool)
        if prev_skippable[0] and prev[1] is not None:
            other = _ended_before(prev[1], a, b)
            skip = other < come
            come = np.minimum(come, other)
        vals = come + c - cs
        run = np.minimum.accumulate(vals)
        pos = a + np.maximum.accumulate(np.where(vals <= run, np.arange(b - a), 0))
        # at least min_frames[s] frames: the state ending at t entered at k <= t - L + 1
        shift = int(min_frames[s]) - 1
        if shift:
            run = np.concatenate([np.full(min(shift, b - a), np.inf), run[: max(b - a - shift, 0)]])
            pos = np.concatenate([np.full(min(shift, b - a), a), pos[: max(b - a - shift, 0)]])
        d = cs + run
        entries.append((a, pos, skip))
        prev = [(d, a, b), prev[0]]
        prev_skippable = [bool(optional[s]), prev_skippable[0]]
    # the end: the last state, or the one before a skippable last state
    last = n_states - 1
    end_cost = prev[0][0][-1] if prev[0][2] == n else np.inf
    if optional[last] and prev[1] is not None and prev[1][2] == n and prev[1][0][-1] < end_cost:
        last, end_cost = n_states - 2, prev[1][0][-1]
    if not np.isfinite(end_cost):
        return None
    starts = np.full(n_states, n, np.int64)
    t, s = n - 1, last
    while s >= 0:
        a, entry, skip = entries[s]
        if not a <= t < a + len(entry):
            return None
        k = int(entry[t - a])
        starts[s] = k
        step = 2 if skip[k - a] else 1
        if step == 2:
            starts[s - 1] = k
        s -= step
        t = k - 1
    if t != -1:
        return None
    return starts


def _ended_before(state, a: int, b: int) -> np.ndarray:
    """``(b - a,)``: the cost of a state having ended at frame ``t - 1``, for ``t`` in
    ``[a, b)`` (``inf`` outside its window)."""
    d, pa, pb = state
    out = np.full(b - a, np.inf)
    t0, t1 = max(a, pa + 1), min(b, pb + 1)
    if t1 > t0:
        out[t0 - a : t1 - a] = d[t0 - 1 - pa : t1 - 1 - pa]
    return out


def voice_template(
    phones: list[Phone],
    x: np.ndarray,
    t0: float,
    layout: list[Phone],
    n: int,
    t1: float,
    hop: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The reference spoken in the recording's voice, as features: each state's mean over the
    recording's frames ``x`` (``(m, d)``, frame ``k`` at ``t0 + k * hop`` s) under ``phones``
    (its aligned phones), laid out on ``n`` frames at ``t1 + k * hop`` s by ``layout`` (the
    same phones in the reference's clock). Returns it and the recording's frames, both scaled
    by the inverse pooled standard deviation (so that their distance is the refinement's)."""
    m = len(x)
    is_pause = np.array([p.phoneme in PAUSES for p in phones])
    per = np.where(is_pause, 1, STATES)
    owner = np.repeat(np.arange(len(phones)), per)
    sub = np.concatenate([np.arange(k) for k in per])
    label = _labels(phones, owner, sub)
    klass = np.array(
        [(phones[k].viseme or 0) * STATES + s for k, s in zip(owner, sub, strict=True)]
    )
    bounds = np.clip(np.round((np.array([p.start for p in phones]) - t0) / hop), 0, m)
    bounds = np.maximum.accumulate(bounds.astype(np.int64))
    means, inv_var = _models(x, _split(bounds, per, m), label, klass)
    at = np.clip(np.round((np.array([p.start for p in layout]) - t1) / hop), 0, n)
    at = np.maximum.accumulate(at.astype(np.int64))
    at[0] = 0
    starts = _split(at, per, n)
    frame_state = np.repeat(np.arange(len(starts)), np.diff(np.append(starts, n)).clip(0))[:n]
    scale = np.sqrt(inv_var)
    return (means[frame_state] * scale).astype(np.float32), (x * scale).astype(np.float32)
