"""The interval integral and the deformation engine."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vtts.face import (
    N_PARAMS,
    Adt,
    AnimationTables,
    DeformationEngine,
    MeshTable,
    Miap,
    TransformTable,
    interval_weights,
    load_model,
)
from vtts.vrml import rotation_matrix


@st.composite
def tables(draw):
    """Random increasing borders containing 0 and random slopes for 3 vertices."""
    below = draw(st.lists(st.floats(-2000, -1), max_size=3, unique=True))
    above = draw(st.lists(st.floats(1, 2000), max_size=3, unique=True))
    if not below and not above:
        above = [draw(st.floats(1, 2000))]
    borders = np.array(sorted({0.0, *below, *above}))
    if (np.diff(borders) < 1e-3).any():
        borders = np.array([-1.0, 0.0, 1.0])
    n = borders.size - 1
    disp = np.array(draw(st.lists(st.floats(-1, 1), min_size=9 * n, max_size=9 * n))).reshape(
        n, 3, 3
    )
    return MeshTable("F", borders, [0, 1, 2], disp)


@settings(max_examples=150, deadline=None)
@given(tables(), st.floats(-3000, 3000))
def test_displacement_is_continuous_at_every_border(table, f):
    for b in table.borders:
        eps = 1e-7 * max(1.0, abs(b))
        left, right = table.displacement(b - eps), table.displacement(b + eps)
        assert np.allclose(left, right, atol=1e-9 + 4 * eps * np.abs(table.displacements).max())
    assert np.allclose(table.displacement(0.0), 0.0)


@settings(max_examples=150, deadline=None)
@given(tables(), st.data())
def test_displacement_is_linear_inside_an_interval(table, data):
    k = data.draw(st.integers(0, table.borders.size - 2))
    lo, hi = table.borders[k], table.borders[k + 1]
    a, b = data.draw(st.floats(0, 1)), data.draw(st.floats(0, 1))
    fa, fb = lo + a * (hi - lo), lo + b * (hi - lo)
    fm = (fa + fb) / 2
    mid = (table.displacement(fa) + table.displacement(fb)) / 2
    assert np.allclose(table.displacement(fm), mid, atol=1e-6)
    # the slope inside interval k is that interval's displacement per unit
    if abs(fb - fa) > 1e-3:
        slope = (table.displacement(fb) - table.displacement(fa)) / (fb - fa)
        assert np.allclose(slope, table.displacements[k], atol=1e-5)


def test_the_integral_by_hand():
    t = MeshTable("F", [0, 512, 1024], [7], [[[0, -1, 0]], [[0, -3, 0]]])
    assert t.displacement(256).tolist() == [[0, -256, 0]]
    assert t.displacement(1024).tolist() == [[0, -512 - 3 * 512, 0]]
    assert t.displacement(2048).tolist() == [[0, -512 - 3 * 1536, 0]]  # last interval extends
    assert t.displacement(-100).tolist() == [[0, 100, 0]]  # so does the first
    w = interval_weights(np.array([-10.0, 0, 5, 20]), np.array([-20.0, 3, 30]))
    assert w.tolist() == [[-20, 0, 0], [0, 3, 0], [0, 5, 25]]


def _engine_with(tables_list, points):
    t = AnimationTables()
    for adt in tables_list:
        t.add(adt)
    neutral_t = {
        "T": {"rotation": np.array([0, 0, 1, 0.0]), "translation": np.zeros(3), "scale": np.ones(3)}
    }
    return DeformationEngine(t, {"F": points}, neutral_t)


@pytest.mark.parametrize("split", [False, True])  # large tables run in two threads
@pytest.mark.parametrize("active", [1, 30])  # few active MIAPs (gather) and many (full product)
def test_engine_equals_the_sum_of_table_integrals(active, split, monkeypatch):
    if split:
        monkeypatch.setattr(DeformationEngine, "SPLIT_ABOVE", 0)
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(500, 3))
    adts = []
    for number in range(3, 40):
        verts = rng.choice(500, size=40, replace=False)
        adts.append(
            Adt(
                Miap("fap", number),
                meshes=[
                    MeshTable("F", [-300, 0, 200, 900], verts, rng.normal(size=(3, 40, 3)) * 1e-4)
                ],
            )
        )
    engine = _engine_with(adts, pts)
    params = np.zeros(N_PARAMS)
    chosen = rng.choice(np.arange(2, 39), size=active, replace=False)
    params[chosen] = rng.uniform(-1500, 1500, size=active)
    expected = pts.copy()
    for adt in adts:
        m = adt.meshes[0]
        expected[m.vertices] += m.displacement(params[adt.miap.index])
    assert np.allclose(engine.deform(params).points["F"], expected, atol=1e-12)


def test_the_gathered_entries_of_the_active_columns_serve_while_they_stay_active():
    """A pose after another with the same active columns (other values) takes the entries
    gathered for the first: the sums of a fresh engine, to the bit; other columns gather anew."""
    rng = np.random.default_rng(4)
    pts = rng.normal(size=(300, 3))
    adts = [
        Adt(
            Miap("fap", number),
            meshes=[
                MeshTable(
                    "F",
                    [-300, 0, 200, 900],
                    rng.choice(300, size=30, replace=False),
                    rng.normal(size=(3, 30, 3)) * 1e-4,
                )
            ],
        )
        for number in range(3, 40)
    ]
    kept = _engine_with(adts, pts)
    poses = []
    for values in ({3: 120.0, 5: -40.0}, {3: 150.0, 5: -10.0}, {3: 150.0, 7: 600.0}):
        params = np.zeros(N_PARAMS)
        for number, value in values.items():
            params[number - 1] = value
        poses.append(params)
    gathered = []
    for params in poses:
        fresh = _engine_with(adts, pts)
        assert np.array_equal(kept.deform(params).points["F"], fresh.deform(params).points["F"])
        (entry,) = kept._gathered.values()
        gathered.append(entry)
    assert gathered[1] is gathered[0]  # the same columns active: gathered once
    assert gathered[2] is not gathered[1]


def test_rotations_about_one_axis_add_and_about_others_compose():
    parallel = _engine_with(
        [
            Adt(
                Miap("fap", 48), transforms=[TransformTable("T", "rotation", [1, 0, 0, 0], [1e-5])]
            ),
            Adt(
                Miap("fap", 49), transforms=[TransformTable("T", "rotation", [-1, 0, 0, 0], [1e-5])]
            ),
        ],
        np.zeros((1, 3)),
    )
    p = np.zeros(N_PARAMS)
    p[47], p[48] = 30000, 10000
    r = parallel.deform(p).transforms["T"]["rotation"]
    assert np.allclose(r, [1, 0, 0, 0.2])
    crossed = _engine_with(
        [
            Adt(
                Miap("fap", 48), transforms=[TransformTable("T", "rotation", [1, 0, 0, 0], [1e-5])]
            ),
            Adt(
                Miap("fap", 49), transforms=[TransformTable("T", "rotation", [0, 1, 0, 0], [1e-5])]
            ),
        ],
        np.zeros((1, 3)),
    )
    r = crossed.deform(p).transforms["T"]["rotation"]
    want = rotation_matrix([1, 0, 0, 0.3]) @ rotation_matrix([0, 1, 0, 0.1])
    assert np.allclose(rotation_matrix(r), want)


def test_translation_and_scale_tables():
    e = _engine_with(
        [
            Adt(
                Miap("fap", 3),
                transforms=[TransformTable("T", "translation", [0, 0, 0], [0, -1e-3, 0])],
            ),
            Adt(
                Miap("expression", 1),
                transforms=[TransformTable("T", "scale", [1, 1, 1], [0.1, 0, 0])],
            ),
        ],
        np.zeros((1, 3)),
    )
    p = np.zeros(N_PARAMS)
    p[2] = 500
    p[Miap("expression", 1).index] = 0.5
    pose = e.deform(p)
    assert np.allclose(pose.transforms["T"]["translation"], [0, -0.5, 0])
    assert np.allclose(pose.transforms["T"]["scale"], [1.05, 1, 1])


def test_transform_values_of_some_transforms():
    t = AnimationTables()
    t.add(
        Adt(
            Miap("fap", 3),
            transforms=[TransformTable("JAW", "translation", [0, 0, 0], [0, -1e-3, 0])],
        )
    )
    t.add(
        Adt(Miap("fap", 48), transforms=[TransformTable("HEAD", "rotation", [1, 0, 0, 0], [1e-5])])
    )
    neutral = {"rotation": np.array([0, 0, 1, 0.0]), "translation": np.zeros(3)}
    e = DeformationEngine(t, {"F": np.zeros((1, 3))}, {"JAW": neutral, "HEAD": neutral})
    p = np.zeros(N_PARAMS)
    p[2], p[47] = 500, 10000
    every = e.transform_values(p)
    assert set(every) == {"JAW", "HEAD"}
    assert np.allclose(every["HEAD"]["rotation"], [1, 0, 0, 0.1])
    some = e.transform_values(p, names={"JAW"})
    assert set(some) == {"JAW"} and np.allclose(some["JAW"]["translation"], [0, -0.5, 0])
    assert e.transform_values(p, names=()) == {}


def test_model_deform_api_and_posed_scene(model_dir):
    model = load_model(model_dir / "head.wrl")
    neutral = model.neutral_points("FACE_MESH")
    pose = model.deform({"stretch_l_cornerlip": 500}, expressions={"smile": 1.0})
    moved = pose.points["FACE_MESH"] - neutral
    # FAP 6 at 500 moves vertex 50 by 0.05 in x; joy at 1 adds 0.02·0.5 + 0.01·0.5 in x and y
    assert np.allclose(moved[50], [0.05 + 0.015, 0.015, 0])
    assert np.allclose(moved[np.setdiff1d(np.arange(len(neutral)), [50, 51, 52])], 0)
    assert np.allclose(pose.transforms["HEAD"]["translation"], [0, 0.05, 0])
    scene = model.posed_scene(pose)
    assert np.allclose(scene.node("FACE_MESH")["coord"]["point"], pose.points["FACE_MESH"])
    assert np.allclose(model.neutral_points("FACE_MESH"), neutral)  # the model is untouched
    assert not scene.find("FaceDefTables")
