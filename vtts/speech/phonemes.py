"""Phonemes and MPEG-4 visemes: espeak-ng's phoneme names, IPA, Amazon Polly visemes, ARPAbet.

The visemes are the 15 of ISO/IEC 14496-2 (``vtts/data/visemes.tsv``): 0 none, 1 p b m, 2 f v,
3 T D, 4 t d, 5 k g, 6 tS dZ S, 7 s z, 8 n l, 9 r, 10 A: (car), 11 e (bed), 12 I (tip),
13 Q (top), 14 U (book). The mapping is data, ``vtts/data/phoneme_visemes.tsv``, one row per
symbol of four alphabets:

``espeak-en``
    every phoneme name of espeak-ng's English phoneme tables (``en`` and its accents ``en-us``,
    ``en-n``, ``en-rp``, ``en-sc``, ``en-us-nyc``, ``en-wi``, ``en-wm``, with the ``base`` and
    ``base1`` tables they inherit): 165 names read from the compiled ``phontab`` of espeak-ng
    1.51, and checked against the phoneme events of all eight English voices (``en-us``, ``en-gb``,
    ``en-gb-x-rp``, ``en-gb-scotland``, ``en-gb-x-gbclan``, ``en-gb-x-gbcwmd``, ``en-029``,
    ``en-us-nyc``) on a 520 kB text (licences, Python docstrings, a list of rare words; 3.5 million
    phones), which used 79 of them, all in the table. Pause, stress and boundary symbols map
    to 0. The ``ipa`` column is what espeak-ng itself reports for the name in those voices (``-``
    for names no English voice emitted).
``ipa``
    IPA letters (and the affricates written with two); used for other languages.
``espeak``
    names that other languages' tables use and the English ones lack (``y``, ``Y``, ``W`` …).
``polly``
    Amazon Polly's viseme alphabet (``p t S T f k i r s u @ a e E o O l sil``).
``arpabet``
    CMU/ARPAbet phonemes (stress digits stripped), as forced aligners write them.

How :func:`viseme_of` decides, in this order (the first that answers wins):

1. a pause, stress, syllable or word-boundary symbol (``_``, ``_:``, ``||``, ``'``, ``,``, ``%``,
   ``=``, ``sil``, ``sp``, the empty string …) is viseme 0;
2. for an English ``language`` (``en``, ``en-us``, ``en-gb-x-rp`` …) the ``espeak-en`` table;
3. the ``ipa`` given by the caller (espeak-ng's own IPA for the phone, see
   :func:`vtts.speech.tts.synthesize`), through the ``ipa`` table as in step 6;
4. for other languages the ``espeak-en`` table too: the tables share most names (``S``, ``tS``,
   ``x``, ``N``, ``n^`` …);
5. the name without espeak's modifier characters (digits and ``# : ; - / ^ . " [ ~ ` '``),
   through ``espeak-en`` then ``espeak`` (``z2`` → ``z``, ``O~`` → ``O``, ``l^`` → ``l``);
6. IPA: the symbol with stress, length marks and diacritics removed, then the longest prefix
   that is in the ``ipa`` table (``tʃʰ`` → ``tʃ``, ``aɪ`` → ``a``);
7. the first letter of the name through ``espeak-en``, ``espeak``, then ``ipa``;
8. otherwise 0.

An explicit ``alphabet`` (``"ipa"``, ``"polly"``, ``"arpabet"``) looks the symbol up in that table
only (after step 1), which is how phoneme files are read.
"""

from __future__ import annotations

import csv
import json
import math
import re
import unicodedata
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

from vtts.errors import SpeechError
from vtts.limits import MAX_DURATION_S, MAX_TEXT_BYTES, LimitError, read_bytes_capped
from vtts.resources import package_data
from vtts.speech.timings import HEADER, TimedWord, word_ends

#: The viseme of p, b and m: the lips close.
BILABIAL = 1
#: Alphabets of ``phoneme_visemes.tsv``.
ALPHABETS = ("espeak-en", "ipa", "espeak", "polly", "arpabet")
#: Duration given to the last phone of a Polly file, which has no end time, s.
LAST_PHONE_S = 0.1

