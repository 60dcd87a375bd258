"""The timeline: speech, bookmarks and a model's habits become one parameter vector per frame.

For a model and an utterance (timed phonemes, bookmarks with their times in the audio) it builds,
at ``fps`` frames per second:

- the **viseme track** with coarticulation in the manner of Cohen & Massaro: every phone has a
  dominance function over time (vowels reach far ahead of their centre — anticipation — consonants
  less, bilabials strongly but narrowly) and each viseme's weight is its share of the total
  dominance, so mouth shapes blend without hard switches;
- **expressions** from the model's temporal tables: onset, a climax for the requested duration and
  amplitude, offset; overlapping requests superimpose linearly;
- **mouth closure wins**: the lips are shut for every p/b/m from its closure's start to its
  release, where the engine's own audio has them shut against its phones
  (:class:`vtts.speech.engine.BilabialTiming`), :data:`CLOSURE_LEAD` ahead — the viseme weights
  go to viseme 1 and expressions that would open the model's mouth are held back;
- **autonomous behaviour** from the model's habits: blinks, small nods, head motion and gaze,
  drawn from a generator seeded by ``seed`` and the model's name (reproducible, and different
  for two models); a bookmark for the same action overrides the autonomous one near it;
- explicit ``<fap …>`` bookmarks.

Units: times in seconds; low-level FAPs in FAP units; viseme and expression weights 0–1.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field

import numpy as np

from vtts.face.miap import EXPRESSION_BASE, N_PARAMS, VISEME_BASE, Miap
from vtts.fap import FapStream
from vtts.speech.bookmarks import Bookmark
from vtts.speech.engine import BilabialTiming, engine_timing
from vtts.speech.timings import TimedPhone

VOWEL_VISEMES = frozenset({10, 11, 12, 13, 14})
BILABIAL = 1
#: Low-level FAPs that open the lips or jaw; held back during a bilabial closure.
MOUTH_FAPS = (3, 4, 5, 8, 9, 10, 11, 16, 17, 51, 52, 55, 56, 57, 58)
#: The lead of phones timed by espeak-ng, and of phones from elsewhere (``--phonemes``, a
#: recording aligned with espeak-ng's phones), s: each engine gives its own
#: (:attr:`vtts.speech.engine.Engine.lead`, :func:`speech_lead`).
LEAD = 0.04
#: How far a bilabial's closure is put ahead of where the engine's audio has it, s: half a
#: 30 Hz frame (a frame is on screen for 33 ms from its time, so a pose is seen 17 ms after it
#: on average). Chosen on the lip sync bench's tuned texts (docs/speech.md, *The closure
#: measure*).
CLOSURE_LEAD = 1 / 60
#: How long the lips take to shut before a bilabial's closure and to free after it, s (a linear
#: ramp, on top of the coarticulation, which already draws them towards viseme 1): the shortest
#: that moves a viseme weight at most 0.75 in a 30 Hz frame.
CLOSING_S = 0.045
#: Ramp time of a ``<fap …>`` bookmark's values, s.
FAP_RAMP = 0.12


@dataclass
class Timeline:
    """One model's animation: ``params (n, N_PARAMS)`` at ``fps``; ``times (n,)`` in s;
    ``closures``: (start, end) s of each span the lips are shut for bilabials, and
    ``bilabial_centres`` their centres (s); ``events``: behaviour → list of (start s, duration s)
    it ran."""

    params: np.ndarray
    fps: float
    times: np.ndarray
    bilabial_centres: list[float] = field(default_factory=list)
    closures: list[tuple[float, float]] = field(default_factory=list)
    events: dict[str, list[tuple[float, float]]] = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return self.params.shape[0]


# ---- visemes ---------------------------------------------------------------------------------


def dominance(t: np.ndarray, phone: TimedPhone) -> np.ndarray:
    """Cohen–Massaro dominance ``(n,)`` of a phone over times ``t`` (s).

    ``α · exp(−(|t − c| / s)^1.5)`` with the phone's centre c; the spread s is a multiple of the
    phone's duration, wider before the centre for vowels (anticipation) and narrow for
    bilabials, whose α is high so the closure is reached."""
    c = 0.5 * (phone.start + phone.end)
    d = max(phone.end - phone.start, 0.02)
    v = phone.viseme
    if v in VOWEL_VISEMES:
        alpha, before, after = 1.0, 1.6 * d, 0.8 * d
    elif v == BILABIAL:
        alpha, before, after = 2.0, 0.6 * d, 0.5 * d
    elif v == 0:
        alpha, before, after = 0.7, 0.5 * d, 0.5 * d
    else:
        alpha, before, after = 0.8, 0.7 * d, 0.6 * d
    dt = t - c
    s = np.where(dt < 0, before, after)
    return alpha * np.exp(-((np.abs(dt) / s) ** 1.5))


def viseme_weights(t: np.ndarray, phones: list[TimedPhone]) -> np.ndarray:
    """``(n, 15)`` viseme weights (columns 0–14, rows sum to 1): each viseme's share of the total
    dominance, with a small constant neutral share so silence relaxes to viseme 0."""
    w = np.zeros((t.size, 15))
    w[:, 0] = 1e-2
    if phones:
        # the silence before and after the utterance dominates like a phone of its own
        first, last = min(p.start for p in phones), max(p.end for p in phones)
        edges = [TimedPhone(first - 0.3, first, 0), TimedPhone(last, last + 0.3, 0)]
        for p in [*phones, *edges]:
            w[:, p.viseme] += dominance(t, p)
    return w / w.sum(axis=1, keepdims=True)


def closure(t: np.ndarray, centres: list[float], fps: float, width: float = 0.05) -> np.ndarray:
    """``(n,)`` in [0, 1]: 1 within half a frame of a bilabial centre (so the nearest frame is
    fully closed), falling smoothly to 0 over ``width`` s on either side (the live voice's
    closures, :mod:`vtts.animate.voice`, which knows no engine's timing)."""
    k = np.zeros(t.size)
    half = 0.5 / fps
    for c in centres:
        x = np.clip((np.abs(t - c) - half) / width, 0.0, 1.0)
        k = np.maximum(k, 0.5 + 0.5 * np.cos(np.pi * x))
    return k


def shut(
    t: np.ndarray, spans: list[tuple[float, float]], fps: float, width: float = CLOSING_S
) -> np.ndarray:
    """``(n,)`` in [0, 1]: 1 over each (start, end) span (s; one shorter than a frame is widened
    to a frame about its centre, so a frame falls inside it), falling linearly to 0 over
    ``width`` s on either side."""
    k = np.zeros(t.size)
    for a, b in spans:
        if b - a < 1.0 / fps:
            c = 0.5 * (a + b)
            a, b = c - 0.5 / fps, c + 0.5 / fps
        x = np.clip(np.maximum(a - t, t - b) / width, 0.0, 1.0)
        k = np.maximum(k, 1.0 - x)
    return k


def closure_spans(phones: list[TimedPhone], bilabials: BilabialTiming) -> list[tuple[float, float]]:
    """When the lips are shut for the bilabials of ``phones``, (start, end) s: each run of
    adjacent bilabial phones is one closure (``m b``), from its onset to its release where
    ``bilabials`` (the engine's :class:`~vtts.speech.engine.BilabialTiming`) puts them in the
    audio, :data:`CLOSURE_LEAD` ahead; never before the time 0."""
    spans = []
    i = 0
    while i < len(phones):
        if phones[i].viseme != BILABIAL:
            i += 1
            continue
        j = i
        while j + 1 < len(phones) and phones[j + 1].viseme == BILABIAL:
            j += 1
        onset, release = bilabials.span(phones[i], phones[j])
        a = max(onset - CLOSURE_LEAD, 0.0)
        spans.append((a, max(release - CLOSURE_LEAD, a)))
        i = j + 1
    return spans


# ---- behaviours ----------------------------------------------------------------------------------


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def blink_profile(t: np.ndarray, start: float, duration: float) -> np.ndarray:
    """A blink: closes over the first 35 % of ``duration``, opens over the rest (0–1)."""
    x = (t - start) / duration
    up = _smoothstep(x / 0.35)
    down = 1 - _smoothstep((x - 0.35) / 0.65)
    return np.where(x < 0.35, up, down) * ((x >= 0) & (x <= 1))


def bump(t: np.ndarray, start: float, duration: float) -> np.ndarray:
    """``sin²`` bump over [start, start + duration] (0–1)."""
    x = (t - start) / duration
    return np.where((x >= 0) & (x <= 1), np.sin(np.pi * np.clip(x, 0, 1)) ** 2, 0.0)


def _event_times(rng, habit, end: float, first: float = 0.3) -> list[float]:
    times = []
    t = first + rng.uniform(0, habit.interval)
    while t < end:
        times.append(t)
        t += max(habit.duration + 0.25, rng.normal(habit.interval, habit.jitter))
    return times


def _near(t: float, others: list[float], window: float) -> bool:
    return any(abs(t - o) < window for o in others)


def speech_lead(engine: str | None) -> float:
    """The lead (s) for phones timed by ``engine`` (its :attr:`~vtts.speech.engine.Engine.lead`;
    espeak-ng's, :data:`LEAD`, for others)."""
    return engine_timing(engine)[0]


def speech_bilabials(engine: str | None) -> BilabialTiming:
    """The :class:`~vtts.speech.engine.BilabialTiming` of phones timed by ``engine`` (espeak-ng's
    for others)."""
    return engine_timing(engine)[1]


# ---- the whole timeline --------------------------------------------------------------------------


def build_timeline(
    model,
    phones: list[TimedPhone],
    bookmarks: list[Bookmark],
    duration: float,
    *,
    fps: float = 30.0,
    seed: int = 0,
    autonomous: bool = True,
    lead: float = LEAD,
    bilabials: BilabialTiming | None = None,
) -> Timeline:
    """The :class:`Timeline` of ``model`` speaking ``phones`` with ``bookmarks`` (times set)
    for ``duration`` s. ``lead``: how far the visemes are put ahead of the phones' times, s
    (:func:`speech_lead` of the engine that timed them); ``bilabials``: where its audio has the
    lips shut against its phones (:func:`speech_bilabials` of the engine; espeak-ng's when
    None), which places the closures (:func:`closure_spans`)."""
    n = max(1, int(np.ceil(duration * fps - 1e-9)))
    t = np.arange(n) / fps
    p = np.zeros((n, N_PARAMS))
    events: dict[str, list[tuple[float, float]]] = {}
    temporal = model.temporal
    have = set(model.tables.adts)

    # visemes with coarticulation ahead of the phones by the lead, then the bilabial closures
    vw = viseme_weights(t + lead, phones)
    spans = closure_spans(phones, bilabials or speech_bilabials(None))
    centres = [0.5 * (a + b) for a, b in spans]
    kappa = shut(t, spans, fps, CLOSING_S)
    vw = (1 - kappa)[:, None] * vw
    vw[:, BILABIAL] += kappa
    p[:, VISEME_BASE + 1 : VISEME_BASE + 15] = vw[:, 1:]

    # expressions
    for b in bookmarks:
        if b.kind != "expression" or b.time is None:
            continue
        number = Miap.parse(f"expression {b.name}").number
        timing = temporal.expression(b.name)
        amp = 1.0 if b.amplitude is None else b.amplitude
        p[:, EXPRESSION_BASE + number] += timing.envelope(t, b.time, b.duration, amp)
        events.setdefault(f"expression {b.name}", []).append((b.time, timing.total(b.duration)))
    p[:, EXPRESSION_BASE + 1 : EXPRESSION_BASE + 7] = np.clip(
        p[:, EXPRESSION_BASE + 1 : EXPRESSION_BASE + 7], 0.0, 2.0
    )
    for e in mouth_opening_expressions(model):
        p[:, EXPRESSION_BASE + e] *= 1 - kappa

    # explicit FAP bookmarks
    for b in bookmarks:
        if b.kind != "fap" or b.time is None:
            continue
        d = 1.0 if b.duration is None else b.duration
        x = t - b.time
        ramp = np.clip(np.minimum(x, d - x) / FAP_RAMP + 0.5, 0.0, 1.0) * ((x >= 0) & (x <= d))
        amp = 1.0 if b.amplitude is None else b.amplitude
        for k, v in b.faps.items():
            p[:, k - 1] += amp * v * ramp

    # actions asked for by bookmarks, and the autonomous behaviours they override
    rng = np.random.default_rng([seed, zlib.crc32(model.name.encode())])
    asked: dict[str, list[Bookmark]] = {}
    for b in bookmarks:
        if b.kind == "action" and b.time is not None:
            asked.setdefault(b.name, []).append(b)

    blink = temporal.habit("blink")
    blinks = [
        (b.time, b.duration or blink.duration, b.amplitude or 1.0) for b in asked.get("blink", [])
    ]
    if autonomous:
        taken = [b[0] for b in blinks]
        blinks += [
            (s, blink.duration, 1.0)
            for s in _event_times(rng, blink, duration)
            if not _near(s, taken, 1.0)
        ]
    for start, d, a in blinks:
        prof = blink_profile(t, start, d) * a * blink.amplitude
        for k, share in ((19, 1.0), (20, 1.0), (21, 0.12), (22, 0.12)):
            p[:, k - 1] = np.maximum(p[:, k - 1], share * prof)
        events.setdefault("blink", []).append((start, d))

    nod = temporal.habit("nod")
    nods = [(b.time, b.duration or nod.duration, b.amplitude or 1.0) for b in asked.get("nod", [])]
    if autonomous:
        taken = [x[0] for x in nods]
        nods += [
            (s, nod.duration, rng.uniform(0.5, 1.0))
            for s in _event_times(rng, nod, duration)
            if not _near(s, taken, 1.5)
        ]
    for start, d, a in nods:
        p[:, 47] += a * nod.amplitude * bump(t, start, d)
        events.setdefault("nod", []).append((start, d))

    head = temporal.habit("head_motion")
    shakes = asked.get("shake", [])
    for b in shakes:
        d = b.duration or 0.9
        x = np.clip((t - b.time) / d, 0, 1)
        inside = (t >= b.time) & (t <= b.time + d)
        amp = (b.amplitude or 1.0) * 2.5 * head.amplitude
        p[:, 48] += np.where(inside, amp * np.sin(2 * np.pi * 2 * x) * np.sin(np.pi * x), 0.0)
        events.setdefault("shake", []).append((b.time, d))
    if autonomous:
        quiet = np.ones(n)
        for b in shakes:
            quiet *= 1 - bump(t, b.time - 0.3, (b.duration or 0.9) + 0.6)
        for k, share in ((48, 0.6), (49, 1.0), (50, 0.4)):
            wave = np.zeros(n)
            for _ in range(3):
                f = rng.uniform(0.5, 1.5) / head.duration
                wave += np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi)) / 3
            p[:, k - 1] += share * head.amplitude * wave * quiet
        events["head_motion"] = [(0.0, duration)]

    gaze = temporal.habit("gaze")
    looks = {
        "look_left": (1.5, 0.0),
        "look_right": (-1.5, 0.0),
        "look_up": (0.0, -1.0),
        "look_down": (0.0, 1.0),
        "look_ahead": (0.0, 0.0),
    }
    yaw = np.zeros(n)
    pitch = np.zeros(n)
    held = np.zeros(n, dtype=bool)
    for name, (gy, gp) in looks.items():
        for b in asked.get(name, []):
            d = b.duration or 1.5
            a = (b.amplitude or 1.0) * gaze.amplitude
            shape = np.clip(np.minimum(t - b.time, b.time + d - t) / max(gaze.duration, 1e-3), 0, 1)
            yaw += gy * a * _smoothstep(shape)
            pitch += gp * a * _smoothstep(shape)
            held |= (t >= b.time - 0.5) & (t <= b.time + d + 0.5)
            events.setdefault(name, []).append((b.time, d))
    if autonomous:
        target_y = target_p = 0.0
        cur_y = np.zeros(n)
        cur_p = np.zeros(n)
        last = 0.0
        for s in _event_times(rng, gaze, duration):
            new_y = rng.uniform(-gaze.amplitude, gaze.amplitude)
            new_p = rng.uniform(-0.4, 0.4) * gaze.amplitude
            x = _smoothstep((t - s) / max(gaze.duration, 1e-3))
            seg = t >= last
            cur_y = np.where(seg, target_y + (new_y - target_y) * x, cur_y)
            cur_p = np.where(seg, target_p + (new_p - target_p) * x, cur_p)
            target_y, target_p, last = new_y, new_p, s
            events.setdefault("gaze", []).append((s, gaze.duration))
        yaw += np.where(held, 0.0, cur_y)
        pitch += np.where(held, 0.0, cur_p)
    p[:, 22] += yaw
    p[:, 23] += yaw
    p[:, 24] += pitch
    p[:, 25] += pitch

    for k in MOUTH_FAPS:
        p[:, k - 1] *= 1 - kappa
    # MIAPs the model cannot show stay in the vector (the exported stream keeps them)
    del have
    return Timeline(p, fps, t, centres, closures=spans, events=events)


