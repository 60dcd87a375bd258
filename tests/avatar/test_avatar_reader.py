"""Reading glTF avatars (vtts.gltf.reader): quantized, strided and sparse accessors, Draco and
meshopt compression, KTX2 textures dropped with a warning, and clear errors for broken or hostile
files. Every file is built by hand in the test (tests/avatar/avatar_helpers.py)."""

from __future__ import annotations

import warnings

import numpy as np
import pygltflib as gl
import pytest

from vtts.avatar.importer import import_avatar
from vtts.errors import AvatarError, VttsWarning
from vtts.face import Miap
from vtts.gltf import GltfReader
from vtts.limits import MAX_ACCESSOR_COUNT, MAX_MORPH_TARGETS

from .avatar_helpers import (
    BYTE,
    FLOAT,
    SHORT,
    UINT,
    USHORT,
    Builder,
    grid,
    moves,
    simple_avatar,
)


def rotated(faces: np.ndarray) -> np.ndarray:
    """Each triangle rotated to start at its smallest index (the winding kept)."""
    k = np.argmin(faces, axis=1)
    return np.stack([np.roll(f, -i) for f, i in zip(faces, k, strict=True)])


def read_mesh(path):
    return GltfReader(path, error=AvatarError).mesh(0)


def test_a_float_avatar_reads_back_exactly(tmp_path):
    path = simple_avatar(tmp_path / "a.glb")
    (prim,) = read_mesh(path).primitives
    pos, faces = grid()
    assert np.allclose(prim.positions, pos) and np.array_equal(prim.faces, faces)
    assert np.allclose(prim.targets[0], moves(len(pos), 1))


@pytest.mark.parametrize(
    "ctype,normalized,scale",
    [(SHORT, False, 1 / 1000), (USHORT, False, 1 / 1000), (BYTE, True, 0.5), (SHORT, True, 0.5)],
    ids=["int16", "uint16", "int8-normalized", "int16-normalized"],
)
def test_quantized_positions_and_targets(tmp_path, ctype, normalized, scale):
    """KHR_mesh_quantization: integer positions (unnormalized, their scale in the node, or
    normalized) and normalized 8-bit morph targets."""
    pos, faces = grid()
    pos = pos + 0.5  # within 0–1: unsigned types too
    b = Builder()
    if normalized:
        limit = 127 if ctype == BYTE else 32767
        stored = np.round(pos / 2 * limit)  # value = stored / limit, times the node's 2
        node_scale = [2.0, 2.0, 2.0]
    else:
        stored = np.round(pos * 1000)
        node_scale = [scale] * 3
    p = b.accessor(stored, ctype, normalized=normalized)
    delta = moves(len(pos), 3, (0.0, -0.5, 0.0))
    t = b.accessor(np.round(delta * 127), BYTE, normalized=True)
    idx = b.accessor(faces.reshape(-1), USHORT)
    mesh = b.mesh({"POSITION": p}, idx, [{"POSITION": t}], ["jawOpen"])
    b.doc.extensionsUsed = b.doc.extensionsRequired = ["KHR_mesh_quantization"]
    b.node(name="Head", mesh=mesh, scale=node_scale)
    path = b.save(tmp_path / "q.glb")
    (prim,) = read_mesh(path).primitives
    want = stored / (127 if ctype == BYTE else 32767) if normalized else stored
    assert np.allclose(prim.positions, want)
    assert np.allclose(prim.targets[0], np.round(delta * 127) / 127)
    avatar = import_avatar(path)
    head = avatar.scene.node("Head")
    assert np.allclose(head["scale"], node_scale)  # the dequantization stays in the node


@pytest.mark.parametrize("stride", [16, 14, 252])
def test_strided_positions_are_read(tmp_path, stride):
    """Interleaved or padded elements: any byteStride from the element size to 252 is read (14 is
    not a multiple of 4, as glTF wants, but nothing stops reading it)."""
    pos, faces = grid()
    b = Builder()
    p = b.accessor(pos, FLOAT, stride=stride)
    idx = b.accessor(faces.reshape(-1), UINT)
    b.node(mesh=b.mesh({"POSITION": p}, idx, [], []))
    (prim,) = read_mesh(b.save(tmp_path / "s.glb")).primitives
    assert np.allclose(prim.positions, pos)


