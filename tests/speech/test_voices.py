"""``vtts voices``: every installed engine's voices with language, sample rate and licence; the
engine interface of espeak-ng (festival's voice is listed from its folder, without running it)."""

from __future__ import annotations

import numpy as np

from vtts.speech.bookmarks import parse_bookmarks
from vtts.speech.engine import installed_voices, load_engine

from ..in_process import vtts


def _rows(stdout: str) -> dict[tuple[str, str], list[str]]:
    lines = stdout.splitlines()
    assert lines[0].split()[:5] == ["engine", "voice", "language", "rate", "licence"]
    return {(r.split()[0], r.split()[1]): r.split() for r in lines[1:]}


def test_voices_lists_every_engine_with_rate_and_licence():
    r = vtts("voices", "en")
    assert r.returncode == 0, r.stderr
    rows = _rows(r.stdout)
    espeak = rows[("espeak", "en-us")]
    assert espeak[2:6] == ["en-us", "22050", "Hz", "GPL-3.0-or-later"]
    festival = rows[("festival", "cmu_us_slt_arctic_hts")]  # the test bench installs it
    assert festival[2:5] == ["en-us", "32000", "Hz"] and "BSD-3-Clause" in festival[5]
    assert all(k[0] != "espeak" or v[2].startswith("en") for k, v in rows.items())
    everything = _rows(vtts("voices").stdout)
    assert ("espeak", "fr-fr") in everything and ("espeak", "fr-fr") not in rows


def test_voices_of_one_engine_and_of_no_language():
    r = vtts("voices", "--engine", "festival")
    assert r.returncode == 0 and {k[0] for k in _rows(r.stdout)} == {"festival"}
    r = vtts("voices", "zz")
    assert r.returncode == 1 and "no voice for language 'zz'" in r.stderr
    assert "Traceback" not in r.stderr
    found, missing = installed_voices(["espeak"])
    assert not missing and all(v.engine == "espeak" and v.rate == 22050 for v in found)


def test_espeak_gives_its_speech_whole_as_one_sentence():
    engine = load_engine("espeak")
    bt = parse_bookmarks("One. Two <smile> three.")
    whole = engine.speak(bt)
    (piece,) = list(engine.sentences(bt))
    assert np.array_equal(piece.speech.audio, whole.speech.audio)
    assert piece.bookmarks == whole.bookmarks and len(whole.bookmarks) == 1
