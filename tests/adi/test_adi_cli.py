"""The ``adi`` command: build and show, error output without tracebacks."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from adt_tools.cli import main

from .adi_helpers import TABLES, export_pose


def adi(*args: str) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).with_name("adi")
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=60)


def test_console_script_builds_and_reports(neutral_wrl, phase_files, tmp_path):
    out = tmp_path / "m.adt"
    r = adi("build", str(neutral_wrl), *map(str, phase_files), "-o", str(out))
    assert r.returncode == 0, r.stderr
    assert r.stdout == f"wrote {out}: 6 MIAPs, 2 nodes\n"
    assert out.read_text().startswith("#AnimationDefinitionTables\n")


@pytest.mark.parametrize("case", ["unknown-miap", "missing-file", "bad-adt", "bad-gltf", "no-args"])
def test_console_script_bad_input_has_no_traceback(model, neutral_wrl, tmp_path, case):
    out = tmp_path / "m.adt"
    if case == "unknown-miap":
        bad = export_pose(model, "joy", 1, tmp_path / "frown@1.wrl")
        r = adi("build", str(neutral_wrl), str(bad), "-o", str(out))
        want = f"{bad}: error: unknown MIAP 'frown' in file name frown@1.wrl"
    elif case == "missing-file":
        r = adi("build", str(neutral_wrl), str(tmp_path / "joy@1.wrl"), "-o", str(out))
        want = f"{tmp_path / 'joy@1.wrl'}: error: no such file"
    elif case == "bad-adt":
        (tmp_path / "x.adt").write_text("#AnimationDefinitionTables\nMIAP 99\n")
        r = adi("show", str(tmp_path / "x.adt"))
        want = f"{tmp_path / 'x.adt'}:2:"
    elif case == "bad-gltf":
        (tmp_path / "joy.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage")
        r = adi("build", str(neutral_wrl), str(tmp_path / "joy.glb"), "-o", str(out))
        want = f"{tmp_path / 'joy.glb'}: error: not a readable glTF file"
    else:
        r = adi("build")
        want = "usage: adi build"
    assert r.returncode in (1, 2)
    assert "Traceback" not in r.stderr
    assert r.stderr.startswith(want), r.stderr
    assert not out.exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (["-o", "x.wrl"], "the output is a .adt file; pass --embed"),
        (["-o", "x.txt"], "the output is a .adt file"),
        (["-o", "x.adt", "--embed"], "--embed writes a .wrl"),
        (["-o", "x.adt", "--tolerance", "-1"], "--tolerance must not be negative"),
    ],
)
def test_build_output_rules(neutral_wrl, phase_files, tmp_path, capsys, args, message):
    args = [a if not a.startswith("x.") else str(tmp_path / a) for a in args]
    assert main(["build", str(neutral_wrl), str(phase_files[0]), *args]) == 1
    assert message in capsys.readouterr().err


def test_embed_warns_about_a_sidecar_beside_the_output(neutral_wrl, phase_files, tmp_path, capsys):
    (tmp_path / "m.adt").write_text("#AnimationDefinitionTables\n")
    assert main(["build", str(neutral_wrl), *map(str, phase_files), "-o",
                 str(tmp_path / "m.wrl"), "--embed"]) == 0  # fmt: skip
    assert "warning: m.adt lies beside it" in capsys.readouterr().err


def test_zero_motion_warns(model, neutral_wrl, tmp_path, capsys):
    same = export_pose(model, "open_jaw", 0, tmp_path / "open_jaw@100.wrl")
    assert main(["build", str(neutral_wrl), str(same), "-o", str(tmp_path / "m.adt")]) == 0
    err = capsys.readouterr()
    assert "warning: MIAP 3 (open_jaw): its poses move nothing" in err.err
    assert "0 MIAPs, 0 nodes" in err.out


# ---- show ----------------------------------------------------------------------------------------

SHOWN = """\
{path}: 6 MIAPs (4 FAPs, 1 viseme, 1 expression); 1 IndexedFaceSet (FACE_MESH), 1 Transform (HEAD)
MIAP 6 (stretch_l_cornerlip)
  IndexedFaceSet FACE_MESH: 2{of} vertices, 2 intervals, borders -1000 0 1000
MIAP 19 (close_t_l_eyelid)
  IndexedFaceSet FACE_MESH: 3{of} vertices, 2 intervals, borders 0 512 1024
MIAP 48 (head_pitch)
  Transform HEAD: rotation about 1 0 0 from 0 rad, 1e-05 rad per unit
MIAP 49 (head_yaw)
  Transform HEAD: rotation about 0 1 0 from 0 rad, 1e-05 rad per unit
MIAP viseme 3 (T, D)
  IndexedFaceSet FACE_MESH: 2{of} vertices, 1 interval, borders 0 1
MIAP expression 1 (joy)
  IndexedFaceSet FACE_MESH: 2{of} vertices, 2 intervals, borders 0 0.5 1
  Transform HEAD: translation from 0 0 0, 0 0.05 0 per unit
"""


def test_show_adt(tmp_path, capsys):
    path = tmp_path / "head.adt"
    path.write_text(TABLES)
    assert main(["show", str(path)]) == 0
    assert capsys.readouterr().out == SHOWN.format(path=path, of="")


def test_show_model_wrl_with_sidecar(model_dir, capsys):
    path = model_dir / "head.wrl"
    assert main(["show", str(path)]) == 0
    assert capsys.readouterr().out == SHOWN.format(path=path, of=" of 113")


def test_show_embedded_tables_with_temporal_tables_and_feature_points(
    neutral_wrl, phase_files, tmp_path, capsys
):
    # a neutral with embedded temporal tables and feature points keeps them through adi build
    text = neutral_wrl.read_text() + (
        'WorldInfo { title "vtts:TemporalDefinitionTables" info [ "expression joy: onset 0.5 '
        'offset 0.8 shape smooth climax 1 duration 2" "blink: interval 4 jitter 1.5 duration 0.2 '
        'amplitude 1024" ] }\n'
        'WorldInfo { title "vtts:FeaturePoints" info [ "3.5 FACE_MESH 12" ] }\n'
    )
    neutral = tmp_path / "neutral.wrl"
    neutral.write_text(text)
    out = tmp_path / "model.wrl"
    assert main(["build", str(neutral), *map(str, phase_files), "-o", str(out), "--embed"]) == 0
    capsys.readouterr()
    assert main(["show", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == (
        f"{out}: 6 MIAPs (4 FAPs, 1 viseme, 1 expression); 1 IndexedFaceSet "
        "(FACE_MESH), 1 Transform (HEAD)"
    )
    assert lines[-5:] == [
        "temporal tables:",
        "  expression joy: onset 0.5 offset 0.8 shape smooth climax 1 duration 2",
        "  blink: interval 4 jitter 1.5 duration 0.2 amplitude 1024",
        "feature points (1):",
        "  3.5 FACE_MESH 12",
    ]


def test_show_plain_scene_and_unknown_types(neutral_wrl, tmp_path, capsys):
    assert main(["show", str(neutral_wrl)]) == 0
    assert capsys.readouterr().out.strip() == (
        f"{neutral_wrl}: no animation tables (neither FaceDefTables nor a sidecar .adt)"
    )
    assert main(["show", str(tmp_path / "x.obj")]) == 1
    assert "unknown file type '.obj'" in capsys.readouterr().err
    assert main(["show", str(tmp_path / "none.wrl")]) == 1
    assert capsys.readouterr().err == f"{tmp_path / 'none.wrl'}: error: no such file\n"
