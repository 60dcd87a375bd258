"""The model commands: vtts pose, vtts info MODEL, vtts check for .adt and models."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vtts.cli import main
from vtts.face import load_model
from vtts.vrml import read

from ..in_process import vtts


def test_pose_writes_plain_posed_vrml(model_dir: Path, capsys):
    out = model_dir / "posed.wrl"
    rc = main(["pose", "--model", str(model_dir / "head.wrl"), "--fap", "6=500,head_pitch=20000",
               "--viseme", "1", "--expression", "joy=0.5", "-o", str(out)])  # fmt: skip
    assert rc == 0 and capsys.readouterr().out.strip() == f"wrote {out}"
    posed = read(out)
    assert not posed.find("FaceDefTables")
    model = load_model(model_dir / "head.wrl")
    want = model.deform({6: 500, 48: 20000}, visemes={1: 1}, expressions={"joy": 0.5})
    assert np.allclose(posed.node("FACE_MESH")["coord"]["point"], want.points["FACE_MESH"])
    assert np.allclose(posed.node("HEAD")["rotation"], [1, 0, 0, 0.2])


def test_pose_warns_about_miaps_without_tables(model_dir: Path, capsys):
    rc = main(["pose", "--model", str(model_dir / "head.wrl"), "--fap", "3=100",
               "-o", str(model_dir / "p.wrl")])  # fmt: skip
    assert rc == 0
    assert "has no table for 3; ignored" in capsys.readouterr().err


def test_pose_bad_input_is_a_clear_error(model_dir: Path):
    cases = [
        (["--fap", "6=abc"], "error: FAP '6': 'abc' is not a number"),
        (["--fap", "nope=1"], "unknown FAP 'nope'"),
        (["--fap", "6"], "FAP '6' needs a value"),
        (["--expression", "glee=1"], "glee"),
        (["--viseme", "99"], "viseme"),
    ]
    for extra, fragment in cases:
        r = vtts(
            "pose", "--model", str(model_dir / "head.wrl"), *extra, "-o", str(model_dir / "x.wrl")
        )
        assert r.returncode == 1, extra
        assert fragment in r.stderr, (extra, r.stderr)
        assert "Traceback" not in r.stderr
        assert not (model_dir / "x.wrl").exists()
    r = vtts("pose", "--model", "no-such-model", "--fap", "3=1", "-o", str(model_dir / "x.wrl"))
    assert r.returncode == 1 and "no model 'no-such-model'" in r.stderr


def test_info_lists_what_the_model_can_do(model_dir: Path, capsys):
    assert main(["info", str(model_dir / "head.wrl")]) == 0
    out = capsys.readouterr().out
    assert "MIAPs: 5 (3 low-level FAPs, 1 visemes, 1 expressions)" in out
    assert "6 stretch_l_cornerlip, 19 close_t_l_eyelid, 48 head_pitch" in out
    assert "joy: 0.5/2/0.8 smooth, climax 1" in out
    assert "blink: 4 ± 1.5, 0.2, 1024" in out


def test_check_models_and_adt_files(model_dir: Path, capsys):
    assert main(["check", str(model_dir / "head.wrl"), str(model_dir / "head.adt")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].endswith("(7 nodes, 184 triangles, 5 MIAPs)")
    assert out[1].endswith("(5 MIAPs on 2 nodes of head.wrl)")
    lonely = model_dir / "lonely.adt"
    lonely.write_text((model_dir / "head.adt").read_text())
    bad = model_dir / "head.adt"
    bad.write_text(bad.read_text().replace("vertex 52 ", "vertex 700 "))
    assert main(["check", str(lonely), str(bad)]) == 1
    err = capsys.readouterr().err
    assert "no lonely.wrl beside it" in err
    assert f"{bad}: error: MIAP expression 1 (joy): vertex 700 is out of range" in err
