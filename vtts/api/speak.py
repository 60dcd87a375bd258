"""One clause of bookmarked text spoken by one model, kept in memory (:func:`speak`): what
``vtts serve`` streams clause by clause, and what a program that feeds a head text piece by piece
calls. ``vtts say`` is the same speech and timeline, written to files."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vtts.api.say import ENGINES
from vtts.errors import RenderError


@dataclass(frozen=True)
class Spoken:
    """A spoken clause.

    audio      ``(n,)`` int16 samples (mono) at ``rate`` Hz
    params     ``(T, N_PARAMS)`` float64 parameter vectors (:mod:`vtts.face.miap`), frame ``k``
               at ``k / fps`` s of the audio's clock
    words      ``(start s, end s, word)`` of each spoken word
    bookmarks  ``(time s, written name)`` of each bookmark, as the text wrote it
    """

    audio: np.ndarray
    rate: int
    params: np.ndarray
    fps: float
    words: list[tuple[float, float, str]]
    bookmarks: list[tuple[float, str]]

    @property
    def duration(self) -> float:
        """Length of the audio in s."""
        return self.audio.shape[0] / self.rate


def speak(
    text: str,
    model,
    *,
    engine: str = "espeak",
    voice: str | None = None,
    rate: int | None = None,
    pitch: int | None = None,
    seed: int = 0,
    fps: float = 30.0,
    autonomous: bool = True,
) -> Spoken:
    """``text`` (with bookmarks) spoken by ``engine`` (:data:`vtts.api.say.ENGINES`) in
    ``voice`` at ``rate`` words per minute and ``pitch`` 0–99, and ``model``'s (a
    :class:`~vtts.face.FaceModel`) timeline of it at ``fps`` Hz with the autonomous behaviour of
    ``seed``. Raises :class:`~vtts.errors.BookmarkError` for a bad bookmark and
    :class:`~vtts.errors.SpeechError` when the engine fails."""
    from vtts.animate.timeline import build_timeline, speech_bilabials, speech_lead
    from vtts.utterance import prepare_utterance

    if engine not in ENGINES:
        raise RenderError(f"unknown speech engine {engine!r}; known: {', '.join(ENGINES)}")
    known = {x.name for x in model.tables.adts if x.kind == "expression"}
    utt = prepare_utterance(text, known=known, engine=engine, voice=voice, rate=rate, pitch=pitch)
    tl = build_timeline(
        model,
        utt.phones,
        utt.bookmarks,
        utt.duration,
        fps=fps,
        seed=seed,
        autonomous=autonomous,
        lead=speech_lead(engine),
        bilabials=speech_bilabials(engine),
    )
    words = [(float(w.start), float(w.end), str(w.label)) for w in utt.words]
    marks = [(float(b.time), str(b.written)) for b in utt.bookmarks if b.time is not None]
    return Spoken(np.asarray(utt.audio, dtype=np.int16), int(utt.rate), tl.params, float(fps),
                  words, marks)  # fmt: skip