@pytest.mark.parametrize(
    "stride,message",
    [(-12, "byteStride -12 is not positive"), (8, "byteStride 8 is smaller than one element"),
     (256, "byteStride 256 is more than glTF's 252")],
)  # fmt: skip
def test_bad_strides_are_clear_errors(tmp_path, stride, message):
    pos, faces = grid()
    b = Builder()
    p = b.accessor(pos)
    b.doc.bufferViews[b.doc.accessors[p].bufferView].byteStride = stride
    b.node(mesh=b.mesh({"POSITION": p}, None, [], []))
    path = b.save(tmp_path / "bad.glb")
    with pytest.raises(AvatarError, match=message) as e:
        import_avatar(path)
    assert e.value.file == str(path)


def test_sparse_targets(tmp_path):
    pos, faces = grid()
    b = Builder()
    p = b.accessor(pos)
    idx_view = b.view(np.array([2, 7], np.uint16).tobytes())
    val_view = b.view(np.array([[0, 0.1, 0], [0, 0.2, 0]], np.float32).tobytes())
    b.doc.accessors.append(gl.Accessor(
        componentType=FLOAT, count=len(pos), type="VEC3",
        sparse=gl.Sparse(count=2, indices=gl.AccessorSparseIndices(bufferView=idx_view,
                                                                   componentType=USHORT),
                         values=gl.AccessorSparseValues(bufferView=val_view))))  # fmt: skip
    t = len(b.doc.accessors) - 1
    b.node(mesh=b.mesh({"POSITION": p}, b.accessor(faces.reshape(-1), USHORT),
                       [{"POSITION": t}], ["mouthClose"]))  # fmt: skip
    (prim,) = read_mesh(b.save(tmp_path / "sp.glb")).primitives
    want = np.zeros((len(pos), 3))
    want[2, 1], want[7, 1] = 0.1, 0.2
    assert np.allclose(prim.targets[0], want)


def test_draco_compressed_mesh(tmp_path):
    import DracoPy

    pos, faces = grid(6)
    data = DracoPy.encode(pos.astype(np.float32), faces.astype(np.uint32), preserve_order=True,
                          quantization_bits=16)  # fmt: skip
    b = Builder()
    view = b.view(data)
    position_id = next(a["unique_id"] for a in DracoPy.decode(data).attributes
                       if a["attribute_type"] == 0)  # fmt: skip
    b.doc.accessors.append(gl.Accessor(componentType=FLOAT, count=len(pos), type="VEC3",
                                       min=[-0.5, -0.5, 0], max=[0.5, 0.5, 0]))  # fmt: skip
    p = len(b.doc.accessors) - 1
    b.doc.accessors.append(gl.Accessor(componentType=UINT, count=faces.size, type="SCALAR"))
    idx = len(b.doc.accessors) - 1
    t = b.accessor(moves(len(pos), 4))
    ext = {"KHR_draco_mesh_compression": {"bufferView": view,
                                          "attributes": {"POSITION": position_id}}}  # fmt: skip
    b.node(name="Head", mesh=b.mesh({"POSITION": p}, idx, [{"POSITION": t}], ["jawOpen"],
                                    extensions=ext))  # fmt: skip
    b.doc.extensionsUsed = b.doc.extensionsRequired = ["KHR_draco_mesh_compression"]
    (prim,) = read_mesh(b.save(tmp_path / "d.glb")).primitives
    decoded = prim.positions[prim.faces]
    assert np.allclose(np.sort(decoded.reshape(-1, 3), axis=0),
                       np.sort(pos[faces].reshape(-1, 3), axis=0), atol=1e-4)  # fmt: skip
    assert np.allclose(prim.positions, pos, atol=1e-4)  # the order kept (preserve_order)


def test_broken_draco_data_is_a_clear_error(tmp_path):
    b = Builder()
    view = b.view(b"not draco at all")
    b.doc.accessors.append(gl.Accessor(componentType=FLOAT, count=3, type="VEC3"))
    ext = {"KHR_draco_mesh_compression": {"bufferView": view, "attributes": {"POSITION": 0}}}
    b.node(mesh=b.mesh({"POSITION": 0}, None, [], [], extensions=ext))
    with pytest.raises(AvatarError, match="KHR_draco_mesh_compression.*cannot decode"):
        import_avatar(b.save(tmp_path / "d.glb"))


