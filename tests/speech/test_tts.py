"""espeak-ng through its C API: audio, phones and mark times in the audio's clock.

These tests need espeak-ng and fail (never skip) when it is missing: ``make test`` installs it.
"""

from __future__ import annotations

import ctypes

import numpy as np
import pytest

from vtts.errors import SpeechError
from vtts.speech import tts
from vtts.speech.phonemes import viseme_tables
from vtts.speech.tts import escape, synthesize, voices

TWO_MARKS = '<speak>Hello <mark name="m1"/> world <mark name="m2"/> again</speak>'


@pytest.fixture(scope="module")
def speech():
    return synthesize(TWO_MARKS)


def first(speech, phoneme, after=0.0):
    return next(p for p in speech.phonemes if p.phoneme == phoneme and p.start >= after)


def test_espeak_ng_library_is_installed():
    try:
        ctypes.CDLL("libespeak-ng.so.1")
    except OSError as e:  # the project rule: a missing espeak-ng is a failure, not a skip
        pytest.fail(f"{tts.INSTALL_HINT}: {e}")


def test_audio_and_phones_cover_the_same_clock(speech):
    assert speech.rate == 22050
    assert speech.audio.dtype == np.int16 and speech.audio.ndim == 1
    assert speech.audio.size > speech.rate // 2 and np.abs(speech.audio).max() > 1000
    phones = speech.phonemes
    assert phones[0].start == 0.0
    assert phones[-1].end == pytest.approx(speech.duration)
    assert all(p.end > p.start for p in phones)
    assert all(a.end == b.start for a, b in zip(phones, phones[1:], strict=False))
    assert [p.phoneme for p in phones if p.viseme != 0] == [
        "h", "@", "l", "oU", "w", "3:", "l", "d", "a#", "g", "E", "n",
    ]  # fmt: skip
    assert all(p.viseme is not None for p in phones)
    # the first phone starts 264 samples in; the end pause is about 300 ms of silence
    assert first(speech, "h").start == pytest.approx(264 / 22050)
    pause = next(p for p in phones if p.phoneme == "_:")
    assert 0.25 < pause.duration < 0.35
    assert np.abs(speech.audio[int(pause.start * 22050) + 200 :]).max() < 500


def test_marks_in_order_between_the_right_phones(speech):
    assert [m.name for m in speech.marks] == ["m1", "m2"]
    m1, m2 = (m.time for m in speech.marks)
    o, w = first(speech, "oU"), first(speech, "w")
    assert o.start < m1 <= w.start  # after "Hello", before "world"
    d, a = first(speech, "d"), first(speech, "a#")
    assert d.start < m2 <= a.start  # after "world", before "again"
    assert 0 < m1 < m2 < speech.duration


def test_identical_results_run_to_run(speech):
    again = synthesize(TWO_MARKS)
    assert np.array_equal(again.audio, speech.audio)
    assert again.phonemes == speech.phonemes
    assert again.marks == speech.marks


def test_mark_after_a_full_stop_is_not_lost():
    # espeak-ng drops this mark (its issue 920); it gets the time of the next word
    s = synthesize('Hello world. <mark name="x"/>Tom again. <mark name="end"/>')
    assert [m.name for m in s.marks] == ["x", "end"]
    x = s.marks[0].time
    assert first(s, "d").end <= x <= first(s, "t").start
    n = first(s, "n", after=x)  # the last sound of "again"; espeak reports the mark during it
    assert n.start <= s.marks[1].time <= n.end


@pytest.mark.parametrize(
    ("text", "word"),
    [
        ('Hi <mark name="a"/> there', "there"),
        ('<mark name="a"/>Hi there', "Hi"),  # not 0: at the H, after the leading silence
        ('Say <mark name="a"/> "hello" now', "hello"),  # an opening quote is not spoken
        ('Then <mark name="x"/><mark name="a"/> now', "now"),  # nor another mark
        ("One <mark name='a'/>(two) three", "two"),
    ],
)
def test_a_mark_right_before_a_word_is_at_the_words_first_phone(text, word):
    s = synthesize(text)
    mark = next(m for m in s.marks if m.name == "a")
    w = next(w for w in s.words if w.text == word)
    assert mark.time == w.start
    assert any(p.start == w.start and p.viseme for p in s.phonemes)


def test_a_mark_before_a_pause_stays_before_it():
    """A comma between the mark and the next word: the mark stays where espeak-ng puts it, at
    the end of the word before, not after the pause."""
    s = synthesize('One <mark name="a"/>, two')
    one, two = s.words
    assert s.marks[0].time == pytest.approx(one.end, abs=0.02) and s.marks[0].time < two.start - 0.1


def test_mark_names_come_back_as_written():
    s = synthesize(
        "<speak>A <mark name='single'/> b <mark name=\"a&amp;b &lt;é&gt;\"/> c "
        '<mark name="single"/> d</speak>'
    )
    assert [m.name for m in s.marks] == ["single", "a&b <é>", "single"]
    times = [m.time for m in s.marks]
    assert times == sorted(times) and len(set(times)) == 3


