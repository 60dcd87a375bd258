"""vtts render and vtts play end to end: files, durations, audio, and bad input."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from vtts.fap import read_fap
from vtts.render import probe_media, write_wav

from ..in_process import vtts

DATA = Path(__file__).parents[1] / "data"
HEAD = DATA / "models" / "head.wrl"
JOY = DATA / "fap" / "xface-joy.fap"


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


def _tone(path: Path, rate: int, channels: int, seconds: float = 1.5) -> Path:
    """A 440 Hz tone (on the first channel) written by soundfile, or by ffmpeg for ``.mp3``."""
    import soundfile as sf

    from vtts.media import ffmpeg_exe

    t = np.arange(int(rate * seconds)) / rate
    x = np.zeros((t.size, channels), np.float32)
    x[:, 0] = 0.4 * np.sin(2 * np.pi * 440 * t)
    if path.suffix != ".mp3":
        sf.write(path, x, rate)
        return path
    wav = path.with_suffix(".src.wav")
    sf.write(wav, x, rate)
    cmd = [ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y", "-i", str(wav)]
    subprocess.run([*cmd, "-c:a", "libmp3lame", str(path)], check=True, timeout=60)
    return path


@pytest.mark.parametrize(
    ("name", "rate", "channels", "muxed_rate"),
    [
        ("speech.mp3", 44100, 1, 44100),  # not a WAV: read as say reads it
        ("speech.flac", 20000, 2, 22050),  # stereo at a rate AAC does not take: as say muxes it
    ],
)
def test_play_audio_takes_what_say_takes(tmp_path, capsys, name, rate, channels, muxed_rate):
    from vtts.cli import main

    audio = _tone(tmp_path / name, rate, channels)
    out = tmp_path / "joy.mp4"
    args = ["play", str(JOY), "--model", str(HEAD), "--audio", str(audio), "-o", str(out)]
    assert main([*args, "--size", "96x80", "--fps", "10", "--quiet"]) == 0
    info = probe_media(out)
    assert info.audio_rate == muxed_rate and info.audio_channels == 1
    assert info.duration_audio == pytest.approx(1.5, abs=0.06)
    assert abs(info.frames - round(read_fap(JOY).duration * 10)) <= 1


def test_play_audio_that_is_no_audio_names_the_file(tmp_path, capsys):
    from vtts.cli import main

    text = tmp_path / "notes.mp3"
    text.write_text("not a sound\n")
    out = tmp_path / "joy.mp4"
    args = ["play", str(JOY), "--model", str(HEAD), "--audio", str(text), "-o", str(out)]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert f"{text}: error: not an audio file" in err and "Traceback" not in err
    assert not out.exists()
