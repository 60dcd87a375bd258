"""The Khronos glTF-Validator (npm ``gltf-validator``, installed by ``scripts/setup.sh`` into
``tools/node``) finds no error and no warning in what vtts exports: binary and JSON, one head and
two, every kind of Transform, texture and primitive the rig has, the room layout."""

from __future__ import annotations

import numpy as np
import pygltflib
import pytest

from vtts.export import write_gltf
from vtts.face import N_PARAMS, load_model

from .gltf_helpers import HEAD, problems, sweep, validate, write_rig


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    return load_model(write_rig(tmp_path_factory.mktemp("rig")))


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
@pytest.mark.parametrize("case", ["cybatt", "rig", "two heads in a room"])
def test_the_validator_finds_nothing_wrong(case, suffix, rig, tmp_path):
    if case == "cybatt":
        models, kw = [load_model("cybatt")], {}
    elif case == "rig":
        models, kw = [rig], {}
    else:
        models, kw = [rig, load_model(HEAD)], {"layout": "room"}
    params = [sweep(m, n_frames=20, seed=i) for i, m in enumerate(models)]
    path = write_gltf(tmp_path / f"out{suffix}", models, params, 30.0, **kw)
    report = validate(path)
    assert problems(report) == []
    issues = report["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0
    assert issues["messages"] == []  # not even an info or a hint
    info = report["info"]
    assert info["animationCount"] == 1 and info["hasMorphTargets"]
    if case != "two heads in a room":
        assert info["hasTextures"]


def test_the_validator_is_wired_to_fail(tmp_path):
    """The wrapper reports what the validator finds: a file with a broken accessor has errors
    (so the test above can fail)."""
    head = load_model(HEAD)
    path = write_gltf(tmp_path / "x.gltf", [head], np.zeros((2, N_PARAMS)), 30.0)
    text = path.read_text(encoding="utf-8")
    broken = tmp_path / "broken.gltf"
    # the first accessor claims a million times more elements than its bufferView holds
    broken.write_text(text.replace('"count":', '"count":1000000', 1), "utf-8")
    report = validate(broken)
    assert report["issues"]["numErrors"] > 0


def test_an_appearance_without_material_is_unlit_as_in_vrml97(tmp_path):
    wrl = tmp_path / "u.wrl"
    wrl.write_text(
        "#VRML V2.0 utf8\n"
        "Shape { appearance Appearance { texture PixelTexture { image 1 1 3 0xff0000 } }\n"
        "  geometry IndexedFaceSet { coord Coordinate { point [0 0 0, 1 0 0, 0 1 0] }\n"
        "  coordIndex [0 1 2 -1] } }\n"
        "Transform { translation 2 0 0 children Shape { appearance Appearance {\n"
        "  material Material { diffuseColor 0 0 1 } } geometry Sphere {} } }\n",
        encoding="utf-8",
    )
    path = write_gltf(tmp_path / "u.glb", [load_model(wrl)], np.zeros((1, N_PARAMS)), 30.0)
    report = validate(path)
    assert problems(report) == [] and report["info"]["extensionsUsed"] == ["KHR_materials_unlit"]
    doc = pygltflib.GLTF2.load(str(path))
    unlit, lit = doc.materials
    assert unlit.extensions == {"KHR_materials_unlit": {}}
    assert unlit.pbrMetallicRoughness.baseColorFactor == [1.0, 1.0, 1.0, 1.0]  # the texture's
    assert not lit.extensions and lit.pbrMetallicRoughness.baseColorFactor == [0, 0, 1, 1]


def test_a_texture_with_alpha_is_a_cutout_as_the_renderer_draws_it(tmp_path):
    """An RGBA texture transparent somewhere (a fitted head's glasses) exports as ``alphaMode``
    MASK at the renderer's cutoff; an opaque one stays OPAQUE."""
    from vtts.render.scene import ALPHA_CUTOFF

    wrl = tmp_path / "a.wrl"
    shape = (
        "Shape {{ appearance Appearance {{ texture PixelTexture {{ image 2 1 4 {} }} }}\n"
        "  geometry IndexedFaceSet {{ coord Coordinate {{ point [0 0 0, 1 0 0, 0 1 0] }}\n"
        "  coordIndex [0 1 2 -1] }} }}\n"
    )
    wrl.write_text("#VRML V2.0 utf8\n" + shape.format("0xff000000 0xff0000ff")
                   + shape.format("0x00ff00ff 0x00ff00ff"), encoding="utf-8")  # fmt: skip
    path = write_gltf(tmp_path / "a.glb", [load_model(wrl)], np.zeros((1, N_PARAMS)), 30.0)
    assert problems(validate(path)) == []
    cut, opaque = pygltflib.GLTF2.load(str(path)).materials
    assert cut.alphaMode == "MASK" and cut.alphaCutoff == ALPHA_CUTOFF
    assert opaque.alphaMode == "OPAQUE"
