"""Text with bookmarks: ``Hello <smile 5s> nice to <surprise 1.5s 0.7> meet you <blink>``.

A bookmark is ``<NAME [DURATION] [AMPLITUDE]>`` where NAME is an expression (joy, sadness, anger,
fear, disgust, surprise, or an alias such as smile), an action (blink, nod, shake, look_left …),
or ``fap`` with explicit values (``<fap 3=400 19=1024 1s>``); DURATION is in s or ms, AMPLITUDE
in 0–1. SSML ``<mark name="smile 2s"/>`` carries a bookmark in its name. ``\\<`` is a literal
``<``. The grammar is ``grammars/bookmarks.lark``.

The text goes to the speech synthesizer as SSML with one ``<mark/>`` per bookmark, so each
bookmark gets its time in the audio from the synthesizer's own mark event.

Punctuation right after bookmarks (``people <sad>.``) is spoken before them (``people.<mark/>``):
left after a mark, away from its word, espeak-ng reads a full stop aloud as "dot" (its SSML mode
does so even for ``people<mark/>.``). Such a bookmark's time is the end of the word before it,
where espeak-ng puts a mark written before the punctuation
(:attr:`BookmarkedText.before_punctuation`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from functools import cache

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedInput

from vtts.errors import BookmarkError, FapError
from vtts.face.miap import EXPRESSION_ALIASES, Miap
from vtts.limits import MAX_DURATION_S, MAX_FAP_VALUE
from vtts.resources import lark_parser
from vtts.speech.tts import escape

EXPRESSIONS = ("joy", "sadness", "anger", "fear", "disgust", "surprise")
#: Actions a bookmark can ask for; each maps to an autonomous behaviour it overrides.
ACTIONS = {
    "blink": "blink",
    "nod": "nod",
    "shake": "head_motion",
    "look_left": "gaze",
    "look_right": "gaze",
    "look_up": "gaze",
    "look_down": "gaze",
    "look_ahead": "gaze",
}


@dataclass
class Bookmark:
    """One bookmark.

    kind       ``"expression"``, ``"action"`` or ``"fap"``
    name       the expression (canonical, e.g. ``joy`` for ``smile``) or action name
    duration   seconds, or None for the model's default
    amplitude  0–1, or None for the default (1)
    faps       FAP number → value in FAP units (``fap`` bookmarks)
    column     1-based column of the bookmark in the text (for messages)
    written    the name as written (``smile``)
    """

    kind: str
    name: str
    duration: float | None = None
    amplitude: float | None = None
    faps: dict[int, float] = field(default_factory=dict)
    column: int = 0
    written: str = ""
    time: float | None = None  # seconds in the audio, once known


@dataclass
class BookmarkedText:
    """Text pieces and bookmarks in order, as spoken.

    pieces              the spoken text and the bookmarks, in order; punctuation written right
                        after bookmarks is moved before them, onto its word (see the module)
    before_punctuation  indices (in :attr:`bookmarks`) of the bookmarks written before such
                        punctuation, whose time is the end of the word before them
    """

    pieces: list[str | Bookmark]
    before_punctuation: frozenset[int] = frozenset()

    @property
    def bookmarks(self) -> list[Bookmark]:
        return [p for p in self.pieces if isinstance(p, Bookmark)]

    @property
    def text(self) -> str:
        """The plain text that is spoken."""
        return "".join(p for p in self.pieces if isinstance(p, str))

    def ssml(self) -> str:
        """SSML for the synthesizer: the text escaped, ``<mark name="bN"/>`` per bookmark."""
        out = ["<speak>"]
        k = 0
        for p in self.pieces:
            if isinstance(p, str):
                out.append(escape(p))
            else:
                out.append(f'<mark name="b{k}"/>')
                k += 1
        out.append("</speak>")
        return "".join(out)

    def check_names(self, expressions: set[str], model: str = "the model") -> list[Bookmark]:
        """Bookmarks naming an expression the model has no table for (to warn about)."""
        return [b for b in self.bookmarks if b.kind == "expression" and b.name not in expressions]


@cache
def _lark() -> Lark:
    # the tables kept between processes: building them again would slow every vtts say's
    # start (docs/speech.md, "Speed")
    return lark_parser("bookmarks", parser="lalr", lexer="contextual", maybe_placeholders=False)


def known_names(expressions: set[str] | None = None) -> list[str]:
    """The bookmark names that work, for messages: the expressions (of a model, when given) with
    their aliases, the actions, and ``fap``."""
    shown = [e for e in EXPRESSIONS if expressions is None or e in expressions]
    names = []
    for e in shown:
        aliases = sorted(a for a, target in EXPRESSION_ALIASES.items() if target == e)
        names.append(f"{e} ({', '.join(aliases)})" if aliases else e)
    return [*names, *ACTIONS, "fap"]


#: Characters that SSML (XML 1.0) cannot hold, so that no synthesizer can be given them.
_UNSPEAKABLE = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


def parse_bookmarks(text: str, known: set[str] | None = None) -> BookmarkedText:
    """Parse text with bookmarks; errors are :class:`BookmarkError` with the column (1-based;
    and the line, when the text has several) and, for unknown names, the names that work:
    ``known`` is the set of expressions the model has tables for (None: all six)."""
    lines = "\n" in text
    bad = _UNSPEAKABLE.search(text)
    if bad is not None:
        line = text.count("\n", 0, bad.start()) + 1
        col = bad.start() - (text.rfind("\n", 0, bad.start()) + 1) + 1
        error = BookmarkError(
            f"column {col}: the control character {bad.group()!r} cannot be spoken (SSML cannot "
            "hold it); remove it",
            column=col,
        )
        raise _on_line(error, line) if lines else error
    try:
        tree = _lark().parse(text)
    except UnexpectedInput as e:
        col = getattr(e, "column", 0) or 1
        pos = getattr(e, "pos_in_stream", None)
        near = text[pos : pos + 12] if pos is not None else ""
        error = BookmarkError(
            f"column {col}: cannot read a bookmark here ({near!r}); a bookmark is "
            "<NAME [DURATION] [AMPLITUDE]> or <fap N=V ... [DURATION]>, and \\< writes a "
            "literal <",
            column=col,
        )
        raise (_on_line(error, getattr(e, "line", 1)) if lines else error) from None
    pieces: list[str | Bookmark] = []
    for item in tree.children:
        try:
            _add_piece(pieces, item, known)
        except BookmarkError as e:
            if not lines:
                raise
            token = item if isinstance(item, Token) else item.children[0]
            raise _on_line(e, token.line) from None
    return _punctuation_on_its_word(pieces)


#: Stands for a bookmark in the text while punctuation is moved (the text cannot hold it:
#: :data:`_UNSPEAKABLE`).
_MARK = "\x00"
#: Bookmarks (with spaces around and between them) after a word, then punctuation that stands
#: alone (a space, another bookmark or the end after it; not the decimal point of ``.5``). The
#: word's last character is not punctuation itself: ``Hello. <sad>. Bye`` stays as it is (espeak
#: reads a second full stop after a first one silently, and ``Hello..`` would lose the pause).
_DETACHED = re.compile(
    r"(?<=[^\s\x00.,!?;:\u2026])\s*(?P<marks>\x00(?:\s*\x00)*)\s*"
    r"(?P<punct>[.,!?;:\u2026]+[\"')\]\u00bb\u201d\u2019]*)(?=[\s\x00]|\Z)"
)


def _punctuation_on_its_word(pieces: list[str | Bookmark]) -> BookmarkedText:
    """The pieces with each punctuation run written after bookmarks moved before them, right after
    its word: ``people <sad> <blink>. Bye`` is spoken ``people.<sad><blink> Bye``."""
    marks = [p for p in pieces if isinstance(p, Bookmark)]
    flat = "".join(_MARK if isinstance(p, Bookmark) else p for p in pieces)
    moved: set[int] = set()

    def attach(m: re.Match) -> str:
        first = flat.count(_MARK, 0, m.start("marks"))
        n = m.group("marks").count(_MARK)
        moved.update(range(first, first + n))
        return m.group("punct") + _MARK * n

    spoken = _DETACHED.sub(attach, flat)
    out: list[str | Bookmark] = []
    for k, text in enumerate(spoken.split(_MARK)):
        if k:
            out.append(marks[k - 1])
        if text:
            out.append(text)
    return BookmarkedText(out, frozenset(moved))


def _on_line(error: BookmarkError, line: int) -> BookmarkError:
    """``error`` (whose message starts with ``column N:``) placed on ``line`` of a text of several
    lines: the line and column become its location (``FILE:LINE:COLUMN:`` in messages)."""
    message = (
        error.message.split(": ", 1)[1] if error.message.startswith("column ") else error.message
    )
    return BookmarkError(message, line=line, column=error.column)


def _add_piece(pieces: list[str | Bookmark], item, known: set[str] | None) -> None:
    """Append the parse tree's ``item`` (text, a bookmark or an SSML mark) to ``pieces``."""
    if isinstance(item, Token):
        piece = item[1:] if item.type == "ESCAPE" else str(item)
        if pieces and isinstance(pieces[-1], str):
            pieces[-1] += piece
        else:
            pieces.append(piece)
    elif item.data == "bookmark":
        pieces.append(_bookmark(item, item.children[0].column, known))
    else:  # an SSML mark: its name holds a bookmark
        quoted = item.children[1]
        inner = str(quoted)[1:-1]
        try:
            sub = _lark().parse(f"<{inner}>")
            (bm_tree,) = [c for c in sub.children if isinstance(c, Tree)]
        except (UnexpectedInput, ValueError):
            raise BookmarkError(
                f'column {quoted.column}: mark name {inner!r} is not a bookmark such as "smile 2s"',
                column=quoted.column,
            ) from None
        try:
            pieces.append(_bookmark(bm_tree, item.children[0].column, known))
        except BookmarkError as e:
            reason = e.message.split(": ", 1)[-1]
            raise BookmarkError(
                f"column {quoted.column}: mark name {inner!r} is not a bookmark: {reason}",
                column=quoted.column,
            ) from None


