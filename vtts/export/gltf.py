"""Animated glTF 2.0 of one or more talking heads: :func:`write_gltf` and :func:`animation_gltf`.

What the file holds (``docs/web.md``, "glTF encoding", says it for users):

- one root node per head, named after its model, placed as :class:`~vtts.render.FaceRenderer`
  places it (``layout``), under it one node per VRML Transform (its DEF name kept; a Transform
  with a ``center`` or a ``scaleOrientation`` gets helper children named ``NAME.center`` /
  ``NAME.scale``), and one node per Shape carrying its mesh (named after the geometry's DEF name);
- the meshes with their materials (VRML Material as metallic-roughness, as the renderer maps it)
  and textures (the image files embedded, PNG or JPEG as they are, other formats as PNG);
- every spatial ADT as morph targets, one per (MIAP, IndexedFaceSet, interval), exactly
  (:mod:`vtts.export.morph`), with normal deltas;
- a perspective camera on a node named ``vtts``: the renderer's camera for ``size`` (pose, yfov,
  and an aspect ratio that keeps ``fx ≠ fy``); its exact intrinsics in the camera's extras;
- one animation, ``vtts``, of the whole stream: keyframe ``i`` at ``i / fps`` seconds (LINEAR),
  the morph weights of every animated mesh node, the rotation / translation / scale of every
  animated Transform (from the Transform ADTs), and the heads' root translation when ``roots``
  moves them.

At every keyframe the file reproduces vtts's own deformation to float32 rounding
(``tests/export/test_gltf.py`` decodes it and compares).
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pygltflib as gl

from vtts.errors import ExportError, VttsWarning
from vtts.export.morph import (
    MorphTargets,
    gather,
    morph_targets,
    unit_normals,
    vertex_layout,
)
from vtts.export.scene import HeadScene, Placement, SceneNode, ShapeItem, place
from vtts.face import N_PARAMS, FaceModel
from vtts.gltf import BufferBuilder, image_file, write_document
from vtts.gltf.images import brightened, png_bytes
from vtts.gltf.spec import CLAMP_TO_EDGE, LINEAR, LINEAR_MIPMAP_LINEAR, REPEAT, UNLIT
from vtts.gltf.uri import data_uri
from vtts.gltf.writer import GLTF_SUFFIXES
from vtts.limits import MAX_FPS, MAX_FRAMES, MIN_FPS
from vtts.mesh import incidence
from vtts.render.camera import Camera
from vtts.render.scene import ALPHA_CUTOFF, has_alpha, load_image
from vtts.vrml import Node, rotation_matrix

#: The name of the camera node (the web player looks through it).
CAMERA_NODE = "vtts"
#: The name of the one animation.
ANIMATION = "vtts"


def write_gltf(
    path: str | os.PathLike[str],
    models: list[FaceModel],
    params,
    fps: float,
    *,
    roots=None,
    camera: Camera | None = None,
    size: tuple[int, int] = (352, 288),
    layout: str = "row",
    viewpoint: str | None = None,
) -> Path:
    """Write the animation of ``models`` driven by ``params`` to ``path``: ``.glb`` (binary) or
    ``.gltf`` (JSON, the buffer and images embedded as data URIs), atomically (a temporary name
    renamed when complete). Arguments as :func:`animation_gltf`. Returns the path."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in GLTF_SUFFIXES:
        raise ExportError(
            f"a glTF file ends in {' or '.join(GLTF_SUFFIXES)}, not {path.suffix or 'nothing'}",
            file=str(path),
        )
    doc = _Exporter(
        models, params, fps, roots, camera, size, layout, viewpoint, embed=suffix == ".gltf"
    ).build()
    return write_document(doc, path)


