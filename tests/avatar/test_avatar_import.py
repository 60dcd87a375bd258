"""The round trip of ``adi import``: cybatt exported as an ARKit-blendshape avatar
(vtts.export.avatar), checked by the Khronos glTF-Validator, imported, accepted by ``vtts check``,
``adi show`` and ``vtts info``, its FAPUs measured on the mesh, its eyes turning, and ``vtts say``
on the import within a PSNR bound of ``vtts say`` on cybatt itself."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pygltflib
import pytest
from PIL import Image

from adt_tools.cli import main as adi
from vtts.avatar.arkit import ARKIT_NAMES, OCULUS_VISEMES
from vtts.cli import main as vtts
from vtts.export.avatar import write_arkit_avatar
from vtts.face import Miap, load_model
from vtts.vrml import rotation_matrix

from ..export.gltf_helpers import problems, validate

#: The least PSNR of any frame of `vtts say` on the import against cybatt (measured: 45.1 dB at
#: 160x120; identical frames where the face is at rest).
MIN_PSNR_DB = 35.0
TEXT = "Hello, nice to meet you"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("avatar")
    glb = write_arkit_avatar(folder / "cybatt-arkit.glb", load_model("cybatt"))
    wrl = folder / "imported.wrl"
    assert adi(["import", str(glb), "-o", str(wrl)]) == 0
    return glb, wrl


def test_the_exported_avatar_is_valid_gltf(files):
    glb, _ = files
    report = validate(glb)
    assert problems(report) == []
    assert report["issues"]["numErrors"] == 0 and report["info"]["hasMorphTargets"]


def test_the_exported_targets_carry_arkit_and_oculus_names(files):
    glb, _ = files
    doc = pygltflib.GLTF2.load(str(glb))
    face = next(m for m in doc.meshes if m.name == "FACE")
    names = face.extras["targetNames"]
    assert set(names) <= set(ARKIT_NAMES) | set(OCULUS_VISEMES)
    assert {"jawOpen", "eyeBlinkLeft", "mouthSmileRight", "viseme_PP", "viseme_aa"} <= set(names)
    assert len(face.primitives[0].targets) == len(names)
    assert {m.name for m in doc.meshes} >= {"L_EYEBALL", "R_EYEBALL"}


def test_vtts_and_adi_accept_the_import(files, capsys):
    _, wrl = files
    assert {p.name for p in wrl.parent.iterdir()} >= {"imported.wrl", "imported.adt",
                                                       "imported-tex0.png"}  # fmt: skip
    assert vtts(["check", str(wrl), str(wrl.with_suffix(".adt"))]) == 0
    assert adi(["show", str(wrl)]) == 0
    assert vtts(["info", str(wrl)]) == 0
    out = capsys.readouterr().out
    assert f"OK {wrl}" in out and "70 MIAPs" in out


def test_other_commands_take_the_import(files, tmp_path):
    """render, pose, play (a real FAP file) and the glTF export run on the import as on any
    head."""
    _, wrl = files
    m = str(wrl)
    assert vtts(["render", "--model", m, "--expression", "joy", "--viseme", "10", "--size",
                 "96x80", "-o", str(tmp_path / "still.png")]) == 0  # fmt: skip
    assert vtts(["pose", "--model", m, "--fap", "3=500,23=20000", "-o",
                 str(tmp_path / "posed.wrl")]) == 0  # fmt: skip
    fap = Path(__file__).parents[1] / "data" / "fap" / "xface-happy-for.fap"
    assert vtts(["play", str(fap), "--model", m, "--size", "64x48", "-o",
                 str(tmp_path / "play.glb")]) == 0  # fmt: skip
    assert (tmp_path / "still.png").stat().st_size > 0 and (tmp_path / "play.glb").is_file()


def test_the_import_has_tables_for_faps_visemes_and_expressions(files):
    model = load_model(files[1])
    kinds = [m.kind for m in model.miaps]
    assert kinds.count("viseme") == 14 and kinds.count("expression") == 6
    assert kinds.count("fap") >= 40
    # the lids close as far as cybatt's: FAP 19 at 1024 moves the upper lid's middle alike
    original = load_model("cybatt")
    node, v = model.tables.feature_points["3.1"]
    moved = model.deform({19: 1024}).points[node][v] - model.neutral_points(node)[v]
    node0, v0 = original.tables.feature_points["3.1"]
    want = original.deform({19: 1024}).points[node0][v0] - original.neutral_points(node0)[v0]
    assert np.allclose(moved, want, atol=1e-4)


def test_fapus_are_measured_on_the_imported_mesh(files):
    fapu = load_model(files[1]).fapu
    original = load_model("cybatt").fapu
    assert fapu is not None
    for unit in ("irisd", "es", "ens", "mns", "mw"):
        assert getattr(fapu, unit) == pytest.approx(getattr(original, unit), rel=0.1), unit


def test_the_eyes_become_rotating_transforms(files):
    model = load_model(files[1])
    assert {"L_EYE_ROTATION", "R_EYE_ROTATION"} <= set(model.tables.transform_nodes())
    pose = model.deform({23: 20000, 26: -10000})  # 0.2 rad to the face's left, 0.1 rad up
    left = pose.transforms["L_EYE_ROTATION"]["rotation"]
    right = pose.transforms["R_EYE_ROTATION"]["rotation"]
    assert np.allclose(rotation_matrix(left), rotation_matrix([0, 1, 0, 0.2]))
    assert np.allclose(rotation_matrix(right), rotation_matrix([1, 0, 0, -0.1]))
    for m in (23, 24, 25, 26):
        assert Miap("fap", m) in model.tables.adts


def _psnr(x: np.ndarray, y: np.ndarray) -> float:
    mse = float(((x - y) ** 2).mean())
    return 99.0 if mse == 0 else float(10 * np.log10(255**2 / mse))


def _frames(folder: Path) -> list[np.ndarray]:
    return [np.asarray(Image.open(p), dtype=np.float64) for p in sorted(folder.glob("*.png"))]


def test_say_on_the_import_looks_like_say_on_the_original(files, tmp_path):
    _, wrl = files
    runs = {}
    for name, model in (("original", "cybatt"), ("imported", str(wrl))):
        out = tmp_path / name
        code = vtts(["say", TEXT, "--model", model, "--no-autonomous", "--size", "160x120",
                     "--png-dir", str(out)])  # fmt: skip
        assert code == 0
        runs[name] = _frames(out)
    a, b = runs["original"], runs["imported"]
    assert len(a) == len(b) > 10
    error = [_psnr(x, y) for x, y in zip(a, b, strict=True)]
    assert min(error) >= MIN_PSNR_DB, np.round(error, 1)
    # the face did move, and far more than the import is off (two still heads would pass the
    # bound above)
    motion = min(_psnr(f, a[0]) for f in a)
    assert motion < min(error) - 6, (motion, min(error))


def test_adi_import_errors(tmp_path, capsys):
    """Outputs ``adi import`` refuses, on a small avatar (what is checked is the paths, not the
    mesh: an output beside the input is imported, one that would replace it is not)."""
    glb = _avatar_with(tmp_path)
    assert adi(["import", str(glb), "-o", str(tmp_path / "x.adt")]) == 1
    assert "the output is a .wrl file" in capsys.readouterr().err
    assert adi(["import", str(tmp_path / "missing.glb"), "-o", str(tmp_path / "x.wrl")]) == 1
    assert "missing.glb: error: cannot read file" in capsys.readouterr().err
    (tmp_path / "x.glb").write_text("{}", encoding="utf-8")
    assert adi(["import", str(tmp_path / "x.glb"), "-o", str(tmp_path / "x.wrl")]) == 1
    err = capsys.readouterr().err
    assert "x.glb" in err and "Traceback" not in err
    assert not (tmp_path / "x.wrl").exists()
    # an output that would replace the input
    assert adi(["import", str(glb), "-o", str(glb.with_suffix(".wrl"))]) == 0  # beside it: fine
    link = tmp_path / "same.wrl"
    link.symlink_to(glb)
    assert adi(["import", str(glb), "-o", str(link)]) == 1
    assert glb.read_bytes()[:4] == b"glTF"


# ---- transforms and names nothing can render or read back (issue 45) -----------------------------


def _avatar_with(tmp_path: Path, *, positions=None, **node) -> Path:
    from .avatar_helpers import Builder, grid, moves

    pos, faces = grid(3)
    if positions is not None:
        pos = pos + positions
    b = Builder()
    p = b.accessor(pos)
    idx = b.accessor(faces.reshape(-1), 5123)
    mesh = b.mesh({"POSITION": p}, idx, [{"POSITION": b.accessor(moves(len(pos), 1))}],
                  ["jawOpen"])  # fmt: skip
    b.node(mesh=mesh, **{"name": "Head", **node})
    return b.save(tmp_path / "a.glb")


@pytest.mark.parametrize(
    "node, message",
    [
        ({"scale": [1e300, 1e300, 1e300]}, "node 0: its transform reaches 1e+300"),
        ({"translation": [1e308, 0, 0]}, "node 0: its transform reaches 1e+308"),
        ({"translation": [0, -2e9, 0]}, "node 0: its transform reaches 2e+09"),
        ({"matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 3e38, 0, 0, 1]}, "reaches 3e+38"),
        ({"positions": 3e38}, "mesh Face: its positions reach 3e+38"),
        ({"positions": -3e38}, "mesh Face: its positions reach 3e+38"),
        ({"positions": 1e9 * 1.5, "scale": [0.1, 0.1, 0.1]}, "its positions reach 1.5e+09"),
        ({"positions": 1e6, "scale": [1e4, 1e4, 1e4]}, "its positions reach 1e+10"),
    ],
)
def test_a_model_nothing_can_render_is_refused(tmp_path, capsys, node, message):
    """Scale 1e300 or translation 1e308 ended in an OverflowError while writing; ±3e38
    positions were written as a model nothing can render or frame."""
    path = _avatar_with(tmp_path, **node)
    out = tmp_path / "out.wrl"
    assert adi(["import", str(path), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert f"{path}: error: " in err and message in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize(
    "node", [{"scale": [1e4, 1e4, 1e4]}, {"translation": [0, 9e8, 0]}, {"positions": 1e3}]
)
def test_large_models_within_the_extent_import(tmp_path, node):
    path = _avatar_with(tmp_path, **node)
    assert adi(["import", str(path), "-o", str(tmp_path / "out.wrl")]) == 0


KEYWORDS = ["USE", "DEF", "TRUE", "FALSE", "NULL", "PROTO", "EXTERNPROTO", "ROUTE", "TO", "IS",
            "field", "eventIn", "exposedField"]  # fmt: skip


@pytest.mark.parametrize("name", KEYWORDS)
def test_vrml_keywords_are_renamed_as_def_names(tmp_path, name):
    path = _avatar_with(tmp_path, name=name)
    out = tmp_path / "out.wrl"
    assert adi(["import", str(path), "-o", str(out)]) == 0
    text = out.read_text()
    assert f"DEF {name} " not in text and f"DEF {name}_ Transform" in text
    load_model(out)


def test_a_skin_lit_brighter_than_the_lights_exports_a_brighter_texture():
    """A head whose skin is lit brighter than the renderer's lights (diffuseColor above 1: a
    fitted head's, vtts.fit.head.set_exposure) exports factors of at most 1 and, for the skin,
    its atlas that much brighter (an image of its own; the eyes and teeth keep the file)."""
    from vtts.export.avatar import arkit_avatar_gltf

    model = load_model("cybatt")
    plain = arkit_avatar_gltf(model)
    model.scene.node("SKIN").expand()["material"].expand().fields["diffuseColor"] = np.array(
        [1.4, 1.0, 1.0]
    )
    lit = arkit_avatar_gltf(model)
    assert len(lit.images) == len(plain.images) + 1
    factors = [m.pbrMetallicRoughness.baseColorFactor for m in lit.materials]
    assert max(max(f) for f in factors) <= 1.0
    assert factors == [m.pbrMetallicRoughness.baseColorFactor for m in plain.materials]
