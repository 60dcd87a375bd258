"""Hostile and unusual values through the CLI and the renderer: non-finite and out-of-range
numbers are clear errors; scenes with nothing to see render an empty picture (issue 21)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import vtts
from vtts.errors import RenderError
from vtts.render import FaceRenderer
from vtts.render.camera import Camera

# in this process: these tests are about what a command says of a value; a command's process
# is the hostile fuzz and size tests' concern
from .in_process import vtts as vtts_cli

DATA = Path(__file__).parent / "data"
VTTS = Path(sys.executable).with_name("vtts")


def vtts_process(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """``vtts ARGS`` as a process of its own: for a command that might wait for ever."""
    return subprocess.run([str(VTTS), *args], capture_output=True, text=True, timeout=120, cwd=cwd)


SCENES = {
    "empty": "",
    "scale0": "Transform { scale 0 0 0 children Shape { geometry Box {} } }",
    "switch": "Switch { whichChoice 5 choice [ Shape { geometry Box {} } ] }",
}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_nothing_to_see_renders_an_empty_picture(tmp_path, name):
    path = tmp_path / f"{name}.wrl"
    path.write_text("#VRML V2.0 utf8\n" + SCENES[name] + "\n")
    model = vtts.load_model(path)
    with FaceRenderer(model, size=(64, 48), background=(0, 0, 1)) as r:
        frame = r.render(model.params())
    assert frame.shape == (48, 64, 3)
    assert (frame[..., 2] == 255).all() and (frame[..., :2] == 0).all()


@pytest.mark.parametrize("path", sorted((DATA / "vrml97" / "good").glob("*.wrl")), ids=str)
def test_every_good_conformance_file_renders(path):
    model = vtts.load_model(path)
    with FaceRenderer(model, size=(64, 48)) as r:
        assert r.render(model.params()).shape == (48, 64, 3)


def test_coordinates_too_large_to_frame(tmp_path):
    path = tmp_path / "huge.wrl"
    path.write_text(
        "#VRML V2.0 utf8\nShape { geometry IndexedFaceSet { coord Coordinate { point "
        "[0 0 0, 1e308 0 0, 0 1e308 0] } coordIndex [0 1 2 -1] } }\n"
    )
    with pytest.raises(RenderError, match="spans 1e\\+308 units"):
        FaceRenderer(vtts.load_model(path), size=(64, 48))


@pytest.mark.parametrize("fx", [1e308, float("inf"), 0.0, -5.0])
def test_camera_focal_lengths_are_bounded(fx):
    with pytest.raises(RenderError, match="camera fx"):
        Camera(fx, 100.0, 32, 24)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--fap", "48=inf"], "inf is not a finite number"),
        (["--fap", "3=1e32"], "must be within -1e+06–1e+06"),
        (["--viseme", "7=nan"], "nan is not a finite number"),
        (["--expression", "joy=5"], "must be within 0–1"),
        (["--viseme", "-1"], "unknown viseme '-1'"),
        (["--camera", "1e308,1e308,1,1"], "camera fx"),
    ],
)
def test_render_refuses_bad_numbers(tmp_path, args, message):
    out = tmp_path / "x.png"
    r = vtts_cli("render", "--model", "cybatt", *args, "-o", str(out))
    assert r.returncode == 1, r.stdout
    assert message in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()


def test_pose_refuses_nan_and_writes_nothing(tmp_path):
    out = tmp_path / "posed.wrl"
    r = vtts_cli("pose", "--model", "cybatt", "--fap", "3=nan", "-o", str(out))
    assert r.returncode == 1 and "not a finite number" in r.stderr
    assert not out.exists()


@pytest.mark.parametrize("seed", ["-1", "2e3", str(2**63)])
def test_say_seed_must_be_a_whole_non_negative_number(tmp_path, seed):
    r = vtts_cli("say", "hi", "--model", "cybatt", "--seed", seed, "-o", str(tmp_path / "x.mp4"))
    assert r.returncode == 2 and "--seed" in r.stderr and "Traceback" not in r.stderr


# ---- messages ------------------------------------------------------------------------------------


def test_control_characters_in_context_lines_are_escaped(tmp_path):
    path = tmp_path / "esc.wrl"
    path.write_bytes(b"#VRML V2.0 utf8\nShape { geometry Box { size 1 \x1b[31mRED 1 } }\n")
    r = vtts_cli("check", str(path))
    assert r.returncode == 1
    assert "\x1b" not in r.stderr and "\\x1b[31mRED" in r.stderr


def test_say_writes_videos_only(tmp_path):
    r = vtts_cli("say", "hi", "--model", "cybatt", "-o", str(tmp_path / "x.png"))
    assert r.returncode == 1 and "--png-dir" in r.stderr and "vtts render" in r.stderr
    assert not (tmp_path / "x.png").exists()


def test_fap_bookmark_without_a_value_says_so(tmp_path):
    text = tmp_path / "t.txt"
    text.write_text("hello <fap 3> there")
    r = vtts_cli("say", "--file", str(text), "--model", "cybatt", "-o", str(tmp_path / "x.mp4"))
    assert r.returncode == 1 and "<fap 3=VALUE>" in r.stderr


def test_an_empty_adt_is_not_ok(tmp_path):
    shutil.copy(Path(__file__).parents[1] / "models" / "cybatt.wrl", tmp_path / "e.wrl")
    (tmp_path / "e.adt").write_text("")
    r = vtts_cli("check", str(tmp_path / "e.adt"))
    assert r.returncode == 1 and "no tables in it" in r.stderr


def test_a_pipe_is_not_a_video(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    # a process of its own: a command that opened the pipe would wait for a writer for ever
    r = vtts_process("analyze", str(fifo), "--model", "cybatt", "-o", str(tmp_path / "v.fap"))
    assert r.returncode == 1 and "a pipe or a device" in r.stderr


def test_analyze_output_and_report_must_differ(tmp_path):
    same = tmp_path / "R"
    r = vtts_cli("analyze", str(DATA / "video" / "akiyo_cif.mp4"), "--model", "cybatt",
                 "-o", str(same), "--report", str(same))  # fmt: skip
    assert r.returncode == 1 and "name the same path" in r.stderr


def test_errors_name_the_output_not_its_temporary(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    out = folder / "x.png"
    long_name = tmp_path / ("a" * 248 + ".png")
    r = vtts_cli("render", "--model", "cybatt", "--size", "32x24", "-o", str(long_name))
    assert r.returncode == 0, r.stderr  # a long name does not fail on its temporary's length
    if os.geteuid() != 0:  # root writes anywhere
        folder.chmod(0o500)
        r = vtts_cli("render", "--model", "cybatt", "--size", "32x24", "-o", str(out))
        assert r.returncode == 1 and f"{out}: error" in r.stderr and ".part" not in r.stderr


def test_check_refuses_what_render_refuses_and_names_the_file(tmp_path):
    path = tmp_path / "oob.wrl"
    path.write_text(
        "#VRML V2.0 utf8\nShape { geometry IndexedFaceSet { coord Coordinate { point "
        "[0 0 0, 1 0 0, 0 1 0] } coordIndex [0 1 7 -1] } }\n"
    )
    for args in (["check", str(path)], ["render", "--model", str(path), "-o", "x.png"]):
        r = vtts_cli(*args, cwd=tmp_path)
        assert r.returncode == 1, r.stdout
        assert f"{path}:2:" in r.stderr and "out of range" in r.stderr


def test_a_missing_texture_is_a_warning(tmp_path):
    path = tmp_path / "notex.wrl"
    path.write_text(
        "#VRML V2.0 utf8\nShape { appearance Appearance { texture ImageTexture { url "
        '"nothere.png" } } geometry Box {} }\n'
    )
    for args in (["check", str(path)], ["render", "--model", str(path), "-o", "x.png"]):
        r = vtts_cli(*args, cwd=tmp_path)
        assert r.returncode == 0, r.stderr
        assert "texture 'nothere.png' not found" in r.stderr and f"{path}:2" in r.stderr
