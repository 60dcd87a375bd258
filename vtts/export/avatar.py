"""A vtts head as an ARKit-blendshape avatar: :func:`write_arkit_avatar` writes a ``.glb`` whose
morph targets are named after Apple's 52 blendshapes (and the 15 Oculus visemes), the kind of
file ``adi import`` reads (:mod:`vtts.avatar.importer`).

Each ARKit shape is the model's own deformation for the FAPs of its recipe: the recipe table read
backwards (:meth:`RecipeTable.fap_content <vtts.avatar.arkit.RecipeTable.fap_content>`) gives the
FAP values a shape at weight 1 stands for, and the target is the model posed with them minus its
neutral pose. ``viseme_PP`` … ``viseme_U`` are the model's visemes 1–14 at weight 1. Motions the
model makes with Transforms (the eyeballs' rotations) are not in the targets: the eyeballs are
meshes named ``L_EYEBALL``/``R_EYEBALL`` (as the bundled heads name them), which the import
turns into rotating Transforms again.

The scene is flattened: every drawn Shape becomes one node whose mesh is in the head's file
coordinates (the Transforms' matrices applied), so the file needs no node tree to look right.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pygltflib as gl

from vtts.avatar.arkit import ARKIT_NAMES, OCULUS_VISEMES, RecipeTable, recipes
from vtts.errors import ExportError
from vtts.export.morph import gather, vertex_layout
from vtts.export.scene import SceneNode, ShapeItem, walk_head
from vtts.face import N_PARAMS, FaceModel
from vtts.face.miap import Miap
from vtts.gltf import BufferBuilder, image_file, write_document
from vtts.gltf.images import brightened, png_bytes
from vtts.render.scene import load_image


def arkit_targets(model: FaceModel, table: RecipeTable | None = None, *, oculus: bool = True):
    """``{target name: (N_PARAMS,) parameter vector}``: the pose each ARKit shape (and Oculus
    viseme) stands for on ``model``. Shapes whose FAPs the model has no table for are left
    out."""
    table = table or recipes()
    content = table.fap_content()  # (68, 52): FAP k-1 moved by shape j at 1
    have = {m.index for m in model.tables.adts}
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(ARKIT_NAMES):
        p = np.zeros(N_PARAMS)
        p[: content.shape[0]] = content[:, j]
        if not any(p[i] != 0 for i in have):
            continue
        out[name] = p
    if oculus:
        for v in range(1, 15):
            miap = Miap("viseme", v)
            if miap.index in have:
                p = np.zeros(N_PARAMS)
                p[miap.index] = 1.0
                out[OCULUS_VISEMES[v]] = p
    return out


def arkit_avatar_gltf(model: FaceModel, table: RecipeTable | None = None, *,
                      oculus: bool = True) -> gl.GLTF2:  # fmt: skip
    """The avatar as a ``pygltflib.GLTF2`` whose one buffer is its binary blob."""
    poses = arkit_targets(model, table, oculus=oculus)
    deformed = {name: model.deform(p) for name, p in poses.items()}
    head = walk_head(model)
    blob = BufferBuilder()
    nodes: list[gl.Node] = []
    meshes: list[gl.Mesh] = []
    materials: list[gl.Material] = []
    images: list[gl.Image] = []
    textures: list[gl.Texture] = []
    image_cache: dict[tuple[Path, tuple[float, ...]], int] = {}

    def material(item: ShapeItem) -> tuple[int, bool]:
        app = item.appearance.expand() if item.appearance is not None else None
        mat = app["material"] if app is not None else None
        base, emissive, rough = [0.8, 0.8, 0.8, 1.0], [0.0, 0.0, 0.0], 0.8
        if mat is not None:
            mat = mat.expand()
            base = [*map(float, mat["diffuseColor"]), 1.0 - float(mat["transparency"])]
            emissive = [float(v) for v in mat["emissiveColor"]]
            rough = float(np.clip(1.0 - 0.8 * mat["shininess"], 0.05, 1.0))
        pbr = gl.PbrMetallicRoughness(baseColorFactor=[float(np.clip(v, 0, 1)) for v in base],
                                      metallicFactor=0.0, roughnessFactor=rough)  # fmt: skip
        tex = app["texture"] if app is not None else None
        textured = False
        if tex is not None and item.mesh is not None and tex.expand().type.name == "ImageTexture":
            path = model.texture_file(tex.expand())
            if path is not None:
                # a diffuseColor above 1 (glTF's factor stops at 1) brightens the texture itself
                gain = tuple(max(v, 1.0) for v in base[:3]) if mat is not None else (1.0,) * 3
                key = (path, gain)
                if key not in image_cache:
                    if gain == (1.0,) * 3:
                        data, mime = image_file(path)
                    else:
                        data, mime = png_bytes(brightened(load_image(path), gain)), "image/png"
                    images.append(gl.Image(bufferView=blob.view(data), mimeType=mime))
                    textures.append(gl.Texture(source=len(images) - 1))
                    image_cache[key] = len(textures) - 1
                pbr.baseColorTexture = gl.TextureInfo(index=image_cache[key])
                textured = True
                if mat is None:
                    pbr.baseColorFactor = [1.0, 1.0, 1.0, 1.0]
                else:
                    scaled = np.asarray(base) / np.asarray([*gain, 1.0])
                    pbr.baseColorFactor = [float(v) for v in np.clip(scaled, 0, 1)]
        materials.append(gl.Material(
            pbrMetallicRoughness=pbr, emissiveFactor=[float(np.clip(v, 0, 1)) for v in emissive],
            alphaMode="BLEND" if base[3] < 1 else "OPAQUE", doubleSided=item.double_sided,
        ))  # fmt: skip
        return len(materials) - 1, textured

    def add(item: ShapeItem, world: np.ndarray) -> None:
        lin, shift = world[:3, :3], world[:3, 3]
        geom = item.geometry
        if item.mesh is None:  # a VRML primitive: static
            tri = item.primitive
            positions, faces = np.asarray(tri.vertices), np.asarray(tri.faces)
            normals, uv, targets = np.asarray(tri.vertex_normals), None, {}
        else:
            tm = item.mesh
            points = np.asarray(geom["coord"].expand()["point"], dtype=np.float64).reshape(-1, 3)
            layout = vertex_layout(tm, points.shape[0])
            positions, faces = points[layout.point], layout.faces
            normals = gather(tm.normals, layout, (0.0, 0.0, 1.0))
            uv = gather(tm.texcoords, layout) if tm.texcoords is not None else None
            targets = {}
            if geom.name and geom.name in model.engine.meshes:
                for name, pose in deformed.items():
                    d = pose.points[geom.name] - points
                    if np.abs(d).max() > 0:
                        targets[name] = d[layout.point] @ lin.T
        positions = positions @ lin.T + shift
        normals = normals @ np.linalg.inv(lin)  # the inverse transpose, row vectors
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
        bad = ~(np.abs(normals).sum(axis=1) > 0)
        normals[bad] = (0.0, 0.0, 1.0)
        mat, textured = material(item)
        attrs = gl.Attributes(
            POSITION=blob.attribute(positions, bounds=True), NORMAL=blob.attribute(normals)
        )
        if textured and uv is not None:
            attrs.TEXCOORD_0 = blob.attribute(np.c_[uv[:, 0], 1.0 - uv[:, 1]])
        n = len(positions)
        prim = gl.Primitive(attributes=attrs, material=mat, indices=blob.indices(faces, n))
        names = list(targets)
        for name in names:
            d = targets[name].astype(np.float32)
            idx = np.flatnonzero(np.abs(d).max(axis=1) > 0)
            prim.targets.append(gl.Attributes(POSITION=blob.sparse(n, idx, d[idx])))
        mesh = gl.Mesh(name=geom.name or None, primitives=[prim])
        if names:
            mesh.extras = {"targetNames": names}
            mesh.weights = [0.0] * len(names)
        meshes.append(mesh)
        nodes.append(gl.Node(name=geom.name or None, mesh=len(meshes) - 1))

    def walk(sn: SceneNode, world: np.ndarray) -> None:
        world = world @ sn.local
        for item in sn.shapes:
            add(item, world)
        for child in sn.children:
            walk(child, world)

    walk(head.root, np.eye(4))
    if not meshes:
        raise ExportError(f"{model.name}: nothing to export, the model draws no mesh")
    doc = gl.GLTF2(
        asset=gl.Asset(version="2.0", generator="vtts ARKit avatar export"),
        scene=0,
        scenes=[gl.Scene(name=model.name, nodes=list(range(len(nodes))))],
        nodes=nodes, meshes=meshes, materials=materials, textures=textures, images=images,
    )  # fmt: skip
    return blob.attach(doc)


def write_arkit_avatar(
    path: str | os.PathLike[str],
    model: FaceModel,
    table: RecipeTable | None = None,
    *,
    oculus: bool = True,
) -> Path:
    """Write ``model`` as an ARKit-blendshape ``.glb`` (see the module docstring), atomically.
    Returns the path."""
    path = Path(path)
    if path.suffix.lower() != ".glb":
        raise ExportError(f"an ARKit avatar is written as .glb, not {path.suffix or 'nothing'}",
                          file=str(path))  # fmt: skip
    return write_document(arkit_avatar_gltf(model, table, oculus=oculus), path)
