"""festival's HTS voice (issue 19): phones and words from the utterance structure, in the audio's
clock; ``vtts say --engine festival`` end to end. Needs Debian's festival and festvox-us-slt-hts
(scripts/setup.sh installs them); the tests fail, loudly, without them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vtts.errors import SpeechError
from vtts.render import probe_media
from vtts.speech import festival
from vtts.speech.festival import PHONE_SET, SILENCES, festival_viseme, synthesize
from vtts.utterance import prepare_utterance

from ..in_process import vtts

HEAD = Path(__file__).parents[1] / "data" / "models" / "head.wrl"
TEXT = "Hello <smile 1s> my name is Bob. Maybe <blink> we meet at 3 pm, Dr. Müller."
WORDS = ["Hello", "my", "name", "is", "Bob", "Maybe", "we", "meet", "at", "3", "pm", "Dr"]
WORDS += ["Müller"]


@pytest.fixture(scope="module")
def utterance():
    return prepare_utterance(TEXT, engine="festival")


def test_every_phone_of_the_set_has_a_viseme() -> None:
    visemes = {p: festival_viseme(p) for p in PHONE_SET}
    assert {p for p, v in visemes.items() if v == 0} == SILENCES
    assert [p for p, v in visemes.items() if v == 1] == ["b", "em", "m", "p"]
    assert visemes["f"] == visemes["v"] == 2 and visemes["th"] == visemes["dh"] == 3
    assert visemes["hv"] == visemes["hh"]
    with pytest.raises(SpeechError, match="not in its radio set"):
        festival_viseme("xx")


def test_phones_cover_the_audio_without_overlap(utterance) -> None:
    u = utterance
    assert u.rate == 32000 and u.audio.dtype == np.int16 and np.abs(u.audio).max() > 3000
    assert 2.5 < u.duration < 8.0  # 13 words
    assert u.phones[0].start == 0.0 and u.phones[-1].end == pytest.approx(u.duration)
    for a, b in zip(u.phones, u.phones[1:], strict=False):
        assert a.end == b.start and a.start < a.end
    spoken = [p for p in u.phones if p.viseme]
    assert len(spoken) > 30
    durations = [p.end - p.start for p in spoken]
    assert min(durations) >= 0.005 and max(durations) < 0.4  # HTS frames are 5 ms
    assert all(p.phoneme in PHONE_SET for p in u.phones)


def test_pauses_are_silent_and_vowels_loud(utterance) -> None:
    # festival's segment times are the truth for its audio (what an aligner is measured with)
    u = utterance
    x = u.audio.astype(np.float64)

    def rms(p) -> float:
        return float(np.sqrt(np.mean(x[int(p.start * u.rate) : int(p.end * u.rate)] ** 2)))

    vowels = [rms(p) for p in u.phones if p.viseme >= 10]
    pauses = [rms(p) for p in u.phones if p.phoneme == "pau"]
    assert len(pauses) >= 3  # the start, after "Bob." and after "Maybe we meet at 3 pm,"
    assert max(pauses) < 0.1 * np.median(vowels) and min(vowels) > 0.25 * np.median(vowels)


def test_bilabials_are_viseme_1_and_the_lips_close_in_the_audio(utterance) -> None:
    u = utterance
    bilabials = [p for p in u.phones if p.phoneme in ("p", "b", "m")]
    assert [p.phoneme for p in bilabials] == ["m", "m", "b", "b", "m", "b", "m", "p", "m", "m"]
    assert all(p.viseme == 1 for p in bilabials)
    # a stop's (b, p) closure is much quieter than the vowel beside it: the times are this
    # audio's (the quietest 10 ms of the segment against the vowel's mean)
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
            ratios.append(quietest(p.start, p.end) / rms(vowel.start, vowel.end))
    assert len(ratios) == 4 and max(ratios) < 0.3, ratios


def test_words_and_bookmarks(utterance) -> None:
    u = utterance
    assert [w.label for w in u.words] == WORDS  # as written, "3" and "Dr" one word each
    for a, b in zip(u.words, u.words[1:], strict=False):
        assert a.start < a.end <= b.start
    smile, blink = u.bookmarks
    assert smile.time == u.words[1].start and blink.time == u.words[6].start
    three = u.words[WORDS.index("3")]
    spoken = [p.phoneme for p in u.phones if three.start <= p.start < three.end]
    assert spoken == ["th", "r", "iy"]


def test_long_text_is_spoken_in_utterances_of_a_few_sentences(monkeypatch) -> None:
    assert festival._chunks("Hi. Bob is here! Mary, too.\n\nYes", 5) == [
        "Hi. Bob is here! ",
        "Mary, too.\n\n",
        "Yes",
    ]
    assert festival._chunks("a b c d e f g h i j k", 8) == ["a b c d ", "e f g h ", "i j k"]
    assert festival._chunks("Short.", 300) == ["Short."]
    monkeypatch.setattr(festival, "CHUNK_CHARS", 8)
    text = "Bob is here. Mary is there."
    one = synthesize(text, marks=[text.index("Mary")])
    assert [w.text for w in one.words] == ["Bob", "is", "here", "Mary", "is", "there"]
    assert one.marks[0].time == one.words[3].start
    assert one.words[2].end < one.words[3].start  # a pause: the second utterance's
    for a, b in zip(one.phonemes, one.phonemes[1:], strict=False):
        assert a.end == pytest.approx(b.start, abs=1e-9) and a.start < a.end
    assert one.phonemes[-1].end == pytest.approx(one.duration)
    # the chunks' audio joined: the second utterance's phones are where its sound is
    m = next(p for p in one.phonemes if p.phoneme == "m")
    i = int(m.start * one.rate)
    assert np.abs(one.audio[i - 3200 : i - 1600]).max() < 1500  # the pause before Mary


def test_rate_and_pitch() -> None:
    slow = synthesize("Hello there.", rate=120)
    fast = synthesize("Hello there.", rate=240)
    assert fast.duration < 0.7 * slow.duration
    with pytest.raises(SpeechError, match="rate must be an integer within 80–450"):
        synthesize("Hi", rate=20)


def test_deterministic() -> None:
    a, b = synthesize("Bob."), synthesize("Bob.")
    assert np.array_equal(a.audio, b.audio) and a.phonemes == b.phonemes


def test_missing_voice_and_program(monkeypatch) -> None:
    with pytest.raises(SpeechError, match="festival has no voice 'kal_nobody'"):
        synthesize("Hi", voice="kal_nobody")
    with pytest.raises(SpeechError, match="invalid festival voice"):
        synthesize("Hi", voice='x) (system "rm"')
    monkeypatch.setattr(festival, "DEFAULT_VOICE", "cmu_us_nobody_hts")
    with pytest.raises(SpeechError, match="apt-get install .*festvox-us-slt-hts"):
        synthesize("Hi", voice="cmu_us_nobody_hts")
    monkeypatch.setenv("PATH", "/nonexistent")
    with pytest.raises(SpeechError, match="festival is missing: install it with 'apt-get"):
        synthesize("Hi")


@pytest.mark.parametrize(
    "attack",
    [
        '{q}) (system "touch {f}") ("',
        '\\{q}) (system "touch {f}") ;',
        '\n(system "touch {f}")\n',
        '\'(system "touch {f}")',
    ],
)
def test_text_cannot_escape_its_scheme_string(tmp_path: Path, attack: str) -> None:
    marker = tmp_path / "pwned"
    text = "Say " + attack.format(q='"', f=marker) + " done"
    speech = synthesize(text)
    assert not marker.exists()
    assert speech.words[0].text == "Say" and speech.words[-1].text == "done"


def test_say_engine_festival_end_to_end(tmp_path: Path) -> None:
    out, tsv = tmp_path / "f.mp4", tmp_path / "f.tsv"
    cmd = ["say", "Bob <smile> is here.", "--engine", "festival", "--model", str(HEAD)]
    cmd += ["--size", "160x120", "--quiet", "-o", str(out), "--timings-out", str(tsv)]
    r = vtts(*cmd)
    assert r.returncode == 0, r.stderr
    info = probe_media(out)
    assert info.audio_rate == 32000
    assert abs(info.duration_video - info.duration_audio) <= 1 / 30 + 1e-6
    rows = [ln.split("\t") for ln in tsv.read_text().splitlines()[1:]]
    assert [r[3] for r in rows if r[0] == "word"] == ["Bob", "is", "here"]
    assert [r[3] for r in rows if r[0] == "phone"][:3] == ["pau", "b", "aa"]
    # an espeak-ng voice is no festival voice
    cmd = ["say", "Hi", "--engine", "festival", "--voice", "en-gb", "--model", str(HEAD)]
    r = vtts(*cmd, "--timings-out", str(tmp_path / "x.tsv"))
    assert r.returncode == 1 and "invalid festival voice 'en-gb'" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "x.tsv").exists()
