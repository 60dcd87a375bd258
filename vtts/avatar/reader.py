"""Reading a glTF 2.0 avatar: its node tree, meshes with their morph targets, materials and images,
as plain arrays (:class:`GltfAsset`).

What real avatar files use is read:

- accessors of every component type, normalized or not, strided (``byteStride``), sparse; in
  particular ``KHR_mesh_quantization`` (positions, normals, texture coordinates and morph targets
  as 8- or 16-bit integers, their scale in the node's transform);
- ``KHR_draco_mesh_compression``, decoded with DracoPy (Google's Draco library);
- ``EXT_meshopt_compression`` (and ``KHR_meshopt_compression``), decoded with the ``meshoptimizer``
  package (zeux's meshoptimizer library), filters included;
- images embedded, in data uris or in files beside the ``.gltf`` (never outside its folder); a
  ``KHR_texture_basisu`` (KTX2) texture, or any image Pillow cannot read, is dropped with a
  warning: the mesh imports untextured.

Every size comes from the file, so each is checked before anything is allocated: the file itself
(:data:`~vtts.limits.MAX_GLTF_BYTES`), each accessor's count
(:data:`~vtts.limits.MAX_ACCESSOR_COUNT`), the morph targets of a mesh
(:data:`~vtts.limits.MAX_MORPH_TARGETS`), strides and offsets against their buffers. A broken
file fails with :class:`~vtts.errors.AvatarError` naming the file and the glTF object.
"""

from __future__ import annotations

import base64
import io
import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import numpy as np

from vtts.errors import AvatarError, VttsWarning
from vtts.limits import (
    MAX_ACCESSOR_COUNT,
    MAX_GLTF_BYTES,
    MAX_MORPH_TARGETS,
    check_image_size,
    read_bytes_capped,
)

#: numpy dtype of each glTF componentType.
COMPONENT_TYPES: dict[int, np.dtype] = {
    5120: np.dtype("<i1"),
    5121: np.dtype("<u1"),
    5122: np.dtype("<i2"),
    5123: np.dtype("<u2"),
    5125: np.dtype("<u4"),
    5126: np.dtype("<f4"),
}
#: What a normalized integer component is divided by (signed ones are then clamped at −1).
NORMALIZE = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0, 5125: 4294967295.0}
COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
#: The largest byteStride glTF allows.
MAX_STRIDE = 252

DRACO = "KHR_draco_mesh_compression"
MESHOPT = ("EXT_meshopt_compression", "KHR_meshopt_compression")
BASISU = "KHR_texture_basisu"
QUANTIZATION = "KHR_mesh_quantization"
#: Extensions a file may require: read (or, for textures, dropped with a warning).
SUPPORTED_REQUIRED = frozenset(
    {QUANTIZATION, DRACO, *MESHOPT, BASISU, "KHR_materials_unlit", "KHR_texture_transform",
     "EXT_texture_webp"}
)  # fmt: skip

_TRIANGLES, _STRIP, _FAN = 4, 5, 6
_MODE_NAMES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP"}


@dataclass(eq=False)
class Primitive:
    """One triangle primitive of a mesh, its vertices as the file gives them.

    positions  ``(v, 3) float64``  mesh-local coordinates
    faces      ``(m, 3) int64``    triangles (strips and fans turned into triangles)
    normals    ``(v, 3) float64`` or None
    uv, uv1    ``(v, 2) float64`` TEXCOORD_0 and _1 (glTF's v runs down the image) or None
    colors     ``(v, 3) float64`` COLOR_0 (alpha dropped) or None
    targets    per morph target ``(v, 3) float64`` POSITION displacements
    joints     ``(v, 4) int64`` JOINTS_0 and ``weights`` ``(v, 4) float64`` WEIGHTS_0, or None
    material   the glTF material index, or None
    """

    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    uv: np.ndarray | None = None
    uv1: np.ndarray | None = None
    colors: np.ndarray | None = None
    targets: list[np.ndarray] = field(default_factory=list)
    joints: np.ndarray | None = None
    weights: np.ndarray | None = None
    material: int | None = None


@dataclass(eq=False)
class Mesh:
    """A glTF mesh: its name, its morph target names (``extras.targetNames``, else ``target0``…)
    and its triangle primitives."""

    name: str | None
    target_names: list[str]
    primitives: list[Primitive]


