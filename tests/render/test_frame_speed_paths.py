"""The fast paths of a speaking head's frames give the same frames: geometry prepared for many
frames at once (``FaceRenderer.prepare_many``), mipmaps made by NumPy (``vtts.render.mipmaps``)
and the resolve shader made for the scene's light counts."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.face import load_model
from vtts.mesh import vertex_normals
from vtts.render import FaceRenderer
from vtts.render.mipmaps import mip_levels, power_of_two
from vtts.render.pyrender_adapter import make_current, offscreen, pyrender_texture


def _speaking(model, n: int = 14) -> list[np.ndarray]:
    """``n`` parameter vectors of a head that speaks, turns and blinks, with repeats."""
    rng = np.random.default_rng(3)
    out = []
    for i in range(n):
        faps = {3: int(rng.integers(0, 600)), 48: 3000 * np.sin(i / 3), 19: 900 * (i % 5 == 0)}
        out.append(model.params(faps, visemes={int(rng.integers(1, 15)): 1.0}))
        if i % 4 == 0:
            out.append(out[-1].copy())  # a frame like the one before
    return out


def test_prepare_many_is_prepare_frame_by_frame():
    model = load_model("cybatt")
    params = _speaking(model)
    with FaceRenderer(model, size=(176, 144)) as r:
        together = r.prepare_many([(p, None, None) for p in params])
    with FaceRenderer(model, size=(176, 144)) as r:
        one_by_one = [r.prepare(p) for p in params]
    assert len(together) == len(one_by_one) == len(params)
    for a, b in zip(together, one_by_one, strict=True):
        (meshes_a, matrices_a, _), (meshes_b, matrices_b, _) = a[0], b[0]
        assert [m[0].name for m in meshes_a] == [m[0].name for m in meshes_b]
        for x, y in zip(meshes_a, meshes_b, strict=True):
            for u, v in zip(x[1:], y[1:], strict=True):
                assert np.array_equal(u, v)  # the same bits
        assert len(matrices_a) == len(matrices_b)
        for (_, u), (_, v) in zip(matrices_a, matrices_b, strict=True):
            assert np.array_equal(u, v)


def test_frames_are_the_renders_of_each_frame():
    model = load_model("cybatt")
    params = _speaking(model, 8)
    with FaceRenderer(model, size=(176, 144)) as r:
        frames = list(r.frames(params))
        assert len(frames) == len(params)
        for p, frame in zip(params, frames, strict=True):
            assert np.array_equal(frame, r.render(p))


def test_points_many_is_deform():
    model = load_model("cybatt")
    params = np.array(_speaking(model, 6))
    many = model.engine.points_many(params)
    for t, p in enumerate(params):
        for name, pts in model.engine.deform(p).points.items():
            assert np.array_equal(many[name][t], pts)
    with pytest.raises(ValueError, match="shape"):
        model.engine.points_many(params[0])


def test_vertex_normals_of_many_shapes_are_each_shapes():
    from vtts.mesh import incidence as _incidence

    rng = np.random.default_rng(0)
    faces = rng.integers(0, 40, (70, 3))
    shapes = rng.normal(size=(5, 40, 3))
    inc = _incidence(faces, 40)
    many = vertex_normals(shapes, faces, inc)
    assert many.shape == shapes.shape
    for s, n in zip(shapes, many, strict=True):
        assert np.array_equal(vertex_normals(s, faces, inc), n)


@pytest.mark.parametrize("shape", [(64, 64), (512, 256), (16, 1), (1, 8), (2, 32)])
def test_mipmaps_are_the_rasterizers(shape):
    """:func:`mip_levels` gives the texels of llvmpipe's ``glGenerateMipmap``."""
    make_current(offscreen())
    from OpenGL import GL

    if "llvmpipe" not in GL.glGetString(GL.GL_RENDERER).decode():
        pytest.skip("the levels copy Mesa's llvmpipe")
    h, w = shape
    image = np.random.default_rng(h * w).integers(0, 256, (h, w, 4), dtype=np.uint8)
    tex = GL.glGenTextures(1)
    try:
        GL.glBindTexture(GL.GL_TEXTURE_2D, tex)
        GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
        GL.glTexImage2D(
            GL.GL_TEXTURE_2D, 0, GL.GL_RGBA, w, h, 0, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE, image
        )
        GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 4)
        GL.glGenerateMipmap(GL.GL_TEXTURE_2D)
        levels = mip_levels(image)
        assert levels[-1].shape == (1, 1, 4)
        for k, level in enumerate(levels[1:], start=1):
            got = GL.glGetTexImage(GL.GL_TEXTURE_2D, k, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE)
            assert np.array_equal(np.frombuffer(got, np.uint8).reshape(level.shape), level), k
    finally:
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        GL.glDeleteTextures([tex])


