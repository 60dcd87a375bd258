"""VRML97 files as other tools write them: strict mode rejects what breaks the standard (naming
the place), ``lenient=True`` loads it with one warning per problem at its line and column; url
roots let a model tree with a shared textures/ folder load fully."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from vtts.errors import VrmlSemanticError, VrmlSyntaxError, VrmlUrlError, VttsError, VttsWarning
from vtts.vrml import dumps, parse, read, resolve_url

H = "#VRML V2.0 utf8\n"
WILD = Path(__file__).parents[1] / "data" / "vrml97" / "wild"


def lenient(text: str, **kw):
    """The scene and its warnings as ``(line, column, message)``."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = parse(text, lenient=True, **kw)
    found = [w.message for w in caught]
    assert all(isinstance(w, VttsWarning) for w in found), found
    return scene, [(w.line, w.column, w.message) for w in found]


# ---- one file per kind ---------------------------------------------------------------------------

#: kind → (text, strict error (class, fragment), warnings (line, column, fragment)); strict mode
#: stops at the first problem lenient mode warns about, at its line and column.
CASES = {
    "fields other browsers add": (
        H + "Shape {\n"
        '  shading "smooth"\n'
        "  appearance Appearance {\n"
        "    material Material { diffuseColor 1 0 0 mirror 0.5\n"
        '      normalTexture ImageTexture { url "n.png" } }\n'
        '    texture ImageTexture { url "t.png" alphaChannel "AUTO" }\n'
        "  }\n"
        "  geometry Box {}\n"
        "}\n"
        "Fog { volumetric TRUE volumetricDirection [ 0 0 1 ] }\n"
        "Viewpoint { direction 0 0 -1 autoCenterOfRotation TRUE }\n",
        (VrmlSemanticError, "Shape has no field 'shading'"),
        [
            (3, 3, "Shape has no field 'shading'"),
            (5, 44, "Material has no field 'mirror'"),
            (6, 7, "Material has no field 'normalTexture'"),
            (7, 40, "ImageTexture has no field 'alphaChannel'"),
            (11, 7, "Fog has no field 'volumetric'"),
            (11, 23, "Fog has no field 'volumetricDirection'"),
            (12, 13, "Viewpoint has no field 'direction'"),
            (12, 30, "Viewpoint has no field 'autoCenterOfRotation'"),
        ],
    ),
    "misplaced nodes": (
        H + "Shape {\n"
        "  appearance Material { diffuseColor 1 0 0 }\n"
        '  geometry Text { string "a" fontStyle Color { color [ 1 0 0 ] } }\n'
        "}\n"
        "Group { children [ Material {} Group {} ] }\n",
        (VrmlSemanticError, "field 'appearance' of Shape takes a appearance node"),
        [
            (3, 14, "Material is a material node: dropped"),
            (4, 40, "Color is a color node: dropped"),
            (6, 20, "field 'children' of Group takes a child node"),
        ],
    ),
    "PROTO fields and IS": (
        H + "PROTO Head [ field SFFloat size 1 ] {\n"
        "  Transform { scale IS scaleFactor\n"
        "    children Shape { geometry Sphere { radius IS size } } }\n"
        "}\n"
        "Head { size 2 skinTone 0.5 }\n",
        (VrmlSemanticError, "PROTO Head has no interface member 'scaleFactor'"),
        [
            (3, 24, "'scale IS scaleFactor' ignored"),
            (6, 15, "PROTO Head has no field 'skinTone'"),
        ],
    ),
    "X3D statements": (
        H + "PROFILE Immersive\n"
        "COMPONENT H-Anim:1\n"
        'META "generator" "an X3D exporter"\n'
        "DEF Head Transform { children Shape { geometry Sphere {} } }\n"
        "EXPORT Head AS FaceRoot\n"
        "IMPORT Body.Root AS BodyRoot\n"
        "ROUTE BodyRoot.translation_changed TO Head.set_translation\n",
        (VrmlSyntaxError, "PROFILE is an X3D statement, not VRML97"),
        [
            (2, 1, "X3D statement PROFILE skipped"),
            (3, 1, "X3D statement COMPONENT skipped"),
            (4, 1, "X3D statement META skipped"),
            (6, 1, "X3D statement EXPORT skipped"),
            (7, 1, "X3D statement IMPORT skipped"),
            (8, 7, "ROUTE names 'BodyRoot', a node of a skipped X3D IMPORT"),
        ],
    ),
    "PROTO default USEs an outer DEF": (
        H + "DEF Skin Material { diffuseColor 0.8 0.6 0.5 }\n"
        "PROTO Part [\n"
        "  field SFNode material USE Skin\n"
        "  field MFNode extras [ USE Nowhere ]\n"
        "] {\n"
        "  Shape { appearance Appearance { material IS material } geometry Box {} }\n"
        "}\n"
        "Part {}\n",
        (VrmlSemanticError, "USE of undefined name 'Skin'"),
        [
            (4, 29, "USE Skin in the default of PROTO Part field 'material' names a DEF outside"),
            (5, 29, "USE Nowhere in the default of PROTO Part field 'extras' names no DEF"),
        ],
    ),
    "values of the wrong type": (
        H + "Transform {\n"
        "  translation 1 2\n"
        "  children Shape {\n"
        '    appearance Appearance { material Material { shininess "high" } }\n'
        "    geometry IndexedFaceSet {\n"
        "      coord Coordinate { point [ 0 0 0, 1 0 0, 0 1 0 ] }\n"
        "      color Color { color [ 1 0 0, 0 1 0, ..., 0 0 1 ] }\n"
        '      solid "no" coordIndex [ 0 1 2 -1 ]\n'
        "    }\n"
        "  }\n"
        "}\n"
        'PROTO Ball [ field SFFloat size "big" ] { Sphere { radius IS size } }\n'
        "Shape { geometry Ball {} }\n",
        (VrmlSemanticError, "expects SFVec3f (3 numbers), got 2 numbers"),
        [
            (3, 15, "field 'translation' of Transform expects SFVec3f"),
            (5, 59, "field 'shininess' of Material expects SFFloat (1 number), got a string"),
            (8, 43, "field 'color' of Color expects MFColor: '...' is not a number"),
            (9, 13, "field 'solid' of IndexedFaceSet expects SFBool, got a string"),
            (13, 33, "PROTO Ball field 'size' gets an empty value"),
        ],
    ),
    "a field given twice": (
        H + "DEF Clock TimeSensor { loop TRUE cycleInterval 2 loop FALSE }\n"
        'NavigationInfo {\n  type "FLY"\n  type [ "WALK" "ANY" ]\n}\n'
        "PROTO Ball [ field SFFloat size 1 ] { Sphere { radius 2 radius IS size } }\n",
        (VrmlSemanticError, "field 'loop' is given twice in one TimeSensor"),
        [
            (2, 50, "field 'loop' is given twice in one TimeSensor: the last one is kept"),
            (5, 3, "field 'type' is given twice in one NavigationInfo"),
            (7, 57, "field 'radius' is given twice in one Sphere"),
        ],
    ),
    "field types VRML97 lacks": (
        H + "EXTERNPROTO Tessellation [\n"
        "  exposedField SFLong slices\n"
        "  exposedField SFInt32 divisions\n"
        '] [ "urn:example:Tessellation" ]\n'
        "Tessellation { slices 8 divisions 50 }\n"
        "PROTO Head [ field SFDouble scale 1.5 field SFFloat size 1 ] {\n"
        "  Transform { scale IS scale children Shape { geometry Sphere { radius IS size } } }\n"
        "}\n"
        "Head { scale 2 size 3 }\n"
        "Script { field SFVec3d where 1 2 3 field SFInt32 n 2 }\n",
        (VrmlSemanticError, "unknown field type 'SFLong'"),
        [
            (3, 16, "unknown field type 'SFLong': EXTERNPROTO Tessellation member 'slices'"),
            (6, 16, "EXTERNPROTO Tessellation has no field 'slices'"),
            (7, 20, "unknown field type 'SFDouble': PROTO Head member 'scale' left out"),
            (8, 24, "PROTO Head has no interface member 'scale'"),
            (10, 8, "PROTO Head has no field 'scale'"),
            (11, 16, "unknown field type 'SFVec3d': Script member 'where' left out"),
        ],
    ),
    "a ROUTE that cannot connect": (
        H + "DEF Clock TimeSensor { loop TRUE }\n"
        "DEF Lamp PointLight { }\n"
        "ROUTE Clock.fraction_changed TO Lamp.set_on\n"
        "ROUTE Clock.isActive TO Lamp.set_on\n"
        "ROUTE Clock.cycleTime TO Door.set_open\n"
        "ROUTE Clock.set_startTime TO Lamp.set_on\n"
        "ROUTE Clock.isActive TO Lamp.set_glow\n",
        (VrmlSemanticError, "connects an SFFloat eventOut to an SFBool eventIn"),
        [
            (4, 7, "connects an SFFloat eventOut to an SFBool eventIn (rule: a ROUTE connects"),
            (6, 26, "ROUTE names 'Door', which is not DEFed before this point"),
            (7, 13, "TimeSensor has no eventOut 'set_startTime': the ROUTE is skipped"),
            (8, 30, "PointLight has no eventIn 'set_glow': the ROUTE is skipped"),
        ],
    ),
    "a USE of an undefined name": (
        H + "DEF Red Material { diffuseColor 1 0 0 }\n"
        "Shape { appearance Appearance { material USE Blue } geometry Box { } }\n"
        "Group { children [ USE Ball Shape { geometry Sphere { } } ] }\n"
        "USE Cone\n",
        (VrmlSemanticError, "USE of undefined name 'Blue'"),
        [
            (
                3,
                46,
                "USE of undefined name 'Blue': a USE must follow a DEF of the same name in "
                "the same scope (DEF names here: Red): the USE is dropped",
            ),
            (4, 24, "USE of undefined name 'Ball'"),
            (5, 5, "USE of undefined name 'Cone'"),
        ],
    ),
    "IS that cannot bind": (
        H + "DEF Mover Script {\n"
        "  field SFNode target IS Target\n"
        "  eventIn SFTime start\n"
        "}\n"
        "Transform { translation IS where }\n"
        "PROTO Ball [ field SFFloat size 1 eventIn SFFloat set_size ] {\n"
        "  Transform { translation IS size\n"
        "    children Shape { geometry Sphere { radius IS set_size } } }\n"
        "}\n"
        "Ball { size 2 }\n",
        (VrmlSemanticError, "'target IS Target' outside a PROTO body"),
        [
            (
                3,
                16,
                "'target IS Target' outside a PROTO body: IS binds a node's member to its "
                "PROTO's interface and is legal only inside a PROTO definition: the binding is "
                "ignored",
            ),
            (6, 13, "'translation IS where' outside a PROTO body"),
            (8, 15, "Transform.translation is SFVec3f but PROTO Ball.size is SFFloat"),
            (9, 40, "a field cannot be bound to the PROTO's eventIn"),
        ],
    ),
    "interface members that clash": (
        H + "PROTO Lamp [\n"
        "  exposedField SFBool on TRUE\n"
        "  eventIn SFBool set_on\n"
        "  eventOut SFBool on_changed\n"
        "] { PointLight { on IS on } }\n"
        "DEF L Lamp { on FALSE }\n"
        "DEF Panel Script { field SFInt32 n 1 eventIn SFInt32 n }\n",
        (VrmlSemanticError, "'set_on' clashes with the implicit event of exposedField 'on'"),
        [
            (
                4,
                18,
                "'set_on' clashes with the implicit event of exposedField 'on': the later member",
            ),
            (5, 19, "'on_changed' clashes with the implicit event of exposedField 'on'"),
            (8, 54, "Script: 'n' is declared twice: the later member is left out"),
        ],
    ),
    "exposedField in a Script": (
        H + "DEF Counter Script {\n"
        "  exposedField SFInt32 count 3\n"
        "  eventIn SFTime tick\n"
        "}\n"
        "DEF Clock TimeSensor { }\n"
        "ROUTE Clock.cycleTime TO Counter.tick\n",
        (VrmlSemanticError, "exposedField is not allowed in a Script"),
        [
            (
                3,
                3,
                "exposedField is not allowed in a Script (rule: a Script declares eventIn, "
                "eventOut and field members only): read as a field",
            )
        ],
    ),
    "url out of the folder": (
        H + "Shape {\n"
        '  appearance Appearance { texture ImageTexture { url "../textures/wall.png" } }\n'
        "  geometry Box {}\n"
        "}\n",
        (VrmlUrlError, "'../textures/wall.png' leaves the file's folder"),
        [(3, 54, "'../textures/wall.png' leaves the file's folder: not loaded")],
    ),
}


