"""Every rule of the ADI gives a clear error naming the file (and the node, where there is one)."""

from __future__ import annotations

import copy
import shutil
from pathlib import Path

import numpy as np
import pytest

from adt_tools.build import build_tables, load_pose, load_poses
from adt_tools.cli import main
from vtts.errors import AdtError
from vtts.face import FaceModel
from vtts.vrml import read, standard_node_types, write

from .adi_helpers import (
    SAMPLE,
    export_pose,
    face_points,
    face_triangles,
    with_worldinfo,
    write_gltf,
    write_obj,
)


def posed_scene(model: FaceModel, key: str | None = None, amplitude: float = 0.0):
    """A deep copy of the model's scene posed with one MIAP (neutral by default)."""
    if key is None:
        memo = {id(t): t for t in standard_node_types().values()}
        return copy.deepcopy(model.scene, memo)
    from .adi_helpers import params_for

    return model.posed_scene(model.deform(params_for(model, key, amplitude)))


def build_error(neutral: Path, *files: Path, node: str | None = None) -> AdtError:
    scene = read(neutral)
    with pytest.raises(AdtError) as info:
        poses = [p for f in files for p in load_poses(f, scene, node=node)]
        build_tables(scene, poses)
    return info.value


# ---- naming the MIAP and amplitude ---------------------------------------------------------------


@pytest.mark.parametrize(
    "name, miap, amplitude",
    [
        ("close_t_l_eyelid@1024.wrl", "19", 1024),
        ("19@-512.wrl", "19", -512),
        ("viseme3@1.wrl", "viseme 3", 1),
        ("viseme3.wrl", "viseme 3", 1),
        ("joy@0.5.wrl", "expression 1", 0.5),
        ("smile.wrl", "expression 1", 1),
        ("expression_sadness@0.75.wrl", "expression 2", 0.75),
        ("head_pitch@1e4.wrl", "48", 10000),
    ],
)
def test_file_names_name_the_miap_and_amplitude(
    model, neutral_wrl, tmp_path, name, miap, amplitude
):
    pose = load_pose(export_pose(model, "joy", 0.5, tmp_path / name), read(neutral_wrl))
    assert (pose.miap.key, pose.amplitude) == (miap, amplitude)


@pytest.mark.parametrize(
    "info, miap, amplitude",
    [
        ("miap 19 1024", "19", 1024),
        ("miap close_t_l_eyelid -300", "19", -300),
        ("miap viseme 3 1", "viseme 3", 1),
        ("miap viseme 3", "viseme 3", 1),
        ("miap viseme3 0.5", "viseme 3", 0.5),
        ("miap joy 1", "expression 1", 1),
        ("MIAP expression joy 0.25", "expression 1", 0.25),
    ],
)
def test_worldinfo_strings_name_the_miap_and_amplitude(
    model, neutral_wrl, tmp_path, info, miap, amplitude
):
    # the WorldInfo string wins over the file name
    path = tmp_path / "open_jaw@5.wrl"
    path.write_text(with_worldinfo(posed_scene(model, "joy", 1), info))
    pose = load_pose(path, read(neutral_wrl))
    assert (pose.miap.key, pose.amplitude) == (miap, amplitude)


@pytest.mark.parametrize(
    "name, message",
    [
        ("deformed.wrl", "no MIAP given: deformed.wrl has no WorldInfo"),
        ("close_eyes@1024.wrl", "unknown MIAP 'close_eyes' in file name close_eyes@1024.wrl"),
        ("joy@0.wrl", "amplitude 0 in file name joy@0.wrl"),
        ("19@-0.wrl", "amplitude 0 in file name 19@-0.wrl"),
        ("joy@lots.wrl", "amplitude 'lots' in file name joy@lots.wrl is not a number"),
        ("joy@inf.wrl", "is not finite"),
        ("close_t_l_eyelid.wrl", "names FAP MIAP 19 (close_t_l_eyelid) without an amplitude"),
        ("1@3.wrl", "unknown MIAP '1'"),
        ("viseme 15@1.wrl", "unknown MIAP 'viseme 15'"),
    ],
)
def test_bad_file_names(model, neutral_wrl, tmp_path, name, message):
    path = export_pose(model, "joy", 1, tmp_path / name)
    e = build_error(neutral_wrl, path)
    assert message in e.message
    assert e.file == str(path)


