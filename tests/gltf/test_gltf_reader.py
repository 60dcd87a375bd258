"""The one glTF reader (vtts.gltf.reader) behind both of its users: ``adi import`` (an avatar,
:func:`vtts.avatar.importer.import_avatar`) and ``adi build`` (a deformed pose,
:func:`adt_tools.build.load_poses`). Before the merge each had its own reader and checks the other
lacked; every check below holds on both paths, with the caller's error class and the file named.
The buffer builder and writer are read back through the same reader."""

from __future__ import annotations

import copy
import json
import os
import tracemalloc
import warnings
from pathlib import Path

import numpy as np
import pytest

from adt_tools.build import load_poses
from vtts.avatar.importer import import_avatar
from vtts.errors import AdtError, AvatarError
from vtts.gltf import ARRAY_BUFFER, BufferBuilder, GltfReader, write_document
from vtts.gltf.uri import data_uri, local_file
from vtts.limits import MAX_MORPH_TARGETS
from vtts.vrml import read

from .. import in_process

POINTS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float32)
JOY = np.array([[0, 0, 0], [0, -0.1, 0], [0, 0, 0]], dtype=np.float32)
NEUTRAL_WRL = """#VRML V2.0 utf8
Shape { geometry DEF FACE IndexedFaceSet {
  coord Coordinate { point [ 0 0 0, 1 0 0, 0 1 0 ] } coordIndex [ 0 1 2 -1 ] } }
"""


def triangle_gltf() -> dict:
    """A ``.gltf`` of one triangle mesh named FACE with one morph target, ``joy`` (an expression,
    so a pose for ``adi build``), its buffer a data uri."""
    blob = POINTS.tobytes() + JOY.tobytes() + np.array([0, 1, 2, 0, 0, 0], "<u2").tobytes()
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "FACE", "mesh": 0}],
        "meshes": [
            {
                "name": "FACE",
                "extras": {"targetNames": ["joy"]},
                "primitives": [
                    {"attributes": {"POSITION": 0}, "indices": 2, "targets": [{"POSITION": 1}]}
                ],
            }
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5123, "count": 3, "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 36},
            {"buffer": 0, "byteOffset": 72, "byteLength": 12},
        ],
        "buffers": [{"byteLength": len(blob), "uri": data_uri(blob, "application/octet-stream")}],
    }


def adi_import(path: Path) -> None:
    import_avatar(path)


def adi_build(path: Path) -> None:
    neutral = path.parent / "neutral.wrl"
    neutral.write_text(NEUTRAL_WRL)
    load_poses(path, read(neutral))


#: The reader's two users, each with the error class it raises.
USERS = pytest.mark.parametrize(
    "load, error", [(adi_import, AvatarError), (adi_build, AdtError)], ids=["import", "build"]
)


def write(tmp_path: Path, doc: dict) -> Path:
    path = tmp_path / "joy.gltf"
    path.write_text(json.dumps(doc))
    return path


@USERS
def test_the_triangle_reads(tmp_path, load, error):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # joy is no ARKit name
        load(write(tmp_path, triangle_gltf()))


def _set(path: tuple, value):
    def change(doc: dict) -> None:
        target = doc
        for k in path[:-1]:
            target = target[k]
        target[path[-1]] = value

    return change


def _too_many_targets(doc: dict) -> None:
    doc["meshes"][0]["primitives"][0]["targets"] = [{"POSITION": 1}] * (MAX_MORPH_TARGETS + 1)
    doc["meshes"][0]["extras"]["targetNames"] = ["joy"] * (MAX_MORPH_TARGETS + 1)


def _nan_position(doc: dict) -> None:
    blob = np.r_[POINTS.reshape(-1), np.float32("nan")].astype("<f4").tobytes()
    doc["buffers"].append({"byteLength": 40, "uri": data_uri(blob, "application/octet-stream")})
    doc["bufferViews"][0].update(buffer=1, byteOffset=4)


