"""Speech from espeak-ng: audio, timed phonemes and SSML mark times in one clock.

espeak-ng reports, through its C API, a phoneme event for every phone and a mark event for every
SSML ``<mark/>``, each with the index of the audio sample where it happens (``sample``; the
``audio_position`` field is the same instant in milliseconds, truncated). :func:`synthesize`
uses ``sample / rate``, so phone and mark times are exact in the audio's own clock.

Facts measured with espeak-ng 1.51 (Debian ``espeak-ng``) that shape this module:

- ``espeak_Initialize`` in synchronous mode returns 22050 Hz; audio comes as int16 chunks.
- The first phone starts 264 samples (12 ms) into the audio; :func:`synthesize` fills that with a
  pause phone ``_`` so the phones cover the audio from 0 to its end. With ``espeakENDPAUSE`` every
  clause ends in a ``_:`` pause (about 300 ms at the end of a sentence); the last event of a clause
  is a zero-length ``_`` at the clause's last sample (dropped: phones never have zero length).
- A ``<mark/>`` reports the sample where the next word starts (the start of the pause before it at
  the end of the text). Known espeak-ng bugs, worked around here: a mark right after a
  sentence-final full stop is never reported (espeak-ng issue 920), and a name in single quotes
  comes back with the quote and following characters (issue 921); names are also returned
  without decoding ``&amp;``. So every mark is sent to espeak-ng as ``<mark name="K"/>`` (its index)
  and mapped back to the real name; a mark espeak loses gets the time of the next word event
  after its place in the text.
- Audio and events are identical from run to run for the **first** synthesis in a process, but
  not for later ones in the same process: espeak-ng keeps static state between calls (the pitch
  flutter index, the roughness cycle counter, the automatic gain, libc ``rand()`` for breath
  noise), so phone boundaries move by a few samples and the audio differs. Each synthesis
  therefore runs in a fresh worker process (``vtts/speech/_espeak.py``, ~25 ms overhead), which
  makes every call deterministic and keeps espeak's global state, and any crash, out of the caller
  (so no lock is needed here).
"""

from __future__ import annotations

import atexit
import contextlib
import json
import os
import re
import string
import subprocess
import sys
import threading
import xml.parsers.expat
from dataclasses import dataclass, field, replace
from functools import cache
from pathlib import Path

import numpy as np

from vtts.errors import SpeechError
from vtts.speech.engine import BilabialTiming, LipTiming
from vtts.speech.phonemes import PAUSES, Mark, Phone, viseme_of

__all__ = [
    "Mark", "Phone", "Speech", "Voice", "Word", "escape", "keep_workers_ready", "synthesize",
    "voices",
]  # fmt: skip

_WORKER = Path(__file__).with_name("_espeak.py")
#: Environment variable naming another espeak-ng shared library to load.
LIBRARY_ENV = "VTTS_ESPEAK_LIBRARY"

# espeak_Synth flags (speak_lib.h)
CHARS_UTF8 = 0x1
SSML = 0x10
ENDPAUSE = 0x1000

EVENT_WORD = 1
EVENT_MARK = 3
EVENT_PHONEME = 7

#: Speaking rate limits, words per minute (espeak-ng's range without its sonic speed-up).
RATE_RANGE = (80, 450)
#: Pitch limits (espeak-ng's 0–99, 50 normal).
PITCH_RANGE = (0, 99)

INSTALL_HINT = (
    "espeak-ng is missing: install it with 'apt-get install espeak-ng' "
    "('make test' and 'make demo' install it when run as root)"
)

_VOICE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_+\-/ ().,]{0,47}$")
_SPEAK_ROOT = re.compile(r"^\s*(<\?xml[^>]*\?>\s*)?<speak[\s>/]", re.DOTALL)
_START_TAG = re.compile(r"""<[^\s/>!?]+(?:\s+[^\s=/>]+\s*=\s*(?:"[^"]*"|'[^']*'))*\s*(/?)>""")


@dataclass(frozen=True)
class Voice:
    """An espeak-ng voice.

    name        e.g. ``English (America)``
    language    its main language code, e.g. ``en-us``; pass it (or ``identifier``) as ``voice``
    languages   every language code it speaks, most preferred first
    gender      ``"male"``, ``"female"`` or ``""``
    identifier  the voice file, e.g. ``gmw/en-US``
    """

    name: str
    language: str
    languages: tuple[str, ...]
    gender: str
    identifier: str


