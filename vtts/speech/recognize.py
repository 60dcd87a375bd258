"""Phones recognized from the voice alone: lip-sync for audio without a transcript.

:func:`recognize` takes each 10 ms frame's viseme from the viseme classifier
(:mod:`vtts.speech.viseme_classifier`, trained on synthetic speech), with PocketSphinx's visemes
(below) adding to its scores before the smoothing; each run of one viseme is a phone, named by
PocketSphinx's phone where the two agree, else by the classifier's class (:data:`CLASS_NAMES`),
and a bilabial run whose level steps (a nasal's murmur, then a stop's closure) is two phones
(:func:`split_closures`).
Where the classifier is unsure of a piece (real speech, speech in loud noise: the mean entropy of
its probabilities at least :data:`WORDS_ENTROPY`), PocketSphinx also recognizes its **words**
with the wheel's US-English language model and dictionary (:func:`make_word_decoder`), aligns
their phones to the audio (:func:`decode_words`), and those phones take the phone loop's place
as the evidence, weighing :data:`WORD_EVIDENCE`; the words are in :attr:`Recognition.words`
(``RecognizerOptions(words="always" | "never")`` to choose otherwise).
Where the classifier hears a piece better with the noise taken out (speech in loud noise), the
phone loop is not consulted: it decodes noisy speech poorly and misled the smoothing there.
With ``RecognizerOptions(classifier=False)``, and for a steady loud sound (music, loud noise),
PocketSphinx's phones alone. :class:`LiveRecognizer` uses PocketSphinx alone.

PocketSphinx (``pocketsphinx`` 5.1.1, BSD; its wheel carries the US-English acoustic model and
``en-us-phone.lm.bin``, a phone language model) decodes the audio in *allphone* mode, Rhubarb Lip
Sync's settings (:class:`RecognizerOptions`): a phone loop weighted by the phone model, with
context-independent phones and wide beams, which gives ARPAbet phones on 10 ms frames. Each phone
gets its MPEG-4 viseme from the ``arpabet`` rows of ``vtts/data/phoneme_visemes.tsv`` — the
same :class:`~vtts.speech.phonemes.Phone` list every other timing source makes, so the model's
coarticulation follows as for any other speech.

Audible sound the recognizer gives no phone for (it decodes music, noise and unknown languages
as silence or fillers) takes its mouth shapes from the voice's energy and spectrum
(:mod:`vtts.speech.energy`): never a frozen face over audible sound. A recognized phone lying
wholly in inaudible frames is a pause (viseme 0).

:func:`recognize` decodes a whole recording in pieces of at most :data:`PIECE_S` cut at quiet
frames (bounded memory; a ``progress`` callback after each), from 20 s on in two processes
(:func:`workers`: every other piece in a worker forked from this process); a recording of one
piece from 8 s on has its word search in two halves (:data:`HALF_S`), the second in a forked
worker, which starts on it while this process classifies the piece. Each piece's and half's
decoders start anew, so the result is the same in one process or two, on any machine.
:class:`LiveRecognizer` takes chunks of PCM as they arrive and gives each 10 ms frame's
viseme as soon as the decoder has one (what ``vtts play --audio -`` uses, and what a server
can feed).

``pocketsphinx`` is imported when a decoder is made, not before: other commands do not pay for
it. The decoders :func:`recognize` made are kept for the next recognition in the process (a
batch's worker, a server), which finds what new ones would; :func:`release_decoders` drops them.
"""

from __future__ import annotations

import functools
import os
import re
import signal
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import NoReturn

import numpy as np

from vtts.errors import SpeechError
from vtts.speech.energy import (
    FRAME_S,
    EnergyFrames,
    Levels,
    energy_frames,
    energy_visemes,
    levels,
)
from vtts.speech.phonemes import Phone, viseme_of
from vtts.speech.timings import TimedWord

__all__ = [
    "DECODER_RATE",
    "WORD_MODES",
    "LiveRecognizer",
    "Recognition",
    "RecognizerOptions",
    "decode_words",
    "make_word_decoder",
    "recognize",
    "release_decoders",
    "segments_to_phones",
    "set_cpus",
    "split_closures",
    "word_dictionary",
]

#: The acoustic model's rate, Hz: audio is resampled to it.
DECODER_RATE = 16000
#: Lowest rate a recording may have, Hz: below it there is too little of speech's spectrum.
MIN_RATE = 8000
#: Longest piece decoded as one utterance, s (the decoder's memory grows with an utterance).
PIECE_S = 30.0
#: A piece is cut at the quietest frame of the CUT_WINDOW_S around its even share's end.
CUT_WINDOW_S = 5.0
#: Shortest piece made for two processes (:func:`workers`): a recording of less than two of
#: them is one piece; a longer one an even number of pieces.
MIN_PIECE_S = 10.0
#: A recording of one piece and at least two HALF_S long has its word search in two halves,
#: in two processes (:func:`workers`), cut near its middle (:func:`_half`); the classifier,
#: and whether words are recognized at all, still judge the piece whole.
HALF_S = 4.0
#: Each half's word search also hears CONTEXT_FRAMES of the other half around the cut (the
#: language model's context of the first words after it), and keeps what lies in its own.
CONTEXT_FRAMES = 60
#: Names the decoder gives to what is not a phone.
NOT_PHONES = frozenset({"SIL", "<sil>", "<s>", "</s>", "(NULL)", "+SPN+", "+NSN+", "[NOISE]"})
#: Names of the classifier's phones, by viseme: the ARPAbet phones of its class.
CLASS_NAMES = ("SIL", "P|B|M", "F|V", "TH|DH", "T|D", "K|G|NG|HH", "CH|JH|SH|ZH", "S|Z", "N|L",
               "R", "AA|AE|AH|AW|AY", "AX|EH|ER|EY", "IH|IY|Y", "AO|OW|OY", "UH|UW|W")  # fmt: skip
#: Names of the two phones a bilabial closure is split into (:func:`split_closures`): the
#: louder part, a nasal's murmur, and the quieter, a stop's closure.
MURMUR_NAME, CLOSURE_NAME = "M", "P|B"
_CLASS_VISEMES = {name: v for v, name in enumerate(CLASS_NAMES) if v} | {CLOSURE_NAME: 1}
#: A run of the classifier's bilabial of at least SPLIT_FRAMES frames whose level steps by at
#: least SPLIT_DB between two parts of at least SPLIT_FRAMES // 2 frames is two phones.
SPLIT_FRAMES = 6
SPLIT_DB = 6.0
#: A classifier's bilabial lying wholly in inaudible frames between two heard phones, of at
#: most CLOSURE_FRAMES frames where the classifier's mean probability of p b m is at least
#: CLOSURE_P, is kept (a stop's silent closure), not made a pause.
CLOSURE_FRAMES = 20
CLOSURE_P = 0.5
#: ``RecognizerOptions.words``: recognize words where the classifier is unsure, always, never.
WORD_MODES = ("auto", "always", "never")
#: With ``words="auto"``, a piece's words are recognized where the mean entropy (nats) of the
#: classifier's probabilities over its audible frames is at least WORDS_ENTROPY (real speech;
#: a speech engine's clean voice stays below it), or in noise (the noise subtracted from the
#: classifier's features) at least WORDS_ENTROPY_IN_NOISE (noise itself makes it unsure).
WORDS_ENTROPY = 0.45
WORDS_ENTROPY_IN_NOISE = 0.5
#: What a word-aligned phone's viseme adds to a frame's score in the smoothing, in place of
#: the classifier's ``evidence`` for PocketSphinx's phone loop (the entropy's share the same).
WORD_EVIDENCE = 6.0
#: The word search's cap on the HMMs active per frame (``-maxhmmpf``): half its time, and on
#: the bench's tuning part the same agreement and closures as with no cap.
WORD_MAX_HMMS = 1500
#: The word search's beam on the last phone of one-phone words (``-lponlybeam``; PocketSphinx's
#: default is 7e-29): a tenth of its time, and on the bench's tuning part the same phones
#: and words, frame for frame, as with the default.
WORD_LAST_PHONE_BEAM = 1e-20
#: A dictionary word's alternative pronunciation: ``read(2)``.
_VARIANT = re.compile(r"\(\d+\)$")
#: A recognized word or phone: its name and its first and last 10 ms frames (inclusive).
Segment = tuple[str, int, int]
#: Names of the phones filled in from the energy (:mod:`vtts.speech.energy`), by viseme.
ENERGY_NAMES = {0: "SIL", 7: "~hiss", 10: "~wide", 11: "~half", 12: "~slight"}