@pytest.mark.parametrize("kind", sorted(CASES))
def test_strict_rejects_with_the_place(kind: str):
    text, (cls, fragment), warned = CASES[kind]
    line, column, _ = warned[0]
    with pytest.raises(cls) as info:
        parse(text, file="/tmp/wild/model.wrl")
    err = info.value
    assert (err.line, err.column) == (line, column), str(err)
    assert fragment in err.message
    assert f"model.wrl:{line}:{column}:" in str(err)


@pytest.mark.parametrize("kind", sorted(CASES))
def test_lenient_loads_with_exactly_the_warnings(kind: str):
    text, _, expected = CASES[kind]
    scene, got = lenient(text, file="/tmp/wild/model.wrl")
    assert len(got) == len(expected), got
    for (line, column, message), (want_line, want_column, fragment) in zip(
        got, expected, strict=True
    ):
        assert (line, column) == (want_line, want_column), message
        assert fragment in message and "(--lenient" in message
    # what lenient mode loads, written back, is VRML97 that strict mode reads as the same scene
    # (a url that leaves the folder is kept as data: it needs lenient mode or a url root)
    if kind == "url out of the folder":
        assert parse(dumps(scene), file="/tmp/wild/model.wrl", url_root="/tmp") == scene
    else:
        assert parse(dumps(scene)) == scene