@pytest.mark.parametrize("extension", ["EXT_meshopt_compression", "KHR_meshopt_compression"])
def test_meshopt_compressed_buffer_views(tmp_path, extension):
    """EXT_meshopt_compression: vertex attributes and triangle indices decoded by the meshoptimizer
    package; the bufferViews' own buffer is a fallback without data."""
    import meshoptimizer

    pos, faces = grid(6)
    b = Builder()
    b.doc.buffers.append(gl.Buffer(byteLength=10**6, extensions={extension: {"fallback": True}}))
    vdata = meshoptimizer.encode_vertex_buffer(pos.astype(np.float32))
    idata = meshoptimizer.encode_index_buffer(faces.reshape(-1).astype(np.uint32),
                                              vertex_count=len(pos))  # fmt: skip
    views = []
    for data, count, stride, mode in ((vdata, len(pos), 12, "ATTRIBUTES"),
                                      (idata, faces.size, 4, "TRIANGLES")):  # fmt: skip
        off = b.doc.bufferViews[b.view(data)].byteOffset
        b.doc.bufferViews.append(
            gl.BufferView(
                buffer=1,
                byteOffset=0,
                byteLength=count * stride,
                byteStride=stride if mode == "ATTRIBUTES" else None,
                extensions={
                    extension: {
                        "buffer": 0,
                        "byteOffset": off,
                        "byteLength": len(data),
                        "byteStride": stride,
                        "count": count,
                        "mode": mode,
                    }
                },
            )
        )
        views.append(len(b.doc.bufferViews) - 1)
    p = b.accessor(pos, view=views[0])
    b.doc.accessors.append(gl.Accessor(bufferView=views[1], componentType=UINT,
                                       count=faces.size, type="SCALAR"))  # fmt: skip
    b.node(mesh=b.mesh({"POSITION": p}, len(b.doc.accessors) - 1, [], []))
    b.doc.extensionsUsed = b.doc.extensionsRequired = [extension]
    (prim,) = read_mesh(b.save(tmp_path / "m.glb")).primitives
    assert np.allclose(prim.positions, pos)
    # the index codec keeps every triangle and its winding, but may start it at another corner
    assert np.array_equal(rotated(prim.faces), rotated(faces))


def test_a_ktx2_texture_is_dropped_with_a_warning(tmp_path):
    pos, faces = grid()
    b = Builder()
    p = b.accessor(pos)
    uv = b.accessor(pos[:, :2] + 0.5)
    ktx2 = b"\xabKTX 20\xbb\r\n\x1a\n" + bytes(64)
    b.doc.images.append(gl.Image(bufferView=b.view(ktx2), mimeType="image/ktx2"))
    b.doc.textures.append(gl.Texture(extensions={"KHR_texture_basisu": {"source": 0}}))
    b.doc.materials.append(gl.Material(pbrMetallicRoughness=gl.PbrMetallicRoughness(
        baseColorTexture=gl.TextureInfo(index=0))))  # fmt: skip
    b.doc.extensionsUsed = b.doc.extensionsRequired = ["KHR_texture_basisu"]
    b.node(
        name="Head",
        mesh=b.mesh(
            {"POSITION": p, "TEXCOORD_0": uv},
            b.accessor(faces.reshape(-1), USHORT),
            [],
            [],
            material=0,
        ),
    )
    path = b.save(tmp_path / "k.glb")
    with pytest.warns(VttsWarning, match="KTX2/Basis Universal.*untextured"):
        avatar = import_avatar(path)
    assert avatar.scene.find("ImageTexture") == [] and avatar.images == {}
    assert avatar.scene.find("IndexedFaceSet")  # the mesh is there


def test_a_png_texture_is_kept(tmp_path):
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (4, 4), (200, 10, 10)).save(buf, format="PNG")
    pos, faces = grid()
    b = Builder()
    p = b.accessor(pos)
    uv = b.accessor(pos[:, :2] + 0.5)
    b.doc.images.append(gl.Image(bufferView=b.view(buf.getvalue()), mimeType="image/png"))
    b.doc.textures.append(gl.Texture(source=0))
    b.doc.materials.append(gl.Material(pbrMetallicRoughness=gl.PbrMetallicRoughness(
        baseColorTexture=gl.TextureInfo(index=0))))  # fmt: skip
    b.node(
        name="Head",
        mesh=b.mesh(
            {"POSITION": p, "TEXCOORD_0": uv},
            b.accessor(faces.reshape(-1), USHORT),
            [],
            [],
            material=0,
        ),
    )
    avatar = import_avatar(b.save(tmp_path / "t.glb"))
    files = avatar.write(tmp_path / "out.wrl")
    assert [f.name for f in files] == ["out.wrl", "out.adt", "out-tex0.png"]
    assert files[2].read_bytes() == buf.getvalue()
    (tex,) = avatar.scene.find("ImageTexture")
    assert list(tex["url"]) == ["image0"]  # the scene keeps its key; the file says out-tex0.png
    assert 'url "out-tex0.png"' in files[0].read_text() or "out-tex0.png" in files[0].read_text()


# ---- errors -----------------------------------------------------------------------------------


