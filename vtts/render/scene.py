"""The pyrender scene of VRML models, built once per renderer.

:class:`SceneBuilder` walks each model's VRML scene graph: Transforms become pyrender nodes with
their local matrices, Shapes become meshes under them (IndexedFaceSets triangulated, Box, Sphere,
Cylinder and Cone as meshes), Appearances become metallic-roughness materials and textures. It
records what the model's tables animate — :class:`AnimatedMesh` for each animated
IndexedFaceSet, :class:`AnimatedTransform` for each animated Transform — in a
:class:`ModelInstance`, which :class:`~vtts.render.renderer.FaceRenderer` updates per frame. It
also lays the models out side by side (or in a room) and puts the camera and lights in.
"""

from __future__ import annotations

import hashlib
import threading
import weakref
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from vtts.errors import RenderError, VttsError
from vtts.face import FaceModel
from vtts.limits import check_image_size
from vtts.mesh import incidence, vertex_normals
from vtts.render.camera import row_layout
from vtts.render.lod import Collapses
from vtts.render.pyrender_adapter import load_pyrender, order_scene, pyrender_texture
from vtts.vrml import Node, drawn_children, primitive_mesh, transform_matrix, triangulate
from vtts.vrml.geometry import TriangleMesh
from vtts.vrml.scene import GROUPING

#: The attribute that marks a pyrender material as unlit (VRML97: an Appearance without a
#: Material is not lit, its texture's colour shows as it is): the deferred pass's resolve writes
#: the texture's sample times the base color factor, as stored. pyrender's own shader has no
#: such mode: a scene that the G-buffer cannot hold draws these materials lit.
UNLIT = "vtts_unlit"

#: The attribute that gives a pyrender material's dielectric highlight as a fraction of
#: pyrender's (its fixed Fresnel reflectance of 0.04): 0 for a VRML Material that sets
#: ``specularColor 0 0 0`` in the file (VRML97's "no highlight", which a photo-textured head
#: asks for: its photo brings its own), 1 for every other (a Material that leaves the field at
#: its default keeps pyrender's highlight, as the bundled heads were made with). Honoured by the
#: deferred pass; pyrender's own shader draws every material with the highlight.
SPECULAR = "vtts_specular"

#: The alpha (0–1) under which a texel of a texture with an alpha channel is not drawn: such a
#: texture draws as a cutout (glTF's ``alphaMode`` MASK), opaque where it shows — the fitted
#: heads' glasses (:mod:`vtts.fit.glasses`). VRML97 blends a four-component texture; a cutout
#: keeps the part in the G-buffer (:mod:`vtts.render.deferred`), sorted by depth like the rest.
ALPHA_CUTOFF = 0.5

#: The scene's ambient light (RGB, 0–1).
AMBIENT_LIGHT = (0.35, 0.35, 0.35)


@dataclass
class AnimatedMesh:
    """One animated IndexedFaceSet instance in the pyrender scene."""

    name: str  # DEF name of the IndexedFaceSet
    template: TriangleMesh
    parent: object  # pyrender.Node
    node: object  # the current mesh node
    material: object
    incidence: sp.csr_matrix  # (vertices, triangles): which triangles touch each output vertex
    # the vertex buffer's constant columns after positions and normals (texture coordinates,
    # colors) as pyrender lays them out, (vertices, k) float32; None: not updatable in place
    constant_columns: np.ndarray | None = None
    # the last Coordinate points prepared and what came of them (positions, normals, vertex
    # buffer): parts of a face that a frame leaves as they were cost nothing
    last: tuple | None = None
    first_triangle: int = 0  # the number of its first triangle (see FaceRenderer.triangle_sets)
    # opaque and unlit (UNLIT): drawn through the G-buffer its normals show nowhere, so a frame
    # leaves them as the template has them unless the scene is drawn lit (FaceRenderer.apply)
    unlit: bool = False
    # the triangles drawn: the template's, or fewer over the same vertices (FaceRenderer's
    # ``detail``, vtts.render.lod); the normals are always the template's triangles'
    faces: np.ndarray | None = None
    # with fewer triangles, the vertices they use, the template's triangles around those and
    # their incidence: the normals of vertices no triangle draws are never read (normals)
    drawn: tuple[np.ndarray, np.ndarray, sp.csr_matrix] | None = None
    # its progressive mesh, once a view has asked for it (read or made once)
    collapses: Collapses | None = None
    # the vertex positions of the frame on the GPU (FaceRenderer.apply), None: the template's
    applied: np.ndarray | None = None
    # (primitive, its GPU buffers, vertex buffer) last written by FaceRenderer.apply: the same
    # vertex buffer object again (a frame that leaves the mesh as it was) is not sent again
    uploaded: tuple | None = None

    def normals(self, positions: np.ndarray) -> np.ndarray:
        """The vertex normals for ``positions`` (``(n, 3)`` or ``(T, n, 3)``, as
        :func:`~vtts.mesh.vertex_normals`) from the template's triangles. With fewer triangles
        drawn (see :attr:`drawn`) only the vertices they use get them, from the same triangles
        summed in the same order (the same bits); the others, never read, are zero."""
        if self.drawn is None:
            return vertex_normals(positions, self.template.faces, self.incidence)
        used, faces, inc = self.drawn
        out = np.zeros(positions.shape)
        # the triangles' corners index the whole vertex list; the incidence's rows are the used
        out[..., used, :] = vertex_normals(positions, faces, inc)
        return out

    def vertex_data(self, positions: np.ndarray, normals: np.ndarray) -> np.ndarray | None:
        """The interleaved vertex buffer pyrender would upload for these positions and normals,
        ``(n, 6 + k) float32`` (``(T, n, 6 + k)`` for ``(T, n, 3)`` of each), or None when it
        cannot be updated in place."""
        const = self.constant_columns
        n = positions.shape[-2]
        if const is None or const.shape[0] != n:
            return None
        data = np.empty((*positions.shape[:-1], 6 + const.shape[1]), dtype=np.float32)
        data[..., :3] = positions
        data[..., 3:6] = normals
        data[..., 6:] = const
        return data