def test_unknown_fields_are_skipped_and_the_rest_kept():
    scene, _ = lenient(CASES["fields other browsers add"][0])
    shape, fog, viewpoint = scene.roots
    material = shape["appearance"]["material"]
    assert material["diffuseColor"].tolist() == [1, 0, 0]
    assert set(material.fields) == {"diffuseColor"}
    assert shape["appearance"]["texture"]["url"] == ["t.png"]
    assert shape["geometry"].type.name == "Box"
    assert not fog.fields and not viewpoint.fields


def test_misplaced_nodes_are_dropped_and_the_shape_keeps_its_geometry():
    scene, _ = lenient(CASES["misplaced nodes"][0])
    shape, group = scene.roots
    assert "appearance" not in shape.fields and shape["appearance"] is None
    assert shape["geometry"].type.name == "Text"
    assert shape["geometry"]["fontStyle"] is None
    assert [c.type.name for c in group["children"]] == ["Group"]


def test_proto_with_unknown_members_expands():
    scene, _ = lenient(CASES["PROTO fields and IS"][0])
    head = scene.roots[0]
    assert set(head.fields) == {"size"}
    transform = head.expand()
    assert transform.type.name == "Transform" and "scale" not in transform.fields
    assert transform["children"][0].expand()["geometry"]["radius"] == 2.0