def animation_gltf(
    models: list[FaceModel],
    params,
    fps: float,
    *,
    roots=None,
    camera: Camera | None = None,
    size: tuple[int, int] = (352, 288),
    layout: str = "row",
    viewpoint: str | None = None,
) -> gl.GLTF2:
    """The animation as a ``pygltflib.GLTF2`` whose one buffer is its binary blob (GLB style:
    ``doc.save_binary(path)`` writes a ``.glb``).

    ``models``: one or more :class:`~vtts.face.FaceModel` (a single model is taken too).
    ``params``: ``(T, N_PARAMS)`` parameter vectors for every model, or a list with one
    ``(T, N_PARAMS)`` array per model (the vectors :meth:`FaceRenderer.prepare
    <vtts.render.FaceRenderer.prepare>` takes, frame after frame). ``fps``: the frame rate
    (keyframe ``i`` at ``i / fps`` s). ``roots``: per model None or its root pose in each frame
    ``(T, 4, 4)`` in the renderer's world (:func:`vtts.animate.fapstream.model_roots`), or None.
    ``camera``, ``size``, ``layout``, ``viewpoint`` as :class:`~vtts.render.FaceRenderer` takes
    them: the file's camera is the renderer's. Raises :class:`~vtts.errors.ExportError` for bad
    arguments."""
    return _Exporter(models, params, fps, roots, camera, size, layout, viewpoint).build()


def placement(
    models: list[FaceModel],
    *,
    camera: Camera | None = None,
    size: tuple[int, int] = (352, 288),
    layout: str = "row",
    viewpoint: str | None = None,
) -> Placement:
    """Where the export puts the heads and its camera (as the renderer would, without OpenGL):
    ``placement(models).matrices[i]`` is ``FaceRenderer.model_matrix(i)``, the root pose that
    :func:`vtts.animate.fapstream.model_roots` moves."""
    return place(_model_list(models), size=size, camera=camera, viewpoint=viewpoint, layout=layout)


# ---- the exporter -------------------------------------------------------------------------------


@dataclass(eq=False)
class _MeshEntry:
    index: int  # glTF mesh
    targets: MorphTargets | None
    nodes: list[int] = field(default_factory=list)  # node instances showing it


@dataclass(eq=False)
class _TransformEntry:
    """The glTF nodes of one VRML Transform instance that its animated fields drive."""

    vrml: Node
    rotation: int  # node index whose rotation is the Transform's rotation
    translation: int  # node whose translation is the Transform's translation + center
    scale: int  # node whose scale is the Transform's scale
    center: np.ndarray