def test_an_unknown_required_extension_is_named(tmp_path):
    b = Builder()
    b.doc.extensionsRequired = ["EXT_something_new"]
    b.node(mesh=b.mesh({"POSITION": b.accessor(grid()[0])}, None, [], []))
    with pytest.raises(AvatarError, match="requires the glTF extension EXT_something_new"):
        import_avatar(b.save(tmp_path / "x.glb"))


def test_a_hostile_accessor_count_is_refused_before_allocating(tmp_path):
    b = Builder()
    p = b.accessor(grid()[0])
    b.doc.accessors[p].count = 10**12
    b.node(mesh=b.mesh({"POSITION": p}, None, [], []))
    with pytest.raises(AvatarError, match=f"more than the limit of {MAX_ACCESSOR_COUNT}"):
        import_avatar(b.save(tmp_path / "x.glb"))


def test_too_many_morph_targets_are_refused(tmp_path):
    pos, _ = grid()
    b = Builder()
    p = b.accessor(pos)
    t = b.accessor(np.zeros_like(pos))
    b.node(mesh=b.mesh({"POSITION": p}, None, [{"POSITION": t}] * (MAX_MORPH_TARGETS + 1), []))
    with pytest.raises(AvatarError, match=f"more than the limit of {MAX_MORPH_TARGETS}"):
        import_avatar(b.save(tmp_path / "x.glb"))


def test_an_accessor_past_its_buffer_is_refused(tmp_path):
    b = Builder()
    p = b.accessor(grid()[0])
    b.doc.accessors[p].count = 1000
    b.node(mesh=b.mesh({"POSITION": p}, None, [], []))
    with pytest.raises(AvatarError, match="reach past the end of bufferView"):
        import_avatar(b.save(tmp_path / "x.glb"))


def test_a_triangle_naming_a_missing_vertex_is_refused(tmp_path):
    b = Builder()
    p = b.accessor(grid()[0])
    b.node(mesh=b.mesh({"POSITION": p}, b.accessor(np.array([0, 1, 99]), USHORT), [], []))
    with pytest.raises(AvatarError, match="names vertex 99"):
        import_avatar(b.save(tmp_path / "x.glb"))


def test_a_node_cycle_is_refused(tmp_path):
    b = Builder()
    b.node(name="a", children=[1], mesh=b.mesh({"POSITION": b.accessor(grid()[0])}, None, [], []))
    b.node(name="b", children=[0])
    with pytest.raises(AvatarError, match="its own ancestor"):
        import_avatar(b.save(tmp_path / "x.glb", roots=[0]))


@pytest.mark.parametrize(
    "content,message",
    [(b"glTF\x02\x00\x00\x00garbage", "not a readable glTF file"),
     (b"{not json", "not a readable glTF file"),
     (b'{"asset": {"version": "1.0"}}', "only glTF 2.x")],
)  # fmt: skip
def test_files_that_are_not_gltf(tmp_path, content, message):
    path = tmp_path / "x.glb"
    path.write_bytes(content)
    with pytest.raises(AvatarError, match=message):
        import_avatar(path)


def test_a_file_without_meshes(tmp_path):
    b = Builder()
    b.node(name="empty")
    with pytest.raises(AvatarError, match="no triangle mesh"):
        import_avatar(b.save(tmp_path / "x.glb"))


def test_points_primitives_are_skipped_with_a_warning(tmp_path):
    pos, faces = grid()
    b = Builder()
    p = b.accessor(pos)
    b.node(mesh=b.mesh({"POSITION": p}, b.accessor(faces.reshape(-1), USHORT), [], []))
    b.doc.meshes[0].primitives.append(gl.Primitive(attributes=gl.Attributes(POSITION=p), mode=0))
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        avatar = import_avatar(b.save(tmp_path / "x.glb"))
    assert any("POINTS primitives are not drawn" in str(x.message) for x in w)
    assert len(avatar.scene.find("IndexedFaceSet")) == 1


def test_fap_tables_follow_the_recipe(tmp_path):
    """jawOpen moving one vertex by 0.1 makes open_jaw's table 0.1 / 1000 per unit (the recipe:
    open_jaw at +1000 looks like jawOpen at 1)."""
    from vtts.avatar.arkit import recipes

    avatar = import_avatar(simple_avatar(tmp_path / "a.glb", ["jawOpen"]))
    row = recipes().fap(3, 1)
    (table,) = avatar.tables.adts[Miap("fap", 3)].meshes
    assert table.borders.tolist() == [0.0, row.amplitude]
    assert table.vertices.tolist() == [1]
    assert np.allclose(table.displacements[0, 0], [0, -0.1 * row.shapes["jawOpen"] / 1000, 0])


