"""vtts say end to end with the real espeak-ng: marks on the right frame, closures, durations."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vtts.animate.timeline import LEAD, build_timeline
from vtts.face import load_model
from vtts.face.miap import EXPRESSION_BASE
from vtts.fap import read_fap
from vtts.render import probe_media
from vtts.utterance import prepare_utterance

from ..in_process import vtts

HEAD = Path(__file__).parents[1] / "data" / "models" / "head.wrl"
TEXT = "Hello <smile 1s> my name is Bob. <surprise 0.5s 0.7> Maybe <blink> we meet."


@pytest.fixture(scope="module")
def utterance():
    return prepare_utterance(TEXT)


def test_utterance_has_audio_phones_and_bookmark_times(utterance):
    u = utterance
    assert u.rate > 8000 and u.audio.size > u.rate  # more than a second of speech
    assert len(u.phones) > 20
    starts = [p.start for p in u.phones]
    assert starts == sorted(starts)
    times = [b.time for b in u.bookmarks]
    assert all(t is not None for t in times) and times == sorted(times)
    assert 0 < times[0] < times[1] < times[2] < u.duration
    assert any(p.viseme == 1 for p in u.phones)  # the m and b of "my name is Bob"


def test_expressions_start_on_their_marks_frame(utterance):
    model = load_model(HEAD)
    tl = build_timeline(
        model, utterance.phones, utterance.bookmarks, utterance.duration, autonomous=False
    )
    smile = utterance.bookmarks[0]
    w = tl.params[:, EXPRESSION_BASE + 1]
    first = int(np.flatnonzero(w > 0)[0])
    # the smile starts with "my", at its m (espeak-ng's own mark event is a phone earlier) …
    m = next(p for p in utterance.phones if p.start == smile.time)
    assert m.phoneme == "m"
    # … and the smile, which opens the mouth, waits for the lips to open (a lead before the m
    # ends: the mouth moves ahead of the sound)
    assert 0 <= first - (m.end - LEAD) * 30 <= 1.0
    # without the closure it starts on the mark's frame
    alone = build_timeline(model, [], utterance.bookmarks, utterance.duration, autonomous=False)
    first = int(np.flatnonzero(alone.params[:, EXPRESSION_BASE + 1] > 0)[0])
    assert 0 <= first - smile.time * 30 <= 1.0


def test_say_writes_mp4_wav_and_fap_with_matching_durations(tmp_path):
    out, wav, fap = tmp_path / "hello.mp4", tmp_path / "hello.wav", tmp_path / "hello.fap"
    r = vtts(
        "say",
        TEXT,
        "--model",
        str(HEAD),
        "-o",
        str(out),
        "--wav-out",
        str(wav),
        "--fap-out",
        str(fap),
        "--size",
        "176x144",
        "--quiet",
    )
    assert r.returncode == 0, r.stderr
    info = probe_media(out)
    assert info.duration_audio is not None
    assert abs(info.duration_video - info.duration_audio) <= 1 / 30 + 1e-6
    stream = read_fap(fap)
    assert abs(stream.n_frames - info.frames) <= 1
    assert probe_media(wav).duration_audio == pytest.approx(info.duration_audio, abs=1 / 30)
    assert "no table for <surprise>" in r.stderr  # the test head has only joy


def test_say_leaves_no_speech_files_behind(tmp_path):
    """The speech's WAV and its AAC track, encoded while the renderer is set up, are temporary:
    gone after a say that wrote its MP4 (with the whole utterance's sound) and after one whose
    renderer could not be set up once the speech was made."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    exe = str(Path(sys.executable).with_name("vtts"))
    env = {**os.environ, "TMPDIR": str(tmp)}

    def say(*args: str) -> subprocess.CompletedProcess:
        argv = [exe, "say", TEXT, "--model", str(HEAD), "--size", "176x144", "--quiet", *args]
        return subprocess.run(argv, capture_output=True, text=True, timeout=300, env=env)

    r = say("-o", str(tmp_path / "a.mp4"), "--wav-out", str(tmp_path / "a.wav"))
    assert r.returncode == 0, r.stderr
    sound = probe_media(tmp_path / "a.wav").duration_audio
    assert probe_media(tmp_path / "a.mp4").duration_audio == pytest.approx(sound, abs=0.03)
    r = say("-o", str(tmp_path / "b.mp4"), "--viewpoint", "NoSuchView")
    assert r.returncode == 1 and "NoSuchView" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "b.mp4").exists()
    assert sorted(p.name for p in tmp.iterdir()) == []


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["Hi <grin>"], "column 4: unknown bookmark <grin>"),
        (["Hi", "--voice", "xx-nope"], "xx-nope"),
        (["Hi", "--phonemes", "{tmp}/p.txt"], "--audio"),
        (["Hi"], "nothing to write"),
        (["", "-o", "{tmp}/x.mp4"], "nothing to say"),
        (["Hi", "--text", "there"], "give the text once: got the text twice"),
        (["--text", "Hi", "--file", "{tmp}/t.txt"], "give the text once: got --text and --file"),
        (["--text", "Hi <grin>"], "column 4: unknown bookmark <grin>"),
        (["Hi \x01 there"], "column 4: the control character '\\x01' cannot be spoken"),
        (["--file", "{tmp}/t.txt"], "{tmp}/t.txt:2:7: error: unknown bookmark <frown>"),
        (["--file", "{tmp}/t1.txt"], "{tmp}/t1.txt: error: column 4: unknown bookmark <grin>"),
    ],
)
def test_say_bad_input(tmp_path, args, fragment):
    (tmp_path / "p.txt").write_text("0 0.1 h\n")
    (tmp_path / "t.txt").write_text("Hello\nthere <frown> now\n")
    (tmp_path / "t1.txt").write_text("Hi <grin>")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in args]
    fragment = fragment.replace("{tmp}", str(tmp_path))
    if "-o" not in argv and fragment != "nothing to write":
        argv += ["-o", str(tmp_path / "x.mp4")]
    r = vtts("say", *argv, "--model", str(HEAD))
    assert r.returncode == 1
    assert fragment in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "x.mp4").exists()