@pytest.mark.parametrize(
    "info, message",
    [
        ("miap frown 1", "unknown MIAP 'frown' in WorldInfo string 'miap frown 1'"),
        ("miap", "names no MIAP"),
        ("miap 19", "without an amplitude"),
        ("miap joy 0", "amplitude 0 in WorldInfo string"),
    ],
)
def test_bad_worldinfo_strings_give_file_and_line(model, neutral_wrl, tmp_path, info, message):
    path = tmp_path / "joy@1.wrl"
    text = with_worldinfo(posed_scene(model, "joy", 1), info)
    path.write_text(text)
    e = build_error(neutral_wrl, path)
    assert message in e.message and e.file == str(path)
    assert e.line == text.count("\n")  # the appended WorldInfo is the last line


def test_two_worldinfo_miap_strings(model, neutral_wrl, tmp_path):
    path = tmp_path / "x.wrl"
    path.write_text(
        with_worldinfo(posed_scene(model, "joy", 1), "miap joy 1")
        + 'WorldInfo { info [ "miap 19 20" ] }\n'
    )
    e = build_error(neutral_wrl, path)
    assert "2 WorldInfo 'miap' strings" in e.message and e.file == str(path)


def test_duplicate_amplitudes_name_both_files(model, neutral_wrl, tmp_path):
    a = export_pose(model, "close_t_l_eyelid", 1024, tmp_path / "close_t_l_eyelid@1024.wrl")
    b = tmp_path / "blink.wrl"
    b.write_text(with_worldinfo(posed_scene(model, "close_t_l_eyelid", 1024), "miap 19 1024.0"))
    e = build_error(neutral_wrl, a, b)
    assert "MIAP 19 (close_t_l_eyelid): amplitude 1024 is given twice" in e.message
    assert str(a) in e.message and str(b) in e.message


# ---- topology ------------------------------------------------------------------------------------


def test_mismatched_point_count(model, neutral_wrl, tmp_path):
    scene = posed_scene(model)
    coord = scene.node("FACE_MESH").expand()["coord"].expand()
    coord.fields["point"] = np.asarray(coord["point"])[:110]
    path = tmp_path / "joy@1.wrl"
    write(scene, path)
    e = build_error(neutral_wrl, path)
    assert e.message == (
        f"topology differs: FACE_MESH has 113 points in {neutral_wrl} but 110 in joy@1.wrl"
    )
    assert e.file == str(path) and e.line is not None


def test_changed_faces(model, neutral_wrl, tmp_path):
    scene = posed_scene(model)
    ifs = scene.node("FACE_MESH").expand()
    ci = np.array(ifs["coordIndex"])
    ci[[0, 1]] = ci[[1, 0]]
    ifs.fields["coordIndex"] = ci
    path = tmp_path / "joy@1.wrl"
    write(scene, path)
    e = build_error(neutral_wrl, path)
    assert "topology differs: the faces (coordIndex) of FACE_MESH in joy@1.wrl" in e.message


@pytest.mark.parametrize(
    "node, kind", [("FACE_MESH", "an IndexedFaceSet"), ("HEAD", "a Transform")]
)
def test_missing_def_name(model, neutral_wrl, tmp_path, node, kind):
    path = tmp_path / "joy@1.wrl"
    write(posed_scene(model, "joy", 1), path)
    path.write_text(path.read_text().replace(f"DEF {node} ", ""))
    e = build_error(neutral_wrl, path)
    assert f"has {kind} DEFed as {node} but joy@1.wrl has none" in e.message
    assert e.file == str(path)