@dataclass(frozen=True)
class Word:
    """A spoken word: ``start`` and ``end`` in s, ``position`` and ``length`` in characters of
    the input, ``text`` the input's characters there (XML entities decoded).

    espeak-ng's word event comes up to a phone early (at the start of the last phone of the
    previous word, sometimes), but every phone event carries the text position of its word: a
    word spans from its first to its last phone that is not a pause. Words espeak speaks as
    several (``123``) are one word; a word with no phones is left out. ``text`` is the
    whitespace-delimited word of the input at ``position`` with the punctuation around it
    stripped.
    """

    start: float
    position: int
    length: int
    end: float | None = None
    text: str = ""


@dataclass
class Speech:
    """What :func:`synthesize` returns.

    audio     ``(n,)`` int16 samples, mono, at ``rate`` Hz
    phonemes  phones in order, covering the audio from 0 to its end without gaps or overlaps;
              ``phoneme`` is espeak-ng's name (``aI``), ``viseme`` its MPEG-4 viseme, ``ipa``
              espeak-ng's IPA when it was asked for (non-English voices by default)
    marks     one per SSML ``<mark/>`` of the input, in document order, with its time (s); names
              may repeat. A mark right before a word (only spaces, other marks or opening quotes
              and brackets between) is at the word's first phone, as in ``words``; another at
              espeak-ng's mark event
    words     the spoken words (start and end s, position in the input)
    voice     the voice that spoke
    """

    audio: np.ndarray
    rate: int
    phonemes: list[Phone]
    marks: list[Mark]
    words: list[Word] = field(default_factory=list)
    voice: Voice | None = None

    @property
    def duration(self) -> float:
        """Length of the audio in s."""
        return self.audio.shape[0] / self.rate

    @property
    def language(self) -> str:
        return self.voice.language if self.voice else "en"


def escape(text: str) -> str:
    """``text`` made safe as SSML character data (``&``, ``<``, ``>`` escaped, as
    ``xml.sax.saxutils.escape`` does; that module imports urllib and http, a tenth of the
    imports of ``vtts say``)."""
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def _unescape(text: str) -> str:
    """SSML character data back to text: the five XML entities (as ``xml.sax.saxutils
    .unescape`` with ``&quot;`` and ``&apos;``, ``&amp;`` last)."""
    for entity, char in (("&lt;", "<"), ("&gt;", ">"), ("&quot;", '"'), ("&apos;", "'")):
        text = text.replace(entity, char)
    return text.replace("&amp;", "&")


# ---- running espeak-ng -----------------------------------------------------------------------


class _Spares:
    """espeak-ng workers started ahead of their request (:func:`keep_workers_ready`)."""

    def __init__(self) -> None:
        self.count = 0
        self.ready: list[subprocess.Popen] = []
        self.lock = threading.Lock()

    def take(self) -> subprocess.Popen:
        """A started worker: a spare if one is ready, else a new one."""
        with self.lock:
            proc = self.ready.pop() if self.ready else None
        if proc is not None and proc.poll() is None:
            return proc
        return _start_worker()

    def refill(self) -> None:
        with self.lock:
            missing = self.count - len(self.ready)
        started = [_start_worker() for _ in range(max(missing, 0))]
        with self.lock:
            self.ready += started

    def drain(self) -> None:
        with self.lock:
            idle, self.ready = self.ready, []
        for proc in idle:  # a worker whose request never comes reads the end of its input
            with contextlib.suppress(OSError, subprocess.TimeoutExpired):
                proc.communicate(timeout=5)


_SPARES = _Spares()
atexit.register(_SPARES.drain)


def keep_workers_ready(count: int) -> None:
    """Keep ``count`` espeak-ng workers started and waiting, each for one request, so that a
    synthesis does not wait for its worker's start-up (the interpreter and its imports: most of
    a short clause's time). For servers (``vtts serve``); 0, the default, starts each worker at
    its request and stops the waiting ones. Each worker still synthesizes once, so the same text
    still gives the same audio."""
    _SPARES.count = max(int(count), 0)
    if _SPARES.count == 0:
        _SPARES.drain()
    else:
        _SPARES.refill()


