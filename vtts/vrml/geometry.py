"""IndexedFaceSet → triangles, the form renderers and the deformation engine use.

Polygons (``coordIndex`` runs separated by ``-1``) are fan-triangulated, which is exact for the
convex polygons VRML97 asks for by default. Where normals, colors or texture coordinates are
indexed differently from the coordinates (per face, or by their own index arrays), corners that
differ become separate output vertices; :attr:`TriangleMesh.coord_index` maps each output vertex
back to its Coordinate point so that animation can move them together. :func:`primitive_mesh`
gives the triangles of the primitives (Box, Sphere, Cylinder, Cone).
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np

from vtts.errors import VrmlSemanticError

if TYPE_CHECKING:
    from vtts.vrml.scene import Node


@dataclass(eq=False)
class TriangleMesh:
    """Triangles ready for rendering.

    positions    ``(n, 3) float64``  output vertices (model units)
    faces        ``(m, 3) int64``    counter-clockwise triangles (front side)
    normals      ``(n, 3) float64``  unit vertex normals
    colors       ``(n, 3) float64`` or None, RGB in [0, 1]
    texcoords    ``(n, 2) float64`` or None, (s, t)
    coord_index  ``(n,) int64``      the Coordinate point each output vertex comes from
    face_polygon ``(m,) int64``      the polygon (IndexedFaceSet face number) of each triangle
    double_sided True when the node is not ``solid`` (both sides visible)
    """

    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    colors: np.ndarray | None
    texcoords: np.ndarray | None
    coord_index: np.ndarray
    face_polygon: np.ndarray
    double_sided: bool


def _corners(coord_index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions of the corners in coordIndex, polygon number of each, index in its polygon)."""
    ci = np.asarray(coord_index, dtype=np.int64)
    sep = ci == -1
    pos = np.flatnonzero(~sep)
    pid = np.cumsum(sep)[pos]
    if pos.size == 0:
        return pos, pid, pid
    first = np.r_[True, pid[1:] != pid[:-1]]
    idx = np.arange(pos.size)
    start = np.maximum.accumulate(np.where(first, idx, 0))
    return pos, pid, idx - start


def polygon_triangle_count(coord_index: np.ndarray) -> int:
    """Number of fan triangles of a coordIndex array."""
    ci = np.asarray(coord_index, dtype=np.int64)
    return _fan_triangle_count(ci == -1, ci.size)


def _fan(k: np.ndarray) -> np.ndarray:
    """``(m, 3)`` corner numbers of the fan triangles, given each corner's index in its polygon."""
    c = np.flatnonzero(k >= 2)
    start = c - k[c]
    return np.stack([start, c - 1, c], axis=1)


def _check_range(name: str, idx: np.ndarray, n: int, node: Node, what: str) -> None:
    if idx.size == 0:
        return
    bad = (idx < 0) | (idx >= n)
    if bad.any():
        i = int(np.argmax(bad))
        raise VrmlSemanticError(
            f"IndexedFaceSet {name} value {int(idx[i])} (entry {i}) is out of range: the "
            f"{what} has {n} entries",
            line=node.line,
            column=node.column,
        )


def _attribute_index(
    node: Node, index_field: str, per_vertex: bool, pos: np.ndarray, pid: np.ndarray
) -> np.ndarray:
    """Per-corner index into an attribute node (normal, color, texCoord) following the spec's
    rules for ``*PerVertex`` and ``*Index``."""
    own = np.asarray(node[index_field], dtype=np.int64)
    if per_vertex:
        if own.size:
            if own.size < pos.max(initial=-1) + 1:
                raise VrmlSemanticError(
                    f"IndexedFaceSet {index_field} has {own.size} entries but coordIndex needs "
                    f"{pos.max() + 1}",
                    line=node.line,
                    column=node.column,
                )
            return own[pos]
        return np.asarray(node["coordIndex"], dtype=np.int64)[pos]
    if own.size:
        if own.size < pid.max(initial=-1) + 1:
            raise VrmlSemanticError(
                f"IndexedFaceSet {index_field} has {own.size} entries for {pid.max() + 1} faces",
                line=node.line,
                column=node.column,
            )
        return own[pid]
    return pid


