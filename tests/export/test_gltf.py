"""The animated glTF export: decoded at its keyframes, the file puts every triangle where vtts's
renderer puts it (deformation, Transforms, placement), looks through the renderer's camera, and
encodes each ADT interval as one morph target whose weight is the progress through it."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import vtts
from vtts.errors import ExportError, RenderError
from vtts.export import CAMERA_NODE, animation_gltf, placement, write_gltf
from vtts.face import N_PARAMS, load_model
from vtts.render import Camera, FaceRenderer

from .gltf_helpers import HEAD, Decoded, sweep, write_rig

FPS = 25.0


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    return load_model(write_rig(tmp_path_factory.mktemp("rig")))


@pytest.fixture(scope="module")
def head():
    return load_model(HEAD)


def renderer_triangles(renderer: FaceRenderer, params, roots=None) -> dict[str, list[np.ndarray]]:
    """IndexedFaceSet DEF name → per instance the world corners ``(m, 3, 3)`` of its triangles
    as the renderer poses them (its prepared vertex arrays under its scene's node poses)."""
    renderer.apply(renderer.prepare(params, roots=roots))
    out: dict[str, list[np.ndarray]] = {}
    for inst in renderer.instances:
        for am in inst.meshes:
            positions = am.last[1]  # what prepare made of this frame's points
            world = renderer.scene.get_pose(am.parent)
            pts = positions @ world[:3, :3].T + world[:3, 3]
            out.setdefault(am.name, []).append(pts[am.template.faces])
    return out


def assert_same_triangles(decoded: dict, expected: dict, extent: float) -> None:
    for name, instances in expected.items():
        got = decoded[name]
        assert len(got) == len(instances), name
        # instances of one mesh come in scene order in both
        for g, e in zip(got, instances, strict=True):
            assert g.shape == e.shape, name
            err = np.abs(g - e).max()
            assert err <= 2e-6 * extent, f"{name}: off by {err:.3g} (extent {extent:.3g})"


# Not the rig: pyrender keeps a node's matrix as translation, rotation and scale, so the renderer
# draws a Transform whose scaleOrientation turns a non-uniform scale (a shear) without its shear;
# the rig is checked against the VRML97 scene itself below.
@pytest.mark.parametrize("which", ["head", "cybatt"])
def test_keyframes_put_every_vertex_where_the_renderer_does(which, head, tmp_path):
    model = head if which == "head" else load_model("cybatt")
    params = sweep(model, n_frames=9, seed=3)
    path = write_gltf(tmp_path / "a.glb", [model], params, FPS, size=(200, 160))
    decoded = Decoded(path)
    assert np.array_equal(decoded.times(), (np.arange(9) / FPS).astype(np.float32))
    placed = placement([model], size=(200, 160))  # the heads' bounds, as the renderer's
    extent = float((placed.hi - placed.lo).max())
    with FaceRenderer([model], size=(200, 160)) as r:
        for frame in (0, 1, 4, 8):
            expected = renderer_triangles(r, params[frame])
            assert expected, "the model animates no mesh"
            assert_same_triangles(decoded.triangles(frame), expected, extent)


def test_every_mesh_and_transform_follows_vtts_deformation(rig, tmp_path):
    """All IndexedFaceSets (animated or not) against ``model.deform`` and the posed scene's own
    Transforms, without the renderer: the file's world = the renderer's placement · the posed
    VRML scene."""
    from vtts.vrml import triangulate

    params = sweep(rig, n_frames=7, seed=5)
    decoded = Decoded(write_gltf(tmp_path / "a.glb", [rig], params, FPS))
    matrix = placement([rig]).matrices[0]
    for frame in range(7):
        posed = rig.posed_scene(rig.engine.deform(params[frame]))
        expected: dict[str, list[np.ndarray]] = {}
        for node, world, _ in posed.traverse():
            if node.type.name != "Shape" or node["geometry"] is None:
                continue
            geom = node["geometry"].expand()
            if geom.type.name != "IndexedFaceSet":
                continue
            tm = triangulate(geom)
            m = matrix @ world
            pts = tm.positions @ m[:3, :3].T + m[:3, 3]
            expected.setdefault(geom.name, []).append(pts[tm.faces])
        assert set(expected) == {"LIP"} and len(expected["LIP"]) == 2  # the jaw is USEd
        assert_same_triangles(decoded.triangles(frame), expected, 1.0)


def test_vertices_begin_with_the_coordinate_points_and_weights_are_interval_progress(rig, tmp_path):
    params = np.zeros((5, N_PARAMS))
    params[:, 2] = [0, 100, 200, 300, -150]  # open_jaw: borders -100 0 200 400
    decoded = Decoded(write_gltf(tmp_path / "a.glb", [rig], params, FPS))
    doc = decoded.doc
    (mesh,) = [m for m in doc.meshes if m.name == "LIP"]
    names = mesh.extras["targetNames"]
    assert names[:3] == ["FAP3_open_jaw#0", "FAP3_open_jaw#1", "FAP3_open_jaw#2"]
    assert names[3:] == ["viseme1#0", "joy#0", "joy#1"]
    assert mesh.extras["vtts"]["intervals"][:3] == [[0.0, -100.0], [0.0, 200.0], [200.0, 400.0]]
    points = mesh.extras["vtts"]["points"]
    assert points == 10
    base = decoded.accessor(mesh.primitives[0].attributes.POSITION)
    neutral = rig.neutral_points("LIP")
    assert len(base) > points  # seam copies (flat normals, the texture seam) come after
    np.testing.assert_array_equal(base[:points], neutral.astype(np.float32))
    # each copy sits on a Coordinate point
    copies = base[points:].astype(np.float64)
    assert np.abs(copies[:, None] - neutral[None]).sum(axis=2).min(axis=1).max() < 1e-7
    lip_nodes = [i for i, n in enumerate(doc.nodes) if n.name == "LIP"]
    weights = np.array([decoded.channels(f)[(lip_nodes[0], "weights")] for f in range(5)])
    np.testing.assert_allclose(
        weights[:, :3],
        [[0, 0, 0], [0, 0.5, 0], [0, 1, 0], [0, 1, 0.5], [1.5, 0, 0]],  # -150: extrapolated
        atol=1e-7,
    )
    # instances of one mesh share its weights
    assert len(lip_nodes) == 2
    assert np.array_equal(
        decoded.channels(3)[(lip_nodes[0], "weights")],
        decoded.channels(3)[(lip_nodes[1], "weights")],
    )


def test_transforms_become_named_nodes_with_helpers_for_center_and_scale_orientation(rig, tmp_path):
    params = sweep(rig, n_frames=4, seed=1)
    decoded = Decoded(write_gltf(tmp_path / "a.glb", [rig], params, FPS))
    doc = decoded.doc
    names = [n.name for n in doc.nodes]
    for name in ("rig", "RIG", "RIG.scale", "RIG.center", "EYE", "EYE.center", "SQUASH",
                 "SQUASH.scale", "SQUASH.center", CAMERA_NODE):  # fmt: skip
        assert name in names, name
    assert names.count("JAW") == 2 and names.count("JAW.center") == 2
    # the animated fields are channels of the right nodes
    paths = {(doc.nodes[k[0]].name, k[1]) for k in decoded.channels(0)}
    assert {("JAW", "rotation"), ("EYE", "rotation"), ("EYE", "translation"),
            ("SQUASH.scale", "scale"), ("LIP", "weights")} <= paths  # fmt: skip
    # a VRML Transform's whole matrix, T·C·R·SR·S·SR⁻¹·C⁻¹, from its glTF nodes
    from vtts.vrml import transform_matrix

    for frame in range(4):
        anim = decoded.channels(frame)
        posed = rig.posed_scene(rig.engine.deform(params[frame]))
        for name in ("RIG", "EYE", "SQUASH"):
            outer = decoded.node_named(name) if name != "JAW" else None
            inner = decoded.node_named(f"{name}.center")
            m = decoded.world(inner, anim)
            parent = decoded.world(decoded.parents[outer], anim)
            np.testing.assert_allclose(
                np.linalg.inv(parent) @ m, transform_matrix(posed.node(name)), atol=1e-6
            )


def test_rotation_keyframes_turn_the_short_way(rig, tmp_path):
    params = np.zeros((40, N_PARAMS))
    params[:, 22] = np.linspace(-12000, 12000, 40)  # yaw_l_eyeball: through ±π about y
    decoded = Decoded(write_gltf(tmp_path / "a.glb", [rig], params, FPS))
    eye = decoded.node_named("EYE")
    q = np.array([decoded.channels(f)[(eye, "rotation")] for f in range(40)])
    assert (np.einsum("ij,ij->i", q[1:], q[:-1]) > 0).all()
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-6)


