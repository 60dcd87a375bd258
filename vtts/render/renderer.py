"""Rendering personalized models with pyrender, offscreen on Mesa's EGL.

The VRML scene graph of each model becomes pyrender nodes once: Transforms become nodes with
their local matrices, Shapes become meshes under them. Per frame only what the tables animate
changes — the vertex arrays (and normals) of the animated IndexedFaceSets and the matrices of the
animated Transforms — so the cost of a frame is the deformation plus one draw.

Several models share one scene, side by side (or in a simple room), each driven by its own
parameter vector: one stream, several heads, each with its own tables (the "virtual conference"
of Ostermann & Haratsch, Figure 15).
"""

from __future__ import annotations

import contextlib
import os
import sys
import types
import weakref
from collections.abc import Iterable, Iterator, MutableSet, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from vtts.deferred import defer_package
from vtts.errors import RenderError, VttsError
from vtts.face import N_PARAMS, FaceModel
from vtts.limits import MAX_IMAGE_SIDE, MAX_RENDER_PIXELS, check_image_size
from vtts.mesh import incidence, vertex_normals
from vtts.render import lod
from vtts.render.camera import Camera, find_viewpoint, frame_bounds, row_layout
from vtts.render.color import TRANSPARENT, parse_background
from vtts.render.lod import Collapses, progressive_mesh, simplified_faces
from vtts.vrml import Node, drawn_children, primitive_mesh, transform_matrix, triangulate
from vtts.vrml.geometry import TriangleMesh
from vtts.vrml.scene import GROUPING
from vtts.vrml.transform import compose_transform

_pyrender = None
#: Frames whose geometry :meth:`FaceRenderer.frames` computes together (a second of video at
#: 25–30 frames/s is two or three batches; a batch of the bundled heads is about 15 MB).
BATCH_FRAMES = 12

#: Multisampling of the main framebuffer (pyrender's own default is 4).
MSAA_SAMPLES = 0


#: The attribute that marks a pyrender material as unlit (VRML97: an Appearance without a
#: Material is not lit, its texture's colour shows as it is): the deferred pass's resolve writes
#: the texture's sample times the base color factor, as stored. pyrender's own shader has no
#: such mode: a scene that the G-buffer cannot hold draws these materials lit.
UNLIT = "vtts_unlit"

#: The fewest rasterizer threads Mesa's llvmpipe is given (``LP_NUM_THREADS``, unless the
#: environment sets it): its default, one per CPU, leaves the cores idle while the main thread
#: bins the next draw and the deformation thread and ffmpeg take their turn. Measured on the
#: 2-core machine, ``vtts say`` of 5 s took 2.42 s with 2 threads, 2.25 s with 4, 2.25 s with 6
#: or 8 and 2.28 s with 16.
LLVMPIPE_MIN_THREADS = 4


def llvmpipe_threads() -> int:
    """The rasterizer threads vtts asks llvmpipe for: one per CPU, at least
    :data:`LLVMPIPE_MIN_THREADS`."""
    return max(LLVMPIPE_MIN_THREADS, os.cpu_count() or 1)


def _pr():
    """pyrender, imported on first use (it opens the GL library)."""
    global _pyrender
    if _pyrender is None:
        # Mesa's software EGL: headless, deterministic. Must be set before OpenGL is imported.
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
        # llvmpipe's rasterizer threads (ignored by hardware drivers); a caller's choice stands
        os.environ.setdefault("LP_NUM_THREADS", str(llvmpipe_threads()))
        if os.environ["PYOPENGL_PLATFORM"] in ("egl", "osmesa"):
            # pyrender's interactive Viewer (a pyglet window) cannot run headless, and importing
            # it and pyglet is a fifth of pyrender's import time: leave it out.
            sys.modules.setdefault("pyrender.viewer", _headless_viewer_module())
        defer_package("trimesh", lone_submodules=True)  # pyrender: trimesh.transformations
        defer_package("networkx")
        defer_package("freetype")  # pyrender's text rendering, which vtts does not use
        try:
            import pyrender
            import pyrender.renderer as pr_renderer
            import pyrender.scene as pr_scene
        except Exception as e:  # pragma: no cover - depends on the machine
            raise RenderError(f"cannot load pyrender/OpenGL (EGL): {e}") from None
        # pyrender keeps its scene tree in a networkx graph, whose import (every algorithm
        # networkx has) took 0.14 s of a 5 s `vtts say`; a tree needs none of them
        pr_scene.nx = _SceneTrees
        # pyrender hard-codes 4x multisampling, which makes Mesa's software rasterizer 2.5 times
        # slower; vtts renders single-sampled and antialiases stills by supersampling instead.
        storage = pr_renderer.glRenderbufferStorageMultisample

        def single_sampled(target, samples, *args):
            return storage(target, MSAA_SAMPLES, *args)

        pr_renderer.glRenderbufferStorageMultisample = single_sampled
        _pyrender = pyrender
    return _pyrender


class _InsertionOrdered(MutableSet):
    """A set that iterates in the order its members were added (a dict's keys)."""

    def __init__(self, items: Iterable = ()) -> None:
        self._items = dict.fromkeys(items)

    def __contains__(self, item) -> bool:
        return item in self._items

    def __iter__(self) -> Iterator:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def add(self, item) -> None:
        self._items[item] = None

    def discard(self, item) -> None:
        self._items.pop(item, None)


#: The node sets of a pyrender ``Scene`` whose order reaches the pixels: the drawing order of
#: meshes the same distance from the camera (pyrender sorts them by their origin's distance,
#: and a head's meshes share one), and the order of the lights, whose contributions the shader
#: sums in that order.
ORDERED_SCENE_SETS = ("_mesh_nodes", "_point_light_nodes", "_spot_light_nodes",
                      "_directional_light_nodes")  # fmt: skip


def _order_scene(scene) -> None:
    """Make ``scene`` draw in the order its nodes were added. pyrender keeps them in sets,
    which iterate in the order of the nodes' memory addresses: two renderers of the same model
    drew a head's meshes in different orders, so pixels where two meshes meet at the same
    depth came out of one mesh or the other, and the analysis of a video went another way
    from there from one run to the next. pyrender's own ``render`` iterates the same sets, so
    its pixels stay ours."""
    for name in ORDERED_SCENE_SETS:
        setattr(scene, name, _InsertionOrdered(getattr(scene, name)))


