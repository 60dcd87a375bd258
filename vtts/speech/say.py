"""From bookmarked text to an utterance: audio, timed visemes and bookmark times.

``prepare_utterance`` runs the bookmark parser, then either espeak-ng (its own phoneme and mark
events, in the audio's clock) or another engine's timings (``--phonemes FILE`` with a WAV), and
returns what the timeline needs. It knows nothing about models or rendering.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vtts.animate.timeline import TimedPhone
from vtts.errors import SpeechError, VttsWarning
from vtts.speech.bookmarks import Bookmark, BookmarkedText, parse_bookmarks
from vtts.speech.timings import TimedWord, write_timings


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
    voice: str = "en-us",
    rate: int | None = None,
    pitch: int | None = None,
    phonemes: str | Path | None = None,
    audio: str | Path | None = None,
    known: set[str] | None = None,
) -> Utterance:
    """Parse ``text`` and synthesize it with espeak-ng, or take the timings from ``phonemes``
    (an Amazon Polly speech-marks file or a ``start end phoneme`` table) with the WAV ``audio``.
    ``known``: the expressions the models have tables for (for the unknown-name message)."""
    from vtts.speech.phonemes import read_phoneme_file

    bt = parse_bookmarks(text, known)
    language = voice.split("-")[0] if voice else "en"
    if phonemes is not None:
        if audio is None:
            raise SpeechError("--phonemes needs the speech itself: give --audio FILE too")
        pf = read_phoneme_file(phonemes, language=language)
        samples, sr = _read_audio(Path(audio))
        phones = [TimedPhone(p.start, p.end, p.viseme, p.phoneme) for p in pf.phones]
        marks = [(m.name, m.time) for m in pf.marks]
        utt = Utterance(bt, samples, sr, phones, bt.bookmarks, list(pf.words))
        _place_marks(utt, marks, fallback=True)
        return utt
    from vtts.speech.tts import synthesize

    speech = synthesize(bt.ssml(), voice=voice, rate=rate, pitch=pitch)
    phones = [TimedPhone(p.start, p.end, p.viseme, p.phoneme) for p in speech.phonemes]
    words = [TimedWord(w.start, w.end, w.text) for w in speech.words if w.end is not None]
    utt = Utterance(bt, np.asarray(speech.audio), int(speech.rate), phones, bt.bookmarks, words)
    _place_marks(utt, [(m.name, m.time) for m in speech.marks], fallback=False)
    return utt


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
    # Another engine's file without marks: place each bookmark at the same fraction of the audio
    # as of the text (a rough estimate; say so).
    warnings.warn(
        VttsWarning(
            "the phoneme file gives no mark times (SSML marks named b0, b1, …): bookmarks are "
            "placed in proportion to their position in the text"
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


def _read_audio(path: Path) -> tuple[np.ndarray, int]:
    """``(n,)`` int16 mono samples of any audio file :func:`~vtts.speech.audio.read_audio`
    reads, at a rate the MP4's AAC encoder takes: the file's own when it is one, else the next
    higher one up to 48 kHz."""
    from vtts.speech.audio import AAC_RATES, read_audio, resample, to_int16

    samples, sr = read_audio(path)
    if sr not in AAC_RATES:
        to = min([r for r in AAC_RATES if r >= sr] + [48000])
        samples, sr = resample(samples, sr, to), to
    return to_int16(samples), sr
