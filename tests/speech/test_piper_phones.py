"""Piper's symbols to phones (:func:`vtts.speech.piper.phones_of`) and the engine interface;
no Piper needed (the symbols and sample counts are written here as Piper gives them)."""

from __future__ import annotations

import importlib

import pytest

from vtts.errors import SpeechError
from vtts.speech.engine import ENGINES, load_engine
from vtts.speech.piper import phones_of, symbol_kind, symbol_viseme

#: Every letter Piper's en_US voice spoke on README.md and docs/*.md (634,000 symbols), by
#: viseme: the table docs/speech.md gives.
SPOKEN = {
    1: "p m b", 2: "f v", 3: "ð θ", 4: "t d ɾ ʔ", 5: "k h ŋ ɡ", 6: "ʃ ʒ tʃ dʒ", 7: "s z",
    8: "n l", 9: "ɹ", 10: "æ a ʌ ɑ ɐ", 11: "ə ɛ e ɚ ɜ", 12: "ɪ i ᵻ j", 13: "ɔ o", 14: "ʊ w u",
}  # fmt: skip


@pytest.mark.parametrize("viseme", sorted(SPOKEN))
def test_every_letter_the_voice_speaks_has_its_viseme(viseme):
    for symbol in SPOKEN[viseme].split():
        assert symbol_viseme(symbol) == viseme, symbol
        assert len(symbol) > 1 or symbol_kind(symbol) == "phone"


def test_symbol_kinds():
    assert symbol_kind(" ") == "space"
    assert {symbol_kind(s) for s in ",.;:?!^$_"} == {"pause"}
    assert {symbol_kind(s) for s in "ˈˌ"} == {"stress"}
    assert {symbol_kind(s) for s in "ːʲ\u0329\u0303"} == {"modifier"}
    assert symbol_kind("☃") == "unknown"
    with pytest.raises(SpeechError, match="no viseme"):
        symbol_viseme("☃")


def _phones(text: str, counts: list[int]):
    symbols = ["^", *text, "$"]
    phones, words = phones_of(symbols, counts)
    return [(a, b, label, v) for a, b, label, v, _, _ in phones], words


def test_stress_starts_the_phone_after_it_and_length_lengthens_the_one_before():
    # "bˈɑːb." as Piper aligned "Bob." (samples per symbol)
    phones, words = _phones("bˈɑːb.", [768, 512, 1792, 1792, 1024, 2048, 512, 768])
    assert phones == [
        (0, 768, "_", 0),
        (768, 1280, "b", 1),
        (1280, 5888, "ɑː", 10),  # the stress mark's 1792 samples and the length mark's 1024
        (5888, 7936, "b", 1),
        (7936, 9216, ".", 0),  # the full stop and the end of the sentence: one pause
    ]
    assert words == 1


def test_a_space_within_a_phrase_is_shared_and_after_punctuation_a_pause():
    phones, words = _phones("ma ɪz, ɪt", [100, 10, 20, 40, 10, 20, 300, 60, 10, 20, 50])
    labels = [p[2] for p in phones]
    assert labels == ["_", "m", "a", "ɪ", "z", ",", "ɪ", "t", "_"]
    a, i = phones[2], phones[3]
    assert a[1] == i[0] == 130 + 20  # half the space's 40 samples to "a", half to "ɪ"
    comma = phones[5]
    assert comma[:2] == (200, 560) and comma[3] == 0  # the comma and the space after it
    assert words == 3


def test_affricates_are_one_phone_and_phones_cover_the_sentence():
    counts = [50, 30, 40, 60, 30, 20, 70, 40, 10]  # ^ t ʃ ˈ ɜ ː t ʃ $
    phones, _ = _phones("tʃˈɜːtʃ", counts)
    assert [p[2] for p in phones] == ["_", "tʃ", "ɜː", "tʃ", "_"]
    assert [p[3] for p in phones] == [0, 6, 11, 6, 0]
    for p, q in zip(phones, phones[1:], strict=False):
        assert p[1] == q[0] and p[0] < p[1]
    assert phones[0][0] == 0 and phones[-1][1] == sum(counts)


def test_alignments_must_match_the_symbols():
    with pytest.raises(SpeechError, match="alignments for"):
        phones_of(["^", "a", "$"], [1, 2])


@pytest.mark.parametrize("name", sorted(ENGINES))
def test_every_engine_module_gives_the_interface(name):
    module = importlib.import_module(ENGINES[name])  # importing never needs the engine itself
    engine = load_engine(name)
    assert engine is module.ENGINE and engine.name == name and engine.default_voice
    for method in ("speak", "sentences", "voices"):
        assert callable(getattr(engine, method))


def test_an_unknown_engine_is_named():
    with pytest.raises(SpeechError, match="unknown speech engine 'flite'; known: espeak"):
        load_engine("flite")