# ---- node tree, skins, eyes -------------------------------------------------------------------


def _sphere(n: int = 8, radius: float = 0.1):
    """The front half of a sphere around the origin: positions, triangles."""
    th, ph = np.meshgrid(np.linspace(0, np.pi / 2, n), np.linspace(0, 2 * np.pi, n))
    pos = radius * np.c_[(np.sin(th) * np.cos(ph)).ravel(), (np.sin(th) * np.sin(ph)).ravel(),
                         np.cos(th).ravel()]  # fmt: skip
    faces = [
        (r * n + c, r * n + c + 1, (r + 1) * n + c) for r in range(n - 1) for c in range(n - 1)
    ]
    return pos, np.array(faces)


def test_a_nested_eye_turns_about_its_centre_in_the_heads_axes(tmp_path):
    """An eye node under a parent turned 90° about z: its Transform's rotation axes are the head's
    y (yaw) and x (pitch) axes written in the eye's own frame, its centre the sphere's centre."""
    pos, faces = _sphere()
    b = Builder()
    eye = b.mesh({"POSITION": b.accessor(pos)}, b.accessor(faces.reshape(-1), USHORT), [], [],
                 name="EyeMesh")  # fmt: skip
    b.node(name="Eye_L", mesh=eye, translation=[0.3, 0.2, 0.0])
    quarter = [0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)]  # 90° about z
    b.node(name="Head", children=[0], rotation=quarter)
    avatar = import_avatar(b.save(tmp_path / "e.glb", roots=[1]))
    assert avatar.eyes == ["left"]
    tables = avatar.tables
    (yaw,) = tables.adts[Miap("fap", 23)].transforms
    (pitch,) = tables.adts[Miap("fap", 25)].transforms
    assert yaw.node == pitch.node == "L_EYE_ROTATION"
    # the head's y axis is the eye frame's -x after a 90° turn about z; its x axis the frame's y
    assert np.allclose(yaw.neutral[:3], [1, 0, 0], atol=1e-6) or np.allclose(
        yaw.neutral[:3], [-1, 0, 0], atol=1e-6)  # fmt: skip
    assert np.allclose(np.abs(pitch.neutral[:3]), [0, 1, 0], atol=1e-6)
    centre = avatar.scene.node("L_EYE_ROTATION")["center"]
    assert np.allclose(centre, 0, atol=1e-6)  # the sphere's centre, not the half's box
    assert Miap("fap", 24) not in tables.adts  # no right eye


def test_a_skinned_mesh_is_posed_at_its_rest_pose(tmp_path):
    """A skinned eye mesh bound to a joint named LeftEye: its vertices go through the joint's world
    matrix times its inverse bind matrix, and it sits at the top of the scene."""
    pos, faces = _sphere()
    b = Builder()
    p = b.accessor(pos)
    joints = b.accessor(np.zeros((len(pos), 4)), USHORT)
    weights = b.accessor(np.c_[np.ones(len(pos)), np.zeros((len(pos), 3))])
    mesh = b.mesh({"POSITION": p, "JOINTS_0": joints, "WEIGHTS_0": weights},
                  b.accessor(faces.reshape(-1), USHORT), [], [], name="Eyes")  # fmt: skip
    ibm = np.eye(4)
    ibm[:3, 3] = [0.0, -1.0, 0.0]  # bound where the joint stood at y = 1
    b.doc.accessors.append(gl.Accessor(
        bufferView=b.view(ibm.T.astype(np.float32).tobytes()), componentType=FLOAT, count=1,
        type="MAT4"))  # fmt: skip
    b.node(name="LeftEye", translation=[0.3, 1.2, 0.0])  # the joint, 0.2 above its bind pose
    b.node(name="Body", mesh=mesh, skin=0, translation=[5.0, 5.0, 5.0])  # ignored (glTF)
    b.doc.skins.append(gl.Skin(joints=[0], inverseBindMatrices=len(b.doc.accessors) - 1))
    avatar = import_avatar(b.save(tmp_path / "s.glb", roots=[0, 1]))
    assert avatar.eyes == ["left"]
    points = avatar.scene.node("Eyes")["coord"]["point"]
    want = pos + [0.3, 0.2, 0.0]  # (the pole and the seam's copies joined into one point each)
    gap = np.linalg.norm(points[:, None] - want[None], axis=2)
    assert gap.min(axis=0).max() < 1e-6 and gap.min(axis=1).max() < 1e-6
    assert avatar.scene.roots[-1].name == "L_EYE_ROTATION"  # at the top, outside Body


# ---- .gltf with files beside it ---------------------------------------------------------------


