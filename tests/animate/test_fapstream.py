"""A FAP stream as per-frame parameter vectors for a model: hold, FAPs 1/2, filling, resampling."""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vtts.animate.fapstream import (
    LIP_LAYER,
    MIRROR,
    MissingTableWarning,
    StreamParams,
    fill_candidates,
    hold,
    missing_fap_warning,
    plan_fills,
    resample_params,
    stream_params,
    warn_ignored,
)
from vtts.errors import FapError, VttsWarning
from vtts.face.miap import EXPRESSION_BASE, N_PARAMS, VISEME_BASE, Miap, all_miaps
from vtts.fap import FAPS, FapStream, fap, read_fap

FAP_FILES = sorted((Path(__file__).resolve().parents[1] / "data" / "fap").glob("*.fap"))
ALL = set(all_miaps())


def faps(*numbers: int) -> set[Miap]:
    return {Miap("fap", k) for k in numbers}


def make(n: int, fps: float = 25.0, **kw: Any) -> FapStream:
    """A stream of n frames with nothing masked unless given."""
    values = kw.pop("values", np.zeros((n, 68)))
    mask = kw.pop("mask", np.zeros((n, 68), dtype=bool))
    return FapStream(fps=fps, name="t", values=values, mask=mask, **kw)


def with_faps(n: int, columns: dict[int, list[float | None]], fps: float = 25.0) -> FapStream:
    """A stream setting FAP k to columns[k][i] in frame i (None: not masked in that frame)."""
    values = np.zeros((n, 68))
    mask = np.zeros((n, 68), dtype=bool)
    for k, col in columns.items():
        for i, v in enumerate(col):
            if v is not None:
                values[i, k - 1] = v
                mask[i, k - 1] = True
    return make(n, fps, values=values, mask=mask)


# --- real files ----------------------------------------------------------------------------


def test_there_are_real_files() -> None:
    assert len(FAP_FILES) >= 9


@pytest.mark.parametrize("path", FAP_FILES, ids=lambda p: p.name)
def test_real_file_at_30_fps(path: Path) -> None:
    stream = read_fap(path)
    out = stream_params(stream, ALL, fps=30)
    n = out.n_frames
    assert abs(n - round(stream.duration * 30)) <= 1
    assert out.params.shape == (n, N_PARAMS) and out.params.dtype == np.float64
    assert out.fps == 30.0 and out.times.shape == (n,)
    np.testing.assert_allclose(out.times, np.arange(n) / 30)
    assert np.all(np.isfinite(out.params))
    assert out.filled == {} and out.ignored == []
    # Frames that coincide in time (output 6j = input 5j at 25 -> 30 fps) equal the source's held
    # values exactly; the files set some FAPs only in some frames (blinks), hence the hold.
    held, *_ = hold(stream)
    for j in range(0, n, 6):
        i = j * 5 // 6
        if i < stream.n_frames:
            assert np.array_equal(out.params[j, 2:68], held[i, 2:])
    # Where the file sets a FAP, the held value is the file's own.
    assert np.array_equal(held[stream.mask], stream.values[stream.mask])
    # Every other output frame lies between its two neighbouring input frames.
    pos = np.arange(n) * 25 / 30
    i0 = np.minimum(np.floor(pos).astype(int), stream.n_frames - 1)
    i1 = np.minimum(i0 + 1, stream.n_frames - 1)
    lo = np.minimum(held[i0], held[i1])[:, 2:]
    hi = np.maximum(held[i0], held[i1])[:, 2:]
    assert np.all(out.params[:, 2:68] >= lo - 1e-9) and np.all(out.params[:, 2:68] <= hi + 1e-9)


def test_real_file_on_a_model_with_few_tables() -> None:
    stream = read_fap(FAP_FILES[0])
    # Only the left eyelid, the inner lip and the jaw: the right eyelid and outer lip are filled
    # where their counterparts are free, and the rest is ignored.
    out = stream_params(stream, faps(3, 19, 4, 5, 6, 7), fps=30)
    used = set((np.flatnonzero(stream.mask.any(axis=0)) + 1).tolist())
    assert 20 in used and 19 in used  # 19 is shown, so 20 has nowhere to go
    assert 20 in out.ignored and 19 not in out.ignored
    assert set(out.ignored) <= used and not set(out.ignored) & {3, 4, 5, 6, 7, 19}
    assert out.filled == {}  # 4-7 are set by the stream itself: never overwritten


def test_real_file_keeps_its_rate_without_fps() -> None:
    stream = read_fap(FAP_FILES[-1])
    out = stream_params(stream, ALL)
    assert out.fps == stream.fps and out.n_frames == stream.n_frames
    held, *_ = hold(stream)
    assert np.array_equal(out.params[:, 2:68], held[:, 2:])
    assert stream_params(stream, ALL, fps=25.0).n_frames == stream.n_frames


