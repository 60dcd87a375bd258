"""Temporal tables: expression envelopes (onset, climax, offset) and habits."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.errors import AdtError
from vtts.face import ExpressionTiming, TemporalTables


@pytest.mark.parametrize("shape", ["linear", "smooth", "exponential"])
def test_envelope_has_onset_climax_and_offset(shape):
    t = ExpressionTiming(onset=0.5, offset=1.0, shape=shape, climax=0.9, duration=2.0)
    times = np.linspace(0, 6, 601)
    w = t.envelope(times, start=1.0, duration=3.0, amplitude=0.5)
    assert w[times < 1.0].max() == 0  # nothing before the bookmark
    climax = (times >= 1.5) & (times <= 4.5)
    assert np.allclose(w[climax], 0.45)
    assert np.all(np.diff(w[(times >= 1.0) & (times <= 1.5)]) >= 0)  # onset rises
    assert np.all(np.diff(w[(times >= 4.5) & (times <= 5.5)]) <= 0)  # offset falls
    assert np.allclose(w[times >= 5.5], 0)
    assert np.all(np.abs(np.diff(w)) < 0.1)  # no jumps at 100 Hz
    assert t.total(3.0) == 4.5


def test_default_duration_and_defaults():
    tt = TemporalTables()
    joy = tt.expression("joy")
    w = joy.envelope(np.array([0.0, joy.onset + joy.duration / 2]), start=0.0)
    assert w[1] == pytest.approx(joy.climax)
    assert tt.habit("blink").duration > 0
    with pytest.raises(AdtError, match="unknown behaviour 'wink'"):
        tt.habit("wink")


def test_two_models_differ_in_time():
    a = ExpressionTiming(onset=0.2, offset=0.3)
    b = ExpressionTiming(onset=1.0, offset=1.5, shape="linear")
    times = np.linspace(0, 4, 81)
    assert not np.allclose(a.envelope(times, 0.5, 1.0), b.envelope(times, 0.5, 1.0))
