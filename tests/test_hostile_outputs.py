"""Outputs never destroy inputs, links or devices, and SIGTERM cleans up as Ctrl-C (issue 21)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"
VTTS = Path(sys.executable).with_name("vtts")
MODELS = Path(__file__).parents[1] / "models"


def vtts_cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([str(VTTS), *args], capture_output=True, text=True, timeout=120, cwd=cwd)


@pytest.fixture
def model(tmp_path) -> Path:
    """A copy of cybatt (scene, tables, texture) in tmp_path."""
    for suffix in (".wrl", ".adt"):
        shutil.copy(MODELS / f"cybatt{suffix}", tmp_path / f"cybatt{suffix}")
    shutil.copy(MODELS / "cybatt-face.png", tmp_path / "cybatt-face.png")
    return tmp_path / "cybatt.wrl"


def unchanged(path: Path, before: bytes) -> bool:
    return path.read_bytes() == before


@pytest.mark.parametrize(
    "make_args, victim",
    [
        (lambda m: ["render", "--model", str(m), "-o", str(m.with_name("cybatt-face.png"))],
         "cybatt-face.png"),
        (lambda m: ["pose", "--model", str(m), "--fap", "3=100", "-o", str(m)], "cybatt.wrl"),
        (lambda m: ["pose", "--model", str(m), "-o", str(m.with_suffix(".adt"))], "cybatt.adt"),
    ],
)  # fmt: skip
def test_an_output_that_is_an_input_is_refused(model, make_args, victim):
    path = model.parent / victim
    before = path.read_bytes()
    r = vtts_cli(*make_args(model))
    assert r.returncode == 1, r.stdout
    assert "also an input" in r.stderr and "Traceback" not in r.stderr
    assert unchanged(path, before)


def test_encode_onto_its_input_is_refused(tmp_path):
    fap = tmp_path / "joy.fap"
    shutil.copy(DATA / "fap" / "xface-joy.fap", fap)
    before = fap.read_bytes()
    r = vtts_cli("encode", str(fap), "-o", str(fap))
    assert r.returncode == 1 and "also an input" in r.stderr
    assert unchanged(fap, before)


def test_analyze_onto_its_video_is_refused(tmp_path):
    video = tmp_path / "v.mp4"
    video.write_bytes(b"not really a video")
    r = vtts_cli("analyze", str(video), "--model", "cybatt", "-o", str(video))
    assert r.returncode == 1 and "also an input" in r.stderr
    assert video.read_bytes() == b"not really a video"


def test_two_outputs_naming_one_file_are_refused(tmp_path):
    out = tmp_path / "x"
    r = vtts_cli("say", "hi", "--model", "cybatt", "--fap-out", str(out), "--wav-out", str(out))
    assert r.returncode == 1 and "two outputs name the same file" in r.stderr
    assert not out.exists()


def test_an_output_link_or_device_is_refused(tmp_path):
    target = tmp_path / "precious.png"
    target.write_bytes(b"keep")
    link = tmp_path / "out.png"
    link.symlink_to(target)
    r = vtts_cli("render", "--model", "cybatt", "-o", str(link))
    assert r.returncode == 1 and "is a link" in r.stderr
    assert target.read_bytes() == b"keep" and link.is_symlink()
    r = vtts_cli("render", "--model", "cybatt", "-o", os.devnull)
    assert r.returncode == 1 and "not a regular file" in r.stderr


def test_a_failing_say_leaves_its_other_outputs_alone(tmp_path):
    fap, wav = tmp_path / "s.fap", tmp_path / "s.wav"
    fap.write_text("old fap")
    wav.write_text("old wav")
    frames = tmp_path / "frames"
    frames.mkdir()
    (frames / "keep.txt").write_text("not a frame")  # the frames cannot go there: the say fails
    r = vtts_cli("say", "hello", "--model", "cybatt", "--fap-out", str(fap), "--wav-out", str(wav),
                 "--png-dir", str(frames), "--quiet")  # fmt: skip
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert fap.read_text() == "old fap" and wav.read_text() == "old wav"


def test_sigterm_cleans_up_like_ctrl_c(tmp_path):
    text = "This is a long sentence that takes a while to say and longer to render. " * 6
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.Popen(
        [str(VTTS), "say", text, "--model", "cybatt", "-o", str(out / "talk.mp4"), "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )  # fmt: skip
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not list(out.glob(".*part*")):
        time.sleep(0.05)  # wait until the video is being written
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert list(out.iterdir()) == []
    assert not list(tmp_path.glob("vtts-say-*"))


def test_adi_build_never_rewrites_its_neutral_model(tmp_path):
    neutral = tmp_path / "n.wrl"
    shutil.copy(DATA / "models" / "head.wrl", neutral)
    before = neutral.read_bytes()
    adi = Path(sys.executable).with_name("adi")
    r = subprocess.run([str(adi), "build", str(neutral), str(neutral), "-o", str(neutral),
                        "--embed"], capture_output=True, text=True, timeout=120)  # fmt: skip
    assert r.returncode == 1 and "also an input" in r.stderr
    assert neutral.read_bytes() == before