@dataclass
class AnimatedTransform:
    """One animated Transform: its VRML node and the pyrender nodes of its instances."""

    name: str
    vrml: Node
    nodes: list = field(default_factory=list)  # pyrender nodes (one per instance)
    last: tuple | None = None  # the last animated field values prepared, and their matrix
    applied: object = None  # the matrix its nodes were last given (set again only when new)


@dataclass
class ModelInstance:
    """One model in the scene: its root node, what its tables animate, and its bounds ``(3,)``
    in the renderer's world (once placed)."""

    model: FaceModel
    root: object
    meshes: list[AnimatedMesh] = field(default_factory=list)
    transforms: dict[str, AnimatedTransform] = field(default_factory=dict)
    lo: np.ndarray = field(default_factory=lambda: np.full(3, np.inf))
    hi: np.ndarray = field(default_factory=lambda: np.full(3, -np.inf))
    # the animated meshes' points in each pose of renderer.detail_poses (see lod_key), once
    # needed
    detail_points: dict | None = None
    # the IndexedFaceSets the tables leave as they are: DEF name -> (pyrender node, vertex
    # positions (n, 3) as drawn)
    still: dict = field(default_factory=dict)


class SceneBuilder:
    """Builds one pyrender scene (:attr:`scene`) of VRML models, cleared to ``bg_color``
    (RGBA, 0–1).

    :attr:`triangle_sets` lists every IndexedFaceSet added as ``(node, first, count)`` (see
    :class:`~vtts.render.renderer.FaceRenderer`); :attr:`triangle_numbers` maps each of their
    pyrender primitives to its first triangle's number."""

    def __init__(self, bg_color: list[float]) -> None:
        pr = load_pyrender()
        self.scene = pr.Scene(bg_color=bg_color, ambient_light=list(AMBIENT_LIGHT))
        order_scene(self.scene)
        self._image_textures: dict[Path, object] = {}  # image file -> its pyrender texture
        self._materials: dict[tuple[int, bool], object] = {}
        self._hidden: frozenset[str] = frozenset()
        self.triangle_sets: list[tuple[Node, int, int]] = []
        self.triangle_numbers: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

    def add_model(self, model: FaceModel, hidden: frozenset[str] = frozenset()) -> ModelInstance:
        """Add ``model``'s scene under a root node of its own (at the origin: see
        :meth:`place`); the IndexedFaceSets DEFed with a name in ``hidden`` are posed as the
        others but not drawn."""
        pr = load_pyrender()
        self._hidden = hidden
        root = pr.Node(matrix=np.eye(4))
        self.scene.add_node(root)
        inst = ModelInstance(model, root)
        animated_meshes = set(model.tables.mesh_nodes())
        animated_transforms = set(model.tables.transform_nodes())
        self._materials = {}

        def walk(node: Node, parent, world: np.ndarray, depth: int) -> None:
            node = node.expand()
            t = node.type.name
            if depth > 128:
                raise RenderError(f"{model.name}: scene graph nests deeper than 128 levels")
            if t == "Transform":
                local = transform_matrix(node)
                if not np.isfinite(local).all() or abs(np.linalg.det(local[:3, :3])) < 1e-30:
                    return  # a scale of 0 (or overflowing fields) hides what is below
                pn = pr.Node(matrix=local)
                self.scene.add_node(pn, parent_node=parent)
                if node.name in animated_transforms:
                    inst.transforms.setdefault(
                        node.name, AnimatedTransform(node.name, node)
                    ).nodes.append(pn)
                for c in drawn_children(node):
                    walk(c, pn, world @ local, depth + 1)
            elif t in GROUPING:
                for c in drawn_children(node):
                    walk(c, parent, world, depth + 1)
            elif t == "Shape":
                self._add_shape(inst, node, parent, world, animated_meshes)

        for r in model.scene.roots:
            walk(r, root, np.eye(4), 0)
        return inst

    def _add_shape(self, inst, shape: Node, parent, world: np.ndarray, animated: set[str]) -> None:
        pr = load_pyrender()
        geom = shape["geometry"]
        if geom is None:
            return
        geom = geom.expand()
        solid = bool(geom.get("solid", True))
        material = self._material(inst.model, shape["appearance"], not solid)
        if geom.type.name == "IndexedFaceSet":
            try:
                tm = triangulate(geom)
            except VttsError as e:
                e.file = e.file or (str(inst.model.path) if inst.model.path else None)
                raise
            if tm.faces.size == 0:
                return
            _, last, count = self.triangle_sets[-1] if self.triangle_sets else (None, 0, 0)
            first = last + count
            self.triangle_sets.append((geom, first, len(tm.faces)))
            mesh = self.mesh(tm, tm.positions, tm.normals, material, first)
            mesh.is_visible = geom.name not in self._hidden
            node = self.scene.add(mesh, parent_node=parent)
            pts = tm.positions
            if geom.name and geom.name not in animated:
                inst.still[geom.name] = (node, tm.positions)
            if geom.name in animated:
                inc = _incidence(tm)
                inst.meshes.append(
                    AnimatedMesh(
                        geom.name,
                        tm,
                        parent,
                        node,
                        material,
                        inc,
                        constant_columns(mesh),
                        first_triangle=first,
                        unlit=getattr(material, UNLIT, False) and not mesh.is_transparent,
                    )
                )
        else:
            tri = primitive_mesh(geom)
            if tri is None:
                return
            mesh = pr.Mesh.from_trimesh(tri, material=material, smooth=geom.type.name != "Box")
            self.scene.add(mesh, parent_node=parent)
            pts = np.asarray(tri.vertices)
        world_pts = pts @ world[:3, :3].T + world[:3, 3]
        inst.lo = np.minimum(inst.lo, world_pts.min(axis=0))
        inst.hi = np.maximum(inst.hi, world_pts.max(axis=0))

    def replace_mesh(self, am: AnimatedMesh, positions, normals) -> None:
        """Put an animated mesh into the scene anew: a node with these positions and normals
        and the triangles it draws (pyrender uploads it at the next frame)."""
        visible = am.node.mesh.is_visible
        self.scene.remove_node(am.node)
        mesh = self.mesh(am.template, positions, normals, am.material, am.first_triangle, am.faces)
        mesh.is_visible = visible
        am.node = self.scene.add(mesh, parent_node=am.parent)

    def mesh(
        self,
        tm: TriangleMesh,
        positions: np.ndarray,
        normals: np.ndarray,
        material,
        first_triangle: int,
        faces: np.ndarray | None = None,
    ):
        """A pyrender mesh of ``tm``'s triangles (or ``faces``) with these ``(n, 3)``
        ``positions`` and ``normals``, whose triangles are numbered from ``first_triangle``."""
        pr = load_pyrender()
        colors = None if tm.colors is None else np.c_[tm.colors, np.ones(len(tm.colors))]
        prim = pr.Primitive(
            positions=positions.astype(np.float32),
            normals=normals.astype(np.float32),
            texcoord_0=None if tm.texcoords is None else tm.texcoords.astype(np.float32),
            color_0=None if colors is None else colors.astype(np.float32),
            indices=(tm.faces if faces is None else faces).astype(np.uint32),
            material=material,
        )
        self.triangle_numbers[prim] = first_triangle
        return pr.Mesh([prim])

    def _material(self, model: FaceModel, appearance: Node | None, double_sided: bool):
        """The pyrender material of a VRML Appearance; ``double_sided`` for geometry that is not
        ``solid`` (VRML's default is solid: back faces are culled)."""
        pr = load_pyrender()
        key = (id(appearance), double_sided)
        if key in self._materials:
            return self._materials[key]
        base = np.array([0.8, 0.8, 0.8, 1.0])
        emissive = np.zeros(3)
        roughness = 0.8
        texture = None
        specular = 1.0
        if appearance is not None:
            appearance = appearance.expand()
            mat = appearance["material"]
            if mat is not None:
                mat = mat.expand()
                base[:3] = mat["diffuseColor"]
                base[3] = 1.0 - float(mat["transparency"])
                emissive = np.asarray(mat["emissiveColor"], dtype=np.float64)
                roughness = float(np.clip(1.0 - 0.8 * mat["shininess"], 0.05, 1.0))
                if "specularColor" in mat.fields and not np.any(mat["specularColor"]):
                    specular = 0.0
            tex = appearance["texture"]
            if tex is not None:
                texture = self._texture(model, tex.expand())
                if texture is not None and mat is None:
                    base[:3] = 1.0
        mode = "BLEND" if base[3] < 1.0 else "OPAQUE"
        if mode == "OPAQUE" and texture is not None and has_alpha(texture.source):
            mode = "MASK"
        material = pr.MetallicRoughnessMaterial(
            baseColorFactor=base,
            metallicFactor=0.0,
            roughnessFactor=roughness,
            emissiveFactor=emissive,
            baseColorTexture=texture,
            alphaMode=mode,
            alphaCutoff=ALPHA_CUTOFF,
            doubleSided=double_sided,
        )
        # VRML97: an Appearance without a Material is not lit; its texture shows as it is
        setattr(material, UNLIT, appearance is not None and appearance["material"] is None)
        setattr(material, SPECULAR, specular)
        self._materials[key] = material
        return material

    def _texture(self, model: FaceModel, tex: Node):
        if tex.type.name == "PixelTexture":
            img = tex["image"]
            if img.width == 0 or img.height == 0:
                return None
            return pyrender_texture(img.to_rgba())
        if tex.type.name != "ImageTexture":
            return None
        path = model.texture_file(tex)
        if path is None:
            if list(tex["url"]):
                import warnings

                warnings.warn(model.texture_warning(tex, list(tex["url"])), stacklevel=2)
            return None
        # one texture per image file: a head's appearances often share one (decoding it and
        # building its mipmaps again for each would only cost time)
        shared = self._image_textures.get(path)
        if shared is None:
            shared = self._image_textures[path] = pyrender_texture(load_image(path))
        return shared

    def place(self, instances: list[ModelInstance], layout: str) -> tuple[np.ndarray, np.ndarray]:
        """Put the models side by side along x, centred, with a gap of 15 % of a head; with
        ``layout`` ``"room"`` also a floor and a back wall. Returns the bounds ``(3,)`` of them
        all, placed."""
        pr = load_pyrender()
        matrices, fixed, lo, hi = row_layout(
            [(i.lo, i.hi) for i in instances], [i.model.name for i in instances]
        )
        for inst, m, bounds in zip(instances, matrices, fixed, strict=True):
            inst.lo, inst.hi = bounds
            self.scene.set_pose(inst.root, m)
        if layout == "room":
            size = hi - lo
            floor_y = lo[1] - 0.6 * size[1]
            wall_z = lo[2] - 0.5 * size[2]
            room = pr.MetallicRoughnessMaterial(
                baseColorFactor=[0.55, 0.5, 0.45, 1.0], metallicFactor=0.0, roughnessFactor=1.0
            )
            wall = pr.MetallicRoughnessMaterial(
                baseColorFactor=[0.7, 0.72, 0.75, 1.0], metallicFactor=0.0, roughnessFactor=1.0
            )
            import trimesh

            span = 3 * max(size[0], size[1])
            floor = trimesh.creation.box([span, 0.02 * span, span])
            floor.apply_translation([0, floor_y, wall_z + span / 2])
            back = trimesh.creation.box([span, span, 0.02 * span])
            back.apply_translation([0, floor_y + span / 2, wall_z])
            self.scene.add(pr.Mesh.from_trimesh(floor, material=room, smooth=False))
            self.scene.add(pr.Mesh.from_trimesh(back, material=wall, smooth=False))
        return lo, hi

    def add_camera(self):
        """A camera node (its intrinsics and pose set by the renderer's view)."""
        pr = load_pyrender()
        return self.scene.add(pr.IntrinsicsCamera(1.0, 1.0, 0.0, 0.0), pose=np.eye(4))

    def add_lights(self, key: np.ndarray) -> None:
        """A key light from above left of the camera pose ``key`` ``(4, 4)``, and a fill light
        from its right."""
        pr = load_pyrender()
        self.scene.add(
            pr.DirectionalLight(color=np.ones(3), intensity=2.2), pose=key @ _rot_xy(-0.35, -0.3)
        )
        self.scene.add(
            pr.DirectionalLight(color=np.ones(3), intensity=0.8), pose=key @ _rot_xy(-0.1, 0.5)
        )


