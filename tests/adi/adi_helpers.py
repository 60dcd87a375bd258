"""Helpers of the ADI tests: a personalized model with known tables (the Candide-3 sample scene
plus a sidecar ``.adt``), exporting its phases, and writers of OBJ, PLY and glTF files."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from vtts.face import FaceModel, Miap
from vtts.vrml import write

SAMPLE = Path(__file__).parents[2] / "samples" / "candide3.wrl"

#: Known tables: a two-interval table (the paper's two-phase blink), a bidirectional one, a viseme,
#: an expression with two phases that also moves a Transform, and rotations about two axes of
#: the same Transform.
TABLES = """#AnimationDefinitionTables

MIAP 6 (stretch_l_cornerlip)
IndexedFaceSet: FACE_MESH
interval borders: -1000 0 1000
displacements:
vertex 50 -0.0001 0 0 0.0001 0.00002 0
vertex 51 -0.00005 0 0 0.0001 0 0

MIAP 19 (close_t_l_eyelid)
IndexedFaceSet: FACE_MESH
interval borders: 0 512 1024
displacements:
vertex 20 0 -0.0001 0 0 -0.0003 0
vertex 21 0 -0.0002 0 0 -0.0001 0.00001
vertex 22 0.00003 0 0 -0.00001 0 0

MIAP 48 (head_pitch)
Transform: HEAD
rotation neutral value: 1 0 0 (axis) 0 (angle)

MIAP 49 (head_yaw)
Transform: HEAD
rotation neutral value: 0 1 0 (axis) 0 (angle)

MIAP viseme 3 (T, D)
IndexedFaceSet: FACE_MESH
interval borders: 0 1
displacements:
vertex 60 0 0.01 0
vertex 61 0 -0.01 0

MIAP expression 1 (joy)
IndexedFaceSet: FACE_MESH
interval borders: 0 0.5 1
displacements:
vertex 50 0.02 0.02 0 0.01 0.01 0
vertex 52 0.01 0 0 0.01 0 0
Transform: HEAD
translation neutral value: 0 0 0
per unit: 0 0.05 0
"""

#: The phases exported per MIAP: the interval borders other than 0.
PHASES: dict[str, list[float]] = {
    "stretch_l_cornerlip": [-1000, 1000],
    "close_t_l_eyelid": [512, 1024],
    "head_pitch": [-20000],
    "head_yaw": [30000],
    "viseme3": [1],
    "joy": [0.5, 1],
}


def params_for(model: FaceModel, key: str, amplitude: float) -> np.ndarray:
    """A parameter vector with only MIAP ``key`` at ``amplitude``."""
    p = model.params()
    p[Miap.parse(key).index] = amplitude
    return p


def export_pose(model: FaceModel, key: str, amplitude: float, path: Path) -> Path:
    """Write the model posed with MIAP ``key`` at ``amplitude`` as a ``.wrl``."""
    write(model.posed_scene(model.deform(params_for(model, key, amplitude))), path)
    return path


def with_worldinfo(scene, info: str) -> str:
    """The VRML text of ``scene`` with a WorldInfo carrying ``info`` appended."""
    from vtts.vrml import dumps

    return dumps(scene) + f'WorldInfo {{ info [ "{info}" ] }}\n'


def face_points(model: FaceModel, key: str | None = None, amplitude: float = 0.0) -> np.ndarray:
    """``(113, 3)`` FACE_MESH points of the model posed with one MIAP (neutral by default)."""
    if key is None:
        return model.neutral_points("FACE_MESH")
    return model.deform(params_for(model, key, amplitude)).points["FACE_MESH"]


def face_triangles(model: FaceModel) -> np.ndarray:
    """``(184, 3) int64`` FACE_MESH triangles (Candide's coordIndex is all triangles)."""
    ci = np.asarray(model.scene.node("FACE_MESH").expand()["coordIndex"])
    return ci.reshape(-1, 4)[:, :3]


def write_obj(path: Path, points: np.ndarray, faces: np.ndarray, *, uv: bool = True) -> Path:
    """An OBJ as modelers write it: ``v`` lines, texture coordinates indexed apart from the
    vertices (so a loader that splits vertices at seams would reorder them)."""
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(points).tolist()]
    if uv:
        lines += [f"vt {i / len(faces):.6f} 0.5" for i in range(len(faces))]
        lines += [
            f"f {a + 1}/{i + 1} {b + 1}/{i + 1} {c + 1}/{i + 1}"
            for i, (a, b, c) in enumerate(faces)
        ]
    else:
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_ply(path: Path, points: np.ndarray, faces: np.ndarray) -> Path:
    """A binary PLY through trimesh (it keeps the unreferenced vertices too)."""
    import trimesh

    trimesh.Trimesh(points, faces, process=False).export(path)
    return path


