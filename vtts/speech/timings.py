"""Word and phone timings as a table: what ``vtts say --timings-out FILE.tsv`` writes.

One header line, then one row per word and per phone in time order (a word's row before the
first phone of the word), tab-separated::

    kind    start   end     label   viseme
    phone   0.0000  0.0120  _       0
    word    0.0120  0.3059  Hello   -
    phone   0.0120  0.0630  h       5
    …

``kind`` is ``word`` or ``phone``; ``start`` and ``end`` are seconds in the audio's clock (four
decimals); ``label`` is the word as written in the text or the phone as its engine names it
(espeak-ng's ``aI``, festival's ``ay``, an ARPAbet or IPA symbol); ``viseme`` the phone's MPEG-4
viseme 0–14 (``-`` for words). :func:`vtts.speech.phonemes.read_phoneme_file` reads the file back
(``say --phonemes FILE.tsv --audio …``), with each phone's viseme as written.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from vtts.atomic import write_text

__all__ = ["HEADER", "TimedPhone", "TimedWord", "format_timings", "word_ends", "write_timings"]

#: The header line's columns.
HEADER = ("kind", "start", "end", "label", "viseme")
#: Characters a label cannot hold in a TSV cell (each becomes one space, then runs of spaces an
#: underscore, so that a label stays one field).
_SEPARATORS = re.compile(r"[\t\r\n\v\f\x1c-\x1f\x85\u2028\u2029 ]+")


@dataclass
class TimedPhone:
    """A phone in the audio's clock: ``start``/``end`` in s, its MPEG-4 ``viseme`` (0–14)."""

    start: float
    end: float
    viseme: int
    phoneme: str = ""


@dataclass(frozen=True)
class TimedWord:
    """A spoken word in the audio's clock: ``start`` and ``end`` in s, ``label`` as written."""

    start: float
    end: float
    label: str


class _Phone(Protocol):
    start: float
    end: float
    viseme: int | None
    phoneme: str


def _label(text: str) -> str:
    return _SEPARATORS.sub("_", text.strip()) or "_"


def format_timings(phones: Sequence[_Phone], words: Sequence[TimedWord] = ()) -> str:
    """The table (see the module docstring) of ``phones`` (anything with ``start``, ``end``,
    ``phoneme`` and ``viseme``, e.g. :class:`TimedPhone`) and ``words``."""
    rows: list[tuple[float, int, str]] = []
    for w in words:
        line = f"word\t{w.start:.4f}\t{w.end:.4f}\t{_label(w.label)}\t-"
        rows.append((w.start, 0, line))
    for p in phones:
        vis = "-" if p.viseme is None else str(int(p.viseme))
        line = f"phone\t{p.start:.4f}\t{p.end:.4f}\t{_label(p.phoneme)}\t{vis}"
        rows.append((p.start, 1, line))
    rows.sort(key=lambda r: (round(r[0], 4), r[1]))  # stable: phones keep their order
    return "\t".join(HEADER) + "\n" + "".join(line + "\n" for _, _, line in rows)


def write_timings(
    path: str | os.PathLike[str], phones: Sequence[_Phone], words: Sequence[TimedWord] = ()
) -> None:
    """Write :func:`format_timings` to ``path`` atomically (UTF-8)."""
    write_text(path, format_timings(phones, words))


def word_ends(
    starts: Sequence[tuple[float, str]], phones: Sequence[_Phone], duration: float | None = None
) -> list[TimedWord]:
    """Words from their start times alone (Amazon Polly's ``word`` marks): each ends where the
    last phone that is not a pause ends before the next word starts (or before ``duration``,
    or the last phone's end, for the last word)."""
    spoken = [p for p in phones if p.viseme]
    last = duration if duration is not None else (phones[-1].end if phones else 0.0)
    ordered = sorted(starts, key=lambda s: s[0])
    words: list[TimedWord] = []
    for k, (start, label) in enumerate(ordered):
        limit = ordered[k + 1][0] if k + 1 < len(ordered) else last
        inside = [p.end for p in spoken if start - 1e-6 <= p.start < limit and p.end > start]
        end = min(max(inside), limit) if inside else max(min(limit, last), start)
        words.append(TimedWord(start, max(end, start), label))
    return words
