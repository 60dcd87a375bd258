"""The mouth leads the sound: the cross-correlation of the lip gap with the speech's RMS per
30 Hz frame peaks at 0 or -1 frame (issue 45: it peaked at +1, the mouth 33 ms late)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from vtts.animate.lipsync import correlations, lip_gaps, peak_lag, rms_per_frame
from vtts.animate.timeline import build_timeline, speech_lead
from vtts.face import load_model
from vtts.utterance import prepare_utterance

#: Rich in bilabials (the issue's case).
TEXT = "My mom bought a big map, maybe a bamboo boat, by the pub. Pam put the maple pie by Bob."


@pytest.fixture(scope="module")
def cybatt():
    return load_model("cybatt")


def mouth_and_sound(model, engine: str, fps: float = 30.0, lead: float | None = None):
    utt = prepare_utterance(TEXT, engine=engine)
    lead = speech_lead(engine) if lead is None else lead
    tl = build_timeline(model, utt.phones, [], utt.duration, fps=fps, autonomous=False, lead=lead)
    return lip_gaps(model, tl.params), rms_per_frame(utt.audio, utt.rate, fps, tl.n_frames)


@pytest.mark.parametrize("engine", ["espeak", "festival"])
def test_the_mouth_leads_the_sound(cybatt, engine):
    # make test's setup installs festival: its absence is a failure, not a skip
    assert engine != "festival" or shutil.which("festival"), "festival is not installed"
    gap, rms = mouth_and_sound(cybatt, engine)
    c = correlations(gap, rms, 5)
    assert peak_lag(gap, rms) in (0, -1), c
    assert max(c.values()) > 0.3  # the measure sees speech, not noise


def test_without_the_lead_espeak_mouth_is_late(cybatt):
    """The measure itself: without the lead the same speech peaks after the sound."""
    gap, rms = mouth_and_sound(cybatt, "espeak", lead=0.0)
    assert peak_lag(gap, rms) >= 1


def test_the_measure_finds_a_known_shift():
    rng = np.random.default_rng(0)
    sound = np.repeat(rng.random(60), 4)  # 240 frames of a blocky envelope
    for shift in (-2, 0, 3):
        mouth = np.roll(sound, shift)
        assert peak_lag(mouth, sound) == shift


def test_rms_per_frame_covers_each_frames_interval():
    rate, fps = 1000, 10.0
    audio = np.zeros(1000)
    audio[300:400] = 2.0  # the fourth frame, [0.3, 0.4) s
    r = rms_per_frame(audio, rate, fps, 10)
    assert r[3] == pytest.approx(2.0) and np.count_nonzero(r) == 1