def test_x3d_statements_leave_the_scene():
    scene, _ = lenient(CASES["X3D statements"][0])
    assert [n.name for n in scene.roots] == ["Head"] and scene.routes == []
    assert len(scene.statements) == 1


def test_proto_default_use_is_resolved_or_dropped():
    scene, _ = lenient(CASES["PROTO default USEs an outer DEF"][0])
    proto = scene.protos[0]
    default = proto.decls["material"].default
    assert default.type.name == "Material" and default["diffuseColor"].tolist() == [0.8, 0.6, 0.5]
    assert proto.decls["extras"].default == []
    shape = scene.roots[-1].expand()
    assert shape["appearance"]["material"]["diffuseColor"].tolist() == [0.8, 0.6, 0.5]


def test_conformance_bad_default_use_is_dropped_when_lenient():
    bad = Path(__file__).parents[1] / "data" / "vrml97" / "bad"
    with pytest.warns(VttsWarning, match="USE G in the default of PROTO Node field 'val1'"):
        scene = read(bad / "use-def-in-different-proto-default-value.wrl", lenient=True)
    assert scene.protos[0].decls["val1"].default is None


def test_values_of_the_wrong_type_are_skipped():
    """The field keeps its default (or, given twice, its earlier value); a PROTO field whose
    default cannot be typed gets the type's empty value."""
    scene, _ = lenient(CASES["values of the wrong type"][0])
    transform, shape = scene.roots
    assert "translation" not in transform.fields
    ifs = transform["children"][0]["geometry"]
    assert ifs["solid"] is True and ifs["color"]["color"].shape == (0, 3)
    assert ifs["coord"]["point"].shape == (3, 3)
    assert shape.expand()["geometry"].expand()["radius"] == 0.0
    scene, _ = lenient(H + "Transform { translation 1 2 3 translation 4 five 6 }")
    assert scene.roots[0]["translation"].tolist() == [1, 2, 3]
    scene, got = lenient(H + "Transform { scale [ 2 2 2 ] }")
    assert "a single value, not a '[ ]' list: the value is skipped" in got[0][2]
    assert scene.roots[0]["scale"].tolist() == [1, 1, 1]