def test_camera_is_the_renderers(rig, head, tmp_path):
    cases = [
        dict(size=(352, 288)),
        dict(size=(320, 180), camera=Camera.parse("500,380,160,90")),  # fx != fy, unplaced
        dict(size=(240, 240), layout="room"),
    ]
    for kw in cases:
        models = [rig, head]
        doc = animation_gltf(models, np.zeros((2, N_PARAMS)), FPS, **kw)
        with FaceRenderer(models, **kw) as r:
            cam = r.camera
            node = next(n for n in doc.nodes if n.name == CAMERA_NODE)
            persp = doc.cameras[node.camera].perspective
            w, h = r.size
            assert math.isclose(persp.yfov, 2 * math.atan(h / 2 / cam.fy), rel_tol=1e-12)
            assert math.isclose(persp.aspectRatio, (w / h) * cam.fy / cam.fx, rel_tol=1e-12)
            assert math.isclose(persp.znear, cam.znear) and math.isclose(persp.zfar, cam.zfar)
            pose = Decoded.local(_Fake(doc), doc.nodes.index(node), {})
            np.testing.assert_allclose(pose, cam.pose, atol=1e-12)
            # a point projects to the same pixel through the glTF camera
            pts = np.array([[0.1, 0.2, 0.0], [-0.3, 0.1, 0.2], [0.0, -0.2, -0.1]])
            view = np.linalg.inv(pose)
            cam_pts = pts @ view[:3, :3].T + view[:3, 3]
            t = math.tan(persp.yfov / 2)
            ndc_x = cam_pts[:, 0] / (persp.aspectRatio * t * -cam_pts[:, 2])
            ndc_y = cam_pts[:, 1] / (t * -cam_pts[:, 2])
            pixels = np.c_[(ndc_x + 1) * w / 2, (1 - ndc_y) * h / 2]
            np.testing.assert_allclose(pixels, cam.project(pts), atol=1e-9)
            for i in range(2):
                root = next(n for n in doc.nodes if n.name == models[i].name)
                np.testing.assert_allclose(root.translation, r.model_matrix(i)[:3, 3])
            extras = doc.cameras[0].extras["vtts"]
            assert extras["size"] == [w, h] and extras["fx"] == cam.fx and extras["cy"] == cam.cy
    names = [n.name for n in animation_gltf([rig], np.zeros((1, N_PARAMS)), FPS,
                                            layout="room").nodes]  # fmt: skip
    assert "floor" in names and "wall" in names


