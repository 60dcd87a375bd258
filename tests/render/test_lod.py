"""Level of detail: the progressive mesh (vtts.render.lod) and FaceRenderer's ``detail``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vtts.errors import RenderError
from vtts.face import load_model
from vtts.render import DETAIL_PX, FaceRenderer
from vtts.render.lod import progressive_mesh, simplified_faces

TEST_HEAD = Path(__file__).resolve().parents[1] / "data" / "models" / "head.wrl"


def _grid(n: int, height=lambda x, y: 0.0 * x) -> tuple[np.ndarray, np.ndarray]:
    """An n×n grid of vertices over [0, 1]², lifted by ``height``, and its triangles."""
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    pts = np.c_[x.ravel(), y.ravel(), height(x, y).ravel()]
    faces = []
    for i in range(n - 1):
        for j in range(n - 1):
            a, b, c, d = i * n + j, i * n + j + 1, (i + 1) * n + j, (i + 1) * n + j + 1
            faces += [(a, b, d), (a, d, c)]
    return pts, np.array(faces)


def _border(faces: np.ndarray) -> set[tuple[int, int]]:
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    uniq, counts = np.unique(edges, axis=0, return_counts=True)
    return {tuple(e) for e in uniq[counts == 1].tolist()}


def _area(pts: np.ndarray, faces: np.ndarray) -> float:
    a, b, c = (pts[faces[:, i]] for i in range(3))
    return float(np.linalg.norm(np.cross(b - a, c - a), axis=1).sum() / 2)


def test_a_flat_mesh_keeps_its_border_and_area_with_few_triangles():
    pts, faces = _grid(9)
    collapses = progressive_mesh(pts, faces, max_error=1e-9)
    out = simplified_faces(faces, collapses, 1e-9)
    assert len(out) < len(faces) / 4  # the 49 inner vertices of a plane all go
    assert np.all(collapses.errors <= 1e-9)
    # the border's vertices stay where they were: the outline is the same polyline
    kept = set(np.unique(out).tolist())
    assert {v for e in _border(faces) for v in e} <= kept
    assert _area(pts, out) == pytest.approx(1.0)
    # no triangle flipped: every one still faces +z
    a, b, c = (pts[out[:, i]] for i in range(3))
    assert np.all(np.cross(b - a, c - a)[:, 2] > 0)


def test_the_tolerance_is_a_prefix_of_the_collapses_and_bounds_the_surface():
    pts, faces = _grid(13, lambda x, y: 0.3 * np.sin(3 * x) * np.cos(2 * y))
    collapses = progressive_mesh(pts, faces, max_error=0.05)
    assert np.all(np.diff(collapses.errors) >= 0)
    sizes = [len(simplified_faces(faces, collapses, e)) for e in (0.0, 0.002, 0.01, 0.05)]
    assert sizes[0] == len(faces)
    assert sizes == sorted(sizes, reverse=True) and sizes[-1] < sizes[1] < sizes[0]
    # every removed vertex lies within the tolerance of the simplified surface's planes near it
    out = simplified_faces(faces, collapses, 0.01)
    gone = np.setdiff1d(np.arange(len(pts)), np.unique(out))
    a, b, c = (pts[out[:, i]] for i in range(3))
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    for v in gone:
        # the triangle under the vertex (in x, y) holds it within the tolerance
        p = pts[v]
        d0, d1, d2 = b - a, c - a, p - a
        den = d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):  # triangles edge-on from above
            s = (d2[:, 0] * d1[:, 1] - d2[:, 1] * d1[:, 0]) / den
            t = (d0[:, 0] * d2[:, 1] - d0[:, 1] * d2[:, 0]) / den
            inside = (s >= -1e-9) & (t >= -1e-9) & (s + t <= 1 + 1e-9)
        assert inside.any()
        assert np.min(np.abs(np.sum((p - a[inside]) * n[inside], axis=1))) <= 0.01 + 1e-9


def test_a_pose_that_bends_the_mesh_keeps_its_vertices():
    flat, faces = _grid(9)
    bent = flat.copy()
    bent[:, 2] = 0.2 * np.sin(np.pi * bent[:, 0]) * np.sin(np.pi * bent[:, 1])  # a second pose
    alone = simplified_faces(faces, progressive_mesh(flat, faces, max_error=0.01), 0.01)
    both = simplified_faces(
        faces, progressive_mesh(np.stack([flat, bent]), faces, max_error=0.01), 0.01
    )
    assert len(alone) < len(both) < len(faces)


def test_nothing_to_simplify():
    pts, faces = _grid(2)  # two triangles: every vertex on the border
    collapses = progressive_mesh(pts, faces, max_error=1.0)
    assert collapses.pairs.shape == (0, 2)
    assert np.array_equal(simplified_faces(faces, collapses, 1.0), faces)


@pytest.mark.parametrize("name", ["cybatt", "lotta"])
def test_a_talking_head_drawn_with_fewer_triangles_looks_the_same(name, tmp_path, monkeypatch):
    monkeypatch.setenv("VTTS_CACHE_DIR", str(tmp_path))
    model = load_model(name)
    rng = np.random.default_rng(3)
    params = []
    for k in range(6):  # visemes, an expression, blinks: what vtts say draws
        p = model.params(
            visemes={int(rng.integers(1, 15)): 1.0}, expressions={"joy": 0.5 * (k % 2)}
        )
        p[18:20] = 900 * (k == 3)
        p[47] = 0.05 * k  # a nod
        params.append(p)
    with FaceRenderer(model) as full:
        ref = [full.render(p) for p in params]
        n_full = sum(len(am.template.faces) for am in full.instances[0].meshes)
    with FaceRenderer(model, detail=DETAIL_PX) as r:
        out = [r.render(p) for p in params]
        n = sum(len(am.faces) for am in r.instances[0].meshes)
        with pytest.raises(RenderError, match="detail"):
            r.render(triangles=True)
    assert n < 0.6 * n_full
    for a, b in zip(ref, out, strict=True):
        mse = np.mean((a.astype(float) - b) ** 2)
        assert 10 * np.log10(255**2 / mse) > 40
    # the bundled heads' progressive meshes are shipped: the user's cache is not needed
    assert not (tmp_path / "lod").exists() or not any((tmp_path / "lod").iterdir())


def test_every_bundled_head_ships_its_progressive_meshes():
    from vtts.face import bundled_models
    from vtts.render.renderer import lod_key
    from vtts.resources import models_dir

    for name in bundled_models():
        with FaceRenderer(load_model(name)) as r:
            for inst in r.instances:
                for am in inst.meshes:
                    file, _, _ = lod_key(inst, am)
                    # if this fails, the head changed: run make models (or build_lod.py)
                    assert (models_dir() / "lod" / file).is_file(), f"{name} {am.name}"


def test_another_head_keeps_its_progressive_meshes_in_the_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("VTTS_CACHE_DIR", str(tmp_path))
    model = load_model(TEST_HEAD)
    with FaceRenderer(model, detail=0.5) as r:
        first = [am.faces.copy() for am in r.instances[0].meshes]
        image = r.render()
    kept = sorted((tmp_path / "lod").iterdir())
    assert kept and all(f.suffix == ".npz" for f in kept)
    with FaceRenderer(model, detail=0.5) as again:  # read back: the same triangles and pixels
        assert all(
            np.array_equal(a, am.faces)
            for a, am in zip(first, again.instances[0].meshes, strict=True)
        )
        assert np.array_equal(again.render(), image)
    # an entry that does not fit the mesh is made again, as is one another user could write
    for f in kept:
        np.savez(f, pairs=np.array([[10**9, 0]], np.int32), errors=np.zeros(1, np.float32))
    kept[0].chmod(0o666)
    with FaceRenderer(model, detail=0.5) as again:
        assert all(
            np.array_equal(a, am.faces)
            for a, am in zip(first, again.instances[0].meshes, strict=True)
        )


def test_a_larger_view_draws_more_triangles(tmp_path, monkeypatch):
    monkeypatch.setenv("VTTS_CACHE_DIR", str(tmp_path))
    model = load_model("cybatt")
    counts = []
    for size in ((176, 144), (352, 288), (704, 576)):
        with FaceRenderer(model, size=size, detail=0.5) as r:
            counts.append(sum(len(am.faces) for am in r.instances[0].meshes))
    assert counts[0] < counts[1] < counts[2]
    # a view set afterwards chooses again, and draws what a new renderer of that view draws
    smile = model.params(expressions={"joy": 1.0})
    with FaceRenderer(model, size=(704, 576), detail=0.5) as big:
        expected = big.render(smile)
    with FaceRenderer(model, size=(176, 144), detail=0.5) as r:
        r.render(smile)  # normals computed for the small view's vertices, then kept
        r.set_view(FaceRenderer(model, size=(704, 576)).camera, size=(704, 576))
        assert sum(len(am.faces) for am in r.instances[0].meshes) == counts[2]
        assert np.array_equal(r.render(smile), expected)


def test_normals_only_where_triangles_are_drawn_are_the_full_meshs():
    from vtts.mesh import vertex_normals
    from vtts.render.renderer import deformed_points

    model = load_model("cybatt")
    with FaceRenderer(model, detail=0.5) as r:
        inst = r.instances[0]
        params = [model.params(visemes={v: 1.0}) for v in (2, 9)]
        points = deformed_points(inst, [(p, None) for p in params])
        for am in inst.meshes:
            pos = np.stack(points[am.name])[:, am.template.coord_index]
            full = vertex_normals(pos, am.template.faces, am.incidence)
            used = np.unique(am.faces)
            assert np.array_equal(am.normals(pos)[:, used], full[:, used])  # the same bits


def test_the_drawn_vertices_are_found_without_numpy_ma(tmp_path):
    """The vertices a simplified mesh draws are ``np.unique``'s answer, found without its look
    for masked arrays: a renderer with a detail leaves ``numpy.ma`` unimported (12–35 ms of a
    ``vtts say``'s start-up), also when the model is parsed afresh (an empty model cache)."""
    import os
    import subprocess
    import sys

    from vtts.render.lod import present

    rng = np.random.default_rng(3)
    for n in (1, 7, 500):
        ids = rng.integers(0, n, size=(40, 3))
        assert np.array_equal(present(ids, n), np.unique(ids))
    assert present(np.zeros((0, 3), dtype=np.int64), 4).size == 0
    code = (
        "import sys\n"
        "from vtts.face import load_model\n"
        "from vtts.render import FaceRenderer\n"
        "m = load_model('cybatt')\n"
        "with FaceRenderer(m, detail=0.5) as r:\n"
        "    r.render(m.params(visemes={2: 1.0}))\n"
        "    assert any(am.drawn is not None for am in r.instances[0].meshes)\n"
        "print(type(sys.modules['numpy.ma']).__name__)\n"
    )
    env = {**os.environ, "VTTS_CACHE_DIR": str(tmp_path)}
    r = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["_DeferredPackage"]


@pytest.mark.parametrize("detail", [-1, 101, float("nan"), "0.5"])
def test_detail_must_be_a_distance(detail):
    with pytest.raises(RenderError, match="detail"):
        FaceRenderer(load_model("cybatt"), detail=detail)


def test_say_draws_within_half_a_pixel_unless_told_every_triangle(tmp_path, capsys):
    from PIL import Image

    from vtts import cli

    frames = {}
    for detail in ("default", "0"):
        out = tmp_path / detail
        argv = ["say", "Hello there", "--model", "cybatt", "--png-dir", str(out), "--quiet"]
        assert cli.main(argv + ([] if detail == "default" else ["--detail", detail])) == 0
        frames[detail] = [np.asarray(Image.open(p)) for p in sorted(out.glob("*.png"))]
    assert len(frames["default"]) == len(frames["0"]) > 10
    worst = min(
        10 * np.log10(255**2 / max(np.mean((a.astype(float) - b) ** 2), 1e-12))
        for a, b in zip(frames["default"], frames["0"], strict=True)
    )
    assert 40 < worst < 200  # close, and not the same triangles
    for bad in ("-1", "nan", "101", "half"):
        with pytest.raises(SystemExit) as e:
            cli.main(
                ["say", "Hi", "--model", "cybatt", "-o", str(tmp_path / "x.mp4"), "--detail", bad]
            )
        assert e.value.code == 2
        assert "--detail: a distance in pixels from 0 to 100" in capsys.readouterr().err


def test_holes_duplicates_and_degenerate_triangles_simplify_cleanly():
    model = load_model("cybatt")
    with FaceRenderer(model) as r:
        meshes = {am.name: am for am in r.instances[0].meshes}
    rng = np.random.default_rng(0)
    for trial in range(24):
        am = meshes[("TONGUE", "L_EAR", "MOUTH", "HAIR")[trial % 4]]
        pts, faces = am.template.positions, am.template.faces
        f = faces[rng.random(len(faces)) < rng.uniform(0.5, 1.0)]  # holes
        if trial % 3 == 0:  # a duplicate, a triangle with a repeated corner, a non-manifold fin
            f = np.concatenate(
                [f, f[:1], [[f[0, 0], f[0, 0], f[0, 1]]], [[f[1, 0], f[1, 1], f[5, 2]]]]
            )
        poses = pts[None] + rng.normal(0, 0.01, (3, *pts.shape)) * (trial % 2)
        collapses = progressive_mesh(poses, f, max_error=0.05)
        assert np.all(np.diff(collapses.errors) >= 0)
        for error in (0.001, 0.01, 0.05):
            out = simplified_faces(f, collapses, error)
            assert len(out) <= len(f)
            assert out.size == 0 or (out.min() >= 0 and out.max() < len(pts))