@USERS
@pytest.mark.parametrize(
    "change, message",
    [
        # adi build took a null item for an object (an AttributeError traceback)
        (_set(("accessors", 0), None), "accessor 0 is not a glTF object"),
        (_set(("bufferViews", 1), None), "bufferView 1 is not a glTF object"),
        (_set(("buffers", 0), None), "buffer 0 is not a glTF object"),
        # adi build read any version and ignored required extensions
        (_set(("asset", "version"), "1.0"), "only glTF 2.x is read, this file is version 1.0"),
        (
            _set(("extensionsRequired",), ["EXT_something_new"]),
            "the file requires the glTF extension EXT_something_new",
        ),
        # adi build read triangle indices never, and any number of morph targets
        (_set(("accessors", 2, "componentType"), 5126), "indices must be unsigned integers"),
        (_too_many_targets, f"more than the limit of {MAX_MORPH_TARGETS}"),
        # adi build took the GLB chunk for any buffer without a uri (a .gltf has none)
        (_set(("buffers", 0, "uri"), None), "buffer 0 has no data (no uri, and it is not the GLB"),
        # adi import named a negative index as a bad integer, adi build as a missing buffer
        (_set(("bufferViews", 0, "buffer"), -1), "buffer -1 does not exist"),
        (_set(("bufferViews", 0, "byteStride"), -12), "byteStride -12 is not positive"),
        (_set(("accessors", 0, "count"), 10**10), "count 10000000000 is more than the limit of"),
        (_set(("accessors", 0, "count"), -1), "count -1 is not an integer >= 0"),
        (_set(("accessors", 0, "byteOffset"), 40), "reach past the end of bufferView 0"),
        (_nan_position, "holds non-finite numbers (nan or inf)"),
    ],
    ids=lambda v: v if isinstance(v, str) and len(v) < 30 else None,
)
def test_a_broken_file_is_the_same_error_on_both_paths(tmp_path, load, error, change, message):
    doc = copy.deepcopy(triangle_gltf())
    change(doc)
    path = write(tmp_path, doc)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(error, match=message.replace("(", r"\(").replace(")", r"\)")) as e:
            load(path)
    assert e.value.file == str(path)


