"""Fuzzing the reader: whatever the text, the only exception is FapError."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vtts.errors import FapError
from vtts.fap import FapStream, format_fap, parse_fap
from vtts.fap.stream import WRITE_VERSION

from ..fuzzing import examples
from ..hostile import mutate, mutations

DATA = Path(__file__).resolve().parent.parent / "data" / "fap"
# A short real file keeps each example fast: the header and the first 6 frames of xface-hate.
REAL_LINES = (DATA / "xface-hate.fap").read_text().split("\n")[:13]
REAL = "\n".join(REAL_LINES) + "\n"

FUZZ = settings(
    max_examples=examples(200), deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


def parse_or_fap_error(text: str) -> FapStream | None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            stream = parse_fap(text, file="fuzz.fap")
        except FapError as e:
            assert e.file == "fuzz.fap" and e.line is not None and e.line >= 1
            assert e.message and str(e)
            return None
    # Whatever was accepted must also write and read back unchanged, but for the version: a
    # 2.0 file is written as 2.1, the version we write.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        back = parse_fap(format_fap(stream))
    assert back.version == WRITE_VERSION
    back.version = stream.version
    assert back == stream
    return stream


def test_real_prefix_parses() -> None:
    s = parse_or_fap_error(REAL)
    assert s is not None and s.n_frames == 6


@FUZZ
@given(st.binary(max_size=2000))
def test_random_bytes(data: bytes) -> None:
    parse_or_fap_error(data.decode("latin-1"))


@FUZZ
@given(st.text(max_size=300))
def test_random_unicode_text(text: str) -> None:
    parse_or_fap_error(text)
    parse_or_fap_error("2.1 x 25 1\n" + text)


@FUZZ
@given(st.binary(max_size=200))
def test_random_bytes_after_a_header(data: bytes) -> None:
    parse_or_fap_error("2.1 x 25 1\n" + data.decode("latin-1"))


@FUZZ
@given(mutations)
def test_mutated_real_file(ops: list[tuple[str, int, int, str]]) -> None:
    parse_or_fap_error(mutate(REAL, ops))


TOKENS = ["0", "1", "2", "-3", "4.5", "1e999", "x", "#", "63", "64", "14", "15"]


def words(alphabet: list[str], min_size: int = 0, *, max_size: int) -> st.SearchStrategy:
    """Lists of words of ``alphabet``, drawn as one byte string, a byte a word (one draw instead
    of one a word: the draws were most of the test's time)."""
    return st.binary(min_size=min_size, max_size=max_size).map(
        lambda b: [alphabet[x % len(alphabet)] for x in b]
    )


@FUZZ
@given(
    masks=st.lists(words(["0", "1"], 66, max_size=70), max_size=3),
    values=st.lists(words(TOKENS, max_size=80), max_size=3),
    nframes=st.sampled_from(["0", "1", "3", "-1", "x"]),
)
def test_token_soup(masks: list[list[str]], values: list[list[str]], nframes: str) -> None:
    lines = [f"2.1 soup 25 {nframes}"]
    for i, (m, v) in enumerate(zip(masks, values, strict=False)):
        lines += [" ".join(m), " ".join([str(i), *v])]
    parse_or_fap_error("\n".join(lines) + "\n")


@FUZZ
@given(data=st.data())
def test_high_level_soup(data: st.DataObject) -> None:
    # Valid masks with FAPs 1 and 2 and random integer tokens: reaches the range checks.
    mask = ["1", "1"] + ["0"] * 66
    count = data.draw(st.integers(8, 12))
    vals = data.draw(st.lists(st.integers(-2, 70).map(str), min_size=count, max_size=count))
    s = parse_or_fap_error("2.1 hl 25 1\n" + " ".join(mask) + "\n0 " + " ".join(vals) + "\n")
    if s is not None:
        assert np.all(s.viseme >= 0) and np.all(s.expression <= 63)


def test_a_version_2_0_file_reads_back_as_written_in_2_1() -> None:
    """The case the fuzzer found: a 2.0 header (which we read) is written as 2.1 (which we
    write), everything else unchanged."""
    stream = parse_or_fap_error("2.0" + REAL[3:])
    assert stream is not None and stream.version == "2.0" and stream.n_frames == 6
