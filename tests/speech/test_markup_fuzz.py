"""Fuzzing the reader of ``vtts say`` text (issue 21): bookmarks (``<smile 2s>``, ``<fap 3=0.5>``),
SSML marks and escapes. Whatever the text, the only exception is BookmarkError with a column;
what is accepted is a valid SSML document with one mark per bookmark, its numbers are finite and
within their rules, and it reads back the same when written out again.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from vtts.errors import BookmarkError
from vtts.limits import MAX_DURATION_S, MAX_FAP_VALUE
from vtts.speech.bookmarks import Bookmark, BookmarkedText, parse_bookmarks

from ..fuzzing import examples
from ..hostile import mutate, mutations

ROOT = Path(__file__).resolve().parents[2]
TEXTS = [p.read_text(encoding="utf-8") for p in sorted((ROOT / "samples" / "texts").glob("*.txt"))]
CORPUS = [
    *TEXTS,
    "Hello <smile 2s> nice to <surprise 1.5s 0.7> meet you <blink> \\<not a bookmark> a\\\\b",
    'Look <mark name="look_left 300ms"/> there <fap 3=400 open_jaw=-20 19=1024 1s> ok <nod .5>',
    "<joy>\n<Sadness 250ms 1>line two <fap 48=+1.5>\\",
]

FUZZ = settings(
    max_examples=examples(150), deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


def _number(x: float) -> str:
    # the grammar takes plain decimals only: no exponent
    return np.format_float_positional(x, trim="-")


def written(bt: BookmarkedText) -> str:
    """The text again: pieces escaped, bookmarks in their plain form."""
    out = []
    for p in bt.pieces:
        if isinstance(p, str):
            out.append(p.replace("\\", "\\\\").replace("<", "\\<"))
            continue
        args = [p.written]
        args += [f"{k}={_number(v)}" for k, v in p.faps.items()]
        if p.duration is not None:
            args.append(_number(p.duration) + "s")
        if p.amplitude is not None:
            args.append(_number(p.amplitude))
        out.append("<" + " ".join(args) + ">")
    return "".join(out)


def same(a: Bookmark, b: Bookmark) -> bool:
    return (a.kind, a.name, a.duration, a.amplitude, a.faps, a.written) == (
        b.kind, b.name, b.duration, b.amplitude, b.faps, b.written
    )  # fmt: skip


def parse_or_bookmark_error(text: str) -> BookmarkedText | None:
    try:
        bt = parse_bookmarks(text)
    except BookmarkError as e:
        assert e.message and e.column is not None and e.column >= 1, str(e)
        return None
    root = ET.fromstring(bt.ssml())
    assert [m.get("name") for m in root.iter("mark")] == [f"b{k}" for k in range(len(bt.bookmarks))]
    assert "".join(root.itertext()) == bt.text.replace("\r\n", "\n").replace("\r", "\n")
    for b in bt.bookmarks:
        assert b.duration is None or 0 <= b.duration <= MAX_DURATION_S, b
        assert b.amplitude is None or 0 <= b.amplitude <= 1, b
        assert all(math.isfinite(v) and abs(v) <= MAX_FAP_VALUE for v in b.faps.values())
    again = parse_bookmarks(written(bt))
    assert again.text == bt.text
    assert len(again.bookmarks) == len(bt.bookmarks)
    assert all(same(a, b) for a, b in zip(again.bookmarks, bt.bookmarks, strict=True))
    return bt


def test_the_corpus_parses() -> None:
    for text in CORPUS:
        assert parse_or_bookmark_error(text) is not None


@FUZZ
@given(st.text(max_size=200))
def test_random_text(text: str) -> None:
    parse_or_bookmark_error(text)


@FUZZ
@given(st.sampled_from(CORPUS), mutations)
def test_mutated_texts(text: str, ops: list[tuple[str, int, int, str]]) -> None:
    parse_or_bookmark_error(mutate(text, ops))


PARTS = [
    "<", ">", "/>", "\\", "\\<", "\\\\", " ", "\t", "\n", "smile", "joy", "blink", "fap", "nod",
    "unknown", "mark", 'mark name="', '"', "=", "3=400", "open_jaw=1", "viseme3=1", "99=1",
    "3=1e6", "3=1000001", "2s", "300ms", "1.5s", ".5", "0.7", "1", "2", "s", "ms", "9" * 400,
    "hello", "&", "&amp;", "]]>", "<!--", "é", "\u2028",
]  # fmt: skip


@FUZZ
@given(st.lists(st.sampled_from(PARTS), max_size=25).map("".join))
@example("Hi <smile " + "9" * 400 + "s>")  # 10^400 s read as inf
@example("Hi <fap 3=5 " + "9" * 40 + "s>")
def test_markup_soup(text: str) -> None:
    parse_or_bookmark_error(text)