def test_a_field_given_twice_keeps_the_last():
    scene, _ = lenient(CASES["a field given twice"][0])
    (clock, nav), ball = scene.roots, scene.protos[0]
    assert clock["loop"] is False and clock["cycleInterval"] == 2.0
    assert nav["type"] == ["WALK", "ANY"]
    sphere = ball.first_node()
    assert "radius" not in sphere.fields and sphere.is_maps == {"radius": "size"}
    assert dumps(scene).count("loop") == 1


def test_members_of_unknown_types_are_left_out():
    scene, _ = lenient(CASES["field types VRML97 lacks"][0])
    tessellation, head, script = scene.roots
    assert set(tessellation.type.decls) == {"divisions"}
    assert tessellation.fields == {"divisions": 50}
    assert set(head.type.decls) == {"size"}
    assert head.expand()["children"][0]["geometry"]["radius"] == 3.0
    assert [d.name for d in script.script_decls] == ["n"]


def test_bad_routes_are_skipped_and_good_ones_kept():
    scene, _ = lenient(CASES["a ROUTE that cannot connect"][0])
    assert [(r.from_node, r.from_event, r.to_node, r.to_event) for r in scene.routes] == [
        ("Clock", "isActive", "Lamp", "set_on")
    ]


def test_undefined_uses_leave_the_rest_of_the_scene():
    scene, _ = lenient(CASES["a USE of an undefined name"][0])
    red, shape, group = scene.roots
    assert shape["appearance"]["material"] is None and shape["geometry"].type.name == "Box"
    assert [c.type.name for c in group["children"]] == ["Shape"]


def test_is_bindings_that_cannot_bind_are_ignored():
    scene, _ = lenient(CASES["IS that cannot bind"][0])
    mover, transform, ball = scene.roots
    assert mover.is_maps == {} and mover["target"] is None
    assert transform.is_maps == {} and list(transform["translation"]) == [0, 0, 0]
    inner = ball.expand()
    assert list(inner["translation"]) == [0, 0, 0]
    assert inner["children"][0]["geometry"]["radius"] == 1.0


def test_a_script_exposed_field_is_a_field_with_its_value():
    scene, _ = lenient(CASES["exposedField in a Script"][0])
    counter = scene.roots[0]
    assert counter["count"] == 3 and counter.type.decls["count"].access == "field"
    assert len(scene.routes) == 1


def test_clashing_members_keep_the_first():
    scene, _ = lenient(CASES["interface members that clash"][0])
    lamp, panel = scene.protos[0], scene.roots[1]
    assert lamp.decls["on"].access == "exposedField" and "set_on" not in lamp.decls
    assert scene.roots[0].expand()["on"] is False
    assert [d.access for d in panel.script_decls] == ["field"]


def test_every_conformance_file_loads_leniently():
    """The conformance set's invalid files break VRML97 in ways browsers forgive: strict mode
    rejects each (test_conformance), lenient mode loads each with warnings."""
    bad = sorted((Path(__file__).parents[1] / "data" / "vrml97" / "bad").glob("*.wrl"))
    assert len(bad) == 12
    for path in bad:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            read(path, lenient=True)
        assert caught and all(isinstance(w.message, VttsWarning) for w in caught), path.name


def test_lenient_keeps_the_other_rules():
    """What leaves no scene to show stays an error in lenient mode too."""
    with pytest.raises(VrmlSyntaxError):
        parse(H + "Group { children [ Shape { } }", lenient=True)
    with pytest.raises(VrmlSemanticError, match="has no node in its body"):
        with pytest.warns(VttsWarning, match="USE of undefined name 'Nothing'"):
            parse(H + "PROTO P [ ] { USE Nothing }", lenient=True)


