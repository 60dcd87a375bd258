"""Long runs of integers (a large coordIndex) are read by numpy's C parser without a Python string
per word; whatever the text, the result or the error is that of the word-by-word reading."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vtts.vrml import parse
from vtts.vrml.fields import _FAST_INTS_MIN, NumberError, _ints_by_word, parse_ints

#: Words an integer run may hold, well formed or not: the fast path must read the first kind
#: exactly and hand every other to the word-by-word path.
WORDS = [
    "0", "7", "-1", "+5", "010", "-0", "2147483647", "-2147483648", "2147483648",
    "99999999999999999999", "0x1F", "-", "+", "+-1", "5-3", "1.5", "1e3", "--2", "3+", "abc",
]  # fmt: skip
SEPARATORS = [" ", ",", ", ", "\n", "\t", "  ", "\r\n"]


def outcome(fn, text: str):
    try:
        arr = fn(text)
    except NumberError as e:
        return ("error", e.word, e.offset, e.expected)
    return ("ok", arr.dtype, arr.tolist())


def word_by_word(text: str) -> np.ndarray:
    """parse_ints as it reads without the fast path."""
    lo, hi = -(2**31), 2**31 - 1
    arr = _ints_by_word(text, lo, hi)
    if arr.size and (arr.min() < lo or arr.max() > hi):
        with pytest.raises(NumberError) as info:
            parse_ints(text)
        raise info.value
    return arr


@settings(max_examples=150, deadline=None)
@given(
    st.lists(st.tuples(st.sampled_from(WORDS), st.sampled_from(SEPARATORS)), min_size=1),
    st.integers(0, 3),
    st.booleans(),
)
def test_fast_path_reads_as_word_by_word(words, bad_at, lead):
    # long enough for the fast path: repeat a clean block, then the drawn words
    clean = " ".join(str(i) for i in range(_FAST_INTS_MIN // 2))
    drawn = "".join(w + s for w, s in words)
    text = (" " if lead else "") + (clean + " " + drawn if bad_at else drawn + " " + clean)
    assert len(text) >= _FAST_INTS_MIN
    assert outcome(parse_ints, text) == outcome(word_by_word, text)


@pytest.mark.parametrize(
    "tail, word",
    [("1 5-3 2", "5-3"), ("1 - 2", "-"), ("0x10 3000000000", "3000000000"), ("4 1.5", "1.5")],
)
def test_fast_path_errors_name_the_word(tail, word):
    text = " ".join(["1"] * _FAST_INTS_MIN) + " " + tail
    with pytest.raises(NumberError) as info:
        parse_ints(text)
    assert info.value.word == word and text[info.value.offset :].startswith(word)


def test_a_large_coord_index_reads_exactly():
    n = 20000
    faces = ", ".join(f"{i} {i + 1} {i + 2} -1" for i in range(n))
    scene = parse("#VRML V2.0 utf8\nDEF F IndexedFaceSet { coordIndex [ " + faces + " ] }\n")
    ci = scene.node("F")["coordIndex"]
    assert ci.dtype == np.int32 and ci.size == 4 * n
    assert ci[-4:].tolist() == [n - 1, n, n + 1, -1]
