"""The ADI round trip (issue 3): deform a model with known tables, export the phases, rebuild
the tables with ``adi build``, and get the same tables and the same deformed vertices at values
between and beyond the borders, negative ones included."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from adt_tools.build import build_tables, load_poses
from adt_tools.cli import main
from vtts.face import AnimationTables, FaceModel, Miap, load_model, read_adt
from vtts.vrml import read

from .adi_helpers import (
    SAMPLE,
    face_points,
    face_triangles,
    params_for,
    write_gltf,
    write_obj,
    write_ply,
)

#: MIAP → values to compare the original and rebuilt models at: inside the intervals, at the
#: borders, beyond them, and negative.
PROBES: dict[str, list[float]] = {
    "stretch_l_cornerlip": [-2500, -1000, -400, 0, 1, 300, 1000, 1700],
    "close_t_l_eyelid": [-300, -1, 100, 512, 700, 1024, 2000],
    "head_pitch": [-40000, -5000, 7000, 50000],
    "head_yaw": [-30000, 1234, 90000],
    "viseme3": [-0.5, 0.3, 1, 1.5],
    "joy": [-1, 0.25, 0.5, 0.75, 1, 1.4],
}


def assert_same_tables(got: AnimationTables, want: AnimationTables, atol: float = 1e-12) -> None:
    assert sorted(got.adts, key=lambda m: m.index) == sorted(want.adts, key=lambda m: m.index)
    for miap, w in want.adts.items():
        g = got.adts[miap]
        assert [m.node for m in g.meshes] == [m.node for m in w.meshes], miap
        for gm, wm in zip(g.meshes, w.meshes, strict=True):
            assert np.array_equal(gm.borders, wm.borders), (miap, gm.borders, wm.borders)
            assert np.array_equal(gm.vertices, wm.vertices), (miap, gm.vertices, wm.vertices)
            np.testing.assert_allclose(gm.displacements, wm.displacements, atol=atol, rtol=0)
        key = lambda t: (t.node, t.field)  # noqa: E731
        assert sorted(map(key, g.transforms)) == sorted(map(key, w.transforms)), miap
        for gt, wt in zip(
            sorted(g.transforms, key=key), sorted(w.transforms, key=key), strict=True
        ):
            np.testing.assert_allclose(gt.neutral, wt.neutral, atol=1e-12)
            np.testing.assert_allclose(gt.unit, wt.unit, rtol=1e-9)


def assert_same_motion(got: FaceModel, want: FaceModel, atol: float = 1e-10) -> None:
    for key, values in PROBES.items():
        for f in values:
            p = params_for(want, key, f)
            a, b = got.deform(p), want.deform(p)
            np.testing.assert_allclose(
                a.points["FACE_MESH"],
                b.points["FACE_MESH"],
                atol=atol,
                rtol=0,
                err_msg=f"{key} = {f}",
            )
            assert a.transforms.keys() == b.transforms.keys()
            for node, fields in b.transforms.items():
                for fld, value in fields.items():
                    np.testing.assert_allclose(
                        a.transforms[node][fld],
                        value,
                        atol=1e-12,
                        err_msg=f"{key} = {f}: {node}.{fld}",
                    )


def rebuilt_model(tmp_path: Path, adt: Path) -> FaceModel:
    """The neutral scene with the rebuilt tables as a sidecar."""
    shutil.copy(SAMPLE, tmp_path / "rebuilt.wrl")
    shutil.copy(adt, tmp_path / "rebuilt.adt")
    return load_model(tmp_path / "rebuilt.wrl")


def test_round_trip_through_adi_build(model, neutral_wrl, phase_files, tmp_path, capsys):
    out = tmp_path / "model.adt"
    rc = main(["build", str(neutral_wrl), *map(str, phase_files), "-o", str(out)])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert captured.out.strip() == f"wrote {out}: 6 MIAPs, 2 nodes"
    assert captured.err == ""
    assert_same_tables(read_adt(out), model.tables)
    assert_same_motion(rebuilt_model(tmp_path, out), model)


def test_exact_exports_give_the_same_adt_text(model, neutral_wrl, phase_files, tmp_path):
    """Rounding away the float noise of subtraction makes the rebuilt tables exactly the
    original ones."""
    out = tmp_path / "model.adt"
    assert main(["build", str(neutral_wrl), *map(str, phase_files), "-o", str(out)]) == 0
    assert read_adt(out) == model.tables


def test_round_trip_embedded(model, neutral_wrl, phase_files, tmp_path, capsys):
    out = tmp_path / "embedded.wrl"
    rc = main(["build", str(neutral_wrl), *map(str, phase_files), "-o", str(out), "--embed"])
    assert rc == 0, capsys.readouterr().err
    assert not out.with_suffix(".adt").exists()
    embedded = load_model(out)
    assert embedded.scene.find("FaceDefTables") == []
    assert read(out).find("FaceDefTables")
    assert_same_tables(embedded.tables, model.tables)
    assert_same_motion(embedded, model)


def test_one_phase_of_a_fap_gives_one_interval(model, neutral_wrl, phase_files):
    """A linear motion needs one export: borders 0 and the amplitude, extended both ways."""
    neutral = read(neutral_wrl)
    pose = load_poses(next(f for f in phase_files if f.name == "close_t_l_eyelid@512.wrl"), neutral)
    tables = build_tables(neutral, pose)
    (table,) = tables.adts[Miap.parse("close_t_l_eyelid")].meshes
    assert table.borders.tolist() == [0, 512]
    want = face_points(model, "close_t_l_eyelid", 512) - face_points(model)
    np.testing.assert_allclose(table.displacement(512), want[table.vertices], atol=1e-12)
    np.testing.assert_allclose(table.displacement(-256), -want[table.vertices] / 2, atol=1e-12)


@pytest.mark.parametrize(
    "tolerance, kept", [(0.0, [20, 21, 22]), (0.02, [20, 21]), (0.16, [20]), (1.0, None)]
)
def test_tolerance_leaves_out_vertices_that_barely_move(
    model, neutral_wrl, phase_files, tolerance, kept
):
    # farthest moves: vertex 20 by 0.2048 (at 1024), 21 by 0.1537 (at 1024), 22 by 0.01536 (512)
    neutral = read(neutral_wrl)
    poses = [
        p
        for f in phase_files
        if f.name.startswith("close_t_l_eyelid")
        for p in load_poses(f, neutral)
    ]
    if kept is None:
        with pytest.warns(UserWarning, match="move nothing"):
            tables = build_tables(neutral, poses, tolerance)
        assert not tables.adts
        return
    tables = build_tables(neutral, poses, tolerance)
    (table,) = tables.adts[Miap.parse("close_t_l_eyelid")].meshes
    assert table.vertices.tolist() == kept


# ---- meshes: OBJ, PLY, glTF ----------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["obj", "obj-plain", "ply", "glb-pose"])
def test_mesh_poses_round_trip(model, neutral_wrl, tmp_path, fmt):
    """Each phase of the FAP, viseme and expression tables as a mesh file."""
    tri = face_triangles(model)
    files = []
    for key, amps in {
        "stretch_l_cornerlip": [-1000, 1000],
        "close_t_l_eyelid": [512, 1024],
        "viseme3": [1],
        "joy": [0.5, 1],
    }.items():
        for a in amps:
            pts = face_points(model, key, a)
            path = tmp_path / f"{key}@{a:g}.{fmt[:3]}"
            if fmt.startswith("obj"):
                write_obj(path, pts, tri, uv=fmt == "obj")
            elif fmt == "ply":
                write_ply(path, pts, tri)
            else:
                write_gltf(path, [(None, pts, tri, {})])
            files.append(path)
    out = tmp_path / "mesh.adt"
    assert (
        main(["build", str(neutral_wrl), *map(str, files), "-o", str(out), "--tolerance", "1e-5"])
        == 0
    )
    got = read_adt(out)
    # float32 files (PLY, glTF) carry ~1e-8 of noise per coordinate
    atol = 1e-12 if fmt.startswith("obj") else 1e-7
    want = AnimationTables({m: a for m, a in model.tables.adts.items() if m.number not in (48, 49)})
    for adt in want.adts.values():
        adt.transforms = []  # mesh files carry no Transforms
    assert_same_tables(got, want, atol=atol)


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
@pytest.mark.parametrize("sparse", [False, True])
def test_gltf_morph_targets_named_after_miaps(model, neutral_wrl, tmp_path, suffix, sparse):
    base = face_points(model)
    targets = {
        "stretch_l_cornerlip@-1000": face_points(model, "stretch_l_cornerlip", -1000) - base,
        "stretch_l_cornerlip@1000": face_points(model, "stretch_l_cornerlip", 1000) - base,
        "close_t_l_eyelid@512": face_points(model, "close_t_l_eyelid", 512) - base,
        "19@1024": face_points(model, "close_t_l_eyelid", 1024) - base,
        "viseme3": face_points(model, "viseme3", 1) - base,
        "joy@0.5": face_points(model, "joy", 0.5) - base,
        "smile": face_points(model, "joy", 1) - base,
    }
    path = write_gltf(
        tmp_path / f"head{suffix}",
        [("FACE_MESH", base, face_triangles(model), targets)],
        sparse=sparse,
    )
    neutral = read(neutral_wrl)
    poses = load_poses(path, neutral)
    assert [(p.miap.key, p.amplitude) for p in poses] == [
        ("6", -1000), ("6", 1000), ("19", 512), ("19", 1024), ("viseme 3", 1),
        ("expression 1", 0.5), ("expression 1", 1),
    ]  # fmt: skip
    assert poses[0].source == f"{path}#stretch_l_cornerlip@-1000"
    got = build_tables(neutral, poses, tolerance=1e-5)
    want = AnimationTables({m: a for m, a in model.tables.adts.items() if m.number not in (48, 49)})
    for adt in want.adts.values():
        adt.transforms = []
    assert_same_tables(got, want, atol=1e-7)


def test_gltf_targets_of_several_meshes_make_one_pose(model, tmp_path):
    """Two IndexedFaceSets, two glTF meshes named after them, one target name in both."""
    text = SAMPLE.read_text().replace("DEF FACE_MESH", "DEF FACE_MESH") + (
        "DEF TEETH Shape { geometry DEF TEETH_MESH IndexedFaceSet { coord Coordinate { "
        "point [ 0 0 0, 1 0 0, 0 1 0 ] } coordIndex [ 0 1 2 -1 ] } }\n"
    )
    (tmp_path / "two.wrl").write_text(text)
    neutral = read(tmp_path / "two.wrl")
    base = face_points(model)
    teeth = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    jaw = np.zeros((3, 3))
    jaw[:, 1] = -0.25
    path = write_gltf(
        tmp_path / "two.glb",
        [
            ("TEETH_MESH", teeth, np.array([[0, 1, 2]]), {"open_jaw@1000": jaw}),
            (
                "FACE_MESH",
                base,
                face_triangles(model),
                {"open_jaw@1000": face_points(model, "viseme3", 1) - base},
            ),
        ],
    )
    (pose,) = load_poses(path, neutral)
    assert sorted(pose.points) == ["FACE_MESH", "TEETH_MESH"]
    tables = build_tables(neutral, [pose])
    adt = tables.adts[Miap.parse("open_jaw")]
    assert [m.node for m in adt.meshes] == ["FACE_MESH", "TEETH_MESH"]
    np.testing.assert_allclose(adt.meshes[1].displacement(2000), jaw * 2, atol=1e-7)


def test_gltf_interleaved_and_quantized_accessors(tmp_path):
    """Positions interleaved with normals (byteStride 24) and a morph target stored as
    normalized int16 (KHR_mesh_quantization) read as plain float displacements."""
    import pygltflib as g

    from adt_tools.build import read_gltf_meshes

    base = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype="<f4")
    normals = np.tile(np.array([0, 0, 1], dtype="<f4"), (3, 1))
    interleaved = np.concatenate([base, normals], axis=1).tobytes()  # 3 × 24 bytes
    delta = np.array([[0, 0, 0], [0.5, 0, 0], [0, -0.25, 0]])
    quantized = np.round(delta * 32767).astype("<i2")
    quantized = np.concatenate([quantized, np.zeros((3, 1), "<i2")], axis=1).tobytes()  # pad 8 B
    blob = interleaved + quantized
    doc = g.GLTF2(
        meshes=[
            g.Mesh(
                name="M",
                extras={"targetNames": ["joy"]},
                primitives=[
                    g.Primitive(
                        attributes=g.Attributes(POSITION=0, NORMAL=1),
                        targets=[g.Attributes(POSITION=2)],
                    )
                ],
            )
        ],
        accessors=[
            g.Accessor(bufferView=0, componentType=g.FLOAT, count=3, type=g.VEC3),
            g.Accessor(bufferView=0, byteOffset=12, componentType=g.FLOAT, count=3, type=g.VEC3),
            g.Accessor(bufferView=1, componentType=g.SHORT, normalized=True, count=3, type=g.VEC3),
        ],
        bufferViews=[
            g.BufferView(buffer=0, byteOffset=0, byteLength=72, byteStride=24),
            g.BufferView(buffer=0, byteOffset=72, byteLength=24, byteStride=8),
        ],
        buffers=[g.Buffer(byteLength=len(blob))],
    )
    doc.set_binary_blob(blob)
    doc.save_binary(str(tmp_path / "q.glb"))
    (mesh,) = read_gltf_meshes(tmp_path / "q.glb")
    np.testing.assert_array_equal(mesh.base, base)
    np.testing.assert_allclose(mesh.targets["joy"], delta, atol=1e-4)
