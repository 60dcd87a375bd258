"""Fuzzing the ADI's readers of deformed exports (issue 21): glTF (the JSON and its values, and
GLB bytes), OBJ and PLY files, and the MIAP names of file names and WorldInfo strings. Whatever
the input, the only exception is AdtError naming the file; poses that load build tables, which
write as ``.adt`` and read back unchanged.
"""

from __future__ import annotations

import base64
import functools
import json
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from adt_tools.build import build_tables, load_poses, miap_from_info, miap_from_label
from vtts.errors import AdtError, VttsError
from vtts.face import load_model
from vtts.face.adt import format_adt, parse_adt
from vtts.vrml import read

from ..fuzzing import examples
from ..hostile import byte_mutations, mutate, mutate_bytes, mutations
from .adi_helpers import SAMPLE, face_points, face_triangles, write_gltf, write_obj, write_ply

NEUTRAL = read(SAMPLE)


@functools.cache
def corpus() -> dict[str, bytes]:
    """A joy pose of the sample head as OBJ, PLY, GLB and glTF (the glTF's buffer sparse).
    Made when a test first needs it, not when the module is collected (writing the PLY imports
    trimesh and SciPy, which a worker that runs none of these tests need not pay for)."""
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        (d / "head.wrl").write_bytes(SAMPLE.read_bytes())
        model = load_model(d / "head.wrl")
        base, tris = face_points(model), face_triangles(model)
        joy = base.copy()
        joy[50:53] += [0.01, 0.02, 0.0]
        write_obj(d / "x.obj", joy, tris)
        write_ply(d / "x.ply", joy, tris)
        write_gltf(d / "x.glb", [("FACE_MESH", base, tris, {"joy@1": joy - base})])
        write_gltf(d / "x.gltf", [("FACE_MESH", base, tris, {"joy@0.5": (joy - base) / 2})],
                   sparse=True)  # fmt: skip
        return {p.suffix: p.read_bytes() for p in d.glob("x.*")}


def gltf() -> dict:
    """A fresh copy of the corpus's glTF document."""
    return json.loads(corpus()[".gltf"])


