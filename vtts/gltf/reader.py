"""Reading a glTF 2.0 file (:class:`GltfReader`): its node tree, meshes with their morph targets,
materials and images, as plain arrays. ``adi import`` reads avatars with it
(:mod:`vtts.avatar.importer`), ``adi build`` deformed poses (:mod:`adt_tools.build`).

What real files use is read:

- accessors of every component type, normalized or not, strided (``byteStride``), sparse; in
  particular ``KHR_mesh_quantization`` (positions, normals, texture coordinates and morph targets
  as 8- or 16-bit integers, their scale in the node's transform);
- ``KHR_draco_mesh_compression``, decoded with DracoPy (:mod:`vtts.gltf.draco`);
- ``EXT_meshopt_compression`` (and ``KHR_meshopt_compression``), decoded with the ``meshoptimizer``
  package, filters included (:mod:`vtts.gltf.meshopt`);
- images embedded, in data uris or in files beside the ``.gltf`` (never outside its folder); a
  ``KHR_texture_basisu`` (KTX2) texture, or any image Pillow cannot read, is dropped with a
  warning: the mesh reads untextured.

Every size comes from the file, so each is checked before anything is allocated: the file itself
(:data:`~vtts.limits.MAX_GLTF_BYTES`), each accessor's count
(:data:`~vtts.limits.MAX_ACCESSOR_COUNT`), the morph targets of a mesh
(:data:`~vtts.limits.MAX_MORPH_TARGETS`), strides and offsets against their buffers. Every index
must name an object of its array. A broken file fails with the error class the caller gives
(:class:`~vtts.errors.AvatarError` for ``adi import``, :class:`~vtts.errors.AdtError` for
``adi build``) naming the file, the glTF object (``bufferView 3``, ``mesh 0 (Face), primitive 1
NORMAL (accessor 4)``) and the rule it breaks.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vtts.errors import VttsError, VttsWarning
from vtts.gltf.draco import DracoError, decode_draco, short_reason
from vtts.gltf.geometry import floats, quat_matrix, triangles, uv_transform
from vtts.gltf.images import KTX2_MAGIC, web_image
from vtts.gltf.meshopt import MeshoptError, decode_view
from vtts.gltf.spec import (
    BASISU,
    COMPONENT_TYPES,
    COMPONENTS,
    DRACO,
    INDEX_TYPES,
    MAX_STRIDE,
    MESHOPT,
    MODE_NAMES,
    NORMALIZE,
    SUPPORTED_REQUIRED,
    TEXTURE_TRANSFORM,
    TRIANGLE_FAN,
    TRIANGLE_STRIP,
    TRIANGLES,
    UNLIT,
    WEBP,
)
from vtts.gltf.uri import data_uri_bytes, is_data_uri, local_file
from vtts.limits import (
    MAX_ACCESSOR_COUNT,
    MAX_GLTF_BYTES,
    MAX_GLTF_OBJECTS,
    MAX_MORPH_TARGETS,
    MAX_UNBACKED_COUNT,
    LimitError,
    read_bytes_capped,
)

#: The primitive modes drawn as triangles.
TRIANGLE_MODES = (TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN)


@dataclass(eq=False)
class Primitive:
    """One primitive of a mesh, its vertices as the file gives them.

    positions  ``(v, 3) float64``  mesh-local coordinates
    faces      ``(m, 3) int64``    triangles (strips and fans turned into triangles; none for
                                   points and lines)
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
    """An image the file's textures use: its bytes and format (``"png"`` or ``"jpeg"``; other
    formats Pillow reads are converted to PNG)."""

    name: str | None
    data: bytes
    format: str