def _start_worker() -> subprocess.Popen:
    try:
        return subprocess.Popen(
            [sys.executable, "-I", "-S", str(_WORKER)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
    except OSError as e:
        raise SpeechError(f"cannot start the espeak-ng worker: {e}") from None


def _run_worker(request: dict, timeout: float) -> tuple[dict, bytes]:
    library = os.environ.get(LIBRARY_ENV)
    if library:
        request = {**request, "library": library}
    proc = _SPARES.take()
    try:
        stdout, stderr = proc.communicate(json.dumps(request).encode("utf-8"), timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        raise SpeechError(f"espeak-ng did not finish within {timeout:.0f} s") from None
    except BaseException:
        proc.kill()
        proc.communicate()
        raise
    finally:
        if _SPARES.count:
            _SPARES.refill()
    proc = subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr)
    head, newline, payload = proc.stdout.partition(b"\n")
    try:
        header = json.loads(head) if newline else None
    except ValueError:
        header = None
    if not isinstance(header, dict):
        tail = proc.stderr.decode("utf-8", "replace").strip().splitlines()[-3:]
        raise SpeechError(
            f"espeak-ng failed (worker exit code {proc.returncode})"
            + (": " + " | ".join(tail) if tail else "")
        )
    if not header.get("ok"):
        kind = header.get("kind")
        if kind == "missing":
            raise SpeechError(f"{INSTALL_HINT} ({header.get('message')})")
        if kind == "voice":
            raise SpeechError(_voice_message(header["message"], request.get("voice", ""), header))
        raise SpeechError(f"espeak-ng failed: {header.get('message')}")
    return header, payload


def _voice_from(raw: dict) -> Voice:
    langs = tuple(name for _, name in raw.get("languages", []))
    gender = {1: "male", 2: "female"}.get(raw.get("gender", 0), "")
    return Voice(raw.get("name", ""), langs[0] if langs else "", langs, gender, raw["identifier"])


def _voice_message(message: str, asked: str, header: dict) -> str:
    known = [_voice_from(v) for v in header.get("voices", [])]
    prefix = asked.partition("+")[0].split("-")[0].lower()
    near = [v.language for v in known if v.language.split("-")[0] == prefix]
    common = ["en-us", "en-gb", "fr-fr", "de", "es", "it", "pt-br", "nl", "ru", "cmn"]
    present = {v.language for v in known}
    some = near or [c for c in common if c in present]
    return (
        f"{message}; voices include {', '.join(some[:10])} "
        f"('vtts voices' lists all {len(known)}; a variant is written like en-us+f3)"
    )


@cache
def _voice_list() -> tuple[Voice, ...]:
    header, _ = _run_worker({"op": "voices"}, timeout=60)
    return tuple(_voice_from(v) for v in header["voices"])


def voices(language: str | None = None) -> list[Voice]:
    """espeak-ng's voices, optionally only those speaking ``language`` (``"en"`` matches
    ``en-us``, ``en-gb-x-rp`` …)."""
    found = list(_voice_list())
    if language:
        lang = language.lower()
        found = [
            v
            for v in found
            if any(code == lang or code.startswith(lang + "-") for code in v.languages)
        ]
    return found


# ---- SSML ------------------------------------------------------------------------------------


@dataclass
class _Document:
    """The SSML sent to espeak-ng, the marks it holds and how to map positions back."""

    text: str
    marks: list[str]  # real names, by index
    mark_ends: list[int]  # 0-based position in ``text`` just after each rewritten mark tag
    # (new_start, new_end, old_start, old_end) of every rewritten span, in order
    spans: list[tuple[int, int, int, int]]
    prefix: int  # characters added in front of the caller's text
    source: str  # the caller's text

    def position(self, tp: int) -> int:
        """0-based position in the caller's text of espeak's 1-based ``text_position``."""
        p = tp - 1
        old = p
        for new_start, new_end, old_start, old_end in self.spans:
            if p < new_start:
                break
            old = old_start if p < new_end else old_end + (p - new_end)
        pos = min(max(old - self.prefix, 0), len(self.source))
        # After a full stop espeak-ng counts one character too many: step back onto the word's
        # first character when the position is its second.
        src = self.source
        if (
            0 < pos <= len(src)
            and src[pos - 1].isalnum()
            and (pos < 2 or not src[pos - 2].isalnum())
        ):
            pos -= 1
        return pos


def _ssml_document(text: str) -> _Document:
    wrapped = _SPEAK_ROOT.match(text) is None
    prefix = "<speak>" if wrapped else ""
    doc = prefix + text + ("</speak>" if wrapped else "")
    data = doc.encode("utf-8")
    found: list[tuple[int, str]] = []
    parser = xml.parsers.expat.ParserCreate()

    def start(name: str, attrs: dict[str, str]) -> None:
        if name.rpartition(":")[2] == "mark":
            found.append((parser.CurrentByteIndex, attrs.get("name", "")))

    def doctype(*_args) -> None:
        raise SpeechError("SSML with a DOCTYPE is not accepted")

    parser.StartElementHandler = start
    parser.StartDoctypeDeclHandler = doctype
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as e:
        line, col = e.lineno, e.offset + 1
        if wrapped and line == 1:
            col = max(col - len(prefix), 1)
        reason = xml.parsers.expat.ErrorString(e.code)
        raise SpeechError(
            f"the text is not well-formed SSML ({reason} at line {line}, column {col}); "
            "escape &, < and > in plain text, or pass ssml=False"
        ) from None
    # Rewrite each <mark .../> as <mark name="K"/> (see the module docstring for why).
    out: list[str] = []
    spans: list[tuple[int, int, int, int]] = []
    names: list[str] = []
    ends: list[int] = []
    last = 0
    new_len = 0
    for k, (byte_index, name) in enumerate(found):
        old_start = len(data[:byte_index].decode("utf-8"))
        m = _START_TAG.match(doc, old_start)
        if m is None:  # expat accepted it, so this cannot happen; be safe all the same
            raise SpeechError(f"cannot read the <mark> tag at character {old_start}")
        piece = doc[last:old_start]
        out.append(piece)
        new_len += len(piece)
        tag = f'<mark name="{k}"{m.group(1)}>'
        out.append(tag)
        spans.append((new_len, new_len + len(tag), old_start, m.end()))
        new_len += len(tag)
        ends.append(new_len)
        names.append(name)
        last = m.end()
    out.append(doc[last:])
    return _Document("".join(out), names, ends, spans, len(prefix), text)


# ---- synthesis -------------------------------------------------------------------------------


def synthesize(
    ssml_or_text: str,
    *,
    voice: str = "en-us",
    rate: int | None = None,
    pitch: int | None = None,
    ssml: bool = True,
    ipa: bool | None = None,
) -> Speech:
    """Speak ``ssml_or_text`` with espeak-ng; see :class:`Speech` for what comes back.

    ssml   ``True``: the text is SSML, a whole ``<speak>`` document or a fragment (wrapped in
           ``<speak>`` here), and must be well-formed XML (use :func:`escape` on plain pieces);
           ``False``: plain text, spoken as written
    voice  a language code (``en-us``, ``en-gb``, ``fr``), a voice name or identifier, optionally
           with a variant (``en-us+f3``); :func:`voices` lists them
    rate   words per minute, 80–450 (espeak-ng's default 175 when ``None``)
    pitch  0–99 (default 50)
    ipa    also ask espeak-ng for each phone's IPA (a second synthesis); ``None`` does it for
           non-English voices, whose phoneme names the viseme table does not list
    """
    if not isinstance(ssml_or_text, str):
        raise SpeechError(f"the text must be a string, got {type(ssml_or_text).__name__}")
    if not isinstance(voice, str) or not _VOICE_NAME.match(voice) or ".." in voice:
        raise SpeechError(
            f"invalid voice {voice!r}: write a language code such as en-us, fr or en-gb+f3"
        )
    rate, pitch = check_rate_pitch(rate, pitch)
    if ssml:
        doc = _ssml_document(ssml_or_text)
        flags = CHARS_UTF8 | SSML | ENDPAUSE
    else:
        doc = _Document(ssml_or_text, [], [], [], 0, ssml_or_text)
        flags = CHARS_UTF8 | ENDPAUSE
    request = {
        "op": "synth",
        "text": doc.text,
        "voice": voice,
        "rate": rate,
        "pitch": pitch,
        "flags": flags,
        "ipa": "auto" if ipa is None else bool(ipa),
    }
    header, payload = _run_worker(request, timeout=60 + len(doc.text) / 50)
    return _speech(header, payload, doc)


def check_rate_pitch(rate, pitch) -> tuple[int | None, int | None]:
    """``(rate, pitch)`` as ints after checking them as every engine takes them: ``rate`` in
    words per minute within :data:`RATE_RANGE`, ``pitch`` within :data:`PITCH_RANGE` (50
    normal); ``None`` (the voice's own) stays ``None``. Raises :class:`SpeechError` naming the
    value and the range."""
    return (
        _check_int("rate", rate, RATE_RANGE, "words per minute"),
        _check_int("pitch", pitch, PITCH_RANGE, "with 50 normal"),
    )


def _check_int(what: str, value, limits: tuple[int, int], unit: str) -> int | None:
    if value is None:
        return None
    lo, hi = limits
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not lo <= value <= hi:
        raise SpeechError(f"{what} must be an integer within {lo}–{hi} ({unit}), got {value!r}")
    return int(value)


def _speech(header: dict, payload: bytes, doc: _Document) -> Speech:
    rate = int(header["rate"])
    audio = np.frombuffer(payload, dtype=np.int16).copy()
    n = audio.shape[0]
    if n != header["nsamples"]:
        raise SpeechError(f"espeak-ng sent {n} samples, announced {header['nsamples']}")
    voice = _voice_from(header["voice"])
    events = header["events"]
    ipa = header.get("ipa")
    raw = [(e[3], e[4]) for e in events if e[0] == EVENT_PHONEME]
    ipas = ipa if ipa is not None and len(ipa) == len(raw) else [None] * len(raw)
    phones = _phones(raw, ipas, n, rate, voice.language)
    words = _words(events, doc, n, rate)
    marks = _marks(events, doc, phones, words, n, rate)
    return Speech(audio, rate, phones, marks, words, voice)


def _words(events, doc: _Document, n: int, rate: int) -> list[Word]:
    raw = sorted(
        ((min(max(int(e[3]), 0), n), e[1], e[4]) for e in events if e[0] == EVENT_PHONEME),
        key=lambda r: r[0],
    )
    spans: dict[int, list[int]] = {}  # text position → [first sample, last sample]
    for j, (start, tp, name) in enumerate(raw):
        end = raw[j + 1][0] if j + 1 < len(raw) else n
        if end <= start or name in PAUSES or name.startswith("_"):
            continue
        span = spans.setdefault(tp, [start, end])
        span[0], span[1] = min(span[0], start), max(span[1], end)
    words: list[Word] = []
    for e in events:
        if e[0] != EVENT_WORD or e[2] <= 0 or e[1] not in spans:
            continue
        span = spans.pop(e[1])  # later events at the same position: the same word
        pos = doc.position(e[1])
        if words and words[-1].position == pos:  # "123": one hundred and / twenty three
            words[-1] = replace(words[-1], end=span[1] / rate)
            continue
        words.append(Word(span[0] / rate, pos, e[2], span[1] / rate, _word_at(doc.source, pos)))
    return words


#: Characters stripped from a word's ends (punctuation, curly quotes; not ``&`` nor ``'``).
WORD_EDGE = string.punctuation.replace("&", "").replace("'", "") + "\u201c\u201d\u2018\u2019"


def _word_at(source: str, pos: int) -> str:
    """The word of the SSML ``source`` around ``pos``: the run of characters without spaces and
    tags, entities decoded, punctuation around it stripped (espeak-ng's word positions point
    into entities, and its lengths count them oddly)."""
    start = pos
    while start > 0 and not source[start - 1].isspace() and source[start - 1] != ">":
        start -= 1
    end = pos
    while end < len(source) and not source[end].isspace() and source[end] != "<":
        end += 1
    text = _unescape(source[start:end])
    return text.strip(WORD_EDGE) or text


def _phones(raw, ipas, n: int, rate: int, language: str) -> list[Phone]:
    order = sorted(range(len(raw)), key=lambda i: raw[i][0])  # stable; espeak sends them sorted
    samples = [min(max(int(raw[i][0]), 0), n) for i in order]
    phones: list[Phone] = []
    if samples and samples[0] > 0:
        phones.append(Phone(0.0, samples[0] / rate, "_", 0))
    for j, i in enumerate(order):
        start = samples[j]
        end = samples[j + 1] if j + 1 < len(samples) else n
        if end <= start:
            continue  # zero length: a boundary marker, or several events at one sample
        name, ip = raw[i][1], ipas[i]
        phones.append(Phone(start / rate, end / rate, name, viseme_of(name, language, ipa=ip), ip))
    if not phones and n > 0:
        phones.append(Phone(0.0, n / rate, "_", 0))
    return phones


#: What may stand between a mark and the word it comes right before: spaces, other marks and
#: opening quotes or brackets, none of which is spoken.
_BEFORE_WORD = re.compile(
    r"""(?:\s|<(?:[\w.-]+:)?mark\b[^>]*>|&quot;|&apos;|["'\u201c\u2018\u00ab(\[\u00bf\u00a1])*"""
)


def _word_after(doc: _Document, k: int, words: list[Word]) -> Word | None:
    """The spoken word that mark ``k`` stands right before in the text (only what
    :data:`_BEFORE_WORD` allows between them), or None."""
    end = doc.spans[k][3] - doc.prefix  # just after the mark's tag, in the caller's text
    after = [w for w in words if w.position >= end]
    if not after:
        return None
    word = min(after, key=lambda w: w.position)
    reach = _BEFORE_WORD.match(doc.source, end).end()
    # the word's position may be inside its token (after a quote, say): no space or tag before it
    between = doc.source[reach : word.position]
    return word if not any(c.isspace() or c == "<" for c in between) else None


def _marks(
    events, doc: _Document, phones: list[Phone], words: list[Word], n: int, rate: int
) -> list[Mark]:
    """Each mark's time: the first phone of the word it stands right before, where there is one
    (espeak-ng's mark event comes up to a phone early, as its word event does: "my name <mark/>
    is" is reported 67 ms before the ``I`` of "is"), else espeak-ng's mark event, else (a mark
    espeak-ng lost) the next word's event."""
    if not doc.marks:
        return []
    reported: dict[int, int] = {}
    for e in events:
        if e[0] == EVENT_MARK:
            try:
                k = int(e[4])
            except (TypeError, ValueError):
                continue
            if 0 <= k < len(doc.marks) and k not in reported:
                reported[k] = int(e[3])
    word_events = [(e[1] - 1, int(e[3])) for e in events if e[0] == EVENT_WORD and e[2] > 0]
    speech_end = next((p.end for p in reversed(phones) if p.viseme != 0), 0.0)
    marks: list[Mark] = []
    previous = 0.0
    for k, name in enumerate(doc.marks):
        word = _word_after(doc, k, words)
        if word is not None:
            t = word.start
        elif k in reported:
            t = reported[k] / rate
        else:
            # Lost by espeak (after a full stop): the next word after the mark's place.
            # (espeak's positions can be one too far, never too early: allow one character)
            later = [s for pos, s in word_events if pos >= doc.mark_ends[k] - 1]
            after = [reported[j] for j in range(k + 1, len(doc.marks)) if j in reported]
            if later:
                t = later[0] / rate
            elif after:
                t = after[0] / rate
            else:
                t = speech_end
        t = min(max(t, previous), n / rate)
        marks.append(Mark(name, t))
        previous = t
    return marks


# ---- the engine (vtts.speech.engine) -------------------------------------------------------------

#: espeak-ng's voices and program (Debian ``espeak-ng``).
LICENCE = "GPL-3.0-or-later"
#: The rate espeak-ng speaks at in synchronous mode, Hz.
SAMPLE_RATE = 22050


class EspeakEngine:
    """espeak-ng as a :class:`vtts.speech.engine.Engine`: SSML with a ``<mark/>`` per bookmark
    (named ``b0``, ``b1`` … in order), each bookmark at its mark's time."""

    name = "espeak"
    default_voice = "en-us"
    #: espeak-ng's phones start at the sound they name (a stop at its release, its silent
    #: closure in the phone before); the lip sync bench chose the lead (docs/speech.md).
    lead = 0.04
    #: In its audio a p's closure lies in the phone before and the p starts at the burst; a b
    #: holds its (voiced) closure and opens before its end; an m is its murmur (medians of its
    #: audio's closures: docs/speech.md, *The closure measure*).
    bilabials = BilabialTiming(
        p=LipTiming(-0.05, 0.0, "start"), b=LipTiming(0.0, -0.02), m=LipTiming(-0.005, -0.015)
    )

    def speak(self, text, *, voice=None, rate=None, pitch=None):
        from vtts.speech.engine import Spoken, end_of_word_before

        speech = synthesize(text.ssml(), voice=voice or self.default_voice, rate=rate, pitch=pitch)
        times = [m.time for m in speech.marks]
        if text.before_punctuation:
            end_of_word_before(text, speech.words, times)
        return Spoken(speech, times)

    def sentences(self, text, *, voice=None, rate=None):
        yield self.speak(text, voice=voice, rate=rate)

    def voices(self):
        from vtts.speech.engine import VoiceInfo

        try:
            found = voices()
        except SpeechError:
            return []
        return [
            VoiceInfo(
                self.name,
                v.language,
                v.language,
                SAMPLE_RATE,
                LICENCE,
                v.languages,
                f"{v.name} ({v.identifier})",
            )  # fmt: skip
            for v in found
        ]


ENGINE = EspeakEngine()