class _Exporter:
    def __init__(
        self,
        models,
        params,
        fps,
        roots,
        camera: Camera | None,
        size,
        layout: str,
        viewpoint: str | None,
        *,
        embed: bool = False,
    ) -> None:
        self.models = _model_list(models)
        self.params = _params(params, len(self.models))
        self.n_frames = self.params[0].shape[0]
        self.fps = _fps(fps)
        self.roots = _roots(roots, len(self.models), self.n_frames)
        self.placement = place(
            self.models, size=size, camera=camera, viewpoint=viewpoint, layout=layout
        )
        self.embed = embed
        self.blob = BufferBuilder()
        self.nodes: list[gl.Node] = []
        self.meshes: list[gl.Mesh] = []
        self.materials: list[gl.Material] = []
        self.textures: list[gl.Texture] = []
        self.images: list[gl.Image] = []
        self.samplers: list[gl.Sampler] = []
        self._mesh_cache: dict[tuple, _MeshEntry] = {}
        self._material_cache: dict[tuple, int] = {}
        self._cutouts: set[int] = set()  # textures whose alpha cuts them out (the renderer's)
        self._image_cache: dict[object, int] = {}
        self._sampler_cache: dict[tuple, int] = {}

    # ---- document -----------------------------------------------------------------------------

    def build(self) -> gl.GLTF2:
        pl = self.placement
        scene_nodes = []
        animations: list[tuple[int, str, np.ndarray]] = []  # (node, path, (T, k) values)
        names = unique_names([h.model.name for h in pl.heads])
        for i, (head, matrix) in enumerate(zip(pl.heads, pl.matrices, strict=True)):
            root, entries, meshes = self._head(head, names[i], matrix)
            scene_nodes.append(root)
            animations += self._head_channels(i, head, root, entries, meshes)
        for name, tri, color in pl.room:
            scene_nodes.append(self._room_node(name, tri, color))
        scene_nodes.append(self._camera_node(pl.camera, pl.size))
        animation = self._animation(animations)
        used = sorted({e for m in self.materials for e in (m.extensions or {})})
        doc = gl.GLTF2(
            extensionsUsed=used,
            asset=gl.Asset(
                version="2.0",
                generator=f"vtts {_version()}",
                extras={
                    "vtts": {
                        "fps": self.fps,
                        "frames": self.n_frames,
                        "duration": self.n_frames / self.fps,
                        "heads": names,
                        "size": list(pl.size),
                    }
                },
            ),
            scene=0,
            scenes=[gl.Scene(name="vtts", nodes=scene_nodes)],
            nodes=self.nodes,
            meshes=self.meshes,
            materials=self.materials,
            textures=self.textures,
            images=self.images,
            samplers=self.samplers,
            cameras=[self._camera(pl.camera, pl.size)],
            animations=[animation] if animation is not None else [],
        )
        return self.blob.attach(doc, embed=self.embed)

    def _node(self, node: gl.Node) -> int:
        self.nodes.append(node)
        return len(self.nodes) - 1

    # ---- heads --------------------------------------------------------------------------------

    def _head(self, head: HeadScene, name: str, matrix: np.ndarray):
        entries: list[tuple[str, _TransformEntry]] = []
        meshes: list[_MeshEntry] = []
        root = self._node(gl.Node(name=name, translation=_list(matrix[:3, 3])))
        self._fill(head, root, head.root, entries, meshes)
        return root, entries, meshes

    def _fill(self, head: HeadScene, parent: int, sn: SceneNode, entries, meshes) -> None:
        """Put ``sn``'s shapes and Transforms below glTF node ``parent``."""
        for item in sn.shapes:
            entry = self._mesh(head.model, item)
            node = self._node(gl.Node(name=item.geometry.name or None, mesh=entry.index))
            self.nodes[parent].children.append(node)
            entry.nodes.append(node)
            if entry.targets is not None and entry not in meshes:
                meshes.append(entry)
        for child in sn.children:
            outer, inner, entry = self._transform(child, head.model)
            self.nodes[parent].children.append(outer)
            if child.name is not None:
                entries.append((child.name, entry))
            self._fill(head, inner, child, entries, meshes)

    def _transform(self, sn: SceneNode, model: FaceModel) -> tuple[int, int, _TransformEntry]:
        """The glTF nodes of a VRML Transform ``T·C·R·SR·S·SR⁻¹·C⁻¹``: ``NAME`` (translation
        T + C, rotation R, and scale S when SR does not matter), ``NAME.scale`` (rotation SR,
        scale S) and ``NAME.center`` (rotation SR⁻¹, translation −SR⁻¹·C) where needed. Returns
        (outer node, the node children go under, the animation entry). SR does not matter when
        it is the identity, or when S is uniform and no table animates it."""
        v = sn.transform
        t = np.asarray(v["translation"], dtype=np.float64)
        r = np.asarray(v["rotation"], dtype=np.float64)
        s = np.asarray(v["scale"], dtype=np.float64)
        so = np.asarray(v["scaleOrientation"], dtype=np.float64)
        c = np.asarray(v["center"], dtype=np.float64)
        sr = rotation_matrix(so)
        animated_scale = (sn.name, "scale") in model.engine.transforms
        plain_scale = np.array_equal(sr, np.eye(3)) or (s[0] == s[1] == s[2] and not animated_scale)
        outer = self._node(
            gl.Node(
                name=sn.name,
                translation=_opt(t + c, 0.0),
                rotation=_opt_rotation(r),
                scale=_opt(s, 1.0) if plain_scale else None,
            )
        )
        inner, scale_node = outer, outer
        if not plain_scale:
            q = _quat_of_matrix(sr)
            scale_node = inner = self._add_child(
                inner, gl.Node(name=f"{sn.name}.scale", rotation=_list(q), scale=_list(s))
            )
            q_inv = q * np.array([-1, -1, -1, 1.0])
            inner = self._add_child(
                inner,
                gl.Node(
                    name=f"{sn.name}.center",
                    rotation=_list(q_inv),
                    translation=_opt(-(sr.T @ c), 0.0),
                ),
            )
        elif np.any(c != 0):
            inner = self._add_child(inner, gl.Node(name=f"{sn.name}.center", translation=_list(-c)))
        return outer, inner, _TransformEntry(v, outer, outer, scale_node, c)

    def _add_child(self, parent: int, node: gl.Node) -> int:
        index = self._node(node)
        self.nodes[parent].children.append(index)
        return index

    def _head_channels(self, i: int, head: HeadScene, root: int, entries, meshes) -> list:
        model, params = head.model, self.params[i]
        out = []
        for entry in meshes:
            w = entry.targets.weights(params)
            for node in entry.nodes:
                out.append((node, "weights", w))
        tracks = model.engine.transform_tracks(params) if model.engine.transforms else {}
        for name, te in entries:
            for fld in ("rotation", "translation", "scale"):
                values = tracks.get((name, fld))
                if values is not None:
                    if fld == "rotation":
                        out.append((te.rotation, "rotation", _continuous(_quats(values))))
                    elif fld == "translation":
                        out.append((te.translation, "translation", values + te.center))
                    else:
                        out.append((te.scale, "scale", values))
        if self.roots[i] is not None:
            out += self._root_channels(root, self.roots[i], model.name)
        return out

    def _root_channels(self, root: int, poses: np.ndarray, name: str) -> list:
        lin = poses[:, :3, :3]
        scale = np.linalg.norm(lin, axis=1)  # column norms: (T, 3)
        rot = lin / scale[:, None, :]
        if (
            not np.allclose(rot @ rot.transpose(0, 2, 1), np.eye(3), atol=1e-6)
            or (np.linalg.det(rot) < 0).any()
        ):
            raise ExportError(
                f"{name}: a root pose shears or mirrors the head; a glTF node can only move, "
                "turn and scale it"
            )
        out = [(root, "translation", poses[:, :3, 3])]
        if not np.allclose(rot, np.eye(3), atol=1e-12):
            out.append((root, "rotation", _continuous(np.array([_quat_of_matrix(m) for m in rot]))))
        if not np.allclose(scale, 1.0, atol=1e-12):
            out.append((root, "scale", scale))
        return out

    # ---- meshes -------------------------------------------------------------------------------

    def _mesh(self, model: FaceModel, item: ShapeItem) -> _MeshEntry:
        textured = item.mesh is not None
        key = (id(item.geometry), id(item.appearance), item.double_sided)
        entry = self._mesh_cache.get(key)
        if entry is not None:
            return entry
        material = self._material(model, item.appearance, item.double_sided, textured)
        uses_texture = self.materials[material].pbrMetallicRoughness.baseColorTexture is not None
        if item.mesh is None:
            prim, targets, extras = self._primitive_geometry(item), None, None
        else:
            prim, targets, extras = self._face_set(model, item, uses_texture)
        prim.material = material
        mesh = gl.Mesh(name=item.geometry.name or None, primitives=[prim])
        if extras:
            mesh.extras = extras
        self.meshes.append(mesh)
        entry = self._mesh_cache[key] = _MeshEntry(len(self.meshes) - 1, targets)
        return entry

    def _face_set(self, model: FaceModel, item: ShapeItem, uses_texture: bool):
        tm = item.mesh
        geom = item.geometry
        block = model.engine.meshes.get(geom.name) if geom.name else None
        if block is not None:
            points = block.neutral
        else:
            coord = geom["coord"]
            points = np.asarray(coord.expand()["point"], dtype=np.float64).reshape(-1, 3)
        layout = vertex_layout(tm, points.shape[0])
        positions = points[layout.point]
        if block is not None:
            # as the renderer draws an animated mesh: its normals recomputed from the positions
            normals = unit_normals(positions, layout.faces, incidence(layout.faces, len(positions)))
        else:
            normals = gather(tm.normals, layout, (0.0, 0.0, 1.0))
            normals[~(np.abs(normals).sum(axis=1) > 0)] = (0.0, 0.0, 1.0)
        b = self.blob
        attributes = gl.Attributes(
            POSITION=b.attribute(positions, bounds=True), NORMAL=b.attribute(normals)
        )
        if uses_texture:
            st = gather(tm.texcoords, layout)
            # VRML's t runs up the image, glTF's v down it
            attributes.TEXCOORD_0 = b.attribute(np.c_[st[:, 0], 1.0 - st[:, 1]])
        if tm.colors is not None:
            attributes.COLOR_0 = b.attribute(np.clip(gather(tm.colors, layout), 0.0, 1.0))
        prim = gl.Primitive(attributes=attributes, indices=b.indices(layout.faces, len(positions)))
        extras = {"vtts": {"points": layout.n_points}}
        if block is None:
            return prim, None, extras
        miaps = {m.index: m for m in model.tables.adts}
        targets = morph_targets(block, miaps, layout)
        n = len(positions)
        for c in range(len(targets.names)):
            t = gl.Attributes(POSITION=b.sparse(n, *targets.positions[c]))
            if targets.normals is not None:
                t.NORMAL = b.sparse(n, *targets.normals[c])
            prim.targets.append(t)
        extras["targetNames"] = targets.names
        extras["vtts"]["intervals"] = [
            [float(a), float(e)] for a, e in zip(targets.start, targets.end, strict=True)
        ]
        return prim, targets, extras

    def _primitive_geometry(self, item: ShapeItem) -> gl.Primitive:
        tri = item.primitive
        faces = np.asarray(tri.faces)
        if item.geometry.type.name == "Box":
            # flat, as the renderer draws a Box: each face its own vertices
            positions = np.asarray(tri.vertices)[faces].reshape(-1, 3)
            normals = np.repeat(np.asarray(tri.face_normals), 3, axis=0)
            faces = np.arange(positions.shape[0]).reshape(-1, 3)
        else:
            positions = np.asarray(tri.vertices)
            normals = np.asarray(tri.vertex_normals)
        return self._plain_primitive(positions, normals, faces)

    def _plain_primitive(self, positions, normals, faces) -> gl.Primitive:
        b = self.blob
        return gl.Primitive(
            attributes=gl.Attributes(
                POSITION=b.attribute(positions, bounds=True), NORMAL=b.attribute(normals)
            ),
            indices=b.indices(faces, len(positions)),
        )

    def _room_node(self, name: str, tri, color) -> int:
        faces = np.asarray(tri.faces)
        positions = np.asarray(tri.vertices)[faces].reshape(-1, 3)
        normals = np.repeat(np.asarray(tri.face_normals), 3, axis=0)
        prim = self._plain_primitive(positions, normals, np.arange(len(positions)).reshape(-1, 3))
        self.materials.append(
            gl.Material(
                name=name,
                pbrMetallicRoughness=gl.PbrMetallicRoughness(
                    baseColorFactor=list(color), metallicFactor=0.0, roughnessFactor=1.0
                ),
            )
        )
        prim.material = len(self.materials) - 1
        self.meshes.append(gl.Mesh(name=name, primitives=[prim]))
        return self._node(gl.Node(name=name, mesh=len(self.meshes) - 1))

    # ---- materials ----------------------------------------------------------------------------

    def _material(
        self, model: FaceModel, appearance: Node | None, double_sided: bool, textured: bool
    ) -> int:
        """The renderer's mapping of a VRML Appearance: diffuseColor and 1 − transparency as the
        base color, emissiveColor, roughness 1 − 0.8·shininess, not metallic; a texture
        multiplies the base color (white when there is no Material). An Appearance without a
        Material is not lit (VRML97): ``KHR_materials_unlit``. A texture with an alpha channel
        that is under the cutoff somewhere is a cutout (``alphaMode`` MASK), as the renderer
        draws it (:data:`vtts.render.scene.ALPHA_CUTOFF`)."""  # fmt: skip
        key = (id(appearance), double_sided, textured)
        if key in self._material_cache:
            return self._material_cache[key]
        base = [0.8, 0.8, 0.8, 1.0]
        emissive = [0.0, 0.0, 0.0]
        roughness = 0.8
        texture = None
        name = None
        unlit = False
        if appearance is not None:
            appearance = appearance.expand()
            name = appearance.name or None
            mat = appearance["material"]
            unlit = mat is None
            if mat is not None:
                mat = mat.expand()
                name = name or mat.name or None
                base[:3] = [float(v) for v in mat["diffuseColor"]]
                base[3] = 1.0 - float(mat["transparency"])
                emissive = [float(v) for v in mat["emissiveColor"]]
                roughness = float(np.clip(1.0 - 0.8 * mat["shininess"], 0.05, 1.0))
            tex = appearance["texture"]
            if tex is not None and textured:
                # a diffuseColor above 1 (glTF's factor stops at 1) brightens the texture itself
                gain = tuple(max(v, 1.0) for v in base[:3])
                texture = self._texture(model, tex.expand(), gain)
                if texture is not None and mat is None:
                    base[:3] = [1.0, 1.0, 1.0]
                elif texture is not None:
                    base[:3] = [v / g for v, g in zip(base[:3], gain, strict=True)]
        base = [float(np.clip(v, 0.0, 1.0)) for v in base]
        pbr = gl.PbrMetallicRoughness(
            baseColorFactor=base, metallicFactor=0.0, roughnessFactor=roughness
        )
        if texture is not None:
            pbr.baseColorTexture = gl.TextureInfo(index=texture)
        mode = "BLEND" if base[3] < 1.0 else "OPAQUE"
        if mode == "OPAQUE" and texture in self._cutouts:
            mode = "MASK"
        material = gl.Material(
            name=name,
            pbrMetallicRoughness=pbr,
            emissiveFactor=[float(np.clip(v, 0.0, 1.0)) for v in emissive],
            alphaMode=mode,
            alphaCutoff=ALPHA_CUTOFF if mode == "MASK" else None,
            doubleSided=double_sided,
        )
        if unlit:
            material.extensions = {UNLIT: {}}
        self.materials.append(material)
        index = self._material_cache[key] = len(self.materials) - 1
        return index

    def _texture(self, model: FaceModel, tex: Node, gain=(1.0, 1.0, 1.0)) -> int | None:
        """The index of the glTF texture of ``tex``; an image texture ``gain (3,)`` times
        brighter (linear light: :func:`~vtts.gltf.images.brightened`) where a gain is above 1."""
        if tex.type.name == "PixelTexture":
            img = tex["image"]
            if img.width == 0 or img.height == 0:
                return None
            image = self._image(("pixel", id(tex)), lambda: (png_bytes(img.to_rgba()), "image/png"))
            cutout = has_alpha(img.to_rgba())
        elif tex.type.name == "ImageTexture":
            path = model.texture_file(tex)
            if path is None:
                if list(tex["url"]):
                    warnings.warn(model.texture_warning(tex, list(tex["url"])), stacklevel=4)
                return None
            if any(g != 1.0 for g in gain):
                image = self._image((path, gain), lambda: (
                    png_bytes(brightened(load_image(path), gain)), "image/png"))  # fmt: skip
            else:
                image = self._image(path, lambda: image_file(path))
            cutout = has_alpha(load_image(path))
        else:
            return None
        wrap = tuple(REPEAT if tex[f] else CLAMP_TO_EDGE for f in ("repeatS", "repeatT"))
        sampler = self._sampler_cache.get(wrap)
        if sampler is None:
            self.samplers.append(
                gl.Sampler(
                    magFilter=LINEAR, minFilter=LINEAR_MIPMAP_LINEAR, wrapS=wrap[0], wrapT=wrap[1]
                )
            )
            sampler = self._sampler_cache[wrap] = len(self.samplers) - 1
        self.textures.append(gl.Texture(source=image, sampler=sampler))
        if cutout:
            self._cutouts.add(len(self.textures) - 1)
        return len(self.textures) - 1

    def _image(self, key, load) -> int:
        if key in self._image_cache:
            return self._image_cache[key]
        data, mime = load()
        if self.embed:
            image = gl.Image(uri=data_uri(data, mime))
        else:
            image = gl.Image(bufferView=self.blob.view(data), mimeType=mime)
        if isinstance(key, Path):
            image.name = key.name
        self.images.append(image)
        index = self._image_cache[key] = len(self.images) - 1
        return index

    # ---- camera and animation -----------------------------------------------------------------

    def _camera(self, camera: Camera, size: tuple[int, int]) -> gl.Camera:
        w, h = size
        if not (math.isclose(camera.cx, w / 2) and math.isclose(camera.cy, h / 2)):
            warnings.warn(
                VttsWarning(
                    f"the camera's principal point ({camera.cx:g}, {camera.cy:g}) is not the "
                    f"middle of the {w}x{h} image: a glTF camera looks through the middle (its "
                    "extras keep the exact intrinsics)"
                ),
                stacklevel=4,
            )
        return gl.Camera(
            name=CAMERA_NODE,
            type="perspective",
            perspective=gl.Perspective(
                yfov=2 * math.atan(h / (2 * camera.fy)),
                aspectRatio=(w / h) * (camera.fy / camera.fx),
                znear=float(camera.znear),
                zfar=float(camera.zfar),
            ),
            extras={
                "vtts": {
                    "size": [w, h],
                    "fx": float(camera.fx),
                    "fy": float(camera.fy),
                    "cx": float(camera.cx),
                    "cy": float(camera.cy),
                }
            },
        )

    def _camera_node(self, camera: Camera, size) -> int:
        pose = camera.pose  # camera-to-world, looking along −z with y up: glTF's convention
        return self._node(
            gl.Node(
                name=CAMERA_NODE,
                camera=0,
                translation=_list(pose[:3, 3]),
                rotation=_list(_quat_of_matrix(pose[:3, :3])),
            )
        )

    def _animation(self, channels: list[tuple[int, str, np.ndarray]]) -> gl.Animation | None:
        if not channels:
            return None
        b = self.blob
        times = (np.arange(self.n_frames) / self.fps).astype(np.float32)
        time_acc = b.accessor(times, bounds=True)
        samplers: list[gl.AnimationSampler] = []
        out_channels: list[gl.AnimationChannel] = []
        shared: dict[int, int] = {}  # id of a value array -> its sampler (mesh instances)
        for node, path, values in channels:
            sampler = shared.get(id(values))
            if sampler is None:
                v = np.asarray(values, dtype=np.float32)
                output = b.accessor(v.reshape(-1) if path == "weights" else v)
                samplers.append(
                    gl.AnimationSampler(input=time_acc, output=output, interpolation="LINEAR")
                )
                sampler = shared[id(values)] = len(samplers) - 1
            out_channels.append(
                gl.AnimationChannel(
                    sampler=sampler, target=gl.AnimationChannelTarget(node=node, path=path)
                )
            )
        return gl.Animation(name=ANIMATION, samplers=samplers, channels=out_channels)


