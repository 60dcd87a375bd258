"""Speech engines: the one interface every synthesizer vtts speaks with gives.

An engine takes bookmarked text (:class:`vtts.speech.bookmarks.BookmarkedText`) and returns a
:class:`Spoken`: the audio, its phones (with their MPEG-4 visemes) and words in the audio's clock,
and the time of each bookmark. It also lists its installed voices (:class:`VoiceInfo`) and states
its timing facts, measured on its own audio: the mouth's lead and where the lips are shut for
its bilabials (:class:`BilabialTiming`). A new engine is one module that defines ``ENGINE``, an
object with the methods and attributes of :class:`Engine`, and a line in :data:`ENGINES`;
nothing else changes (the timeline, the outputs and ``vtts voices`` take it from there).

The engines:

``espeak``    espeak-ng through its C API (:mod:`vtts.speech.tts`), always installed;
``festival``  festival's HTS voice (:mod:`vtts.speech.festival`), Debian packages;
``piper``     Piper's neural voices (:mod:`vtts.speech.piper`), the optional extra
              ``vtts[piper]`` (GPL-3.0, unlike vtts: see docs/speech.md).

An engine whose Python packages are missing is a :class:`~vtts.errors.SpeechError` naming the
extra to install; ``vtts voices`` leaves it out with a note.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

from vtts.errors import SpeechError

if TYPE_CHECKING:
    from vtts.speech.bookmarks import BookmarkedText
    from vtts.speech.tts import Speech

__all__ = [
    "BilabialTiming",
    "DEFAULT_ENGINE",
    "ENGINES",
    "Engine",
    "LipTiming",
    "MissingEngine",
    "Spoken",
    "VoiceInfo",
    "bookmark_positions",
    "installed_voices",
    "end_of_word_before",
    "engine_timing",
    "load_engine",
    "words_before",
]

#: Engine name → the module defining its ``ENGINE``.
ENGINES = {
    "espeak": "vtts.speech.tts",
    "festival": "vtts.speech.festival",
    "piper": "vtts.speech.piper",
}
#: The engine of ``vtts say`` without ``--engine``: espeak-ng, which every install has (the
#: others need Debian packages or a GPL-3.0 extra; docs/speech.md says why).
DEFAULT_ENGINE = "espeak"


@dataclass(frozen=True)
class VoiceInfo:
    """An installed voice, as ``vtts voices`` lists it.

    engine     the engine's name (``espeak``, ``festival``, ``piper``)
    name       what ``--voice`` takes
    language   its language code (``en-us``)
    rate       its sample rate, Hz (None where the engine tells it only by speaking)
    licence    the voice's licence (SPDX where there is one)
    languages  every language code it speaks (espeak-ng's voices speak several)
    """

    engine: str
    name: str
    language: str
    rate: int | None
    licence: str
    languages: tuple[str, ...] = ()
    description: str = ""

    def speaks(self, language: str) -> bool:
        """True when the voice speaks ``language`` (``en`` matches ``en-us``, ``en-gb-x-rp``)."""
        lang = language.lower().replace("_", "-")
        codes = self.languages or (self.language,)
        return any(c.lower() == lang or c.lower().startswith(lang + "-") for c in codes)


@dataclass
class Spoken:
    """What an engine returns for a bookmarked text.

    speech     the audio, phones (covering it without gaps) and words (:class:`Speech`)
    bookmarks  each bookmark's time in the audio, s, in the text's order
    """

    speech: Speech
    bookmarks: list[float] = field(default_factory=list)


@dataclass(frozen=True)
class LipTiming:
    """Where an engine's own audio has the lips shut for one kind of bilabial, against the
    phone it gives (s): the closure starts ``onset`` after the phone's start (negative: in the
    phone before) and the lips open ``release`` after the phone's ``anchor`` (``"start"`` or
    ``"end"``)."""

    onset: float
    release: float
    anchor: str = "end"


@dataclass(frozen=True)
class BilabialTiming:
    """An engine's :class:`LipTiming` of ``p``, ``b`` and ``m`` (measured on its own audio by
    :func:`vtts.animate.lipsync.lip_closures`; docs/speech.md gives the figures)."""

    p: LipTiming
    b: LipTiming
    m: LipTiming

    def of(self, phoneme: str) -> LipTiming:
        """The timing of a bilabial phone by its label: m (``m``, ``em``, ``m-``) or p, and b
        for the rest (``b`` and the rarer bilabials)."""
        label = phoneme.lower().lstrip("'ˈˌ")
        if label.startswith(("m", "em")):
            return self.m
        return self.p if label.startswith("p") else self.b

    def span(self, first, last) -> tuple[float, float]:
        """(closure onset, release), s, of adjacent bilabial phones ``first`` … ``last`` (with
        ``start``, ``end`` and ``phoneme``): one closure from the first's onset to the last's
        release."""
        a = self.of(first.phoneme)
        z = self.of(last.phoneme)
        release = (last.start if z.anchor == "start" else last.end) + z.release
        return first.start + a.onset, release


class Engine(Protocol):
    """What every engine module's ``ENGINE`` gives."""

    #: ``--engine`` name
    name: str
    #: the voice used without ``--voice``
    default_voice: str
    #: how far the mouth leads the phone times it gives, s (the lip sync bench's choice)
    lead: float
    #: where its audio has the lips shut for a p, b or m, against its phones
    bilabials: BilabialTiming

    def speak(
        self,
        text: BookmarkedText,
        *,
        voice: str | None = None,
        rate: int | None = None,
        pitch: int | None = None,
    ) -> Spoken:
        """The speech of ``text`` with its bookmarks' times; ``rate`` words per minute (80–450)
        and ``pitch`` 0–99, each None for the voice's own."""
        ...

    def sentences(
        self, text: BookmarkedText, *, voice: str | None = None, rate: int | None = None
    ) -> Iterator[Spoken]:
        """The speech of ``text`` sentence by sentence, each in its own clock from 0, as soon
        as each is made (a server sends the first while the rest is synthesized); engines that
        synthesize at once give one piece."""
        ...

    def voices(self) -> list[VoiceInfo]:
        """The engine's installed voices (empty when its program or data is missing)."""
        ...


