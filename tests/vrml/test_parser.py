"""Parsing: every field type, syntax and semantic errors with their places, lenient mode, limits
and url safety."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from vtts.errors import (
    VrmlLimitError,
    VrmlSemanticError,
    VrmlSyntaxError,
    VrmlUrlError,
    VttsError,
    VttsWarning,
)
from vtts.vrml import SFImage, parse

H = "#VRML V2.0 utf8\n"


def one(body: str):
    """Parse one node and return it."""
    return parse(H + body).roots[0]


# ---- values of every type --------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, field, expected",
    [
        ("Transform { translation 1 -2.5 3e2 }", "translation", np.array([1, -2.5, 300.0])),
        ("Transform { rotation 0 1 0 1.5708 }", "rotation", np.array([0, 1, 0, 1.5708])),
        ("Material { diffuseColor 1, 0.5, .25 }", "diffuseColor", np.array([1, 0.5, 0.25])),
        ("Material { shininess 0.7 }", "shininess", 0.7),
        ("Switch { whichChoice 0x10 }", "whichChoice", 16),
        ("TimeSensor { loop TRUE }", "loop", True),
        ("TimeSensor { startTime -1 }", "startTime", -1.0),
        ('WorldInfo { title "a \\"q\\" \\\\ é" }', "title", 'a "q" \\ é'),
        ('WorldInfo { info [ "x", "y" ] }', "info", ["x", "y"]),
        ('WorldInfo { info "single" }', "info", ["single"]),
        (
            "TextureCoordinate { point [ 0 0, 1 0, 1 1 ] }",
            "point",
            np.array([[0, 0], [1, 0], [1, 1.0]]),
        ),
        ("Coordinate { point 1 2 3 }", "point", np.array([[1, 2, 3.0]])),
        ("Coordinate { point [] }", "point", np.zeros((0, 3))),
        ("ScalarInterpolator { key [ 0 0.5 1 ] }", "key", np.array([0, 0.5, 1])),
        (
            "OrientationInterpolator { keyValue [ 0 0 1 0, 0 1 0 3.14 ] }",
            "keyValue",
            np.array([[0, 0, 1, 0], [0, 1, 0, 3.14]]),
        ),
        ("Color { color [ 1 0 0 0 1 0 ] }", "color", np.array([[1, 0, 0], [0, 1, 0.0]])),
    ],
)
def test_field_values(text, field, expected):
    value = one(text)[field]
    if isinstance(expected, np.ndarray):
        assert isinstance(value, np.ndarray)
        assert value.shape == expected.shape and np.array_equal(value, expected)
    else:
        assert value == expected and type(value) is type(expected)


def test_mfint32_is_an_int32_array_and_defaults_apply():
    n = one("IndexedFaceSet { coordIndex [ 0 1 2 -1, 2 3 0 -1 ] }")
    assert n["coordIndex"].dtype == np.int32
    assert n["coordIndex"].tolist() == [0, 1, 2, -1, 2, 3, 0, -1]
    assert n["solid"] is True and n["creaseAngle"] == 0.0 and n["coord"] is None
    assert "solid" not in n.fields  # only what the file sets is stored


def test_sfimage():
    img = one("PixelTexture { image 2 1 3 0xFF0000 0x00FF00 }")["image"]
    assert isinstance(img, SFImage)
    assert (img.width, img.height, img.components) == (2, 1, 3)
    assert img.pixels.tolist() == [0xFF0000, 0x00FF00]
    assert img.to_rgba()[0, 0].tolist() == [255, 0, 0, 255]


def test_comments_and_commas_are_whitespace():
    n = one("Transform { # a comment\n translation 1, 2, # inside\n 3 }")
    assert n["translation"].tolist() == [1, 2, 3]


def test_numeric_arrays_are_built_without_python_objects_per_number():
    pts = " ".join(f"{i} {i + 0.5} -{i}" for i in range(2000))
    n = one(f"Coordinate {{ point [ {pts} ] }}")
    assert n["point"].shape == (2000, 3) and n["point"].dtype == np.float64


# ---- header and syntax errors ----------------------------------------------------------------


def test_vrml1_is_refused_clearly():
    with pytest.raises(VrmlSyntaxError, match="VRML 1.0 is not supported"):
        parse("#VRML V1.0 ascii\nSeparator {}")


@pytest.mark.parametrize("text", ["", "Group {}", "#VRML V2.0 utf16\n", "#X3D V3.0 utf8\n"])
def test_missing_header(text):
    with pytest.raises(VrmlSyntaxError, match="header") as info:
        parse(text)
    assert info.value.line == 1


def test_syntax_error_has_file_line_column_and_caret():
    with pytest.raises(VrmlSyntaxError) as info:
        parse(H + "Group {\n  children [ Shape { } \n}\n", file="x.wrl")
    e = info.value
    assert (e.file, e.line, e.column) == ("x.wrl", 4, 1)
    assert "unexpected '}'" in e.message and "']'" in e.message
    assert e.context.splitlines()[-1].strip() == "^"
    assert str(e).startswith("x.wrl:4:1: ")


def test_unexpected_end_of_file():
    with pytest.raises(VrmlSyntaxError, match="unexpected end of file"):
        parse(H + "Group { children [")


def test_invalid_utf8_is_located():
    with pytest.raises(VrmlSyntaxError, match="invalid UTF-8") as info:
        parse(H.encode() + b'WorldInfo { title "\xff" }')
    assert (info.value.line, info.value.column) == (2, 20)


@pytest.mark.parametrize(
    "body, fragment, line, column",
    [
        ("Transform { translation 1 2 }", "expects SFVec3f (3 numbers), got 2 numbers", 2, 25),
        ("Transform {\n translation 1 2 3.4.5 }", "'3.4.5' is not a number", 3, 18),
        ("Coordinate { point [ 1 2 3 4 ] }", "a multiple of 3 numbers, got 4", 2, 22),
        ("Switch { whichChoice 1.5 }", "'1.5' is not an integer", 2, 22),
        ("IndexedFaceSet { coordIndex [ 0 1 99999999999 ] }", "is not an integer in", 2, 35),
        ("TimeSensor { loop 1 }", "expects SFBool, got a number", 2, 19),
        ("WorldInfo { title 5 }", "expects SFString, got a number", 2, 19),
        ("Transform { translation [ 1 2 3 ] }", "a single value, not a '[ ]' list", 2, 27),
        ("Shape { geometry Material {} }", "takes a geometry node; Material is a material", 2, 18),
        ("Group { children [ Box {} ] }", "takes a child node; Box is a geometry node", 2, 20),
        ("Group { frobnicate 1 }", "Group has no field 'frobnicate'", 2, 9),
        ("Group { children [] children [] }", "given twice", 2, 21),
        ("Group { children USE X }", "USE of undefined name 'X'", 2, 22),
        ("Group { eventIn SFBool x }", "only PROTO interfaces and Script nodes", 2, 9),
        ("Script { field SFFoo x 1 }", "unknown field type 'SFFoo'", 2, 16),
        ("Script { eventIn SFBool a eventIn SFBool a }", "'a' is declared twice", 2, 42),
        ("PROTO P [] { }", "has no node in its body", 2, 7),
        ("PixelTexture { image 2 2 1 0 0 0 }", "needs 4 pixels, got 3", 2, 22),
        ("PixelTexture { image 1 1 1 0x1FF }", "more than 1 component byte", 2, 22),
        (
            "PROTO P [ field SFBool b TRUE ] { Group { children IS nope } } ",
            "PROTO P has no interface member 'nope'",
            2,
            55,
        ),
        (
            "DEF A TimeSensor {} DEF B Transform {} ROUTE A.fraction_changed TO B.set_translation",
            "SFFloat eventOut to an SFVec3f eventIn",
            2,
            46,
        ),
        ("DEF A TimeSensor {} ROUTE A.nothing TO A.set_x", "has no eventOut 'nothing'", 2, 29),
        ("ROUTE A.x TO B.y", "ROUTE names 'A', which is not DEFed", 2, 7),
    ],
)
def test_semantic_errors_name_rule_and_place(body, fragment, line, column):
    with pytest.raises(VrmlSemanticError) as info:
        parse(H + body, file="f.wrl")
    e = info.value
    assert fragment in e.message
    assert (e.line, e.column) == (line, column), str(e)


# ---- PROTO, Script, ROUTE ---------------------------------------------------------------------


def test_proto_instance_defaults_and_is():
    scene = parse(
        H
        + """
