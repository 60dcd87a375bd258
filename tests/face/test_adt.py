"""The .adt text format, the embedded FaceDefTables form, and checking tables against a scene."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vtts.errors import AdtError, ModelError
from vtts.face import Miap, embed_tables, format_adt, load_model, parse_adt, tables_from_scene
from vtts.fap import AU
from vtts.vrml import parse, read, write

PAPER_TABLE_1 = """#AnimationDefinitionTables

MIAP 6 (stretch left corner lip)

IndexedFaceSet: Face

interval borders: -1000 0 1000

displacements:

vertex 50 -1 0 0 1 0 0

vertex 51 -1 0 0 1 0 0

MIAP 23 (yaw left eye ball)

Transform: LeftEyeX

rotation neutral value: 0 -1 0 (axis) 0 (angle)
"""


def test_the_papers_table_1_reads_as_written():
    t = parse_adt(PAPER_TABLE_1)
    assert list(t.adts) == [Miap("fap", 6), Miap("fap", 23)]
    mesh = t.adts[Miap("fap", 6)].meshes[0]
    assert mesh.node == "Face" and mesh.borders.tolist() == [-1000, 0, 1000]
    assert mesh.vertices.tolist() == [50, 51]
    assert mesh.displacements.shape == (2, 2, 3)
    assert mesh.displacements[0, 0].tolist() == [-1, 0, 0]
    rot = t.adts[Miap("fap", 23)].transforms[0]
    assert (rot.node, rot.field) == ("LeftEyeX", "rotation")
    assert rot.neutral.tolist() == [0, -1, 0, 0] and rot.unit.tolist() == [AU]


def test_format_is_exact_and_a_fixed_point(tables_text):
    t = parse_adt(tables_text)
    text = format_adt(t)
    assert parse_adt(text) == t
    assert format_adt(parse_adt(text)) == text
    assert t.temporal.expression("joy").onset == 0.5
    assert t.temporal.habit("blink").amplitude == 1024
    assert t.feature_points == {"3.5": ("FACE_MESH", 12)}


@pytest.mark.parametrize(
    "body, line, fragment",
    [
        (
            "MIAP 6\nIndexedFaceSet: F\ninterval borders: 1 2\ndisplacements:\n",
            5,
            "interval borders must include 0, got [1 2]",
        ),
        (
            "MIAP 6\nIndexedFaceSet: F\ninterval borders: 0 2 1\ndisplacements:\n",
            5,
            "interval borders must increase",
        ),
        (
            "MIAP 6\nIndexedFaceSet: F\ninterval borders: 0 2\ndisplacements:\nvertex 1 2 3\n",
            7,
            "needs the vertex index and 3 displacement values (3 per interval, 1 interval), got 2",
        ),
        (
            "MIAP 6\nIndexedFaceSet: F\ninterval borders: 0 2\ndisplacements:\nvertex 1 2 x 3\n",
            7,
            "'x' is not a number",
        ),
        (
            "MIAP 6\nIndexedFaceSet: F\ninterval borders: 0 2\ndisplacements:\n"
            "vertex 1 0 0 0\nvertex 1 0 0 0\n",
            8,
            "vertex 1 is listed twice",
        ),
        (
            "MIAP 6\nIndexedFaceSet: F\ninterval borders: 0 2\ndisplacements:\nvertex 1.5 0 0 0\n",
            7,
            "vertex index must be a non-negative integer",
        ),
        ("MIAP 99\nTransform: X\nrotation neutral value: 0 1 0 0\n", 3, "FAP 99"),
        ("MIAP 2\nTransform: X\nrotation neutral value: 0 1 0 0\n", 3, "not a MIAP"),
        (
            "MIAP viseme 15\nTransform: X\nrotation neutral value: 0 1 0 0\n",
            3,
            "viseme MIAP number must be 1–14",
        ),
        ("MIAP expression glee\nTransform: X\nrotation neutral value: 0 1 0 0\n", 3, "glee"),
        ("MIAP 6\nTransform: X\nscale neutral value: 1 1 1\n", 5, "needs a 'per unit:' line"),
        ("MIAP 6\nTransform: X\nrotation neutral value: 0 0 0 0\n", 5, "axis must not be 0 0 0"),
        ("MIAP 6\nIndexedFaceSet F\n", 4, "unexpected 'F'; expected ':'"),
        (
            "MIAP 6\nTransform: X\nrotation neutral value: 0 1 0 0\nMIAP 6\nTransform: X\n"
            "rotation neutral value: 0 1 0 0\n",
            6,
            "MIAP 6 (stretch_l_cornerlip) is defined twice",
        ),
    ],
)
def test_errors_name_the_line_and_rule(body, line, fragment):
    with pytest.raises(AdtError) as info:
        parse_adt("#AnimationDefinitionTables\n\n" + body, file="t.adt")
    e = info.value
    assert fragment in e.message
    assert (e.file, e.line) == ("t.adt", line), str(e)


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("#TemporalDefinitionTables\nblink: interval 4 foo 2\n", "unknown setting 'foo'"),
        ("#TemporalDefinitionTables\nexpression glee: onset 1\n", "'expression' needs one of"),
        ("#TemporalDefinitionTables\nwink: interval 1\n", "unknown temporal entry 'wink'"),
        ("#TemporalDefinitionTables\nexpression joy: shape wobbly\n", "shape must be one of"),
        ("#TemporalDefinitionTables\nexpression joy: onset -1\n", "non-negative"),
        ("#TemporalDefinitionTables\nblink: interval 0\n", "interval must be positive"),
        ("#TemporalDefinitionTables\nblink: interval 1 interval 2\n", "given twice"),
        ("#FeaturePoints\n3.5 F 1\n3.5 F 2\n", "feature point 3.5 is given twice"),
    ],
)
def test_temporal_and_feature_errors(text, fragment):
    with pytest.raises(AdtError) as info:
        parse_adt(text, file="t.adt")
    assert fragment in info.value.message and info.value.line is not None


def test_large_blocks_load_fast_as_arrays():
    rows = "\n".join(f"vertex {i} {i * 1e-4} 0 -1e-5 0 0 {i}" for i in range(20000))
    t = parse_adt(
        "#AnimationDefinitionTables\nMIAP 3\nIndexedFaceSet: F\ninterval borders: 0 10 20\n"
        "displacements:\n# a comment inside the block\n" + rows + "\n"
    )
    mesh = t.adts[Miap("fap", 3)].meshes[0]
    assert mesh.displacements.shape == (2, 20000, 3)
    assert mesh.displacements[1, 7].tolist() == [0, 0, 7]


def test_sidecar_and_embedded_load_to_the_same_model(model_dir: Path):
    side = load_model(model_dir / "head.wrl")
    embedded_scene = embed_tables(side.scene, side.tables)
    write(embedded_scene, model_dir / "embedded.wrl")
    emb = load_model(model_dir / "embedded.wrl")
    assert emb.tables == side.tables
    params = side.params({6: 300, 19: 700, 48: 5000}, visemes={1: 0.5}, expressions={"joy": 0.7})
    a, b = side.deform(params), emb.deform(params)
    for name in a.points:
        assert np.array_equal(a.points[name], b.points[name])
    assert a.transforms.keys() == b.transforms.keys()
    # the embedded form is plain VRML97 with MPEG-4 nodes
    scene = read(model_dir / "embedded.wrl")
    assert len(scene.find("FaceDefTables")) == len(side.tables.adts)
    assert tables_from_scene(scene) == side.tables


def test_tables_in_both_places_is_an_error(model_dir: Path, tables_text):
    model = load_model(model_dir / "head.wrl")
    write(embed_tables(model.scene, model.tables), model_dir / "both.wrl")
    (model_dir / "both.adt").write_text(tables_text)
    with pytest.raises(ModelError, match="must come from one place"):
        load_model(model_dir / "both.wrl")


@pytest.mark.parametrize(
    "change, fragment",
    [
        (("FACE_MESH", "NOPE", 1), "no node is DEFed as 'NOPE'"),
        (
            ("vertex 52 ", "vertex 999 ", 1),
            "vertex 999 is out of range for IndexedFaceSet FACE_MESH",
        ),
        (
            ("Transform: HEAD\nrotation", "Transform: FACE_MESH\nrotation", 1),
            "'FACE_MESH' is a IndexedFaceSet, not a Transform",
        ),
        (
            ("translation neutral value: 0 0 0", "translation neutral value: 0 1 0", 1),
            "neutral value of Transform HEAD is 0 1 0 in the tables but 0 0 0 in the scene",
        ),
        (("3.5 FACE_MESH 12", "3.5 FACE_MESH 500", 1), "feature point 3.5: vertex 500"),
    ],
)
def test_tables_are_checked_against_the_scene(model_dir: Path, tables_text, change, fragment):
    old, new, count = change
    (model_dir / "head.adt").write_text(tables_text.replace(old, new, count))
    with pytest.raises(AdtError) as info:
        load_model(model_dir / "head.wrl")
    assert fragment in info.value.message
    assert info.value.file.endswith("head.adt")


def test_embedded_table_errors_name_the_node_line():
    base = "#VRML V2.0 utf8\nDEF F IndexedFaceSet { coord Coordinate { point [ 0 0 0 ] } }\n"
    with pytest.raises(AdtError, match="need 2 displacements, got 1") as info:
        tables_from_scene(
            parse(
                base
                + "FaceDefTables { fapID 3 faceDefMesh [ FaceDefMesh { faceSceneGraphNode USE F "
                "intervalBorders [ 0 1 2 ] coordIndex [ 0 ] displacements [ 0 0 0 ] } ] }"
            )
        )
    assert info.value.line == 3
    with pytest.raises(AdtError, match="fieldId must be 1"):
        tables_from_scene(
            parse(
                "#VRML V2.0 utf8\nDEF T Transform {}\nFaceDefTables { fapID 48 faceDefTransform [ "
                "FaceDefTransform { faceSceneGraphNode USE T fieldId 7 } ] }"
            )
        )


def test_embedding_keeps_the_direction_of_an_opposite_axis_rotation(tmp_path):
    """A table written about (-axis, -angle) must turn the same way once embedded."""
    (tmp_path / "eye.wrl").write_text(
        "#VRML V2.0 utf8\nDEF EYE Transform { rotation 0 1 0 0.5 children Shape { geometry "
        "IndexedFaceSet { coord Coordinate { point [ 0 0 0, 1 0 0, 0 1 0 ] } coordIndex [ 0 1 2 ] "
        "} } }\n"
    )
    (tmp_path / "eye.adt").write_text(
        "#AnimationDefinitionTables\nMIAP 23\nTransform: EYE\n"
        "rotation neutral value: 0 -1 0 (axis) -0.5 (angle)\n"
    )
    model = load_model(tmp_path / "eye.wrl")
    want = model.deform({23: 10000}).transforms["EYE"]["rotation"]
    (tmp_path / "emb").mkdir()
    write(embed_tables(model.scene, model.tables), tmp_path / "emb" / "eye.wrl")
    got = load_model(tmp_path / "emb" / "eye.wrl").deform({23: 10000}).transforms["EYE"]["rotation"]
    assert np.allclose(got, want) and np.allclose(want, [0, 1, 0, 0.4])