def test_mip_levels_refuse_other_sizes():
    assert power_of_two((512, 1)) and not power_of_two((6, 8)) and not power_of_two((0, 4))
    with pytest.raises(ValueError, match="2\\^k"):
        mip_levels(np.zeros((6, 8, 4), np.uint8))


def test_a_texture_of_another_size_keeps_gl_mipmaps(tmp_path):
    """A texture whose sides are not powers of two renders (GL makes its levels)."""
    tex = pyrender_texture(np.full((6, 10, 4), 200, np.uint8))
    make_current(offscreen())
    tex._add_to_context()
    try:
        assert tex._texid is not None
    finally:
        tex._remove_from_context()


def test_a_scene_draws_in_the_order_its_nodes_were_added():
    """pyrender keeps a scene's nodes in sets (address order); a FaceRenderer's scene iterates
    its meshes and lights in the order they were added, so two renderers of one model draw
    alike (pyrender_adapter.order_scene)."""
    model = load_model("cybatt")
    orders = []
    for _ in range(3):
        with FaceRenderer(model, size=(176, 144)) as r:
            nodes = list(r.scene.mesh_nodes)
            primitives = [n.mesh.primitives[0] for n in nodes]
            firsts = [r._triangle_numbers.get(p) for p in primitives]
            triangles = [f for f in firsts if f is not None]
            assert triangles == sorted(triangles)  # the IndexedFaceSets in model order
            lights = [n.light.intensity for n in r.scene.light_nodes]
            orders.append((firsts, lights))
            junk = [np.empty(n) for n in range(1, 4000, 97)]  # other addresses for the next
            del junk
    assert orders[0] == orders[1] == orders[2]
    assert orders[0][1] == [2.2, 0.8]  # the key light, then the fill light


def _unlit_cybatt(folder) -> str:
    """cybatt with its skin's Material taken out: an unlit face (as a head made for a video),
    animated by the same tables."""
    import shutil
    from pathlib import Path

    models = Path(__file__).resolve().parents[2] / "models"
    for name in ("cybatt.adt", "cybatt-face.png"):
        shutil.copy(models / name, folder / name)
    text = (models / "cybatt.wrl").read_text(encoding="utf-8")
    skin = "      material Material { diffuseColor 1 1 1 shininess 0.12 }\n"
    assert text.count(skin) == 1
    (folder / "cybatt.wrl").write_text(text.replace(skin, ""), encoding="utf-8")
    return str(folder / "cybatt.wrl")


@pytest.mark.parametrize("deferred", [True, False])
def test_an_unlit_face_needs_no_normals_where_they_do_not_show(tmp_path, monkeypatch, deferred):
    """An opaque unlit mesh drawn through the G-buffer keeps its template's normals frame after
    frame (they show nowhere) and its frames are the pixels of normals computed every frame;
    where the scene falls back to pyrender's lit forward pass, the normals are computed."""
    import vtts.render.deferred as deferred_module

    model = load_model(_unlit_cybatt(tmp_path))
    params = _speaking(model, 8)
    if not deferred:
        monkeypatch.setattr(deferred_module.DeferredPass, "deferrable", lambda self, scene: False)
    frames = {}
    for skip in (True, False):
        with FaceRenderer(model, size=(176, 144)) as r:
            assert [am.unlit for am in r.instances[0].meshes if am.name == "FACE"] == [True]
            if not skip:  # every mesh lit as far as the frames' geometry is concerned
                for am in r.instances[0].meshes:
                    am.unlit = False
            frames[skip] = [f.copy() for f in r.frames(params)]
            if skip:
                assert r._draws_unlit() == deferred
    assert all(np.array_equal(a, b) for a, b in zip(frames[True], frames[False], strict=True))
    assert not all(np.array_equal(frames[True][0], f) for f in frames[True][1:])  # it moves


def test_a_mesh_left_as_it_was_is_not_uploaded_again(monkeypatch):
    """A frame sends the GPU only the vertex buffers that changed since the last one it
    drew; its pixels stay those of a fresh renderer posed for it."""
    import vtts.render.renderer as renderer_module

    model = load_model("cybatt")
    sent: list[str] = []
    rewrite = renderer_module.rewrite_vertex_buffer

    def counting(primitive, data):
        sent.append(primitive)
        return rewrite(primitive, data)

    monkeypatch.setattr(renderer_module, "rewrite_vertex_buffer", counting)
    still = model.params({48: 4000})
    moved = model.params({48: 4000, 3: 300})  # the jaw: some meshes move, others not
    with FaceRenderer(model, size=(176, 144)) as r:
        r.render(still)  # the first frame puts the meshes on the GPU
        r.render(still)  # the second writes their buffers
        first = len(sent)
        again = r.render(still)
        assert len(sent) == first  # nothing changed: nothing sent
        frame = r.render(moved)
        assert 0 < len(sent) - first < first / 2
    for params, got in ((still, again), (moved, frame)):
        with FaceRenderer(model, size=(176, 144)) as fresh:
            assert np.array_equal(got, fresh.render(params))