#: Symbols that are not sounds: espeak's pauses, stress and boundary marks, aligners' silences.
PAUSES = frozenset(
    {
        "", "_", "_:", "_::", "_!", "_|", "_;_", "_^_", "_X1", "||", "|", ":", "-", "=", "1",
        "%", "%%", "'", "''", "'!", ",", ",,", "#@", "#a", "#e", "#i", "#o", "#u", "#X1",
        "sil", "SIL", "sp", "SP", "spn", "SPN", "pau", "PAU", "h#", "<sil>", "<p:>",
    }
)  # fmt: skip

_ESPEAK_MODIFIERS = re.compile(r"[0-9#:;\-/^.\"\[~`']")
# IPA marks that do not change the mouth shape class: stress, length, tie bars, syllable breaks,
# and modifier letters (aspiration, palatalization, labialization, rhotic hook …).
_IPA_DROP = set("ˈˌːˑ.‿|‖͜͡ʰʲʷˠˤ˞ⁿˡ'")


@dataclass(frozen=True)
class Phone:
    """One phone in the audio's clock.

    start, end  seconds (``start <= end``)
    phoneme     the name as the source wrote it (espeak-ng mnemonic such as ``aI``, IPA, a Polly
                viseme or an ARPAbet phoneme)
    viseme      its MPEG-4 viseme 0–14, filled in by whoever made the phone
    ipa         espeak-ng's IPA for the phone when it was asked for (non-English voices)
    """

    start: float
    end: float
    phoneme: str
    viseme: int | None = None
    ipa: str | None = None

    @property
    def duration(self) -> float:
        return self.end - self.start


@dataclass(frozen=True)
class Mark:
    """An SSML ``<mark/>`` and its time in the audio (s)."""

    name: str
    time: float


@dataclass
class PhonemeFile:
    """Timings from another speech engine (``--phonemes FILE``).

    kind   ``"polly"`` (Amazon Polly speech marks, JSON lines), ``"table"`` (``start end
           phoneme`` lines) or ``"timings"`` (what ``say --timings-out`` writes)
    words  the words with their times, when the file gives them (Polly's ``word`` marks, the
           timings' ``word`` rows)
    """

    phones: list[Phone]
    marks: list[Mark] = field(default_factory=list)
    kind: str = "table"
    alphabet: str = "espeak-en"
    words: list[TimedWord] = field(default_factory=list)


# ---- the table -------------------------------------------------------------------------------


@cache
def viseme_tables() -> dict[str, dict[str, int]]:
    """``alphabet → {symbol: viseme}`` from ``vtts/data/phoneme_visemes.tsv``."""
    tables: dict[str, dict[str, int]] = {a: {} for a in ALPHABETS}
    path = package_data("phoneme_visemes.tsv")
    with path.open(encoding="utf-8", newline="") as f:
        rows = [r for r in csv.reader(f, delimiter="\t", quoting=csv.QUOTE_NONE)]
    header = rows[0]
    if header[:3] != ["alphabet", "symbol", "viseme"]:
        raise SpeechError(f"{path.name}: header must start with 'alphabet symbol viseme'")
    for n, row in enumerate(rows[1:], start=2):
        if not row or row[0].startswith("#"):
            continue
        alphabet, symbol, viseme = row[0], row[1], int(row[2])
        if alphabet not in tables or not 0 <= viseme <= 14 or symbol in tables[alphabet]:
            raise SpeechError(f"{path.name}:{n}: bad or repeated row {row!r}")
        tables[alphabet][symbol] = viseme
    return tables


def is_english(language: str | None) -> bool:
    """True for ``en``, ``en-us``, ``en_GB``, ``en-gb-x-rp`` …"""
    return bool(language) and re.split(r"[-_]", language.lower(), maxsplit=1)[0] == "en"


