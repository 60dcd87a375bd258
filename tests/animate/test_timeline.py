"""The timeline: coarticulated visemes, expression envelopes, mouth closure, habits."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vtts.animate.timeline import (
    CLOSURE_LEAD,
    LEAD,
    build_timeline,
    closure,
    closure_spans,
    timeline_stream,
    viseme_weights,
)
from vtts.face import load_model
from vtts.face.miap import EXPRESSION_BASE, VISEME_BASE
from vtts.fap import format_fap, parse_fap
from vtts.speech.bookmarks import Bookmark
from vtts.speech.engine import ENGINES, BilabialTiming, LipTiming, engine_timing, load_engine
from vtts.speech.timings import TimedPhone

HEAD = Path(__file__).parents[1] / "data" / "models" / "head.wrl"


@pytest.fixture(scope="module")
def head():
    return load_model(HEAD)


def phones_for(visemes: list[int], start: float = 0.2, step: float = 0.09) -> list[TimedPhone]:
    return [TimedPhone(start + i * step, start + (i + 1) * step, v) for i, v in enumerate(visemes)]


# "a mama boba ..." — vowels, bilabials and others
SEQ = [10, 1, 10, 1, 10, 0, 4, 12, 7, 1, 13, 1, 10, 0]


def test_viseme_weights_blend_without_hard_switches():
    t = np.arange(0, 2, 1 / 30)
    w = viseme_weights(t, phones_for(SEQ))
    assert np.allclose(w.sum(axis=1), 1)
    assert np.abs(np.diff(w, axis=0)).max() < 0.6  # no hard switch between frames
    assert w[0, 0] > 0.8 and w[-1, 0] > 0.8  # silence before and after


def test_vowels_are_anticipated():
    """A vowel's weight rises before its own start (anticipation), more than it lingers."""
    phones = phones_for([4, 10, 4])  # t A t
    a = phones[1]
    t = np.array([a.start - 0.03, a.end + 0.03])
    w = viseme_weights(t, phones)
    assert w[0, 10] > 0.2
    assert w[0, 10] > w[1, 10]


def test_bilabial_centres_close_fully_under_an_expression(head):
    phones = phones_for(SEQ)
    marks = [Bookmark("expression", "joy", duration=1.0, time=0.1)]
    tl = build_timeline(head, phones, marks, 1.6, fps=30, autonomous=False)
    assert len(tl.bilabial_centres) == 4
    for c in tl.bilabial_centres:
        i = int(round(c * 30))
        assert tl.params[i, VISEME_BASE + 1] == pytest.approx(1.0)
        assert tl.params[i, EXPRESSION_BASE + 1] == pytest.approx(0.0)  # joy held back
        assert np.all(tl.params[i, [2, 3, 4]] == 0)  # jaw and mid-lip FAPs too
    # between closures the expression is there
    assert tl.params[int(0.75 * 30), EXPRESSION_BASE + 1] > 0.5


#: espeak-ng-like: a p's closure is the 50 ms before it, a b opens 20 ms before its end.
TIMING = BilabialTiming(LipTiming(-0.05, 0.0, "start"), LipTiming(0.0, -0.02), LipTiming(0.0, 0.0))


def test_lips_shut_from_the_closures_onset_to_its_release(head):
    # "a p a m b a": the p's closure in the phone before it; m b one closure
    phones = [TimedPhone(0.0, 0.3, 10, "a"), TimedPhone(0.3, 0.35, 1, "p"),
              TimedPhone(0.35, 0.6, 10, "a"), TimedPhone(0.6, 0.68, 1, "m"),
              TimedPhone(0.68, 0.76, 1, "b"), TimedPhone(0.76, 1.0, 10, "a")]  # fmt: skip
    spans = closure_spans(phones, TIMING)
    lead = CLOSURE_LEAD
    assert np.allclose(spans, [(0.25 - lead, 0.3 - lead), (0.6 - lead, 0.74 - lead)])
    tl = build_timeline(head, phones, [], 1.2, fps=30, autonomous=False, bilabials=TIMING)
    assert tl.closures == spans
    assert tl.bilabial_centres == pytest.approx([0.5 * (a + b) for a, b in spans])
    for a, b in spans:
        inside = (tl.times >= a) & (tl.times <= b)
        assert inside.sum() >= 2 and np.all(tl.params[inside, VISEME_BASE + 1] == 1.0)
    vowel = (tl.times > 0.32) & (tl.times < 0.55)
    assert tl.params[vowel, VISEME_BASE + 1].min() < 0.2  # open between the closures
    # a bilabial at the very start is shut from the first frame
    first = closure_spans([TimedPhone(0.0, 0.05, 1, "p"), TimedPhone(0.05, 0.3, 10, "a")], TIMING)
    assert first[0][0] == 0.0 and first[0][1] >= 0.0


