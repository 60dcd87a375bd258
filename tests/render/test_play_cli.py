"""vtts render and vtts play end to end: files, durations, audio, and bad input."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vtts.fap import read_fap
from vtts.render import probe_media, write_wav

DATA = Path(__file__).parents[1] / "data"
HEAD = DATA / "models" / "head.wrl"
JOY = DATA / "fap" / "xface-joy.fap"


def vtts(*args: str) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).with_name("vtts")
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=300)


def test_render_writes_a_png(tmp_path):
    from PIL import Image

    out = tmp_path / "still.png"
    r = vtts(
        "render",
        "--model",
        str(HEAD),
        "--fap",
        "48=20000",
        "--expression",
        "joy=0.8",
        "--size",
        "160x120",
        "-o",
        str(out),
    )
    assert r.returncode == 0, r.stderr
    assert Image.open(out).size == (160, 120)


def test_play_mp4_has_the_streams_duration_and_the_wavs_audio(tmp_path):
    stream = read_fap(JOY)
    wav = tmp_path / "speech.wav"
    rate = 16000
    t = np.arange(int(rate * 3.0)) / rate
    write_wav(wav, (0.2 * np.sin(2 * np.pi * 220 * t)).astype(np.float32), rate)
    out = tmp_path / "joy.mp4"
    pngs = tmp_path / "frames"
    r = vtts(
        "play",
        str(JOY),
        "--model",
        str(HEAD),
        "--audio",
        str(wav),
        "-o",
        str(out),
        "--png-dir",
        str(pngs),
        "--size",
        "176x144",
        "--fps",
        "30",
        "--quiet",
    )
    assert r.returncode == 0, r.stderr
    info = probe_media(out)
    want_frames = round(stream.duration * 30)
    assert abs(info.frames - want_frames) <= 1
    assert abs(info.duration_video - stream.duration) <= 1 / 30 + 1e-6
    assert info.duration_audio == pytest.approx(3.0, abs=0.06)
    assert (info.width, info.height) == (176, 144)
    assert len(list(pngs.glob("*.png"))) == info.frames
    assert "has no tables for" in r.stderr  # the test head shows only a few FAPs: one warning
    assert r.stderr.count("warning:") == 1


def test_play_two_models_side_by_side(tmp_path):
    out = tmp_path / "two.mp4"
    r = vtts(
        "play",
        str(JOY),
        "--model",
        str(HEAD),
        "--model",
        str(HEAD),
        "--fps",
        "10",
        "--size",
        "160x96",
        "-o",
        str(out),
        "--quiet",
    )
    assert r.returncode == 0, r.stderr
    assert probe_media(out).width == 160


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["nope.fap", "--model", str(HEAD), "-o", "{tmp}/x.mp4"], "nope.fap"),
        ([str(JOY), "--model", "no-such-head", "-o", "{tmp}/x.mp4"], "no model 'no-such-head'"),
        ([str(JOY), "--model", str(HEAD)], "nothing to write"),
        ([str(JOY), "--model", str(HEAD), "--fps", "0", "-o", "{tmp}/x.mp4"], "--fps must be"),
        ([str(JOY), "--model", str(HEAD), "--size", "big", "-o", "{tmp}/x.mp4"], "--size takes"),
        ([str(JOY), "--model", str(HEAD), "--camera", "1,2", "-o", "{tmp}/x.mp4"], "four numbers"),
        (
            [str(JOY), "--model", str(HEAD), "--audio", "{tmp}/none.wav", "-o", "{tmp}/x.mp4"],
            "none.wav",
        ),
        (["{tmp}/bad.fap", "--model", str(HEAD), "-o", "{tmp}/x.mp4"], "bad.fap:1"),
    ],
)
def test_play_bad_input_is_a_clear_error_and_leaves_nothing(tmp_path, args, fragment):
    (tmp_path / "bad.fap").write_text("3.7 x 25 1\n")
    r = vtts("play", *(a.replace("{tmp}", str(tmp_path)) for a in args))
    assert r.returncode != 0
    assert fragment in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "x.mp4").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.fap"]


def test_play_and_check_accept_coded_streams(tmp_path):
    fbs = tmp_path / "joy.fbs"
    assert vtts("encode", str(JOY), "-o", str(fbs), "--quiet").returncode == 0
    r = vtts("check", str(fbs))
    assert r.returncode == 0 and r.stdout.startswith(f"OK {fbs} (108 frames at 25 Hz")
    out = tmp_path / "joy.mp4"
    r = vtts("play", str(fbs), "--model", str(HEAD), "--size", "96x80", "-o", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    assert abs(probe_media(out).frames - round(read_fap(JOY).duration * 30)) <= 1
    bad = tmp_path / "bad.fbs"
    bad.write_bytes(fbs.read_bytes()[:40])
    r = vtts("check", str(bad))
    assert r.returncode == 1 and f"{bad}: error: byte " in r.stderr and "Traceback" not in r.stderr
