"""--viewpoint and --background of vtts render, play and say."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from vtts.cli import main
from vtts.face import load_model
from vtts.render import FaceRenderer, viewpoint_fields

DATA = Path(__file__).parents[1] / "data"
HEAD = DATA / "models" / "head.wrl"
JOY = DATA / "fap" / "xface-joy.fap"


def _pixels(path: Path) -> tuple[str, np.ndarray]:
    with Image.open(path) as im:
        return im.mode, np.asarray(im)


def test_render_transparent_writes_an_rgba_png(tmp_path):
    args = ["render", "--model", str(HEAD), "--size", "160x120", "-o"]
    assert main([*args, str(tmp_path / "t.png"), "--background", "transparent"]) == 0
    assert main([*args, str(tmp_path / "w.png"), "--background", "white"]) == 0
    mode, rgba = _pixels(tmp_path / "t.png")
    _, white = _pixels(tmp_path / "w.png")
    assert mode == "RGBA" and rgba.shape == (120, 160, 4)
    assert white[0, 0].tolist() == [255, 255, 255]
    full, none = rgba[..., 3] == 255, rgba[..., 3] == 0
    assert full.any() and none.any()
    assert np.array_equal(rgba[full][:, :3], white[full])
    assert np.all(white[none] == 255)


def test_play_transparent_writes_rgba_frames(tmp_path):
    frames = tmp_path / "frames"
    args = ["play", str(JOY), "--model", str(HEAD), "--size", "64x48", "--fps", "5"]
    assert main([*args, "--background", "transparent", "--png-dir", str(frames), "--quiet"]) == 0
    first = sorted(frames.iterdir())[0]
    mode, rgba = _pixels(first)
    assert mode == "RGBA" and set(np.unique(rgba[..., 3])) == {0, 255}
    assert not (tmp_path / "x.mp4").exists()


def test_render_through_a_viewpoint_like_the_automatic_framing(tmp_path):
    with FaceRenderer(load_model(HEAD)) as r:
        eye = np.linalg.inv(r.model_matrix(0)) @ r.camera.pose[:, 3]
        fov = viewpoint_fields(r.camera, r.size)["fieldOfView"]
    position = " ".join(repr(float(v)) for v in eye[:3])
    wrl = tmp_path / "head.wrl"
    wrl.write_text(
        HEAD.read_text() + f"DEF AUTO Viewpoint {{ position {position} fieldOfView {fov!r} }}\n"
    )
    (tmp_path / "head.adt").write_bytes(HEAD.with_suffix(".adt").read_bytes())
    args = ["render", "--model", str(wrl), "--expression", "joy", "-o"]
    assert main([*args, str(tmp_path / "auto.png")]) == 0
    assert main([*args, str(tmp_path / "vp.png"), "--viewpoint", "AUTO"]) == 0
    assert np.array_equal(_pixels(tmp_path / "auto.png")[1], _pixels(tmp_path / "vp.png")[1])


def test_an_unknown_viewpoint_lists_the_scenes_viewpoints(tmp_path, capsys):
    wrl = tmp_path / "head.wrl"
    wrl.write_text(HEAD.read_text() + "DEF FRONT Viewpoint {}\nDEF SIDE Viewpoint {}\n")
    assert main(["render", "--model", str(wrl), "--viewpoint", "TOP", "-o", "x.png"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: no Viewpoint named 'TOP'")
    assert "its Viewpoints are FRONT, SIDE" in err
