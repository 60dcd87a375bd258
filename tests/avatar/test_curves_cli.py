"""``--curves-out FILE --curves FORMAT`` of ``vtts say`` and ``vtts play``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from vtts.avatar import ARKIT_NAMES, OCULUS_VISEMES
from vtts.cli import main

XFACE = Path(__file__).resolve().parents[1] / "data" / "fap" / "xface-joy.fap"


@pytest.fixture(scope="module")
def said(tmp_path_factory) -> dict[str, object]:
    """One short say per format, plus its FAP stream."""
    tmp = tmp_path_factory.mktemp("said")
    out: dict[str, object] = {}
    for fmt in ("arkit", "oculus", "azure", "talkinghead"):
        path = tmp / f"{fmt}.json"
        args = ["say", "Bob is up.", "--model", "cybatt", "--curves-out", str(path), "--quiet"]
        if fmt != "arkit":  # arkit is the default
            args += ["--curves", fmt]
        if fmt == "oculus":
            args += ["--fap-out", str(tmp / "said.fap")]
        if fmt == "talkinghead":
            args += ["--timings-out", str(tmp / "said.tsv")]
        assert main(args) == 0
        out[fmt] = json.loads(path.read_text())
    out["fap"] = tmp / "said.fap"
    out["timings"] = (tmp / "said.tsv").read_text()
    return out


def test_say_arkit(said):
    a = said["arkit"]
    assert a["names"] == list(ARKIT_NAMES) and a["fps"] == 30.0
    frames = a["frames"]
    assert len(frames) > 20 and all(len(f) == 52 for f in frames)
    col = {n: [f[i] for f in frames] for i, n in enumerate(ARKIT_NAMES)}
    assert max(col["jawOpen"]) > 0.3  # the vowels open the jaw
    assert max(col["mouthClose"]) > 0.1 and max(col["mouthPressLeft"]) > 0.4  # b, p
    assert all(0 <= w <= 1 for f in frames for w in f)
    head = a["head_rotation"]  # the autonomous head motion, in radians
    assert len(head) == len(frames) and 0 < max(abs(x) for h in head for x in h) < 0.3


def test_say_oculus(said):
    o = said["oculus"]
    assert o["names"] == list(OCULUS_VISEMES)
    pp = [f[1] for f in o["frames"]]
    assert max(pp) == pytest.approx(1.0, abs=1e-3)  # the lips shut fully for b and p
    assert o["frames"][-1][0] > 0.9  # silence at the end


def test_say_events(said):
    az = said["azure"]
    ids = [e["viseme_id"] for e in az]
    assert ids[0] == 0 and ids[-1] == 0 and 21 in ids
    times = [e["audio_offset_ms"] for e in az]
    assert times == sorted(times)
    th = said["talkinghead"]
    assert th["visemes"][0] == "sil" and "PP" in th["visemes"]
    assert len(th["visemes"]) == len(th["vtimes"]) == len(th["vdurations"])
    # the events of both formats start at the phones' times
    assert set(th["vtimes"]) >= {t for t in times}


def test_say_talkinghead_words(said):
    """TalkingHead's word track is the utterance's words, as --timings-out writes them."""
    th = said["talkinghead"]
    assert th["words"] == ["Bob", "is", "up"]
    rows = [line.split("\t") for line in said["timings"].splitlines()[1:]]
    words = [(float(r[1]), float(r[2])) for r in rows if r[0] == "word"]
    assert th["wtimes"] == pytest.approx([1000 * s for s, _ in words], abs=0.11)
    assert th["wdurations"] == pytest.approx([1000 * (e - s) for s, e in words], abs=0.21)
    assert th["wtimes"] == sorted(th["wtimes"]) and all(d > 0 for d in th["wdurations"])
    # each word starts with a phone of its own, so with a viseme event
    assert set(th["wtimes"]) <= set(th["vtimes"])


def test_play_curves_from_a_stream(said, tmp_path, capsys):
    """play's curves come from the stream: the visemes of a said stream come back from FAP 1."""
    out = tmp_path / "th.json"
    args = ["play", str(said["fap"]), "--model", "cybatt", "--curves-out", str(out)]
    assert main([*args, "--curves", "talkinghead"]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    th = json.loads(out.read_text())
    assert "PP" in th["visemes"] and th["vtimes"][0] == 0.0
    assert "words" not in th and "wtimes" not in th  # a stream has no words
    out = tmp_path / "joy.json"
    assert main(["play", str(XFACE), "--model", "lotta", "--curves-out", str(out), "--quiet"]) == 0
    frames = json.loads(out.read_text())["frames"]
    smile = [f[ARKIT_NAMES.index("mouthSmileLeft")] for f in frames]
    assert max(smile) > 0.2  # Xface's joy raises the lip corners


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--curves-out", "c.json", "--curves", "bvh"],
         "unknown curves format 'bvh': expected one of arkit, oculus, azure, talkinghead"),
        (["--curves", "oculus", "--fap-out", "x.fap"], "--curves FORMAT says how to write"),
        (["--curves-out", "x.fap", "--fap-out", "x.fap"], "two outputs name the same file"),
    ],
)  # fmt: skip
def test_say_errors(tmp_path, monkeypatch, capsys, extra, message):
    monkeypatch.chdir(tmp_path)
    assert main(["say", "Hi", "--model", "cybatt", *extra]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_play_curves_onto_the_stream_is_refused(tmp_path, capsys):
    stream = tmp_path / "s.fap"
    stream.write_bytes(XFACE.read_bytes())
    assert main(["play", str(stream), "--model", "cybatt", "--curves-out", str(stream)]) == 1
    assert "also an input" in capsys.readouterr().err
    assert stream.read_bytes() == XFACE.read_bytes()


def test_a_failing_say_leaves_the_curves_alone(tmp_path, capsys):
    curves = tmp_path / "c.json"
    curves.write_text("old")
    frames = tmp_path / "frames"
    frames.mkdir()
    (frames / "keep.txt").write_text("not a frame")  # the frames cannot go there: say fails
    args = ["say", "Hi", "--model", "cybatt", "--curves-out", str(curves), "--png-dir",
            str(frames), "--size", "160x120", "--quiet"]  # fmt: skip
    assert main(args) == 1
    assert curves.read_text() == "old"