FUZZ = settings(
    max_examples=examples(100), deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("meshes")


def load_or_adt_error(path: Path, data: bytes) -> None:
    path.write_bytes(data)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # trimesh's and the ADI's own
            poses = load_poses(path, NEUTRAL)
            tables = build_tables(NEUTRAL, poses)
    except AdtError as e:
        assert e.file == str(path) and e.message, str(e)
        return
    for pose in poses:
        assert all(np.isfinite(p).all() for p in pose.points.values())
    assert parse_adt(format_adt(tables)) == tables


def test_the_corpus_builds(folder: Path) -> None:
    for suffix, data in corpus().items():
        path = folder / f"joy@1{suffix}"
        path.write_bytes(data)
        tables = build_tables(NEUTRAL, load_poses(path, NEUTRAL))
        assert len(tables.adts) == 1, suffix


@FUZZ
@given(st.sampled_from([".obj", ".gltf"]), mutations)
def test_mutated_text_files(folder: Path, suffix: str, ops) -> None:
    text = mutate(corpus()[suffix].decode(), ops)
    load_or_adt_error(folder / f"joy@1{suffix}", text.encode("utf-8", "surrogatepass"))


@FUZZ
@given(st.sampled_from([".glb", ".ply"]), byte_mutations)
def test_mutated_binary_files(folder: Path, suffix: str, ops) -> None:
    load_or_adt_error(folder / f"joy@1{suffix}", mutate_bytes(corpus()[suffix], ops))


#: Where the glTF reader takes numbers and references from the JSON.
PLACES = [
    ("accessors", 0, "count"), ("accessors", 0, "byteOffset"), ("accessors", 0, "componentType"),
    ("accessors", 0, "type"), ("accessors", 0, "bufferView"), ("accessors", 0, "normalized"),
    ("accessors", 2, "count"), ("accessors", 2, "sparse"), ("bufferViews", 0, "byteLength"),
    ("bufferViews", 0, "byteOffset"), ("bufferViews", 0, "byteStride"),
    ("bufferViews", 0, "buffer"),
    ("buffers", 0, "uri"), ("buffers", 0, "byteLength"), ("meshes", 0, "primitives"),
    ("meshes", 0, "extras"), ("meshes", 0, "name"), ("nodes", 0, "mesh"),
]  # fmt: skip
VALUES = st.one_of(
    st.integers(-(2**63), 2**64),
    st.sampled_from([0, 1, 3, 4, 12, 252, 253, 5126, 5125, 5121, 10**10, 2**31, -1]),
    st.floats(),
    st.none(),
    st.booleans(),
    st.sampled_from(["VEC3", "SCALAR", "MAT4", "", "data:,", "../x.bin", "/etc/passwd",
                     "data:application/octet-stream;base64,AAAA"]),
    st.lists(st.integers(-1, 5), max_size=3),
    st.dictionaries(st.sampled_from(["targetNames", "count", "POSITION"]),
                    st.one_of(st.integers(-1, 5), st.lists(st.text(max_size=8), max_size=2))),
)  # fmt: skip


class SparseIndices(dict):
    """In an example: the sparse accessor of the glTF's morph target with these fields of its
    indices changed (:func:`sparse_indices`, made when the test runs)."""


def sparse_indices(doc: dict, **fields) -> dict:
    """The sparse accessor of ``doc``'s morph target with ``fields`` of its indices changed."""
    return {**doc["accessors"][2]["sparse"], "indices": {"bufferView": 2, **fields}}


@FUZZ
@given(st.lists(st.tuples(st.sampled_from(PLACES), VALUES), min_size=1, max_size=3))
# tracebacks before: count false (TypeError), a target of another length than its base (numpy
# broadcast ValueError), a buffer index null (TypeError), sparse indices without a
# componentType (KeyError); an index -1 took the last element
@example([(("accessors", 0, "count"), False)])
@example([(("accessors", 2, "count"), 53)])
@example([(("bufferViews", 0, "buffer"), None)])
@example([(("accessors", 2, "sparse"), SparseIndices())])
@example([(("accessors", 2, "sparse"), SparseIndices(componentType=5126))])
@example([(("nodes", 0, "mesh"), 0), (("bufferViews", 0, "buffer"), -1)])
def test_gltf_values(folder: Path, changes) -> None:
    doc = gltf()
    for (array, index, key), value in changes:
        if isinstance(value, SparseIndices):
            value = sparse_indices(doc, **value)
        if index < len(doc.get(array, [])):
            doc[array][index][key] = value
    load_or_adt_error(folder / "joy@1.gltf", json.dumps(doc).encode())


def test_a_negative_gltf_index_is_no_index(folder: Path) -> None:
    doc = gltf()
    doc["bufferViews"][0]["buffer"] = -1  # Python's last buffer, the only one
    (folder / "joy@1.gltf").write_text(json.dumps(doc))
    with pytest.raises(AdtError, match="buffer -1 does not exist"):
        load_poses(folder / "joy@1.gltf", NEUTRAL)


@FUZZ
@given(st.binary(max_size=200))
def test_gltf_buffer_bytes(folder: Path, blob: bytes) -> None:
    """Any buffer contents behind valid accessors (too short, NaN floats, …)."""
    doc = gltf()
    doc["buffers"][0]["uri"] = (
        "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
    )
    load_or_adt_error(folder / "joy@1.gltf", json.dumps(doc).encode())


NAMES = [
    "19", "joy", "viseme3", "viseme 3", "close_t_l_eyelid", "@", "1024", "0", "-512", "1e999",
    "nan", "inf", "²", "9" * 5000, "expression", "miap", " ", "smile", "wink", "1_0",
]  # fmt: skip


@FUZZ
@given(st.lists(st.sampled_from(NAMES), max_size=4), st.sampled_from(["@", " ", ""]))
def test_miap_names(words: list[str], sep: str) -> None:
    """What a deformed file's name (``NAME@AMPLITUDE.ext``) or WorldInfo string says."""
    label = sep.join(words)
    for call in (
        lambda: miap_from_label(label, what="file name", file="f.obj"),
        lambda: miap_from_info("miap " + " ".join(words), file="f.wrl", line=3),
    ):
        try:
            miap, amplitude = call()
        except AdtError as e:
            assert e.file in ("f.obj", "f.wrl") and e.message
            continue
        except VttsError as e:  # pragma: no cover - the wrong class
            raise AssertionError(f"{type(e).__name__} instead of AdtError: {e}") from None
        assert np.isfinite(amplitude) and amplitude != 0
        assert miap.kind in ("fap", "viseme", "expression")