@dataclass(frozen=True)
class RecognizerOptions:
    """PocketSphinx's allphone search (Rhubarb Lip Sync's settings, which the issue measured:
    a narrower beam lost most phones of real speech).

    ``language_weight``: weight of the phone language model (``-lw``); ``beam`` and
    ``phone_beam``: the search's beams (``-beam``, ``-pbeam``); ``dither``: add the decoder's
    1-bit noise (``-dither``, with its fixed seed) before the features, so that digital silence
    (a speech engine's pauses) does not skew them — on espeak-ng's speech the recognizer took
    audible frames for silence half as often with it (docs/speech.md); ``fill``: give audible
    frames without a recognized phone visemes from the energy (False: they stay pauses, as the
    recognizer said); ``classifier``: :func:`recognize` takes each frame's viseme from the
    viseme classifier (:mod:`vtts.speech.viseme_classifier`) instead of PocketSphinx's phones
    (False: PocketSphinx's, as before the classifier; :class:`LiveRecognizer` always uses
    PocketSphinx); ``weights``: the classifier's ``.npz`` file (one written by
    ``scripts/train_viseme_classifier.py``; None: the package's ``viseme_classifier.npz``);
    ``words`` (:data:`WORD_MODES`): where :func:`recognize` also recognizes words — PocketSphinx
    with its US-English language model and dictionary, the words' phones aligned to the audio
    in place of the phone loop's — ``"auto"`` in the pieces where the classifier is unsure
    (:data:`WORDS_ENTROPY`: real speech, speech in noise), ``"always"`` or ``"never"``;
    ``workers``: how many processes :func:`recognize` decodes a recording's pieces in (None:
    :func:`workers` chooses, two for a recording of 8 s or more on two CPUs or more)."""

    language_weight: float = 0.8
    beam: float = 1e-20
    phone_beam: float = 1e-20
    dither: bool = True
    fill: bool = True
    classifier: bool = True
    weights: Path | None = None
    words: str = "auto"
    workers: int | None = None

    def __post_init__(self) -> None:
        w = self.workers
        if w is not None and (isinstance(w, bool) or not isinstance(w, int) or w < 1):
            raise SpeechError(f"workers must be a whole number of at least 1, got {w!r}")
        if self.words not in WORD_MODES:
            raise SpeechError(f"words must be one of {', '.join(WORD_MODES)}, got {self.words!r}")
        if not (0.0 < self.language_weight <= 100.0):
            raise SpeechError(f"language_weight must be in (0, 100], got {self.language_weight}")
        for name in ("beam", "phone_beam"):
            v = getattr(self, name)
            if not (0.0 < v < 1.0):
                raise SpeechError(f"{name} must be in (0, 1), got {v}")


@dataclass
class Recognition:
    """What :func:`recognize` found.

    phones      the phones in the audio's clock (s), covering it from 0 to ``duration`` without
                gaps, pauses included (viseme 0); ``phoneme`` is the decoder's ARPAbet name, or
                an energy name (``~wide``, ``~half``, ``~slight``, ``~hiss``) where the energy
                filled in
    duration    the audio's length, s
    recognized  seconds of audible frames under a recognized phone
    filled      seconds of audible frames that took their viseme from the energy
    visemes     ``(n,)`` int8, the viseme of each 10 ms frame (frame ``k`` spans ``[k, k + 1) *
                FRAME_S`` s), what ``phones`` are made of
    words       the words recognized (``RecognizerOptions.words``), in the audio's clock (s);
                none where only phones were
    """

    phones: list[Phone]
    duration: float
    recognized: float = 0.0
    filled: float = 0.0
    visemes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int8), repr=False)
    words: list[TimedWord] = field(default_factory=list)


#: The ``pocketsphinx`` the recognizer was measured with (``constraints.txt`` installs it).
_PINNED = "pocketsphinx==5.1.1"


def model_paths() -> tuple[str, str]:
    """The acoustic model's folder and the phone language model inside the ``pocketsphinx``
    wheel; :class:`SpeechError` saying what to install when it is missing."""
    try:
        import pocketsphinx
    except ImportError:
        raise SpeechError(
            f"recognizing speech needs the pocketsphinx package: pip install {_PINNED}"
        ) from None
    root = os.path.join(pocketsphinx.get_model_path(), "en-us")
    hmm, phone_lm = os.path.join(root, "en-us"), os.path.join(root, "en-us-phone.lm.bin")
    if not (os.path.isdir(hmm) and os.path.isfile(phone_lm)):
        raise SpeechError(f"the pocketsphinx wheel lacks its en-us model ({root})")
    return hmm, phone_lm


def make_decoder(options: RecognizerOptions):
    """A ``pocketsphinx.Decoder`` in allphone mode with ``options``, its log silenced."""
    hmm, phone_lm = model_paths()
    return _decoder(
        hmm=hmm,
        allphone=phone_lm,
        allphone_ci=True,
        lw=options.language_weight,
        beam=options.beam,
        pbeam=options.phone_beam,
        dither=options.dither,
    )


#: What to do about a damaged ``pocketsphinx`` installation.
_REINSTALL = f"reinstall it: pip install --force-reinstall {_PINNED}"


def _decoder(**config):
    """A ``pocketsphinx.Decoder`` of ``config``, its log silenced; where PocketSphinx cannot
    make it (a file of its installation damaged), a :class:`SpeechError` naming the language
    model it cannot read, else the acoustic model and dictionary it was given. The phone
    language model (``allphone``) is read first: without it PocketSphinx would decode an
    unconstrained phone loop, saying nothing."""
    from pocketsphinx import Decoder

    if "allphone" in config:
        _check_lm(config["allphone"])
    try:
        return Decoder(**config, loglevel="FATAL", logfn=os.devnull)
    except (RuntimeError, ValueError):
        if "lm" in config:
            _check_lm(config["lm"])
        files = " and ".join(str(config[k]) for k in ("hmm", "dict") if k in config)
        raise SpeechError(f"PocketSphinx cannot load {files}: {_REINSTALL}") from None


def _check_lm(path: str) -> None:
    """A :class:`SpeechError` naming the language model ``path`` where PocketSphinx cannot
    read it (its own complaints silenced)."""
    from pocketsphinx import NGramModel, set_loglevel

    set_loglevel("FATAL")
    try:
        NGramModel.readfile(path)
    except (OSError, RuntimeError, ValueError):
        raise SpeechError(
            f"PocketSphinx cannot read its language model {path}: {_REINSTALL}"
        ) from None