def ipa_key(symbol: str) -> str:
    """An IPA symbol without stress, length, tie bars, modifier letters and combining
    diacritics (NFD), e.g. ``ˈaːʰ`` → ``a``, ``ɔ̃`` → ``ɔ``, ``n̩`` → ``n``."""
    decomposed = unicodedata.normalize("NFD", symbol)
    kept = "".join(c for c in decomposed if c not in _IPA_DROP and not unicodedata.combining(c))
    return unicodedata.normalize("NFC", kept)


def _ipa_viseme(symbol: str) -> int | None:
    table = viseme_tables()["ipa"]
    key = ipa_key(symbol)
    for n in range(min(len(key), 3), 0, -1):
        if key[:n] in table:
            return table[key[:n]]
    return None


def viseme_of(
    phoneme: str, language: str = "en", *, ipa: str | None = None, alphabet: str | None = None
) -> int:
    """The MPEG-4 viseme (0–14) of a phoneme; the rules are in the module docstring.

    ``alphabet`` ``None`` means an espeak-ng name or IPA; ``"ipa"``, ``"polly"``, ``"arpabet"``
    (stress digits allowed) and ``"espeak-en"`` restrict the lookup to that table and raise
    :class:`SpeechError` for a symbol it lacks.
    """
    phoneme = phoneme.strip()
    if phoneme in PAUSES:
        return 0
    tables = viseme_tables()
    if alphabet is not None:
        return _from_alphabet(phoneme, alphabet, tables)
    english = tables["espeak-en"]
    if is_english(language) and phoneme in english:
        return english[phoneme]
    if ipa:
        found = _ipa_viseme(ipa)
        if found is not None:
            return found
        if ipa_key(ipa) == "":
            return 0  # espeak gives no IPA for its pauses and boundary marks
    if phoneme in english:
        return english[phoneme]
    stripped = _ESPEAK_MODIFIERS.sub("", phoneme)
    for table in (english, tables["espeak"]):
        if stripped and stripped in table:
            return table[stripped]
    found = _ipa_viseme(phoneme)
    if found is not None:
        return found
    first = (stripped or phoneme)[:1]
    for table in (english, tables["espeak"]):
        if first in table:
            return table[first]
    found = _ipa_viseme(first)
    return 0 if found is None else found


def _from_alphabet(symbol: str, alphabet: str, tables: dict[str, dict[str, int]]) -> int:
    if alphabet == "ipa":
        found = _ipa_viseme(symbol)
    elif alphabet == "arpabet":
        found = tables["arpabet"].get(symbol.upper().rstrip("012"))
    elif alphabet in tables:
        found = tables[alphabet].get(symbol)
    else:
        raise SpeechError(f"unknown phoneme alphabet {alphabet!r}; known: {', '.join(ALPHABETS)}")
    if found is None:
        raise SpeechError(f"{symbol!r} is not a symbol of the {alphabet} alphabet")
    return found


def is_bilabial(phoneme: str, language: str = "en") -> bool:
    """True when the lips close for the phoneme (viseme 1: p, b, m)."""
    return viseme_of(phoneme, language) == BILABIAL


# ---- phoneme files ---------------------------------------------------------------------------