# --- hold ------------------------------------------------------------------------------------


def test_hold_last_value() -> None:
    s = with_faps(6, {19: [None, 100, None, None, 300, None], 31: [5, 5, 5, 5, 5, 5]})
    out = stream_params(s, ALL)
    assert out.params[:, 18].tolist() == [0, 100, 100, 100, 300, 300]  # 0 until first set
    assert out.params[:, 30].tolist() == [5] * 6
    assert out.params[:, 19].tolist() == [0] * 6  # never set: stays neutral


def test_hold_before_resampling() -> None:
    # FAP 19 is set only in frames 0 and 5 at 5 fps: at 10 fps it must not dip to 0 between.
    s = with_faps(6, {19: [200, None, None, None, None, 400]}, fps=5)
    out = stream_params(s, ALL, fps=10)
    col = out.params[:, 18]
    assert out.n_frames == 12
    assert col[:9].tolist() == [200] * 9
    assert col[9] == 300  # halfway between input frames 4 (held 200) and 5
    assert col[10] == 400 and col[11] == 400  # frame 10 = input 5; 11 is past the end: held


def test_hold_high_level_faps() -> None:
    mask = np.zeros((4, 68), dtype=bool)
    mask[0, :2] = True
    viseme = np.zeros((4, 4), dtype=int)
    expression = np.zeros((4, 6), dtype=int)
    viseme[0] = [3, 0, 63, 0]
    expression[0] = [1, 63, 0, 0, 0, 0]
    out = stream_params(make(4, mask=mask, viseme=viseme, expression=expression), ALL)
    assert out.params[:, VISEME_BASE + 3].tolist() == [1.0] * 4
    assert out.params[:, EXPRESSION_BASE + 1].tolist() == [1.0] * 4


@settings(max_examples=40, deadline=None)
@given(st.lists(st.one_of(st.none(), st.integers(-500, 500)), min_size=1, max_size=30))
def test_hold_matches_a_reference(column: list[int | None]) -> None:
    out = stream_params(with_faps(len(column), {31: list(column)}), ALL)
    expect, last = [], 0.0
    for v in column:
        last = float(v) if v is not None else last
        expect.append(last)
    assert out.params[:, 30].tolist() == expect


# --- FAPs 1 and 2 ------------------------------------------------------------------------------


def high_level(
    viseme: list[list[int]] | None = None, expression: list[list[int]] | None = None
) -> FapStream:
    n = len(viseme or expression or [])
    mask = np.zeros((n, 68), dtype=bool)
    mask[:, 0] = viseme is not None
    mask[:, 1] = expression is not None
    return make(n, mask=mask, viseme=viseme, expression=expression)


def test_viseme_blend() -> None:
    out = stream_params(
        high_level(
            viseme=[[1, 4, 21, 0], [7, 0, 63, 0], [0, 9, 0, 1], [5, 5, 10, 0], [0, 0, 30, 0]]
        ),
        ALL,
    )
    w = out.params[:, VISEME_BASE : VISEME_BASE + 15]
    assert w[0, 1] == pytest.approx(21 / 63) and w[0, 4] == pytest.approx(42 / 63)
    assert w[1, 7] == 1.0 and w[1].sum() == 1.0  # viseme_select2 = 0: neutral adds nothing
    assert w[2, 9] == 1.0 and w[2].sum() == 1.0  # viseme_select1 = 0, blend 0: all select2
    assert w[3, 5] == pytest.approx(1.0)  # the same viseme twice adds up
    assert not w[4].any()  # neutral and neutral
    assert not w[:, 0].any()
    assert out.params[:, VISEME_BASE + 15 :].sum() == 0  # no expression
    assert not out.params[:, :68].any()


def test_expression_intensities() -> None:
    out = stream_params(
        high_level(
            expression=[
                [1, 63, 3, 21, 0, 0],
                [0, 40, 6, 63, 1, 0],
                [2, 10, 2, 20, 0, 1],
                [0, 0, 0, 0, 0, 0],
            ]
        ),
        ALL,
    )
    w = out.params[:, EXPRESSION_BASE : EXPRESSION_BASE + 7]
    assert w[0].tolist() == pytest.approx([0, 1, 0, 21 / 63, 0, 0, 0])
    assert w[1].tolist() == pytest.approx([0, 0, 0, 0, 0, 0, 1])  # select 0: nothing
    assert w[2, 2] == pytest.approx(30 / 63)
    assert not w[3].any()
    assert not out.params[:, :EXPRESSION_BASE].any()