@dataclass(eq=False)
class Material:
    """A glTF material as VRML can show it: base color ``(4,)`` RGBA, emissive ``(3,)``,
    roughness, double-sidedness, the base color texture's image index (None: untextured),
    whether it is unlit, which texture coordinates it reads (``TEXCOORD_n``) and their
    ``KHR_texture_transform`` as a ``(3, 3)`` matrix on ``(u, v, 1)``."""

    name: str | None
    base_color: np.ndarray
    emissive: np.ndarray
    roughness: float
    double_sided: bool
    image: int | None
    unlit: bool
    texcoord: int = 0
    uv_transform: np.ndarray = field(default_factory=lambda: np.eye(3))


@dataclass(eq=False)
class Image:
    """An image the avatar's textures use: its bytes and format (``"png"`` or ``"jpeg"``; other
    formats Pillow reads are converted to PNG)."""

    name: str | None
    data: bytes
    format: str


class GltfAsset:
    """A glTF 2.0 file (``.glb`` or ``.gltf``) read for import: ``doc`` is the pygltflib document;
    :meth:`mesh`, :meth:`material`, :meth:`image` and :meth:`accessor` decode its parts (once
    each). Raises :class:`~vtts.errors.AvatarError` for a file that cannot be read."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        from pygltflib import GLTF2

        self.path = Path(path)
        self.file = str(self.path)
        if self.path.suffix.lower() not in (".glb", ".gltf"):
            raise AvatarError(
                f"an avatar is a .glb or .gltf file, not {self.path.suffix or 'no suffix'}",
                file=self.file,
            )
        try:
            data = read_bytes_capped(self.path, MAX_GLTF_BYTES, what="glTF file")
        except IsADirectoryError:
            raise AvatarError("is a folder, not a glTF file", file=self.file) from None
        except OSError as e:
            raise AvatarError(f"cannot read file: {e.strerror or e}", file=self.file) from None
        try:
            if data[:4] == b"glTF":
                doc = GLTF2.load_from_bytes(data)
            else:
                doc = GLTF2.gltf_from_json(data.decode("utf-8"))
        except Exception as e:  # pygltflib raises json, struct, type and value errors alike
            raise AvatarError(f"not a readable glTF file: {_short(e)}", file=self.file) from None
        if doc is None or getattr(doc, "asset", None) is None:
            raise AvatarError("not a readable glTF file: no asset", file=self.file)
        version = str(getattr(doc.asset, "version", "") or "")
        if not version.startswith("2."):
            raise AvatarError(f"only glTF 2.x is read, this file is version {version or '?'}",
                              file=self.file)  # fmt: skip
        self.doc = doc
        required = [e for e in (doc.extensionsRequired or []) if e not in SUPPORTED_REQUIRED]
        if required:
            raise AvatarError(
                f"the file requires the glTF extension {', '.join(map(str, required))}, which vtts "
                f"cannot read (it reads {', '.join(sorted(SUPPORTED_REQUIRED))})",
                file=self.file,
            )
        #: the files besides ``path`` that were read (buffers and images a ``.gltf`` names)
        self.sources: list[Path] = []
        self._buffers: dict[int, bytes] = {}
        self._meshopt: dict[int, bytes] = {}
        self._meshes: dict[int, Mesh] = {}
        self._images: dict[int, Image | None] = {}

    # ---- errors -------------------------------------------------------------------------------

    def error(self, message: str) -> AvatarError:
        return AvatarError(message, file=self.file)

    def item(self, items: list | None, index: Any, what: str) -> Any:
        """``items[index]`` for a glTF index: an integer (not a bool) within the array."""
        if not isinstance(items, list):
            items = []
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(items):
            raise self.error(f"{what} {index!r} does not exist")
        if items[index] is None or isinstance(items[index], (str, int, float, list)):
            raise self.error(f"{what} {index} is not a glTF object")
        return items[index]

    # ---- buffers ------------------------------------------------------------------------------

    def buffer(self, index: int) -> bytes:
        if index in self._buffers:
            return self._buffers[index]
        buf = self.item(self.doc.buffers, index, "buffer")
        uri = buf.uri
        if uri is None:
            data = self.doc.binary_blob() if index == 0 else None
            if data is None:
                raise self.error(
                    f"buffer {index} has no data (no uri, and it is not the GLB binary chunk)"
                )
        else:
            data = self._uri_bytes(str(uri), f"buffer {index}", MAX_GLTF_BYTES)
        self._buffers[index] = data
        return data

    def _uri_bytes(self, uri: str, what: str, limit: int) -> bytes:
        if uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            if not head.endswith(";base64"):
                raise self.error(f"{what}: only base64 data uris are read")
            if len(payload) > limit * 4 // 3 + 4:
                raise self.error(f"{what}: a data uri larger than {limit >> 20} MiB")
            try:
                return base64.b64decode(payload, validate=False)
            except ValueError as e:
                raise self.error(f"{what}: bad base64 data: {e}") from None
        from vtts.vrml import resolve_url

        found = resolve_url([unquote(uri)], self.path.parent)
        if found is None:
            raise self.error(f"{what}: '{uri}' is not a file inside the glTF file's folder")
        self.sources.append(Path(found))
        try:
            return read_bytes_capped(found, limit, what=what)
        except OSError as e:
            raise self.error(f"{what}: cannot read '{uri}': {e.strerror or e}") from None

    def view(self, index: int) -> tuple[bytes, int | None]:
        """The bytes of bufferView ``index`` (decompressed when meshopt-compressed) and its
        byteStride."""
        view = self.item(self.doc.bufferViews, index, "bufferView")
        stride = view.byteStride
        if stride is not None and (isinstance(stride, bool) or not isinstance(stride, int)):
            raise self.error(f"bufferView {index}: byteStride must be an integer, got {stride!r}")
        if stride is not None and stride <= 0:
            raise self.error(
                f"bufferView {index}: byteStride {stride} is not positive (glTF: 4–{MAX_STRIDE})"
            )
        ext = _extension(view, *MESHOPT)
        if ext is not None:
            return self._meshopt_view(index, ext), stride
        data = self.buffer(_int(view.buffer, f"bufferView {index} buffer", self))
        start = _int(view.byteOffset or 0, f"bufferView {index} byteOffset", self)
        length = _int(view.byteLength, f"bufferView {index} byteLength", self)
        if start + length > len(data):
            raise self.error(
                f"bufferView {index} (bytes {start}–{start + length}) reaches past the end of its "
                f"buffer ({len(data)} bytes)"
            )
        return data[start : start + length], stride

    def _meshopt_view(self, index: int, ext: dict) -> bytes:
        """A bufferView compressed by EXT_meshopt_compression, decoded (and its filter undone)."""
        if index in self._meshopt:
            return self._meshopt[index]
        what = f"bufferView {index} (EXT_meshopt_compression)"
        try:
            import meshoptimizer
        except ImportError:  # pragma: no cover - a dependency of vtts
            raise self.error(f"{what}: the meshoptimizer package is not installed") from None
        if not isinstance(ext, dict):
            raise self.error(f"{what}: the extension must be an object")
        data = self.buffer(_int(ext.get("buffer"), f"{what} buffer", self))
        start = _int(ext.get("byteOffset", 0), f"{what} byteOffset", self)
        length = _int(ext.get("byteLength"), f"{what} byteLength", self)
        stride = _int(ext.get("byteStride"), f"{what} byteStride", self)
        count = _int(ext.get("count"), f"{what} count", self)
        mode, filt = ext.get("mode"), ext.get("filter", "NONE")
        if start + length > len(data):
            raise self.error(f"{what} reaches past the end of its buffer")
        if count > MAX_ACCESSOR_COUNT:
            raise self.error(
                f"{what}: count {count} is more than the limit of {MAX_ACCESSOR_COUNT} "
                "(vtts.limits)"
            )
        source = data[start : start + length]
        try:
            if mode == "ATTRIBUTES":
                if not (stride % 4 == 0 and 4 <= stride <= 256):
                    raise self.error(f"{what}: ATTRIBUTES need a byteStride of 4–256 in steps of "
                                     f"4, got {stride}")  # fmt: skip
                # the package's default (float32) mode holds count·stride bytes; its dtype= mode
                # allocates count elements only and overflows for strides above the itemsize
                out = meshoptimizer.decode_vertex_buffer(count, stride, source)
                raw = np.ascontiguousarray(out).view(np.uint8).reshape(-1)[: count * stride]
                raw = self._meshopt_filter(meshoptimizer, raw, count, stride, filt, what)
            elif mode in ("TRIANGLES", "INDICES"):
                if stride not in (2, 4):
                    raise self.error(f"{what}: {mode} need a byteStride of 2 or 4, got {stride}")
                decode = (meshoptimizer.decode_index_buffer if mode == "TRIANGLES"
                          else meshoptimizer.decode_index_sequence)  # fmt: skip
                out = decode(count, stride, source)
                raw = np.ascontiguousarray(out).view(np.uint8).reshape(-1)[: count * stride]
            else:
                raise self.error(f"{what}: mode must be ATTRIBUTES, TRIANGLES or INDICES, got "
                                 f"{mode!r}")  # fmt: skip
        except (RuntimeError, ValueError) as e:
            raise self.error(f"{what}: cannot decode: {e}") from None
        result = raw.tobytes()
        self._meshopt[index] = result
        return result

    def _meshopt_filter(self, lib, raw: np.ndarray, count: int, stride: int, filt, what: str):
        if filt in (None, "NONE"):
            return raw
        funcs = {"OCTAHEDRAL": lib.decode_filter_oct, "QUATERNION": lib.decode_filter_quat,
                 "EXPONENTIAL": lib.decode_filter_exp}  # fmt: skip
        if filt not in funcs:
            raise self.error(f"{what}: unknown filter {filt!r}")
        need = {"OCTAHEDRAL": (4, 8), "QUATERNION": (8,)}.get(filt)
        if need is not None and stride not in need:
            raise self.error(f"{what}: the {filt} filter needs a byteStride of "
                             f"{' or '.join(map(str, need))}, got {stride}")  # fmt: skip
        if filt == "EXPONENTIAL" and stride % 4:
            raise self.error(f"{what}: the EXPONENTIAL filter needs a byteStride in steps of 4")
        return np.asarray(funcs[filt](raw.copy(), count, stride), dtype=np.uint8)

    # ---- accessors ----------------------------------------------------------------------------

    def accessor(self, index: Any, what: str, *, normalize: bool = True) -> np.ndarray:
        """``(count, components)`` values of accessor ``index``: float64 (normalized integers
        divided out) or, with ``normalize=False``, the stored numbers as int64/float64."""
        acc = self.item(self.doc.accessors, index, f"{what}: accessor")
        what = f"{what} (accessor {index})"
        ncomp = COMPONENTS.get(acc.type)
        ctype = acc.componentType
        if ncomp is None or ctype not in COMPONENT_TYPES:
            raise self.error(f"{what}: unknown type {acc.type!r}/componentType {ctype!r}")
        count = _count(acc.count, f"{what} count", self)
        sparse = acc.sparse
        if acc.bufferView is None:
            values = np.zeros((count, ncomp), dtype=COMPONENT_TYPES[ctype])
        else:
            values = self._read(acc.bufferView, acc.byteOffset or 0, count, ctype, ncomp, what)
        if sparse is not None:
            k = _count(sparse.count, f"{what} sparse count", self)
            if k > count:
                raise self.error(f"{what}: {k} sparse values for {count} elements")
            ind, val = sparse.indices, sparse.values
            if ind is None or val is None or ind.componentType not in (5121, 5123, 5125):
                raise self.error(f"{what}: sparse indices must be unsigned integers (5121, 5123 "
                                 "or 5125), and sparse values are needed")  # fmt: skip
            idx = (
                self._read(
                    ind.bufferView,
                    ind.byteOffset or 0,
                    k,
                    ind.componentType,
                    1,
                    f"{what} sparse indices",
                    plain=True,
                )
                .reshape(-1)
                .astype(np.int64)
            )
            vals = self._read(val.bufferView, val.byteOffset or 0, k, ctype, ncomp,
                              f"{what} sparse values", plain=True)  # fmt: skip
            if idx.size and (idx.min() < 0 or idx.max() >= count):
                raise self.error(f"{what}: a sparse index is out of range 0–{count - 1}")
            values = values.copy()
            values[idx] = vals
        if normalize and acc.normalized and ctype in NORMALIZE:
            return np.maximum(values.astype(np.float64) / NORMALIZE[ctype], -1.0)
        if values.dtype.kind == "f":
            out = values.astype(np.float64)
            if not np.isfinite(out).all():
                raise self.error(f"{what}: holds non-finite numbers (nan or inf)")
            return out
        return values.astype(np.int64) if not normalize else values.astype(np.float64)

    def _read(self, view_index: Any, offset: Any, count: int, ctype: int, ncomp: int, what: str,
              *, plain: bool = False) -> np.ndarray:  # fmt: skip
        """``(count, ncomp)`` elements of a bufferView region, strided as the view says (sparse
        parts, ``plain``, are tightly packed)."""
        dtype = COMPONENT_TYPES[ctype]
        data, stride = self.view(_int(view_index, f"{what} bufferView", self))
        offset = _int(offset, f"{what} byteOffset", self)
        item = dtype.itemsize * ncomp
        if plain or stride is None:
            stride = item
        elif stride < item:
            raise self.error(f"{what}: byteStride {stride} is smaller than one element "
                             f"({item} bytes): elements would overlap")  # fmt: skip
        elif stride > MAX_STRIDE:
            raise self.error(f"{what}: byteStride {stride} is more than glTF's {MAX_STRIDE}")
        end = offset + stride * (count - 1) + item if count else offset
        if end > len(data):
            raise self.error(f"{what}: {count} elements from byte {offset} reach past the end of "
                             f"bufferView {view_index} ({len(data)} bytes)")  # fmt: skip
        if count == 0:
            return np.zeros((0, ncomp), dtype=dtype)
        return np.ndarray((count, ncomp), dtype=dtype, buffer=data, offset=offset,
                          strides=(stride, dtype.itemsize)).copy()  # fmt: skip

    # ---- meshes -------------------------------------------------------------------------------

    def mesh(self, index: int) -> Mesh:
        if index in self._meshes:
            return self._meshes[index]
        m = self.item(self.doc.meshes, index, "mesh")
        label = f"mesh {index}" + (f" ({m.name})" if m.name else "")
        prims = []
        n_targets = None
        for pi, p in enumerate(m.primitives or []):
            mode = 4 if p.mode is None else p.mode
            if mode not in (_TRIANGLES, _STRIP, _FAN):
                warnings.warn(VttsWarning(f"{label}, primitive {pi}: {_MODE_NAMES.get(mode, mode)}"
                                          " primitives are not drawn (only triangles)",
                                          file=self.file), stacklevel=2)  # fmt: skip
                continue
            prim = self._primitive(p, f"{label}, primitive {pi}", mode)
            if n_targets is not None and len(prim.targets) != n_targets:
                raise self.error(f"{label}: its primitives have different numbers of morph "
                                 "targets (glTF requires the same number)")  # fmt: skip
            n_targets = len(prim.targets)
            prims.append(prim)
        names = _target_names(m)
        n = n_targets or 0
        if len(names) != n:
            if names:
                warnings.warn(VttsWarning(f"{label}: {len(names)} target names for {n} morph "
                                          "targets; the targets are numbered instead",
                                          file=self.file), stacklevel=2)  # fmt: skip
            names = [f"target{i}" for i in range(n)]
        mesh = self._meshes[index] = Mesh(m.name, names, prims)
        return mesh

    def _primitive(self, p, label: str, mode: int) -> Primitive:
        attrs = _attributes(p.attributes)
        if attrs is None:
            raise self.error(f"{label}: attributes must be an object")
        draco = _extension(p, DRACO)
        decoded: dict[str, np.ndarray] = {}
        faces = None
        if draco is not None:
            decoded, faces = self._draco(draco, attrs, label)
        if "POSITION" not in attrs:
            raise self.error(f"{label} has no POSITION")

        def attr(name: str, width: tuple[int, ...]) -> np.ndarray | None:
            if name not in attrs:
                return None
            if name in decoded:
                a = decoded[name]
            else:
                a = self.accessor(attrs[name], f"{label} {name}")
            if a.shape[1] not in width:
                raise self.error(f"{label}: {name} must have {' or '.join(map(str, width))} "
                                 f"components, has {a.shape[1]}")  # fmt: skip
            return a

        positions = attr("POSITION", (3,))
        v = len(positions)
        out = Primitive(positions, np.zeros((0, 3), dtype=np.int64), material=p.material)
        for name, width, slot in (
            ("NORMAL", (3,), "normals"),
            ("TEXCOORD_0", (2,), "uv"),
            ("TEXCOORD_1", (2,), "uv1"),
            ("COLOR_0", (3, 4), "colors"),
        ):
            a = attr(name, width)
            if a is not None:
                if len(a) != v:
                    raise self.error(f"{label}: {name} has {len(a)} elements, POSITION {v}")
                setattr(out, slot, a[:, :3] if slot == "colors" else a)
        if "JOINTS_0" in attrs and "WEIGHTS_0" in attrs:
            j = (
                decoded.get("JOINTS_0")
                if "JOINTS_0" in decoded
                else self.accessor(attrs["JOINTS_0"], f"{label} JOINTS_0", normalize=False)
            )
            w = attr("WEIGHTS_0", (4,))
            if j.shape != (v, 4) or w.shape != (v, 4):
                raise self.error(f"{label}: JOINTS_0 and WEIGHTS_0 must be VEC4 per vertex")
            out.joints, out.weights = j.astype(np.int64), w
        targets = p.targets or []
        if len(targets) > MAX_MORPH_TARGETS:
            raise self.error(f"{label} has {len(targets)} morph targets, more than the limit of "
                             f"{MAX_MORPH_TARGETS} (vtts.limits)")  # fmt: skip
        if not isinstance(targets, list):
            raise self.error(f"{label}: targets must be a list")
        for ti, t in enumerate(targets):
            ta = _attributes(t)
            if ta is None:
                raise self.error(f"{label}: morph target {ti} must be an object")
            if "POSITION" not in ta:
                out.targets.append(np.zeros((v, 3)))
                continue
            d = self.accessor(ta["POSITION"], f"{label} morph target {ti} POSITION")
            if d.shape != (v, 3):
                raise self.error(f"{label}: morph target {ti} POSITION is {d.shape[0]}×"
                                 f"{d.shape[1]}, the primitive has {v} VEC3 positions")  # fmt: skip
            out.targets.append(d)
        if faces is None:
            if p.indices is None:
                idx = np.arange(v, dtype=np.int64)
            else:
                idx = self.accessor(p.indices, f"{label} indices", normalize=False).reshape(-1)
                if idx.dtype.kind == "f":
                    raise self.error(f"{label}: indices must be unsigned integers")
            faces = _triangles(idx, mode)
        faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
        if faces.size and (faces.min() < 0 or faces.max() >= v):
            raise self.error(f"{label}: a triangle names vertex {int(faces.max())}, but the "
                             f"primitive has {v} vertices")  # fmt: skip
        out.faces = faces
        return out

    def _draco(self, ext: Any, attrs: dict, label: str) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """The attributes and triangles of a KHR_draco_mesh_compression primitive."""
        what = f"{label} ({DRACO})"
        try:
            import DracoPy
        except ImportError:  # pragma: no cover - a dependency of vtts
            raise self.error(f"{what}: the DracoPy package is not installed") from None
        if not isinstance(ext, dict) or not isinstance(ext.get("attributes"), dict):
            raise self.error(f"{what}: the extension needs a bufferView and attributes")
        data, _ = self.view(_int(ext.get("bufferView"), f"{what} bufferView", self))
        try:
            mesh = DracoPy.decode(bytes(data))
        except Exception as e:  # DracoPy raises its own exception types and ValueError
            raise self.error(f"{what}: cannot decode the Draco data: {_short(e)}") from None
        faces = getattr(mesh, "faces", None)
        if faces is None or not len(faces):
            raise self.error(f"{what}: the Draco data is a point cloud, not triangles")
        out: dict[str, np.ndarray] = {}
        for name, uid in ext["attributes"].items():
            if name not in attrs:
                continue
            att = mesh.get_attribute_by_unique_id(_int(uid, f"{what} {name} id", self))
            if att is None:
                raise self.error(f"{what}: no Draco attribute with id {uid} for {name}")
            a = np.asarray(att["data"])
            a = a.reshape(len(a), -1)
            acc = self.item(self.doc.accessors, attrs[name], f"{what} {name}: accessor")
            if acc.count != len(a):
                raise self.error(f"{what}: {name} decodes to {len(a)} values, its accessor says "
                                 f"{acc.count}")  # fmt: skip
            if a.dtype.kind in "iu" and acc.normalized and acc.componentType in NORMALIZE:
                a = np.maximum(a / NORMALIZE[acc.componentType], -1.0)
            out[name] = a if name == "JOINTS_0" else a.astype(np.float64)
        return out, np.asarray(faces, dtype=np.int64)

    # ---- materials and images -----------------------------------------------------------------

    def material(self, index: int | None) -> Material:
        if index is None:
            return Material(None, np.array([1.0, 1, 1, 1]), np.zeros(3), 1.0, False, None, False)
        m = self.item(self.doc.materials, index, "material")
        pbr = m.pbrMetallicRoughness
        base = np.array(_floats(getattr(pbr, "baseColorFactor", None), [1, 1, 1, 1], 4))
        rough = _floats([getattr(pbr, "roughnessFactor", None)], [1.0], 1)[0]
        emissive = np.array(_floats(m.emissiveFactor, [0, 0, 0], 3))
        image, texcoord, transform = None, 0, np.eye(3)
        info = getattr(pbr, "baseColorTexture", None)
        if info is not None:
            image = self.texture_image(info.index)
            texcoord = info.texCoord if info.texCoord in (0, 1) else 0
            ext = _extension(info, "KHR_texture_transform")
            if isinstance(ext, dict):
                transform = _uv_transform(ext)
                if isinstance(ext.get("texCoord"), int) and ext["texCoord"] in (0, 1):
                    texcoord = ext["texCoord"]
        return Material(
            m.name, np.clip(base, 0, 1), np.clip(emissive, 0, 1), float(np.clip(rough, 0, 1)),
            bool(m.doubleSided), image, bool(_extension(m, "KHR_materials_unlit") is not None),
            texcoord, transform,
        )  # fmt: skip

    def texture_image(self, index: Any) -> int | None:
        """The image a texture shows, or None (with a warning) when it cannot be decoded."""
        tex = self.item(self.doc.textures, index, "texture")
        source = tex.source
        basis = _extension(tex, BASISU)
        webp = _extension(tex, "EXT_texture_webp")
        if source is None and webp is not None:
            source = webp.get("source") if isinstance(webp, dict) else None
        if source is None:
            if basis is not None:
                warnings.warn(VttsWarning(
                    f"texture {index} is a KTX2/Basis Universal texture ({BASISU}), which vtts "
                    "cannot decode: dropped, the mesh imports untextured", file=self.file),
                    stacklevel=3)  # fmt: skip
            return None
        return source if self.image(source) is not None else None

    def image(self, index: Any) -> Image | None:
        """Image ``index`` (PNG or JPEG bytes), or None with a warning when it cannot be read
        (KTX2, a broken file): the texture is dropped, never the import."""
        if index in self._images:
            return self._images[index]
        img = self.item(self.doc.images, index, "image")
        what = f"image {index}" + (f" ({img.name})" if img.name else "")
        result = None
        try:
            if img.bufferView is not None:
                data, _ = self.view(img.bufferView)
                data = bytes(data)
            elif img.uri is not None:
                data = self._uri_bytes(str(img.uri), what, MAX_GLTF_BYTES)
            else:
                raise self.error(f"{what} has neither a bufferView nor a uri")
            result = self._decode_image(data, img, what)
        except AvatarError as e:
            warnings.warn(VttsWarning(f"{e.message}: the texture is dropped", file=self.file),
                          stacklevel=3)  # fmt: skip
        self._images[index] = result
        return result

    def _decode_image(self, data: bytes, img, what: str) -> Image | None:
        from PIL import Image as PilImage

        if data[:12] == b"\xabKTX 20\xbb\r\n\x1a\n" or img.mimeType == "image/ktx2":
            warnings.warn(
                VttsWarning(
                    f"{what} is KTX2 (Basis Universal), which vtts cannot decode: the texture is "
                    "dropped and the mesh imports untextured",
                    file=self.file,
                ),
                stacklevel=4,
            )
            return None
        try:
            with PilImage.open(io.BytesIO(data)) as im:
                check_image_size(*im.size, file=self.file, what=what)
                fmt = (im.format or "").lower()
                if fmt in ("png", "jpeg"):
                    im.load()
                    return Image(img.name, data, fmt)
                buf = io.BytesIO()
                im.convert("RGBA").save(buf, format="PNG")
                return Image(img.name, buf.getvalue(), "png")
        except (OSError, ValueError, PilImage.DecompressionBombError) as e:
            raise self.error(f"{what} is not an image vtts can read ({_short(e)})") from None

    # ---- nodes --------------------------------------------------------------------------------

    def scene_roots(self) -> list[int]:
        """The root nodes of the default scene (else the first scene; else every parentless
        node)."""
        scenes = self.doc.scenes or []
        if scenes:
            index = self.doc.scene if isinstance(self.doc.scene, int) else 0
            scene = self.item(scenes, index, "scene")
            return [self._node_index(n) for n in scene.nodes or []]
        children = {c for n in self.doc.nodes or [] for c in (n.children or [])}
        return [i for i in range(len(self.doc.nodes or [])) if i not in children]

    def _node_index(self, n: Any) -> int:
        self.item(self.doc.nodes, n, "node")
        return n

    def local_matrix(self, index: int) -> np.ndarray:
        """``(4, 4) float64`` a node's local matrix (``matrix``, else T·R·S)."""
        n = self.item(self.doc.nodes, index, "node")
        if n.matrix is not None:
            m = np.array(_floats(n.matrix, list(np.eye(4).reshape(-1)), 16)).reshape(4, 4).T
            return m
        t = np.array(_floats(n.translation, [0, 0, 0], 3))
        q = np.array(_floats(n.rotation, [0, 0, 0, 1], 4))
        s = np.array(_floats(n.scale, [1, 1, 1], 3))
        m = np.eye(4)
        m[:3, :3] = quat_matrix(q) @ np.diag(s)
        m[:3, 3] = t
        return m

    def skin_matrices(self, skin_index: int, world: dict[int, np.ndarray]) -> np.ndarray:
        """``(j, 4, 4)`` the joint matrices of a skin at the nodes' rest pose (joint world matrix
        times its inverse bind matrix)."""
        skin = self.item(self.doc.skins, skin_index, "skin")
        joints = skin.joints or []
        ibm = np.tile(np.eye(4), (len(joints), 1, 1))
        if skin.inverseBindMatrices is not None:
            a = self.accessor(skin.inverseBindMatrices, f"skin {skin_index} inverseBindMatrices")
            if a.shape != (len(joints), 16):
                raise self.error(f"skin {skin_index}: inverseBindMatrices must be one MAT4 per "
                                 "joint")  # fmt: skip
            ibm = a.reshape(-1, 4, 4).transpose(0, 2, 1)
        mats = []
        for k, j in enumerate(joints):
            self._node_index(j)
            mats.append(world.get(j, np.eye(4)) @ ibm[k])
        return np.array(mats).reshape(-1, 4, 4)