def read_phoneme_file(
    path: str | Path, *, language: str = "en", duration: float | None = None
) -> PhonemeFile:
    """Read timings made by another engine, to pair with its WAV.

    Three formats, told apart by the first line that is not blank or a ``#`` comment:

    - **Amazon Polly speech marks** (JSON lines, ``{"time": ms, "type": …, "value": …}``):
      ``viseme`` entries become phones (a phone ends where the next begins; the last lasts until
      ``duration`` when given, else :data:`LAST_PHONE_S`), ``ssml`` entries become marks,
      ``word`` entries words (ending with their last phone before the next word);
      ``sentence`` entries are skipped.
    - **timings** as ``say --timings-out`` writes them (:mod:`vtts.speech.timings`): the header
      ``kind start end label viseme``, then ``phone`` rows (the viseme as written) and ``word``
      rows.
    - **a table**: lines ``start end phoneme`` (seconds; the phoneme an espeak-ng name or IPA),
      lines ``mark TIME NAME`` for SSML mark times, ``#`` comments. A comment
      ``# alphabet: arpabet`` (or ``ipa``, ``polly``, ``espeak-en``) says how to read the
      phonemes; without it they are espeak-ng names or IPA in ``language``.

    Every phone gets its viseme. Errors are :class:`SpeechError` with the file and line.
    """
    path = Path(path)
    try:
        text = read_bytes_capped(path, MAX_TEXT_BYTES, what="phoneme file").decode("utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise SpeechError(f"cannot read the phoneme file: {e}", file=str(path)) from None
    lines = text.splitlines()
    first = next((ln.strip() for ln in lines if ln.strip() and not ln.lstrip().startswith("#")), "")
    if not first:
        raise SpeechError("the phoneme file has no phones", file=str(path))
    if first.startswith("{"):
        result = _read_polly(lines, str(path), duration)
    elif first.split() == list(HEADER):
        result = _read_timings(lines, str(path))
    else:
        result = _read_table(lines, str(path), language)
    if not result.phones:
        raise SpeechError("the phoneme file has no phones", file=str(path))
    last = max(
        [p.end for p in result.phones]
        + [m.time for m in result.marks]
        + [w.end for w in result.words]
    )
    if last > MAX_DURATION_S:
        raise LimitError(
            f"the phonemes last until {last:g} s, more than the limit of {MAX_DURATION_S:g} s",
            file=str(path),
        )
    return result


def _read_polly(lines: list[str], file: str, duration: float | None) -> PhonemeFile:
    polly = viseme_tables()["polly"]
    starts: list[tuple[float, str, int]] = []
    marks: list[Mark] = []
    words: list[tuple[float, str]] = []
    for n, line in enumerate(lines, start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        try:
            entry = json.loads(s)
        except json.JSONDecodeError as e:
            raise SpeechError(
                f"not a JSON speech mark ({e.msg}): {_short(s)}", file=file, line=n
            ) from None
        except (ValueError, RecursionError) as e:  # an integer of 5,000 digits, deep nesting
            reason = "nested too deeply" if isinstance(e, RecursionError) else str(e).split(";")[0]
            raise SpeechError(
                f"not a JSON speech mark ({reason}): {_short(s)}", file=file, line=n
            ) from None
        if not isinstance(entry, dict) or "type" not in entry or "time" not in entry:
            raise SpeechError(
                f'expected {{"time": ms, "type": ..., "value": ...}}, got {_short(s)}',
                file=file,
                line=n,
            )
        t = entry["time"]
        if isinstance(t, bool) or not isinstance(t, int | float) or not _finite(t) or t < 0:
            raise SpeechError(
                f"time must be milliseconds >= 0, got {_short(repr(t))}", file=file, line=n
            )
        seconds = t / 1000.0
        kind, value = entry["type"], entry.get("value")
        if kind == "viseme":
            if not isinstance(value, str) or value not in polly:
                raise SpeechError(
                    f"unknown Polly viseme {value!r}; known: {' '.join(polly)}", file=file, line=n
                )
            if starts and seconds < starts[-1][0]:
                raise SpeechError(
                    f"viseme times must not decrease, got {t} ms after {starts[-1][0] * 1000:g} ms",
                    file=file,
                    line=n,
                )
            starts.append((seconds, value, polly[value]))
        elif kind == "ssml":
            marks.append(Mark(str(value), seconds))
        elif kind == "word":
            words.append((seconds, str(value)))
    phones = []
    for k, (start, value, vis) in enumerate(starts):
        if k + 1 < len(starts):
            end = starts[k + 1][0]
        elif duration is not None and duration >= start:
            end = duration
        else:
            end = start + LAST_PHONE_S
        phones.append(Phone(start, end, value, vis))
    marks.sort(key=lambda m: m.time)
    return PhonemeFile(phones, marks, "polly", "polly", word_ends(words, phones))


_ALPHABET_LINE = re.compile(r"#\s*alphabet\s*[:=]\s*(\S+)", re.IGNORECASE)


def _read_table(lines: list[str], file: str, language: str) -> PhonemeFile:
    alphabet: str | None = None
    phones: list[Phone] = []
    marks: list[Mark] = []
    for n, line in enumerate(lines, start=1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            m = _ALPHABET_LINE.match(s)
            if m:
                alphabet = m.group(1).lower()
                if alphabet not in ALPHABETS:
                    raise SpeechError(
                        f"unknown alphabet {alphabet!r}; known: {', '.join(ALPHABETS)}",
                        file=file,
                        line=n,
                    )
            continue
        fields = s.split()
        if fields[0] == "mark":
            if len(fields) != 3 or _number(fields[1]) is None or _number(fields[1]) < 0:
                raise SpeechError(f"expected 'mark TIME NAME', got {_short(s)}", file=file, line=n)
            marks.append(Mark(fields[2], _number(fields[1])))
            continue
        start = _number(fields[0]) if len(fields) == 3 else None
        end = _number(fields[1]) if len(fields) == 3 else None
        if start is None or end is None or not 0 <= start <= end:
            raise SpeechError(
                f"expected 'start end phoneme' (seconds) with 0 <= start <= end, got {_short(s)}",
                file=file,
                line=n,
            )
        _check_follows(phones, start, file, n)
        symbol = fields[2]
        try:
            vis = viseme_of(symbol, language, alphabet=alphabet)
        except SpeechError as e:
            raise SpeechError(e.message, file=file, line=n) from None
        phones.append(Phone(start, end, symbol, vis))
    marks.sort(key=lambda m: m.time)
    return PhonemeFile(phones, marks, "table", alphabet or "espeak-en")


_VISEME_NAMES = frozenset(str(v) for v in range(15))


def _read_timings(lines: list[str], file: str) -> PhonemeFile:
    phones: list[Phone] = []
    words: list[TimedWord] = []
    header_seen = False
    for n, line in enumerate(lines, start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        fields = s.split("\t") if "\t" in s else s.split()
        if not header_seen:  # the caller checked it
            header_seen = True
            continue
        fields = [f.strip() for f in fields]
        start = _number(fields[1]) if len(fields) == 5 else None
        end = _number(fields[2]) if len(fields) == 5 else None
        if (
            len(fields) != 5
            or fields[0] not in ("word", "phone")
            or start is None
            or end is None
            or not 0 <= start <= end
        ):
            raise SpeechError(
                "expected 'kind start end label viseme' with kind word or phone and "
                f"0 <= start <= end (seconds), got {_short(s)}",
                file=file,
                line=n,
            )
        kind, label, vis = fields[0], fields[3], fields[4]
        if kind == "word":
            words.append(TimedWord(start, end, label))
            continue
        if vis not in _VISEME_NAMES:
            raise SpeechError(
                f"a phone's viseme must be 0–14, got {_short(vis)}", file=file, line=n
            )
        _check_follows(phones, start, file, n)
        phones.append(Phone(start, end, label, int(vis)))
    words.sort(key=lambda w: w.start)
    return PhonemeFile(phones, [], "timings", "timings", words)


def _check_follows(phones: list[Phone], start: float, file: str, line: int) -> None:
    """A phone starting at ``start`` (s) must not start before the last of ``phones`` ends."""
    if phones and start < phones[-1].end - 1e-6:
        raise SpeechError(
            f"phones must follow each other: starts at {start:g} s before the previous "
            f"phone ends ({phones[-1].end:g} s)",
            file=file,
            line=line,
        )


def _finite(x: float) -> bool:
    try:
        return math.isfinite(x)
    except OverflowError:  # an int too large for a float
        return False


def _number(s: str) -> float | None:
    try:
        x = float(s)
    except ValueError:
        return None
    return x if math.isfinite(x) else None


def _short(s: str, limit: int = 60) -> str:
    return repr(s if len(s) <= limit else s[: limit - 1] + "…")