def two_mesh_neutral(tmp_path: Path) -> Path:
    """The Candide scene with a second IndexedFaceSet of the same size (DEF COPY_MESH)."""
    text = SAMPLE.read_text()
    path = tmp_path / "two.wrl"
    path.write_text(
        text + "Transform { children Shape { geometry DEF COPY_MESH IndexedFaceSet "
        "{ coord USE FACE_COORD coordIndex [ 0 1 2 -1 ] } } }\n"
    )
    return path


def test_ambiguous_obj_needs_node(model, tmp_path):
    neutral = two_mesh_neutral(tmp_path)
    obj = write_obj(tmp_path / "joy@1.obj", face_points(model, "joy", 1), face_triangles(model))
    e = build_error(neutral, obj)
    assert e.message == (
        f"ambiguous: the mesh in joy@1.obj has 113 vertices, as have the IndexedFaceSets "
        f"FACE_MESH, COPY_MESH of {neutral}; name one with --node"
    )
    assert e.file == str(obj)
    (pose,) = load_poses(obj, read(neutral), node="COPY_MESH")
    assert list(pose.points) == ["COPY_MESH"]


def test_obj_of_no_size_in_the_neutral(model, neutral_wrl, tmp_path):
    obj = write_obj(
        tmp_path / "joy@1.obj", face_points(model, "joy", 1)[:100], face_triangles(model)[:10]
    )
    e = build_error(neutral_wrl, obj)
    assert "topology differs: the mesh in joy@1.obj has 100 vertices but no IndexedFaceSet" in (
        e.message
    )
    assert "FACE_MESH (113)" in e.message


@pytest.mark.parametrize(
    "node, message",
    [
        ("NOPE", "--node NOPE: "),
        ("FACE_MESH", "topology differs: FACE_MESH has 113 points in"),
    ],
)
def test_node_option_errors(model, neutral_wrl, tmp_path, node, message):
    obj = write_obj(
        tmp_path / "joy@1.obj", face_points(model, "joy", 1)[:100], face_triangles(model)[:10]
    )
    e = build_error(neutral_wrl, obj, node=node)
    assert message in e.message and e.file == str(obj)


def test_unknown_file_type(neutral_wrl, tmp_path):
    path = tmp_path / "joy@1.stl"
    path.write_text("solid x\nendsolid x\n")
    e = build_error(neutral_wrl, path)
    assert "unknown file type '.stl'" in e.message and e.file == str(path)


def test_bad_obj_vertex_line(neutral_wrl, tmp_path):
    path = tmp_path / "joy@1.obj"
    path.write_text("v 0 0 0\nv 1 zero 0\n")
    e = build_error(neutral_wrl, path)
    assert (e.file, e.line) == (str(path), 2)


# ---- glTF ----------------------------------------------------------------------------------------


def test_gltf_targets_need_names(model, neutral_wrl, tmp_path):
    base = face_points(model)
    path = write_gltf(
        tmp_path / "x.glb", [("FACE_MESH", base, face_triangles(model), {"joy": base * 0})]
    )
    import pygltflib

    doc = pygltflib.GLTF2.load(str(path))
    doc.meshes[0].extras = {}
    doc.save_binary(str(path))
    e = build_error(neutral_wrl, path)
    assert "mesh FACE_MESH has 1 morph targets but no target names" in e.message
    assert e.file == str(path)


def _hostile_gltf(model, tmp_path, change):
    import pygltflib

    base = face_points(model)
    path = write_gltf(
        tmp_path / "x.glb", [("FACE_MESH", base, face_triangles(model), {"joy@1": base * 0})]
    )
    doc = pygltflib.GLTF2.load(str(path))
    blob = doc.binary_blob()
    change(doc)
    doc.set_binary_blob(blob)
    doc.save_binary(str(path))
    return path


