"""The ADI reads vtts's glTF back: its reader finds each IndexedFaceSet's neutral points and the
interval targets, and ``adi build`` on the export rebuilds mesh tables that deform the model as
the original tables do."""

from __future__ import annotations

import numpy as np
import pytest

from adt_tools.build import build_tables, load_poses, read_gltf_meshes
from vtts.errors import AdtError
from vtts.export import write_gltf
from vtts.face import N_PARAMS, FaceModel, load_model
from vtts.vrml import read

from .gltf_helpers import HEAD, sweep, write_rig


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    return load_model(write_rig(tmp_path_factory.mktemp("rig")))


def test_the_reader_sees_the_neutral_points_and_the_interval_targets(rig, tmp_path):
    path = write_gltf(tmp_path / "rig.glb", [rig], np.zeros((3, N_PARAMS)), 30.0)
    meshes = {m.name: m for m in read_gltf_meshes(path)}
    lip = meshes["LIP"]
    np.testing.assert_allclose(lip.base, rig.neutral_points("LIP"), atol=1e-7)
    block = rig.engine.meshes["LIP"]
    assert list(lip.targets) == [
        "FAP3_open_jaw#0", "FAP3_open_jaw#1", "FAP3_open_jaw#2", "viseme1#0", "joy#0", "joy#1",
    ]  # fmt: skip
    assert lip.intervals["FAP3_open_jaw#0"] == (0.0, -100.0)
    assert lip.intervals["joy#1"] == (0.5, 1.0)
    # a target is its column of the engine's matrix times the interval's length
    a = block.csr.toarray()
    for c, (name, delta) in enumerate(lip.targets.items()):
        start, end = lip.intervals[name]
        np.testing.assert_allclose(delta.reshape(-1), a[:, c] * (end - start), atol=1e-7)


@pytest.mark.parametrize("which", ["rig", "head", "cybatt"])
def test_adi_build_on_the_export_gives_back_the_mesh_tables(which, rig, tmp_path):
    model = {"rig": rig}.get(which) or load_model(HEAD if which == "head" else "cybatt")
    path = write_gltf(tmp_path / "x.glb", [model], np.zeros((2, N_PARAMS)), 30.0)
    neutral = read(model.path)
    tables = build_tables(neutral, load_poses(path, neutral))
    mesh_miaps = {m for m, adt in model.tables.adts.items() if adt.meshes}
    assert {m for m, adt in tables.adts.items() if adt.meshes} == mesh_miaps
    for miap in mesh_miaps:
        got = {t.node: t.borders.tolist() for t in tables.adts[miap].meshes}
        want = {t.node: t.borders.tolist() for t in model.tables.adts[miap].meshes}
        assert got == want, miap
    rebuilt = FaceModel(neutral, tables, model.path)
    params = sweep(model, n_frames=10, seed=11)
    for p in params:
        a, b = model.engine.deform(p), rebuilt.engine.deform(p)
        for name, pts in a.points.items():
            extent = float(np.ptp(pts, axis=0).max())
            # float32 storage and adi's tolerance (1e-6: vertices moving less are left out)
            assert np.abs(b.points[name] - pts).max() < 1e-6 * max(extent, 1.0) + 2e-6, name


def test_two_heads_read_but_do_not_build(rig, tmp_path):
    path = write_gltf(tmp_path / "two.gltf", [rig, rig], np.zeros((2, N_PARAMS)), 30.0)
    names = [m.name for m in read_gltf_meshes(path)]
    assert names.count("LIP") == 1  # one mesh, shown by both heads
    heads = [load_model(HEAD), load_model(HEAD)]  # two parses: two meshes named FACE_MESH
    path = write_gltf(tmp_path / "two.glb", heads, np.zeros((2, N_PARAMS)), 30.0)
    with pytest.raises(AdtError, match="map onto IndexedFaceSet FACE_MESH"):
        load_poses(path, read(HEAD))


def test_broken_vtts_extras_are_clear_errors(rig, tmp_path):
    path = write_gltf(tmp_path / "r.gltf", [rig], np.zeros((2, N_PARAMS)), 30.0)
    text = path.read_text(encoding="utf-8")
    bad = tmp_path / "bad.gltf"
    bad.write_text(text.replace('"points":10', '"points":99'), encoding="utf-8")
    with pytest.raises(AdtError, match="extras.vtts.points must be an integer within 0–"):
        read_gltf_meshes(bad)
    bad.write_text(text.replace('"intervals":[[0.0,-100.0]', '"intervals":[[1,1]'), "utf-8")
    with pytest.raises(AdtError, match=r"extras.vtts.intervals must give \[from, to\]"):
        read_gltf_meshes(bad)
    bad.write_text(text.replace("FAP3_open_jaw#0", "FAP3_close_jaw#0"), encoding="utf-8")
    with pytest.raises(AdtError, match="FAP 3 is open_jaw, not close_jaw"):
        load_poses(bad, read(rig.path))
