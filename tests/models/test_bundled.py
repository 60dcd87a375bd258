"""The bundled heads (cybatt and lotta): what they are made of, what they can do, that they
differ, and that `make models` rebuilds exactly the committed files."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import vtts
from vtts.face import Miap, bundled_models, face_params
from vtts.resources import models_dir
from vtts.vrml import triangulate

ROOT = Path(__file__).parents[2]
MODELS = ("cybatt", "lotta")
EXPRESSIONS = ("joy", "sadness", "anger", "fear", "disgust", "surprise")
#: The IndexedFaceSets of Ostermann–Haratsch's Figure 11 (and the mouth cavity, ears, sockets).
MESHES = ("FACE", "HAIR", "NECK", "UPPER_TEETH", "LOWER_TEETH", "TONGUE", "L_EYEBALL",
          "R_EYEBALL", "MOUTH", "L_EAR", "R_EAR", "SOCKETS")  # fmt: skip


@pytest.fixture(scope="module", params=MODELS)
def model(request):
    return vtts.load_model(request.param)


def test_both_heads_are_bundled():
    assert set(MODELS) <= set(bundled_models())
    for name in MODELS:
        assert (models_dir() / f"{name}.wrl").is_file()
        assert (models_dir() / f"{name}.adt").is_file()


def test_scene_graph_is_figure_11(model):
    scene = model.scene
    yaw = scene.node("HEAD_YAW").expand()
    pitch = scene.node("HEAD_PITCH").expand()
    roll = scene.node("HEAD_ROLL").expand()
    assert yaw.type.name == pitch.type.name == roll.type.name == "Transform"
    assert [c.expand() for c in yaw["children"]] == [pitch]
    assert [c.expand() for c in pitch["children"]] == [roll]
    for name in MESHES:
        assert scene.node(name).expand().type.name == "IndexedFaceSet", name
    # each eyeball sits under its own yaw and pitch Transforms
    for side in ("L", "R"):
        eye_yaw = scene.node(f"{side}_EYE_YAW").expand()
        eye_pitch = scene.node(f"{side}_EYE_PITCH").expand()
        assert [c.expand() for c in eye_yaw["children"]] == [eye_pitch]
        shape = eye_pitch["children"][0].expand()
        assert shape["geometry"].expand() is scene.node(f"{side}_EYEBALL").expand()


def test_face_is_a_refined_candide_of_at_least_5000_triangles(model):
    face = triangulate(model.scene.node("FACE").expand())
    assert len(face.faces) >= 5000
    assert len(face.positions) > 5000
    assert face.texcoords is not None
    whole = sum(len(triangulate(model.scene.node(n).expand()).faces) for n in MESHES)
    assert whole < 25_000  # stays quick to render


def test_tables_cover_candide_faps_visemes_and_expressions(model):
    miaps = set(model.tables.adts)
    low = [m for m in miaps if m.kind == "fap"]
    assert len(low) >= 46
    # every FAP Candide-3 defines (3–42, 51–64) plus tongue, head and ears
    assert {Miap("fap", n) for n in [*range(3, 43), *range(51, 65)]} <= miaps
    assert {Miap("viseme", v) for v in range(1, 15)} <= miaps
    assert {Miap("expression", e) for e in range(1, 7)} <= miaps


@pytest.mark.parametrize("number", [23, 24, 25, 26, 48, 49, 50])
def test_eye_and_head_rotations_are_transform_tables(model, number):
    adt = model.tables.adts[Miap("fap", number)]
    assert not adt.meshes
    (t,) = adt.transforms
    assert t.field == "rotation"
    assert t.node.startswith("HEAD_") if number >= 48 else "_EYE_" in t.node


@pytest.mark.parametrize("number", [19, 20])
def test_blink_closes_in_two_phases(model, number):
    (mesh,) = model.tables.adts[Miap("fap", number)].meshes
    assert mesh.node == "FACE"
    borders = list(mesh.borders)
    assert {0, 512, 1024} <= set(borders)
    assert borders.index(1024) - borders.index(0) == 2  # close half, close fully
    half = mesh.displacement(512)
    full = mesh.displacement(1024)
    # non-linear: the second half is not the first one again
    assert not np.allclose(full, 2 * half, atol=1e-4)


def test_jaw_moves_teeth_and_tongue(model):
    adt = model.tables.adts[Miap("fap", 3)]
    assert {"FACE", "LOWER_TEETH", "TONGUE"} <= {m.node for m in adt.meshes}
    pose = model.deform({3: 600})
    neutral = model.deform({})
    drop = neutral.points["LOWER_TEETH"][:, 1] - pose.points["LOWER_TEETH"][:, 1]
    assert drop.min() > 0.02
    assert "UPPER_TEETH" not in pose.points  # fixed to the skull: no tables


def test_fapus_come_from_feature_points(model):
    fapu = model.fapu
    assert fapu is not None
    # a face of Candide's size: the eyes about 0.6 apart, the mouth about half as wide
    assert 0.4 < fapu.es * 1024 < 0.9
    assert 0.3 < fapu.mw * 1024 < 0.8
    assert {"3.5", "3.6", "9.15", "2.2", "8.3", "8.4", "3.1", "3.3"} <= set(
        model.tables.feature_points
    )


def test_temporal_tables_are_complete_and_personal():
    cybatt, lotta = (vtts.load_model(n) for n in MODELS)
    for m in (cybatt, lotta):
        assert set(m.temporal.expressions) == set(EXPRESSIONS)
        assert set(m.temporal.habits) == {"blink", "nod", "head_motion", "gaze"}
    a, b = cybatt.temporal, lotta.temporal
    assert a.lines() != b.lines()
    assert a.habit("blink").interval != b.habit("blink").interval
    assert a.habit("nod").amplitude != b.habit("nod").amplitude
    assert a.expression("joy").shape != b.expression("joy").shape


def test_same_stream_different_faces():
    cybatt, lotta = (vtts.load_model(n) for n in MODELS)
    from vtts.render import FaceRenderer

    params = face_params({19: 300}, visemes={10: 0.7}, expressions={"joy": 0.8})
    with FaceRenderer(cybatt) as r:
        a = r.render(params).astype(float)
    with FaceRenderer(lotta) as r:
        b = r.render(params).astype(float)
    background = np.round(np.array([0.32, 0.36, 0.42]) * 255)
    head = (np.abs(a - background).sum(axis=2) > 12) | (np.abs(b - background).sum(axis=2) > 12)
    assert np.abs(a - b)[head].mean() > 20
    # and each personality's smile is its own: lotta's is lopsided, cybatt's is not
    for m, lopsided in ((cybatt, False), (lotta, True)):
        pose = m.deform(expressions={"joy": 1}).points["FACE"] - m.neutral_points("FACE")
        left = pose[m.neutral_points("FACE")[:, 0] > 0.15][:, 1].max()
        right = pose[m.neutral_points("FACE")[:, 0] < -0.15][:, 1].max()
        assert (abs(left - right) > 0.01) == lopsided


@pytest.mark.parametrize("name", MODELS)
def test_texture_is_textured_and_small(name):
    path = models_dir() / f"{name}-face.png"
    assert path.stat().st_size <= 320_000
    img = np.asarray(Image.open(path).convert("L"), dtype=float)
    skin = img[200:300, 180:330]  # cheeks and nose in the skin chart
    # fine detail for optical flow: the image differs from its 3x3 local mean
    local = sum(np.roll(np.roll(skin, i, 0), j, 1) for i in (-1, 0, 1) for j in (-1, 0, 1)) / 9
    assert np.std((skin - local)[2:-2, 2:-2]) > 2.0


def test_readme_credits_candide():
    text = (ROOT / "models" / "README.md").read_text(encoding="utf-8")
    assert "Jörgen Ahlberg" in text and "Linköping University" in text


def test_make_models_rebuilds_the_committed_files(tmp_path):
    out = tmp_path / "models"
    subprocess.run(
        [sys.executable, str(ROOT / "models" / "src" / "build_models.py"), "--quiet",
         "--out", str(out), "--work", str(tmp_path / "work")],
        check=True,
        timeout=300,
    )  # fmt: skip
    built = sorted(p.name for p in out.iterdir())
    assert built == sorted(f"{n}{ext}" for n in MODELS for ext in (".wrl", ".adt", "-face.png"))
    for name in built:
        assert (out / name).read_bytes() == (models_dir() / name).read_bytes(), (
            f"models/{name} differs from what `make models` builds: run `make models`"
        )