@pytest.mark.parametrize(
    "change, message",
    [
        # a count of 1e10 was allocated (5.2 GB) before anything checked it
        (
            lambda d: (
                setattr(d.accessors[0], "bufferView", None)
                or setattr(d.accessors[0], "count", 10**10)
            ),
            "count 10000000000 is more than the limit of 50000000",
        ),
        (lambda d: setattr(d.accessors[0], "count", -1), "count -1 is not an integer"),
        (
            lambda d: setattr(d.bufferViews[d.accessors[0].bufferView], "byteStride", -12),
            "byteStride -12 is not positive",
        ),
        (lambda d: setattr(d.accessors[0], "byteOffset", -4), "byteOffset must be an integer >= 0"),
    ],
)
def test_hostile_gltf_accessors_are_clear_errors(model, neutral_wrl, tmp_path, change, message):
    path = _hostile_gltf(model, tmp_path, change)
    e = build_error(neutral_wrl, path)
    assert message in e.message
    assert e.file == str(path)


@pytest.mark.parametrize(
    "target, message",
    [
        ("close_t_l_eyelid", "names FAP MIAP 19 (close_t_l_eyelid) without an amplitude"),
        ("wink@1", "unknown MIAP 'wink' in morph target name 'wink@1' of mesh FACE_MESH"),
        ("joy@0", "amplitude 0"),
    ],
)
def test_gltf_target_names_must_be_miaps(model, neutral_wrl, tmp_path, target, message):
    base = face_points(model)
    path = write_gltf(
        tmp_path / "x.glb",
        [("FACE_MESH", base, face_triangles(model), {target: face_points(model, "joy", 1) - base})],
    )
    e = build_error(neutral_wrl, path)
    assert message in e.message and e.file == str(path)


def test_gltf_base_must_be_the_neutral(model, neutral_wrl, tmp_path):
    base = face_points(model)
    moved = base[::-1].copy()  # same points, other order
    path = write_gltf(
        tmp_path / "x.glb", [("FACE_MESH", moved, face_triangles(model), {"joy": base * 0})]
    )
    e = build_error(neutral_wrl, path)
    assert "the base of glTF mesh FACE_MESH is not the neutral FACE_MESH" in e.message
    assert " is at " in e.message and "in the same vertex order" in e.message


def test_not_a_gltf(neutral_wrl, tmp_path):
    path = tmp_path / "x.glb"
    path.write_bytes(b"this is not glTF")
    e = build_error(neutral_wrl, path)
    assert "not a readable glTF file" in e.message and e.file == str(path)


def test_external_buffer_outside_the_folder(model, neutral_wrl, tmp_path):
    import pygltflib

    base = face_points(model)
    path = write_gltf(
        tmp_path / "x.gltf", [("FACE_MESH", base, face_triangles(model), {"joy": base * 0})]
    )
    doc = pygltflib.GLTF2.load(str(path))
    doc.buffers[0].uri = "../../etc/passwd"
    doc.save_json(str(path))
    e = build_error(neutral_wrl, path)
    assert "'../../etc/passwd' is not a file inside the glTF file's folder" in e.message


# ---- Transforms ----------------------------------------------------------------------------------

SCENE = """#VRML V2.0 utf8
DEF EYE Transform {{
  rotation {rotation}
  translation {translation}
  scale {scale}
  children Shape {{ geometry DEF BALL IndexedFaceSet {{
    coord Coordinate {{ point [ 0 0 0, 1 0 0, 0 1 0 ] }} coordIndex [ 0 1 2 -1 ] }} }}
}}
"""


def eye_scene(path: Path, rotation="0 1 0 0.5", translation="0 0 0", scale="1 1 1") -> Path:
    path.write_text(SCENE.format(rotation=rotation, translation=translation, scale=scale))
    return path


def eye_tables(tmp_path: Path, poses: dict[str, dict[str, str]], **neutral: str):
    n = eye_scene(tmp_path / "neutral.wrl", **neutral)
    files = [eye_scene(tmp_path / name, **{**neutral, **fields}) for name, fields in poses.items()]
    scene = read(n)
    return build_tables(scene, [load_pose(f, scene) for f in files])


def test_rotation_about_a_nonzero_neutral_angle(tmp_path):
    tables = eye_tables(
        tmp_path,
        {
            "yaw_l_eyeball@-10000.wrl": {"rotation": "0 1 0 0.4"},
            "yaw_l_eyeball@20000.wrl": {"rotation": "0 -1 0 -0.7"},
        },
    )
    (t,) = tables.adts[next(iter(tables.adts))].transforms
    assert (t.node, t.field) == ("EYE", "rotation")
    np.testing.assert_allclose(t.neutral, [0, 1, 0, 0.5])
    assert t.unit[0] == 1e-5


