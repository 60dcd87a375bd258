"""Writing .fap files: exact version 2.1 output and lossless round trips."""

from __future__ import annotations

import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, reject, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from vtts.errors import FapError
from vtts.fap import FapStream, format_fap, parse_fap, read_fap, write_fap
from vtts.limits import MAX_FPS, MIN_FPS

DATA = Path(__file__).resolve().parent.parent / "data" / "fap"
REAL_FILES = sorted(DATA.glob("*.fap"))


def small_stream() -> FapStream:
    values = np.zeros((2, 68))
    mask = np.zeros((2, 68), dtype=bool)
    mask[:, [0, 2, 3]] = True
    mask[1, 1] = True
    values[0, 2:4] = [5.0, -0.1]
    values[1, 2:4] = [1e20, 2.5e-7]
    viseme = [[1, 2, 63, 0], [0, 14, 0, 1]]
    expression = [[0, 0, 0, 0, 0, 0], [6, 63, 1, 0, 1, 1]]
    return FapStream(
        fps=30,
        name="my clip",
        values=values,
        mask=mask,
        viseme=viseme,
        expression=expression,
        first_frame=1,
    )


def test_format_exactly() -> None:
    m0 = "1 0 1 1 " + " ".join(["0"] * 64)
    m1 = "1 1 1 1 " + " ".join(["0"] * 64)
    assert format_fap(small_stream()) == (
        "2.1 my clip 30 2\n"
        f"{m0}\n"
        "1 1 2 63 0 5 -0.1\n"
        f"{m1}\n"
        "2 0 14 0 1 6 63 1 0 1 1 1e+20 2.5e-07\n"
    )  # fmt: skip


@pytest.mark.parametrize(
    "name", ["take#2", "a\xa0#b", "C:\\My Files\\x y", "a\tb", "été", "a\x0bb", "a  b", "x#"]
)
def test_names_survive_the_header(name: str) -> None:
    s = FapStream(fps=25, name=name, values=np.zeros((0, 68)), mask=np.zeros((0, 68), bool))
    assert parse_fap(format_fap(s)).name == name


@pytest.mark.parametrize("name", ["", "a #b", "a\t#b", "#a", " a", "a ", "a\nb", "a\rb"])
def test_names_that_cannot_be_written(name: str) -> None:
    with pytest.raises(FapError, match="name must be non-empty"):
        FapStream(fps=25, name=name, values=np.zeros((0, 68)), mask=np.zeros((0, 68), bool))


def test_format_non_integral_fps_and_version_2_0() -> None:
    s = FapStream(
        fps=29.97, name="x", values=np.zeros((0, 68)), mask=np.zeros((0, 68), bool), version="2.0"
    )
    assert format_fap(s) == "2.1 x 29.97 0\n"


def test_write_fap_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "out.fap"
    s = small_stream()
    write_fap(s, path)
    assert path.read_text(encoding="utf-8") == format_fap(s)
    assert read_fap(path) == s
    assert [p.name for p in path.parent.iterdir()] == ["out.fap"]  # no temporary left


@pytest.mark.parametrize("path", REAL_FILES, ids=lambda p: p.stem)
def test_real_file_round_trip(path: Path, tmp_path: Path) -> None:
    s = read_fap(path)
    out = tmp_path / path.name
    write_fap(s, out)
    assert read_fap(out) == s
    # Xface files are already exact 2.1: writing reproduces them but for trailing blanks.
    original = "\n".join(line.rstrip() for line in path.read_text().split("\n"))
    assert format_fap(s) == original


@pytest.mark.parametrize(
    "value",
    [0.1, -0.0, 1e-300, 5e-324, sys.float_info.max, -sys.float_info.max, 1e16, 1e15 + 0.5,
     2.0**53 + 2, 123456789.125, -1 / 3, math.pi],
)  # fmt: skip
def test_float_round_trip(value: float) -> None:
    values = np.zeros((1, 68))
    values[0, 5] = value
    mask = np.zeros((1, 68), dtype=bool)
    mask[0, 5] = True
    s = FapStream(fps=1 / 3, name="f", values=values, mask=mask)
    back = parse_fap(format_fap(s))
    assert back == s and back.values[0, 5] == value and back.fps == 1 / 3


# --- property: any valid stream survives write -> read ----------------------------------------

TRICKY = st.sampled_from(list("a#  \t\x0b\x0c\xa0\x85\u2028é\\:."))
ANY_CHAR = st.characters(blacklist_categories=("Cs",))
# Any text: the names FapStream refuses are skipped, so that the test checks that every name
# it accepts survives the header.
names = st.one_of(st.text(TRICKY, max_size=8), st.text(ANY_CHAR, max_size=12))
finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
fps_values = st.one_of(
    st.integers(1, 240).map(float),
    st.floats(min_value=MIN_FPS, max_value=MAX_FPS, allow_nan=False, allow_infinity=False),
)


def _writable(name: str) -> bool:
    """Whether :class:`FapStream` accepts ``name`` (a name it refuses is skipped)."""
    try:
        FapStream(fps=25, name=name, values=np.zeros((0, 68)), mask=np.zeros((0, 68), bool))
    except FapError as e:
        assert "name must be" in e.message
        return False
    return True


def high_level(draw: st.DrawFn, ranges: list[tuple[int, int]], sent: np.ndarray) -> np.ndarray:
    """``(n, len(ranges)) int64``: a high-level FAP's parameters in each of the ``n`` frames,
    each column within its range; drawn only if a frame sends the FAP (``sent``): the stream
    stores 0 where none does."""
    n = len(sent)
    if not sent.any():
        return np.zeros((n, len(ranges)), dtype=np.int64)
    columns = [draw(hnp.arrays(np.int64, n, elements=st.integers(lo, hi))) for lo, hi in ranges]
    return np.column_stack(columns).reshape(n, len(ranges))


@st.composite
def streams(draw: st.DrawFn) -> FapStream:
    """Any valid stream. The name is drawn first and a refused one rejected before the arrays
    are drawn; values are drawn only where the mask sets a low-level FAP (the stream stores 0
    elsewhere), the high-level parameters only if a frame sets FAP 1 or 2."""
    name = draw(names)
    if not _writable(name):
        reject()
    n = draw(st.integers(0, 5))
    mask = draw(hnp.arrays(np.bool_, (n, 68)))
    low = mask.copy()
    low[:, :2] = False
    values = np.zeros((n, 68))
    values[low] = draw(
        hnp.arrays(
            np.float64,
            int(low.sum()),
            elements=st.one_of(finite, st.integers(-5000, 5000).map(float)),
        )
    )
    viseme = high_level(draw, [(0, 14), (0, 14), (0, 63), (0, 1)], mask[:, 0])
    expression = high_level(draw, [(0, 6), (0, 63), (0, 6), (0, 63), (0, 1), (0, 1)], mask[:, 1])
    return FapStream(
        fps=draw(fps_values),
        name=name,
        values=values,
        mask=mask,
        viseme=viseme,
        expression=expression,
        first_frame=draw(st.integers(0, 10**6)),
    )


@settings(max_examples=150, deadline=None)
@given(streams())
def test_write_read_is_lossless(stream: FapStream) -> None:
    text = format_fap(stream)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the written header's frame count is right
        back = parse_fap(text)
    assert back == stream
    lines = text.split("\n")
    assert lines[0].startswith("2.1 ") and lines[-1] == ""
    assert all(len(line.split(" ")) == 68 for line in lines[1:-1:2])
    assert format_fap(back) == text