def _gltf_with_files(folder, image_name: str = "skin.png", buffer_uri: str = "mesh.bin"):
    """A JSON .gltf whose buffer and PNG image are files beside it."""
    import io

    from PIL import Image

    pos, faces = grid()
    b = Builder()
    p = b.accessor(pos)
    uv = b.accessor(pos[:, :2] + 0.5)
    idx = b.accessor(faces.reshape(-1), USHORT)
    buf = io.BytesIO()
    Image.new("RGB", (4, 4), (10, 200, 10)).save(buf, format="PNG")
    (folder / image_name).write_bytes(buf.getvalue())
    b.doc.images.append(gl.Image(uri=image_name))
    b.doc.textures.append(gl.Texture(source=0))
    b.doc.materials.append(gl.Material(pbrMetallicRoughness=gl.PbrMetallicRoughness(
        baseColorTexture=gl.TextureInfo(index=0))))  # fmt: skip
    b.node(name="Head", mesh=b.mesh({"POSITION": p, "TEXCOORD_0": uv}, idx, [], [], material=0))
    b.doc.scenes = [gl.Scene(nodes=[0])]
    (folder / "mesh.bin").write_bytes(bytes(b.blob))
    b.doc.buffers = [gl.Buffer(uri=buffer_uri, byteLength=len(b.blob))]
    path = folder / "avatar.gltf"
    path.write_text(b.doc.gltf_to_json(), encoding="utf-8")
    return path, buf.getvalue()


def test_a_gltf_with_its_buffer_and_image_beside_it(tmp_path):
    path, png = _gltf_with_files(tmp_path)
    with pytest.warns(VttsWarning, match="static scene"):
        avatar = import_avatar(path)
    assert [p.name for p in avatar.sources] == ["mesh.bin", "skin.png"]
    assert list(avatar.images.values())[0].data == png


def test_a_buffer_outside_the_files_folder_is_refused(tmp_path):
    (tmp_path / "inner").mkdir()
    path, _ = _gltf_with_files(tmp_path / "inner", buffer_uri="../mesh.bin")
    (tmp_path / "mesh.bin").write_bytes((tmp_path / "inner" / "mesh.bin").read_bytes())
    with pytest.raises(AvatarError, match="not a file inside the glTF file's folder"):
        import_avatar(path)


def test_adi_import_never_writes_over_the_avatars_own_image(tmp_path, capsys):
    from adt_tools.cli import main as adi

    path, png = _gltf_with_files(tmp_path, image_name="out-tex0.png")
    assert adi(["import", str(path), "-o", str(tmp_path / "out.wrl")]) == 1
    assert "also an input" in capsys.readouterr().err
    assert (tmp_path / "out-tex0.png").read_bytes() == png
    assert not (tmp_path / "out.wrl").exists()


def test_meshopt_octahedral_filter_on_normals(tmp_path):
    """A meshopt ATTRIBUTES view with the OCTAHEDRAL filter: 4-byte elements (x, y on the
    octahedron, the scale K, w) decode to normalized int8 normals; (0, 0, 127) is +z."""
    import meshoptimizer

    pos, faces = grid()
    n = len(pos)
    raw = np.tile(np.array([0, 0, 127, 0], np.int8), (n, 1))
    raw[0] = [127, 0, 127, 0]  # x at the octahedron's corner: the normal +x
    data = meshoptimizer.encode_vertex_buffer(raw.view(np.uint8).reshape(n, 4).view(np.float32))
    b = Builder()
    b.doc.buffers.append(
        gl.Buffer(byteLength=n * 4, extensions={"EXT_meshopt_compression": {"fallback": True}})
    )
    off = b.doc.bufferViews[b.view(data)].byteOffset
    b.doc.bufferViews.append(gl.BufferView(
        buffer=1, byteLength=n * 4, byteStride=4,
        extensions={"EXT_meshopt_compression": {"buffer": 0, "byteOffset": off,
                    "byteLength": len(data), "byteStride": 4, "count": n, "mode": "ATTRIBUTES",
                    "filter": "OCTAHEDRAL"}}))  # fmt: skip
    normals = b.accessor(np.zeros((n, 3)), BYTE, normalized=True, view=len(b.doc.bufferViews) - 1)
    b.doc.accessors[normals].min = b.doc.accessors[normals].max = None
    p = b.accessor(pos)
    b.node(mesh=b.mesh({"POSITION": p, "NORMAL": normals}, b.accessor(faces.reshape(-1), USHORT),
                       [], []))  # fmt: skip
    b.doc.extensionsUsed = b.doc.extensionsRequired = ["EXT_meshopt_compression"]
    (prim,) = read_mesh(b.save(tmp_path / "o.glb")).primitives
    assert np.allclose(prim.normals[1:], [0, 0, 1], atol=1e-2)
    assert np.allclose(prim.normals[0], [1, 0, 0], atol=1e-2)


