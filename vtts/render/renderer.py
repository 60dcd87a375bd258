"""Rendering personalized models with pyrender, offscreen on Mesa's EGL.

The VRML scene graph of each model becomes pyrender nodes once (:mod:`vtts.render.scene`). Per
frame only what the tables animate changes — the vertex arrays (and normals) of the animated
IndexedFaceSets and the matrices of the animated Transforms — so the cost of a frame is the
deformation plus one draw (:mod:`vtts.render.deferred`).

Several models share one scene, side by side (or in a simple room), each driven by its own
parameter vector: one stream, several heads, each with its own tables (the "virtual conference"
of Ostermann & Haratsch, Figure 15).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Iterator, Sequence

import numpy as np

from vtts.errors import RenderError
from vtts.face import N_PARAMS, FaceModel
from vtts.limits import MAX_IMAGE_SIDE, MAX_RENDER_PIXELS
from vtts.render import lod
from vtts.render.camera import Camera, find_viewpoint, frame_bounds
from vtts.render.color import TRANSPARENT, parse_background
from vtts.render.lod import Collapses, present, progressive_mesh, simplified_faces
from vtts.render.pyrender_adapter import gpu_buffers, offscreen, on_gpu, rewrite_vertex_buffer
from vtts.render.scene import AnimatedMesh, ModelInstance, SceneBuilder
from vtts.vrml.transform import compose_transform

#: Frames whose geometry :meth:`FaceRenderer.frames` computes together: a second of video at
#: 25–30 frames/s is two or three batches, few enough that a batch of a head's vertex buffers
#: stays small (docs/rendering.md, "Speed").
BATCH_FRAMES = 12


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

    ``hidden``: DEF names of IndexedFaceSets that are posed but not drawn (their places show
    what lies behind them; :meth:`world_points` still gives their vertices).

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
        hidden: Sequence[str] = (),
    ) -> None:
        if isinstance(models, FaceModel):
            models = [models]
        if not models:
            raise RenderError("nothing to render: no model given")
        w, h = check_size(size)
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
        self._builder = SceneBuilder(
            [*bg, 0.0 if self.background_image is not None or self.transparent else 1.0]
        )
        self.scene = self._builder.scene
        # every IndexedFaceSet drawn, with the number of its first triangle (in model order)
        self.triangle_sets = self._builder.triangle_sets
        self._triangle_numbers = self._builder.triangle_numbers  # primitive -> its first
        self.instances = [self._builder.add_model(m, frozenset(hidden)) for m in self.models]
        self._lo, self._hi = self._builder.place(self.instances, layout)
        if viewpoint is not None:
            camera = self._viewpoint_camera(viewpoint)
        elif camera is None or not camera.placed:
            camera = frame_bounds(self._lo, self._hi, self.size, intrinsics=camera)
        self._cam_node = self._builder.add_camera()
        self.set_view(camera)
        self._builder.add_lights(np.array(self.camera.pose, copy=True))
        self._renderer = offscreen()
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
            size = check_size(size)
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
                    faces = simplified_faces(am.template.faces, progressive(inst, am), error)
                if am.faces is not None and np.array_equal(am.faces, faces):
                    continue
                am.faces = faces
                am.last = None  # its normals were computed for other vertices
                if len(faces) == len(am.template.faces):
                    am.drawn = None
                else:
                    used = present(faces, am.incidence.shape[0])
                    rows = am.incidence[used]
                    around = present(rows.indices, am.incidence.shape[1])
                    am.drawn = (used, am.template.faces[around], rows[:, around].tocsr())
                prim = am.node.mesh.primitives[0]
                if on_gpu(prim):  # drawn before: a new node uploads the new triangles
                    self._builder.replace_mesh(am, prim.positions, prim.normals)
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
            points = deformed_points(inst, column)
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
    def _mesh_frames(am: AnimatedMesh, points: list | None) -> list:
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
                data = am.vertex_data(positions, am.template.normals)
            else:
                normals = am.normals(positions)
                data = am.vertex_data(positions, normals)
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
    def _matrices(inst: ModelInstance, transforms: dict) -> list:
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
                am.applied = positions
                if normals is None:  # an unlit mesh (see AnimatedMesh.unlit)
                    if self._draws_unlit():
                        normals = am.template.normals
                    else:
                        normals = am.normals(positions)
                        vertex_data = am.vertex_data(positions, normals)
                primitive = am.node.mesh.primitives[0]
                uploaded = (primitive, gpu_buffers(primitive), vertex_data)
                if am.uploaded is not None and all(
                    a is b for a, b in zip(am.uploaded, uploaded, strict=True)
                ):
                    continue  # its GPU buffer holds this vertex buffer already
                if rewrite_vertex_buffer(primitive, vertex_data):
                    am.uploaded = uploaded
                else:
                    am.uploaded = None
                    self._builder.replace_mesh(am, positions, normals)
            for at, m in matrices:
                if m is at.applied:  # the same array: the same pose (pyrender's set_pose is slow)
                    continue
                for pn in at.nodes:
                    self.scene.set_pose(pn, m)
                at.applied = m

    def world_points(self, name: str, index: int = 0) -> np.ndarray:
        """The vertices ``(n, 3)`` of model ``index``'s IndexedFaceSet DEFed ``name`` in the
        renderer's world, as the frame last put into the scene (:meth:`apply`) poses them: its
        Transforms and root included, one row per vertex drawn (a Coordinate point used by
        several corners with different texture coordinates is several rows; the order is the
        same in every frame)."""
        if not 0 <= index < len(self.instances):
            raise RenderError(f"no model {index}: the renderer has {len(self.instances)}")
        inst = self.instances[index]
        for am in inst.meshes:
            if am.name == name:
                points = am.template.positions if am.applied is None else am.applied
                node = am.node
                break
        else:
            if name not in inst.still:
                raise RenderError(f"{inst.model.name} draws no IndexedFaceSet DEFed {name}")
            node, points = inst.still[name]
        world = np.asarray(self.scene.get_pose(node), dtype=np.float64)
        return np.asarray(points, np.float64) @ world[:3, :3].T + world[:3, 3]

    def _draws_unlit(self) -> bool:
        """Whether this scene's frames are drawn through the G-buffer, where unlit meshes need
        no normals (:meth:`~vtts.render.deferred.DeferredPass.draws_unlit`; the same for every
        frame: the scene's materials and lights do not change)."""
        if self._unlit_drawn is None:
            self._unlit_drawn = drawing_pass().draws_unlit(self.scene)
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

        from vtts.threads import result

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
                # in slices: a signal another thread took must still end the wait
                prepared = result(nxt)
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
            return drawing_pass().render(
                self.scene, w, h, rgba=self.transparent, triangles=self._triangle_numbers
            )
        if self.transparent:
            return downsample_coverage(drawing_pass().render(self.scene, w, h, rgba=True), ss)
        if self.background_image is None:
            return downsample(drawing_pass().render(self.scene, w, h), ss)
        rgba = downsample(drawing_pass().render(self.scene, w, h, rgba=True), ss)
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


def deformed_points(inst: ModelInstance, column: list) -> dict[str, list]:
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


#: The ``detail`` (pixels) ``vtts say`` and ``vtts play`` draw with: half a pixel, where the
#: frames of a talking head are hard to tell from every triangle's (docs/rendering.md, "Level of
#: detail", has the measurements).
DETAIL_PX = 0.5

#: The version of the progressive meshes kept in the cache (a new one makes them again).
_LOD_VERSION = 1
#: How far (model units, as a fraction of the mesh's size) the progressive mesh is carried: far
#: beyond any tolerance a frame asks for.
_LOD_REACH = 0.01


def detail_poses(model: FaceModel) -> list[np.ndarray]:
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


def lod_key(inst: ModelInstance, am: AnimatedMesh) -> tuple[str, np.ndarray, np.ndarray]:
    """What an animated mesh's progressive mesh is made from — its vertices in each of
    :func:`detail_poses` ``(P, V, 3)`` and its triangles ``(T, 3) int64`` — and the name of
    the file that keeps it (a digest of both, ``.npz``)."""
    import hashlib

    if inst.detail_points is None:  # every mesh of the model posed at once
        poses = detail_poses(inst.model)
        inst.detail_points = deformed_points(inst, [(p, None) for p in poses])
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


def progressive(inst: ModelInstance, am: AnimatedMesh) -> Collapses:
    """The progressive mesh (:func:`vtts.render.lod.progressive_mesh`) of an animated mesh over
    :func:`detail_poses`: shipped with the bundled heads (``models/lod/``, made by ``make
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


def _root_pose(matrix) -> np.ndarray:
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise RenderError(f"a root pose is a finite (4, 4) matrix, got shape {m.shape}")
    return m


def check_size(size: tuple[int, int]) -> tuple[int, int]:
    """``size`` (W, H) checked against what a renderer can draw: 16 to
    :data:`~vtts.limits.MAX_IMAGE_SIDE` pixels a side, :data:`~vtts.limits.MAX_RENDER_PIXELS` in
    all."""
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


def downsample(img: np.ndarray, k: int) -> np.ndarray:
    """Box-filter an ``(k·H, k·W, C) uint8`` image down to ``(H, W, C)``."""
    if k == 1:
        return img
    h, w, c = img.shape[0] // k, img.shape[1] // k, img.shape[2]
    blocks = img.reshape(h, k, w, k, c).astype(np.float32)
    return np.round(blocks.mean(axis=(1, 3))).astype(np.uint8)


def downsample_coverage(rgba: np.ndarray, k: int) -> np.ndarray:
    """Box-filter an ``(k·H, k·W, 4) uint8`` RGBA image rendered on a transparent black
    background down to ``(H, W, 4)``: alpha is the mean coverage, color the mean over the
    covered samples (straight alpha, as PNG keeps it), so fully covered pixels are exactly
    those of :func:`downsample` of an opaque render."""
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


_DRAWING_PASS = None


def drawing_pass():
    """The :class:`~vtts.render.deferred.DeferredPass` on the process's offscreen context: draws
    the scene as pyrender does, pixel for pixel, in a fraction of the time."""
    global _DRAWING_PASS
    if _DRAWING_PASS is None:
        from vtts.render.deferred import DeferredPass

        _DRAWING_PASS = DeferredPass(offscreen())
    return _DRAWING_PASS


def warm_up() -> None:
    """Create the process's offscreen OpenGL context and its drawing pass now rather than at
    the first frame (EGL's start and the pass's shaders); every renderer of the process shares
    them. A process that runs many commands (``vtts batch``'s workers) calls it once up front."""
    drawing_pass()