def test_missing_visemes_and_expressions() -> None:
    s = high_level(viseme=[[1, 4, 63, 0], [2, 0, 63, 0]])  # viseme 4 has weight 0 throughout
    out = stream_params(s, {Miap("viseme", 1)})
    assert out.missing_visemes == [2] and out.missing_expressions == [] and out.ignored == []
    s = high_level(expression=[[1, 63, 4, 0, 0, 0]])
    assert stream_params(s, set()).missing_expressions == [1]


# --- filling -----------------------------------------------------------------------------------


def test_left_right_and_inner_outer_filling() -> None:
    s = with_faps(3, {20: [10, 20, 30], 51: [-5, 0, 5]})
    out = stream_params(s, faps(19, 4))
    assert out.filled == {19: 20, 4: 51} and out.ignored == []
    assert out.params[:, 18].tolist() == [10, 20, 30]
    assert out.params[:, 3].tolist() == [-5, 0, 5]


def test_no_filling_when_the_model_shows_the_fap() -> None:
    s = with_faps(3, {19: [10, 20, 30]})
    out = stream_params(s, faps(19, 20))
    assert out.filled == {} and out.ignored == []
    assert out.params[:, 19].tolist() == [0, 0, 0]  # 20 left alone


def test_never_overwrites_what_the_stream_sets() -> None:
    # The model shows 19 only; the stream sets both 19 and 20: 20 cannot go anywhere.
    s = with_faps(2, {19: [1, 2], 20: [7, 8]})
    out = stream_params(s, faps(19))
    assert out.params[:, 18].tolist() == [1, 2]
    assert out.filled == {} and out.ignored == [20]


def test_filling_respects_time_varying_masks() -> None:
    s = with_faps(4, {20: [None, 50, None, 0]})
    out = stream_params(s, faps(19))
    assert out.params[:, 18].tolist() == [0, 50, 50, 0]


def test_ranks_inner_outer_before_sides() -> None:
    # Outer left corner stretch (53) on a model with only the inner corners: inner left (6)
    # first; outer right (54) then falls to its own inner counterpart (7).
    assert plan_fills([53, 54], [6, 7]) == ({6: 53, 7: 54}, [])
    # Only 6 shown: 53 (same place) wins it over 7 (other side), so 7 is ignored.
    assert plan_fills([7, 53], [6]) == ({6: 53}, [7])
    # Diagonal: the outer right corner shown only as the inner left one.
    assert plan_fills([54], [6]) == ({6: 54}, [])
    # No counterparts at all.
    assert plan_fills([3, 48, 27], [19]) == ({}, [3, 27, 48])
    assert fill_candidates(53) == [6, 54, 7] and fill_candidates(19) == [20]
    assert fill_candidates(4) == [51] and fill_candidates(3) == []


def test_ignored_are_sorted_and_only_used_faps() -> None:
    s = with_faps(2, {48: [1, 1], 27: [None, 3], 28: [2, None], 3: [0, 0]})
    out = stream_params(s, faps(3))
    assert out.ignored == [27, 28, 48]  # 27 and 28 both lack a shown counterpart


@settings(max_examples=60, deadline=None)
@given(st.sets(st.integers(3, 68)), st.sets(st.integers(3, 68)))
def test_plan_fills_properties(used: set[int], shown: set[int]) -> None:
    filled, ignored = plan_fills(used, shown)
    sources = list(filled.values())
    assert len(sources) == len(set(sources))
    for target, source in filled.items():
        assert target in shown and target not in used
        assert source in used and source not in shown
        assert target in fill_candidates(source)
    assert set(ignored) == (used - shown) - set(sources)
    assert ignored == sorted(ignored)


def test_pairs_follow_the_fap_table() -> None:
    assert {(a, b) for a, b in MIRROR.items() if a < b} >= {
        (6, 7), (8, 9), (10, 11), (12, 13), (19, 20), (21, 22), (23, 24), (25, 26), (27, 28),
        (29, 30), (31, 32), (33, 34), (35, 36), (37, 38), (39, 40), (41, 42), (53, 54),
        (55, 56), (57, 58), (59, 60), (61, 62), (65, 66), (67, 68),
    }  # fmt: skip
    assert len(MIRROR) == 46 and all(MIRROR[MIRROR[k]] == k for k in MIRROR)
    assert {(k, LIP_LAYER[k]) for k in range(4, 14)} == {(k, k + 47) for k in range(4, 14)}
    for a, b in MIRROR.items():
        fa, fb = fap(a), fap(b)
        assert (fa.fapu, fa.bidirectional) == (fb.fapu, fb.bidirectional)
        ma, mb = fa.positive_motion, fb.positive_motion
        # Copying a value unchanged is right: horizontal motions mirror each other, except the
        # eyeballs' yaw (conjugate gaze); all others are the same motion on both sides.
        if {ma, mb} <= {"left", "right"} and "yaw" not in fa.name:
            assert ma != mb, (a, b)
        else:
            assert ma == mb, (a, b)
    for k in range(4, 14):
        assert fap(k).positive_motion == fap(LIP_LAYER[k]).positive_motion
        assert fap(k).fapu == fap(LIP_LAYER[k]).fapu
    assert all(f.number in MIRROR for f in FAPS if "_l_" in f.name or "_r_" in f.name)


