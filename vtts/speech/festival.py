"""Speech from festival (Debian ``festival`` with the ``festvox-us-slt-hts`` voice): audio, timed
phones, words and mark times in one clock, as :func:`vtts.speech.tts.synthesize` gives them.

festival runs as a batch process (``festival -b SCRIPT``) on a Scheme script written here: it
selects the voice, synthesizes the text into an utterance and writes the wave (RIFF) and, from
the utterance structure, every ``Segment`` (phone) with its end time, every ``Token`` (a
whitespace-separated piece of the text) and every ``Word`` with the token it came from and the
start and end of its first and last segment. The HTS voice's segment times are those the HTS
engine synthesized with (the audio ends at the last segment's end), at its 5 ms frame rate.

Phones: festival's ``radio`` phone set is ARPAbet in lower case (``aa ae ah … zh``), plus ``pau``
(a pause), ``h#`` (silence) and ``brth`` (a breath), which are viseme 0; the rest map through the
``arpabet`` rows of ``vtts/data/phoneme_visemes.tsv`` (``hv``, the voiced h, included). Every phone
of the set has a viseme: :data:`PHONE_SET` lists them and the tests check it.

Words and marks: SSML marks are not used (festival's SSML mode drops the utterance structure);
the caller gives the marks' character positions in the text instead. Tokens are found in the text
in order; a mark gets the start of the first spoken word of the first token at or after its
position, or the end of the last phone that is not a pause when no word follows (as espeak-ng
reports a mark at the end). A word as written (``123``, ``Dr.``) is one :class:`Word` spanning
the words festival speaks for it (``one hundred twenty three``), like espeak-ng's.

The text goes to festival in ASCII: accented letters lose their accents, typographic quotes and
dashes become ASCII ones, other characters become spaces; positions are mapped back, so words
keep the text's own spelling.

Rate and pitch: the HTS engine's speed factor ``-r`` is ``rate / 175`` (175 words per minute is
espeak-ng's normal rate, and the voice's own) and its ``-fm`` shifts the pitch by
``(pitch - 50) / 50 * 12`` half-tones (0–99 as for espeak-ng, 50 unchanged).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
import unicodedata
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vtts.errors import SpeechError
from vtts.speech.engine import BilabialTiming, LipTiming
from vtts.speech.phonemes import Mark, Phone, viseme_tables
from vtts.speech.tts import Speech, Voice, Word, check_rate_pitch

__all__ = ["DEFAULT_VOICE", "INSTALL_HINT", "PHONE_SET", "festival_viseme", "synthesize"]

#: The voice of Debian's ``festvox-us-slt-hts`` (CMU ARCTIC's SLT, a female US English speaker).
DEFAULT_VOICE = "cmu_us_slt_arctic_hts"
INSTALL_HINT = (
    "install it with 'apt-get install --no-install-recommends festival festvox-us-slt-hts' "
    "(scripts/setup.sh does as root)"
)
#: festival's ``radio`` phone set (``/usr/share/festival/radio_phones.scm``), which the US
#: English voices use.
PHONE_SET = (
    "aa ae ah ao aw ax axr ay b ch d dh dx eh el em en er ey f g hh hv ih iy jh k l m n nx ng ow "
    "oy p r s sh t th uh uw v w y z zh pau h# brth"
).split()
#: The phones of :data:`PHONE_SET` that are not sounds of speech (viseme 0).
SILENCES = frozenset({"pau", "h#", "brth"})
#: Characters of text festival speaks as one utterance, at least (see :func:`_chunks`).
CHUNK_CHARS = 300
#: espeak-ng's normal speaking rate, words per minute: the HTS speed factor 1.
NORMAL_RATE = 175

_VOICE_NAME = re.compile(r"^[a-z][a-z0-9_]{0,63}$")
#: ASCII for characters NFKD does not reduce to ASCII.
_ASCII = str.maketrans(
    {
        "\u2018": "'", "\u2019": "'", "\u201a": "'", "\u201b": "'", "\u2032": "'",
        "\u201c": '"', "\u201d": '"', "\u201e": '"', "\u00ab": '"', "\u00bb": '"',
        "\u2010": "-", "\u2011": "-", "\u2012": "-", "\u2013": "-", "\u2014": "-",
        "\u2212": "-", "\u00df": "s", "\u00e6": "e", "\u00c6": "E", "\u0153": "e",
        "\u0152": "E", "\u00f8": "o", "\u00d8": "O", "\u0142": "l", "\u0141": "L",
    }
)  # fmt: skip


@dataclass(frozen=True)
class _Token:
    index: tuple[int, int]  # chunk, 1-based token number in it
    name: str


def festival_viseme(phone: str) -> int:
    """The MPEG-4 viseme of a phone of festival's ``radio`` set (``pau`` → 0, ``m`` → 1 …);
    raises :class:`SpeechError` for a name outside the set."""
    if phone in SILENCES:
        return 0
    found = viseme_tables()["arpabet"].get(phone.upper())
    if found is None:
        raise SpeechError(f"festival sent the phone {phone!r}, which is not in its radio set")
    return found


def synthesize(
    text: str,
    *,
    marks: Sequence[int] = (),
    voice: str = DEFAULT_VOICE,
    rate: int | None = None,
    pitch: int | None = None,
) -> Speech:
    """Speak the plain ``text`` with festival; see :class:`vtts.speech.tts.Speech`.

    marks  character positions in ``text`` (0–len) of marks, in order; each comes back as a
           :class:`Mark` named by its index (``"0"``, ``"1"`` …) at the start of the next word
    voice  a festival voice (``voice_NAME`` in Scheme), :data:`DEFAULT_VOICE` by default
    rate   words per minute, 80–450 (the voice's own, 175, when ``None``)
    pitch  0–99 (50, the voice's own, when ``None``)
    """
    if not isinstance(text, str):
        raise SpeechError(f"the text must be a string, got {type(text).__name__}")
    if not isinstance(voice, str) or not _VOICE_NAME.match(voice):
        raise SpeechError(
            f"invalid festival voice {voice!r}: write a voice name such as {DEFAULT_VOICE}"
        )
    rate, pitch = check_rate_pitch(rate, pitch)
    positions = list(marks)
    if any(not 0 <= p <= len(text) for p in positions) or positions != sorted(positions):
        raise SpeechError(f"mark positions must increase within 0–{len(text)}, got {positions}")
    ascii_text, origin = _ascii(text)
    exe = shutil.which("festival")
    if exe is None:
        raise SpeechError(f"festival is missing: {INSTALL_HINT}")
    chunks = _chunks(ascii_text)
    with tempfile.TemporaryDirectory(prefix="vtts-festival-") as tmp:
        folder = Path(tmp)
        script = folder / "say.scm"
        script.write_text(_script(chunks, voice, rate, pitch, folder), encoding="ascii")
        try:
            proc = subprocess.run(
                [exe, "-b", str(script)],
                stdin=subprocess.DEVNULL,
                capture_output=True,
                timeout=60 + len(text) / 20,
                cwd=folder,
                check=False,
            )
        except subprocess.TimeoutExpired:
            raise SpeechError("festival did not finish in time") from None
        except OSError as e:
            raise SpeechError(f"cannot start festival: {e}") from None
        message = (proc.stdout + proc.stderr).decode("utf-8", "replace")
        if f"unbound variable : voice_{voice}" in message:
            if voice == DEFAULT_VOICE:
                raise SpeechError(f"festival's voice {voice} is missing: {INSTALL_HINT}")
            raise SpeechError(f"festival has no voice {voice!r} (festival's voice.list names them)")
        waves = [folder / f"speech{k}.wav" for k in range(len(chunks))]
        table = folder / "structure.tsv"
        if proc.returncode != 0 or not all(w.is_file() for w in waves) or not table.is_file():
            tail = " | ".join(message.strip().splitlines()[-3:])
            raise SpeechError(f"festival failed (exit code {proc.returncode}): {tail}")
        from vtts.speech.audio import read_audio, to_int16

        pieces = [read_audio(w) for w in waves]
        structure = table.read_text(encoding="utf-8", errors="replace")
    rates = {sr for _, sr in pieces}
    if len(rates) != 1:
        raise SpeechError(f"festival's waves came at several rates: {sorted(rates)} Hz")
    lengths = [x.shape[0] for x, _ in pieces]
    audio = to_int16(np.concatenate([x for x, _ in pieces]))
    return _speech(
        structure, audio, rates.pop(), lengths, text, ascii_text, origin, positions, voice
    )


# ---- the text ------------------------------------------------------------------------------------


def _ascii(text: str) -> tuple[str, list[int]]:
    """``text`` in ASCII, and for each character of it the index of the character of ``text`` it
    comes from (one more entry, ``len(text)``, for the end)."""
    out: list[str] = []
    origin: list[int] = []
    for i, c in enumerate(text):
        if c.isascii():
            rep = c if c.isprintable() or c in "\n\t" else " "
        else:
            rep = c.translate(_ASCII)
            if not rep.isascii():
                rep = unicodedata.normalize("NFKD", c).encode("ascii", "ignore").decode("ascii")
            if not rep or not rep.isprintable():
                rep = " "
        out.append(rep)
        origin.extend([i] * len(rep))
    origin.append(len(text))
    return "".join(out), origin


def _scheme_string(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _chunks(text: str, size: int | None = None) -> list[str]:
    """``text`` cut into pieces of ``size`` (:data:`CHUNK_CHARS`) characters or more, at
    sentence ends (in a run-on of over four times ``size``, at a space), each spoken as an
    utterance of its own: festival's time grows faster than the length of one utterance
    (docs/speech.md, "festival")."""
    ends = [m.end() for m in re.finditer(r"""[.!?;:]["')\]]*\s+|\n\s*\n""", text)]
    spaces = [m.end() for m in re.finditer(r"\s+", text)]
    size = CHUNK_CHARS if size is None else size
    out: list[str] = []
    start = 0
    while len(text) - start > size:
        cut = next((e for e in ends if e >= start + size), None)
        if cut is None or cut > start + 4 * size:
            cut = next((e for e in spaces if e >= start + size), None)
        if cut is None or cut >= len(text):
            break
        out.append(text[start:cut])
        start = cut
    out.append(text[start:])
    return out


def _script(
    chunks: list[str], voice: str, rate: int | None, pitch: int | None, folder: Path
) -> str:
    params = []
    if rate is not None:
        params.append(f'(list "-r" {rate / NORMAL_RATE:.6f})')
    if pitch is not None:
        params.append(f'(list "-fm" {(pitch - 50) / 50 * 12:.6f})')
    engine = (
        f"(set! hts_engine_params (append hts_engine_params (list {' '.join(params)})))"
        if params
        else ""
    )
    table = _scheme_string(str(folder / "structure.tsv"))
    calls = "\n".join(
        f"(vtts_say {k} {_scheme_string(chunk)} {_scheme_string(str(folder / f'speech{k}.wav'))})"
        for k, chunk in enumerate(chunks)
    )
    # One utterance per chunk (Utterance does not evaluate its arguments, hence the eval). Token
    # indices are 1-based: item.feat answers 0 for a feature an
    # item lacks.
    return f"""(voice_{voice})
{engine}
(set! fd (fopen {table} "w"))
(define (vtts_say chunk text wavfile)
  (let ((utt (utt.synth (eval (list 'Utterance 'Text text)))) (k 1) (tok nil))
    (utt.save.wave utt wavfile 'riff)
    (format fd "chunk\t%d\n" chunk)
    (set! tok (utt.relation.first utt 'Token))
    (while tok
      (item.set_feat tok "vtts_index" k)
      (format fd "token\t%d\t%s\n" k (item.name tok))
      (set! k (+ k 1))
      (set! tok (item.next tok)))
    (mapcar
      (lambda (w)
        (format fd "word\t%s\t%s\t%s\t%s\n"
          (item.feat w "R:Token.parent.vtts_index")
          (item.feat w "R:SylStructure.daughter1.daughter1.segment_start")
          (item.feat w "R:SylStructure.daughtern.daughtern.end")
          (item.name w)))
      (utt.relation.items utt 'Word))
    (mapcar
      (lambda (s) (format fd "segment\t%s\t%s\n" (item.name s) (item.feat s "end")))
      (utt.relation.items utt 'Segment))))
{calls}
(fclose fd)
"""


# ---- the utterance structure ---------------------------------------------------------------------


def _speech(
    structure: str,
    audio: np.ndarray,
    rate: int,
    lengths: list[int],
    text: str,
    ascii_text: str,
    origin: list[int],
    marks: list[int],
    voice: str,
) -> Speech:
    """The :class:`Speech` of the chunks' structure lines and their concatenated audio
    (``lengths``: each chunk's samples)."""
    offsets = np.concatenate([[0], np.cumsum(lengths)]) / rate  # each chunk's start, s
    tokens: list[_Token] = []
    words: list[tuple[tuple[int, int], float, float, str]] = []  # token, start, end, name
    segments: list[list[tuple[str, float]]] = [[] for _ in lengths]
    chunk = 0
    for line in structure.splitlines():
        fields = line.split("\t")
        try:
            if fields[0] == "chunk" and len(fields) == 2:
                chunk = int(fields[1])
                if not 0 <= chunk < len(lengths):
                    raise ValueError(chunk)
            elif fields[0] == "token" and len(fields) == 3:
                tokens.append(_Token((chunk, int(fields[1])), fields[2]))
            elif fields[0] == "word" and len(fields) == 5:
                start, end = _seconds(fields[2]), _seconds(fields[3])
                t0 = float(offsets[chunk])
                words.append(((chunk, int(float(fields[1]))), t0 + start, t0 + end, fields[4]))
            elif fields[0] == "segment" and len(fields) == 3:
                segments[chunk].append((fields[1], _seconds(fields[2])))
        except ValueError:
            raise SpeechError(f"festival wrote an unexpected line: {line[:80]!r}") from None
    phones: list[Phone] = []
    for k, segs in enumerate(segments):
        t0 = float(offsets[k])
        for p in _phones(segs, lengths[k] / rate):
            phones.append(Phone(t0 + p.start, t0 + p.end, p.phoneme, p.viseme))
    spans = _token_spans(tokens, ascii_text, origin)
    out_words = _words(words, spans, text)
    speech_end = next((p.end for p in reversed(phones) if p.viseme != 0), 0.0)
    out_marks = _marks(marks, out_words, speech_end)
    v = Voice(voice, "en-us", ("en-us", "en"), "female" if "slt" in voice else "", voice)
    return Speech(audio, rate, phones, out_marks, out_words, v)


def _seconds(field: str) -> float:
    # festival prints its float32 times (0.16500001): back to its 10 µs grid
    return round(float(field), 5)


def _phones(segments: list[tuple[str, float]], duration: float) -> list[Phone]:
    phones: list[Phone] = []
    start = 0.0
    for k, (name, end) in enumerate(segments):
        end = min(end, duration) if k + 1 < len(segments) else duration
        if end <= start:
            continue
        phones.append(Phone(start, end, name, festival_viseme(name)))
        start = end
    if not phones and duration > 0:
        phones.append(Phone(0.0, duration, "pau", 0))
    elif phones and phones[-1].end < duration:
        phones.append(Phone(phones[-1].end, duration, "pau", 0))
    return phones


def _token_spans(
    tokens: list[_Token], ascii_text: str, origin: list[int]
) -> dict[tuple[int, int], tuple[int, int]]:
    """Token index → ``[start, end)`` in the caller's text (tokens found in order)."""
    spans: dict[int, tuple[int, int]] = {}
    cursor = 0
    for tok in tokens:
        if not tok.name:
            continue
        at = ascii_text.find(tok.name, cursor)
        if at < 0:
            continue  # festival rewrote it: its words still count, without a place
        end = at + len(tok.name)
        spans[tok.index] = (origin[at], origin[end - 1] + 1)
        cursor = end
    return spans


def _words(
    raw: list[tuple[tuple[int, int], float, float, str]],
    spans: dict[tuple[int, int], tuple[int, int]],
    text: str,
) -> list[Word]:
    """One :class:`Word` per token with spoken words (the words festival speaks for it
    merged), in the order festival speaks them."""
    out: list[Word] = []
    last_token = None
    for token, start, end, name in raw:
        if end <= start:
            continue  # no segments: punctuation festival keeps as a word
        if token == last_token and out:
            out[-1] = Word(out[-1].start, out[-1].position, out[-1].length, end, out[-1].text)
            continue
        last_token = token
        span = spans.get(token)
        if span is None:
            out.append(Word(start, -1, 0, end, name))
        else:
            a, b = span
            out.append(Word(start, a, b - a, end, text[a:b]))
    return out


def _marks(positions: list[int], words: list[Word], speech_end: float) -> list[Mark]:
    marks: list[Mark] = []
    previous = 0.0
    for k, pos in enumerate(positions):
        after = [w.start for w in words if w.position >= pos]
        t = max(after[0] if after else speech_end, previous)
        marks.append(Mark(str(k), t))
        previous = t
    return marks


# ---- the engine (vtts.speech.engine) -------------------------------------------------------------

#: Where Debian's festival keeps its voices (``voices/LANGUAGE/NAME``).
VOICES_DIR = Path("/usr/share/festival/voices")
#: What is known of the voices setup installs without running festival: sample rate (Hz) and
#: licence (Debian's copyright file of ``festvox-us-slt-hts``).
KNOWN_VOICES = {DEFAULT_VOICE: (32000, "BSD-3-Clause AND EST-2000 (CMU ARCTIC SLT)")}
#: festival's voice folders by language → language codes.
_LANGUAGES = {"us": "en-us", "english": "en-us", "british": "en-gb", "spanish": "es"}


class FestivalEngine:
    """festival as a :class:`vtts.speech.engine.Engine`: the plain text, each bookmark at the
    start of the first word spoken at or after its place."""

    name = "festival"
    default_voice = DEFAULT_VOICE
    #: The HTS segments start somewhat before their sound and hold a stop's closure: no lead
    #: (the lip sync bench's choice, docs/speech.md).
    lead = 0.0
    #: In its audio a p holds its closure and then its aspiration, the burst between; a b opens
    #: shortly before its end; an m is its murmur (medians of its audio's closures:
    #: docs/speech.md, *The closure measure*).
    bilabials = BilabialTiming(
        p=LipTiming(-0.01, 0.055, "start"), b=LipTiming(-0.005, -0.012), m=LipTiming(0.0, 0.0)
    )

    def speak(self, text, *, voice=None, rate=None, pitch=None):
        from vtts.speech.engine import Spoken, bookmark_positions

        speech = synthesize(
            text.text,
            marks=bookmark_positions(text),
            voice=voice or self.default_voice,
            rate=rate,
            pitch=pitch,
        )
        return Spoken(speech, [m.time for m in speech.marks])

    def sentences(self, text, *, voice=None, rate=None):
        yield self.speak(text, voice=voice, rate=rate)

    def voices(self):
        from vtts.speech.engine import VoiceInfo

        if shutil.which("festival") is None or not VOICES_DIR.is_dir():
            return []
        found = []
        for folder in sorted(VOICES_DIR.glob("*/*")):
            if not folder.is_dir() or not _VOICE_NAME.match(folder.name):
                continue
            rate, licence = KNOWN_VOICES.get(folder.name, (None, "see its Debian package"))
            language = _LANGUAGES.get(folder.parent.name, folder.parent.name)
            found.append(VoiceInfo(self.name, folder.name, language, rate, licence, (language,)))
        return found


ENGINE = FestivalEngine()
