"""``vtts say --timings-out FILE.tsv`` (issue 19): one row per word and per phone in the audio's
clock, from espeak-ng's own events, and read back by ``--phonemes``."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest

from vtts.errors import SpeechError, VttsWarning
from vtts.limits import LimitError
from vtts.render import write_wav
from vtts.speech.phonemes import read_phoneme_file
from vtts.speech.timings import HEADER, TimedPhone, TimedWord, format_timings, word_ends
from vtts.utterance import prepare_utterance, write_utterance_timings

from ..in_process import vtts

HEAD = Path(__file__).parents[1] / "data" / "models" / "head.wrl"
TEXT = 'Hello <smile 1s> my name is Bob, and 123 "friends". Maybe <blink> we meet.'
WORDS = ["Hello", "my", "name", "is", "Bob", "and", "123", "friends", "Maybe", "we", "meet"]


def rows(path: Path) -> list[list[str]]:
    lines = path.read_text(encoding="utf-8").splitlines()
    assert lines[0].split("\t") == list(HEADER)
    return [ln.split("\t") for ln in lines[1:]]


def test_format() -> None:
    phones = [TimedPhone(0.0, 0.012, 0, "_"), TimedPhone(0.012, 0.1, 1, "m")]
    phones.append(TimedPhone(0.1, 0.25, 10, "A:"))
    words = [TimedWord(0.012, 0.25, "ma\tma")]
    assert format_timings(phones, words) == (
        "kind\tstart\tend\tlabel\tviseme\n"
        "phone\t0.0000\t0.0120\t_\t0\n"
        "word\t0.0120\t0.2500\tma_ma\t-\n"
        "phone\t0.0120\t0.1000\tm\t1\n"
        "phone\t0.1000\t0.2500\tA:\t10\n"
    )


@pytest.fixture(scope="module")
def espeak_utterance():
    return prepare_utterance(TEXT)


def test_espeak_words_span_their_phones(espeak_utterance) -> None:
    utt = espeak_utterance
    assert [w.label for w in utt.words] == WORDS
    for a, b in zip(utt.words, utt.words[1:], strict=False):
        assert a.start < a.end <= b.start
    # every phone that is not a pause (viseme 0) lies inside exactly one word
    spoken = [p for p in utt.phones if p.viseme]
    assert len(spoken) > len(WORDS)
    for p in spoken:
        inside = [w for w in utt.words if w.start - 1e-9 <= p.start and p.end <= w.end + 1e-9]
        assert len(inside) == 1, p
    # the bookmarks' times are the starts of the words after them (not espeak's mark events,
    # which come up to a phone early, like its word events)
    smile, blink = utt.bookmarks
    assert smile.time == utt.words[1].start and blink.time == utt.words[9].start
    # "my": m is bilabial
    m = next(p for p in utt.phones if p.start >= utt.words[1].start - 1e-9)
    assert m.phoneme == "m" and m.viseme == 1


def test_a_bookmark_before_a_word_starts_at_its_first_phone() -> None:
    """espeak-ng reports the mark in "my name <smile> is" 67 ms early, inside the m of "name";
    the smile starts where the timings table says "is" starts, at its I."""
    utt = prepare_utterance("my name <smile> is")
    (smile,) = utt.bookmarks
    assert [w.label for w in utt.words] == ["my", "name", "is"]
    assert smile.time == utt.words[2].start
    phone = next(p for p in utt.phones if p.start == smile.time)
    assert phone.phoneme == "I"
    before = [p for p in utt.phones if p.end <= smile.time]
    assert before[-1].phoneme == "m" and before[-1].start >= utt.words[1].start
    table = format_timings(utt.phones, utt.words).splitlines()
    assert f"word\t{smile.time:.4f}\t{utt.words[2].end:.4f}\tis\t-" in table


def test_say_writes_timings_and_reads_them_back(tmp_path: Path) -> None:
    tsv, wav = tmp_path / "t.tsv", tmp_path / "t.wav"
    r = vtts("say", TEXT, "--model", str(HEAD), "--timings-out", str(tsv), "--wav-out", str(wav))
    assert r.returncode == 0, r.stderr
    assert str(tsv) in r.stdout
    table = rows(tsv)
    words = [row for row in table if row[0] == "word"]
    phones = [row for row in table if row[0] == "phone"]
    assert [w[3] for w in words] == WORDS and all(w[4] == "-" for w in words)
    starts = [float(p[1]) for p in phones]
    assert starts == sorted(starts) and float(phones[0][1]) == 0.0
    for a, b in zip(phones, phones[1:], strict=False):
        assert float(a[2]) == pytest.approx(float(b[1]), abs=1e-4)  # no gaps, no overlaps
    assert all(0 <= int(p[4]) <= 14 for p in phones)
    # the table is a phoneme file: the same timings again, with the same visemes
    again = tmp_path / "again.tsv"
    r = vtts(
        "say", TEXT, "--model", str(HEAD), "--phonemes", str(tsv), "--audio", str(wav),
        "--timings-out", str(again),
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert again.read_text() == tsv.read_text()
    # an output may not replace the phoneme file it reads
    r = vtts("say", TEXT, "--model", str(HEAD), "--phonemes", str(tsv), "--audio", str(wav),
             "--timings-out", str(tsv))  # fmt: skip
    assert r.returncode == 1 and "also an input" in r.stderr


def test_reused_timings_place_bookmarks_at_their_words(tmp_path: Path, espeak_utterance) -> None:
    utt = espeak_utterance
    tsv, wav = tmp_path / "t.tsv", tmp_path / "t.wav"
    write_utterance_timings(tsv, utt)
    write_wav(wav, utt.audio, utt.rate)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "placed in proportion" warning
        again = prepare_utterance(TEXT, phonemes=tsv, audio=wav)
    times = [b.time for b in again.bookmarks]
    assert times == [again.words[1].start, again.words[9].start]
    assert times == pytest.approx([b.time for b in utt.bookmarks], abs=0.03)
    # words that are not the text's: the rough placement, said
    with pytest.warns(VttsWarning, match="in proportion"):
        other = prepare_utterance("One <blink> two three four.", phonemes=tsv, audio=wav)
    assert other.bookmarks[0].time == pytest.approx(other.duration * 4 / len(other.text.text))


def test_polly_word_marks_become_words(tmp_path: Path) -> None:
    marks = [
        {"time": 0, "type": "word", "start": 0, "end": 2, "value": "Hi"},
        {"time": 0, "type": "viseme", "value": "k"},
        {"time": 80, "type": "viseme", "value": "a"},
        {"time": 200, "type": "viseme", "value": "sil"},
        {"time": 300, "type": "word", "start": 3, "end": 6, "value": "Bob"},
        {"time": 300, "type": "viseme", "value": "p"},
        {"time": 380, "type": "viseme", "value": "a"},
        {"time": 500, "type": "viseme", "value": "p"},
    ]
    path = tmp_path / "p.json"
    path.write_text("\n".join(map(json.dumps, marks)))
    pf = read_phoneme_file(path, duration=0.6)
    assert pf.words == [TimedWord(0.0, 0.2, "Hi"), TimedWord(0.3, 0.6, "Bob")]


def test_word_ends_without_phones_inside() -> None:
    phones = [TimedPhone(0.0, 0.5, 0, "_")]
    assert word_ends([(0.1, "x")], phones) == [TimedWord(0.1, 0.5, "x")]


@pytest.mark.parametrize(
    "body, fragment",
    [
        ("phone\t0\t0.1\tm\n", "expected 'kind start end label viseme'"),
        ("phone\t0\t0.1\tm\t15\n", "viseme must be 0–14"),
        ("phone\t0\t0.1\tm\t1²\n", "viseme must be 0–14"),
        ("syllable\t0\t0.1\tm\t1\n", "kind word or phone"),
        ("phone\t0.2\t0.1\tm\t1\n", "0 <= start <= end"),
        ("phone\t0\t0.2\tm\t1\nphone\t0.1\t0.3\ta\t10\n", "phones must follow each other"),
        ("word\t0\t1e9\tx\t-\nphone\t0\t0.1\tm\t1\n", "more than the limit"),
        ("word\t0\t0.1\tx\t-\n", "no phones"),
    ],
)
def test_bad_timings(tmp_path: Path, body: str, fragment: str) -> None:
    path = tmp_path / "t.tsv"
    path.write_text("kind\tstart\tend\tlabel\tviseme\n" + body)
    with pytest.raises((SpeechError, LimitError), match=fragment) as err:
        read_phoneme_file(path)
    assert err.value.file == str(path)