# --- resampling -------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [0, 1, 2, 25, 108])
def test_resampling_25_to_30_keeps_duration(n: int) -> None:
    s = with_faps(n, {3: list(range(n))}) if n else make(0)
    out = stream_params(s, ALL, fps=30)
    assert out.n_frames == round(n * 30 / 25)
    assert abs(out.duration - s.duration) <= 0.5 / 30 + 1e-12
    if n >= 2:
        expect = np.minimum(np.arange(out.n_frames) * 25 / 30, n - 1)
        np.testing.assert_allclose(out.params[:, 2], expect, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(
    st.integers(1, 80),
    st.sampled_from([10.0, 12.5, 24.0, 25.0, 29.97, 30.0, 60.0]),
    st.sampled_from([15.0, 25.0, 30.0, 50.0]),
)
def test_resample_params_properties(n: int, fps_in: float, fps_out: float) -> None:
    rng = np.random.default_rng(n)
    rows = rng.normal(size=(n, 3))
    out = resample_params(rows, fps_in, fps_out)
    assert out.shape == (math.floor(n * fps_out / fps_in + 0.5), 3)
    assert abs(out.shape[0] / fps_out - n / fps_in) <= 0.5 / fps_out + 1e-9
    if out.shape[0]:
        assert np.array_equal(out[0], rows[0])
        assert np.all(out <= rows.max(axis=0) + 1e-12) and np.all(out >= rows.min(axis=0) - 1e-12)


def test_viseme_weights_crossfade_when_resampled() -> None:
    s = high_level(viseme=[[1, 0, 63, 0], [2, 0, 63, 0]])
    out = stream_params(s, ALL, fps=50)  # 25 -> 50: frame 1 halfway between
    assert out.params[1, VISEME_BASE + 1] == pytest.approx(0.5)
    assert out.params[1, VISEME_BASE + 2] == pytest.approx(0.5)


def test_bad_arguments() -> None:
    s = make(2)
    with pytest.raises(FapError, match="fps"):
        stream_params(s, ALL, fps=0)
    with pytest.raises(FapError, match="fps"):
        stream_params(s, ALL, fps="fast")  # type: ignore[arg-type]
    with pytest.raises(FapError, match="Miap"):
        stream_params(s, [19])  # type: ignore[list-item]
    with pytest.raises(FapError, match="more than"):
        resample_params(np.zeros((10, 1)), 1e-3, 1e6)


# --- the warning -------------------------------------------------------------------------------


def test_missing_fap_warning_text() -> None:
    assert missing_fap_warning([28, 27], "cybatt") == (
        "model cybatt has no tables for FAPs 27 thrust_l_eyeball, 28 thrust_r_eyeball; "
        "they are ignored"
    )
    assert missing_fap_warning([48], "m") == (
        "model m has no table for FAP 48 head_pitch; it is ignored"
    )
    assert missing_fap_warning([]) == ""
    assert missing_fap_warning([3], visemes=[1], expressions=[1, 2]) == (
        "the model has no tables for FAP 3 open_jaw, viseme 1 (p, b, m) and "
        "expressions 1 (joy), 2 (sadness); they are ignored"
    )


def test_warn_ignored_emits_once() -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        message = warn_ignored("cybatt", [27, 28])
        assert warn_ignored("cybatt", []) is None
    assert len(caught) == 1
    w = caught[0].message
    assert isinstance(w, MissingTableWarning) and isinstance(w, VttsWarning)
    assert str(w) == message and "27 thrust_l_eyeball, 28 thrust_r_eyeball" in message


def test_warn_ignored_from_stream_params() -> None:
    s = with_faps(2, {27: [1, 1], 48: [0, 5]})
    out = stream_params(s, faps(19))
    assert isinstance(out, StreamParams)
    with pytest.warns(MissingTableWarning, match=r"FAPs 27 thrust_l_eyeball, 48 head_pitch"):
        warn_ignored("cybatt", out)