PROTO Box2 [ field SFVec3f size 2 2 2  exposedField SFColor c 1 0 0 ] {
  Shape {
    appearance Appearance { material Material { diffuseColor IS c } }
    geometry Box { size IS size }
  }
}
DEF A Box2 {}
DEF B Box2 { size 1 2 3 }
"""
    )
    a, b = scene.node("A").expand(), scene.node("B").expand()
    assert a.type.name == "Shape"
    assert a["geometry"]["size"].tolist() == [2, 2, 2]
    assert b["geometry"]["size"].tolist() == [1, 2, 3]
    assert b["appearance"]["material"]["diffuseColor"].tolist() == [1, 0, 0]
    # the PROTO's role is its first node's: a Box2 is a child node
    parse(H + "PROTO P [] { Box {} } Shape { geometry P {} }")
    with pytest.raises(VrmlSemanticError, match="takes a child node"):
        parse(H + "PROTO P [] { Box {} } Group { children P {} }")


def test_routes_resolve_exposedfield_events():
    scene = parse(
        H + "DEF T TimeSensor {} DEF I PositionInterpolator {} DEF X Transform {}\n"
        "ROUTE T.fraction_changed TO I.set_fraction\n"
        "ROUTE I.value_changed TO X.set_translation\n"
        "ROUTE X.translation_changed TO X.translation\n"
    )
    assert [r.to_event for r in scene.routes] == ["set_fraction", "set_translation", "translation"]


def test_script_interface():
    s = one('Script { eventIn SFFloat f eventOut SFVec3f v field SFInt32 n 3 url "javascript:" }')
    assert s["n"] == 3 and s["url"] == ["javascript:"]
    assert [d.name for d in s.script_decls] == ["f", "v", "n"]


def test_externproto_instances_keep_their_fields():
    n = parse(H + 'EXTERNPROTO E [ field SFFloat w ] "urn:x" E { w 2 }').roots[0]
    assert n["w"] == 2.0 and n.expand() is n


# ---- lenient mode ------------------------------------------------------------------------------


def test_unknown_node_is_an_error_unless_lenient():
    text = (
        H + 'Group { children [ VendorNode { gain 1.5 tags [ "a" ] on TRUE kids [ Group {} ] } ] }'
    )
    with pytest.raises(VrmlSemanticError, match="unknown node type 'VendorNode'"):
        parse(text)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = parse(text, lenient=True)
    assert any(
        isinstance(w.message, VttsWarning) and "VendorNode" in str(w.message) for w in caught
    )
    vendor = scene.roots[0]["children"][0]
    assert vendor.type.kind == "generic"
    assert vendor["gain"].tolist() == [1.5] and vendor["tags"] == ["a"] and vendor["on"] is True
    from vtts.vrml import dumps

    with pytest.warns(VttsWarning):
        assert parse(dumps(scene), lenient=True) == scene


# ---- limits and urls ---------------------------------------------------------------------------


def test_nesting_depth_limit_is_a_clear_error():
    deep = "Group { children [ " * 5000 + "]}" * 5000
    with pytest.raises(VrmlLimitError, match="nest deeper than the limit"):
        parse(H + deep)
    parse(H + "Group { children [ " * 50 + "]}" * 50)


def test_size_limit():
    with pytest.raises(VrmlLimitError, match="more than the limit"):
        parse((H + "Group {}\n" * 100).encode(), max_bytes=100)


@pytest.mark.parametrize(
    "url, ok",
    [
        ("tex.png", True),
        ("sub/tex.png", True),
        ("sub/../tex.png", True),
        ("http://example.com/tex.png", True),  # kept as data, never fetched
        ("urn:x", True),
        ("../tex.png", False),
        ("sub/../../tex.png", False),
        ("/etc/passwd", False),
        ("file:///etc/passwd", False),
        ("C:\\\\tex.png", False),
        ("..\\\\tex.png", False),
    ],
)
def test_url_fields_stay_inside_the_folder(url, ok):
    text = H + f'Shape {{ appearance Appearance {{ texture ImageTexture {{ url "{url}" }} }} }}'
    if ok:
        parse(text)
    else:
        with pytest.raises(VrmlUrlError, match="inside the folder"):
            parse(text, file="/tmp/model.wrl")


def test_anchor_urls_are_links_not_loads():
    parse(H + 'Anchor { url "../elsewhere.wrl" }')


def test_resolve_url_follows_links_only_inside(tmp_path):
    from vtts.vrml import resolve_url

    (tmp_path / "in.png").write_bytes(b"x")
    outside = tmp_path.parent / f"{tmp_path.name}-outside.png"
    outside.write_bytes(b"x")
    (tmp_path / "link.png").symlink_to(outside)
    assert resolve_url(["http://x/a.png", "in.png"], tmp_path) == (tmp_path / "in.png").resolve()
    assert resolve_url(["link.png"], tmp_path) is None
    assert resolve_url(["missing.png"], tmp_path) is None


def test_every_error_is_a_vtts_error():
    for cls in (VrmlSyntaxError, VrmlSemanticError, VrmlLimitError, VrmlUrlError):
        assert issubclass(cls, VttsError)


@pytest.mark.parametrize(
    "text",
    [
        "PROTO P [ exposedField MFString u [] ] { ImageTexture { url IS u } }\n"
        'Shape { appearance Appearance { texture P { u "/etc/passwd" } } }',
        'PROTO P [ exposedField MFString u [ "../../secret.png" ] ] { ImageTexture { url IS u } }',
        "PROTO P [ exposedField MFString u [] ] { ImageTexture { url IS u } }\n"
        "PROTO Q [ field MFString v [] ] { P { u IS v } }\n"
        'Shape { appearance Appearance { texture Q { v "../x.png" } } }',
    ],
)
def test_urls_reaching_a_loader_through_proto_are_checked(text):
    with pytest.raises(VrmlUrlError, match="inside the folder"):
        parse(H + text, file="/tmp/m.wrl")


def test_lenient_mixed_values_name_the_field():
    with pytest.warns(VttsWarning, match="field 'odd' of Vendor mixes kinds of values.*skipped"):
        scene = parse(H + 'Vendor { odd [ 1 "a" ] even 2 }', lenient=True)
    assert set(scene.roots[0].fields) == {"even"}
