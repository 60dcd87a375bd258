"""vtts's own drawing passes give pyrender's pixels exactly: the forward pass (pyrender's shaders,
less overhead) and the deferred pass (G-buffer, then pyrender's shader once per pixel)."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.face import load_model
from vtts.render import FaceRenderer
from vtts.render.pyrender_adapter import load_pyrender, offscreen
from vtts.render.renderer import drawing_pass

W, H = 160, 120


def _pyrender(scene, rgba=False) -> np.ndarray:
    pr = load_pyrender()
    off = offscreen()
    off.viewport_width, off.viewport_height = W, H
    flags = pr.RenderFlags.RGBA if rgba else pr.RenderFlags.NONE
    return off.render(scene, flags=flags)[0]


def _forward():
    from vtts.render.forward import ForwardPass

    return ForwardPass(offscreen())


def _grid(n: int = 24, z: float = 0.0, wave: float = 0.15) -> tuple[np.ndarray, np.ndarray]:
    """A wavy ``n × n`` grid over [-1, 1]², facing +z: positions ``(n², 3)``, faces."""
    u, v = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    pos = np.c_[u.ravel(), v.ravel(), z + wave * np.sin(3 * u.ravel()) * np.cos(2 * v.ravel())]
    i = np.arange(n * n).reshape(n, n)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel()
    faces = np.r_[np.c_[a, b, d], np.c_[a, d, c]]
    return pos, faces


def _scene(*, colors=False, transparent=False, no_normals=False, points=False, lights="dir"):
    """A small scene exercising one feature at a time on top of a textured, lit wavy surface."""
    pr = load_pyrender()
    scene = pr.Scene(bg_color=[0.2, 0.3, 0.4, 0.0], ambient_light=[0.3, 0.3, 0.3])
    pos, faces = _grid()
    normals = np.tile([0.0, 0.0, 1.0], (len(pos), 1)) + 0.3 * pos
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    rng = np.random.default_rng(1)
    tex = pr.Texture(
        source=rng.integers(0, 256, (64, 64, 4), dtype=np.uint8), source_channels="RGBA"
    )
    textured = pr.MetallicRoughnessMaterial(
        baseColorFactor=[0.9, 0.8, 0.7, 1.0],
        baseColorTexture=tex,
        metallicFactor=0.1,
        roughnessFactor=0.5,
        emissiveFactor=[0.05, 0.0, 0.02],
    )
    scene.add(
        pr.Mesh(
            [
                pr.Primitive(
                    positions=pos,
                    normals=normals,
                    texcoord_0=(pos[:, :2] + 1) / 2,
                    indices=faces,
                    material=textured,
                )
            ]
        )
    )
    plain = pr.MetallicRoughnessMaterial(
        baseColorFactor=[0.3, 0.6, 0.9, 0.5 if transparent else 1.0],
        metallicFactor=0.0,
        roughnessFactor=0.8,
        alphaMode="BLEND" if transparent else "OPAQUE",
        doubleSided=True,
    )
    small = pos * 0.5 + [0.3, 0.2, 0.4]
    prim = {
        "positions": small,
        "normals": None if no_normals else normals,
        "indices": faces,
        "material": plain,
    }
    if colors:
        prim["color_0"] = np.c_[rng.random((len(pos), 3)), np.ones(len(pos))]
    if points:
        prim["mode"] = 0
        del prim["indices"]
    scene.add(pr.Mesh([pr.Primitive(**prim)]))
    scene.add(pr.IntrinsicsCamera(150, 150, W / 2, H / 2), pose=_look_from(3.0))
    if lights == "dir":
        scene.add(pr.DirectionalLight(color=np.ones(3), intensity=2.0), pose=_look_from(1.0))
        scene.add(pr.DirectionalLight(color=[1.0, 0.9, 0.8], intensity=0.7))
    elif lights == "many":
        for k in range(6):
            scene.add(pr.DirectionalLight(color=np.ones(3), intensity=0.4), pose=_look_from(k))
    else:
        scene.add(pr.PointLight(color=np.ones(3), intensity=6.0), pose=_look_from(2.0))
        scene.add(
            pr.SpotLight(color=np.ones(3), intensity=8.0, outerConeAngle=0.8),
            pose=_look_from(2.5),
        )
    return scene


def _look_from(z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = [0.2, -0.1, z]
    return m


CASES = {
    "textured": {},
    "vertex colors": {"colors": True},
    "transparent": {"transparent": True},
    "no normals": {"no_normals": True},
    "point and spot lights": {"lights": "point"},
    "points (forward only)": {"points": True},
    "more lights than its shader holds (pyrender's render)": {"lights": "many"},
}


@pytest.mark.parametrize("rgba", [False, True])
@pytest.mark.parametrize("case", list(CASES))
def test_passes_give_pyrenders_pixels(case, rgba):
    scene = _scene(**CASES[case])
    want = _pyrender(scene, rgba)
    assert np.array_equal(_forward().render(scene, W, H, rgba), want)
    assert np.array_equal(drawing_pass().render(scene, W, H, rgba), want)
    assert np.array_equal(_pyrender(scene, rgba), want)  # and pyrender after them


def test_the_deferred_pass_covers_the_heads():
    from vtts.render.deferred import DeferredPass

    with FaceRenderer(load_model("cybatt")) as r:
        assert isinstance(drawing_pass(), DeferredPass)
        assert drawing_pass().deferrable(r.scene)


def test_warm_up_makes_the_pass_before_any_renderer(monkeypatch):
    from vtts.render import renderer, warm_up
    from vtts.render.deferred import DeferredPass

    monkeypatch.setattr(renderer, "_DRAWING_PASS", None)  # as in a process that drew nothing
    warm_up()
    made = renderer._DRAWING_PASS
    assert isinstance(made, DeferredPass)
    warm_up()  # once is enough: every renderer shares it
    assert renderer._DRAWING_PASS is made and drawing_pass() is made


@pytest.mark.parametrize("supersample", [1, 2])
def test_animated_heads_match_pyrender(supersample):
    model = load_model("lotta")
    rng = np.random.default_rng(7)
    with FaceRenderer(model, size=(176, 144), supersample=supersample) as r:
        for _ in range(3):
            p = model.params(
                {3: float(rng.uniform(0, 600)), 48: float(rng.uniform(-9000, 9000))},
                visemes={int(rng.integers(1, 15)): 1.0},
                expressions={"joy": float(rng.uniform(0, 1))},
            )
            got = r.render(p)
            want = _pyrender_frame(r)
            assert np.array_equal(got, want)


def _pyrender_frame(r: FaceRenderer) -> np.ndarray:
    from vtts.render.renderer import downsample

    off = offscreen()
    off.viewport_width, off.viewport_height = r.size[0] * r.supersample, r.size[1] * r.supersample
    return downsample(off.render(r.scene)[0], r.supersample)


def test_frames_match_frames_rendered_one_by_one():
    """Parts a frame leaves as they were (eyes, ears, a still Transform) are not recomputed; the
    frames stay exactly those of a fresh renderer posed for each."""
    model = load_model("cybatt")
    still = model.params({48: 4000})
    sequence = [
        still,
        still,
        model.params({48: 4000, 3: 300}, visemes={10: 1.0}),
        model.params({49: -6000, 23: 20000}, expressions={"joy": 0.7}),
        still,
    ]
    with FaceRenderer(model, size=(176, 144)) as r:
        got = list(r.frames(sequence))
    for params, frame in zip(sequence, got, strict=True):
        with FaceRenderer(model, size=(176, 144)) as fresh:
            assert np.array_equal(frame, fresh.render(params))


def test_vrml_primitives_render(tmp_path):
    """Box, Sphere, Cylinder and Cone come from trimesh, whose import is deferred until then."""
    from vtts.face import N_PARAMS

    (tmp_path / "shapes.wrl").write_text(
        "#VRML V2.0 utf8\n"
        "Transform { translation -2 0 0 children Shape { geometry Box { size 1 1 1 } } }\n"
        "Transform { translation 0 0 0 children Shape { geometry Sphere { radius 0.6 } } }\n"
        "Transform { translation 2 0 0 children Shape { geometry Cylinder { } } }\n"
        "Transform { translation 4 0 0 children Shape { geometry Cone { } } }\n"
    )
    with FaceRenderer(load_model(tmp_path / "shapes.wrl"), size=(176, 144)) as r:
        img = r.render(np.zeros(N_PARAMS))
        assert np.array_equal(img, _pyrender_frame(r))
    assert (img != img[0, 0]).any(axis=2).mean() > 0.05


def test_the_deferred_pass_draws_smaller_images_in_the_targets_it_has():
    """Targets made for a larger image are kept for a smaller one (the analysis renders windows
    of changing sizes): the same pixels and triangle numbers as targets of the image's own size."""
    from vtts.render.deferred import DeferredPass

    scene = _scene()
    primitive = next(p for m in scene.meshes if not m.is_transparent for p in m.primitives)
    fresh = DeferredPass(offscreen())
    want, want_numbers = fresh.render(scene, W, H, triangles={primitive: 5})
    assert np.array_equal(want, _pyrender(scene))
    assert (want_numbers >= 5).any()
    reused = DeferredPass(offscreen())
    reused.render(scene, W + 90, H // 2)  # wider, lower: grows to hold both sides
    reused.render(scene, W + 20, H + 40)
    targets = reused._targets
    assert targets.size[0] >= W + 90 and targets.size[1] >= H + 40
    got, numbers = reused.render(scene, W, H, triangles={primitive: 5})
    assert reused._targets is targets
    assert np.array_equal(got, want) and np.array_equal(numbers, want_numbers)
    assert np.array_equal(reused.render(scene, W, H, rgba=True), _pyrender(scene, rgba=True))


def test_an_unlit_materials_pixels_store_no_position_or_normal():
    """The G-buffer keeps position and normal for lit materials only: where an unlit primitive
    lies in front, the position target still holds what lies behind it (the lit surface), and
    the pixel shows the unlit colour as it is; the stencil tells the resolve pass's lit pixels
    (1) from the unlit ones (0)."""
    from OpenGL import GL

    from vtts.render.deferred import G_TARGETS, DeferredPass
    from vtts.render.pyrender_adapter import make_current
    from vtts.render.scene import UNLIT

    scene = _scene()
    front = next(m for m in scene.meshes if m.primitives[0].material.doubleSided).primitives[0]
    front.material.baseColorFactor = [0.2, 0.4, 0.8, 1.0]
    setattr(front.material, UNLIT, True)
    deferred = DeferredPass(offscreen())
    back = next(m for m in scene.meshes if not m.primitives[0].material.doubleSided).primitives[0]
    image, numbers = deferred.render(scene, W, H, triangles={front: 5000, back: 0})
    shown = numbers >= 5000
    assert shown.mean() > 0.05
    assert (image[shown] == [51, 102, 204]).all()  # the factor in 8 bits, no light
    make_current(offscreen())
    GL.glBindTexture(GL.GL_TEXTURE_2D, deferred._targets.textures[G_TARGETS.index("g_position")])
    stored = GL.glGetTexImage(GL.GL_TEXTURE_2D, 0, GL.GL_RGBA, GL.GL_FLOAT)
    GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
    tw, th = deferred._targets.size
    position = np.frombuffer(stored, np.float32).reshape(th, tw, 4)[:H, :W][::-1]
    # the front grid lies at z 0.4 ± 0.08, the lit one behind it at 0 ± 0.15
    assert (position[shown][:, 2] < 0.2).all()
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, deferred._targets.gbuffer)
    stencil = GL.glReadPixels(0, 0, W, H, GL.GL_STENCIL_INDEX, GL.GL_UNSIGNED_BYTE)
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, 0)
    stencil = np.frombuffer(stencil, np.uint8).reshape(H, W)[::-1]
    lit = (numbers >= 0) & ~shown
    assert lit.mean() > 0.05
    assert (stencil[shown] == 0).all() and (stencil[lit] == 1).all()