def mouth_opening_expressions(model) -> list[int]:
    """Expression numbers whose table opens the model's lips (by its feature points 8.1/8.2 or
    2.2/2.3); every expression when the model gives no lip feature points."""
    fp = model.tables.feature_points
    pairs = [("8.1", "8.2"), ("2.2", "2.3")]
    pair = next((pr for pr in pairs if pr[0] in fp and pr[1] in fp), None)
    numbers = [m.number for m in model.tables.adts if m.kind == "expression"]
    if pair is None:
        return numbers
    (n_up, v_up), (n_lo, v_lo) = fp[pair[0]], fp[pair[1]]

    def gap(params) -> float:
        pose = model.engine.deform(params)
        up = pose.points.get(n_up, model.neutral_points(n_up))[v_up]
        lo = pose.points.get(n_lo, model.neutral_points(n_lo))[v_lo]
        return float(up[1] - lo[1])

    base = gap(np.zeros(N_PARAMS))
    out = []
    for e in numbers:
        q = np.zeros(N_PARAMS)
        q[EXPRESSION_BASE + e] = 1.0
        if gap(q) > base + 1e-4:
            out.append(e)
    return out


def timeline_stream(tl: Timeline, name: str = "vtts") -> FapStream:
    """The timeline as an MPEG-4 FAP stream: low-level FAPs (rounded to FAP units) where they move,
    FAP 1 with the two strongest visemes (neutral, viseme 0, among them) and their blend, FAP 2
    with the two strongest expressions and their intensities (0–63)."""
    n = tl.n_frames
    low = np.round(tl.params[:, :68])
    low[:, :2] = 0
    used = np.abs(low).max(axis=0) > 0
    mask = np.repeat(used[None, :], n, axis=0)
    # viseme 0, neutral, takes what the others leave: in a pause the two strongest are then
    # neutral and a trace of a viseme, where the blend of two traces alone would show a whole one
    shown = tl.params[:, VISEME_BASE + 1 : VISEME_BASE + 15]
    vis = np.concatenate([np.clip(1 - shown.sum(axis=1, keepdims=True), 0, 1), shown], axis=1)
    order = np.argsort(-vis, axis=1, kind="stable")
    v1 = order[:, 0]
    v2 = order[:, 1]
    w1 = vis[np.arange(n), v1]
    w2 = vis[np.arange(n), v2]
    total = w1 + w2
    viseme = np.zeros((n, 4), dtype=np.int64)
    speaking = total > 1e-3
    viseme[:, 0] = np.where(speaking, v1, 0)
    viseme[:, 1] = np.where(speaking, v2, 0)
    viseme[:, 2] = np.where(speaking, np.round(63 * w1 / np.maximum(total, 1e-9)), 0)
    ex = tl.params[:, EXPRESSION_BASE + 1 : EXPRESSION_BASE + 7]
    eorder = np.argsort(-ex, axis=1)
    e1, e2 = eorder[:, 0], eorder[:, 1]
    i1 = np.clip(np.round(63 * ex[np.arange(n), e1]), 0, 63)
    i2 = np.clip(np.round(63 * ex[np.arange(n), e2]), 0, 63)
    expression = np.zeros((n, 6), dtype=np.int64)
    expression[:, 0] = np.where(i1 > 0, e1 + 1, 0)
    expression[:, 1] = i1
    expression[:, 2] = np.where(i2 > 0, e2 + 1, 0)
    expression[:, 3] = i2
    mask[:, 0] = True
    mask[:, 1] = (expression[:, 1] > 0).any()
    values = low.astype(np.float64)
    return FapStream(tl.fps, name, values * mask, mask, viseme, expression)