def constant_columns(mesh) -> np.ndarray | None:
    """The columns of ``mesh``'s vertex buffer that animation leaves alone (see
    :meth:`AnimatedMesh.vertex_data`), or None when its layout is not the one
    :func:`~vtts.render.pyrender_adapter.rewrite_vertex_buffer` writes (one primitive of
    positions, normals and optional texture coordinates and colors)."""
    (prim,) = mesh.primitives
    if prim.normals is None or prim.tangents is not None:
        return None
    cols = [c for c in (prim.texcoord_0, prim.texcoord_1, prim.color_0) if c is not None]
    n = prim.positions.shape[0]
    if not cols:
        return np.zeros((n, 0), dtype=np.float32)
    return np.ascontiguousarray(np.hstack(cols), dtype=np.float32)


def _rot_xy(ax: float, ay: float) -> np.ndarray:
    """A rotation about x by ``ax`` then about y by ``ay`` (radians), homogeneous."""
    from vtts.vrml import rotation_matrix

    m = np.eye(4)
    m[:3, :3] = rotation_matrix([0, 1, 0, ay]) @ rotation_matrix([1, 0, 0, ax])
    return m


#: The incidence matrices of the meshes :func:`~vtts.vrml.triangulate` keeps (read-only, given
#: again for the same geometry), while they are kept.
_incidences: weakref.WeakKeyDictionary[TriangleMesh, sp.csr_matrix] = weakref.WeakKeyDictionary()