def quat_matrix(q: np.ndarray) -> np.ndarray:
    """The rotation matrix ``(3, 3)`` of a glTF quaternion ``(x, y, z, w)`` (normalized here;
    a zero quaternion is the identity)."""
    n = float(np.linalg.norm(q))
    if not n > 0 or not math.isfinite(n):
        return np.eye(3)
    x, y, z, w = np.asarray(q, dtype=np.float64) / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


# ---- helpers -------------------------------------------------------------------------------------


def _extension(obj: Any, *names: str) -> Any:
    ext = getattr(obj, "extensions", None)
    if not isinstance(ext, dict):
        return None
    for n in names:
        if n in ext:
            return ext[n] if ext[n] is not None else {}
    return None


def _attributes(attributes: Any) -> dict[str, Any] | None:
    """A primitive's or target's attributes as ``{name: accessor index}`` (None when they are not
    an object)."""
    if attributes is None:
        return {}
    if isinstance(attributes, dict):
        items = attributes.items()
    elif hasattr(attributes, "__dict__") and not isinstance(attributes, type):
        items = ((k, getattr(attributes, k)) for k in vars(attributes))
    else:
        return None
    return {k: v for k, v in items if v is not None}


def _target_names(mesh: Any) -> list[str]:
    """Morph target names: the mesh's ``extras.targetNames`` (Blender's and three.js's
    convention), else its first primitive's."""
    for holder in [mesh, *(mesh.primitives or [])[:1]]:
        extras = getattr(holder, "extras", None)
        if isinstance(extras, dict) and isinstance(extras.get("targetNames"), list):
            return [str(n) for n in extras["targetNames"]]
    return []