class _SceneTree:
    """What pyrender's ``Scene`` asks of its ``networkx.DiGraph``: a tree whose edges go from each
    node to its parent (``"world"`` at the top)."""

    def __init__(self) -> None:
        self._parent: dict = {}  # node -> its parent, or None
        self._children: dict = {}  # node -> the nodes whose parent it is

    def add_node(self, node) -> None:
        if node not in self._parent:
            self._parent[node] = None
            self._children[node] = set()

    def add_edge(self, node, parent) -> None:
        self.add_node(node)
        self.add_node(parent)
        old = self._parent[node]
        if old is not None:
            self._children[old].discard(node)
        self._parent[node] = parent
        self._children[parent].add(node)

    def neighbors(self, node) -> Iterator:
        """The node's parent (a DiGraph's successors), if it has one."""
        parent = self._parent[node]
        return iter(() if parent is None else (parent,))

    def remove_node(self, node) -> None:
        """Remove ``node`` and its edges, as networkx does (its children lose their parent)."""
        parent = self._parent.pop(node)
        if parent is not None:
            self._children[parent].discard(node)
        for child in self._children.pop(node):
            self._parent[child] = None


class _SceneTrees:
    """Stands in for ``networkx`` in ``pyrender.scene`` (see :func:`_pr`)."""

    DiGraph = _SceneTree

    @staticmethod
    def shortest_path(graph, source, target) -> list:
        """The path from ``source`` up to ``target`` (in a tree, the only one); ``graph`` a
        :class:`_SceneTree` or a DiGraph made before pyrender's networkx was replaced."""
        path = [source]
        while path[-1] != target:
            up = next(iter(graph.neighbors(path[-1])), None)
            if up is None:
                raise ValueError(f"no path from {source!r} to {target!r} in the scene")
            path.append(up)
        return path


def _headless_viewer_module() -> types.ModuleType:
    """A stand-in for ``pyrender.viewer`` whose Viewer says why there is none."""
    module = types.ModuleType("pyrender.viewer")

    class Viewer:
        def __init__(self, *args, **kwargs) -> None:
            raise RenderError("pyrender's Viewer needs a display; vtts renders offscreen (EGL)")

    module.Viewer = Viewer
    return module


@dataclass
class _AnimatedMesh:
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
    # their incidence: the normals of vertices no triangle draws are never read (_normals)
    drawn: tuple[np.ndarray, np.ndarray, sp.csr_matrix] | None = None
    # its progressive mesh, once a view has asked for it (_progressive: read or made once)
    collapses: Collapses | None = None


@dataclass
class _AnimatedTransform:
    name: str
    vrml: Node
    nodes: list = field(default_factory=list)  # pyrender nodes (one per instance)
    last: tuple | None = None  # the last animated field values prepared, and their matrix
    applied: object = None  # the matrix its nodes were last given (set again only when new)


@dataclass
class _ModelInstance:
    model: FaceModel
    root: object
    meshes: list[_AnimatedMesh] = field(default_factory=list)
    transforms: dict[str, _AnimatedTransform] = field(default_factory=dict)
    lo: np.ndarray = field(default_factory=lambda: np.full(3, np.inf))
    hi: np.ndarray = field(default_factory=lambda: np.full(3, -np.inf))
    # the animated meshes' points in each pose of _detail_poses (see lod_key), once needed
    detail_points: dict | None = None


def _normals(am: _AnimatedMesh, positions: np.ndarray) -> np.ndarray:
    """An animated mesh's vertex normals for ``positions`` (``(n, 3)`` or ``(T, n, 3)``, as
    :func:`vertex_normals`) from the template's triangles. With fewer triangles drawn (see
    :attr:`_AnimatedMesh.drawn`) only the vertices they use get them, from the same triangles
    summed in the same order (the same bits); the others, never read, are zero."""
    if am.drawn is None:
        return vertex_normals(positions, am.template.faces, am.incidence)
    used, faces, incidence = am.drawn
    out = np.zeros(positions.shape)
    # the triangles' corners index the whole vertex list; the incidence's rows are the used ones
    out[..., used, :] = vertex_normals(positions, faces, incidence)
    return out