class _Fake:
    """Enough of :class:`Decoded` for :meth:`Decoded.local` on an in-memory document."""

    def __init__(self, doc) -> None:
        self.doc = doc


def test_an_off_centre_camera_warns_and_keeps_its_intrinsics_in_extras(rig):
    with pytest.warns(vtts.errors.VttsWarning, match="principal point"):
        doc = animation_gltf(
            [rig], np.zeros((1, N_PARAMS)), FPS, camera=Camera.parse("400,400,100,144")
        )
    assert doc.cameras[0].extras["vtts"]["cx"] == 100.0


def test_viewpoint_camera_is_the_renderers(tmp_path):
    wrl = tmp_path / "vp.wrl"
    wrl.write_text(
        HEAD.read_text(encoding="utf-8")
        + "\nDEF SIDE Viewpoint { position 1.5 0.2 1.5 orientation 0 1 0 0.785 "
        "fieldOfView 0.6 }\n",
        encoding="utf-8",
    )
    (tmp_path / "vp.adt").write_text(HEAD.with_suffix(".adt").read_text("utf-8"), "utf-8")
    model = load_model(wrl)
    doc = animation_gltf([model], np.zeros((1, N_PARAMS)), FPS, viewpoint="SIDE")
    with FaceRenderer([model], viewpoint="SIDE") as r:
        node = next(n for n in doc.nodes if n.name == CAMERA_NODE)
        np.testing.assert_allclose(Decoded.local(_Fake(doc), doc.nodes.index(node), {}),
                                   r.camera.pose, atol=1e-12)  # fmt: skip
        assert math.isclose(doc.cameras[0].perspective.zfar, r.camera.zfar)
    with pytest.raises(RenderError, match="no Viewpoint named 'NOPE'"):
        animation_gltf([model], np.zeros((1, N_PARAMS)), FPS, viewpoint="NOPE")