def _uv_transform(ext: dict) -> np.ndarray:
    """``(3, 3)`` the KHR_texture_transform matrix (translation · rotation · scale) on
    ``(u, v, 1)``; bad values are left at their defaults."""
    offset = _floats(ext.get("offset"), [0.0, 0.0], 2)
    scale = _floats(ext.get("scale"), [1.0, 1.0], 2)
    (rotation,) = _floats([ext.get("rotation")], [0.0], 1)
    c, s = math.cos(rotation), math.sin(rotation)
    t = np.array([[1, 0, offset[0]], [0, 1, offset[1]], [0, 0, 1]])
    # the extension's GLSL: mat3(cos, sin, 0, -sin, cos, 0, 0, 0, 1), filled column by column
    r = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return t @ r @ np.diag([scale[0], scale[1], 1.0])


def _triangles(idx: np.ndarray, mode: int) -> np.ndarray:
    """``(m, 3)`` triangles of an index list drawn as TRIANGLES, TRIANGLE_STRIP or _FAN."""
    n = idx.size
    if mode == _TRIANGLES:
        return idx[: n - n % 3].reshape(-1, 3)
    if n < 3:
        return np.zeros((0, 3), dtype=np.int64)
    k = np.arange(n - 2)
    if mode == _FAN:
        return np.c_[np.full(n - 2, idx[0]), idx[k + 1], idx[k + 2]]
    even = k % 2 == 0  # a strip's odd triangles are wound the other way round
    a = np.where(even, idx[k], idx[k + 1])
    b = np.where(even, idx[k + 1], idx[k])
    return np.c_[a, b, idx[k + 2]]


def _int(value: Any, what: str, asset: GltfAsset) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise asset.error(f"{what} must be an integer >= 0, got {value!r}")
    return value


def _count(value: Any, what: str, asset: GltfAsset) -> int:
    v = _int(value, what, asset)
    if v > MAX_ACCESSOR_COUNT:
        raise asset.error(f"{what} is {v}, more than the limit of {MAX_ACCESSOR_COUNT} "
                          "(vtts.limits)")  # fmt: skip
    return v


def _floats(values: Any, default: list, n: int) -> list[float]:
    """``values`` as n finite floats, else ``default``."""
    if values is None or (len(values) == 1 and values[0] is None):
        return [float(v) for v in default]
    try:
        out = [float(v) for v in values]
    except (TypeError, ValueError):
        return [float(v) for v in default]
    if len(out) != n or not all(math.isfinite(v) for v in out):
        return [float(v) for v in default]
    return out


def _short(e: BaseException) -> str:
    text = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    return text[:200]
