"""A face that follows a voice as it arrives: 10 ms visemes in, one parameter vector per video
frame out (what ``vtts play --audio -`` renders).

:class:`VoiceTrack` takes the visemes a :class:`~vtts.speech.recognize.LiveRecognizer` decides,
in order, and gives each video frame's MIAP parameters as soon as the visemes it needs are known:
frame ``i`` (at ``t = i / fps``) shows the mouth of ``t + lead`` (the lips move ahead of the
sound, :data:`~vtts.animate.timeline.LEAD`), so it waits for the visemes up to there. The mouth
is the timeline's (:mod:`vtts.animate.timeline`): every run of one viseme is a phone with its
Cohen–Massaro dominance, blended by share, and the lips close at each bilabial's centre — over the
phones known so far (those of the last :data:`WINDOW_S`), so the coarticulation reaches back
but not ahead of what has been heard. :class:`LiveHabits` adds the model's blinks, nods, head
motion and gaze for a stream of unknown length.
"""

from __future__ import annotations

import numpy as np

from vtts.animate.timeline import BILABIAL, LEAD, closure, dominance
from vtts.face.miap import N_PARAMS, VISEME_BASE
from vtts.speech.energy import FRAME_S
from vtts.speech.timings import TimedPhone

__all__ = ["WINDOW_S", "LiveHabits", "VoiceTrack"]

#: Visemes older than this before a frame's time no longer shape it, s.
WINDOW_S = 1.0


class VoiceTrack:
    """Video frames' parameters from 10 ms visemes arriving over time (see the module).

    ``fps``: the video's frame rate, Hz; ``lead``: how far the mouth is ahead of the sound, s.
    :meth:`add` takes the next visemes (``(k,)`` ints 0–14, one per 10 ms, the first following
    the last given) and returns the ``(N_PARAMS,)`` float64 vectors of the frames now complete;
    :meth:`finish` those of the rest up to the end of the visemes given. :attr:`frames_out`
    counts the frames given."""

    def __init__(self, fps: float = 30.0, lead: float = LEAD) -> None:
        if not (0 < fps <= 240):
            raise ValueError(f"fps must be in (0, 240], got {fps}")
        self.fps = float(fps)
        self.lead = float(lead)
        self._vis = np.zeros(0, np.int8)  # the visemes kept (the last WINDOW_S and after)
        self._first = 0  # the 10 ms frame index of self._vis[0]
        self.frames_out = 0

    @property
    def known(self) -> float:
        """The time up to which visemes are known, s."""
        return (self._first + self._vis.size) * FRAME_S

    def add(self, visemes: np.ndarray) -> list[np.ndarray]:
        """The next visemes → the parameter vectors of the frames now complete."""
        v = np.asarray(visemes, dtype=np.int8).ravel()
        if v.size and (v.min() < 0 or v.max() > 14):
            raise ValueError("a viseme is 0–14")
        self._vis = np.concatenate([self._vis, v])
        out = []
        while self.frames_out / self.fps + self.lead <= self.known + 1e-9:
            out.append(self._frame(self.frames_out / self.fps))
            self.frames_out += 1
        self._forget(self.frames_out / self.fps + self.lead - WINDOW_S)
        return out

    def finish(self) -> list[np.ndarray]:
        """The frames left up to the end of the visemes given (the mouth of the last ones)."""
        out = []
        end = self.known
        while self.frames_out / self.fps < end - 1e-9:
            out.append(self._frame(self.frames_out / self.fps))
            self.frames_out += 1
        return out

    def _phones(self, upto: float) -> list[TimedPhone]:
        """The runs of the visemes kept, up to ``upto`` s, as phones."""
        v = self._vis[: max(int(round(upto / FRAME_S)) - self._first, 0)]
        if v.size == 0:
            return []
        edges = np.concatenate([[0], np.flatnonzero(np.diff(v)) + 1, [v.size]])
        base = self._first * FRAME_S
        return [
            TimedPhone(base + a * FRAME_S, base + b * FRAME_S, int(v[a]))
            for a, b in zip(edges[:-1], edges[1:], strict=True)
        ]

    def _frame(self, t: float) -> np.ndarray:
        """The parameters of the frame at ``t`` s, as :func:`~vtts.animate.timeline.
        build_timeline` makes its visemes and bilabial closures."""
        # what was heard up to the frame's lead, however the visemes came in chunks
        phones = self._phones(t + self.lead)
        at = np.array([t + self.lead])
        w = np.zeros((1, 15))
        w[:, 0] = 1e-2
        for p in phones:
            w[:, p.viseme] += dominance(at, p)
        w /= w.sum(axis=1, keepdims=True)
        centres = [max(0.5 * (p.start + p.end) - self.lead, 0.0) for p in phones
                   if p.viseme == BILABIAL]  # fmt: skip
        kappa = closure(np.array([t]), centres, self.fps)
        w = (1 - kappa)[:, None] * w
        w[:, BILABIAL] += kappa
        params = np.zeros(N_PARAMS)
        params[VISEME_BASE + 1 : VISEME_BASE + 15] = w[0, 1:]
        return params

    def _forget(self, before: float) -> None:
        """Drop the visemes that end before ``before`` s."""
        drop = int(np.floor(before / FRAME_S)) - self._first
        if drop > 0:
            drop = min(drop, self._vis.size)
            self._vis = self._vis[drop:]
            self._first += drop


class LiveHabits:
    """A model's autonomous behaviour (blinks, nods, head motion, gaze) for a stream of unknown
    length: :func:`~vtts.animate.timeline.build_timeline` without speech, in blocks of
    :attr:`BLOCK_S` seconds (block ``k`` seeded by ``seed`` and ``k``), each crossfaded into the
    next over :attr:`FADE_S`, so the head never jumps. ``habits(i)`` is frame ``i``'s
    ``(N_PARAMS,)`` float64 vector (its visemes at rest: a :class:`VoiceTrack`'s are added)."""

    BLOCK_S = 60.0
    FADE_S = 1.0

    def __init__(self, model, fps: float = 30.0, seed: int = 0) -> None:
        self.model = model
        self.fps = float(fps)
        self.seed = int(seed)
        self._n = max(int(round(self.BLOCK_S * self.fps)), 1)
        self._fade = max(int(round(self.FADE_S * self.fps)), 1)
        self._blocks: dict[int, np.ndarray] = {}

    def _block(self, k: int) -> np.ndarray:
        if k not in self._blocks:
            from vtts.animate.timeline import build_timeline

            for old in [b for b in self._blocks if b < k - 1]:
                del self._blocks[old]
            duration = (self._n + self._fade) / self.fps
            tl = build_timeline(self.model, [], [], duration, fps=self.fps,
                                seed=(self.seed + k) % (1 << 63))  # fmt: skip
            p = tl.params.copy()
            p[:, VISEME_BASE : VISEME_BASE + 15] = 0.0  # the voice gives the mouth
            self._blocks[k] = p
        return self._blocks[k]

    def __call__(self, i: int) -> np.ndarray:
        k, j = divmod(int(i), self._n)
        p = self._block(k)[j]
        if k > 0 and j < self._fade:
            a = (j + 0.5) / self._fade
            p = a * p + (1 - a) * self._block(k - 1)[self._n + j]
        return p