def test_an_unknown_meshopt_filter_is_named(tmp_path):
    import meshoptimizer

    pos, _ = grid()
    data = meshoptimizer.encode_vertex_buffer(pos.astype(np.float32))
    b = Builder()
    off = b.doc.bufferViews[b.view(data)].byteOffset
    b.doc.bufferViews.append(gl.BufferView(
        buffer=0, byteLength=len(pos) * 12,
        extensions={"EXT_meshopt_compression": {"buffer": 0, "byteOffset": off,
                    "byteLength": len(data), "byteStride": 12, "count": len(pos),
                    "mode": "ATTRIBUTES", "filter": "SQUASH"}}))  # fmt: skip
    p = b.accessor(pos, view=len(b.doc.bufferViews) - 1)
    b.node(mesh=b.mesh({"POSITION": p}, None, [], []))
    with pytest.raises(AvatarError, match="unknown filter 'SQUASH'"):
        import_avatar(b.save(tmp_path / "f.glb"))


def test_texture_coordinates_set_and_transform(tmp_path):
    """The base color texture's texCoord (TEXCOORD_1 here) and its KHR_texture_transform
    (offset, rotation, scale) are applied before v is flipped into VRML's t."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (4, 4), (200, 10, 10)).save(buf, format="PNG")
    pos, faces = grid()
    b = Builder()
    p = b.accessor(pos)
    uv0 = b.accessor(np.zeros((len(pos), 2)))
    uv = pos[:, :2] + 0.5
    uv1 = b.accessor(uv)
    b.doc.images.append(gl.Image(bufferView=b.view(buf.getvalue()), mimeType="image/png"))
    b.doc.textures.append(gl.Texture(source=0))
    info = gl.TextureInfo(index=0, texCoord=1, extensions={"KHR_texture_transform": {
        "offset": [0.5, 0.25], "scale": [2.0, 1.0], "rotation": float(np.pi / 2)}})  # fmt: skip
    b.doc.materials.append(gl.Material(pbrMetallicRoughness=gl.PbrMetallicRoughness(
        baseColorTexture=info)))  # fmt: skip
    b.doc.extensionsUsed = ["KHR_texture_transform"]
    b.node(
        name="Head",
        mesh=b.mesh(
            {"POSITION": p, "TEXCOORD_0": uv0, "TEXCOORD_1": uv1},
            b.accessor(faces.reshape(-1), USHORT),
            [],
            [],
            material=0,
        ),
    )
    avatar = import_avatar(b.save(tmp_path / "t.glb"))
    (ifs,) = avatar.scene.find("IndexedFaceSet")
    st = np.asarray(ifs["texCoord"]["point"])
    # scaled, then turned by pi/2 as the extension's GLSL turns it ((u, v) -> (-v, u)), then
    # offset
    su, sv = 2.0 * uv[:, 0], 1.0 * uv[:, 1]
    want_u = -sv + 0.5
    want_v = su + 0.25
    assert np.allclose(st, np.c_[want_u, 1.0 - want_v], atol=1e-6)


def test_the_file_size_is_capped(tmp_path, monkeypatch):
    import vtts.gltf.reader as reader
    from vtts.limits import LimitError

    path = simple_avatar(tmp_path / "a.glb")
    monkeypatch.setattr(reader, "MAX_GLTF_BYTES", 100)
    with pytest.raises(LimitError, match="larger than the limit of 100 bytes") as e:
        GltfReader(path, error=AvatarError)
    assert e.value.file == str(path)


def test_an_avatar_must_be_gltf_by_name(tmp_path):
    path = tmp_path / "a.obj"
    path.write_text("v 0 0 0\n", encoding="utf-8")
    with pytest.raises(AvatarError, match=r"a \.glb or \.gltf file, not \.obj"):
        import_avatar(path)
    (tmp_path / "x.glb").mkdir()
    with pytest.raises(AvatarError, match="is a folder"):
        import_avatar(tmp_path / "x.glb")


def test_an_animated_mesh_in_a_turned_frame_is_placed_in_the_scenes_frame(tmp_path):
    """A Z-up rig: the face mesh under a node turned -90° about x. Its points and its tables are
    written in the scene's y-up frame (FAPs and FAPUs are defined on those axes), the node stays
    in the tree; a static mesh in the same frame keeps its local coordinates."""
    pos, faces = grid()
    b = Builder()
    p = b.accessor(pos)
    down_in_z = moves(len(pos), 1, (0.0, 0.0, -0.1))  # "down" in a Z-up frame
    face = b.mesh({"POSITION": p}, b.accessor(faces.reshape(-1), USHORT),
                  [{"POSITION": b.accessor(down_in_z)}], ["jawOpen"], name="Face")  # fmt: skip
    static = b.mesh({"POSITION": p}, b.accessor(faces.reshape(-1), USHORT), [], [], name="Hat")
    b.node(name="FaceNode", mesh=face)
    b.node(name="HatNode", mesh=static)
    s = np.sin(np.pi / 4)
    b.node(name="Armature", children=[0, 1], rotation=[-s, 0.0, 0.0, s])
    avatar = import_avatar(b.save(tmp_path / "z.glb", roots=[2]))
    turn = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]])  # -90° about x: z -> y, y -> -z
    assert np.allclose(avatar.scene.node("Face")["coord"]["point"], pos @ turn.T, atol=1e-6)
    (table,) = avatar.tables.adts[Miap("fap", 3)].meshes
    assert np.allclose(table.displacements[0, 0], [0, -0.1 / 1000, 0])
    assert np.allclose(avatar.scene.node("Hat")["coord"]["point"], pos)
    assert "Armature" in avatar.scene.defs and "HatNode" in avatar.scene.defs


def test_a_webp_texture_is_converted_to_png(tmp_path):
    """EXT_texture_webp: the WebP image (Pillow decodes it) is written as PNG."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (8, 8), (10, 20, 200)).save(buf, format="WEBP", lossless=True)
    pos, faces = grid()
    b = Builder()
    p = b.accessor(pos)
    uv = b.accessor(pos[:, :2] + 0.5)
    b.doc.images.append(gl.Image(bufferView=b.view(buf.getvalue()), mimeType="image/webp"))
    b.doc.textures.append(gl.Texture(extensions={"EXT_texture_webp": {"source": 0}}))
    b.doc.materials.append(gl.Material(pbrMetallicRoughness=gl.PbrMetallicRoughness(
        baseColorTexture=gl.TextureInfo(index=0))))  # fmt: skip
    b.doc.extensionsUsed = b.doc.extensionsRequired = ["EXT_texture_webp"]
    b.node(
        name="Head",
        mesh=b.mesh(
            {"POSITION": p, "TEXCOORD_0": uv},
            b.accessor(faces.reshape(-1), USHORT),
            [],
            [],
            material=0,
        ),
    )
    avatar = import_avatar(b.save(tmp_path / "w.glb"))
    (img,) = avatar.images.values()
    assert img.format == "png"
    with Image.open(io.BytesIO(img.data)) as im:
        assert im.format == "PNG" and im.convert("RGB").getpixel((3, 3)) == (10, 20, 200)


