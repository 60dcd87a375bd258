"""Phonemes to MPEG-4 visemes, and phoneme files from other engines (Polly, tables)."""

from __future__ import annotations

import csv
import json

import pytest

from vtts.errors import SpeechError
from vtts.resources import package_data
from vtts.speech.phonemes import (
    PAUSES,
    Mark,
    ipa_key,
    is_bilabial,
    read_phoneme_file,
    viseme_of,
    viseme_tables,
)
from vtts.speech.tts import synthesize

# A few hundred words with every English sound, rare ones included (vision, loch, the glottal
# stop in button, syllabic consonants, r-coloured vowels, French loans, letters and numbers).
VARIED = """
The quick brown fox jumps over the lazy dog; sphinx of black quartz, judge my vow.
Thirty-three thistles thrive, although they breathe and bathe in smooth clothes.
Measure the treasure: a beige garage, a genre of vision, azure leisure in Asia.
Church, judge, jazz, cheese, choir, chorus, chef, champagne, machine, nature, soldier.
Sing, singer, finger, longer, anger, ink, think, sixth, twelfth, strengths, length.
Hue, huge, human, youth, yes, yacht, union, few, view, cute, beauty, queue, tune.
Whale, which, where, what, wheel, one, once, queen, squirrel, language, persuade.
Butter, better, water, bottle, little, kitten, button, mountain, certain, written.
Car, far, park, heart, father, palm, calm, bath, path, dance, laugh, aunt, banana.
Bed, head, said, friend, any, many, bury, leopard, says, again, bread, weather.
Bit, busy, women, gym, pretty, myth, build, rhythm, England, minute, roses, wanted.
Hot, lot, what, want, wash, watch, knowledge, cough, sausage, because, often.
Book, put, good, could, woman, wolf, foot, sugar, bush, pull, full.
Cut, love, blood, young, country, double, trouble, does, money, honey, mother.
Bird, word, heard, nurse, first, journey, colonel, were, her, fur, myrrh, earth.
Fleece, sea, key, receive, people, ski, quay, amoeba, phoenix, Caesar, seize, happy.
Goose, two, blue, shoe, through, who, fruit, juice, move, lose, canoe, rheumatism.
Face, day, break, vein, they, weigh, great, gauge, straight, eight, ballet, fiance.
Price, high, try, buy, eye, aisle, island, height, guide, kayak, either, fire, hour.
Choice, boy, voice, noise, oyster, buoy, toy, employ, turquoise, boisterous.
Mouth, now, cow, bough, house, drought, power, flower, our, shower, sure, poor.
Goat, show, no, though, dough, sew, soul, folk, brooch, yeoman, toe, oh.
Near, here, beer, fear, weird, pier, theory, idea, museum, career, clear, period, mirror.
Square, care, air, bear, their, there, prayer, mayor, heir, scarce, fairy, hurry.
North, force, thought, law, caught, talk, door, floor, four, more, war, broad, tour, cure.
Naive cafe, deja vu, rendezvous, bourgeois croissant, ensemble, faux pas, coup, debris.
Bach, loch, Dvorak, Tchaikovsky, Goethe, Zurich, Munich, Beijing, Xhosa, Qatar.
Uh-oh, mm-hmm, hmm, shh, psst, tsk, brr, ahem, whoa, yeah, nope, huh, ouch.
Numbers 0 1 2 3 7 11 12 13 20 99 100 1999 2024 3.14 42% $5 7:30 1st 2nd 3rd.
Letters A B C H J Q R W X Y Z, and https://fsf.org/ with @ # & * + = / ~.
Phthisis, sixths, glimpsed, texts, asks, wasps, months, anthem, asthma, isthmus.
Worcestershire, Leicester, Edinburgh, Arkansas, Illinois, Wednesday, February, library.
Subtle debt, doubt, receipt, salmon, almond, listen, castle, prism, chasm, schism.
Jury, judo, usury, tourist, Europe, furious, curious, obscure, secure, insurance.
"""


def test_every_english_phoneme_espeak_produces_is_in_the_table():
    english = viseme_tables()["espeak-en"]
    seen: set[str] = set()
    for voice in ("en-us", "en-gb"):
        speech = synthesize(VARIED, voice=voice, ssml=False)
        names = {p.phoneme for p in speech.phonemes}
        assert names <= set(english), f"{voice}: not in the table: {sorted(names - set(english))}"
        seen |= names
        # no fallback involved: the phone's viseme is the table's
        assert all(p.viseme == english[p.phoneme] for p in speech.phonemes)
    assert len(seen) >= 70
    # every MPEG-4 viseme shows up in ordinary English speech
    assert {english[n] for n in seen} == set(range(15))


