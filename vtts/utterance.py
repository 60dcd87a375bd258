"""From bookmarked text to an utterance: audio, timed visemes and bookmark times.

``prepare_utterance`` runs the bookmark parser, then a speech engine (:mod:`vtts.speech.engine`:
espeak-ng, with its own phoneme, word and mark events, festival, with its utterance structure, or
Piper, with its phoneme alignments, all in the audio's clock) or another engine's timings
(``--phonemes FILE`` with its audio), and returns what the timeline needs. It knows nothing
about models or rendering; it sits above `vtts.speech` and `vtts.align` (a recording with its
transcript is aligned), which both import nothing of it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from vtts.errors import SpeechError, VttsWarning
from vtts.speech.audio import mp4_samples, read_audio, read_for_mp4
from vtts.speech.bookmarks import Bookmark, BookmarkedText, parse_bookmarks
from vtts.speech.engine import end_of_word_before, load_engine, words_before
from vtts.speech.timings import TimedPhone, TimedWord, write_timings

if TYPE_CHECKING:
    from collections.abc import Callable


@dataclass
class Utterance:
    """Speech ready for the timeline.

    audio      ``(n,)`` int16 samples (mono) at ``rate`` Hz
    phones     the phones with their MPEG-4 visemes, in the audio's clock (s)
    bookmarks  the text's bookmarks with ``time`` set (s)
    words      the spoken words with their start and end (s), when the source gives them
    """

    text: BookmarkedText
    audio: np.ndarray
    rate: int
    phones: list[TimedPhone]
    bookmarks: list[Bookmark]
    words: list[TimedWord] = field(default_factory=list)

    @property
    def duration(self) -> float:
        """Length of the audio in s (at least the end of the last phone)."""
        end = self.phones[-1].end if self.phones else 0.0
        return max(self.audio.shape[0] / self.rate, end)


def prepare_utterance(
    text: str,
    *,
    engine: str = "espeak",
    voice: str | None = None,
    rate: int | None = None,
    pitch: int | None = None,
    phonemes: str | Path | None = None,
    audio: str | Path | None = None,
    known: set[str] | None = None,
    words: str = "auto",
    progress: Callable[[float, float], None] | None = None,
) -> Utterance:
    """Parse ``text`` and synthesize it with ``engine`` (:data:`vtts.speech.engine.ENGINES`:
    ``"espeak"``, the default, ``"festival"`` or ``"piper"``), or take the timings from
    ``phonemes`` (Amazon Polly speech marks, a ``start end phoneme`` table or ``--timings-out``
    table) with the audio file ``audio``; ``audio`` alone is a recording of the text, to which
    espeak-ng's phones of the text are aligned (:mod:`vtts.align`). ``voice`` is the engine's
    (its ``default_voice`` when None); ``rate`` in words per minute and
    ``pitch`` 0–99 as for espeak-ng. ``known``: the expressions the models have tables for
    (for the unknown-name message). ``audio`` with an empty ``text`` (and no ``phonemes``): the
    phones are recognized from the recording (:mod:`vtts.speech.recognize`; and its words,
    :data:`~vtts.speech.recognize.WORD_MODES`: ``words``), no bookmarks; ``progress(done_s,
    total_s)`` is then called as the recognition goes."""
    from vtts.speech.phonemes import read_phoneme_file

    if audio is not None and phonemes is None and not text.strip():
        _only_recording(engine, voice, rate, pitch)
        return recognized(Path(audio), words=words, progress=progress)
    if words != "auto":
        raise SpeechError(
            f"--words {words} applies to a recording without its text (its words are "
            "recognized); with a text, the text's words are the ones spoken"
        )
    found_engine = load_engine(engine)
    bt = parse_bookmarks(text, known)
    if phonemes is not None:
        if audio is None:
            raise SpeechError("--phonemes needs the speech itself: give --audio FILE too")
        language = voice.split("-")[0] if voice else "en"
        pf = read_phoneme_file(phonemes, language=language)
        samples, sr = read_for_mp4(Path(audio))
        phones = [TimedPhone(p.start, p.end, p.viseme, p.phoneme) for p in pf.phones]
        marks = [(m.name, m.time) for m in pf.marks]
        utt = Utterance(bt, samples, sr, phones, bt.bookmarks, list(pf.words))
        _place_marks(utt, marks, fallback=True)
        return utt
    if audio is not None:
        if engine != "espeak":
            raise SpeechError(
                f"--audio without --phonemes aligns the text to the recording with espeak-ng's "
                f"phonemizer; --engine {engine} does not apply"
            )
        if rate is not None or pitch is not None:
            raise SpeechError(
                "--rate and --pitch shape synthesized speech; a recording (--audio) keeps its own"
            )
        return _aligned(bt, Path(audio), voice)
    spoken = found_engine.speak(bt, voice=voice, rate=rate, pitch=pitch)
    speech = spoken.speech
    marks = [(f"b{k}", t) for k, t in enumerate(spoken.bookmarks)]
    phones = [TimedPhone(p.start, p.end, p.viseme, p.phoneme) for p in speech.phonemes]
    words = [TimedWord(w.start, w.end, w.text) for w in speech.words if w.end is not None]
    utt = Utterance(bt, np.asarray(speech.audio), int(speech.rate), phones, bt.bookmarks, words)
    _place_marks(utt, marks, fallback=False)
    return utt


def _aligned(bt: BookmarkedText, audio: Path, voice: str | None) -> Utterance:
    """``--audio`` without timings: the text's phones, words and bookmarks aligned to the
    recording (:func:`vtts.align.align`); where the alignment breaks down is a warning."""
    from vtts.align import align
    from vtts.align.aligner import check_rate, check_transcript

    try:
        # the file's own rate and length: the MP4's conversion lifts 4 kHz to 7350 Hz
        samples, sr = read_audio(audio)
        check_rate(sr)
        check_transcript(bt.ssml(), len(samples) / sr)
        samples, sr = mp4_samples(samples, sr)
        found = align(samples, sr, bt.ssml(), voice=voice or "en-us")
    except SpeechError as e:
        if e.file is None:
            e.file = str(audio)
        raise
    for problem in found.problems:
        warnings.warn(VttsWarning(problem, file=str(audio)), stacklevel=3)
    phones = [TimedPhone(p.start, p.end, p.viseme or 0, p.phoneme) for p in found.phones]
    words = [TimedWord(w.start, w.end, w.text) for w in found.words]
    utt = Utterance(bt, samples, sr, phones, bt.bookmarks, words)
    times = [m.time for m in found.marks]
    if bt.before_punctuation:  # as for espeak-ng's own speech: at the end of the word before
        end_of_word_before(bt, found.words, times)
    _place_marks(utt, [(f"b{k}", t) for k, t in enumerate(times)], fallback=False)
    return utt


def _only_recording(engine: str, voice: str | None, rate: int | None, pitch: int | None) -> None:
    """A recording without a transcript takes none of the options that shape or phonemize
    speech."""
    given = [
        flag
        for flag, value in (
            (f"--engine {engine}", engine != "espeak"),
            ("--voice", voice is not None),
            ("--rate", rate is not None),
            ("--pitch", pitch is not None),
        )
        if value
    ]
    if given:
        raise SpeechError(
            f"{', '.join(given)} do not apply to a recording without its text: its phones are "
            "recognized from the sound (US English); give the transcript with --text to align it "
            "instead"
        )


def recognized(
    audio: Path, *, words: str = "auto", progress: Callable[[float, float], None] | None = None
) -> Utterance:
    """``--audio`` without a text: the phones recognized from the recording
    (:func:`vtts.speech.recognize.recognize`; where none is, the energy's mouth shapes), the
    words where they are recognized (``words``: ``RecognizerOptions.words``), no bookmarks."""
    from vtts.speech.recognize import RecognizerOptions, check_rate, recognize

    try:
        samples, sr = read_audio(audio)  # the file's own rate and length
        check_rate(sr)
        found = recognize(samples, sr, RecognizerOptions(words=words), progress=progress)
        samples, sr = mp4_samples(samples, sr)
    except SpeechError as e:
        if e.file is None:
            e.file = str(audio)
        raise
    phones = [TimedPhone(p.start, p.end, p.viseme or 0, p.phoneme) for p in found.phones]
    return Utterance(parse_bookmarks(""), samples, sr, phones, [], found.words)


def write_utterance_timings(path: str | Path, utt: Utterance) -> None:
    """``--timings-out``: the utterance's words and phones as a table
    (:mod:`vtts.speech.timings`), written atomically."""
    write_timings(path, utt.phones, utt.words)


def _place_marks(utt: Utterance, marks: list[tuple[str, float]], *, fallback: bool) -> None:
    """Give every bookmark the time of its ``<mark name="bK"/>`` event."""
    times = dict(marks)
    missing = []
    for k, b in enumerate(utt.bookmarks):
        t = times.get(f"b{k}")
        if t is None:
            missing.append(b)
        b.time = t
    if not missing:
        return
    if not fallback:
        raise SpeechError(
            f"the synthesizer reported no time for {len(missing)} bookmark(s) "
            f"(<{missing[0].written}> at column {missing[0].column})"
        )
    if _place_at_words(utt):
        return
    # Another engine's file without marks or words: place each bookmark at the same fraction of
    # the audio as of the text (a rough estimate; say so).
    warnings.warn(
        VttsWarning(
            "the phoneme file gives no mark times (SSML marks named b0, b1, …) and no words "
            "matching the text's: bookmarks are placed in proportion to their position in the "
            "text"
        ),
        stacklevel=3,
    )
    total = max(len(utt.text.text), 1)
    pos = 0
    k = 0
    for piece in utt.text.pieces:
        if isinstance(piece, str):
            pos += len(piece)
        else:
            if piece.time is None:
                piece.time = utt.duration * pos / total
            k += 1


def _place_at_words(utt: Utterance) -> bool:
    """Bookmarks without a time at the start of the word after them, when the file's words
    (Polly's word marks, a ``--timings-out`` table) are the text's, one for one: the end of the
    last word for a bookmark after every word. False, and nothing placed, when they are not."""
    if not utt.words:
        return False
    before, count = words_before(utt.text)
    if count != len(utt.words):
        return False
    words = sorted(utt.words, key=lambda w: w.start)
    for b, n in zip(utt.bookmarks, before, strict=True):
        if b.time is None:
            b.time = words[n].start if n < len(words) else words[-1].end
    return True