# ---- real files ---------------------------------------------------------------------------------

#: Each file's warnings in lenient mode (line, column); strict mode stops at the first.
WILD_FILES = {
    "fog_volumetric_linear_z.wrl": [(6, 3), (7, 3), (8, 3), (24, 14)],
    "background_alpha_tex.wrl": [(12, 17), (13, 19), (14, 18), (15, 17), (16, 18), (17, 16),
                                 (34, 18)],
    "openvrml_jsTouch.wrl": [(10, 20)],
}  # fmt: skip


def test_wild_folder_is_complete():
    assert sorted(p.name for p in WILD.glob("*.wrl")) == sorted(WILD_FILES)


@pytest.mark.parametrize("name", sorted(WILD_FILES))
def test_real_files(name: str):
    places = WILD_FILES[name]
    with pytest.raises(VttsError) as info:
        read(WILD / name)
    assert (info.value.line, info.value.column) == places[0]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = read(WILD / name, lenient=True)
    assert [(w.message.line, w.message.column) for w in caught] == places
    assert scene.find("Viewpoint") or scene.find("Shape")


# ---- url roots ----------------------------------------------------------------------------------

SKIN = (
    H + "Shape {\n"
    '  appearance Appearance { texture ImageTexture { url "../textures/skin.png" } }\n'
    "  geometry IndexedFaceSet { coord Coordinate { point [ 0 0 0, 1 0 0, 0 1 0 ] }\n"
    "    coordIndex [ 0 1 2 -1 ] }\n"
    "}\n"
)


@pytest.fixture
def tree(tmp_path: Path) -> Path:
    """``models/head.wrl`` whose texture is ``textures/skin.png`` beside ``models/``."""
    from PIL import Image

    (tmp_path / "models").mkdir()
    (tmp_path / "textures").mkdir()
    (tmp_path / "models" / "head.wrl").write_text(SKIN)
    Image.new("RGB", (4, 4), (200, 120, 90)).save(tmp_path / "textures" / "skin.png")
    return tmp_path


def test_url_out_of_the_folder_needs_a_root(tree: Path, monkeypatch):
    monkeypatch.delenv("VTTS_URL_ROOT", raising=False)
    head = tree / "models" / "head.wrl"
    with pytest.raises(VrmlUrlError, match=r"leaves the file's folder.*--url-root"):
        read(head)
    scene = read(head, url_root=tree)
    assert scene.url_roots == (tree.resolve(),)
    url = scene.find("ImageTexture")[0]["url"]
    assert resolve_url(url, head.parent) is None  # without the root: never loaded
    assert resolve_url(url, head.parent, scene.url_roots) == (tree / "textures/skin.png").resolve()
    monkeypatch.setenv("VTTS_URL_ROOT", str(tree))
    assert read(head).url_roots == (tree.resolve(),)


def test_model_texture_is_used_with_a_root(tree: Path, monkeypatch):
    from vtts.face import load_model

    monkeypatch.delenv("VTTS_URL_ROOT", raising=False)
    monkeypatch.setenv("VTTS_CACHE_DIR", str(tree / "cache"))
    head = tree / "models" / "head.wrl"
    with pytest.raises(VrmlUrlError):
        load_model(head)
    model = load_model(head, url_root=tree)
    tex = model.scene.find("ImageTexture")[0]
    found = resolve_url(tex["url"], head.parent, model.scene.url_roots)
    assert found is not None and found.name == "skin.png"
    with pytest.raises(VrmlUrlError):  # the load with a root left nothing behind for this one
        load_model(head)


@pytest.mark.parametrize("mode", [False, True], ids=["strict", "lenient"])
@pytest.mark.parametrize("url", ["/etc/passwd", "file:///etc/passwd", "C:\\\\skin.png"])
def test_absolute_paths_outside_the_roots_are_refused(tree: Path, url: str, mode: bool):
    text = SKIN.replace("../textures/skin.png", url)
    file = str(tree / "models" / "head.wrl")
    if mode:
        scene, got = lenient(text, file=file, url_root=tree)
        assert len(got) == 1 and "not loaded" in got[0][2]
        assert resolve_url([url], tree / "models", scene.url_roots) is None
    else:
        with pytest.raises(VrmlUrlError, match="absolute path"):
            parse(text, file=file, url_root=tree)