def test_the_standard_viseme_symbols_map_to_their_viseme():
    with package_data("visemes.tsv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f, delimiter="\t"))
    for row in rows[1:]:
        for symbol in row["phonemes"].split(", "):
            assert viseme_of(symbol) == int(row["viseme"]), symbol


@pytest.mark.parametrize("phoneme", ["p", "b", "m", "m-"])
def test_bilabials(phoneme):
    assert is_bilabial(phoneme) and viseme_of(phoneme) == 1


@pytest.mark.parametrize("phoneme", ["f", "v", "w", "t", "@", "_", "U", "B"])
def test_not_bilabial(phoneme):
    assert not is_bilabial(phoneme)


@pytest.mark.parametrize("symbol", ["_", "_:", "_!", "||", "'", ",", "%", "=", "", "sil", "sp"])
def test_pauses_stress_and_boundaries_are_viseme_0(symbol):
    assert symbol in PAUSES and viseme_of(symbol) == 0 and viseme_of(symbol, "fr") == 0


@pytest.mark.parametrize(
    "phoneme, language, ipa, viseme",
    [
        ("aI", "en-us", None, 10),
        ("tS", "en-gb-x-rp", None, 6),
        ("3:", "en", None, 11),
        ("O~", "fr", "ɔ̃", 13),  # espeak's own IPA first for other languages
        ("r", "fr", "ʁ", 5),  # French r is uvular: no lip gesture
        ("r", "en", "ɹ", 9),  # English: the table, not the IPA
        ("y", "fr", None, 14),  # no IPA: names other tables use
        ("z2", "fr", None, 7),  # modifiers stripped
        ("l^", "it", None, 8),
        ("ʃ", "de", None, 6),  # IPA given as the phoneme
        ("tʃʰ", "hi", None, 6),  # longest IPA prefix, aspiration dropped
        ("ɔ̃", "fr", None, 13),
        ("aː", "de", None, 10),
        ("?", "en", None, 4),
        ("Gx", "xx", None, 5),  # the first letter, as a last resort
        ("§", "xx", None, 0),
    ],
)
def test_viseme_of(phoneme, language, ipa, viseme):
    assert viseme_of(phoneme, language, ipa=ipa) == viseme


def test_ipa_key_drops_marks_and_diacritics():
    assert ipa_key("ˈaːʰ") == "a"
    assert ipa_key("n̩") == "n"
    assert ipa_key("t͡ʃ") == "tʃ"
    assert ipa_key("ɔ̃ː") == "ɔ"


# Where the English table deliberately differs from the IPA espeak-ng reports for the name.
DELIBERATE = {
    "0": "en-us says ɑː for the 'top' vowel; MPEG-4 viseme 13 is that lexical set",
    "@L": "syllabic l (əl): the tongue gesture of l, viseme 8",
}


def test_english_table_agrees_with_espeak_ipa():
    path = package_data("phoneme_visemes.tsv")
    with path.open(encoding="utf-8") as f:
        rows = [r for r in csv.DictReader(f, delimiter="\t") if r["alphabet"] == "espeak-en"]
    checked = 0
    for r in rows:
        if r["ipa"] in ("-", "") or r["symbol"] in DELIBERATE:
            continue
        first_ipa, viseme = r["ipa"].split()[0], int(r["viseme"])
        # the IPA alone finds the row's viseme: the IPA table has the sound, or it is a bare
        # modifier (ʲ), no mouth shape of its own, which reads as a pause
        if ipa_key(first_ipa):
            assert viseme_of(first_ipa, alphabet="ipa") == viseme, r
        else:
            assert viseme == 0, r
        assert viseme_of("", "xx", ipa=first_ipa) == 0  # a pause stays one, whatever its IPA
        assert viseme_of("§", "xx", ipa=first_ipa) == viseme, r
        checked += 1
    assert checked >= 60


def test_explicit_alphabets():
    assert viseme_of("T", alphabet="arpabet") == 4  # ARPAbet T is t, espeak's T is θ
    assert viseme_of("AH0", alphabet="arpabet") == 10
    assert viseme_of("sil", alphabet="polly") == 0
    assert viseme_of("E", alphabet="polly") == 11
    assert viseme_of("θ", alphabet="ipa") == 3
    with pytest.raises(SpeechError, match="not a symbol of the polly alphabet"):
        viseme_of("x", alphabet="polly")
    with pytest.raises(SpeechError, match="unknown phoneme alphabet"):
        viseme_of("x", alphabet="klingon")


def test_polly_symbols_mean_the_same_through_the_default_lookup():
    for symbol, viseme in viseme_tables()["polly"].items():
        assert viseme_of(symbol) == viseme, symbol


# ---- phoneme files ---------------------------------------------------------------------------


def write_lines(path, lines):
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def polly(**entry):
    return json.dumps(entry)


def test_polly_speech_marks(tmp_path):
    f = write_lines(
        tmp_path / "marks.json",
        [
            polly(time=0, type="sentence", start=0, end=23, value="Mary had a little lamb."),
            polly(time=6, type="word", start=0, end=4, value="Mary"),
            polly(time=6, type="viseme", value="p"),
            polly(time=73, type="viseme", value="E"),
            polly(time=180, type="viseme", value="r"),
            polly(time=266, type="ssml", start=5, end=29, value="b0"),
            polly(time=266, type="viseme", value="i"),
            polly(time=400, type="viseme", value="sil"),
        ],
    )
    pf = read_phoneme_file(f)
    assert pf.kind == "polly" and pf.alphabet == "polly"
    assert [(p.start, p.end, p.phoneme, p.viseme) for p in pf.phones] == [
        (0.006, 0.073, "p", 1),
        (0.073, 0.18, "E", 11),
        (0.18, 0.266, "r", 9),
        (0.266, 0.4, "i", 12),
        (0.4, 0.5, "sil", 0),
    ]
    assert pf.marks == [Mark("b0", 0.266)]
    assert read_phoneme_file(f, duration=0.45).phones[-1].end == 0.45


@pytest.mark.parametrize(
    "third, message",
    [
        ("{not json", "not a JSON speech mark"),
        (polly(time=50, type="viseme", value="Q"), "unknown Polly viseme 'Q'"),
        (polly(time=1, type="viseme", value="p"), "viseme times must not decrease"),
        (polly(time=-5, type="viseme", value="p"), "time must be milliseconds >= 0"),
        ('{"type": "viseme"}', 'expected {"time": ms'),
    ],
)
def test_polly_errors_name_file_and_line(tmp_path, third, message):
    f = write_lines(
        tmp_path / "bad.json",
        [
            polly(time=0, type="viseme", value="sil"),
            polly(time=10, type="viseme", value="p"),
            third,
        ],
    )
    with pytest.raises(SpeechError, match=message) as e:
        read_phoneme_file(f)
    assert e.value.file == str(f) and e.value.line == 3
    assert str(e.value).startswith(f"{f}:3: ")


def test_table_of_phones(tmp_path):
    f = write_lines(
        tmp_path / "phones.txt",
        [
            "# from an aligner",
            "0.00 0.10 _",
            "0.10 0.18 h",
            "0.18 0.25 @",
            "",
            "0.25 0.31 l   # espeak names, IPA or SAMPA",
            "mark 0.31 b0",
            "0.31 0.50 oʊ",
            "0.50 0.60 m",
        ],
    )
    # a comment after the phoneme is not allowed: the line has four fields
    with pytest.raises(SpeechError) as e:
        read_phoneme_file(f)
    assert e.value.line == 6 and "expected 'start end phoneme'" in e.value.message
    lines = f.read_text().splitlines()
    lines[5] = "0.25 0.31 l"
    write_lines(f, lines)
    pf = read_phoneme_file(f)
    assert pf.kind == "table"
    assert [(p.phoneme, p.viseme) for p in pf.phones] == [
        ("_", 0), ("h", 5), ("@", 11), ("l", 8), ("oʊ", 13), ("m", 1),
    ]  # fmt: skip
    assert pf.phones[1].start == 0.10 and pf.phones[-1].end == 0.60
    assert pf.marks == [Mark("b0", 0.31)]


def test_table_in_arpabet(tmp_path):
    f = write_lines(
        tmp_path / "arpa.txt",
        ["# alphabet: arpabet", "0 0.1 sil", "0.1 0.2 T", "0.2 0.35 AH0", "0.35 0.4 M"],
    )
    pf = read_phoneme_file(f)
    assert pf.alphabet == "arpabet"
    assert [p.viseme for p in pf.phones] == [0, 4, 10, 1]


@pytest.mark.parametrize(
    "third, message",
    [
        (
            "0.5 0.2 a",
            "expected 'start end phoneme' (seconds) with 0 <= start <= end, got '0.5 0.2 a'",
        ),
        ("0.3 0.4", "expected 'start end phoneme'"),
        ("x 0.4 a", "expected 'start end phoneme'"),
        ("0.1 0.4 a", "phones must follow each other"),
        ("mark soon b1", "expected 'mark TIME NAME'"),
        ("# alphabet: klingon", "unknown alphabet 'klingon'"),
    ],
)
def test_table_errors_name_the_line(tmp_path, third, message):
    f = write_lines(tmp_path / "bad.txt", ["0 0.1 _", "0.1 0.2 h", third, "0.9 1.0 a"])
    with pytest.raises(SpeechError) as e:
        read_phoneme_file(f)
    assert e.value.line == 3 and e.value.file == str(f)
    assert message in e.value.message


def test_table_with_an_unknown_alphabet_symbol(tmp_path):
    f = write_lines(tmp_path / "p.txt", ["# alphabet: polly", "0 0.1 sil", "0.1 0.2 zz"])
    with pytest.raises(SpeechError, match="'zz' is not a symbol of the polly alphabet") as e:
        read_phoneme_file(f)
    assert e.value.line == 3


@pytest.mark.parametrize("content", ["", "# only a comment\n\n", "mark 0.1 b0\n"])
def test_files_without_phones(tmp_path, content):
    f = tmp_path / "empty.txt"
    f.write_text(content, encoding="utf-8")
    with pytest.raises(SpeechError, match="no phones"):
        read_phoneme_file(f)


def test_missing_file(tmp_path):
    with pytest.raises(SpeechError, match="cannot read the phoneme file"):
        read_phoneme_file(tmp_path / "nope.json")