def test_two_heads_are_placed_as_the_renderer_places_them(head, tmp_path):
    lotta = load_model("lotta")
    params = [sweep(lotta, 5, seed=2), sweep(head, 5, seed=4)]
    decoded = Decoded(write_gltf(tmp_path / "two.gltf", [lotta, head], params, FPS))
    roots = [n for n in decoded.doc.scenes[0].nodes if decoded.doc.nodes[n].name != CAMERA_NODE]
    assert [decoded.doc.nodes[n].name for n in roots] == ["lotta", "head"]
    assert decoded.doc.asset.extras["vtts"]["heads"] == ["lotta", "head"]
    with FaceRenderer([lotta, head]) as r:
        for frame in (0, 2, 4):
            expected = renderer_triangles(r, [params[0][frame], params[1][frame]])
            assert_same_triangles(decoded.triangles(frame), expected, 2.0)
    # the same model twice: two heads, named apart
    doc = animation_gltf([head, head], np.zeros((2, N_PARAMS)), FPS)
    assert doc.asset.extras["vtts"]["heads"] == ["head", "head-2"]


def test_root_poses_move_the_heads(head, tmp_path):
    params = np.zeros((6, N_PARAMS))
    base = placement([head, head]).matrices
    roots = np.repeat(base[1][None], 6, axis=0)
    roots[:, :3, 3] += np.linspace(0, 0.4, 6)[:, None] * [1.0, 0.5, -0.2]
    decoded = Decoded(
        write_gltf(tmp_path / "a.glb", [head, head], params, FPS, roots=[None, roots])
    )
    first = decoded.node_named("head")
    second = decoded.node_named("head-2")
    for frame in range(6):
        anim = decoded.channels(frame)
        assert (first, "translation") not in anim
        np.testing.assert_allclose(decoded.world(second, anim), roots[frame], atol=1e-6)
    with FaceRenderer([head, head]) as r:
        expected = renderer_triangles(r, params[5], roots=[None, roots[5]])
        got = decoded.triangles(5)
        np.testing.assert_allclose(got["FACE_MESH"][1], expected["FACE_MESH"][1], atol=1e-6)


def test_normals_follow_the_renderers_closely(tmp_path):
    """Normals are the one approximate part (the sum of each target's change): on poses as
    speech makes them they stay close to the renderer's, far closer than the neutral normals,
    and exact at the neutral and at a single MIAP's interval border."""
    model = load_model("cybatt")
    poses = [
        {},
        dict(visemes={1: 1.0}),  # a border of a single MIAP
        dict(visemes={1: 1.0}, expressions={"joy": 0.8}),
        dict(faps={"open_jaw": 600, "close_t_l_eyelid": 1024, "close_t_r_eyelid": 1024}),
        dict(visemes={10: 0.7, 4: 0.3}, expressions={"surprise": 0.6}),
    ]
    params = np.array([model.params(**p) for p in poses])
    decoded = Decoded(write_gltf(tmp_path / "a.glb", [model], params, FPS))
    face = decoded.node_named("FACE")
    points = decoded.doc.meshes[decoded.doc.nodes[face].mesh].extras["vtts"]["points"]
    _, neutral = decoded.mesh_positions(face, decoded.channels(0))
    with FaceRenderer([model]) as r:
        (am,) = [am for am in r.instances[0].meshes if am.name == "FACE"]
        # the renderer's vertex of each Coordinate point: its first
        first = np.full(points, -1)
        first[am.template.coord_index[::-1]] = np.arange(len(am.template.coord_index))[::-1]
        used = first >= 0

        def angles(normals: np.ndarray) -> np.ndarray:
            cos = np.einsum("ij,ij->i", normals[:points][used], am.last[2][first[used]])
            return np.degrees(np.arccos(np.clip(cos, -1, 1)))

        for frame in range(len(poses)):
            r.prepare(params[frame])
            got = angles(decoded.mesh_positions(face, decoded.channels(frame))[1])
            if frame <= 1:
                # the tolerance leaves out changes below 0.01 (0.6°), summed over targets
                assert got.max() < 2.0, frame
                continue
            assert np.median(got) < 0.5 and np.percentile(got, 90) < 3.0, frame
            assert got.mean() < angles(neutral).mean() / 2.5, frame


