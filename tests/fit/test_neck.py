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
from vtts.fit.neck import (
    BORDERS,
    HEAD_ROTATIONS,
    NECK,
    collar_row,
    cut_neck,
    free_neck,
    neck_rings,
    neck_weights,
    skin_chroma,
)
from vtts.render.camera import Camera, look_at
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


# ---- the neck cut at the collar ---------------------------------------------------------------

SKIN = np.array([200.0, 150.0, 120.0])


def _picture(neck_rows: list[np.ndarray], seed: int = 0):
    """A 60 × 40 photo: a face of skin (rows 0–19), and a neck (columns 10–29) from row 20
    whose rows take the colours ``neck_rows``, with a little noise; and the two masks."""
    rng = np.random.default_rng(seed)
    photo = np.zeros((60, 40, 3))
    face = np.zeros((60, 40), bool)
    neck = np.zeros((60, 40), bool)
    face[:20, 5:35] = True
    photo[:20, 5:35] = SKIN * np.linspace(0.5, 1.0, 30)[None, :, None]  # shaded across
    for k, colour in enumerate(neck_rows):
        photo[20 + k, 10:30] = colour
        neck[20 + k, 10:30] = True
    photo = np.clip(photo + rng.normal(0, 3, photo.shape), 0, 255).astype(np.uint8)
    return photo, neck, face


def test_skin_chroma_does_not_change_with_brightness():
    bright, shadow = skin_chroma(SKIN), skin_chroma(SKIN * 0.5)
    assert np.abs(bright - shadow).max() < 2.5  # the constant in the sum: a level or two
    assert np.abs(skin_chroma(np.array([150.0, 20, 30])) - bright).max() > 40  # a red tie
    assert np.abs(skin_chroma(np.array([240.0, 240, 240])) - bright).max() > 15  # a white collar


def test_the_neck_ends_where_the_collar_begins():
    # skin under the chin in shadow, more skin, then a red bow tie
    rows = [SKIN * 0.45] * 5 + [SKIN] * 10 + [np.array([150.0, 20, 30])] * 15
    photo, neck, face = _picture(rows)
    assert collar_row(photo, neck, face) == 35
    # a white collar, as well
    rows = [SKIN] * 12 + [np.array([235.0, 235, 230])] * 8
    photo, neck, face = _picture(rows)
    assert collar_row(photo, neck, face) == 32


def test_a_neck_that_shows_skin_to_its_bottom_is_not_cut():
    photo, neck, face = _picture([SKIN] * 30)
    assert collar_row(photo, neck, face) is None
    # hair beside the jaw at the top of the drawn neck does not end it before it began
    rows = [np.array([25.0, 20, 18])] * 6 + [SKIN] * 24
    photo, neck, face = _picture(rows)
    assert collar_row(photo, neck, face) is None
    # nor do two rows of a necklace
    rows = [SKIN] * 12 + [np.array([235.0, 200, 40])] * 2 + [SKIN] * 16
    photo, neck, face = _picture(rows)
    assert collar_row(photo, neck, face) is None
    # a neck of rows too short to tell skin from clothes is left alone
    photo, neck, face = _picture([SKIN] * 2)
    assert collar_row(photo, neck, face) is None


def test_a_neck_covered_from_under_the_chin_ends_at_its_top():
    """A high collar (or a scarf) right under the chin: the neck shows no skin at all, and
    ends where it first shows (before stop 54 it was left whole, the collar painted on it)."""
    rows = [np.array([235.0, 235, 230])] * 10 + [np.array([40.0, 30, 35])] * 20
    photo, neck, face = _picture(rows)
    assert collar_row(photo, neck, face) == 20
    photo, neck, face = _picture([np.array([30.0, 30, 90])] * 30)
    assert collar_row(photo, neck, face) == 20
    # skin in no row on half of the neck, but on a third of each row: left whole
    photo, neck, face = _picture([np.array([30.0, 30, 90])] * 30)
    photo[20:50, 10:17] = SKIN
    assert collar_row(photo, neck, face) is None


def test_the_neck_is_rings_bottom_first(heads):
    bundled, _ = heads
    points = np.asarray(bundled.scene.node(NECK).expand()["coord"].expand()["point"])
    rings = neck_rings(points)
    assert rings.shape == (8, 32, 3)
    assert np.all(np.diff(rings[..., 1].mean(axis=1)) > 0)
    shuffled = points[np.random.default_rng(1).permutation(len(points))]
    with pytest.raises(FitError, match="not rings"):
        neck_rings(shuffled)


def _copy(scene):
    return copy.deepcopy(scene, {id(t): t for t in standard_node_types().values()})


def _front_camera() -> Camera:
    return Camera(400.0, 400.0, 176.0, 144.0, look_at(np.array([0.0, -0.6, 7.0]),
                                                      np.array([0.0, -0.6, 0.0])))  # fmt: skip


def test_the_cut_moves_the_lower_rings_up_to_the_collar(heads):
    bundled, _ = heads
    scene = _copy(bundled.scene)
    camera = _front_camera()
    coord = scene.node(NECK).expand()["coord"].expand()
    rings = neck_rings(coord["point"])
    front = int(np.argmax(rings[0, :, 2]))  # the camera looks down −z from +z
    y = camera.project(rings[:, front])[:, 1]
    row = 0.7 * y[2] + 0.3 * y[3]  # between the third and the fourth ring from the bottom
    bottom = cut_neck(scene, camera, row)
    cut = neck_rings(coord["point"])
    assert np.allclose(cut[3:], rings[3:])  # above the collar: as it was
    edge = 0.7 * rings[2] + 0.3 * rings[3]
    for k in range(3):  # the rings below it: on the new edge, point for point
        assert np.allclose(cut[k], edge)
    assert bottom == pytest.approx(edge[:, 1].mean())
    assert camera.project(cut[0, front][None])[0, 1] == pytest.approx(row, abs=0.05)
    # a collar below the neck's lowest ring leaves it as it is
    scene = _copy(bundled.scene)
    assert cut_neck(scene, camera, y[0] + 5.0) is None
    assert np.array_equal(scene.node(NECK).expand()["coord"].expand()["point"],
                          bundled.scene.node(NECK).expand()["coord"].expand()["point"])  # fmt: skip