class GltfReader:
    """A glTF 2.0 file (``.glb`` or ``.gltf``, told apart by its first bytes) read: ``doc`` is
    the pygltflib document; :meth:`mesh`, :meth:`material`, :meth:`image` and :meth:`accessor`
    decode its parts (once each). ``error``: the :class:`~vtts.errors.VttsError` subclass raised
    for a file that cannot be read (a file over the size limit raises
    :class:`~vtts.limits.LimitError`)."""

    def __init__(self, path: str | os.PathLike[str], *, error: type[VttsError] = VttsError) -> None:
        from pygltflib import GLTF2

        self.path = Path(path)
        self.file = str(self.path)
        self.error_type = error
        try:
            data = read_bytes_capped(self.path, MAX_GLTF_BYTES, what="glTF file")
        except IsADirectoryError:
            raise self.error("is a folder, not a glTF file") from None
        except OSError as e:
            raise self.error(f"cannot read file: {e.strerror or e}") from None
        if data[:4] == b"glTF" and len(data) >= 8 and (container := data[4:8]) != b"\2\0\0\0":
            # pygltflib reads any version; a version 1 file (KHR_binary_glTF) is laid out otherwise
            raise self.error(f"the GLB container is version {int.from_bytes(container, 'little')}, "
                             "not 2 (the only one glTF 2.0 defines)")  # fmt: skip
        self._check_objects(data)
        data = _object_extras(data)
        try:
            if data[:4] == b"glTF":
                doc = GLTF2.load_from_bytes(data)
            else:
                doc = GLTF2.gltf_from_json(data.decode("utf-8"))
        except Exception as e:  # pygltflib raises json, struct, type and value errors alike
            raise self.error(f"not a readable glTF file: {short_reason(e)}") from None
        if doc is None or getattr(doc, "asset", None) is None:
            raise self.error("not a readable glTF file: no asset")
        version = str(getattr(doc.asset, "version", "") or "")
        if not version.startswith("2."):
            raise self.error(f"only glTF 2.x is read, this file is version {version or '?'}")
        self.doc = doc
        required = [e for e in (doc.extensionsRequired or []) if e not in SUPPORTED_REQUIRED]
        if required:
            raise self.error(
                f"the file requires the glTF extension {', '.join(map(str, required))}, which vtts "
                f"cannot read (it reads {', '.join(sorted(SUPPORTED_REQUIRED))})"
            )
        #: the files besides ``path`` that were read (buffers and images a ``.gltf`` names)
        self.sources: list[Path] = []
        self._buffers: dict[int, bytes] = {}
        self._meshopt: dict[int, bytes] = {}
        self._meshes: dict[int, Mesh] = {}
        self._images: dict[int, Image | None] = {}

    def _check_objects(self, data: bytes) -> None:
        """Refuse a file of more than :data:`~vtts.limits.MAX_GLTF_OBJECTS` objects before
        pygltflib decodes them one by one. JSON that does not parse is left for pygltflib to
        word."""
        import json
        import struct

        try:
            if data[:4] == b"glTF":  # the GLB's first chunk is its JSON
                length, kind = struct.unpack_from("<II", data, 12)
                text = data[20 : 20 + length] if kind == 0x4E4F534A else b""
            else:
                text = data
            doc = json.loads(text)
        except (ValueError, struct.error, RecursionError):
            return
        if isinstance(doc, dict):
            count = sum(len(v) for v in doc.values() if isinstance(v, list))
            if count > MAX_GLTF_OBJECTS:
                raise LimitError(
                    f"{count} glTF objects (nodes, meshes, accessors …), more than the limit "
                    f"of {MAX_GLTF_OBJECTS} (vtts.limits)",
                    file=self.file,
                )

    # ---- errors -------------------------------------------------------------------------------

    def error(self, message: str) -> VttsError:
        """The error to raise for ``message``, naming the file."""
        return self.error_type(message, file=self.file)

    def item(self, items: list | None, index: Any, what: str) -> Any:
        """``items[index]`` for a glTF index: an integer (not a bool, not negative: Python's -1
        would be the last) within the array, naming a glTF object (not a number, string, list
        or null)."""
        if not isinstance(items, list):
            items = []
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(items):
            raise self.error(f"{what} {index!r} does not exist")
        if not is_object(items[index]):
            raise self.error(f"{what} {index} is not a glTF object")
        return items[index]

    # ---- buffers ------------------------------------------------------------------------------

    def buffer(self, index: Any) -> bytes:
        """The bytes of buffer ``index``: its uri's, or the GLB binary chunk's (buffer 0)."""
        buf = self.item(self.doc.buffers, index, "buffer")
        if index in self._buffers:
            return self._buffers[index]
        uri = buf.uri
        if uri is None:
            data = self.doc.binary_blob() if index == 0 else None
            if data is None:
                raise self.error(
                    f"buffer {index} has no data (no uri, and it is not the GLB binary chunk)"
                )
        else:
            data = self.uri_bytes(str(uri), f"buffer {index}", MAX_GLTF_BYTES)
        self._buffers[index] = data
        return data

    def uri_bytes(self, uri: str, what: str, limit: int) -> bytes:
        """The bytes a uri names: a base64 data uri, or a file inside the glTF file's folder
        (recorded in :attr:`sources`)."""
        if is_data_uri(uri):
            try:
                return data_uri_bytes(uri, limit)
            except ValueError as e:
                raise self.error(f"{what}: {e}") from None
        found = local_file(uri, self.path.parent)
        if found is None:
            raise self.error(f"{what}: '{uri}' is not a file inside the glTF file's folder")
        self.sources.append(found)
        try:
            return read_bytes_capped(found, limit, what=what)
        except OSError as e:
            raise self.error(f"{what}: cannot read '{uri}': {e.strerror or e}") from None

    def view(self, index: Any) -> tuple[bytes, int | None]:
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
        ext = extension(view, *MESHOPT)
        if ext is not None:
            return self._meshopt_view(index, ext), stride
        data = self.buffer(view.buffer)
        start = self._int(view.byteOffset or 0, f"bufferView {index} byteOffset")
        length = self._int(view.byteLength, f"bufferView {index} byteLength")
        if start + length > len(data):
            raise self.error(
                f"bufferView {index} (bytes {start}–{start + length}) reaches past the end of its "
                f"buffer ({len(data)} bytes)"
            )
        return data[start : start + length], stride

    def _meshopt_view(self, index: int, ext: Any) -> bytes:
        """A bufferView compressed by EXT_meshopt_compression, decoded (and its filter undone)."""
        if index in self._meshopt:
            return self._meshopt[index]
        what = f"bufferView {index} (EXT_meshopt_compression)"
        if not isinstance(ext, dict):
            raise self.error(f"{what}: the extension must be an object")
        data = self.buffer(ext.get("buffer"))
        start = self._int(ext.get("byteOffset", 0), f"{what} byteOffset")
        length = self._int(ext.get("byteLength"), f"{what} byteLength")
        stride = self._int(ext.get("byteStride"), f"{what} byteStride")
        count = self._int(ext.get("count"), f"{what} count")
        if start + length > len(data):
            raise self.error(f"{what} reaches past the end of its buffer")
        if count > MAX_ACCESSOR_COUNT:
            raise self.error(
                f"{what}: count {count} is more than the limit of {MAX_ACCESSOR_COUNT} "
                "(vtts.limits)"
            )
        if count * stride > MAX_GLTF_BYTES:
            # the decoder allocates it before it reads a byte: no more than a file could hold
            raise self.error(
                f"{what}: {count} elements of {stride} bytes decode to more than the limit of "
                f"{MAX_GLTF_BYTES >> 20} MiB of a glTF file (vtts.limits)"
            )
        try:
            result = decode_view(data[start : start + length], count, stride, ext.get("mode"),
                                 ext.get("filter", "NONE"))  # fmt: skip
        except MeshoptError as e:
            raise self.error(f"{what}: {e}") from None
        self._meshopt[index] = result
        return result

    # ---- accessors ----------------------------------------------------------------------------

    def accessor(self, index: Any, what: str, *, normalize: bool = True,
                 count: int | None = None, shape: str = "") -> np.ndarray:  # fmt: skip
        """``(count, components)`` values of accessor ``index``: float64 (normalized integers
        divided out) or, with ``normalize=False``, the stored numbers as int64/float64. Float
        values must be finite.

        ``count``: the number of elements the accessor must have, where the file fixes it
        elsewhere (a primitive's vertices, a skin's joints), described by ``shape``; checked
        before anything is allocated. An accessor without a bufferView holds zeros (and its
        sparse values) that take memory but no bytes of the file, so where nothing fixes its
        count it may have at most :data:`~vtts.limits.MAX_UNBACKED_COUNT` elements."""
        acc = self.item(self.doc.accessors, index, f"{what}: accessor")
        what = f"{what} (accessor {index})"
        ncomp = COMPONENTS.get(acc.type) if isinstance(acc.type, str) else None
        ctype = acc.componentType
        if ncomp is None or not isinstance(ctype, int) or ctype not in COMPONENT_TYPES:
            raise self.error(f"{what}: unknown type {acc.type!r}/componentType {ctype!r}")
        n = self._count(acc.count, f"{what}: count")
        if count is not None and n != count:
            raise self.error(f"{what}: has {n} elements, {shape or f'{count} expected'}")
        fixed, count = count is not None, n
        sparse = acc.sparse
        if acc.bufferView is None:
            if not fixed and count > MAX_UNBACKED_COUNT:
                raise self.error(
                    f"{what}: count {count} without a bufferView (all zeros) is more than the "
                    f"limit of {MAX_UNBACKED_COUNT} for an accessor without data (vtts.limits)"
                )
            values = np.zeros((count, ncomp), dtype=COMPONENT_TYPES[ctype])
        else:
            values = self._read(acc.bufferView, acc.byteOffset or 0, count, ctype, ncomp, what)
        if sparse is not None:
            if not is_object(sparse):
                raise self.error(f"{what}: sparse must be an object")
            k = self._count(sparse.count, f"{what}: sparse count")
            if k > count:
                raise self.error(f"{what}: {k} sparse values for {count} elements")
            ind, val = sparse.indices, sparse.values
            if not (is_object(ind) and is_object(val)) or ind.componentType not in INDEX_TYPES:
                raise self.error(f"{what}: sparse indices must be unsigned integers (5121, 5123 "
                                 "or 5125), and sparse values are needed")  # fmt: skip
            idx = self._read(ind.bufferView, ind.byteOffset or 0, k, ind.componentType, 1,
                             f"{what} sparse indices", plain=True)  # fmt: skip
            idx = idx.reshape(-1).astype(np.int64)
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
        data, stride = self.view(self._int(view_index, f"{what} bufferView"))
        offset = self._int(offset, f"{what} byteOffset")
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

    def _int(self, value: Any, what: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise self.error(f"{what} must be an integer >= 0, got {value!r}")
        return value

    def _count(self, value: Any, what: str) -> int:
        """An element count: an integer >= 0 within :data:`~vtts.limits.MAX_ACCESSOR_COUNT`."""
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise self.error(f"{what} {value!r} is not an integer >= 0")
        if value > MAX_ACCESSOR_COUNT:
            raise self.error(f"{what} {value} is more than the limit of {MAX_ACCESSOR_COUNT} "
                             "(vtts.limits)")  # fmt: skip
        return value

    # ---- meshes -------------------------------------------------------------------------------

    def mesh(self, index: Any) -> Mesh:
        """Mesh ``index`` with its triangle primitives (others are skipped with a warning)."""
        m = self.item(self.doc.meshes, index, "mesh")
        if index in self._meshes:
            return self._meshes[index]
        label = f"mesh {index}" + (f" ({m.name})" if m.name else "")
        prims = []
        n_targets = None
        for pi, p in enumerate(self.primitives(m, label)):
            mode = primitive_mode(p)
            if mode not in TRIANGLE_MODES:
                warnings.warn(VttsWarning(f"{label}, primitive {pi}: {MODE_NAMES.get(mode, mode)}"
                                          " primitives are not drawn (only triangles)",
                                          file=self.file), stacklevel=2)  # fmt: skip
                continue
            prim = self.primitive(p, f"{label}, primitive {pi}")
            if n_targets is not None and len(prim.targets) != n_targets:
                raise self.error(f"{label}: its primitives have different numbers of morph "
                                 "targets (glTF requires the same number)")  # fmt: skip
            n_targets = len(prim.targets)
            prims.append(prim)
        names = target_names(m)
        n = n_targets or 0
        if len(names) != n:
            if names:
                warnings.warn(VttsWarning(f"{label}: {len(names)} target names for {n} morph "
                                          "targets; the targets are numbered instead",
                                          file=self.file), stacklevel=2)  # fmt: skip
            names = [f"target{i}" for i in range(n)]
        mesh = self._meshes[index] = Mesh(m.name, names, prims)
        return mesh

    def primitives(self, mesh: Any, label: str) -> list[Any]:
        """The primitives of a glTF mesh object, each checked to be an object."""
        prims = mesh.primitives or []
        if not isinstance(prims, list):
            raise self.error(f"{label}: primitives must be a list")
        for pi, p in enumerate(prims):
            if not is_object(p):
                raise self.error(f"{label}, primitive {pi} is not a glTF object")
        return prims

    def primitive(self, p: Any, label: str) -> Primitive:
        """A glTF primitive object decoded (Draco included): its attributes, morph targets and,
        for a triangle mode, triangles (points and lines have none)."""
        mode = primitive_mode(p)
        attrs = attributes(p.attributes)
        if attrs is None:
            raise self.error(f"{label}: attributes must be an object")
        draco = extension(p, DRACO)
        decoded: dict[str, np.ndarray] = {}
        faces = None
        if draco is not None:
            decoded, faces = self._draco(draco, attrs, label)
        if "POSITION" not in attrs:
            raise self.error(f"{label} has no POSITION")

        v: int | None = None  # the vertices, once POSITION is read

        def attr(name: str, width: tuple[int, ...]) -> np.ndarray | None:
            if name not in attrs:
                return None
            if name in decoded:
                a = decoded[name]
            else:
                a = self.accessor(attrs[name], f"{label} {name}", count=v,
                                  shape=f"POSITION has {v}")  # fmt: skip
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
                else self.accessor(
                    attrs["JOINTS_0"],
                    f"{label} JOINTS_0",
                    normalize=False,
                    count=v,
                    shape=f"POSITION has {v}",
                )
            )
            w = attr("WEIGHTS_0", (4,))
            if j.shape != (v, 4) or w.shape != (v, 4):
                raise self.error(f"{label}: JOINTS_0 and WEIGHTS_0 must be VEC4 per vertex")
            out.joints, out.weights = j.astype(np.int64), w
        targets = p.targets or []
        if not isinstance(targets, list):
            raise self.error(f"{label}: targets must be a list")
        if len(targets) > MAX_MORPH_TARGETS:
            raise self.error(f"{label} has {len(targets)} morph targets, more than the limit of "
                             f"{MAX_MORPH_TARGETS} (vtts.limits)")  # fmt: skip
        if len(targets) * v > MAX_ACCESSOR_COUNT:
            # each target is a copy of the positions in memory, whatever bytes it takes in the file
            raise self.error(f"{label} has {len(targets)} morph targets of {v} vertices: more "
                             f"than the limit of {MAX_ACCESSOR_COUNT} "
                             "in all (vtts.limits)")  # fmt: skip
        for ti, t in enumerate(targets):
            ta = attributes(t)
            if ta is None:
                raise self.error(f"{label}: morph target {ti} must be an object")
            if "POSITION" not in ta:
                out.targets.append(np.zeros((v, 3)))
                continue
            d = self.accessor(ta["POSITION"], f"{label} morph target {ti} POSITION", count=v,
                              shape=f"the primitive has {v} VEC3 positions")  # fmt: skip
            if d.shape != (v, 3):
                raise self.error(f"{label}: morph target {ti} POSITION is {d.shape[0]}×"
                                 f"{d.shape[1]}, the primitive has {v} VEC3 positions")  # fmt: skip
            out.targets.append(d)
        if mode not in TRIANGLE_MODES:
            return out
        if faces is None:
            if p.indices is None:
                idx = np.arange(v, dtype=np.int64)
            else:
                idx = self.accessor(p.indices, f"{label} indices", normalize=False).reshape(-1)
                if idx.dtype.kind == "f":
                    raise self.error(f"{label}: indices must be unsigned integers")
            faces = triangles(idx, mode)
        faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
        if faces.size and (faces.min() < 0 or faces.max() >= v):
            raise self.error(f"{label}: a triangle names vertex {int(faces.max())}, but the "
                             f"primitive has {v} vertices")  # fmt: skip
        out.faces = faces
        return out

    def _draco(self, ext: Any, attrs: dict, label: str) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """The attributes and triangles of a KHR_draco_mesh_compression primitive."""
        what = f"{label} ({DRACO})"
        if not isinstance(ext, dict) or not isinstance(ext.get("attributes"), dict):
            raise self.error(f"{what}: the extension needs a bufferView and attributes")
        data, _ = self.view(self._int(ext.get("bufferView"), f"{what} bufferView"))
        try:
            decoded, faces = decode_draco(data)
        except DracoError as e:
            raise self.error(f"{what}: {e}") from None
        out: dict[str, np.ndarray] = {}
        for name, uid in ext["attributes"].items():
            if name not in attrs:
                continue
            a = decoded.get(self._int(uid, f"{what} {name} id"))
            if a is None:
                raise self.error(f"{what}: no Draco attribute with id {uid} for {name}")
            acc = self.item(self.doc.accessors, attrs[name], f"{what} {name}: accessor")
            if acc.count != len(a):
                raise self.error(f"{what}: {name} decodes to {len(a)} values, its accessor says "
                                 f"{acc.count}")  # fmt: skip
            if a.dtype.kind in "iu" and acc.normalized and acc.componentType in NORMALIZE:
                a = np.maximum(a / NORMALIZE[acc.componentType], -1.0)
            out[name] = a if name == "JOINTS_0" else a.astype(np.float64)
        return out, faces

    # ---- materials and images -----------------------------------------------------------------

    def material(self, index: int | None) -> Material:
        if index is None:
            return Material(None, np.array([1.0, 1, 1, 1]), np.zeros(3), 1.0, False, None, False)
        m = self.item(self.doc.materials, index, "material")
        pbr = m.pbrMetallicRoughness
        base = np.array(floats(getattr(pbr, "baseColorFactor", None), [1, 1, 1, 1], 4))
        rough = floats([getattr(pbr, "roughnessFactor", None)], [1.0], 1)[0]
        emissive = np.array(floats(m.emissiveFactor, [0, 0, 0], 3))
        image, texcoord, transform = None, 0, np.eye(3)
        info = getattr(pbr, "baseColorTexture", None)
        if info is not None:
            image = self.texture_image(info.index)
            texcoord = info.texCoord if info.texCoord in (0, 1) else 0
            ext = extension(info, TEXTURE_TRANSFORM)
            if isinstance(ext, dict):
                transform = uv_transform(ext)
                if isinstance(ext.get("texCoord"), int) and ext["texCoord"] in (0, 1):
                    texcoord = ext["texCoord"]
        return Material(
            m.name, np.clip(base, 0, 1), np.clip(emissive, 0, 1), float(np.clip(rough, 0, 1)),
            bool(m.doubleSided), image, bool(extension(m, UNLIT) is not None),
            texcoord, transform,
        )  # fmt: skip

    def texture_image(self, index: Any) -> int | None:
        """The image a texture shows, or None (with a warning) when it cannot be decoded."""
        tex = self.item(self.doc.textures, index, "texture")
        source = tex.source
        basis = extension(tex, BASISU)
        webp = extension(tex, WEBP)
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
        (KTX2, a broken file): the texture is dropped, never the mesh."""
        img = self.item(self.doc.images, index, "image")
        if index in self._images:
            return self._images[index]
        what = f"image {index}" + (f" ({img.name})" if img.name else "")
        result = None
        try:
            if img.bufferView is not None:
                data, _ = self.view(img.bufferView)
                data = bytes(data)
            elif img.uri is not None:
                data = self.uri_bytes(str(img.uri), what, MAX_GLTF_BYTES)
            else:
                raise self.error(f"{what} has neither a bufferView nor a uri")
            result = self._decode_image(data, img, what)
        except self.error_type as e:
            if isinstance(e, LimitError):
                raise
            warnings.warn(VttsWarning(f"{e.message}: the texture is dropped", file=self.file),
                          stacklevel=3)  # fmt: skip
        self._images[index] = result
        return result

    def _decode_image(self, data: bytes, img: Any, what: str) -> Image | None:
        from PIL import Image as PilImage

        if data[:12] == KTX2_MAGIC or img.mimeType == "image/ktx2":
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
            data, fmt = web_image(data, file=self.file, what=what)
        except (OSError, ValueError, PilImage.DecompressionBombError) as e:
            raise self.error(f"{what} is not an image vtts can read ({short_reason(e)})") from None
        return Image(img.name, data, fmt)

    # ---- nodes --------------------------------------------------------------------------------

    def scene_roots(self) -> list[int]:
        """The root nodes of the default scene (else the first scene; else every parentless
        node)."""
        scenes = self.doc.scenes or []
        if scenes:
            index = self.doc.scene if isinstance(self.doc.scene, int) else 0
            scene = self.item(scenes, index, "scene")
            return [self.node_index(n) for n in scene.nodes or []]
        children = {c for n in self.doc.nodes or [] for c in (n.children or [])}
        return [i for i in range(len(self.doc.nodes or [])) if i not in children]

    def node_index(self, n: Any) -> int:
        """``n``, checked to name a node."""
        self.item(self.doc.nodes, n, "node")
        return n

    def local_matrix(self, index: int) -> np.ndarray:
        """``(4, 4) float64`` a node's local matrix (``matrix``, else T·R·S)."""
        n = self.item(self.doc.nodes, index, "node")
        if n.matrix is not None:
            m = np.array(floats(n.matrix, list(np.eye(4).reshape(-1)), 16)).reshape(4, 4).T
            return m
        t = np.array(floats(n.translation, [0, 0, 0], 3))
        q = np.array(floats(n.rotation, [0, 0, 0, 1], 4))
        s = np.array(floats(n.scale, [1, 1, 1], 3))
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
            a = self.accessor(
                skin.inverseBindMatrices,
                f"skin {skin_index} inverseBindMatrices",
                count=len(joints),
                shape=f"one MAT4 for each of {len(joints)} joints",
            )
            if a.shape != (len(joints), 16):
                raise self.error(f"skin {skin_index}: inverseBindMatrices must be one MAT4 per "
                                 "joint")  # fmt: skip
            ibm = a.reshape(-1, 4, 4).transpose(0, 2, 1)
        mats = []
        for k, j in enumerate(joints):
            self.node_index(j)
            mats.append(world.get(j, np.eye(4)) @ ibm[k])
        return np.array(mats).reshape(-1, 4, 4)