def make_word_decoder(options: RecognizerOptions):
    """A ``pocketsphinx.Decoder`` recognizing words: the wheel's US-English acoustic model,
    language model (``en-us.lm.bin``) and dictionary (``cmudict-en-us.dict``, cut to the
    language model's words: :func:`word_dictionary`), one pass of the
    tree search (no flat or lattice pass) capped at :data:`WORD_MAX_HMMS` active HMMs, the
    phone loop's dither; its log silenced."""
    hmm, _ = model_paths()
    root = os.path.dirname(hmm)
    lm, dic = os.path.join(root, "en-us.lm.bin"), os.path.join(root, "cmudict-en-us.dict")
    if not (os.path.isfile(lm) and os.path.isfile(dic)):
        raise SpeechError(f"the pocketsphinx wheel lacks its en-us language model ({root})")
    return _decoder(
        hmm=hmm,
        lm=lm,
        dict=word_dictionary(dic, lm),
        fwdflat=False,
        bestpath=False,
        maxhmmpf=WORD_MAX_HMMS,
        lponlybeam=WORD_LAST_PHONE_BEAM,
        dither=options.dither,
    )


def word_dictionary(dictionary: str, lm: str) -> str:
    """The dictionary file the word search loads: ``dictionary`` (the wheel's
    ``cmudict-en-us.dict``, 134,860 entries) cut to the words of the language model ``lm``
    (72,547 words), their other pronunciations (``read(2)``) kept: 79,426 entries, which the
    decoder loads in about 0.1 s less. The search finds the same with either, word for word
    and phone for phone: it enters no word that its language model lacks.
    Kept in the user's cache (``speech/`` in :func:`vtts.usercache.cache_dir`, named by the
    ``pocketsphinx`` version and the two files' sizes and times) and made there on first use
    (some 0.2 s); ``dictionary`` itself where the cache is off or not the user's own."""
    import hashlib
    from importlib.metadata import version

    from vtts.atomic import atomic_path
    from vtts.usercache import private_folder, trusted_file

    folder = private_folder("speech")
    if folder is None:
        return dictionary
    try:
        stats = [(st.st_size, st.st_mtime_ns) for st in map(os.stat, (dictionary, lm))]
    except OSError:  # the decoder names what is missing
        return dictionary
    key = f"{version('pocketsphinx')}\0{dictionary}\0{lm}\0{stats}".encode()
    path = folder / f"words-{hashlib.sha256(key).hexdigest()[:20]}.dict"
    if trusted_file(path):
        return str(path)
    from pocketsphinx import NGramModel, set_loglevel

    set_loglevel("FATAL")  # as the decoders' own: what cannot be read here, they report
    try:
        model = NGramModel.readfile(lm)
        unknown = model.prob(["<not a word of vtts>"])
        kept: list[str] = []
        with open(dictionary, encoding="utf-8") as f:
            for line in f:
                word = line.split(maxsplit=1)[0] if line.strip() else ""
                if word and model.prob([_VARIANT.sub("", word)]) != unknown:
                    kept.append(line)
    except (OSError, RuntimeError, UnicodeDecodeError, ValueError):
        return dictionary
    try:
        if path.is_symlink() or path.exists():
            path.unlink()  # not trusted (above): never read
        with atomic_path(path) as tmp:
            tmp.write_text("".join(kept), encoding="utf-8")
    except OSError:
        return dictionary
    return str(path)


def decode_words(decoder, pcm: bytes) -> tuple[list[Segment], list[Segment]]:
    """The words of one utterance, ``pcm`` (16 kHz mono int16 bytes), recognized by
    ``decoder`` (:func:`make_word_decoder`), and their phones aligned to it (a second,
    forced pass over the words): ``(words, phones)``, each ``(name, first, last)`` with frames
    of 10 ms, inclusive. Words are the dictionary's (``read(2)`` named ``read``), without
    silences and fillers; phones are ARPAbet, ``SIL`` between words. Both empty where no
    word was recognized."""
    decoder.activate_search()  # the language model's, after the last utterance's alignment
    decoder.start_utt()
    decoder.process_raw(pcm, full_utt=True)
    decoder.end_utt()
    hyp = decoder.hyp()
    if hyp is None or not hyp.hypstr.strip():
        return [], []
    decoder.set_alignment()
    decoder.start_utt()
    decoder.process_raw(pcm, full_utt=True)
    decoder.end_utt()
    words: list[Segment] = []
    phones: list[Segment] = []
    for w in decoder.get_alignment():
        if not _filler(w.name):
            words.append((_VARIANT.sub("", w.name), w.start, w.start + w.duration - 1))
        phones += [(p.name, p.start, p.start + p.duration - 1) for p in w]
    return words, phones


def _wants_words(
    mode: str, log_p: np.ndarray | None, audible: np.ndarray, denoised: bool = False
) -> bool:
    """Whether a piece's words are recognized (``RecognizerOptions.words``, ``mode``): with
    ``"auto"``, where the classifier is unsure of it — the mean entropy of its ``(frames, 15)``
    ``log_p`` over the ``(frames,)`` ``audible`` frames at least :data:`WORDS_ENTROPY`, or
    :data:`WORDS_ENTROPY_IN_NOISE` where its features had the noise ``denoised`` (no
    classifier, no words)."""
    from vtts.speech.viseme_classifier import entropies

    if mode != "auto" or log_p is None:
        return mode == "always"
    m = min(log_p.shape[0], audible.size)
    heard = audible[:m]
    least = WORDS_ENTROPY_IN_NOISE if denoised else WORDS_ENTROPY
    return bool(heard.any()) and float(entropies(log_p[:m])[heard].mean()) >= least


def segments_to_phones(
    names: list[str], first: np.ndarray, last: np.ndarray, n_frames: int
) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame phone index and viseme from the decoder's segments (``names`` with their
    ``first`` and ``last`` frames, inclusive): ``(n_frames,)`` int32 index into ``names`` (-1
    where none) and ``(n_frames,)`` int8 viseme (0 for what is not a phone)."""
    index = np.full(n_frames, -1, np.int32)
    vis = np.zeros(n_frames, np.int8)
    for k, (name, a, b) in enumerate(zip(names, first, last, strict=True)):
        a, b = max(int(a), 0), min(int(b) + 1, n_frames)
        if b <= a:
            continue
        index[a:b] = k
        vis[a:b] = phone_viseme(name)
    return index, vis


def _filler(name: str) -> bool:
    """Whether a decoder's word or phone name is silence or a filler, not speech."""
    return name in NOT_PHONES or name.startswith(("<", "[", "+"))


def phone_viseme(name: str) -> int:
    """The viseme of a decoder's phone name (0 for silence and fillers), or of a classifier's
    (:data:`CLASS_NAMES`)."""
    if name in _CLASS_VISEMES:
        return _CLASS_VISEMES[name]
    if _filler(name):
        return 0
    try:
        return viseme_of(name, alphabet="arpabet")
    except SpeechError:
        return 0


