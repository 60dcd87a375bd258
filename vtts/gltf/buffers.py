"""Building a glTF file's one binary buffer: :class:`BufferBuilder` packs arrays into 4-byte
aligned bufferViews and makes the accessors on them."""

from __future__ import annotations

import numpy as np
import pygltflib as gl

from vtts.gltf.spec import (
    ARRAY_BUFFER,
    ELEMENT_ARRAY_BUFFER,
    FLOAT,
    UNSIGNED_BYTE,
    UNSIGNED_INT,
    UNSIGNED_SHORT,
)
from vtts.gltf.uri import data_uri

#: Accessor type of each number of components.
ACCESSOR_TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}
_COMPONENT_TYPE = {"float32": FLOAT, "uint8": UNSIGNED_BYTE, "uint16": UNSIGNED_SHORT,
                   "uint32": UNSIGNED_INT}  # fmt: skip


class BufferBuilder:
    """The one buffer of a file being written: ``views`` (4-byte aligned) and ``accessors`` on
    them, for the document's ``bufferViews`` and ``accessors``; :meth:`data` is its bytes."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.size = 0
        self.views: list[gl.BufferView] = []
        self.accessors: list[gl.Accessor] = []

    def view(self, data: bytes, target: int | None = None) -> int:
        """A bufferView holding ``data`` (``target``: ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER or
        None); its index."""
        pad = -self.size % 4
        if pad:
            self.parts.append(b"\0" * pad)
            self.size += pad
        self.views.append(
            gl.BufferView(buffer=0, byteOffset=self.size, byteLength=len(data), target=target)
        )
        self.parts.append(data)
        self.size += len(data)
        return len(self.views) - 1

    def accessor(
        self, array: np.ndarray, *, target: int | None = None, bounds: bool = False
    ) -> int:
        """An accessor of ``array`` ``(n,)`` or ``(n, k)`` (float32, uint8, uint16 or uint32)
        on a bufferView of its own, with its ``min``/``max`` when ``bounds``; its index."""
        a = np.ascontiguousarray(array)
        k = 1 if a.ndim == 1 else a.shape[1]
        acc = gl.Accessor(
            bufferView=self.view(a.tobytes(), target),
            componentType=component_type(a.dtype),
            count=int(a.shape[0]),
            type=ACCESSOR_TYPES[k],
        )
        if bounds:
            flat = a.reshape(a.shape[0], k)
            acc.min, acc.max = bounds_of(flat.min(axis=0), flat.max(axis=0), a.dtype)
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def attribute(self, values: np.ndarray, *, bounds: bool = False) -> int:
        """A vertex attribute accessor (POSITION, NORMAL, TEXCOORD_0, …) of ``values``
        ``(v, k)`` stored as float32, with its ``min``/``max`` when ``bounds`` (POSITION needs
        them); its index."""
        return self.accessor(np.asarray(values).astype(np.float32), target=ARRAY_BUFFER,
                             bounds=bounds)  # fmt: skip

    def indices(self, faces: np.ndarray, n_vertices: int) -> int:
        """The triangle indices accessor of ``faces`` ``(m, 3)`` into ``n_vertices`` vertices:
        16-bit while they fit, else 32-bit; its index."""
        # 65535 is the primitive restart value of 16-bit indices: glTF forbids it as an index
        dtype = np.uint16 if n_vertices <= 65535 else np.uint32
        return self.accessor(np.asarray(faces).reshape(-1).astype(dtype),
                             target=ELEMENT_ARRAY_BUFFER)  # fmt: skip

    def sparse(self, count: int, indices: np.ndarray, values: np.ndarray) -> int:
        """A VEC3 float accessor of ``count`` elements, zero but for ``values`` ``(k, 3)`` at
        ``indices`` ``(k,)`` (increasing): sparse when that is smaller, else dense."""
        values = np.asarray(values, dtype=np.float32)
        k = indices.size
        lo = values.min(axis=0) if k else np.zeros(3, np.float32)
        hi = values.max(axis=0) if k else np.zeros(3, np.float32)
        if k < count:
            lo, hi = np.minimum(lo, 0), np.maximum(hi, 0)
        index_type = np.uint16 if count <= 1 << 16 else np.uint32
        if k * (12 + np.dtype(index_type).itemsize) >= 12 * count:
            dense = np.zeros((count, 3), dtype=np.float32)
            dense[indices] = values
            acc = gl.Accessor(
                bufferView=self.view(dense.tobytes(), ARRAY_BUFFER),
                componentType=FLOAT,
                count=count,
                type="VEC3",
            )
        else:
            acc = gl.Accessor(componentType=FLOAT, count=count, type="VEC3", byteOffset=None)
            if k:
                idx = self.view(np.ascontiguousarray(indices, dtype=index_type).tobytes())
                val = self.view(np.ascontiguousarray(values).tobytes())
                acc.sparse = gl.Sparse(
                    count=int(k),
                    indices=gl.AccessorSparseIndices(
                        bufferView=idx, componentType=component_type(np.dtype(index_type))
                    ),
                    values=gl.AccessorSparseValues(bufferView=val),
                )
        acc.min, acc.max = bounds_of(lo, hi, np.float32)
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def data(self) -> bytes:
        """The buffer's bytes, padded to a multiple of 4."""
        pad = -self.size % 4
        return b"".join(self.parts) + b"\0" * pad

    def attach(self, doc: gl.GLTF2, *, embed: bool = False) -> gl.GLTF2:
        """Give ``doc`` the bufferViews, accessors and the buffer: the GLB binary chunk, or with
        ``embed`` a base64 data uri (for a ``.gltf`` that is one file). Returns ``doc``."""
        doc.bufferViews = self.views
        doc.accessors = self.accessors
        data = self.data()
        if embed:
            doc.buffers = [
                gl.Buffer(byteLength=len(data), uri=data_uri(data, "application/octet-stream"))
            ]
        else:
            doc.buffers = [gl.Buffer(byteLength=len(data))]
            doc.set_binary_blob(data)
        return doc


def component_type(dtype: np.dtype) -> int:
    """The componentType of a numpy dtype (float32, uint8, uint16, uint32)."""
    return _COMPONENT_TYPE[np.dtype(dtype).name]


def bounds_of(lo: np.ndarray, hi: np.ndarray, dtype) -> tuple[list, list]:
    """An accessor's ``min`` and ``max`` lists of ``lo`` and ``hi`` ``(k,)`` for components
    of ``dtype``."""
    if np.dtype(dtype).kind == "f":
        # the exact float32 values, as the validator compares them
        return [float(v) for v in np.float32(lo)], [float(v) for v in np.float32(hi)]
    return [int(v) for v in lo], [int(v) for v in hi]
