"""Small hand-made glTF avatars for the import tests, built with pygltflib: a grid "face" whose
morph targets move known vertices, written with whichever accessor encoding, stride or compression
a test asks for."""

from __future__ import annotations

import numpy as np
import pygltflib as gl

from vtts.gltf import glb_chunks

FLOAT, BYTE, UBYTE, SHORT, USHORT, UINT = 5126, 5120, 5121, 5122, 5123, 5125
DTYPE = {FLOAT: np.float32, BYTE: np.int8, UBYTE: np.uint8, SHORT: np.int16, USHORT: np.uint16,
         UINT: np.uint32}  # fmt: skip
TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}


def grid(n: int = 5, size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A flat n×n grid facing +z: positions ``(n², 3)`` within ±size/2, triangles ``(m, 3)``."""
    u = np.linspace(-size / 2, size / 2, n)
    x, y = np.meshgrid(u, u)
    pos = np.c_[x.ravel(), y.ravel(), np.zeros(n * n)]
    faces = []
    for r in range(n - 1):
        for c in range(n - 1):
            a = r * n + c
            faces += [(a, a + 1, a + n + 1), (a, a + n + 1, a + n)]
    return pos, np.array(faces)


def moves(n_vertices: int, vertex: int, delta=(0.0, -0.1, 0.0)) -> np.ndarray:
    """A target displacement ``(v, 3)`` moving one vertex."""
    d = np.zeros((n_vertices, 3))
    d[vertex] = delta
    return d


class Builder:
    """A glTF document assembled by hand: bufferViews on one GLB buffer, accessors of any
    component type, stride and normalization."""

    def __init__(self) -> None:
        self.blob = bytearray()
        self.doc = gl.GLTF2(asset=gl.Asset(version="2.0"), scene=0, buffers=[gl.Buffer()])

    def view(self, data: bytes, stride: int | None = None, **kw) -> int:
        self.blob += b"\0" * (-len(self.blob) % 4)
        self.doc.bufferViews.append(
            gl.BufferView(
                buffer=0, byteOffset=len(self.blob), byteLength=len(data), byteStride=stride, **kw
            )
        )
        self.blob += data
        return len(self.doc.bufferViews) - 1

    def accessor(
        self,
        array,
        ctype: int = FLOAT,
        *,
        normalized: bool = False,
        stride: int | None = None,
        view: int | None = None,
        offset: int = 0,
    ) -> int:
        a = np.asarray(array)
        a = a.reshape(len(a), -1)
        k = a.shape[1]
        if view is None:
            data = a.astype(DTYPE[ctype])
            if stride is not None:  # pad each element to the stride
                item = data.itemsize * k
                raw = np.zeros((len(a), stride), np.uint8)
                raw[:, :item] = data.view(np.uint8).reshape(len(a), item)
                view = self.view(raw.tobytes(), stride)
            else:
                view = self.view(data.tobytes())
        acc = gl.Accessor(bufferView=view, byteOffset=offset, componentType=ctype,
                          normalized=normalized or None, count=len(a), type=TYPES[k])  # fmt: skip
        if ctype == FLOAT and k == 3:
            acc.min = [float(v) for v in a.min(axis=0)]
            acc.max = [float(v) for v in a.max(axis=0)]
        self.doc.accessors.append(acc)
        return len(self.doc.accessors) - 1

    def mesh(self, attributes: dict, indices: int | None, targets: list[dict], names: list[str],
             *, name: str = "Face", extensions: dict | None = None,
             material: int | None = None) -> int:  # fmt: skip
        prim = gl.Primitive(attributes=gl.Attributes(**attributes), indices=indices,
                            targets=[gl.Attributes(**t) for t in targets], material=material,
                            extensions=extensions or {})  # fmt: skip
        self.doc.meshes.append(gl.Mesh(name=name, primitives=[prim],
                                       extras={"targetNames": names} if names else {}))  # fmt: skip
        return len(self.doc.meshes) - 1

    def node(self, **kw) -> int:
        self.doc.nodes.append(gl.Node(**kw))
        return len(self.doc.nodes) - 1

    def save(self, path, roots: list[int] | None = None):
        if not self.doc.scenes:
            self.doc.scenes = [gl.Scene(nodes=roots if roots is not None
                                        else list(range(len(self.doc.nodes))))]  # fmt: skip
        self.blob += b"\0" * (-len(self.blob) % 4)
        self.doc.buffers[0].byteLength = len(self.blob)
        self.doc.set_binary_blob(bytes(self.blob))
        with open(path, "wb") as f:
            f.writelines(glb_chunks(self.doc))
        return path


def simple_avatar(path, names=("jawOpen", "eyeBlink_L"), *, n: int = 5, **save_kw):
    """A float grid whose targets, named ``names``, each move one vertex down by 0.1."""
    pos, faces = grid(n)
    b = Builder()
    p = b.accessor(pos)
    idx = b.accessor(faces.reshape(-1), USHORT)
    targets = [{"POSITION": b.accessor(moves(len(pos), k + 1))} for k in range(len(names))]
    mesh = b.mesh({"POSITION": p}, idx, targets, list(names))
    b.node(name="Head", mesh=mesh)
    return b.save(path, **save_kw)