def _normalize(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def _generated_normals(
    points: np.ndarray,
    corner_coord: np.ndarray,
    pid: np.ndarray,
    tri_corners: np.ndarray,
    crease: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Normals where the file gives none: (per-corner normals ``(c, 3)``, per-corner key ``(c,)``
    or ``(c, 3)`` that tells which corners may share an output vertex)."""
    n_poly = int(pid.max()) + 1 if pid.size else 0
    tri_coord = corner_coord[tri_corners]
    p = points[tri_coord]
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    face_n = np.zeros((n_poly, 3))
    np.add.at(face_n, pid[tri_corners[:, 0]], cross)
    unit_face = _normalize(face_n)
    if crease <= 0.0:
        return unit_face[pid], pid
    if crease >= np.pi:
        vn = np.zeros((points.shape[0], 3))
        np.add.at(
            vn,
            corner_coord,
            face_n[pid] / np.maximum(np.bincount(pid, minlength=n_poly)[pid], 1)[:, None],
        )
        return _normalize(vn)[corner_coord], corner_coord
    # General crease angle: a corner averages the faces around its point whose normals are
    # within the crease angle of its own face's normal.
    order = np.argsort(corner_coord, kind="stable")
    sc = corner_coord[order]
    bounds = np.flatnonzero(np.r_[True, sc[1:] != sc[:-1], True])
    counts = np.diff(bounds)
    group = np.repeat(np.arange(counts.size), counts)
    # all (corner, other corner) pairs around the same point
    rep = np.repeat(counts, counts)
    a = np.repeat(np.arange(sc.size), rep[np.arange(sc.size)])
    starts = bounds[group]
    offs = np.arange(a.size) - np.repeat(np.cumsum(rep) - rep, rep)
    b = starts[a] + offs
    ca, cb = order[a], order[b]
    fa, fb = pid[ca], pid[cb]
    keep = np.einsum("ij,ij->i", unit_face[fa], unit_face[fb]) >= np.cos(crease) - 1e-12
    out = np.zeros((corner_coord.size, 3))
    np.add.at(out, ca[keep], face_n[fb[keep]])
    # A face appears once per corner it has at the point; faces are counted once each by
    # normalising per (corner, face) pair — for convex polygons each face touches a point once.
    normals = _normalize(out)
    key = np.round(normals * 1e6).astype(np.int64)
    return normals, key


def _default_texcoords(points: np.ndarray) -> np.ndarray:
    """The spec's default texture mapping: S along the bounding box's largest dimension, T along
    the second largest, scaled so S spans [0, 1]."""
    if points.size == 0:
        return np.zeros((0, 2))
    lo, hi = points.min(axis=0), points.max(axis=0)
    size = hi - lo
    order = np.argsort(-size, kind="stable")
    s_axis, t_axis = order[0], order[1]
    span = size[s_axis] if size[s_axis] > 0 else 1.0
    return np.stack(
        [(points[:, s_axis] - lo[s_axis]) / span, (points[:, t_axis] - lo[t_axis]) / span], axis=1
    )


def _attribute_node_values(node: Node, field_name: str, value_field: str) -> np.ndarray | None:
    child = node[field_name]
    if child is None:
        return None
    child = child.expand()
    if child.type.kind == "generic" or child.type.field(value_field) is None:
        # a node vtts does not know (parsed leniently, e.g. X3D's TextureCoordinateGenerator)
        # gives no values: the attribute is treated as absent
        return None
    return np.asarray(child[value_field], dtype=np.float64)


def check_face_set(node: Node) -> int:
    """Raise what :func:`triangulate` would raise for an IndexedFaceSet (an index out of range,
    an index array too short for the corners or faces it must cover), at the same node and with
    the same message, without building the mesh; the number of its fan triangles otherwise.

    ``vtts check`` needs only this: triangulating a large mesh to validate it spends most of its
    time on what validation never reads (generated normals, merging corners into vertices).
    """
    node = node.expand()
    if node.type.name != "IndexedFaceSet":
        raise TypeError(f"not an IndexedFaceSet: {node.type.name}")
    pts = _attribute_node_values(node, "coord", "point")
    n_points = 0 if pts is None else pts.size // 3
    ci = np.asarray(node["coordIndex"], dtype=np.int64)
    sep = ci == -1
    pos = np.flatnonzero(~sep)
    corner_coord = ci[pos]
    _check_range("coordIndex", corner_coord, n_points, node, "Coordinate")
    if pos.size == 0:
        return 0
    pid = np.cumsum(sep)[pos]
    # (attribute node, its value field, its index field, per vertex?, what range errors call it)
    attributes = (
        ("normal", "vector", "normalIndex", node["normalPerVertex"], "Normal node"),
        ("color", "color", "colorIndex", node["colorPerVertex"], "Color node"),
        ("texCoord", "point", "texCoordIndex", True, "TextureCoordinate"),
    )
    for field_name, value_field, index_field, per_vertex, what in attributes:
        values = _attribute_node_values(node, field_name, value_field)
        if values is not None:
            idx = _attribute_index(node, index_field, per_vertex, pos, pid)
            _check_range(index_field, idx, values.shape[0], node, what)
    return _fan_triangle_count(sep, ci.size)


def _fan_triangle_count(sep: np.ndarray, n: int) -> int:
    """Fan triangles of a coordIndex given where its ``-1`` separators are: a polygon of ``k``
    corners gives ``k - 2``, a shorter run none."""
    bounds = np.r_[-1, np.flatnonzero(sep), n]
    corners = np.diff(bounds) - 1
    return int(np.maximum(corners - 2, 0).sum())


#: How many meshes :func:`triangulate` keeps, the most recently used.
TRIANGULATED = 256
#: Meshes with fewer coordIndex entries than this are made anew each time: they take less
#: time to make than to look up.
KEEP_FROM = 1024
_triangulated: OrderedDict[bytes, TriangleMesh] = OrderedDict()
_triangulated_lock = threading.Lock()


def _geometry_key(node: Node) -> bytes:
    """A digest of everything :func:`triangulate` reads of an IndexedFaceSet ``node``: two
    nodes with the same digest give the same triangles."""
    h = hashlib.blake2b(digest_size=20)
    for name in ("ccw", "solid", "creaseAngle", "normalPerVertex", "colorPerVertex"):
        h.update(repr(node[name]).encode())
    for name in ("coordIndex", "normalIndex", "colorIndex", "texCoordIndex"):
        a = np.ascontiguousarray(node[name], dtype=np.int64)
        h.update(b"%d|" % a.size)
        h.update(a)
    for name, value in (("coord", "point"), ("normal", "vector"), ("color", "color"),
                        ("texCoord", "point")):  # fmt: skip
        a = _attribute_node_values(node, name, value)
        if a is None:
            h.update(b"none|")
        else:
            a = np.ascontiguousarray(a)
            h.update(repr(a.shape).encode())
            h.update(a)
    return h.digest()


def triangulate(node: Node, points: np.ndarray | None = None) -> TriangleMesh:
    """The :class:`TriangleMesh` of an IndexedFaceSet node.

    ``points`` (``(p, 3) float64``) replaces the Coordinate's points, which is how animated
    (deformed) geometry is triangulated with the same topology.

    Without ``points`` a mesh of :data:`KEEP_FROM` coordIndex entries or more is kept (the last
    :data:`TRIANGULATED`, by a digest of the node's geometry) and given again, read-only, for
    the same geometry: a renderer is made for a head again and again, and its generated normals
    were most of the time that took.
    """
    node = node.expand()
    if node.type.name != "IndexedFaceSet":
        raise TypeError(f"not an IndexedFaceSet: {node.type.name}")
    if points is not None or np.size(node["coordIndex"]) < KEEP_FROM:
        return _triangulate(node, points)
    key = _geometry_key(node)
    with _triangulated_lock:
        mesh = _triangulated.get(key)
        if mesh is not None:
            _triangulated.move_to_end(key)
            return mesh
    mesh = _triangulate(node, None)
    for f in fields(mesh):
        value = getattr(mesh, f.name)
        if isinstance(value, np.ndarray):
            value.flags.writeable = False
    with _triangulated_lock:
        _triangulated[key] = mesh
        while len(_triangulated) > TRIANGULATED:
            _triangulated.popitem(last=False)
    return mesh


def _triangulate(node: Node, points: np.ndarray | None) -> TriangleMesh:
    """:func:`triangulate` of the expanded IndexedFaceSet ``node``, made anew."""
    if points is None:
        pts = _attribute_node_values(node, "coord", "point")
        points = np.zeros((0, 3)) if pts is None else pts
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    ci = np.asarray(node["coordIndex"], dtype=np.int64)
    pos, pid, k = _corners(ci)
    corner_coord = ci[pos]
    _check_range("coordIndex", corner_coord, points.shape[0], node, "Coordinate")
    if pos.size == 0:  # no polygons (no coord, or an empty coordIndex): nothing to draw
        return TriangleMesh(
            positions=np.zeros((0, 3)),
            faces=np.zeros((0, 3), dtype=np.int64),
            normals=np.zeros((0, 3)),
            colors=None,
            texcoords=np.zeros((0, 2)),
            coord_index=np.zeros(0, dtype=np.int64),
            face_polygon=np.zeros(0, dtype=np.int64),
            double_sided=not node["solid"],
        )
    tri = _fan(k)
    if not node["ccw"]:
        tri = tri[:, [0, 2, 1]]
    keys: list[np.ndarray] = []

    normals_given = _attribute_node_values(node, "normal", "vector")
    if normals_given is not None:
        nidx = _attribute_index(node, "normalIndex", node["normalPerVertex"], pos, pid)
        _check_range("normalIndex", nidx, normals_given.shape[0], node, "Normal node")
        corner_normals = _normalize(normals_given[nidx])
        keys.append(nidx[:, None])
    else:
        crease = float(node["creaseAngle"])
        corner_normals, nkey = _generated_normals(points, corner_coord, pid, tri, crease)
        keys.append(nkey.reshape(nkey.shape[0], -1))

    colors_given = _attribute_node_values(node, "color", "color")
    corner_colors = None
    if colors_given is not None:
        cidx = _attribute_index(node, "colorIndex", node["colorPerVertex"], pos, pid)
        _check_range("colorIndex", cidx, colors_given.shape[0], node, "Color node")
        corner_colors = colors_given[cidx]
        keys.append(cidx[:, None])

    tex_given = _attribute_node_values(node, "texCoord", "point")
    if tex_given is not None:
        tidx = _attribute_index(node, "texCoordIndex", True, pos, pid)
        _check_range("texCoordIndex", tidx, tex_given.shape[0], node, "TextureCoordinate")
        corner_tex = tex_given[tidx]
        keys.append(tidx[:, None])
    else:
        corner_tex = _default_texcoords(points)[corner_coord]

    rows = np.concatenate([corner_coord[:, None], *keys], axis=1)
    if all(np.array_equal(key[:, 0], corner_coord) for key in keys if key.shape[1] == 1) and all(
        key.shape[1] == 1 for key in keys
    ):
        # Every attribute follows the coordinates: output vertices are the Coordinate points.
        n = points.shape[0]
        first = np.full(n, -1, dtype=np.int64)
        first[corner_coord[::-1]] = np.arange(corner_coord.size)[::-1]
        used = first >= 0
        src = np.where(used, first, 0)
        vertex_of_corner = corner_coord
        normals = np.zeros((n, 3))
        normals[used] = corner_normals[src[used]]
        colors = None
        if corner_colors is not None:
            colors = np.zeros((n, 3))
            colors[used] = corner_colors[src[used]]
        tex = np.zeros((n, 2))
        tex[used] = corner_tex[src[used]]
        coord_of_vertex = np.arange(n)
    else:
        _, first_corner, vertex_of_corner = np.unique(
            rows, axis=0, return_index=True, return_inverse=True
        )
        vertex_of_corner = vertex_of_corner.reshape(-1)
        coord_of_vertex = corner_coord[first_corner]
        normals = corner_normals[first_corner]
        colors = None if corner_colors is None else corner_colors[first_corner]
        tex = corner_tex[first_corner]
    faces = vertex_of_corner[tri] if tri.size else np.zeros((0, 3), dtype=np.int64)
    return TriangleMesh(
        positions=points[coord_of_vertex],
        faces=faces.astype(np.int64),
        normals=normals,
        colors=colors,
        texcoords=tex,
        coord_index=coord_of_vertex.astype(np.int64),
        face_polygon=pid[tri[:, 0]] if tri.size else np.zeros(0, dtype=np.int64),
        double_sided=not node["solid"],
    )


#: The VRML97 geometry nodes :func:`primitive_mesh` makes triangles of.
PRIMITIVES = ("Box", "Sphere", "Cylinder", "Cone")


def primitive_mesh(geom: Node):
    """A ``trimesh.Trimesh`` of a VRML primitive (:data:`PRIMITIVES`: Box, Sphere, Cylinder and
    Cone) in the node's own units and axes, or None for other geometry. The sphere is an
    icosphere of 3 subdivisions, the cylinder and cone have 32 sections; the renderer and the
    exporters draw the same triangles."""
    import trimesh

    t = geom.type.name
    if t == "Box":
        return trimesh.creation.box(extents=geom["size"])
    if t == "Sphere":
        return trimesh.creation.icosphere(subdivisions=3, radius=geom["radius"])
    if t in ("Cylinder", "Cone"):
        h = geom["height"]
        r = geom["radius"] if t == "Cylinder" else geom["bottomRadius"]
        mesh = (
            trimesh.creation.cylinder(radius=r, height=h, sections=32)
            if t == "Cylinder"
            else trimesh.creation.cone(radius=r, height=h, sections=32)
        )
        if t == "Cone":
            mesh.apply_translation([0, 0, -h / 2])
        # VRML's axis is y; trimesh's is z
        mesh.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
        return mesh
    return None