def write_gltf(
    path: Path,
    meshes: list[tuple[str | None, np.ndarray, np.ndarray, dict[str, np.ndarray]]],
    *,
    sparse: bool = False,
) -> Path:
    """A ``.glb`` (or ``.gltf`` with an embedded data uri) with pygltflib.

    ``meshes``: (name, ``(v, 3)`` base positions, ``(f, 3)`` triangles, morph target name →
    ``(v, 3)`` displacements). Target names go to mesh ``extras.targetNames``; ``sparse`` stores
    the displacements as sparse accessors (only the moving vertices), as Blender does."""
    import base64

    import pygltflib as g

    blob = bytearray()
    views: list[g.BufferView] = []
    accessors: list[g.Accessor] = []

    def add_view(data: bytes, target: int | None = None) -> int:
        while len(blob) % 4:
            blob.append(0)
        views.append(
            g.BufferView(buffer=0, byteOffset=len(blob), byteLength=len(data), target=target)
        )
        blob.extend(data)
        return len(views) - 1

    def add_vec3(a: np.ndarray) -> int:
        a = np.asarray(a, dtype="<f4")
        view = add_view(a.tobytes(), g.ARRAY_BUFFER)
        accessors.append(
            g.Accessor(
                bufferView=view,
                componentType=g.FLOAT,
                count=len(a),
                type=g.VEC3,
                max=a.max(0).tolist(),
                min=a.min(0).tolist(),
            )
        )
        return len(accessors) - 1

    def add_sparse_vec3(a: np.ndarray) -> int:
        idx = np.flatnonzero(np.abs(a).sum(1) > 0).astype("<u4")
        iv = add_view(idx.tobytes())
        vv = add_view(np.asarray(a[idx], dtype="<f4").tobytes())
        accessors.append(
            g.Accessor(
                componentType=g.FLOAT,
                count=len(a),
                type=g.VEC3,
                sparse=g.Sparse(
                    count=len(idx),
                    indices=g.AccessorSparseIndices(bufferView=iv, componentType=g.UNSIGNED_INT),
                    values=g.AccessorSparseValues(bufferView=vv),
                ),
            )
        )
        return len(accessors) - 1

    gl_meshes = []
    for name, base, faces, targets in meshes:
        pos = add_vec3(base)
        idx_view = add_view(np.asarray(faces, dtype="<u4").tobytes(), g.ELEMENT_ARRAY_BUFFER)
        accessors.append(
            g.Accessor(
                bufferView=idx_view,
                componentType=g.UNSIGNED_INT,
                count=int(np.size(faces)),
                type=g.SCALAR,
            )
        )
        ind = len(accessors) - 1
        tgts = [
            g.Attributes(POSITION=(add_sparse_vec3 if sparse else add_vec3)(d))
            for d in targets.values()
        ]
        prim = g.Primitive(attributes=g.Attributes(POSITION=pos), indices=ind, targets=tgts)
        mesh = g.Mesh(name=name, primitives=[prim], weights=[0.0] * len(tgts))
        if targets:
            mesh.extras = {"targetNames": list(targets)}
        gl_meshes.append(mesh)
    doc = g.GLTF2(
        scene=0,
        scenes=[g.Scene(nodes=list(range(len(gl_meshes))))],
        nodes=[g.Node(mesh=i) for i in range(len(gl_meshes))],
        meshes=gl_meshes,
        accessors=accessors,
        bufferViews=views,
        buffers=[g.Buffer(byteLength=len(blob))],
    )
    if path.suffix == ".glb":
        doc.set_binary_blob(bytes(blob))
        doc.save_binary(str(path))
    else:
        doc.buffers[0].uri = (
            "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()
        )
        doc.save_json(str(path))
    return path


MeshWriter = Callable[[Path, np.ndarray, np.ndarray], Path]