def test_plain_text_fragments_and_escaping():
    plain = synthesize("Tom & Jerry <3", ssml=False)
    assert plain.marks == [] and plain.duration > 0.5
    escaped = synthesize(escape("Tom & Jerry <3"))
    assert escaped.duration > 0.5
    fragment = synthesize('Hi <mark name="a"/> there')
    assert [m.name for m in fragment.marks] == ["a"]
    assert fragment.words[1].position == len('Hi <mark name="a"/> ')
    with pytest.raises(SpeechError, match="not well-formed SSML .* line 1, column"):
        synthesize("Tom & Jerry")


def test_rate_changes_duration_and_pitch_changes_pitch():
    text = "The rainbow is a division of white light into many beautiful colours."
    slow, fast = synthesize(text, rate=100), synthesize(text, rate=300)
    assert slow.duration > 2.0 * fast.duration
    low, high = synthesize(text, pitch=10), synthesize(text, pitch=90)
    assert abs(low.duration - high.duration) < 0.05 * low.duration
    assert f0(high) > 1.5 * f0(low)


def f0(speech) -> float:
    """Median fundamental frequency (Hz) over the vowels, by autocorrelation."""
    vowels = {v for s, v in viseme_tables()["espeak-en"].items() if v >= 10}
    found = []
    for p in speech.phonemes:
        if p.viseme in vowels and p.duration > 0.06:
            x = speech.audio[int(p.start * speech.rate) : int(p.end * speech.rate)]
            x = x.astype(float) - x.mean()
            ac = np.correlate(x, x, "full")[x.size - 1 :]
            lo, hi = speech.rate // 500, speech.rate // 50
            found.append(speech.rate / (lo + int(np.argmax(ac[lo:hi]))))
    return float(np.median(found))


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        ({"voice": "xx-nope"}, "unknown voice 'xx-nope'"),
        ({"voice": "en-us+nope"}, "unknown voice variant 'nope'"),
        ({"voice": "../etc"}, "invalid voice"),
        ({"rate": 20}, "rate must be an integer within 80–450"),
        ({"pitch": 100}, "pitch must be an integer within 0–99"),
    ],
)
def test_bad_voice_rate_pitch(kwargs, fragment):
    with pytest.raises(SpeechError, match=fragment.replace("+", r"\+")) as e:
        synthesize("Hello", **kwargs)
    if "unknown voice" in fragment:
        assert "voices include" in str(e.value) and "vtts voices" in str(e.value)


def test_unknown_voice_lists_voices_of_its_language():
    with pytest.raises(SpeechError) as e:
        synthesize("Hello", voice="en-us+nope")
    assert "en-us" in str(e.value) and "en-gb-x-rp" in str(e.value)


def test_missing_library_says_how_to_install(monkeypatch):
    monkeypatch.setenv(tts.LIBRARY_ENV, "libespeak-ng-not-here.so.1")
    with pytest.raises(
        SpeechError, match=r"espeak-ng is missing: install it with 'apt-get install"
    ):
        synthesize("Hello")


def test_voices_and_language_codes():
    english = voices("en")
    langs = {v.language for v in english}
    assert {"en-us", "en-gb", "en-gb-x-rp"} <= langs
    assert all(any(c == "en" or c.startswith("en-") for c in v.languages) for v in english)
    assert len(voices()) > len(english) and voices("fr")
    gb = synthesize("Hello", voice="en-gb")  # a language code, not a voice file name
    assert gb.voice.identifier == "gmw/en" and gb.language == "en-gb"
    assert synthesize("Hello", voice="en-us+f3").voice.gender == "female"


def test_non_english_voice_gets_ipa_and_visemes():
    s = synthesize("Bonjour tout le monde", voice="fr")
    spoken = [p for p in s.phonemes if p.viseme != 0]
    assert [p.ipa for p in spoken[:5]] == ["b", "ɔ̃", "ʒ", "u", "ʁ"]
    assert [p.viseme for p in spoken[:5]] == [1, 13, 6, 14, 5]
    assert synthesize("Hello", voice="en-us").phonemes[1].ipa is None


def test_workers_started_ahead_speak_as_fresh_ones():
    """keep_workers_ready: a worker waits for its request; what it speaks is what a worker
    started at the request speaks, to the sample; 0 ends the waiting ones."""
    plain = synthesize("Hello there, again.")
    tts.keep_workers_ready(1)
    try:
        (waiting,) = tts._SPARES.ready
        assert waiting.poll() is None  # started, waiting for a request
        ahead = synthesize("Hello there, again.")
        assert waiting.returncode == 0  # it spoke and ended
        assert len(tts._SPARES.ready) == 1 and tts._SPARES.ready[0] is not waiting
    finally:
        tts.keep_workers_ready(0)
    assert tts._SPARES.ready == []
    np.testing.assert_array_equal(ahead.audio, plain.audio)
    assert [p.start for p in ahead.phonemes] == [p.start for p in plain.phonemes]