def merge_energy(
    vis: np.ndarray,
    index: np.ndarray,
    frames: EnergyFrames,
    lv: Levels,
    fill: bool = True,
    closure: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The recognized visemes ``vis`` ``(n,)`` with the energy's where audible frames have no
    phone (``fill``), and recognized phones lying wholly in inaudible frames made pauses —
    except, given ``closure`` ``(n,)`` (the classifier's probability of p b m per frame), a
    bilabial (viseme 1) of at most :data:`CLOSURE_FRAMES` frames between two phones that are
    heard, where the mean of ``closure`` is at least :data:`CLOSURE_P`: a stop's silent closure
    (``b`` of "back" between two vowels), whose silence is the lips shut. Returns ``(visemes,
    filled)``: ``(n,)`` int8, and ``(n,)`` bool, the frames filled."""
    audible = frames.db > lv.audible
    out = vis.copy()
    # a phone in inaudible frames only is a pause (a closure inside a word is audible around it)
    if index.size:
        valid = index >= 0
        heard = np.zeros(int(index.max()) + 2, bool)
        np.logical_or.at(heard, index[valid & audible], True)
        silent = valid & ~heard[np.where(valid, index, -1)]
        if closure is not None:
            silent &= ~_silent_closures(vis, index, heard, closure)
        out[silent] = 0
    filled = np.zeros(vis.shape, bool)
    if fill:
        by_energy = energy_visemes(frames, lv)
        filled = audible & (out == 0) & (by_energy != 0)
        out[filled] = by_energy[filled]
    return out, filled


def _silent_closures(
    vis: np.ndarray, index: np.ndarray, heard: np.ndarray, closure: np.ndarray
) -> np.ndarray:
    """``(n,)`` bool, the frames of bilabial phones (runs of one ``index`` ``(n,)`` with viseme
    1 in ``vis`` ``(n,)``) of at most :data:`CLOSURE_FRAMES` frames whose phones before and
    after are ``heard`` (by phone index) and whose mean ``closure`` ``(n,)`` is at least
    :data:`CLOSURE_P`."""
    key = index.astype(np.int64) * 16 + vis
    edges = np.concatenate([[0], np.flatnonzero(np.diff(key)) + 1, [vis.size]])
    keep = np.zeros(vis.size, bool)
    for k in range(1, edges.size - 2):
        a, b = edges[k], edges[k + 1]
        before, after = index[a - 1], index[b]
        if (vis[a] == 1 and index[a] >= 0 and b - a <= CLOSURE_FRAMES and before >= 0
                and after >= 0 and heard[before] and heard[after]
                and float(np.mean(closure[a:b])) >= CLOSURE_P):  # fmt: skip
            keep[a:b] = True
    return keep


def frames_to_phones(
    vis: np.ndarray, index: np.ndarray, names: list[str], filled: np.ndarray, duration: float
) -> list[Phone]:
    """Phones from per-frame visemes: a run of frames with one phone index and viseme is one
    phone (frame ``k`` spans ``[k, k + 1) * FRAME_S``), named by the decoder or by the energy;
    the last phone ends at ``duration``."""
    n = vis.size
    if n == 0:
        return [Phone(0.0, duration, "SIL", 0)]
    key = np.where(filled, -2, index).astype(np.int64) * 16 + vis
    edges = np.concatenate([[0], np.flatnonzero(np.diff(key)) + 1, [n]])
    phones = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        v = int(vis[a])
        if filled[a]:
            name = ENERGY_NAMES.get(v, "~")
        elif v == 0:
            name = "SIL"
        else:
            name = names[index[a]]
        start = a * FRAME_S
        end = duration if b == n else b * FRAME_S
        phones.append(Phone(start, max(end, start), name, v))
    # neighbouring pauses are one
    merged: list[Phone] = []
    for p in phones:
        if merged and p.viseme == 0 and merged[-1].viseme == 0:
            merged[-1] = Phone(merged[-1].start, p.end, "SIL", 0)
        else:
            merged.append(p)
    return merged


def split_closures(
    vis: np.ndarray, index: np.ndarray, names: list[str], db: np.ndarray
) -> tuple[np.ndarray, list[str]]:
    """Bilabial phones (viseme 1) split in two where the level steps inside them: ``m p`` in
    "empty", ``m b`` in "number" — the lips close once, over a nasal's murmur then a stop's
    silent closure (or the reverse), and the classifier, whose class is all of p, b and m,
    gives one run. A phone of ``vis`` ``(n,)`` with one ``index`` ``(n,)`` over at least
    :data:`SPLIT_FRAMES` frames is cut where the mean levels (``db`` ``(n,)``, dB) of the two
    parts (each at least :data:`SPLIT_FRAMES` // 2 frames) differ most, when by at least
    :data:`SPLIT_DB`; the louder part is named :data:`MURMUR_NAME`, the quieter
    :data:`CLOSURE_NAME`. Returns the new ``index`` and ``names`` (``names`` extended); the
    visemes do not change."""
    index, names = index.copy(), list(names)
    key = index.astype(np.int64) * 16 + vis
    edges = np.concatenate([[0], np.flatnonzero(np.diff(key)) + 1, [vis.size]])
    half = SPLIT_FRAMES // 2
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        if vis[a] != 1 or index[a] < 0 or b - a < SPLIT_FRAMES:
            continue
        c = np.arange(a + half, b - half + 1)
        total = np.cumsum(np.concatenate([[0.0], db[a:b].astype(np.float64)]))
        left = total[c - a] / (c - a)
        right = (total[-1] - total[c - a]) / (b - c)
        k = int(np.argmax(np.abs(left - right)))
        if abs(left[k] - right[k]) < SPLIT_DB:
            continue
        cut = int(c[k])
        louder_first = left[k] > right[k]
        names[index[a]] = MURMUR_NAME if louder_first else CLOSURE_NAME
        names.append(CLOSURE_NAME if louder_first else MURMUR_NAME)
        index[cut:b] = len(names) - 1
    return index, names


def _cuts(db: np.ndarray, piece: int, window: int, least: int = 0) -> list[int]:
    """Frame indices where the ``(n,)`` frames of ``db`` are cut into pieces of at most
    ``piece`` frames, as few as may be — but an even number (for two processes) where each is
    still at least ``least`` frames (two where the frames are at least ``2 * least``): each
    cut at the quietest frame of the ``window`` frames around the end of its even share."""
    n = db.size
    count = 1 if n <= piece else int(np.ceil(n / (piece - window)))
    if least > 0 and count % 2 and n >= (count + 1) * least:
        count += 1
    cuts = []
    for k in range(1, count):
        lo = round(k * n / count) - window // 2
        cuts.append(lo + int(np.argmin(db[lo : lo + window])))
    return cuts


def _half(db: np.ndarray, quiet: np.ndarray) -> int:
    """Where a one-piece recording's ``(n,)`` frames (their ``db``, and which are ``quiet``:
    not audible) are cut in two for its word search (:data:`HALF_S`): in the middle of the
    longest run of quiet frames among the eighth of the frames around the middle, or at the
    quietest of them where none is quiet."""
    n = db.size
    w = max(n // 8, 1)
    lo = n // 2 - w // 2
    edges = np.flatnonzero(np.diff(np.concatenate([[0], quiet[lo : lo + w], [0]]).astype(np.int8)))
    starts, ends = edges[::2], edges[1::2]
    if starts.size:
        k = int(np.argmax(ends - starts))
        return lo + int(starts[k] + ends[k]) // 2
    return lo + int(np.argmin(db[lo : lo + w]))


def check_rate(rate: int) -> None:
    """A recording's rate must be at least :data:`MIN_RATE`."""
    if isinstance(rate, bool) or not isinstance(rate, int | np.integer) or rate < MIN_RATE:
        raise SpeechError(
            f"the audio is sampled at {rate} Hz; recognizing speech needs at least {MIN_RATE} Hz"
        )


def recognize(
    samples: np.ndarray,
    rate: int,
    options: RecognizerOptions | None = None,
    *,
    progress: Callable[[float, float], None] | None = None,
) -> Recognition:
    """The phones of ``(n,)`` float ``samples`` in [-1, 1] at ``rate`` Hz (at least
    :data:`MIN_RATE`), recognized by PocketSphinx (see the module docstring).

    The audio is resampled to :data:`DECODER_RATE` and decoded in pieces of at most
    :data:`PIECE_S` cut at quiet frames, one utterance each (each its own cepstral mean), in
    :func:`workers` processes (``RecognizerOptions.workers``; an even number of pieces of
    :data:`MIN_PIECE_S` at least, for two): piece ``i`` in process ``i % workers``, this one
    first; a recording of one piece and at least 2 * :data:`HALF_S` has its word search in
    two halves, the second in the worker (:func:`_half`, :meth:`_Pieces.piece`). Each
    piece's and half's result is its own (:class:`_Pieces`), the same in any process and
    whatever the number of workers; ``progress(done_s, total_s)`` is called after each piece.
    Raises :class:`SpeechError` for a rate below :data:`MIN_RATE`; silence gives one pause."""
    # in 30 s blocks: resample_poly works in float64, and 30 minutes at 48 kHz whole would
    # take over a gigabyte
    from vtts.speech.audio import resample_in_blocks as resample
    from vtts.threads import one_blas_thread

    options = options or RecognizerOptions()
    check_rate(rate)
    x = np.nan_to_num(np.asarray(samples, dtype=np.float32), nan=0.0)
    duration = len(x) / rate
    count = workers(options, duration)
    # BLAS on one thread: the classifier's products are small (a second thread cost a quarter
    # more CPU for the same wall time), and the other core is the worker's
    with one_blas_thread():
        x = resample(np.clip(x, -1.0, 1.0), int(rate), DECODER_RATE)
        frames = energy_frames(x, DECODER_RATE)
        n = frames.db.size
        lv = levels(frames.db)
        hop = int(DECODER_RATE * FRAME_S)
        audible = frames.db > lv.audible
        heard = bool(np.any(audible))
        cuts = _cuts(frames.db, int(PIECE_S / FRAME_S), int(CUT_WINDOW_S / FRAME_S),
                     int(MIN_PIECE_S / FRAME_S))  # fmt: skip
        bounds = list(zip([0, *cuts], [*cuts, n], strict=True))
        half = _half(frames.db, ~audible) if not cuts and n >= 2 * HALF_S / FRAME_S else None
        # a steady loud sound (music, loud noise) lacks speech's rise and fall: the
        # classifier, trained on speech, would see visemes in it; PocketSphinx and the energy
        # judge it alone
        pieces = _Pieces(options, options.classifier and heard and not lv.steady, heard, count)
        names: list[str] = []
        first: list[int] = []
        last: list[int] = []
        closure = np.zeros(n, np.float32) if pieces.classifier is not None else None
        words: list[TimedWord] = []
        jobs = [(x[a * hop : b * hop], audible[a:b], half) for a, b in bounds]  # views
        with _Workers(min(count, len(jobs)), pieces.piece, jobs) as pool:
            for (a, b), found in zip(bounds, pool.results(), strict=True):
                names += found.names
                first += [a + f for f in found.first]
                last += [a + e for e in found.last]
                if closure is not None:
                    closure[a : a + found.closure.size] = found.closure
                words += [TimedWord((a + f) * FRAME_S, (a + e + 1) * FRAME_S, w)
                          for w, f, e in found.words]  # fmt: skip
                if progress is not None:
                    progress(min(b * FRAME_S, duration), duration)
    pieces.keep_decoders()  # every piece decoded: for the next recognition in this process
    index, vis = segments_to_phones(names, np.array(first), np.array(last), n)
    vis, filled = merge_energy(vis, index, frames, lv, options.fill, closure)
    if pieces.classifier is not None:
        index, names = split_closures(vis, index, names, frames.db)
    phones = frames_to_phones(vis, index, names, filled, duration)
    return Recognition(
        phones,
        duration,
        recognized=float(np.sum(audible & (vis != 0) & ~filled) * FRAME_S),
        filled=float(np.sum(filled) * FRAME_S),
        visemes=vis,
        words=[TimedWord(w.start, min(w.end, duration), w.label) for w in words],
    )


#: The CPUs a recognition in this process may count on (:func:`set_cpus`); None: all it may
#: run on.
_CPUS: int | None = None


def set_cpus(count: int | None) -> None:
    """Let :func:`recognize` in this process count on at most ``count`` CPUs — a batch worker
    sharing the machine's cores with others (``vtts.batch``): at 1 it decodes in this process
    alone, as a second process would only take another worker's core; None: every CPU this
    process may run on (the default)."""
    global _CPUS
    if count is not None and (isinstance(count, bool) or not isinstance(count, int) or count < 1):
        raise ValueError(f"CPUs must be a whole number of at least 1 or None, got {count!r}")
    _CPUS = count


def workers(options: RecognizerOptions, duration: float) -> int:
    """How many processes :func:`recognize` decodes a recording of ``duration`` s in:
    ``options.workers``, or where that is None, two where the recording makes two pieces (of
    at least :data:`MIN_PIECE_S`) or its word search two halves (:data:`HALF_S`) and this
    process may run on two CPUs or more (of those :func:`set_cpus` allows), else one."""
    if options.workers is not None:
        return options.workers
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    cpus = min(cpus or 1, _CPUS) if _CPUS is not None else cpus or 1
    forks = hasattr(os, "fork")
    least = 2 * min(MIN_PIECE_S, HALF_S)
    return 2 if duration >= least and cpus >= 2 and forks else 1


@dataclass
class _Found:
    """What :meth:`_Pieces.piece` found in one piece, its frames counted from the piece's
    first: the phones' ``names``, ``first`` and ``last`` frames (inclusive); ``closure``,
    ``(frames,)`` float32, the classifier's probability of p b m (empty without it); ``words``,
    ``(word, first, last)``."""

    names: list[str]
    first: list[int]
    last: list[int]
    closure: np.ndarray
    words: list[Segment]


class _Pieces:
    """The recognizer of one process (:func:`recognize`'s or a worker's): ``options``; the
    viseme classifier where ``classify``; PocketSphinx's decoders, made when first needed,
    where ``decode`` (there is audible sound) and the classifier wants their evidence;
    ``processes``, how many a piece's word search in halves may use (the second half's
    search started in a worker before the classifier, and ended where the classifier wants
    no words: :meth:`piece`). The decoders' features
    are made anew for each piece or half (``reinit_feat``: the dither's random numbers and
    the cepstral mean from the start, some 0.1 ms), so that what a piece gives does not
    depend on the pieces decoded before it: on how many processes, in which order."""

    def __init__(
        self, options: RecognizerOptions, classify: bool, decode: bool, processes: int = 1
    ) -> None:
        self.options, self.classify, self.decode = options, classify, decode
        self.processes = processes
        self.classifier = None
        if classify:
            from vtts.speech.viseme_classifier import load_classifier

            weights = None if options.weights is None else Path(options.weights)
            self.classifier = load_classifier(weights)
        c = self.classifier
        self.use_decoder = decode and (c is None or c.evidence > 0 or c.evidence_per_nat > 0)
        self._decoder = self._word_decoder = None

    def _phone_key(self) -> tuple:
        o = self.options
        return ("phones", o.language_weight, o.beam, o.phone_beam, o.dither)

    def _word_key(self) -> tuple:
        return ("words", self.options.dither)

    def keep_decoders(self) -> None:
        """Keep this recognizer's decoders for the next one in this process
        (:func:`release_decoders`); call it only where every piece was decoded to its end."""
        for key, decoder in ((self._phone_key(), self._decoder),
                             (self._word_key(), self._word_decoder)):  # fmt: skip
            if decoder is not None:
                _keep(key, decoder)
        self._decoder = self._word_decoder = None

    def piece(self, x: np.ndarray, audible: np.ndarray, half: int | None = None) -> _Found:
        """The phones of one piece, ``(n,)`` float32 samples at :data:`DECODER_RATE` whose
        ``(frames,)`` bool ``audible`` frames are louder than the recording's audible level;
        given ``half``, a frame, its words are searched for in the frames before it and from
        it on, each its own utterance, in up to :attr:`processes` processes
        (:class:`_Workers`)."""
        options, classifier = self.options, self.classifier
        n = audible.size
        pcm = np.round(x * 32767.0).astype(np.int16).tobytes() if self.use_decoder else b""
        spans, jobs = self._spans(n, half)
        # the second half's search starts in the worker before the classifier has judged
        # whether the words are wanted, and is ended where they are not: the classifier's
        # time is hidden behind it
        ahead = self.use_decoder and options.words != "never"
        count = min(self.processes, len(jobs)) if ahead else 1
        with _Workers(count, self._words, [(pcm, lo, hi) for lo, hi in jobs]) as pool:
            log_p, denoised = None, False
            if classifier is not None:
                log_p, _, denoised = classifier.warped_log_posteriors(x)
            # PocketSphinx's phones: the words' where they are recognized, else the phone
            # loop's — but not in noise (the classifier hears the piece better with the noise
            # taken out), where the phone loop's phones mislead the classifier more than they
            # help it
            segments: list[Segment] = []
            found: list[Segment] = []
            evidence = None
            decoded = False
            if self.use_decoder and _wants_words(options.words, log_p, audible, denoised):
                found, segments = self._gather(spans, jobs, pool.results())
                evidence = WORD_EVIDENCE if segments else None
                decoded = bool(segments)
            else:
                pool.cancel()
        if self.use_decoder and not decoded and not denoised:
            self._decoder = self._decoder or _take(self._phone_key(), lambda: make_decoder(options))
            self._decoder.reinit_feat()
            self._decoder.start_utt()
            self._decoder.process_raw(pcm, no_search=False, full_utt=True)
            self._decoder.end_utt()
            segments = [(s.word, s.start_frame, s.end_frame) for s in self._decoder.seg() or ()]
            decoded = True
        p_names = [name for name, _, _ in segments]
        if log_p is None:
            return _Found(p_names, [f for _, f, _ in segments], [e for _, _, e in segments],
                          np.zeros(0, np.float32), found)  # fmt: skip
        # PocketSphinx's visemes are evidence for the classifier; its phones name the
        # classifier's runs where they agree
        p_first = np.array([f for _, f, _ in segments], int)
        p_last = np.array([e for _, _, e in segments], int)
        p_index, p_vis = segments_to_phones(p_names, p_first, p_last, n)
        run = classifier.smoothed(log_p, p_vis if decoded else None, evidence)[:n]
        names: list[str] = []
        edges = np.concatenate([[0], np.flatnonzero(np.diff(run)) + 1, [run.size]])
        for s, e in zip(edges[:-1], edges[1:], strict=True):
            v, mid = int(run[s]), (s + e) // 2
            agree = decoded and p_vis[mid] == v and p_index[mid] >= 0
            names.append(p_names[p_index[mid]] if agree else CLASS_NAMES[v])
        return _Found(names, [int(s) for s in edges[:-1]], [int(e) - 1 for e in edges[1:]],
                      np.exp(log_p[: run.size, 1]).astype(np.float32), found)  # fmt: skip

    @staticmethod
    def _spans(n: int, half: int | None) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
        """The word search's utterances of a piece of ``n`` frames: one, or given ``half``, a
        frame, two, the frames before it and from it on — ``(spans, heard)``, the frames each
        keeps and those it hears, :data:`CONTEXT_FRAMES` of the other around its own (the
        language model's context of the first words after the cut)."""
        spans = [(0, n)] if half is None else [(0, half), (half, n)]
        c = CONTEXT_FRAMES
        return spans, [(max(a - c, 0), min(b + c, n)) for a, b in spans]

    @staticmethod
    def _gather(
        spans: list[tuple[int, int]], heard: list[tuple[int, int]], results
    ) -> tuple[list[Segment], list[Segment]]:
        """The words and their phones of a piece from what its utterances' searches gave
        (``results``, :func:`decode_words` of each of ``heard``, :meth:`_spans`), each keeping
        what lies in its own span: a word by its middle frame, a phone cut at the span's
        ends."""
        words: list[Segment] = []
        phones: list[Segment] = []
        for (a, b), (lo, _), (w, p) in zip(spans, heard, results, strict=True):
            words += [(name, f + lo, e + lo) for name, f, e in w if a <= lo + (f + e) // 2 < b]
            for name, f, e in p:
                f, e = max(f + lo, a), min(e + lo, b - 1)
                if f <= e:
                    phones.append((name, f, e))
        return words, phones

    def _words(self, pcm: bytes, a: int, b: int) -> tuple[list[Segment], list[Segment]]:
        """:func:`decode_words` of frames ``a`` to ``b`` (exclusive) of a piece's ``pcm``, as
        their own utterance (frames counted from ``a``), with this process's word decoder (made,
        or taken from those kept, when first needed)."""
        self._word_decoder = self._word_decoder or _take(
            self._word_key(), lambda: make_word_decoder(self.options)
        )
        self._word_decoder.reinit_feat()  # as new: the result its own (see the class)
        step = 2 * int(DECODER_RATE * FRAME_S)  # bytes of a frame's int16 samples
        return decode_words(self._word_decoder, pcm[a * step : b * step])


#: PocketSphinx's decoders kept between recognitions in this process, idle, by what they were
#: made with: at most one of each kind (the word decoder holds some 90 MB), the oldest
#: dropped beyond :data:`MAX_KEPT`. Each piece's decoders start anew (:class:`_Pieces`), so a
#: kept decoder finds what a new one would; a decoder is taken by one recognition at a time.
_KEPT: dict[tuple, object] = {}
_KEPT_LOCK = threading.Lock()
MAX_KEPT = 3


def _take(key: tuple, make: Callable[[], object]):
    """The kept decoder made with ``key`` (no longer kept: it is the caller's), else ``make()``."""
    with _KEPT_LOCK:
        decoder = _KEPT.pop(key, None)
    return make() if decoder is None else decoder


def _keep(key: tuple, decoder) -> None:
    """Keep ``decoder``, made with ``key``, for the next recognition (one of each kind)."""
    with _KEPT_LOCK:
        _KEPT.setdefault(key, decoder)
        while len(_KEPT) > MAX_KEPT:
            del _KEPT[next(iter(_KEPT))]


def release_decoders() -> int:
    """Drop the decoders :func:`recognize` keeps between recognitions in this process (their
    memory goes back once nothing else holds them); how many were kept. The next recognition
    makes new ones (some 0.35 s with words)."""
    with _KEPT_LOCK:
        count = len(_KEPT)
        _KEPT.clear()
    return count


class _Workers:
    """``count`` processes doing ``work(*job)`` for each of ``jobs`` (:meth:`results`): a
    recording's pieces (:meth:`_Pieces.piece`), or a piece's halves of its word search
    (:meth:`_Pieces._words`). This one and ``count - 1`` workers forked from it on entering
    (:func:`_forked`), which have ``work`` and ``jobs`` as this process has them (and so the
    classifier, and a copy of the decoders it kept); worker ``k`` does the jobs ``i`` where
    ``i % count == k + 1`` (:func:`_serve`) and sends back what each gave (it must pickle),
    nothing sent to it. A worker that fails (it could not be forked, or died) leaves its jobs
    to this process. Every process runs BLAS on one thread (:func:`recognize`'s setting,
    which the workers inherit)."""

    def __init__(self, count: int, work: Callable, jobs: list) -> None:
        self.count, self.work, self.jobs = count, work, jobs
        self._links: list = []  # [process, connection (None once failed)] per worker

    def __enter__(self) -> _Workers:
        # forked, not started: a new interpreter would take longer to start than a short
        # recording takes to decode (and multiprocessing's spawn runs the caller's main script
        # again in each worker)
        import socket
        from multiprocessing.connection import Connection

        die = _death_signal() if self.count > 1 else None
        parent = os.getpid()
        for k in range(self.count - 1):
            mine, theirs = socket.socketpair()
            try:
                pid = os.fork()
            except OSError:
                mine.close()
                theirs.close()
                self._links.append([None, None])
                continue
            if pid == 0:
                mine.close()
                others = [link for _, link in self._links if link is not None]
                _forked(theirs, others, self.work, self.jobs[k + 1 :: self.count], die, parent)
            theirs.close()
            self._links.append([_Child(pid), Connection(mine.detach())])
        return self

    def results(self):
        """What each job gave, in order: job ``i`` done here where ``i % count`` is 0 (ahead
        of the others while a worker's answer is not there), else by worker ``i % count -
        1``, or here where that worker failed. A job's result is the same wherever it is done
        (:class:`_Pieces`)."""
        work, jobs = self.work, self.jobs
        mine = {}  # this process's jobs done ahead, by index
        ahead = iter(range(0, len(jobs), self.count))

        def decode_ahead() -> bool:
            i = next(ahead, None)
            if i is not None:
                mine[i] = work(*jobs[i])
            return i is not None

        for i, job in enumerate(jobs):
            if i % self.count == 0:
                if i not in mine:
                    decode_ahead()
                yield mine.pop(i)
                continue
            k = i % self.count - 1
            # this process decodes its next jobs until the worker's answer is there
            while not self._answered(k) and decode_ahead():
                pass
            answer = self._receive(k)
            # the worker failed: its job is done here
            yield answer[0] if answer is not None else work(*job)

    def cancel(self) -> None:
        """End the workers now: their answers are not wanted (none of the jobs is done)."""
        for link in self._links:
            if link[0] is not None:
                link[0].kill()
            if link[1] is not None:
                link[1].close()
                link[1] = None

    def _answered(self, k: int) -> bool:
        """Whether worker ``k``'s next answer needs no more waiting: it is there, or the
        worker failed (this process decodes its jobs)."""
        link = self._links[k][1]
        return link is None or link.poll(0)

    def _receive(self, k: int) -> tuple | None:
        """Worker ``k``'s answer to its next job, ``(result,)``: None where it failed (and is
        given up); its :class:`SpeechError` raised."""
        from vtts.threads import SIGNAL_SLICE

        proc, link = self._links[k]
        if link is None:
            return None
        found = None
        try:
            while not link.poll(SIGNAL_SLICE):  # in slices: a signal ends the wait
                if proc.poll() is not None and not link.poll(0):
                    raise EOFError
            found = link.recv()
        except (OSError, EOFError):
            pass
        if isinstance(found, tuple):
            return found
        link.close()
        self._links[k][1] = None
        if isinstance(found, SpeechError):
            raise found
        return None

    def __exit__(self, kind, *exc) -> None:
        for proc, link in self._links:
            if proc is None:
                continue
            if kind is not None:  # this process failed: no more work for the workers
                proc.kill()
            if link is not None:
                link.close()  # a worker still sending ends (its answers are not wanted)
            try:
                proc.wait(timeout=5)
            except Exception:
                proc.kill()
                proc.wait()


class _Child:
    """A forked worker of :class:`_Workers` by its process id: ``subprocess.Popen``'s
    ``poll``, ``kill`` and ``wait`` for it."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.returncode: int | None = None

    def poll(self) -> int | None:
        """Its exit code once it has ended (reaped), else None."""
        if self.returncode is None:
            try:
                pid, status = os.waitpid(self.pid, os.WNOHANG)
            except ChildProcessError:  # reaped elsewhere
                self.returncode = -1
            else:
                if pid:
                    self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def kill(self) -> None:
        if self.poll() is None:
            try:
                os.kill(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass

    def wait(self, timeout: float | None = None) -> int:
        """Its exit code, waiting at most ``timeout`` s (``TimeoutError`` after)."""
        import time

        end = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            if end is not None and time.monotonic() > end:
                raise TimeoutError(f"worker {self.pid} still runs after {timeout} s")
            time.sleep(0.005)
        return self.returncode


@functools.cache
def _death_signal() -> Callable[[], bool] | None:
    """Linux's ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` as a call (True where it took): a forked
    worker that makes it is killed when the thread that forked it ends — its command exited
    or was killed while the worker still decoded (a command ended by SIGTERM or SIGKILL does
    not wait for the thread that recognizes its speech). None where there is no such call; a
    worker there ends when it finds its link closed, after the job at hand. Looked up before
    the fork, so that the worker only calls it."""
    import ctypes

    if not sys.platform.startswith("linux"):
        return None
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong]
    return lambda: prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0


#: ``PR_SET_PDEATHSIG`` of Linux's ``<sys/prctl.h>``.
_PR_SET_PDEATHSIG = 1


def _forked(
    sock, others: list, work: Callable, jobs: list, die: Callable[[], bool] | None, parent: int
) -> NoReturn:
    """The forked worker's life (:class:`_Workers`), on ``sock``, its end of the socket: it
    dies with the thread that forked it where ``die`` (:func:`_death_signal`) takes — and
    leaves at once where its ``parent`` (process id) is already gone —, closes ``others``
    (the parent's links to the workers forked before it), ends on a signal whose handler is
    the parent's (and ignores those the parent ignores), does ``work`` for ``jobs``
    (:func:`_serve`) and leaves with ``os._exit`` whatever happened, never returning into the
    parent's stack nor running its exit handlers."""
    code = 1
    try:
        if die is not None and die() and os.getppid() != parent:
            return  # the parent ended before the death signal was asked for
        for link in others:
            link.close()
        for name in ("SIGINT", "SIGTERM", "SIGHUP"):
            if signal.getsignal(getattr(signal, name)) not in (signal.SIG_IGN, None):
                signal.signal(getattr(signal, name), signal.SIG_DFL)
        from multiprocessing.connection import Connection

        _serve(Connection(sock.detach()), work, jobs)
        code = 0
    finally:
        os._exit(code)


def _serve(link, work: Callable, jobs: list) -> None:
    """A worker of :class:`_Workers`: ``(work(*job),)`` for each of ``jobs``, sent on
    ``link`` (a ``Connection``) in order, or the exception raised (the parent then does the
    rest itself, or raises a SpeechError)."""
    try:
        for job in jobs:
            link.send((work(*job),))
    except Exception as e:
        link.send(e if isinstance(e, SpeechError) else RuntimeError(repr(e)))
    finally:
        link.close()


def _new_lock_in_child() -> None:
    """After a fork: the kept decoders' lock anew (another thread of the parent may have held
    it at the fork, and none of them is in the child)."""
    global _KEPT_LOCK
    _KEPT_LOCK = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_new_lock_in_child)


class LiveRecognizer:
    """Visemes of audio that arrives in chunks, as soon as the decoder has them.

    ``rate``: of the PCM fed, Hz (at least :data:`MIN_RATE`). :meth:`feed` takes the next
    ``(n,)`` int16 (or float in [-1, 1]) samples and returns the visemes, ``(k,)`` int8, of the
    10 ms frames newly decided (frame ``j`` of the stream spans ``[j, j + 1) * FRAME_S`` s;
    :attr:`frames_out` counts those given so far); :meth:`finish` returns the rest. A frame's
    viseme is the decoder's partial hypothesis at the time (it may revise it later: what was
    shown stays shown). Loudness is judged against running levels (the loud frames' level
    decays by :data:`LOUD_DECAY_DB` a second; the floor rises slowly towards quieter sound).
    The decoder's utterance is restarted at a pause after :data:`RESTART_S` (or at
    :data:`PIECE_S` at the latest), so memory stays bounded however long the stream."""

    #: The running loud level falls by this many dB per second of quieter sound.
    LOUD_DECAY_DB = 1.0
    #: The running floor rises by this many dB per second of louder sound.
    FLOOR_RISE_DB = 2.0
    #: Restart the decoder's utterance at a pause of PAUSE_FRAMES after this long, s.
    RESTART_S = 10.0
    PAUSE_FRAMES = 30

    def __init__(self, rate: int, options: RecognizerOptions | None = None,
                 decoder=None) -> None:  # fmt: skip
        """``decoder``: one :func:`make_decoder` made ahead for ``options`` and not used yet
        (making one takes some 0.2 s, which a live stream need not wait for)."""
        check_rate(rate)
        self.rate = int(rate)
        self.options = options or RecognizerOptions()
        self._decoder = decoder if decoder is not None else make_decoder(self.options)
        self._resampler = StreamResampler(self.rate, DECODER_RATE)
        self._pending = np.zeros(0, np.float32)  # samples at 16 kHz not yet in a whole frame
        self._history = np.zeros(0, np.float32)  # the last window's worth, for frame energies
        self._db: list[float] = []  # this utterance's frames' dB and hiss
        self._hiss: list[float] = []
        self._loud: float | None = None
        self._floor: float | None = None
        self._utt_start = 0  # stream frame where the decoder's utterance began
        self._in_utt = 0  # frames fed to this utterance
        self._quiet_run = 0
        self.frames_out = 0
        self._decoder.start_utt()

    # -- public -------------------------------------------------------------------------------

    def feed(self, samples: np.ndarray) -> np.ndarray:
        """The next samples (``(n,)`` int16, or float32 in [-1, 1], mono at :attr:`rate`) →
        ``(k,)`` int8 visemes of the frames newly decided."""
        x = np.asarray(samples)
        if x.dtype == np.int16:
            x = x.astype(np.float32) / 32768.0
        x = np.clip(np.nan_to_num(x.astype(np.float32, copy=False), nan=0.0), -1.0, 1.0)
        y = self._resampler(x)
        self._pending = np.concatenate([self._pending, y])
        hop = int(DECODER_RATE * FRAME_S)
        whole = (self._pending.size // hop) * hop
        if whole == 0:
            return np.zeros(0, np.int8)
        block, self._pending = self._pending[:whole], self._pending[whole:]
        self._measure(block)
        pcm = np.round(block * 32767.0).astype(np.int16)
        self._decoder.process_raw(pcm.tobytes(), no_search=False, full_utt=False)
        self._in_utt += whole // hop
        out = self._decided(final=False)
        if self._in_utt * FRAME_S >= PIECE_S or (
            self._in_utt * FRAME_S >= self.RESTART_S and self._quiet_run >= self.PAUSE_FRAMES
        ):
            out = np.concatenate([out, self._restart()])
        return out

    def finish(self) -> np.ndarray:
        """The visemes of the frames not yet given (the stream ended; a partial frame counts
        as a whole one, padded with silence)."""
        hop = int(DECODER_RATE * FRAME_S)
        out = np.zeros(0, np.int8)
        if self._pending.size:
            pad = np.zeros(hop - self._pending.size % hop, np.float32)
            self._pending = np.concatenate([self._pending, pad])
            out = self.feed(np.zeros(0, np.float32))
        self._decoder.end_utt()
        out = np.concatenate([out, self._decided(final=True)])
        self._decoder.start_utt()  # ready again (a finished recognizer may be fed more)
        self._utt_start += self._in_utt
        self._in_utt = 0
        self._db, self._hiss = [], []
        return out

    # -- inside -------------------------------------------------------------------------------

    def _measure(self, block: np.ndarray) -> None:
        """Frame energies of ``block`` (whole frames at 16 kHz) with the running levels."""
        hop = int(DECODER_RATE * FRAME_S)
        # two frames before the block give its first frames' windows their left context
        ctx = np.concatenate([self._history, block])
        fr = energy_frames(ctx, DECODER_RATE)
        lo = self._history.size // hop
        db, hiss = fr.db[lo:], fr.hiss[lo:]
        self._history = ctx[-2 * hop :]
        for d, h in zip(db.tolist(), hiss.tolist(), strict=True):
            self._update_levels(d)
            self._db.append(d)
            self._hiss.append(h)
            lv = Levels(self._loud, self._floor)
            self._quiet_run = 0 if d > lv.audible else self._quiet_run + 1

    def _update_levels(self, d: float) -> None:
        if self._loud is None:
            self._loud = self._floor = d
            return
        self._loud = max(d, self._loud - self.LOUD_DECAY_DB * FRAME_S)
        self._floor = min(d, self._floor + self.FLOOR_RISE_DB * FRAME_S)

    def _decided(self, *, final: bool) -> np.ndarray:
        """Visemes of this utterance's frames from :attr:`frames_out` up to the decoder's last
        segment (all frames fed when ``final``)."""
        names, first, last = [], [], []
        for s in self._decoder.seg() or ():  # None before the first hypothesis
            names.append(s.word)
            first.append(s.start_frame)
            last.append(s.end_frame)
        done = self.frames_out - self._utt_start
        upto = self._in_utt if final else min(max(last, default=-1) + 1, self._in_utt)
        if upto <= done:
            return np.zeros(0, np.int8)
        index, vis = segments_to_phones(names, np.array(first), np.array(last), upto)
        frames = EnergyFrames(
            np.asarray(self._db[:upto], np.float32), np.asarray(self._hiss[:upto], np.float32)
        )
        lv = Levels(float(self._loud), float(self._floor))
        # only the new frames: a phone's audibility is judged on what has been heard of it
        vis, _ = merge_energy(vis[done:], index[done:], _tail(frames, done), lv, self.options.fill)
        self.frames_out += upto - done
        return vis

    def _restart(self) -> np.ndarray:
        self._decoder.end_utt()
        out = self._decided(final=True)
        self._utt_start += self._in_utt
        self._in_utt = 0
        self._db, self._hiss = [], []
        self._decoder.start_utt()
        return out


def _tail(frames: EnergyFrames, start: int) -> EnergyFrames:
    return EnergyFrames(frames.db[start:], frames.hiss[start:])


class StreamResampler:
    """Resampling of a stream in chunks, its state kept between them: an 8th-order Butterworth
    low-pass below the lower Nyquist frequency (when going down), then linear interpolation at
    the new rate's instants. Chunk boundaries leave no seam."""

    def __init__(self, rate: int, to: int) -> None:
        from scipy.signal import butter, sosfilt_zi

        self.rate, self.to = int(rate), int(to)
        self._sos = None
        if self.to < self.rate:
            self._sos = butter(8, 0.45 * self.to, fs=self.rate, output="sos")
            self._zi = sosfilt_zi(self._sos) * 0.0
        self._t = 0.0  # the next output instant, in input samples from the carried sample
        self._carry: np.ndarray | None = None  # the last input sample (filtered)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        if self.rate == self.to:
            return np.asarray(x, np.float32)
        from scipy.signal import sosfilt

        x = np.asarray(x, np.float64)
        if self._sos is not None and x.size:
            x, self._zi = sosfilt(self._sos, x, zi=self._zi)
        if self._carry is not None:
            x = np.concatenate([self._carry, x])
        if x.size < 2:
            self._carry = x
            return np.zeros(0, np.float32)
        step = self.rate / self.to
        pos = np.arange(self._t, x.size - 1, step)
        out = np.interp(pos, np.arange(x.size), x).astype(np.float32)
        nxt = (pos[-1] + step) if pos.size else self._t
        self._carry = x[-1:]
        self._t = nxt - (x.size - 1)
        return out
