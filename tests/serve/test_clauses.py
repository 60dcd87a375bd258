"""Text cut into clauses as it arrives (vtts.serve.clauses) and the media messages' coding
(vtts.serve.protocol)."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.serve import protocol
from vtts.serve.clauses import ClauseCutter


def cut(pieces: list[str], max_words: int = 20) -> tuple[list[str], list[str]]:
    c = ClauseCutter(max_words)
    out = []
    for p in pieces:
        out += c.feed(p)
    return out, c.flush()


def test_clauses_end_at_punctuation_followed_by_space():
    out, rest = cut(["Hello", " there, how", " are you", " today? I am", " fine."])
    assert out == ["Hello there,", "how are you today?"]
    assert rest == ["I am fine."]


def test_a_bookmark_is_never_cut_and_stays_with_its_clause():
    out, rest = cut(["Well <joy 2s, 0.5> then, <smile>", " again. ", "<blink>"])
    assert out == ["Well <joy 2s, 0.5> then,", "<smile> again."]
    assert rest == []  # only a bookmark: nothing to say


def test_numbers_escapes_and_a_mark_at_the_end_wait():
    c = ClauseCutter()
    assert c.feed("It costs 3.5 dollars.") == []  # the full stop may be followed by more
    assert c.feed(" Then\\, no cut, ") == ["It costs 3.5 dollars.", "Then\\, no cut,"]


def test_a_text_without_punctuation_is_cut_after_max_words():
    out, rest = cut(["one two three four five six seven"], max_words=3)
    assert out == ["one two three", "four five six"]
    assert rest == ["seven"]


def test_clear_forgets_pending_text():
    c = ClauseCutter()
    c.feed("half a <smi")
    c.clear()
    assert c.feed("done. ") == ["done."] and len(c) == 0


def test_media_round_trip():
    samples = np.array([0, 1, -32768, 32767], dtype=np.int16)
    a = protocol.unpack(protocol.pack_audio(3, 1, 44100, samples))
    assert (a.utterance, a.clause, a.first) == (3, 1, 44100)
    np.testing.assert_array_equal(a.samples, samples)
    values = np.arange(12, dtype=np.float32).reshape(3, 4)
    f = protocol.unpack(protocol.pack_face(3, 2, 1.25, 30.0, values))
    np.testing.assert_array_equal(f.values, values)
    np.testing.assert_allclose(f.times(), [1.25, 1.25 + 1 / 30, 1.25 + 2 / 30])


@pytest.mark.parametrize(
    "data, said",
    [
        (b"\x01\x01", "header"),
        (b"\x09\x01\x00\x00" + bytes(8), "unknown media kind 9"),
        (b"\x01\x07\x00\x00" + bytes(8), "version 7"),
        (protocol.pack_face(1, 0, 0.0, 30.0, np.zeros((2, 2)))[:-1], "2×2 values"),
    ],
)
def test_bad_media_is_refused(data, said):
    with pytest.raises(protocol.ProtocolError, match=said):
        protocol.unpack(data)
