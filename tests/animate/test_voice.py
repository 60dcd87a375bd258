"""A face that follows a voice as it arrives (issue 43): :class:`vtts.animate.voice.VoiceTrack`
and :class:`vtts.animate.voice.LiveHabits`."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vtts.animate.timeline import LEAD
from vtts.animate.voice import LiveHabits, VoiceTrack
from vtts.face import load_model
from vtts.face.miap import VISEME_BASE

HEAD = Path(__file__).parents[1] / "data" / "models" / "head.wrl"


def _visemes() -> np.ndarray:
    """1 s of 10 ms visemes: silence, "ma" twice, silence."""
    return np.array([0] * 20 + [1] * 8 + [10] * 15 + [1] * 8 + [10] * 20 + [0] * 29, np.int8)


def test_frames_come_once_each_the_same_in_any_chunks() -> None:
    v = _visemes()
    whole = VoiceTrack(30.0)
    frames = whole.add(v) + whole.finish()
    assert len(frames) == 30 and whole.frames_out == 30
    chunked = VoiceTrack(30.0)
    parts = []
    for a, b in [(0, 1), (1, 7), (7, 50), (50, 51), (51, 100)]:
        parts += chunked.add(v[a:b])
    parts += chunked.finish()
    assert np.allclose(np.array(parts), np.array(frames))
    mouth = slice(VISEME_BASE + 1, VISEME_BASE + 15)
    got = np.array(frames)[:, mouth]
    assert np.all(got >= 0) and np.all(got.sum(axis=1) <= 1 + 1e-9)  # shares (0: the rest)
    assert np.argmax(got[15]) + 1 == 10  # the vowel of the second "ma"
    # the lips shut at each bilabial's centre
    for c in (0.24, 0.47):
        i = int(round((c - LEAD) * 30))
        assert got[i, 0] > 0.95  # (the bilabial heard up to the lead: its centre a little early)


def test_a_frame_waits_for_the_visemes_of_its_lead() -> None:
    track = VoiceTrack(30.0, lead=0.04)
    assert track.add(np.zeros(3, np.int8)) == []  # 30 ms known: frame 0 needs 40 ms
    assert len(track.add(np.zeros(1, np.int8))) == 1
    with pytest.raises(ValueError, match="0–14"):
        track.add(np.array([15]))


def test_live_habits_continue_across_blocks() -> None:
    model = load_model(HEAD)
    habits = LiveHabits(model, fps=10.0, seed=3)
    habits.BLOCK_S, habits.FADE_S = 6.0, 1.0
    habits._n, habits._fade = 60, 10
    track = np.array([habits(i) for i in range(130)])
    assert np.all(track[:, VISEME_BASE : VISEME_BASE + 15] == 0)
    steps = np.abs(np.diff(track, axis=0)).max(axis=1)
    typical = np.percentile(steps, 95)
    assert steps[59] <= 2 * typical + 1e-9 and steps[119] <= 2 * typical + 1e-9
    assert np.any(track[:, 18] > 0.5)  # a blink in 13 s