def _bookmark(t: Tree, column: int, known: set[str] | None = None) -> Bookmark:
    name_tok = t.children[1]
    written = str(name_tok)
    key = written.lower()
    args = [c for c in t.children[2:] if c.type != "CLOSE"]
    duration = amplitude = None
    faps: dict[int, float] = {}
    for a in args:
        v = str(a).strip()
        if a.type == "BAD_ARG":
            col = a.column + len(a) - len(v)
            raise BookmarkError(
                f"column {col}: {v!r} in <{written}> is neither a duration (1.5s, 300ms) nor an "
                "amplitude (0–1)" + (" nor a FAP value (3=400)" if key == "fap" else ""),
                column=col,
            )
        if a.type == "DURATION":
            if duration is not None:
                raise BookmarkError(
                    f"column {column}: <{written}> has two durations", column=column
                )
            duration = float(v[:-2]) / 1000 if v.endswith("ms") else float(v[:-1])
            if not duration <= MAX_DURATION_S:  # 400 nines read as inf
                raise BookmarkError(
                    f"column {column}: duration {v} of <{written}> is more than the limit of "
                    f"{MAX_DURATION_S:g} s",
                    column=column,
                )
        elif a.type == "AMPLITUDE":
            if amplitude is not None:
                raise BookmarkError(
                    f"column {column}: <{written}> has two amplitudes", column=column
                )
            amplitude = float(v)
            if key == "fap" and not 0.0 <= amplitude <= 1.0:
                raise BookmarkError(
                    f"column {column}: <fap {v}> names FAP {v} without a value: write "
                    f"<fap {v}=VALUE> (e.g. <fap {v}=400 1s>)",
                    column=column,
                )
            if not 0.0 <= amplitude <= 1.0:
                raise BookmarkError(
                    f"column {column}: amplitude {v} of <{written}> must be within 0–1",
                    column=column,
                )
        else:
            if key != "fap":
                raise BookmarkError(
                    f"column {column}: '{v}' belongs in a <fap ...> bookmark, not <{written}>",
                    column=column,
                )
            fap_key, value = v.split("=")
            try:
                miap = Miap.parse(fap_key)
            except FapError as e:
                raise BookmarkError(f"column {column}: {e.message}", column=column) from None
            if miap.kind != "fap":
                raise BookmarkError(
                    f"column {column}: <fap> takes low-level FAPs 3–68, got '{fap_key}'",
                    column=column,
                )
            number = float(value)
            if not (math.isfinite(number) and abs(number) <= MAX_FAP_VALUE):
                raise BookmarkError(
                    f"column {column}: FAP {fap_key}={value} must be a number within "
                    f"±{MAX_FAP_VALUE:g}",
                    column=column,
                )
            faps[miap.number] = number
    if key == "fap":
        if not faps:
            raise BookmarkError(
                f"column {column}: <fap> needs values such as <fap 3=400 19=1024 1s>",
                column=column,
            )
        return Bookmark("fap", "fap", duration, amplitude, faps, column, written)
    canonical = EXPRESSION_ALIASES.get(key, key)
    if canonical in EXPRESSIONS:
        return Bookmark("expression", canonical, duration, amplitude, {}, column, written)
    if key in ACTIONS:
        return Bookmark("action", key, duration, amplitude, {}, column, written)
    raise BookmarkError(
        f"column {column}: unknown bookmark <{written}>; known names: "
        + ", ".join(known_names(known)),
        column=column,
    )
