"""A neck that follows the head's rotation only near the skull (:mod:`vtts.fit.neck`)."""

from __future__ import annotations

import copy
import shutil

import numpy as np
import pytest

from vtts.analysis.geometry import HeadGeometry
from vtts.cli import main
from vtts.errors import FitError
from vtts.face import N_PARAMS, FaceModel, load_model
from vtts.face.adt import format_adt
from vtts.face.miap import Miap
from vtts.fit.neck import BORDERS, HEAD_ROTATIONS, NECK, free_neck, neck_weights
from vtts.resources import models_dir
from vtts.vrml import dumps, standard_node_types


@pytest.fixture(scope="module")
def heads():
    """cybatt as bundled, and a copy with its neck freed."""
    bundled = load_model("cybatt")
    memo = {id(t): t for t in standard_node_types().values()}
    scene = copy.deepcopy(bundled.scene, memo)
    tables = copy.deepcopy(bundled.tables)
    free_neck(scene, tables)
    return bundled, FaceModel(scene, tables, bundled.path)


def _neck(model: FaceModel, params: np.ndarray) -> np.ndarray:
    """The neck's Coordinate points in the world (model at the origin) for ``params``."""
    g = HeadGeometry(model, (48, 49, 50), np.eye(4))
    world = g.positions(params, np.zeros(3))
    for s in g.shapes:
        if s.node.name == NECK:
            pts = np.zeros((s.mesh.coord_index.max() + 1, 3))
            pts[s.mesh.coord_index] = world[s.first_vertex : s.first_vertex + len(s.mesh.positions)]
            return pts
    raise AssertionError("no neck drawn")


def test_the_weight_falls_from_one_at_the_skull_to_zero_at_the_collar():
    y = np.array([-1.35, -1.2, -1.0, -0.8, -0.6])
    w = neck_weights(np.c_[np.zeros(5), y, np.zeros(5)], pivot_y=-0.8)
    assert w[0] == 0 and w[3] == 1 and w[4] == 1
    assert np.all(np.diff(w) >= 0) and 0 < w[1] < w[2] < 1
    with pytest.raises(FitError, match="pivot"):
        neck_weights(np.c_[np.zeros(5), y, np.zeros(5)], pivot_y=-1.5)


@pytest.mark.parametrize("number", sorted(HEAD_ROTATIONS))
@pytest.mark.parametrize("value", [20_000.0, -35_000.0, 7_000.0])
def test_the_collar_stays_and_the_top_turns_as_the_head(heads, number, value):
    bundled, freed = heads
    params = np.zeros(N_PARAMS)
    params[number - 1] = value
    rest = bundled.neutral_points(NECK)
    before = _neck(bundled, params)  # the whole neck inside the head's Transforms
    after = _neck(freed, params)
    collar = rest[:, 1] == rest[:, 1].min()
    top = rest[:, 1] >= -0.8 + 1e-9  # at and above the pivot: the skull's inside
    assert collar.sum() >= 8 and top.sum() >= 8
    assert np.abs(before[collar] - rest[collar]).max() > 0.01  # it used to swing
    assert np.array_equal(after[collar], rest[collar])
    # the top moves as the head does: exactly at the tables' borders, within the chord of a
    # 0.1 rad arc between them (r · 0.1² / 8 at r < 0.7)
    tol = 1e-7 if value in BORDERS else 1e-3  # the tables are written to 1e-12 a unit
    assert np.abs(after[top] - before[top]).max() < tol
    assert np.abs(after[top] - rest[top]).max() > 0.01
    # in between, a part of the motion
    mid = (~collar) & (~top)
    moved = np.linalg.norm(after[mid] - rest[mid], axis=1)
    full = np.linalg.norm(before[mid] - rest[mid], axis=1)
    assert np.all(moved <= full + 1e-3) and np.any(moved < 0.9 * full)


def test_the_neck_leaves_the_head_transforms_and_the_bundled_head_is_unchanged(heads):
    bundled, freed = heads
    for model, inside in ((bundled, True), (freed, False)):
        for shape, _, path in model.scene.shapes():
            geom = shape["geometry"]
            if geom is not None and geom.expand().name == NECK:
                assert any(n.name == "HEAD_ROLL" for n in path) is inside
    assert NECK not in load_model("cybatt").tables.mesh_nodes()
    for number in HEAD_ROTATIONS:
        (table,) = [m for m in freed.tables.adts[Miap("fap", number)].meshes if m.node == NECK]
        assert np.array_equal(table.borders, BORDERS)
    # freed once, it is not inside the head's Transforms any more
    memo = {id(t): t for t in standard_node_types().values()}
    with pytest.raises(FitError, match="not drawn inside"):
        free_neck(copy.deepcopy(freed.scene, memo), copy.deepcopy(freed.tables))


def test_the_written_head_passes_check_and_loads_the_same(heads, tmp_path, capsys):
    _, freed = heads
    wrl = tmp_path / "neck.wrl"
    wrl.write_text(dumps(freed.scene), encoding="utf-8")
    wrl.with_suffix(".adt").write_text(format_adt(freed.tables), encoding="utf-8")
    shutil.copy(models_dir() / "cybatt-face.png", tmp_path)
    assert main(["check", str(wrl)]) == 0
    assert capsys.readouterr().out.startswith(f"OK {wrl}")
    back = load_model(str(wrl))
    params = np.zeros(N_PARAMS)
    params[47], params[48] = 12_345.0, -6_789.0
    assert np.allclose(_neck(back, params), _neck(freed, params), atol=1e-6)


def test_the_renderer_draws_the_collar_still_while_the_head_nods(heads):
    """The decoder's view (the renderer deforms the model by its tables): under a nod the
    collar's pixels stay as they were at rest, while the bundled head's neck swings."""
    from vtts.render import FaceRenderer

    bundled, freed = heads
    nod = np.zeros(N_PARAMS)
    nod[47] = 15_000.0  # 0.15 rad
    images = {}
    for label, model in (("bundled", bundled), ("freed", freed)):
        with FaceRenderer(model, size=(160, 120)) as r:
            rest, numbers = r.render(np.zeros(N_PARAMS), triangles=True)
            images[label] = r.render(nod).astype(np.float64)
            neck = np.zeros(numbers.shape, bool)
            for node, first, n in r.triangle_sets:
                if node.name == NECK:
                    neck |= (numbers >= first) & (numbers < first + n)
    rows = np.flatnonzero(neck.any(axis=1))
    collar = neck & (np.arange(neck.shape[0])[:, None] >= rows[-1] - 3)
    assert collar.sum() >= 10
    still = np.abs(images["freed"] - rest)[collar].mean()
    swung = np.abs(images["bundled"] - rest)[collar].mean()
    assert still < 1.0 < 2.0 < swung, (still, swung)  # measured: 0.5 and 3.6 gray levels