class FaceRenderer:
    """Renders one or more models, each posed by its own parameter vector.

    ``size`` is (width, height) in pixels; ``camera`` an explicit :class:`Camera` (default:
    framing all heads), or ``viewpoint`` the DEF name of a VRML ``Viewpoint`` in the first
    model's scene to look through (:meth:`Camera.from_viewpoint`, placed where the renderer puts
    that model: see :meth:`model_matrix`); ``background`` an RGB color (0–1), a color as
    :func:`~vtts.render.color.parse_background` reads it (``"white"``, ``"#00ff00"``), an
    ``(H, W, 3) uint8`` image, or ``"transparent"``: then frames are ``(H, W, 4) uint8`` RGBA
    whose alpha is the heads' coverage (255 where they cover a pixel, 0 around them; colors
    where they cover it are those of an opaque render); ``layout`` ``"row"`` (side by side) or
    ``"room"`` (side by side in front of a back wall on a floor).

    ``detail``: how far (pixels of the output image) the drawn surface of an animated mesh may
    be from the model's, so that fewer triangles are drawn where the image cannot show them
    (:mod:`vtts.render.lod`; :data:`DETAIL_PX` is what ``vtts say`` and ``vtts play`` use);
    None (the default): every triangle, as the model has them.

    ``triangle_sets`` lists every IndexedFaceSet drawn (of every model, in scene order) as
    ``(node, first, count)``: triangle ``i`` of ``vtts.vrml.triangulate(node)`` has number
    ``first + i`` in the triangle numbers :meth:`render` gives.
    """

    def __init__(
        self,
        models: list[FaceModel] | FaceModel,
        *,
        size: tuple[int, int] = (352, 288),
        camera: Camera | None = None,
        viewpoint: str | None = None,
        background: tuple[float, float, float] | np.ndarray | str = (0.32, 0.36, 0.42),
        layout: str = "row",
        supersample: int = 1,
        detail: float | None = None,
    ) -> None:
        pr = _pr()
        if isinstance(models, FaceModel):
            models = [models]
        if not models:
            raise RenderError("nothing to render: no model given")
        w, h = _check_size(size)
        if layout not in ("row", "room"):
            raise RenderError(f"layout must be 'row' or 'room', got {layout!r}")
        self.size = (w, h)
        self.supersample = _check_supersample(supersample)
        if detail is not None and not (isinstance(detail, int | float) and 0 <= detail <= 100):
            raise RenderError(f"detail is a distance in pixels from 0 to 100, got {detail!r}")
        #: the tolerance (pixels) of the simplified meshes, or None: every triangle
        self.detail = None if detail is None or detail == 0 else float(detail)
        self.models = list(models)
        if camera is not None and viewpoint is not None:
            raise RenderError("give a camera or a viewpoint to look through, not both")
        self.background_image = None
        bg = (0.0, 0.0, 0.0)
        if isinstance(background, str):
            background = parse_background(background)
        #: whether frames are RGBA with the heads' coverage as alpha (``background="transparent"``)
        self.transparent = isinstance(background, str) and background == TRANSPARENT
        if self.transparent:
            pass  # cleared to (0, 0, 0, 0): the alpha channel becomes the heads' coverage
        elif isinstance(background, np.ndarray) and background.ndim == 3:
            if background.shape[:2] != (h, w):
                raise RenderError(
                    f"background image is {background.shape[1]}x{background.shape[0]}, the "
                    f"output is {w}x{h}"
                )
            self.background_image = background[..., :3].astype(np.float32)
        else:
            bg = tuple(float(c) for c in background)
        self.scene = pr.Scene(
            bg_color=[*bg, 0.0 if self.background_image is not None or self.transparent else 1.0],
            ambient_light=[0.35, 0.35, 0.35],
        )
        _order_scene(self.scene)
        self._image_textures: dict[Path, object] = {}  # image file -> its pyrender texture
        # every IndexedFaceSet drawn, with the number of its first triangle (in model order)
        self.triangle_sets: list[tuple[Node, int, int]] = []
        self._triangle_numbers: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        self.instances = [self._add_model(m) for m in self.models]
        self._place(layout)
        if viewpoint is not None:
            camera = self._viewpoint_camera(viewpoint)
        elif camera is None or not camera.placed:
            camera = frame_bounds(self._lo, self._hi, self.size, intrinsics=camera)
        self._cam_node = self.scene.add(pr.IntrinsicsCamera(1.0, 1.0, 0.0, 0.0), pose=np.eye(4))
        self.set_view(camera)
        key = np.array(self.camera.pose, copy=True)
        # key light from above left of the camera, a fill light from the right
        self.scene.add(
            pr.DirectionalLight(color=np.ones(3), intensity=2.2), pose=key @ _rot_xy(-0.35, -0.3)
        )
        self.scene.add(
            pr.DirectionalLight(color=np.ones(3), intensity=0.8), pose=key @ _rot_xy(-0.1, 0.5)
        )
        self._renderer = _offscreen()
        self._unlit_drawn: bool | None = None  # see _draws_unlit

    def set_view(
        self,
        camera: Camera,
        size: tuple[int, int] | None = None,
        supersample: int | None = None,
    ) -> None:
        """Look through ``camera`` (a placed camera: intrinsics in pixels of the output image,
        and a pose) from now on, into images of ``size`` (W, H) rendered ``supersample`` times
        larger (None: as before).

        The scene stays as it is, lights included (they were put for the first camera), so one
        renderer serves several views of the same models: a camera with the first one's pose
        and a shifted principal point renders a window of the first image (the same pixels, up
        to one gray level at a few textured ones where the rasterizer rounds differently), and
        scaled intrinsics render a smaller copy. Switching views is free; switching between
        renderers is not (the GL context holds one scene's meshes and textures at a time)."""
        if not camera.placed:
            raise RenderError("a view needs a placed camera (one with a pose)")
        if size is not None:
            size = _check_size(size)
            if self.background_image is not None and size != self.size:
                raise RenderError("a renderer with a background image keeps its image size")
            self.size = size
        if supersample is not None:
            self.supersample = _check_supersample(supersample)
        # intrinsics are in pixels of the rendered (supersampled) image; pixel edges lie at
        # integer coordinates (pixel i spans [i, i + 1]), so every coordinate scales alike
        ss = self.supersample
        intrinsics = self._cam_node.camera
        intrinsics.fx, intrinsics.fy = camera.fx * ss, camera.fy * ss
        intrinsics.cx, intrinsics.cy = camera.cx * ss, camera.cy * ss
        intrinsics.znear, intrinsics.zfar = camera.znear, camera.zfar
        self.scene.set_pose(self._cam_node, camera.pose)
        self.camera = camera
        if self.detail is not None:
            self._simplify()

    def _simplify(self) -> None:
        """Choose each animated mesh's triangles for the current view: those of its
        progressive mesh (:func:`vtts.render.lod.simplified_faces`) within :attr:`detail`
        pixels, measured at the mesh's nearest point to the camera."""
        view = np.linalg.inv(self.camera.pose)
        f = min(self.camera.fx, self.camera.fy)
        for inst in self.instances:
            for am in inst.meshes:
                world = self.scene.get_pose(am.node)
                scale = float(np.linalg.svd(world[:3, :3], compute_uv=False).max())
                pts = am.template.positions @ (view[:3, :3] @ world[:3, :3]).T
                depth = -(pts[:, 2] + (view[:3, :3] @ world[:3, 3] + view[:3, 3])[2])
                near = float(depth.min(initial=np.inf))
                if not (near > 0 and scale > 0):
                    faces = am.template.faces  # behind the camera or degenerate: as it is
                else:
                    error = self.detail * near / (f * scale)  # model units
                    faces = simplified_faces(am.template.faces, _progressive(inst, am), error)
                if am.faces is not None and np.array_equal(am.faces, faces):
                    continue
                am.faces = faces
                am.last = None  # its normals were computed for other vertices
                if len(faces) == len(am.template.faces):
                    am.drawn = None
                else:
                    used = _present(faces, am.incidence.shape[0])
                    rows = am.incidence[used]
                    around = _present(rows.indices, am.incidence.shape[1])
                    am.drawn = (used, am.template.faces[around], rows[:, around].tocsr())
                prim = am.node.mesh.primitives[0]
                if prim._in_context():  # drawn before: a new node uploads the new triangles
                    self._replace_node(am, prim.positions, prim.normals)
                else:
                    prim.indices = faces.astype(np.uint32)

    def model_matrix(self, index: int = 0) -> np.ndarray:
        """The ``(4, 4)`` matrix that places model ``index`` (its file's coordinates) in the
        renderer's world: the layout moves each head beside the others, centred."""
        if not 0 <= index < len(self.instances):
            raise RenderError(f"no model {index}: the renderer has {len(self.instances)}")
        return np.array(self.scene.get_pose(self.instances[index].root), dtype=np.float64)

    def _viewpoint_camera(self, name: str) -> Camera:
        """The camera of the first model's Viewpoint ``name``, in the renderer's world, with a
        depth range around the heads (as automatic framing chooses it)."""
        node, matrix = find_viewpoint(self.models[0].scene, name)
        camera = Camera.from_viewpoint(node, self.size, self.model_matrix(0) @ matrix)
        centre = (self._lo + self._hi) / 2
        radius = float(np.linalg.norm(self._hi - self._lo)) / 2
        dist = float(np.linalg.norm(camera.pose[:3, 3] - centre))
        # automatic framing's range (dist/50 to 10·dist) when the heads lie beyond the near
        # plane; from within them, a near plane close to the eye
        camera.znear = dist / 50 if dist - radius > dist / 50 else (dist + radius) / 1000
        camera.zfar = max(10 * dist, 2 * (dist + radius))
        return camera

    # ---- building ----------------------------------------------------------------------------

    def _add_model(self, model: FaceModel) -> _ModelInstance:
        pr = _pr()
        root = pr.Node(matrix=np.eye(4))
        self.scene.add_node(root)
        inst = _ModelInstance(model, root)
        animated_meshes = set(model.tables.mesh_nodes())
        animated_transforms = set(model.tables.transform_nodes())
        self._materials: dict[tuple[int, bool], object] = {}

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
                        node.name, _AnimatedTransform(node.name, node)
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
        pr = _pr()
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
            mesh = self._mesh(tm, tm.positions, tm.normals, material, first)
            node = self.scene.add(mesh, parent_node=parent)
            pts = tm.positions
            if geom.name in animated:
                inc = incidence(tm.faces, tm.positions.shape[0])
                inst.meshes.append(
                    _AnimatedMesh(
                        geom.name,
                        tm,
                        parent,
                        node,
                        material,
                        inc,
                        _constant_columns(mesh),
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

    def _replace_node(self, am: _AnimatedMesh, positions, normals) -> None:
        """Put an animated mesh into the scene anew: a node with these positions and normals
        and the triangles it draws (pyrender uploads it at the next frame)."""
        self.scene.remove_node(am.node)
        am.node = self.scene.add(
            self._mesh(am.template, positions, normals, am.material, am.first_triangle, am.faces),
            parent_node=am.parent,
        )

    def _mesh(
        self, tm: TriangleMesh, positions, normals, material, first_triangle: int, faces=None
    ):
        pr = _pr()
        colors = None if tm.colors is None else np.c_[tm.colors, np.ones(len(tm.colors))]
        prim = pr.Primitive(
            positions=positions.astype(np.float32),
            normals=normals.astype(np.float32),
            texcoord_0=None if tm.texcoords is None else tm.texcoords.astype(np.float32),
            color_0=None if colors is None else colors.astype(np.float32),
            indices=(tm.faces if faces is None else faces).astype(np.uint32),
            material=material,
        )
        self._triangle_numbers[prim] = first_triangle
        return pr.Mesh([prim])

    def _material(self, model: FaceModel, appearance: Node | None, double_sided: bool):
        """The pyrender material of a VRML Appearance; ``double_sided`` for geometry that is not
        ``solid`` (VRML's default is solid: back faces are culled)."""
        pr = _pr()
        key = (id(appearance), double_sided)
        if key in self._materials:
            return self._materials[key]
        base = np.array([0.8, 0.8, 0.8, 1.0])
        emissive = np.zeros(3)
        roughness = 0.8
        texture = None
        if appearance is not None:
            appearance = appearance.expand()
            mat = appearance["material"]
            if mat is not None:
                mat = mat.expand()
                base[:3] = mat["diffuseColor"]
                base[3] = 1.0 - float(mat["transparency"])
                emissive = np.asarray(mat["emissiveColor"], dtype=np.float64)
                roughness = float(np.clip(1.0 - 0.8 * mat["shininess"], 0.05, 1.0))
            tex = appearance["texture"]
            if tex is not None:
                texture = self._texture(model, tex.expand())
                if texture is not None and mat is None:
                    base[:3] = 1.0
        material = pr.MetallicRoughnessMaterial(
            baseColorFactor=base,
            metallicFactor=0.0,
            roughnessFactor=roughness,
            emissiveFactor=emissive,
            baseColorTexture=texture,
            alphaMode="BLEND" if base[3] < 1.0 else "OPAQUE",
            doubleSided=double_sided,
        )
        # VRML97: an Appearance without a Material is not lit; its texture shows as it is
        setattr(material, UNLIT, appearance is not None and appearance["material"] is None)
        self._materials[key] = material
        return material

    def _texture(self, model: FaceModel, tex: Node):
        if tex.type.name == "PixelTexture":
            img = tex["image"]
            if img.width == 0 or img.height == 0:
                return None
            return _pyrender_texture(img.to_rgba())
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
            shared = self._image_textures[path] = _pyrender_texture(_load_image(path))
        return shared

    def _place(self, layout: str) -> None:
        """Put the models side by side along x, centred, with a gap of 15 % of a head."""
        pr = _pr()
        matrices, fixed, lo, hi = row_layout(
            [(i.lo, i.hi) for i in self.instances], [i.model.name for i in self.instances]
        )
        for inst, m, bounds in zip(self.instances, matrices, fixed, strict=True):
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
        self._lo, self._hi = lo, hi

    # ---- per frame -----------------------------------------------------------------------------

    def prepare(
        self,
        params: np.ndarray | list[np.ndarray],
        poses: list | None = None,
        roots: list | None = None,
    ) -> list:
        """Compute a frame's geometry without touching OpenGL (safe in a worker thread).

        ``params`` is one ``(N_PARAMS,)`` vector for all models or a list with one per model.
        ``poses``: each model's :class:`~vtts.face.deform.Pose` for its ``params``, when the
        caller has deformed the model already. ``roots``: each model's root pose ``(4, 4)``
        in the renderer's world for this frame (a head's translation, see
        :func:`vtts.animate.fapstream.head_roots`), None where it stays as it is. Returns what
        :meth:`apply` puts on the GPU."""
        return self.prepare_many([(params, poses, roots)])[0]

    def prepare_many(self, items: Sequence[tuple]) -> list[list]:
        """:meth:`prepare` for several frames at once: ``items`` holds one ``(params, poses,
        roots)`` per frame, as :meth:`prepare` takes them; returns one prepared frame each,
        the same numbers as :meth:`prepare` of each in turn. The meshes of all frames are
        deformed (:meth:`~vtts.face.deform.DeformationEngine.points_many`), given normals
        and laid out as vertex buffers together, which costs a fraction of frame by frame."""
        frames = [self._frame_args(*item) for item in items]
        prepared: list[list] = [[] for _ in frames]
        for i, inst in enumerate(self.instances):
            column = [(p[i], None if poses is None else poses[i]) for p, poses, _ in frames]
            points = self._points(inst, column)
            meshes: list[list] = [[] for _ in frames]
            for am in inst.meshes:
                for f, entry in enumerate(self._mesh_frames(am, points.get(am.name))):
                    if entry is not None:
                        meshes[f].append(entry)
            for f, (p, pose) in enumerate(column):
                transforms = (
                    inst.model.engine.transform_values(p) if pose is None else pose.transforms
                )
                prepared[f].append((meshes[f], self._matrices(inst, transforms), frames[f][2][i]))
        return prepared

    def _frame_args(self, params, poses, roots) -> tuple[list, list | None, list]:
        """One frame's arguments of :meth:`prepare`, checked: a ``(N_PARAMS,)`` float vector
        per model, the poses or None, a root pose or None per model."""
        if isinstance(params, np.ndarray) and params.ndim == 1:
            params = [params] * len(self.instances)
        if len(params) != len(self.instances):
            raise RenderError(f"{len(self.instances)} models but {len(params)} parameter vectors")
        if poses is not None and len(poses) != len(self.instances):
            raise RenderError(f"{len(self.instances)} models but {len(poses)} poses")
        if roots is None:
            roots = [None] * len(self.instances)
        if len(roots) != len(self.instances):
            raise RenderError(f"{len(self.instances)} models but {len(roots)} root poses")
        roots = [None if r is None else _root_pose(r) for r in roots]
        checked = []
        for p in params:
            p = np.asarray(p, dtype=np.float64)
            if p.shape != (N_PARAMS,):
                raise RenderError(f"a parameter vector has shape ({N_PARAMS},), got {p.shape}")
            checked.append(p)
        return checked, poses, roots

    @staticmethod
    def _points(inst: _ModelInstance, column: list) -> dict[str, list]:
        """Each animated mesh's Coordinate points ``(p, 3)`` in each frame of ``column``
        (``(params, pose or None)`` per frame): DEF name → one array (or None) per frame."""
        engine = inst.model.engine
        todo = [f for f, (_, pose) in enumerate(column) if pose is None]
        if not todo:
            deformed = {}
        elif len(todo) == 1:
            # one frame: the engine's own path, which gathers only the active columns
            deformed = {k: v[None] for k, v in engine.points(column[todo[0]][0]).items()}
        else:
            deformed = engine.points_many(np.array([column[f][0] for f in todo]))
        out: dict[str, list] = {}
        for am in inst.meshes:
            per_frame = [None] * len(column)
            for f, (_, pose) in enumerate(column):
                if pose is not None:
                    per_frame[f] = pose.points.get(am.name)
            if am.name in deformed:
                for k, f in enumerate(todo):
                    per_frame[f] = deformed[am.name][k]
            out[am.name] = per_frame
        return out

    @staticmethod
    def _mesh_frames(am: _AnimatedMesh, points: list | None) -> list:
        """``(am, positions, normals, vertex buffer)`` for each frame (None where the frame has
        no points for it), computed once for each run of frames with the same points and for
        all the changes together."""
        if points is None:
            return []
        # the frames whose points differ from the frame before (or from the last prepared)
        changed, last = [], am.last[0] if am.last is not None else None
        for f, pts in enumerate(points):
            if pts is None:
                continue
            if last is None or not np.array_equal(last, pts):
                changed.append(f)
            last = pts
        if changed:
            positions = np.stack([points[f] for f in changed])[:, am.template.coord_index]
            if am.unlit:  # computed in apply only if the scene is drawn lit after all
                normals = [None] * len(changed)
                data = _vertex_data(am, positions, am.template.normals)
            else:
                normals = _normals(am, positions)
                data = _vertex_data(am, positions, normals)
        out: list = [None] * len(points)
        k = -1
        for f, pts in enumerate(points):
            if pts is None:
                continue
            if k + 1 < len(changed) and changed[k + 1] == f:
                k += 1
                am.last = (pts, positions[k], normals[k], None if data is None else data[k])
            out[f] = (am, *am.last[1:])
        return out

    @staticmethod
    def _matrices(inst: _ModelInstance, transforms: dict) -> list:
        """``(animated Transform, its (4, 4) matrix)`` for the Transforms ``transforms`` (a
        :attr:`~vtts.face.deform.Pose.transforms`) animates."""
        matrices = []
        for name, at in inst.transforms.items():
            fields = transforms.get(name)
            if not fields:
                continue
            key = [(f, np.asarray(v).tobytes()) for f, v in sorted(fields.items())]
            if at.last is None or at.last[0] != key:
                v = at.vrml
                m = compose_transform(
                    fields.get("translation", v["translation"]),
                    fields.get("rotation", v["rotation"]),
                    fields.get("scale", v["scale"]),
                    v["scaleOrientation"],
                    v["center"],
                )
                at.last = (key, m)
            matrices.append((at, at.last[1]))
        return matrices

    def apply(self, prepared: list) -> None:
        """Put a :meth:`prepare` d frame into the scene (vertex buffers, Transform matrices,
        root poses)."""
        for inst, (meshes, matrices, root) in zip(self.instances, prepared, strict=True):
            if root is not None:
                self.scene.set_pose(inst.root, root)
            for am, positions, normals, vertex_data in meshes:
                if normals is None:  # an unlit mesh (see _AnimatedMesh.unlit)
                    if self._draws_unlit():
                        normals = am.template.normals
                    else:
                        normals = _normals(am, positions)
                        vertex_data = _vertex_data(am, positions, normals)
                if not _update_in_place(am, vertex_data):
                    self._replace_node(am, positions, normals)
            for at, m in matrices:
                if m is at.applied:  # the same array: the same pose (pyrender's set_pose is slow)
                    continue
                for pn in at.nodes:
                    self.scene.set_pose(pn, m)
                at.applied = m

    def _draws_unlit(self) -> bool:
        """Whether this scene's frames are drawn through the G-buffer, where unlit meshes need
        no normals (:meth:`~vtts.render.deferred.DeferredPass.draws_unlit`; the same for every
        frame: the scene's materials and lights do not change)."""
        if self._unlit_drawn is None:
            self._unlit_drawn = _drawing_pass().draws_unlit(self.scene)
        return self._unlit_drawn

    def pose(
        self,
        params: np.ndarray | list[np.ndarray],
        poses: list | None = None,
        roots: list | None = None,
    ) -> None:
        """Pose every model (see :meth:`prepare`)."""
        self.apply(self.prepare(params, poses, roots))

    def frames(
        self, params: Iterable, roots: Iterable | None = None, *, batch: int = BATCH_FRAMES
    ) -> Iterator[np.ndarray]:
        """Render a sequence: one frame ``(H, W, 3) uint8`` (``(H, W, 4)`` when transparent) per
        item of ``params`` (each item as :meth:`prepare` takes it; with ``roots``, the item of
        ``roots`` alongside, as :meth:`prepare` takes its ``roots``). The geometry of the next
        ``batch`` frames (:data:`BATCH_FRAMES`) is computed together (:meth:`prepare_many`) in a
        worker thread while the current ones rasterize, which hides most of the deformation's
        cost (the first frame's alone, so that it waits for no more than its own). A live
        stream passes ``batch=1``: each frame is rendered as soon as its item arrives (the
        pixels are the same for any batch)."""
        from concurrent.futures import ThreadPoolExecutor
        from itertools import islice

        if roots is None:
            it = ((p, None, None) for p in params)
        else:
            it = ((p, None, r) for p, r in zip(params, roots, strict=True))

        if not (isinstance(batch, int) and batch >= 1):
            raise RenderError(f"a batch is a whole number of frames ≥ 1, got {batch!r}")

        def next_batch(size: int):
            items = list(islice(it, size))
            return self.prepare_many(items) if items else None

        pool = ThreadPoolExecutor(max_workers=1)
        done = False
        try:
            # the first frame alone, so that it does not wait for a whole batch's geometry
            nxt = pool.submit(next_batch, 1)
            while True:
                prepared = nxt.result()
                if prepared is None:
                    done = True
                    return
                nxt = pool.submit(next_batch, batch)
                for frame in prepared:
                    self.apply(frame)
                    yield self.render()
        finally:
            # stopped early (Ctrl-C, the reader of the frames gone): the worker may be blocked
            # on ``params`` (a pipe that has nothing yet), so it is not waited for
            pool.shutdown(wait=done, cancel_futures=True)

    def render(
        self,
        params: np.ndarray | list[np.ndarray] | None = None,
        poses: list | None = None,
        *,
        roots: list | None = None,
        triangles: bool = False,
    ):
        """The frame ``(H, W, 3) uint8`` for the given parameters (None: as last posed; ``poses``
        and ``roots`` as :meth:`prepare` takes them); ``(H, W, 4)`` RGBA for a transparent
        background.

        With ``triangles``, returns ``(frame, numbers)``: also the number of the triangle each
        pixel shows ``(H, W) int64`` from the same rasterization (−1: none, or a VRML primitive
        such as a Sphere); see :attr:`triangle_sets`. Needs ``supersample`` 1 and no
        background image."""
        if params is not None:
            self.pose(params, poses, roots)
        if self._renderer is None:
            raise RenderError("this renderer is closed")
        ss = self.supersample
        w, h = self.size[0] * ss, self.size[1] * ss
        if triangles:
            if ss != 1 or self.background_image is not None or self.detail is not None:
                raise RenderError(
                    "triangle numbers need a renderer without supersampling, background image "
                    "or detail"
                )
            return _drawing_pass().render(
                self.scene, w, h, rgba=self.transparent, triangles=self._triangle_numbers
            )
        if self.transparent:
            return _downsample_coverage(_drawing_pass().render(self.scene, w, h, rgba=True), ss)
        if self.background_image is None:
            return _downsample(_drawing_pass().render(self.scene, w, h), ss)
        rgba = _downsample(_drawing_pass().render(self.scene, w, h, rgba=True), ss)
        a = rgba[..., 3:4].astype(np.float32) / 255.0
        out = rgba[..., :3].astype(np.float32) * a + self.background_image * (1 - a)
        return np.round(out).astype(np.uint8)

    def close(self) -> None:
        """Release the scene (the shared GL context stays for the next renderer)."""
        self._renderer = None

    def __enter__(self) -> FaceRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


#: The ``detail`` (pixels) ``vtts say`` and ``vtts play`` draw with: half a pixel, where the
#: frames of a talking cybatt at 352×288 differ from every triangle's by 47 dB at the worst
#: (docs/rendering.md, "Level of detail").
DETAIL_PX = 0.5

#: The version of the progressive meshes kept in the cache (a new one makes them again).
_LOD_VERSION = 1
#: How far (model units, as a fraction of the mesh's size) the progressive mesh is carried: far
#: beyond any tolerance a frame asks for.
_LOD_REACH = 0.01


def _detail_poses(model: FaceModel) -> list[np.ndarray]:
    """The parameter vectors a simplified mesh is checked in: rest, each viseme and each
    expression at full strength, the eyelids closed and the jaw open — the shapes a talking
    head takes, and their extremes."""
    from vtts.face.temporal import EXPRESSION_NAMES

    poses = [model.params()]
    poses += [model.params(visemes={v: 1.0}) for v in range(1, 15)]
    poses += [model.params(expressions={e: 1.0}) for e in EXPRESSION_NAMES]
    poses.append(model.params({19: 1024, 20: 1024, 21: 1024, 22: 1024}))
    poses.append(model.params({3: 1024}))
    return poses


def lod_key(inst: _ModelInstance, am: _AnimatedMesh) -> tuple[str, np.ndarray, np.ndarray]:
    """What an animated mesh's progressive mesh is made from — its vertices in each of
    :func:`_detail_poses` ``(P, V, 3)`` and its triangles ``(T, 3) int64`` — and the name of
    the file that keeps it (a digest of both, ``.npz``)."""
    import hashlib

    if inst.detail_points is None:  # every mesh of the model posed at once
        poses = _detail_poses(inst.model)
        inst.detail_points = FaceRenderer._points(inst, [(p, None) for p in poses])
    positions = np.stack(inst.detail_points[am.name])[:, am.template.coord_index]
    faces = np.ascontiguousarray(am.template.faces, dtype=np.int64)
    digest = hashlib.sha256()
    for part in (str(_LOD_VERSION).encode(), faces.tobytes(), positions.tobytes()):
        digest.update(part)
    return f"{digest.hexdigest()[:32]}.npz", positions, faces


def make_progressive(positions: np.ndarray, faces: np.ndarray) -> Collapses:
    """The progressive mesh of :func:`lod_key`'s ``positions`` and ``faces``, carried to
    :data:`_LOD_REACH` of the mesh's size."""
    size = float(np.ptp(positions[0], axis=0).max(initial=0.0)) or 1.0
    return progressive_mesh(positions, faces, max_error=_LOD_REACH * size)


def _progressive(inst: _ModelInstance, am: _AnimatedMesh) -> Collapses:
    """The progressive mesh (:func:`vtts.render.lod.progressive_mesh`) of an animated mesh over
    :func:`_detail_poses`: shipped with the bundled heads (``models/lod/``, made by ``make
    models``), kept in the user's cache (``lod/`` in :func:`vtts.usercache.cache_dir`), or
    made (a few seconds for a head) and kept there; kept on ``am`` for the views after."""
    from vtts.resources import models_dir
    from vtts.usercache import private_folder, trusted_file

    if am.collapses is not None:
        return am.collapses
    name, positions, faces = lod_key(inst, am)
    n = positions.shape[1]
    shipped = models_dir() / "lod" / name
    collapses = lod.load(shipped, n) if shipped.is_file() else None
    folder = private_folder("lod")
    path = None if folder is None else folder / name
    if collapses is None and path is not None and path.is_file() and trusted_file(path):
        collapses = lod.load(path, n)
    if collapses is None:
        collapses = make_progressive(positions, faces)
        if path is not None:
            with contextlib.suppress(OSError):  # a cache that cannot be written is no cache
                lod.save(path, collapses)
    am.collapses = collapses
    return collapses


def _present(ids: np.ndarray, n: int) -> np.ndarray:
    """The distinct values of ``ids`` (whole numbers in ``0..n-1``), ascending: ``np.unique``'s
    answer without its look for masked arrays, which imports ``numpy.ma`` (12–35 ms of a
    ``vtts say``'s start-up; :mod:`vtts.deferred`)."""
    return np.flatnonzero(np.bincount(ids.ravel(), minlength=n))


def _root_pose(matrix) -> np.ndarray:
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise RenderError(f"a root pose is a finite (4, 4) matrix, got shape {m.shape}")
    return m


def _check_size(size: tuple[int, int]) -> tuple[int, int]:
    w, h = int(size[0]), int(size[1])
    if not (16 <= w <= MAX_IMAGE_SIDE and 16 <= h <= MAX_IMAGE_SIDE):
        raise RenderError(f"image size must be within 16–{MAX_IMAGE_SIDE} pixels, got {w}x{h}")
    if w * h > MAX_RENDER_PIXELS:
        raise RenderError(
            f"image size {w}x{h} has {w * h} pixels, more than the limit of {MAX_RENDER_PIXELS} "
            "(3840x2160; a rendered pixel takes about 400 bytes of buffers)"
        )
    return w, h


def _check_supersample(supersample: int) -> int:
    if supersample not in (1, 2, 3, 4):
        raise RenderError(f"supersample must be 1 to 4, got {supersample}")
    return supersample


def _constant_columns(mesh) -> np.ndarray | None:
    """The columns of ``mesh``'s vertex buffer that animation leaves alone (see
    :func:`_vertex_data`), or None when its layout is not the one :func:`_update_in_place`
    writes (one primitive of positions, normals and optional texture coordinates and colors)."""
    (prim,) = mesh.primitives
    if prim.normals is None or prim.tangents is not None:
        return None
    cols = [c for c in (prim.texcoord_0, prim.texcoord_1, prim.color_0) if c is not None]
    n = prim.positions.shape[0]
    if not cols:
        return np.zeros((n, 0), dtype=np.float32)
    return np.ascontiguousarray(np.hstack(cols), dtype=np.float32)


def _vertex_data(am: _AnimatedMesh, positions: np.ndarray, normals: np.ndarray):
    """The interleaved vertex buffer pyrender would upload for these positions and normals,
    ``(n, 6 + k) float32`` (``(T, n, 6 + k)`` for ``(T, n, 3)`` of each), or None when it
    cannot be updated in place."""
    const = am.constant_columns
    n = positions.shape[-2]
    if const is None or const.shape[0] != n:
        return None
    data = np.empty((*positions.shape[:-1], 6 + const.shape[1]), dtype=np.float32)
    data[..., :3] = positions
    data[..., 3:6] = normals
    data[..., 6:] = const
    return data


def _update_in_place(am: _AnimatedMesh, vertex_data: np.ndarray | None) -> bool:
    """Overwrite the vertex buffer of an animated mesh that is already on the GPU.

    pyrender uploads a primitive once (one interleaved buffer: positions, normals, texture
    coordinates, colors) and offers no public way to change it; replacing the node re-creates
    every GL object each frame. When the primitive is bound, its buffer is rewritten with
    ``glBufferSubData`` instead; otherwise (first frame, or another pyrender layout) the caller
    replaces the node. Returns whether the buffer was updated."""
    prim = am.node.mesh.primitives[0]
    buffers = getattr(prim, "_buffers", None)
    if getattr(prim, "_vaid", None) is None or not buffers or vertex_data is None:
        return False
    from OpenGL.GL import GL_ARRAY_BUFFER, glBindBuffer, glBufferSubData

    glBindBuffer(GL_ARRAY_BUFFER, buffers[0])
    glBufferSubData(GL_ARRAY_BUFFER, 0, vertex_data.nbytes, vertex_data)
    glBindBuffer(GL_ARRAY_BUFFER, 0)
    return True


def _downsample(img: np.ndarray, k: int) -> np.ndarray:
    """Box-filter an ``(k·H, k·W, C) uint8`` image down to ``(H, W, C)``."""
    if k == 1:
        return img
    h, w, c = img.shape[0] // k, img.shape[1] // k, img.shape[2]
    blocks = img.reshape(h, k, w, k, c).astype(np.float32)
    return np.round(blocks.mean(axis=(1, 3))).astype(np.uint8)


def _downsample_coverage(rgba: np.ndarray, k: int) -> np.ndarray:
    """Box-filter an ``(k·H, k·W, 4) uint8`` RGBA image rendered on a transparent black
    background down to ``(H, W, 4)``: alpha is the mean coverage, color the mean over the
    covered samples (straight alpha, as PNG keeps it), so fully covered pixels are exactly
    those of :func:`_downsample` of an opaque render."""
    if k == 1:
        return rgba
    h, w = rgba.shape[0] // k, rgba.shape[1] // k
    blocks = rgba.reshape(h, k, w, k, 4).astype(np.float32)
    mean = blocks.mean(axis=(1, 3))
    alpha = mean[..., 3:4]
    # the background is (0, 0, 0, 0): a block's color sum is its covered samples' sum
    color = np.divide(mean[..., :3] * 255, alpha, out=np.zeros_like(mean[..., :3]), where=alpha > 0)
    full = alpha >= 255
    color = np.where(full, mean[..., :3], color)
    out = np.concatenate([color, alpha], axis=2)
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


_OFFSCREEN = None


def _offscreen():
    """The process's one offscreen OpenGL context. pyrender's EGL platform terminates the EGL
    display when a context is deleted, which breaks every other context of the process, so vtts
    keeps one and changes its viewport per scene."""
    global _OFFSCREEN
    if _OFFSCREEN is None:
        pr = _pr()
        try:
            _OFFSCREEN = pr.OffscreenRenderer(64, 64)
        except Exception as e:  # pragma: no cover - depends on the machine
            raise RenderError(f"cannot create an offscreen OpenGL context (EGL): {e}") from None
    return _OFFSCREEN


_DRAWING_PASS = None


def _drawing_pass():
    """The :class:`~vtts.render.deferred.DeferredPass` on the process's offscreen context: draws
    the scene as pyrender does, pixel for pixel, in a fraction of the time."""
    global _DRAWING_PASS
    if _DRAWING_PASS is None:
        from vtts.render.deferred import DeferredPass

        _DRAWING_PASS = DeferredPass(_offscreen())
    return _DRAWING_PASS


def warm_up() -> None:
    """Create the process's offscreen OpenGL context and its drawing pass now rather than at
    the first frame (EGL's start and the pass's shaders); every renderer of the process shares
    them. A process that runs many commands (``vtts batch``'s workers) calls it once up front."""
    _drawing_pass()


def _rot_xy(ax: float, ay: float) -> np.ndarray:
    """A rotation about x by ``ax`` then about y by ``ay`` (radians), homogeneous."""
    from vtts.vrml import rotation_matrix

    m = np.eye(4)
    m[:3, :3] = rotation_matrix([0, 1, 0, ay]) @ rotation_matrix([1, 0, 0, ax])
    return m


def _pyrender_texture(rgba: np.ndarray):
    """A pyrender texture of an ``(h, w, 4) uint8`` image, top row first, whose mipmaps vtts
    makes (:mod:`vtts.render.mipmaps`)."""
    # pyrender (like glTF) puts t = 0 at the bottom of such images, which is VRML's convention
    # too (a test checks the orientation)
    return _texture_class()(source=np.ascontiguousarray(rgba), source_channels="RGBA")


_TEXTURE_CLASS = None


def _texture_class():
    """pyrender's ``Texture`` with its mipmaps computed by NumPy (:func:`mip_levels`) instead
    of ``glGenerateMipmap``; otherwise set up on the GPU as pyrender sets it up."""
    global _TEXTURE_CLASS
    if _TEXTURE_CLASS is not None:
        return _TEXTURE_CLASS
    from OpenGL import GL

    from vtts.render.mipmaps import mip_levels, power_of_two

    class MipmappedTexture(_pr().Texture):
        def _add_to_context(self) -> None:
            source = self.source
            if (
                source is None
                or source.dtype != np.uint8
                or source.ndim != 3
                or source.shape[2] != 4
                or not power_of_two(source.shape[:2])
                or self.sampler.minFilter is not None
            ):
                super()._add_to_context()
                return
            if self._texid is not None:
                raise ValueError("Texture already loaded into OpenGL context")
            self._texid = GL.glGenTextures(1)
            GL.glBindTexture(self.tex_type, self._texid)
            GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
            for k, level in enumerate(mip_levels(np.flip(source, axis=0))):
                h, w = level.shape[:2]
                GL.glTexImage2D(
                    self.tex_type, k, GL.GL_RGBA, w, h, 0, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE,
                    np.ascontiguousarray(level),
                )  # fmt: skip
            GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 4)
            mag = self.sampler.magFilter if self.sampler.magFilter is not None else GL.GL_LINEAR
            GL.glTexParameteri(self.tex_type, GL.GL_TEXTURE_MAG_FILTER, mag)
            GL.glTexParameteri(self.tex_type, GL.GL_TEXTURE_MIN_FILTER, GL.GL_LINEAR_MIPMAP_LINEAR)
            GL.glTexParameteri(self.tex_type, GL.GL_TEXTURE_WRAP_S, self.sampler.wrapS)
            GL.glTexParameteri(self.tex_type, GL.GL_TEXTURE_WRAP_T, self.sampler.wrapT)
            border = 255 * np.ones(4).astype(np.uint8)
            GL.glTexParameterfv(self.tex_type, GL.GL_TEXTURE_BORDER_COLOR, border)
            GL.glBindTexture(self.tex_type, 0)

    _TEXTURE_CLASS = MipmappedTexture
    return _TEXTURE_CLASS


def _load_image(path: Path) -> np.ndarray:
    from PIL import Image

    try:
        with Image.open(path) as im:
            check_image_size(*im.size, file=str(path), what="texture image")
            return np.asarray(im.convert("RGBA"))
    except (OSError, Image.DecompressionBombError) as e:
        raise RenderError(f"cannot read texture image {path}: {e}") from None