def test_textures_are_embedded_and_turned_to_gltf_coordinates(rig, tmp_path):
    model = load_model("cybatt")
    decoded = Decoded(write_gltf(tmp_path / "c.glb", [model], np.zeros((1, N_PARAMS)), FPS))
    (image,) = decoded.doc.images
    assert image.mimeType == "image/png" and image.uri is None
    png = Path(vtts.resources.models_dir()) / "cybatt-face.png"
    assert decoded.view(image.bufferView) == png.read_bytes()
    # the rig's PixelTexture (red, green / blue, white from the bottom row up) as a PNG, and
    # its texture coordinates flipped to glTF's v
    gltf = tmp_path / "r.gltf"
    write_gltf(gltf, [rig], np.zeros((1, N_PARAMS)), FPS)
    doc = Decoded(gltf)
    (img,) = doc.doc.images
    head, _, payload = img.uri.partition(",")
    assert head == "data:image/png;base64"
    import base64
    import io

    pixels = np.asarray(Image.open(io.BytesIO(base64.b64decode(payload))).convert("RGBA"))
    assert pixels[1, 0, :3].tolist() == [255, 0, 0]  # VRML's first pixel is the bottom left
    (lip,) = [m for m in doc.doc.meshes if m.name == "LIP"]
    uv = doc.accessor(lip.primitives[0].attributes.TEXCOORD_0)
    st = np.array([[0, 0], [0.5, 0], [1, 0], [0, 0.5], [0.5, 0.5], [1, 0.5], [0, 1], [0.5, 1],
                   [1, 1]])  # fmt: skip
    np.testing.assert_allclose(uv[:9], np.c_[st[:, 0], 1 - st[:, 1]])
    sampler = doc.doc.samplers[doc.doc.textures[0].sampler]
    assert (sampler.wrapS, sampler.wrapT) == (10497, 10497)  # VRML's repeatS/T default TRUE


def test_glb_and_gltf_hold_the_same_animation(head, tmp_path):
    params = sweep(head, 6, seed=9)
    a = Decoded(write_gltf(tmp_path / "a.glb", [head], params, FPS))
    b = Decoded(write_gltf(tmp_path / "a.gltf", [head], params, FPS))
    assert (tmp_path / "a.gltf").read_text(encoding="utf-8").startswith("{")
    for frame in (0, 3, 5):
        ta, tb = a.triangles(frame), b.triangles(frame)
        assert ta.keys() == tb.keys()
        for k in ta:
            assert all(np.array_equal(x, y) for x, y in zip(ta[k], tb[k], strict=True))
    assert [f.name for f in tmp_path.iterdir()] and all(
        not f.name.startswith(".") for f in tmp_path.iterdir()
    )


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        (dict(path="x.mp4"), "a glTF file ends in .glb or .gltf, not .mp4"),
        (dict(params=np.zeros((3, 12))), "parameters are (frames, 90) per model"),
        (dict(params=np.zeros((0, N_PARAMS))), "1–216000 frames, got 0"),
        (dict(params=np.full((2, N_PARAMS), np.nan)), "finite"),
        (dict(params=[np.zeros((2, N_PARAMS))] * 2), "1 models but 2 parameter tracks"),
        (dict(fps=0), "fps must be within"),
        (dict(fps="fast"), "fps must be a number"),
        (dict(roots=[np.zeros((3, 4, 4))]), "root poses are finite (2, 4, 4) matrices"),
        (dict(roots=[np.repeat(np.diag([1.0, -1, 1, 1])[None], 2, 0)]), "shears or mirrors"),
        (dict(size=(8, 8)), "image size must be within"),
        (dict(layout="circle"), "layout must be 'row' or 'room'"),
        (dict(models=[]), "no model given"),
    ],
)
def test_bad_arguments_are_clear_errors_and_write_nothing(head, tmp_path, kwargs, fragment):
    target = tmp_path / kwargs.pop("path", "out.glb")
    args = dict(models=[head], params=np.zeros((2, N_PARAMS)), fps=FPS) | kwargs
    with pytest.raises(ExportError) as e:
        write_gltf(target, args.pop("models"), args.pop("params"), args.pop("fps"), **args)
    assert fragment in str(e.value)
    assert list(tmp_path.iterdir()) == []