@pytest.mark.parametrize("count, stride", [(50_000_000, 256), (3_000_000, 256), (50_000_000, 12)])
def test_a_meshopt_view_decoding_to_gigabytes_is_refused(tmp_path, count, stride):
    """A few bytes of meshopt data declaring 50M elements of 256 bytes: the decoder allocates
    12.8 GB before it reads a byte (run in a process limited to 3 GB)."""
    from ..hostile import run_cli

    pos, faces = grid(3)
    b = Builder()
    ext = "EXT_meshopt_compression"
    b.doc.buffers.append(gl.Buffer(byteLength=10**6, extensions={ext: {"fallback": True}}))
    off = b.doc.bufferViews[b.view(bytes(64))].byteOffset
    b.doc.bufferViews.append(gl.BufferView(buffer=1, byteLength=count * stride, byteStride=stride,
        extensions={ext: {"buffer": 0, "byteOffset": off, "byteLength": 64, "byteStride": stride,
                          "count": count, "mode": "ATTRIBUTES"}}))  # fmt: skip
    b.doc.accessors.append(gl.Accessor(bufferView=len(b.doc.bufferViews) - 1, componentType=FLOAT,
                                       count=len(pos), type="VEC3"))  # fmt: skip
    p = len(b.doc.accessors) - 1
    b.node(mesh=b.mesh({"POSITION": p}, b.accessor(faces.reshape(-1), USHORT), [], []))
    b.doc.extensionsUsed = b.doc.extensionsRequired = [ext]
    path = b.save(tmp_path / "m.glb")
    r = run_cli("adi", "import", str(path), "-o", "out.wrl", cwd=tmp_path)
    assert r.returncode == 1, r.stderr[-2000:]
    assert "decode to more than the limit of 512 MiB" in r.stderr and "Traceback" not in r.stderr