class MissingEngine(SpeechError):
    """An engine whose Python packages are not installed (the message names the extra)."""


def load_engine(name: str) -> Engine:
    """The engine called ``name``; raises :class:`SpeechError` for an unknown name and
    :class:`MissingEngine` (naming the extra to install) for one whose packages are missing."""
    module = ENGINES.get(name) if isinstance(name, str) else None
    if module is None:
        raise SpeechError(f"unknown speech engine {name!r}; known: {', '.join(ENGINES)}")
    return importlib.import_module(module).ENGINE


def engine_timing(name: str | None) -> tuple[float, BilabialTiming]:
    """(lead s, :class:`BilabialTiming`) of the phones ``name`` times; espeak-ng's for None or
    a name that is no engine (phones from ``--phonemes`` or a recording aligned with espeak-ng's
    phones)."""
    engine = importlib.import_module(ENGINES.get(name or "", ENGINES["espeak"])).ENGINE
    return engine.lead, engine.bilabials


# ---- bookmarks and words, shared by the engines -------------------------------------------------


def bookmark_positions(text: BookmarkedText) -> list[int]:
    """Each bookmark's character position in ``text.text`` (the plain text without them)."""
    positions = []
    at = 0
    for piece in text.pieces:
        if isinstance(piece, str):
            at += len(piece)
        else:
            positions.append(at)
    return positions


_TEXT_WORD = re.compile(r"\S*\w\S*")


def text_words(text: str) -> list[str]:
    """The words of a plain text as ``--timings-out`` counts them: runs without spaces holding
    a letter or digit."""
    return _TEXT_WORD.findall(text)


def words_before(text: BookmarkedText) -> tuple[list[int], int]:
    """For each bookmark, how many words of the text come before it; and the text's words."""
    before: list[int] = []
    count = 0
    for piece in text.pieces:
        if isinstance(piece, str):
            count += len(text_words(piece))
        else:
            before.append(count)
    return before, count


def end_of_word_before(text: BookmarkedText, words: Sequence, times: list[float]) -> None:
    """Bookmarks written before punctuation (spoken after it, see
    :mod:`vtts.speech.bookmarks`) at the end of the word before them, where espeak-ng reports a
    mark written before punctuation, rather than at the next word's start; ``times`` (s, one per
    bookmark) is changed in place. ``words`` have ``end``. The word is found by its rank among
    the text's words (espeak-ng's word positions can fall into the word before after a full
    stop), so only where the engine's words are the text's, one for one."""
    before, count = words_before(text)
    if count != len(words):
        return
    for k in sorted(text.before_punctuation):
        n = before[k]
        if n and words[n - 1].end is not None:
            earlier = max(times[:k], default=0.0)
            times[k] = max(words[n - 1].end, earlier)


def installed_voices(engines: Sequence[str] = tuple(ENGINES)) -> tuple[list[VoiceInfo], dict]:
    """Every installed voice of ``engines`` (all by default), engine by engine; and for each
    engine that cannot speak here, why (its extra or program missing)."""
    found: list[VoiceInfo] = []
    missing: dict[str, str] = {}
    for name in engines:
        try:
            voices = load_engine(name).voices()
        except SpeechError as e:
            missing[name] = e.message
            continue
        if not voices:
            missing[name] = "no voice installed (docs/speech.md says how to install one)"
        found += voices
    return found, missing