# ---- arguments ----------------------------------------------------------------------------------


def _model_list(models) -> list[FaceModel]:
    if isinstance(models, FaceModel):
        return [models]
    models = list(models)
    if not models:
        raise ExportError("nothing to export: no model given")
    for m in models:
        if not isinstance(m, FaceModel):
            raise ExportError(f"a model is a vtts FaceModel, got {type(m).__name__}")
    return models


def _params(params, n_models: int) -> list[np.ndarray]:
    """One ``(T, N_PARAMS) float64`` array per model."""
    if isinstance(params, np.ndarray) and params.ndim == 2:
        arrays = [params] * n_models
    else:
        arrays = list(params)
        if len(arrays) != n_models:
            raise ExportError(f"{n_models} models but {len(arrays)} parameter tracks")
    out = []
    for a in arrays:
        a = np.asarray(a, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != N_PARAMS:
            raise ExportError(f"parameters are (frames, {N_PARAMS}) per model, got shape {a.shape}")
        if not np.isfinite(a).all():
            raise ExportError("parameters must be finite numbers (a frame has nan or inf)")
        out.append(a)
    counts = {a.shape[0] for a in out}
    if len(counts) != 1:
        raise ExportError(f"every model needs as many frames, got {sorted(counts)}")
    (n,) = counts
    if not 1 <= n <= MAX_FRAMES:
        raise ExportError(f"an animation has 1–{MAX_FRAMES} frames, got {n}")
    return out


def _fps(fps) -> float:
    try:
        v = float(fps)
    except (TypeError, ValueError):
        raise ExportError(f"fps must be a number, got {fps!r}") from None
    if not (math.isfinite(v) and MIN_FPS <= v <= MAX_FPS):
        raise ExportError(f"fps must be within {MIN_FPS:g}–{MAX_FPS:g}, got {fps!r}")
    return v


def _roots(roots, n_models: int, n_frames: int) -> list[np.ndarray | None]:
    if roots is None:
        return [None] * n_models
    roots = list(roots)
    if len(roots) != n_models:
        raise ExportError(f"{n_models} models but {len(roots)} root tracks")
    out = []
    for r in roots:
        if r is None:
            out.append(None)
            continue
        r = np.asarray(r, dtype=np.float64)
        if r.shape != (n_frames, 4, 4) or not np.isfinite(r).all():
            raise ExportError(
                f"a model's root poses are finite ({n_frames}, 4, 4) matrices, got shape {r.shape}"
            )
        out.append(r)
    return out


# ---- small helpers ------------------------------------------------------------------------------


def _list(v) -> list[float]:
    return [float(x) for x in np.asarray(v).reshape(-1)]


def _opt(v: np.ndarray, default: float) -> list[float] | None:
    """``v`` as a list, or None (left out of the JSON) when it is glTF's default."""
    return None if np.all(v == default) else _list(v)


def _quat(rotation: np.ndarray) -> np.ndarray:
    """glTF's ``(x, y, z, w)`` unit quaternion of a VRML axis-angle ``(4,)``."""
    axis = np.asarray(rotation[:3], dtype=np.float64)
    n = np.linalg.norm(axis)
    if n == 0 or rotation[3] == 0:
        return np.array([0.0, 0.0, 0.0, 1.0])
    half = float(rotation[3]) / 2
    return np.r_[axis / n * math.sin(half), math.cos(half)]


def _quats(rotations: np.ndarray) -> np.ndarray:
    """:func:`_quat` of each row of ``rotations`` ``(T, 4)``: ``(T, 4)``."""
    r = np.asarray(rotations, dtype=np.float64)
    n = np.linalg.norm(r[:, :3], axis=1)
    turns = (n > 0) & (r[:, 3] != 0)
    q = np.zeros((len(r), 4))
    q[:, 3] = 1.0
    half = r[turns, 3] / 2
    q[turns, :3] = r[turns, :3] / n[turns, None] * np.sin(half)[:, None]
    q[turns, 3] = np.cos(half)
    return q


def _opt_rotation(rotation: np.ndarray) -> list[float] | None:
    q = _quat(rotation)
    return None if q[3] == 1.0 else _list(q)


def _quat_of_matrix(m: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(np.asarray(m, dtype=np.float64)).as_quat()  # (x, y, z, w)
    return q / np.linalg.norm(q)


def _continuous(q: np.ndarray) -> np.ndarray:
    """Quaternions ``(T, 4)`` with signs chosen so that each is within 90° of the one before:
    LINEAR (slerp) then turns the short way between keyframes."""
    q = np.array(q, dtype=np.float64)
    # flipping one keyframe flips its dot with the next: the signs multiply up
    flips = np.where(np.einsum("ij,ij->i", q[1:], q[:-1]) < 0, -1.0, 1.0)
    return q * np.r_[1.0, np.cumprod(flips)][:, None]


def unique_names(names: list[str]) -> list[str]:
    """``names`` with repeats numbered: cybatt, cybatt-2 (the heads' root nodes in the file, and
    the web player's head menu)."""
    seen: dict[str, int] = {}
    out = []
    for n in names:
        seen[n] = seen.get(n, 0) + 1
        out.append(n if seen[n] == 1 else f"{n}-{seen[n]}")
    return out


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("vtts")
    except Exception:  # not installed: running from a checkout
        return "dev"