def test_a_closure_shorter_than_a_frame_still_shuts_a_frame(head):
    brief = BilabialTiming(*(LipTiming(0.0, -0.08),) * 3)  # the release before the onset
    phones = phones_for([10, 1, 10], start=0.2, step=0.06)
    tl = build_timeline(head, phones, [], 0.6, fps=30, autonomous=False, bilabials=brief)
    assert tl.closures[0][0] == tl.closures[0][1]
    assert tl.params[:, VISEME_BASE + 1].max() == 1.0


def test_each_engine_gives_its_lead_and_bilabial_timing():
    for name in ENGINES:
        engine = load_engine(name)
        assert isinstance(engine.bilabials, BilabialTiming) and 0 <= engine.lead < 0.1
        assert engine_timing(name) == (engine.lead, engine.bilabials)
    assert engine_timing(None) == engine_timing("espeak") == engine_timing("no such engine")
    assert engine_timing(None)[0] == LEAD
    b = TIMING
    assert [b.of(x) for x in ("m", "em", "m-", "p", "b", "ɓ", "")] == [b.m, b.m, b.m, b.p, b.b,
                                                                     b.b, b.b]  # fmt: skip


def test_closure_is_one_at_the_nearest_frame():
    t = np.arange(0, 1, 1 / 30)
    k = closure(t, [0.517], 30)
    assert k[int(round(0.517 * 30))] == 1.0 and k[0] == 0.0


def test_expression_follows_the_models_temporal_table(head):
    marks = [Bookmark("expression", "joy", duration=1.0, amplitude=0.8, time=0.5)]
    tl = build_timeline(head, [], marks, 4.0, fps=30, autonomous=False)
    w = tl.params[:, EXPRESSION_BASE + 1]
    joy = head.temporal.expression("joy")  # onset 0.5, offset 0.8 in the test head
    assert w[int(0.5 * 30)] == pytest.approx(0.0, abs=1e-9)
    assert w[int((0.5 + joy.onset + 0.5) * 30)] == pytest.approx(0.8)
    assert w[int((0.5 + joy.onset + 1.0 + joy.offset + 0.1) * 30)] == 0.0


def test_overlapping_expressions_add(head):
    one = [Bookmark("expression", "joy", duration=2.0, amplitude=0.4, time=0.2)]
    two = one + [Bookmark("expression", "joy", duration=2.0, amplitude=0.3, time=0.2)]
    a = build_timeline(head, [], one, 3, autonomous=False).params[:, EXPRESSION_BASE + 1]
    b = build_timeline(head, [], two, 3, autonomous=False).params[:, EXPRESSION_BASE + 1]
    assert np.allclose(b, a * 0.7 / 0.4)


def test_habits_are_seeded_reproducible_and_bookmarks_override(head):
    a = build_timeline(head, [], [], 20.0, seed=3)
    b = build_timeline(head, [], [], 20.0, seed=3)
    c = build_timeline(head, [], [], 20.0, seed=4)
    assert np.array_equal(a.params, b.params)
    assert not np.array_equal(a.params, c.params)
    assert len(a.events["blink"]) >= 2
    asked = build_timeline(head, [], [Bookmark("action", "blink", time=5.0)], 20.0, seed=3)
    starts = [s for s, _ in asked.events["blink"]]
    assert 5.0 in starts
    assert not any(0 < abs(s - 5.0) < 1.0 for s in starts)  # autonomous blinks kept away
    quiet = build_timeline(head, [], [], 20.0, seed=3, autonomous=False)
    assert not quiet.params[:, :68].any()


def test_no_frame_to_frame_jump_beyond_a_bound(head):
    marks = [
        Bookmark("expression", "surprise", duration=0.5, time=0.3),
        Bookmark("action", "nod", time=1.0),
        Bookmark("action", "look_left", time=1.2),
        Bookmark("fap", "fap", duration=0.8, faps={3: 300}, time=0.4),
    ]
    tl = build_timeline(head, phones_for(SEQ), marks, 3.0, seed=1)
    d = np.abs(np.diff(tl.params, axis=0))
    assert d[:, VISEME_BASE:].max() <= 0.75  # weights
    blink = head.temporal.habit("blink").amplitude
    assert d[:, 18].max() <= 0.75 * blink  # a blink closes in a few frames, not one
    assert d[:, 47:50].max() < 3000 and d[:, 22:26].max() < 8000  # AU per frame


def test_the_stream_export_round_trips(head):
    marks = [Bookmark("expression", "joy", duration=1.0, time=0.2)]
    tl = build_timeline(head, phones_for(SEQ), marks, 2.0, seed=2)
    s = timeline_stream(tl, "test")
    assert s.n_frames == tl.n_frames and s.fps == 30
    assert parse_fap(format_fap(s)) == s
    speaking = s.viseme[:, 0] > 0
    assert speaking.any() and (s.viseme[speaking, 2] <= 63).all()
    assert s.expression[:, 1].max() == 63  # joy at its climax