@pytest.mark.parametrize(
    "field, value, unit",
    [
        ("translation", "0 0.5 -1", [0, 0.001, -0.002]),
        ("scale", "1.5 1 1", [0.001, 0, 0]),
    ],
)
def test_translation_and_scale(tmp_path, field, value, unit):
    tables = eye_tables(tmp_path, {"joy@500.wrl": {field: value}})
    (t,) = tables.adts[next(iter(tables.adts))].transforms
    assert t.field == field
    np.testing.assert_allclose(t.unit, unit)


def test_rotation_axis_must_stay(tmp_path):
    with pytest.raises(AdtError) as info:
        eye_tables(tmp_path, {"yaw_l_eyeball@10000.wrl": {"rotation": "1 0 0 0.6"}})
    e = info.value
    assert e.message.startswith("Transform EYE: the rotation axis changes in MIAP 23")
    assert "its neutral axis 0 1 0 (neutral angle 0.5)" in e.message
    assert e.file == str(tmp_path / "yaw_l_eyeball@10000.wrl")


def test_rotation_axes_of_poses_must_agree_at_angle_zero(tmp_path):
    with pytest.raises(AdtError, match="axis 1 0 0 of the other poses"):
        eye_tables(
            tmp_path,
            {
                "head_pitch@1000.wrl": {"rotation": "1 0 0 0.01"},
                "head_pitch@2000.wrl": {"rotation": "0 0 1 0.02"},
            },
            rotation="0 0 1 0",
        )


@pytest.mark.parametrize(
    "field, a, b",
    [
        ("rotation", "0 1 0 0.6", "0 1 0 0.9"),
        ("translation", "0 0.1 0", "0 0.3 0"),
    ],
)
def test_transform_motion_must_be_linear(tmp_path, field, a, b):
    with pytest.raises(AdtError) as info:
        eye_tables(tmp_path, {"joy@0.5.wrl": {field: a}, "joy@1.wrl": {field: b}})
    e = info.value
    assert f"Transform EYE: {field} is not linear in MIAP expression 1 (joy)" in e.message
    assert "joy@0.5.wrl" in e.message and "joy@1.wrl" in e.message


def test_negative_tolerance(neutral_wrl):
    with pytest.raises(AdtError, match="tolerance must be a non-negative number"):
        build_tables(read(neutral_wrl), [], tolerance=-1)


def test_cli_prints_file_line_col_errors(model, neutral_wrl, tmp_path, capsys):
    path = tmp_path / "joy@1.wrl"
    text = with_worldinfo(posed_scene(model, "joy", 1), "miap frown 1")
    path.write_text(text)
    rc = main(["build", str(neutral_wrl), str(path), "-o", str(tmp_path / "m.adt")])
    err = capsys.readouterr().err
    assert rc == 1
    assert err.startswith(f"{path}:{text.count(chr(10))}: error: unknown MIAP 'frown'")
    assert not (tmp_path / "m.adt").exists()


def test_vrml_syntax_errors_pass_through(neutral_wrl, tmp_path, capsys):
    path = tmp_path / "joy@1.wrl"
    path.write_text("#VRML V2.0 utf8\nTransform { children [ }\n")
    assert main(["build", str(neutral_wrl), str(path), "-o", str(tmp_path / "m.adt")]) == 1
    assert capsys.readouterr().err.startswith(f"{path}:2:")


def test_sidecar_next_to_neutral_is_not_read(model_dir, tmp_path):
    """A neutral model with tables of its own: the ADI compares with its scene only."""
    shutil.copy(model_dir / "head.wrl", tmp_path / "head.wrl")
    shutil.copy(model_dir / "head.adt", tmp_path / "head.adt")
    scene = read(tmp_path / "head.wrl")
    assert not build_tables(scene, []).adts
