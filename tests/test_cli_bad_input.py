"""Every command, given bad input, prints a clear error and exits non-zero — no traceback.

The message, the status and the files left are the command's: each case runs in this process
(``in_process.vtts``). That no traceback reaches the user is the process's: the first case of
each command runs through the installed console script as well."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from . import in_process

DATA = Path(__file__).parent / "data"
HEAD = str(DATA / "models" / "head.wrl")
JOY = str(DATA / "fap" / "xface-joy.fap")


def vtts(*args: str) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).with_name("vtts")
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=120)


CASES = [
    (["render", "--model", HEAD, "--fap", "99=1", "-o", "{tmp}/x.png"], "unknown FAP 99"),
    (["render", "--model", HEAD, "--size", "8x8", "-o", "{tmp}/x.png"], "image size"),
    (["render", "--model", "{tmp}/none.wrl", "-o", "{tmp}/x.png"], "no model"),
    (["render", "--model", HEAD, "-o", "{tmp}/file.txt/x.png"], "error:"),
    (["encode", "{tmp}/none.fap", "-o", "{tmp}/x.fbs"], "cannot read FAP file"),
    (["encode", JOY, "-o", "{tmp}/x.fbs", "--faps", "999"], "unknown FAP '999'"),
    (["decode", "{tmp}/none.fbs", "-o", "{tmp}/x.fap"], "cannot read FAP bitstream"),
    (["decode", "{tmp}/file.txt", "-o", "{tmp}/x.fap"], "byte 0"),
    (["voices", "zz"], "no voice for language 'zz'"),
    (["say", "--file", "{tmp}/none.txt", "--model", HEAD, "-o", "{tmp}/x.mp4"],
     "cannot read the text"),
    (["pose", "--model", HEAD, "--fap", "3=1", "-o", "{tmp}/file.txt/x.wrl"], "error:"),
    (["render", "--model", HEAD, "--background", "mauve", "-o", "{tmp}/x.png"],
     "not a background: 'mauve'; write a name (black, white"),
    (["render", "--model", HEAD, "--viewpoint", "TOP", "-o", "{tmp}/x.png"],
     "no Viewpoint named 'TOP' in the scene of head.wrl: it has no Viewpoint"),
    (["render", "--model", HEAD, "--viewpoint", "TOP", "--camera", "400,400,176,144", "-o",
      "{tmp}/x.png"], "--camera and --viewpoint both choose the camera"),
    (["play", JOY, "--model", HEAD, "--background", "transparent", "-o", "{tmp}/x.mp4",
      "--png-dir", "{tmp}/frames"], "an MP4 (H.264) has no alpha channel"),
    (["say", "Hi", "--model", HEAD, "--background", "transparent", "-o", "{tmp}/x.mp4"],
     "an MP4 (H.264) has no alpha channel"),
    (["render", "--model", HEAD, "--background", "photo", "-o", "{tmp}/x.png"],
     "records none"),
    (["serve", "--port", "99999"], "--port must be within 0 to 65535, got 99999"),
    (["serve", "--model", "{tmp}/none.wrl", "--port", "0"], "no model"),
    (["serve", "--engine", "bogus", "--port", "0"], "--engine must be one of espeak"),
    (["serve", "--fps", "0", "--port", "0"], "--fps must be within"),
    (["serve", "--replicas", "0", "--port", "8080"], "--replicas must be within 0–256, got 0"),
    (["serve", "--ray-address", "127.0.0.1:1"], "--ray-address goes with --replicas N"),
    (["serve", "--replicas", "2", "--model", "{tmp}/none.wrl"], "no model"),
    (["serve", "--replicas", "2", "--ray-address", "nowhere"],
     "--ray-address is HOST:PORT, ray://HOST:PORT or auto, got 'nowhere'"),
    (["serve", "--replicas", "2", "--port", "0"], "--port must be within 1 to 65535 on Ray Serve"),
]  # fmt: skip
#: The first case of each command.
FIRST = [case for i, case in enumerate(CASES) if case[0][0] not in {a[0] for a, _ in CASES[:i]}]


def check(r: subprocess.CompletedProcess, fragment: str, tmp_path: Path) -> None:
    assert r.returncode != 0
    assert fragment in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt"]


def arguments(args: list[str], tmp_path: Path) -> list[str]:
    (tmp_path / "file.txt").write_text("not a bitstream")
    return [a.replace("{tmp}", str(tmp_path)) for a in args]


@pytest.mark.parametrize("args, fragment", CASES)
def test_bad_input_is_a_clear_error(tmp_path, args, fragment):
    check(in_process.vtts(*arguments(args, tmp_path), cwd=tmp_path), fragment, tmp_path)


@pytest.mark.parametrize("args, fragment", FIRST, ids=[a[0] for a, _ in FIRST])
def test_bad_input_never_shows_a_traceback(tmp_path, args, fragment):
    check(vtts(*arguments(args, tmp_path)), fragment, tmp_path)
