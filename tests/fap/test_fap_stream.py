"""FapStream: validation, equality and resampling."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vtts.errors import FapError
from vtts.fap import FapStream, read_fap

DATA = Path(__file__).resolve().parent.parent / "data" / "fap"


def make(n: int = 3, **kw: Any) -> FapStream:
    values = kw.pop("values", np.zeros((n, 68)))
    mask = kw.pop("mask", np.ones((n, 68), dtype=bool))
    return FapStream(
        fps=kw.pop("fps", 25.0), name=kw.pop("name", "s"), values=values, mask=mask, **kw
    )


def test_defaults_and_properties() -> None:
    s = make(5)
    assert s.viseme.shape == (5, 4) and s.viseme.dtype == np.int64 and not s.viseme.any()
    assert s.expression.shape == (5, 6) and s.expression.dtype == np.int64
    assert (s.first_frame, s.version) == (0, "2.1")
    assert s.n_frames == 5 and s.duration == 0.2
    assert s.times.tolist() == [0.0, 0.04, 0.08, 0.12, 0.16]
    assert repr(s) == "FapStream(name='s', fps=25.0, n_frames=5, first_frame=0, version='2.1')"


def test_inputs_are_copied_and_converted() -> None:
    values = np.zeros((1, 68), dtype=np.float32)
    mask = np.zeros((1, 68), dtype=int)
    mask[0, 4] = 1
    values[0, 4] = 2.5
    s = make(values=values, mask=mask, fps=30)
    values[0, 4] = 9
    assert s.values[0, 4] == 2.5 and s.values.dtype == np.float64
    assert s.mask.dtype == np.bool_ and s.fps == 30.0 and isinstance(s.fps, float)


def test_unmasked_values_are_zeroed() -> None:
    values = np.full((2, 68), 7.0)
    values[:, :2] = 0
    mask = np.zeros((2, 68), dtype=bool)
    mask[0, 10] = True
    viseme = [[1, 2, 3, 0], [4, 5, 6, 1]]
    s = make(values=values, mask=mask, viseme=viseme)
    assert s.values.sum() == 7.0 and s.values[0, 10] == 7.0
    assert not s.viseme.any()  # FAP 1 not masked in any frame
    mask[1, 0] = True
    assert make(values=values, mask=mask, viseme=viseme).viseme.tolist() == [[0] * 4, [4, 5, 6, 1]]


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"fps": 0}, "fps must be finite and > 0, got 0"),
        ({"fps": -25}, "fps must be finite and > 0"),
        ({"fps": math.nan}, "fps must be finite and > 0"),
        ({"fps": "fast"}, "fps must be a number, got 'fast'"),
        ({"name": ""}, "name must be non-empty"),
        ({"name": " lead"}, "name must be non-empty"),
        ({"name": "two\nlines"}, "name must be non-empty"),
        ({"name": "#comment"}, "no word starting with '#'"),
        ({"name": "a #comment"}, "no word starting with '#'"),
        ({"name": 3}, "name must be a string"),
        ({"version": "3.0"}, "version must be one of 2.0, 2.1, got '3.0'"),
        ({"first_frame": -1}, "first_frame must be an integer ≥ 0, got -1"),
        ({"first_frame": 1.0}, "first_frame must be an integer ≥ 0"),
        ({"values": np.zeros((3, 67))}, r"values must have shape \(n, 68\), got \(3, 67\)"),
        ({"values": np.zeros(68)}, r"values must have shape \(n, 68\)"),
        ({"values": [["a"] * 68] * 3}, "values must be a numeric array"),
        ({"mask": np.ones((2, 68), bool)}, r"mask must have shape \(3, 68\) like values"),
        ({"mask": np.full((3, 68), 2)}, "mask must hold booleans"),
        ({"viseme": np.zeros((3, 3))}, r"viseme must have shape \(3, 4\), got \(3, 3\)"),
        ({"viseme": np.full((3, 4), 0.5)}, "viseme must hold integers"),
        (
            {"viseme": [[0, 15, 0, 0]] * 3},
            r"viseme\[0, 1\] \(viseme_select2\) must be 0–14, got 15",
        ),
        (
            {"expression": [[0, 0, 0, 64, 0, 0]] * 3},
            r"expression\[0, 3\] \(expression_intensity2\) must be 0–63, got 64",
        ),
    ],
)
def test_validation(kw: dict[str, Any], message: str) -> None:
    with pytest.raises(FapError, match=message):
        make(3, **kw)


def test_validation_of_values() -> None:
    values = np.zeros((3, 68))
    values[1, 5] = np.inf
    with pytest.raises(FapError, match="values must be finite"):
        make(values=values)
    values = np.zeros((3, 68))
    values[1, 0] = 3
    with pytest.raises(FapError, match="values columns 0 and 1 .FAPs 1 and 2. must be zero"):
        make(values=values)


def test_equality() -> None:
    a = read_fap(DATA / "xface-test.fap")
    b = read_fap(DATA / "xface-test.fap")
    assert a == b and not (a != b)
    b.values[3, 4] += 1e-12
    assert a != b
    assert a != make() and a != "xface"
    for change in ({"fps": 30.0}, {"name": "other"}, {"first_frame": 1}, {"version": "2.0"}):
        fields = {
            "fps": a.fps,
            "name": a.name,
            "values": a.values,
            "mask": a.mask,
            "viseme": a.viseme,
            "expression": a.expression,
            "first_frame": 0,
            "version": "2.1",
        }
        assert FapStream(**fields) == a
        assert FapStream(**(fields | change)) != a
    with pytest.raises(TypeError):
        hash(a)


def test_empty_stream_starts_at_0() -> None:
    s = make(0, first_frame=5)
    assert s.first_frame == 0 and s.duration == 0.0


# --- resample ----------------------------------------------------------------------------------


def ramp(n: int, fps: float) -> FapStream:
    """FAP 3 = frame time in ms, FAP 4 = 1 everywhere, FAP 5 masked in frames 2 and 3 only."""
    values = np.zeros((n, 68))
    mask = np.zeros((n, 68), dtype=bool)
    values[:, 2] = np.arange(n) * 1000 / fps
    values[:, 3] = 1.0
    mask[:, 2:4] = True
    mask[2:4, 4] = True
    values[2:4, 4] = 10.0
    return FapStream(fps=fps, name="ramp", values=values, mask=mask, first_frame=1)


def test_resample_to_same_rate_is_identity() -> None:
    s = read_fap(DATA / "xface-hate.fap")
    assert s.resample(25) == s


def test_resample_25_to_30_interpolates_linearly() -> None:
    s = ramp(10, 25.0)
    r = s.resample(30)
    assert r.fps == 30.0 and r.n_frames == 12 and r.duration == pytest.approx(s.duration)
    assert (r.name, r.first_frame, r.version) == ("ramp", 1, "2.1")
    # Output frame j at j/30 s; the ramp is linear in time up to the last input frame (360 ms).
    t = np.arange(12) * 1000 / 30
    assert np.allclose(r.values[:, 2], np.minimum(t, 360.0))
    assert np.all(r.values[:, 3] == 1.0) and r.mask[:, 2:4].all()
    # Frames that coincide in time (0, 200 ms) are copied exactly.
    assert r.values[0, 2] == 0.0 and r.values[6, 2] == 200.0


def test_resample_mask_needs_both_neighbours() -> None:
    r = ramp(10, 25.0).resample(30)
    # FAP 5 is masked in input frames 2, 3 (80, 120 ms). Output frames at 66.7 ms (between 1
    # and 2), 100 ms (between 2 and 3), 133.3 ms (between 3 and 4): only the middle one has it.
    assert r.mask[:, 4].tolist() == [False] * 3 + [True] + [False] * 8
    assert r.values[3, 4] == pytest.approx(10.0)
    assert r.values[:, 4].sum() == pytest.approx(10.0)


def test_resample_high_level_from_nearest_frame() -> None:
    n = 5
    mask = np.zeros((n, 68), dtype=bool)
    mask[:, 0] = True
    mask[3:, 1] = True
    viseme = np.array([[k, 0, 63, 0] for k in range(n)])
    expression = np.array([[0] * 6] * 3 + [[1, 10, 0, 0, 0, 0], [2, 20, 0, 0, 0, 0]])
    s = FapStream(
        fps=10, name="hl", values=np.zeros((n, 68)), mask=mask, viseme=viseme, expression=expression
    )
    r = s.resample(20)  # output frame j at input position j / 2
    assert r.n_frames == 10
    # Nearest input frame of positions 0, .5, 1, 1.5, ... (halves round up), clamped to 4.
    nearest = [0, 1, 1, 2, 2, 3, 3, 4, 4, 4]
    assert r.viseme[:, 0].tolist() == nearest
    assert r.mask[:, 1].tolist() == [k >= 3 for k in nearest]
    assert r.expression[:, 1].tolist() == [
        [0, 0, 0, 0, 0, 10, 10, 20, 20, 20][j] for j in range(10)
    ]


def test_resample_down() -> None:
    s = ramp(30, 30.0)
    r = s.resample(10)
    assert r.n_frames == 10
    assert np.array_equal(r.values[:, 2], s.values[::3, 2])


def test_resample_real_file_to_30_fps() -> None:
    s = read_fap(DATA / "xface-anger.fap")
    r = s.resample(30)
    assert r.n_frames == 130  # 108 frames * 30 / 25 = 129.6
    assert np.array_equal(r.values[::6][:22], s.values[::5][:22])  # every 200 ms coincide
    lo = np.minimum(s.values[:-1], s.values[1:]).min(axis=0)
    hi = np.maximum(s.values[:-1], s.values[1:]).max(axis=0)
    assert np.all((r.values >= lo) & (r.values <= hi))


def test_resample_empty_and_errors() -> None:
    assert make(0).resample(30).n_frames == 0
    assert make(1).resample(60).n_frames == 2
    for bad in (0, -1, math.inf, math.nan):
        with pytest.raises(FapError, match="fps must be finite and > 0"):
            make(2).resample(bad)
    for fps in (1e9, 1e308):
        with pytest.raises(FapError, match="fps 1e.* is outside the limits 0.01–1000"):
            make(2).resample(fps)
    with pytest.raises(FapError, match="outside the limits"):
        make(2, fps=5e-324).resample(30)
    with pytest.raises(FapError, match="would make more than 216000 frames"):
        make(30, fps=0.01).resample(1000)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 12),
    fps_in=st.sampled_from([10.0, 12.5, 24.0, 25.0, 29.97, 30.0, 60.0]),
    fps_out=st.sampled_from([10.0, 15.0, 24.0, 25.0, 30.0, 50.0, 59.94]),
    seed=st.integers(0, 2**32 - 1),
)
def test_resample_properties(n: int, fps_in: float, fps_out: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    values = rng.normal(size=(n, 68)) * 100
    values[:, :2] = 0
    mask = rng.random((n, 68)) < 0.8
    s = FapStream(fps=fps_in, name="r", values=values, mask=mask)
    r = s.resample(fps_out)
    assert r.n_frames == math.floor(n * fps_out / fps_in + 0.5)
    assert abs(r.duration - s.duration) <= 0.5 / fps_out + 1e-9
    # Every output value lies between two neighbouring input values, masked only if both are.
    pos = np.minimum(np.arange(r.n_frames) * fps_in / fps_out, n - 1)
    i0 = np.floor(pos + 1e-9).astype(int)
    i1 = np.minimum(i0 + 1, n - 1)
    low = np.minimum(s.values[i0], s.values[i1]) - 1e-9
    high = np.maximum(s.values[i0], s.values[i1]) + 1e-9
    assert np.all((r.values >= low) & (r.values <= high))
    assert not np.any(r.mask[:, 2:] & ~s.mask[i0, 2:])