def _incidence(tm: TriangleMesh) -> sp.csr_matrix:
    """``(n, m)``: which of ``tm``'s triangles touch each vertex (:func:`vtts.mesh.incidence`),
    made once for a kept (read-only) mesh."""
    if tm.faces.flags.writeable:
        return incidence(tm.faces, tm.positions.shape[0])
    inc = _incidences.get(tm)
    if inc is None:
        inc = _incidences[tm] = incidence(tm.faces, tm.positions.shape[0])
    return inc


#: How many decoded texture images :func:`load_image` keeps, the most recently used.
DECODED_IMAGES = 8
#: Files larger than this (bytes) are decoded every time, not kept.
DECODED_MAX_BYTES = 64 << 20
_decoded: OrderedDict[bytes, np.ndarray] = OrderedDict()
_decoded_lock = threading.Lock()


def has_alpha(rgba: np.ndarray | None) -> bool:
    """Whether an ``(h, w, 4) uint8`` texture image has a texel under :data:`ALPHA_CUTOFF`
    (drawn as a cutout; False for anything else)."""
    if rgba is None or rgba.ndim != 3 or rgba.shape[2] != 4 or rgba.dtype != np.uint8:
        return False
    return bool(rgba[..., 3].min() < round(ALPHA_CUTOFF * 255))


def load_image(path: Path) -> np.ndarray:
    """A texture image file as ``(h, w, 4) uint8`` RGBA, top row first (read-only).

    The last :data:`DECODED_IMAGES` images are kept by a digest of the file's bytes: a renderer
    made again for the same head decodes its atlas (a megapixel PNG) once, and a file written
    anew is decoded anew whatever its name, size and times."""
    from PIL import Image

    try:
        key = None
        if Path(path).stat().st_size <= DECODED_MAX_BYTES:
            key = hashlib.blake2b(Path(path).read_bytes(), digest_size=20).digest()
            with _decoded_lock:
                rgba = _decoded.get(key)
                if rgba is not None:
                    _decoded.move_to_end(key)
                    return rgba
        with Image.open(path) as im:
            check_image_size(*im.size, file=str(path), what="texture image")
            rgba = np.asarray(im.convert("RGBA"))
    except (OSError, Image.DecompressionBombError) as e:
        raise RenderError(f"cannot read texture image {path}: {e}") from None
    rgba.flags.writeable = False
    if key is not None:
        with _decoded_lock:
            _decoded[key] = rgba
            while len(_decoded) > DECODED_IMAGES:
                _decoded.popitem(last=False)
    return rgba