def test_absolute_path_inside_a_root_is_allowed(tree: Path):
    skin = (tree / "textures" / "skin.png").resolve()
    text = SKIN.replace("../textures/skin.png", str(skin))
    scene = parse(text, file=str(tree / "models" / "head.wrl"), url_root=tree)
    assert resolve_url([str(skin)], tree / "models", scene.url_roots) == skin


@pytest.mark.parametrize("mode", [False, True], ids=["strict", "lenient"])
def test_network_urls_are_data_and_never_loaded(tree: Path, mode: bool):
    (tree / "models" / "http:").mkdir()
    (tree / "models" / "http:" / "skin.png").write_bytes(b"x")
    text = SKIN.replace("../textures/skin.png", "http://example.com/skin.png")
    scene, got = lenient(text) if mode else (parse(text), [])
    assert got == []
    url = scene.find("ImageTexture")[0]["url"]
    assert resolve_url(url, tree / "models", (tree,)) is None


def test_url_root_must_be_a_folder(tree: Path, monkeypatch):
    with pytest.raises(VrmlUrlError, match="url root .* is not a folder"):
        parse(H, url_root=tree / "missing")
    monkeypatch.setenv("VTTS_URL_ROOT", str(tree / "missing"))
    with pytest.raises(VrmlUrlError, match=r"\$VTTS_URL_ROOT .* is not a folder"):
        parse(H)


def test_symlink_out_of_the_root_is_not_loaded(tree: Path, tmp_path_factory):
    outside = tmp_path_factory.mktemp("outside") / "secret.png"
    outside.write_bytes(b"x")
    (tree / "textures" / "link.png").symlink_to(outside)
    assert resolve_url(["../textures/link.png"], tree / "models", (tree,)) is None


# ---- the command --------------------------------------------------------------------------------


def vtts(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).with_name("vtts")
    full = {k: v for k, v in os.environ.items() if k != "VTTS_URL_ROOT"} | (env or {})
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=60, env=full)


def test_cli_check_lenient_prints_warnings_and_ok(tmp_path: Path):
    f = tmp_path / "wild.wrl"
    f.write_text(CASES["fields other browsers add"][0])
    strict = vtts("check", str(f))
    assert strict.returncode == 1
    assert strict.stderr.startswith(f"{f}:3:3: error: Shape has no field 'shading'")
    r = vtts("check", "--lenient", str(f))
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"OK {f} (")
    lines = r.stderr.splitlines()
    # eight fields skipped, and the texture its ImageTexture names is not there
    assert len(lines) == 9 and all(": warning: " in line for line in lines)
    assert lines[0].startswith(f"{f}:3:3: warning: Shape has no field 'shading'")
    assert lines[8].startswith(f"{f}:7: warning: texture 't.png' not found")
    assert "Traceback" not in r.stderr


def test_cli_url_root(tree: Path):
    head = tree / "models" / "head.wrl"
    r = vtts("check", str(head))
    assert r.returncode == 1 and f"{head}:3:54: error:" in r.stderr and "--url-root" in r.stderr
    r = vtts("check", "--url-root", str(tree), str(head))
    assert r.returncode == 0 and r.stdout.startswith(f"OK {head}"), r.stderr
    r = vtts("check", str(head), env={"VTTS_URL_ROOT": str(tree)})
    assert r.returncode == 0, r.stderr
    r = vtts("info", "--lenient", str(head))
    assert r.returncode == 0 and "warning: ImageTexture.url '../textures/skin.png'" in r.stderr
    r = vtts("check", "--url-root", str(tree / "nope"), str(head))
    assert r.returncode == 1 and "is not a folder" in r.stderr and "Traceback" not in r.stderr


def test_render_uses_the_texture_under_the_root(tree: Path):
    """The texture under the url root reaches the image: the triangle is skin-coloured."""
    from PIL import Image

    head = tree / "models" / "head.wrl"
    out = tree / "out.png"
    r = vtts("render", "--model", str(head), "--url-root", str(tree), "-o", str(out))
    assert r.returncode == 0, r.stderr
    pixels = np.asarray(Image.open(out).convert("RGB")).reshape(-1, 3).astype(int)
    skin = np.array([200, 120, 90])
    assert (np.abs(pixels - skin).sum(axis=1) < 120).any()
