"""The heads as :class:`~vtts.render.FaceRenderer` sees them, without OpenGL: the VRML scene graphs
walked as the renderer walks them, the heads placed side by side as it places them, and the camera
it looks through.

The glTF export builds its nodes from this, so that a viewer showing the exported file through its
camera sees what ``vtts render`` draws. ``tests/export`` checks placement and camera against a real
:class:`~vtts.render.FaceRenderer`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vtts.errors import ExportError, VttsError
from vtts.face import FaceModel
from vtts.limits import MAX_IMAGE_SIDE
from vtts.render.camera import Camera, find_viewpoint, frame_bounds, row_layout
from vtts.vrml import (
    PRIMITIVES,
    Node,
    TriangleMesh,
    drawn_children,
    primitive_mesh,
    transform_matrix,
    triangulate,
)
from vtts.vrml.scene import GROUPING

#: The deepest scene graph walked (as the renderer: deeper graphs are refused).
MAX_DEPTH = 128


@dataclass(eq=False)
class ShapeItem:
    """One drawn Shape.

    geometry      the (expanded) geometry node: an IndexedFaceSet or a VRML primitive
    appearance    its Appearance node, or None
    double_sided  the geometry is not ``solid`` (back faces drawn)
    mesh          the IndexedFaceSet's triangles (None for a primitive)
    primitive     the primitive as a ``trimesh.Trimesh`` (None for an IndexedFaceSet)
    """

    geometry: Node
    appearance: Node | None
    double_sided: bool
    mesh: TriangleMesh | None = None
    primitive: object | None = None


@dataclass(eq=False)
class SceneNode:
    """A VRML Transform instance (or a head's root, ``transform`` None) with what lies below it.

    ``local`` is its ``(4, 4) float64`` local-to-parent matrix; ``children`` the Transforms below
    it (grouping nodes other than Transform flattened away, as the renderer does), ``shapes`` the
    Shapes directly below it.
    """

    name: str | None
    transform: Node | None
    local: np.ndarray
    children: list[SceneNode] = field(default_factory=list)
    shapes: list[ShapeItem] = field(default_factory=list)


@dataclass(eq=False)
class HeadScene:
    """One model's drawn scene graph and its bounds ``lo``, ``hi`` ``(3,) float64`` (the model's
    file coordinates)."""

    model: FaceModel
    root: SceneNode
    lo: np.ndarray
    hi: np.ndarray


@dataclass(eq=False)
class Placement:
    """The heads placed as the renderer places them.

    heads     one :class:`HeadScene` per model
    matrices  ``(4, 4) float64`` per head: its file coordinates → the shared world
              (:meth:`FaceRenderer.model_matrix <vtts.render.FaceRenderer.model_matrix>`)
    camera    the placed :class:`~vtts.render.Camera` the renderer looks through
    lo, hi    ``(3,) float64`` bounds of all heads in the world
    room      ``(name, trimesh.Trimesh, RGBA)`` of the floor and back wall (``layout="room"``)
    """

    heads: list[HeadScene]
    matrices: list[np.ndarray]
    camera: Camera
    size: tuple[int, int]
    lo: np.ndarray
    hi: np.ndarray
    room: list[tuple[str, object, tuple[float, float, float, float]]] = field(default_factory=list)


def walk_head(model: FaceModel) -> HeadScene:
    """The scene graph of ``model`` as the renderer draws it: Transforms with a non-finite or
    singular matrix hide what is below them, Switch follows ``whichChoice``, LOD its first level,
    Shapes without geometry (or with geometry other than IndexedFaceSet and the primitives) and
    IndexedFaceSets without triangles are left out."""
    root = SceneNode(model.name, None, np.eye(4))
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)

    def walk(node: Node, parent: SceneNode, world: np.ndarray, depth: int) -> None:
        nonlocal lo, hi
        node = node.expand()
        t = node.type.name
        if depth > MAX_DEPTH:
            raise ExportError(f"{model.name}: scene graph nests deeper than {MAX_DEPTH} levels")
        if t == "Transform":
            local = transform_matrix(node)
            if not np.isfinite(local).all() or abs(np.linalg.det(local[:3, :3])) < 1e-30:
                return
            sn = SceneNode(node.name or None, node, local)
            parent.children.append(sn)
            for c in drawn_children(node):
                walk(c, sn, world @ local, depth + 1)
        elif t in GROUPING:
            for c in drawn_children(node):
                walk(c, parent, world, depth + 1)
        elif t == "Shape":
            item = _shape(model, node)
            if item is None:
                return
            parent.shapes.append(item)
            pts = item.mesh.positions if item.mesh is not None else item.primitive.vertices
            world_pts = np.asarray(pts) @ world[:3, :3].T + world[:3, 3]
            lo = np.minimum(lo, world_pts.min(axis=0))
            hi = np.maximum(hi, world_pts.max(axis=0))

    for r in model.scene.roots:
        walk(r, root, np.eye(4), 0)
    return HeadScene(model, root, lo, hi)


def _shape(model: FaceModel, shape: Node) -> ShapeItem | None:
    geom = shape["geometry"]
    if geom is None:
        return None
    geom = geom.expand()
    appearance = shape["appearance"]
    double_sided = not bool(geom.get("solid", True))
    if geom.type.name == "IndexedFaceSet":
        try:
            tm = triangulate(geom)
        except VttsError as e:
            e.file = e.file or (str(model.path) if model.path else None)
            raise
        if tm.faces.size == 0:
            return None
        return ShapeItem(geom, appearance, double_sided, mesh=tm)
    if geom.type.name not in PRIMITIVES:
        return None
    tri = primitive_mesh(geom)
    if tri is None:
        return None
    return ShapeItem(geom, appearance, double_sided, primitive=tri)


def place(
    models: list[FaceModel],
    *,
    size: tuple[int, int] = (352, 288),
    camera: Camera | None = None,
    viewpoint: str | None = None,
    layout: str = "row",
) -> Placement:
    """Walk and place ``models`` as ``FaceRenderer(models, size=size, camera=camera,
    viewpoint=viewpoint, layout=layout)`` does: side by side along x, centred, 15 % of the widest
    head apart; the camera framing them all (or ``camera`` when placed, or the first model's
    Viewpoint ``viewpoint``)."""
    if isinstance(models, FaceModel):
        models = [models]
    if not models:
        raise ExportError("nothing to export: no model given")
    if layout not in ("row", "room"):
        raise ExportError(f"layout must be 'row' or 'room', got {layout!r}")
    if camera is not None and viewpoint is not None:
        raise ExportError("give a camera or a viewpoint to look through, not both")
    w, h = _check_size(size)
    heads = [walk_head(m) for m in models]
    matrices, fixed, lo, hi = row_layout(
        [(hd.lo, hd.hi) for hd in heads], [hd.model.name for hd in heads], ExportError
    )
    for head, bounds in zip(heads, fixed, strict=True):
        head.lo, head.hi = bounds
    if viewpoint is not None:
        camera = _viewpoint_camera(heads[0].model, viewpoint, (w, h), matrices[0], lo, hi)
    elif camera is None or not camera.placed:
        camera = frame_bounds(lo, hi, (w, h), intrinsics=camera)
    room = _room(lo, hi) if layout == "room" else []
    return Placement(heads, matrices, camera, (w, h), lo, hi, room)


def _check_size(size: tuple[int, int]) -> tuple[int, int]:
    try:
        w, h = int(size[0]), int(size[1])
    except (TypeError, ValueError, IndexError):
        raise ExportError(f"size is (width, height) in pixels, got {size!r}") from None
    if not (16 <= w <= MAX_IMAGE_SIDE and 16 <= h <= MAX_IMAGE_SIDE):
        raise ExportError(f"image size must be within 16–{MAX_IMAGE_SIDE} pixels, got {w}x{h}")
    return w, h


def _viewpoint_camera(
    model: FaceModel,
    name: str,
    size: tuple[int, int],
    matrix: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
) -> Camera:
    """The first model's Viewpoint ``name`` in the world, with the renderer's depth range."""
    node, vp_matrix = find_viewpoint(model.scene, name)
    camera = Camera.from_viewpoint(node, size, matrix @ vp_matrix)
    centre = (lo + hi) / 2
    radius = float(np.linalg.norm(hi - lo)) / 2
    dist = float(np.linalg.norm(camera.pose[:3, 3] - centre))
    camera.znear = dist / 50 if dist - radius > dist / 50 else (dist + radius) / 1000
    camera.zfar = max(10 * dist, 2 * (dist + radius))
    return camera


def _room(lo: np.ndarray, hi: np.ndarray) -> list[tuple[str, object, tuple]]:
    """The floor and back wall the renderer's ``"room"`` layout adds (world coordinates)."""
    import trimesh

    size = hi - lo
    floor_y = lo[1] - 0.6 * size[1]
    wall_z = lo[2] - 0.5 * size[2]
    span = 3 * max(size[0], size[1])
    floor = trimesh.creation.box([span, 0.02 * span, span])
    floor.apply_translation([0, floor_y, wall_z + span / 2])
    back = trimesh.creation.box([span, span, 0.02 * span])
    back.apply_translation([0, floor_y + span / 2, wall_z])
    return [("floor", floor, (0.55, 0.5, 0.45, 1.0)), ("wall", back, (0.7, 0.72, 0.75, 1.0))]