def test_adi_build_reads_a_draco_compressed_pose(tmp_path):
    """Draco decoding (the avatar reader's alone before) serves ``adi build`` too."""
    import DracoPy

    data = DracoPy.encode(POINTS, np.array([[0, 1, 2]], np.uint32), preserve_order=True,
                          quantization_bits=16)  # fmt: skip
    position_id = next(a["unique_id"] for a in DracoPy.decode(data).attributes
                       if a["attribute_type"] == 0)  # fmt: skip
    doc = triangle_gltf()
    blob = JOY.tobytes() + data
    doc["buffers"] = [{"byteLength": len(blob), "uri": data_uri(blob, "application/octet-stream")}]
    doc["bufferViews"] = [
        {"buffer": 0, "byteOffset": 0, "byteLength": 36},
        {"buffer": 0, "byteOffset": 36, "byteLength": len(data)},
    ]
    doc["accessors"] = [
        {"componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
        {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
        {"componentType": 5123, "count": 3, "type": "SCALAR"},
    ]
    prim = doc["meshes"][0]["primitives"][0]
    prim["targets"] = [{"POSITION": 1}]
    prim["extensions"] = {
        "KHR_draco_mesh_compression": {"bufferView": 1, "attributes": {"POSITION": position_id}}
    }
    doc["extensionsUsed"] = doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    (pose,) = load_poses(write(tmp_path, doc), read_neutral(tmp_path))
    assert pose.miap.name == "joy" and pose.amplitude == 1
    np.testing.assert_allclose(pose.points["FACE"], POINTS + JOY, atol=1e-4)


def read_neutral(tmp_path: Path):
    (tmp_path / "neutral.wrl").write_text(NEUTRAL_WRL)
    return read(tmp_path / "neutral.wrl")


# ---- the builder and writer, read back -----------------------------------------------------------


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_built_buffers_read_back(tmp_path, suffix):
    """Dense and sparse accessors from :class:`BufferBuilder`, written by
    :func:`write_document` (GLB chunk or data uri), read back exactly by :class:`GltfReader`."""
    import pygltflib as gl

    b = BufferBuilder()
    positions = np.arange(30, dtype=np.float32).reshape(10, 3)
    delta = np.zeros((10, 3), np.float32)
    delta[[2, 7]] = [[0.5, 0, 0], [0, -1, 2]]
    pos = b.accessor(positions, target=ARRAY_BUFFER, bounds=True)
    sparse = b.sparse(10, np.array([2, 7]), delta[[2, 7]])
    dense = b.sparse(10, np.arange(10), delta)  # every element given: stored dense
    doc = gl.GLTF2(asset=gl.Asset(version="2.0"))
    path = write_document(b.attach(doc, embed=suffix == ".gltf"), tmp_path / f"b{suffix}")
    reader = GltfReader(path)
    np.testing.assert_array_equal(reader.accessor(pos, "positions"), positions)
    np.testing.assert_array_equal(reader.accessor(sparse, "sparse"), delta)
    np.testing.assert_array_equal(reader.accessor(dense, "dense"), delta)
    accessors = reader.doc.accessors
    assert accessors[sparse].sparse is not None and accessors[dense].sparse is None
    assert accessors[pos].min == [0, 1, 2] and accessors[pos].max == [27, 28, 29]


def test_a_failed_write_leaves_no_file(tmp_path, monkeypatch):
    import pygltflib as gl

    def broken(self, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(gl.GLTF2, "gltf_to_json", broken)
    with pytest.raises(KeyboardInterrupt):
        write_document(gl.GLTF2(), tmp_path / "x.glb")
    assert list(tmp_path.iterdir()) == []


# ---- uris ----------------------------------------------------------------------------------------


def test_local_files_stay_in_the_folder(tmp_path):
    folder = tmp_path / "model"
    (folder / "sub").mkdir(parents=True)
    (folder / "sub" / "a b.bin").write_bytes(b"x")
    (tmp_path / "secret.bin").write_bytes(b"x")
    os.symlink(tmp_path / "secret.bin", folder / "link.bin")
    inside = (folder / "sub" / "a b.bin").resolve()
    assert local_file("sub/a%20b.bin", folder) == inside
    assert local_file("sub/../sub/a%20b.bin#frag", folder) == inside
    assert local_file(f"file://{inside}", folder) == inside
    for uri in ["../secret.bin", str(tmp_path / "secret.bin"), "link.bin", "http://x/a.bin",
                "C:/a.bin", "sub", "missing.bin"]:  # fmt: skip
        assert local_file(uri, folder) is None, uri


@pytest.mark.parametrize("n_vertices, component", [(65535, 5123), (65536, 5125)])
def test_triangle_indices_are_16_bit_while_they_fit(n_vertices, component):
    """65535 is the primitive restart value of 16-bit indices, which glTF forbids as an index."""
    b = BufferBuilder()
    acc = b.accessors[b.indices(np.array([[0, 1, 2]]), n_vertices)]
    assert acc.componentType == component and acc.count == 3
    assert b.views[acc.bufferView].target == 34963  # ELEMENT_ARRAY_BUFFER


# ---- hostile sizes, transforms and containers (issue 45) -----------------------------------------

BIG = 50_000_000  # within MAX_ACCESSOR_COUNT: a few KB of JSON asking for gigabytes


def _unbacked(doc: dict, count: int, kind: str = "VEC3") -> int:
    """A new accessor of ``count`` elements without a bufferView (zeros); its index."""
    doc["accessors"].append({"componentType": 5126, "count": count, "type": kind})
    return len(doc["accessors"]) - 1


def _big_target(doc: dict) -> None:
    doc["meshes"][0]["primitives"][0]["targets"][0]["POSITION"] = _unbacked(doc, BIG)


def _big_positions(doc: dict) -> None:
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = _unbacked(doc, BIG)
    del doc["meshes"][0]["primitives"][0]["indices"]


def _big_normals(doc: dict) -> None:
    doc["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = _unbacked(doc, BIG)


def _big_indices(doc: dict) -> None:
    doc["accessors"].append({"componentType": 5125, "count": BIG - 2, "type": "SCALAR"})
    doc["meshes"][0]["primitives"][0]["indices"] = len(doc["accessors"]) - 1


def _big_skin(doc: dict) -> None:
    doc["nodes"] = [{"name": "FACE", "mesh": 0, "skin": 0}, {"name": "bone"}]
    doc["scenes"] = [{"nodes": [0, 1]}]
    doc["skins"] = [{"joints": [1], "inverseBindMatrices": _unbacked(doc, BIG, "MAT4")}]
    doc["accessors"] += [  # zeros: fixed by the 3 positions
        {"componentType": 5121, "count": 3, "type": "VEC4"},
        {"componentType": 5126, "count": 3, "type": "VEC4"},
    ]
    n = len(doc["accessors"])
    attrs = doc["meshes"][0]["primitives"][0]["attributes"]
    attrs.update(JOINTS_0=n - 2, WEIGHTS_0=n - 1)


def _many_targets(doc: dict) -> None:
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = _unbacked(doc, 100_000)
    del doc["meshes"][0]["primitives"][0]["indices"]
    doc["meshes"][0]["primitives"][0]["targets"] = [{}] * 1000
    doc["meshes"][0]["extras"]["targetNames"] = ["joy"] * 1000


MEMORY = {
    "a 50M-element morph target": (_big_target, "has 50000000 elements, the primitive has 3"),
    "50M positions": (_big_positions, "count 50000000 without a bufferView (all zeros) is more"),
    "50M normals": (_big_normals, "has 50000000 elements, POSITION has 3"),
    "50M indices": (_big_indices, "count 49999998 without a bufferView (all zeros) is more"),
    "50M inverse bind matrices": (_big_skin, "has 50000000 elements, one MAT4 for each of 1"),
    "1000 targets of 100k vertices": (_many_targets, "1000 morph targets of 100000 vertices"),
}


#: What a refusal of a tiny document may allocate: far below the smallest allocation a missing
#: check would make (50M indices of 4 bytes).
LITTLE = 64 << 20
#: The cases also run as the real command, in a process limited to 3 GB (tests/hostile.py), one
#: per command: its exit status and stderr.
AS_A_PROCESS = {("import", "50M inverse bind matrices"), ("build", "a 50M-element morph target")}


def _adi_in_process(args: list[str], monkeypatch: pytest.MonkeyPatch) -> tuple[int, str, int]:
    """``adi ARGS`` run here: its exit status, its stderr, and the most memory it held at once
    after reading the glTF file (bytes, numpy's arrays included: tracemalloc counts them). A
    file is read into a buffer of the size limit (512 MiB), at once cut to the file's size: the
    peak is taken from there on."""
    import vtts.gltf.reader

    read = vtts.gltf.reader.read_bytes_capped

    def read_then_reset_peak(*args, **kwargs) -> bytes:
        data = read(*args, **kwargs)
        tracemalloc.reset_peak()
        return data

    monkeypatch.setattr(vtts.gltf.reader, "read_bytes_capped", read_then_reset_peak)
    tracemalloc.start()
    try:
        r = in_process.adi(*args)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return r.returncode, r.stderr, peak


@pytest.mark.parametrize(
    "command, case",
    # adi build reads no skins
    [
        (c, k)
        for c in ("import", "build")
        for k in MEMORY
        if (c, k) != ("build", "50M inverse bind matrices")
    ],
)
def test_an_accessor_without_data_is_refused_before_it_is_allocated(
    tmp_path, monkeypatch, case, command
):
    """Accessors without a bufferView (zeros) asked numpy for 3–6 GB and ended in a traceback;
    each count is now checked against what fixes it, or a limit, before anything is allocated:
    ``adi`` run in this process allocates less than :data:`LITTLE` on the way to the error (and
    one case per command runs as the command, in a process limited to 3 GB)."""
    from ..hostile import run_cli

    doc = copy.deepcopy(triangle_gltf())
    change, message = MEMORY[case]
    change(doc)
    path = write(tmp_path, doc)
    args = ["import", str(path), "-o", "out.wrl"]
    if command == "build":
        (tmp_path / "neutral.wrl").write_text(NEUTRAL_WRL)
        args = ["build", "neutral.wrl", str(path), "-o", "out.adt"]
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("VTTS_CACHE_DIR", "")
    code, err, peak = _adi_in_process(args, monkeypatch)
    assert code == 1 and message in err and str(path) in err, err[-2000:]
    assert peak < LITTLE, f"{peak / 2**20:.0f} MiB allocated on the way to the error"
    if (command, case) in AS_A_PROCESS:
        r = run_cli("adi", *args, cwd=tmp_path)
        assert r.returncode == 1, r.stderr[-2000:]
        assert message in r.stderr and "Traceback" not in r.stderr
        assert str(path) in r.stderr


@USERS
def test_accessors_without_data_where_their_count_is_fixed_still_read(tmp_path, load, error):
    """A morph target of zeros (gltf-transform writes sparse targets without a bufferView) with
    as many elements as the positions is legal glTF, and reads."""
    doc = copy.deepcopy(triangle_gltf())
    doc["meshes"][0]["primitives"][0]["targets"][0]["POSITION"] = _unbacked(doc, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        load(write(tmp_path, doc))


def _glb(tmp_path: Path, doc: dict, version: int = 2) -> Path:
    import struct

    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text
    path = tmp_path / "joy.glb"
    path.write_bytes(b"glTF" + struct.pack("<II", version, 12 + len(body)) + body)
    return path


@USERS
@pytest.mark.parametrize("version", [0, 1, 3, 2**32 - 1])
def test_only_glb_container_version_2_is_read(tmp_path, load, error, version):
    path = _glb(tmp_path, triangle_gltf(), version)
    with pytest.raises(error, match=f"the GLB container is version {version}, not 2"):
        load(path)
    _glb(tmp_path, triangle_gltf(), 2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        load(path)


@USERS
@pytest.mark.parametrize("extras", ["hello", 3, [1, 2], None, True, {"a": "b"}])
@pytest.mark.parametrize("where", ["root", "asset", "node", "accessor", "primitive"])
@pytest.mark.parametrize("glb", [False, True], ids=["gltf", "glb"])
def test_extras_of_any_json_type_are_read(tmp_path, load, error, extras, where, glb):
    """glTF allows extras of any JSON type; a string was refused with "'str' object has no
    attribute 'keys'"."""
    doc = copy.deepcopy(triangle_gltf())
    holder = {"root": doc, "asset": doc["asset"], "node": doc["nodes"][0],
              "accessor": doc["accessors"][0],
              "primitive": doc["meshes"][0]["primitives"][0]}[where]  # fmt: skip
    holder["extras"] = extras
    path = _glb(tmp_path, doc) if glb else write(tmp_path, doc)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        load(path)


def glb(doc: dict) -> bytes:
    """``doc`` as a GLB of its JSON chunk alone."""
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    chunk = len(text).to_bytes(4, "little") + b"JSON" + text
    return b"glTF" + (2).to_bytes(4, "little") + (12 + len(chunk)).to_bytes(4, "little") + chunk


@pytest.mark.parametrize("suffix", [".gltf", ".glb"])
def test_more_objects_than_the_limit_are_refused_before_decoding(tmp_path, monkeypatch, suffix):
    """``adi import`` of 300k empty nodes (a 1.2 MB file) ran for minutes: pygltflib decodes
    each object into a dataclass, then the importer walks each node. The objects are counted
    in the JSON first."""
    from vtts.limits import LimitError

    monkeypatch.setattr("vtts.gltf.reader.MAX_GLTF_OBJECTS", 100)
    doc = triangle_gltf()  # 1 scene, 1 node, 1 mesh, 3 accessors, 3 views, 1 buffer: 10
    doc["nodes"] += [{} for _ in range(90)]
    path = tmp_path / f"joy{suffix}"
    path.write_bytes(glb(doc) if suffix == ".glb" else json.dumps(doc).encode())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import_avatar(path)  # 100 objects: at the limit
    doc["nodes"].append({})
    path.write_bytes(glb(doc) if suffix == ".glb" else json.dumps(doc).encode())
    with pytest.raises(LimitError, match="101 glTF objects .* more than the limit of 100") as e:
        import_avatar(path)
    assert e.value.file == str(path)


def test_many_nodes_of_one_name_are_named_in_linear_time():
    """DEF names are made unique with a suffix; the search for a free one starts where the last
    one for that name stopped (it tried every suffix taken before: quadratic)."""
    from vtts.avatar.importer import _Importer

    class CountingSet(set):
        checks = 0

        def __contains__(self, item):
            CountingSet.checks += 1
            return super().__contains__(item)

    imp = object.__new__(_Importer)
    imp.names, imp._next_suffix = CountingSet(), {}
    got = [imp.unique("Bone", "node") for _ in range(2000)]
    assert got[:3] == ["Bone", "Bone_2", "Bone_3"] and len(set(got)) == 2000
    assert imp.unique("Bone_5", "node") == "Bone_5_2"  # taken: suffixed as any other name
    assert CountingSet.checks < 3 * 2001, CountingSet.checks