def test_say_takes_the_text_as_an_option_too(tmp_path):
    """``--text TEXT`` is the positional text under a name (``say --audio REC --text ...``)."""
    r = vtts(
        "say", "--text", "Hi <joy>", "--model", str(HEAD), "--fap-out", str(tmp_path / "a.fap")
    )
    assert r.returncode == 0, r.stderr
    r = vtts("say", "Hi <joy>", "--model", str(HEAD), "--fap-out", str(tmp_path / "b.fap"))
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "a.fap").read_bytes() == (tmp_path / "b.fap").read_bytes()


def test_people_sad_full_stop_is_spoken_as_people_full_stop():
    """espeak-ng reads a full stop after a mark (``people <mark/>.``) as "dot"."""
    u, v = prepare_utterance("people <sad>."), prepare_utterance("people.")
    assert [p.phoneme for p in u.phones] == [p.phoneme for p in v.phones]
    assert "0" not in [p.phoneme for p in u.phones]  # the o of "dot"
    assert np.array_equal(u.audio, v.audio)
    (sad,) = u.bookmarks
    assert sad.time == pytest.approx(v.words[0].end)


@pytest.mark.parametrize(
    "text, plain",
    [
        ("people <sad> <blink> .", "people."),
        ("so <sad>. you came <joy>, then <blink>!", "so. you came, then!"),
        ("Why <surprise>? oh <fear>; so <joy>: yes", "Why? oh; so: yes"),
    ],
)
def test_bookmarks_before_punctuation_are_at_the_end_of_their_word(text, plain):
    u, v = prepare_utterance(text), prepare_utterance(plain)
    spoken = [p.phoneme for p in u.phones if p.viseme]
    assert spoken == [p.phoneme for p in v.phones if p.viseme] and "0" not in spoken
    # each bookmark at the end of the word before it, where espeak-ng puts a mark written before
    # the punctuation (whose pause comes after it); a second one in a row: the same time
    ends = [w.end for w in v.words]
    n = [sum(1 for w in text[: b.column - 1].split() if not w.startswith("<")) for b in u.bookmarks]
    assert [b.time for b in u.bookmarks] == pytest.approx([ends[k - 1] for k in n])