def test_a_failed_export_leaves_the_old_file(head, tmp_path, monkeypatch):
    out = tmp_path / "keep.glb"
    write_gltf(out, [head], np.zeros((2, N_PARAMS)), FPS)
    before = out.read_bytes()
    import pygltflib

    def broken(self, **kwargs):
        raise KeyboardInterrupt  # as Ctrl-C while the file is written

    monkeypatch.setattr(pygltflib.GLTF2, "gltf_to_json", broken)
    with pytest.raises(KeyboardInterrupt):
        write_gltf(out, [head], np.ones((2, N_PARAMS)), FPS)
    assert out.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["keep.glb"]


def test_missing_texture_warns_as_the_renderer_does(tmp_path):
    wrl = tmp_path / "t.wrl"
    wrl.write_text(
        "#VRML V2.0 utf8\nShape { appearance Appearance { texture ImageTexture { url "
        '"gone.png" } } geometry IndexedFaceSet { coord Coordinate { point [0 0 0, 1 0 0, '
        "0 1 0] } coordIndex [0 1 2 -1] } }\n",
        encoding="utf-8",
    )
    model = load_model(wrl)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        doc = animation_gltf([model], np.zeros((1, N_PARAMS)), FPS)
    assert any("'gone.png' not found" in str(w.message) for w in caught)
    assert doc.images == [] and doc.animations == []


def test_a_diffuse_colour_above_one_is_baked_into_its_own_texture(tmp_path):
    """glTF's baseColorFactor stops at 1: a Material lit brighter than the renderer's lights (a
    fitted head's skin, vtts.fit.head.set_exposure: diffuseColor above 1) exports its texture
    that much brighter in linear light (clipped at white) and a factor of 1 there; a Material
    sharing the file at diffuseColor ≤ 1 keeps the file as it is."""
    import io

    Image.new("RGB", (4, 4), (128, 200, 60)).save(tmp_path / "tex.png")
    tri = (
        "geometry IndexedFaceSet { coord Coordinate { point [0 0 0, 1 0 0, 0 1 0] } "
        "coordIndex [0 1 2 -1] }"
    )
    wrl = tmp_path / "t.wrl"
    wrl.write_text(
        "#VRML V2.0 utf8\n"
        "Shape { appearance Appearance { material Material { diffuseColor 1.5 1.2 1 } texture "
        f'ImageTexture {{ url "tex.png" }} }} {tri} }}\n'
        "Shape { appearance Appearance { material Material { diffuseColor 0.5 0.5 0.5 } texture "
        f'ImageTexture {{ url "tex.png" }} }} {tri} }}\n',
        encoding="utf-8",
    )
    model = load_model(wrl)
    decoded = Decoded(write_gltf(tmp_path / "t.glb", [model], np.zeros((1, N_PARAMS)), FPS))
    bright, plain = decoded.doc.materials
    assert bright.pbrMetallicRoughness.baseColorFactor == [1.0, 1.0, 1.0, 1.0]
    assert plain.pbrMetallicRoughness.baseColorFactor == [0.5, 0.5, 0.5, 1.0]

    def pixel(material) -> list[int]:
        texture = decoded.doc.textures[material.pbrMetallicRoughness.baseColorTexture.index]
        data = decoded.view(decoded.doc.images[texture.source].bufferView)
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))[0, 0].tolist()

    assert pixel(plain) == [128, 200, 60]
    lin = ((np.array([128, 200, 60]) / 255 + 0.055) / 1.055) ** 2.4 * [1.5, 1.2, 1.0]
    srgb = 1.055 * np.minimum(lin, 1) ** (1 / 2.4) - 0.055
    assert pixel(bright) == [round(v) for v in 255 * srgb]
    assert pixel(bright)[0] > 128 and pixel(bright)[2] == 60