# ---- helpers -------------------------------------------------------------------------------------


def _object_extras(data: bytes) -> bytes:
    """A glTF or GLB file's bytes with every ``extras`` that is not a JSON object left out.

    glTF allows ``extras`` of any JSON type, and vtts reads none but a mesh's ``targetNames``;
    pygltflib takes every ``extras`` for an object (``'str' object has no attribute 'keys'``).
    Bytes that are not JSON pass unchanged, for the parser to word the error."""
    import json
    import struct

    glb = data[:4] == b"glTF"
    try:
        if glb:
            length, kind = struct.unpack_from("<I4s", data, 12)
            text, rest = data[20 : 20 + length], data[20 + length :]
            if kind != b"JSON" or len(text) != length:
                return data
        else:
            text = data
        doc = json.loads(text)
    except (ValueError, struct.error, RecursionError):
        return data
    if not _drop_extras(doc):
        return data
    out = json.dumps(doc).encode("utf-8")
    if not glb:
        return out
    out += b" " * (-len(out) % 4)
    chunk = struct.pack("<I4s", len(out), b"JSON") + out
    return data[:8] + struct.pack("<I", 12 + len(chunk) + len(rest)) + chunk + rest


def _drop_extras(value: Any) -> bool:
    """Remove each non-object ``extras`` in a parsed JSON document (not inside an ``extras``,
    which is the user's own data); whether any was removed."""
    dropped = False
    stack = [value]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            if "extras" in item and not isinstance(item["extras"], dict):
                del item["extras"]
                dropped = True
            stack += [v for k, v in item.items() if k != "extras"]
        elif isinstance(item, list):
            stack += item
    return dropped


def is_object(value: Any) -> bool:
    """Whether a value pygltflib parsed is a glTF object (not null, a number, a string or a
    list)."""
    return value is not None and not isinstance(value, (str, int, float, list))


def extension(obj: Any, *names: str) -> Any:
    """The first of the extensions ``names`` that ``obj`` has (``{}`` for a null one), else
    None."""
    ext = getattr(obj, "extensions", None)
    if not isinstance(ext, dict):
        return None
    for n in names:
        if n in ext:
            return ext[n] if ext[n] is not None else {}
    return None


def attributes(attributes: Any) -> dict[str, Any] | None:
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


def primitive_mode(p: Any) -> Any:
    """A primitive's mode (TRIANGLES when it has none)."""
    return TRIANGLES if p.mode is None else p.mode


def target_names(mesh: Any) -> list[str]:
    """Morph target names: the mesh's ``extras.targetNames`` (Blender's and three.js's
    convention), else its first primitive's."""
    prims = mesh.primitives if isinstance(mesh.primitives, list) else []
    for holder in [mesh, *prims[:1]]:
        extras = getattr(holder, "extras", None)
        if isinstance(extras, dict) and isinstance(extras.get("targetNames"), list):
            return [str(n) for n in extras["targetNames"]]
    return []
