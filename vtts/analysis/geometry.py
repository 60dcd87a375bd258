"""The model's surface as the estimator sees it: world positions and their linear motion.

For the parameters of the current estimate this gives every vertex's world position and, for
each unknown k, its 3D motion per unit — the columns of Eisert–Girod's matrix T (Equation 9)
before the barycentric combination:

* a FAP that deforms a mesh moves a vertex by the slope of its ADT interval at the current value
  (the table is piecewise linear, so the slope is exact within the interval), carried to world
  space by the Transforms above the mesh;
* a FAP that rotates a Transform (head, eyes) moves the points below it along the tangent of the
  rotation — the linearized rotation of Equations 6–7 — obtained by differentiating the posed
  Transform chain;
* the head translation (unknowns ``tx``, ``ty``, ``tz``) moves every point along a world axis.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from vtts.face import FaceModel
from vtts.face.deform import Pose
from vtts.vrml import Node, transform_matrix, triangulate
from vtts.vrml.geometry import TriangleMesh
from vtts.vrml.transform import compose_transform

#: Step (in parameter units) of the central difference of a Transform chain: rotations are in
#: 1e-5 rad, so this is exact to far below the estimator's resolution.
_H = 1.0

#: The fields of a Transform that place its children.
_TRANSFORM_FIELDS = ("translation", "rotation", "scale", "scaleOrientation", "center")

#: How many point sets' gathered table columns :meth:`HeadGeometry._slopes` keeps (the
#: landmarks', the eyes', a rendering's vertices) before it starts again.
GATHERED_SETS = 8


@dataclass
class _Shape:
    chain: list[Node]  # the Transforms above the shape, outermost first
    node: Node  # the IndexedFaceSet
    mesh: TriangleMesh
    name: str | None  # DEF name of the IndexedFaceSet when the tables deform it
    first_vertex: int
    first_face: int  # index of its first triangle in HeadGeometry.faces

    @functools.cached_property
    def chain_key(self) -> tuple[int, ...]:
        """Which Transforms are above the shape (shapes with the same key share their world
        matrix)."""
        return tuple(id(node) for node in self.chain)


class HeadGeometry:
    """Every IndexedFaceSet of ``model`` as one triangle set, placed by ``root`` ``(4, 4)`` (the
    model's placement in the renderer's world).

    ``unknowns`` are FAP numbers and ``"tx"``, ``"ty"``, ``"tz"``.
    Attributes: ``faces`` ``(m, 3)`` global vertex indices, ``n_vertices``, ``lit`` ``(m,)``
    whether each triangle's Shape is lit (its Appearance has a Material; VRML97 draws a Shape
    without one unlit, its colors then independent of the pose).
    """

    def __init__(self, model: FaceModel, unknowns, root: np.ndarray) -> None:
        self.model = model
        self.engine = model.engine
        self.root = np.asarray(root, dtype=np.float64)
        self.unknowns = tuple(unknowns)
        self.shapes: list[_Shape] = []
        animated = set(model.tables.mesh_nodes())
        self._static_cache: dict[int, np.ndarray] = {}
        # the last posed matrix of each animated Transform, by id of its node, with its fields
        self._posed: dict[int, tuple[tuple, np.ndarray]] = {}
        self._last = None
        # the posed Coordinate points of each mesh, by DEF name, with the values of the
        # parameters that drive it (a mesh whose parameters did not change is not deformed again)
        self._mesh_points: dict[str, tuple[bytes, np.ndarray]] = {}
        # each shape's local and world points at the last pose asked for, made when asked
        self._local_shapes: tuple[bytes, dict[int, np.ndarray]] | None = None
        self._world_shapes: tuple[tuple[bytes, bytes], list, dict[int, np.ndarray]] | None = None
        # the derivatives of the world matrices at the last pose asked for, by unknown
        self._derivatives: tuple[tuple[bytes, bytes], dict] | None = None
        self._local: tuple[bytes, dict[int, np.ndarray]] | None = None
        self._pose: tuple[bytes, Pose] | None = None
        self._columns: dict[tuple[str, int], np.ndarray] = {}
        self._driven_by: dict[int, tuple[set[str], list[bool]]] = {}
        #: each posed Transform's own field values, by id of its node
        self._own_fields: dict[int, dict[str, object]] = {}
        #: table columns gathered at a set of points, by (mesh DEF name, the points' bytes)
        self._gathered: dict[tuple[str, bytes], dict[int, np.ndarray]] = {}
        #: mesh DEF name -> (unknown's column, parameter index, its table columns) per FAP
        self._tables: dict[str, list[tuple[int, int, np.ndarray]]] = {}
        #: parameter indices that drive a Transform (the head and eye rotations)
        self._rotating = {int(i) for t in self.engine.transforms.values() for i in t.param}
        faces = []
        lit = []
        count = n_faces = 0

        for shape, _, path in model.scene.shapes():
            geom = shape["geometry"]
            if geom is None:
                continue
            geom = geom.expand()
            if geom.type.name != "IndexedFaceSet":
                continue
            tm = triangulate(geom)
            if tm.faces.size == 0:
                continue
            chain = [n for n in path if n.type.name == "Transform"]
            name = geom.name if geom.name in animated else None
            self.shapes.append(_Shape(chain, geom, tm, name, count, n_faces))
            n_faces += len(tm.faces)
            faces.append(tm.faces + count)
            appearance = shape["appearance"]
            appearance = appearance.expand() if appearance is not None else None
            shaded = appearance is None or appearance["material"] is not None
            lit.append(np.full(len(tm.faces), shaded))
            count += tm.positions.shape[0]
        self.faces = np.concatenate(faces).astype(np.int64)
        self.lit = np.concatenate(lit)
        self.n_vertices = count
        self.shape_of_vertex = np.repeat(
            np.arange(len(self.shapes)), [s.mesh.positions.shape[0] for s in self.shapes]
        )

    # ---- posing --------------------------------------------------------------------------------

    def _node_matrix(self, node: Node, posed: dict[str, dict[str, np.ndarray]]) -> np.ndarray:
        """The local matrix of a Transform: posed by the tables, or its own fields."""
        fields = posed.get(node.name)
        if not fields:
            return self._static(node)
        own = self._own_fields.get(id(node))
        if own is None:  # the scene's own values do not change while a geometry poses it
            own = self._own_fields[id(node)] = {f: node[f] for f in _TRANSFORM_FIELDS}
        return compose_transform(
            fields.get("translation", own["translation"]),
            fields.get("rotation", own["rotation"]),
            fields.get("scale", own["scale"]),
            own["scaleOrientation"],
            own["center"],
        )

    def _top(self, translation: np.ndarray) -> np.ndarray:
        top = self.root.copy()
        top[:3, 3] += translation
        return top

    def _locals(self, params: np.ndarray) -> dict[int, np.ndarray]:
        """The local matrix ``(4, 4)`` of every Transform above a shape, by ``id`` of its node,
        posed by ``params`` (the last ones are kept)."""
        key = np.asarray(params, np.float64).tobytes()
        if self._local is None or self._local[0] != key:
            posed = self.engine.transform_values(params)
            local: dict[int, np.ndarray] = {}
            for s in self.shapes:
                for node in s.chain:
                    if id(node) not in local:
                        local[id(node)] = self._posed_matrix(node, posed)
            self._local = (key, local)
        return self._local[1]

    def _posed_matrix(self, node: Node, posed: dict[str, dict[str, np.ndarray]]) -> np.ndarray:
        """:meth:`_node_matrix` of a pose, the last one of each Transform kept by its posed
        fields' values (a pose usually moves the head's Transforms only, not the eyes')."""
        fields = posed.get(node.name)
        if not fields:
            return self._static(node)
        values = tuple((name, np.asarray(v, np.float64).tobytes()) for name, v in fields.items())
        kept = self._posed.get(id(node))
        if kept is None or kept[0] != values:
            kept = self._posed[id(node)] = (values, self._node_matrix(node, posed))
        return kept[1]

    def _matrices(self, params: np.ndarray, translation: np.ndarray) -> list[np.ndarray]:
        """World matrix ``(4, 4)`` of each shape."""
        local = self._locals(params)
        top = self._top(translation)
        out = []
        done: dict[tuple[int, ...], np.ndarray] = {}  # shapes under the same Transforms share it
        for s in self.shapes:
            key = s.chain_key
            if key not in done:
                m = top
                for node in s.chain:
                    m = m @ local[id(node)]
                done[key] = m
            out.append(done[key])
        return out

    def _matrix_derivatives(
        self, params: np.ndarray, translation: np.ndarray, pi: int
    ) -> list[np.ndarray | None]:
        """d(world matrix)/d(parameter ``pi``) of each shape (None where it does not depend on
        it): the product rule over the shape's Transform chain, with each driven Transform's own
        derivative by central differences of its posed fields (exact for the tables' linear
        angles)."""
        names, driven = self._driven(pi)
        local = self._locals(params)
        up, down = params.copy(), params.copy()
        up[pi] += _H
        down[pi] -= _H
        posed_up, posed_down = (
            self.engine.transform_values(up, names),
            self.engine.transform_values(down, names),
        )
        top = self._top(translation)
        slope: dict[int, np.ndarray] = {}
        out: list[np.ndarray | None] = []
        done: dict[tuple[int, ...], np.ndarray] = {}  # shapes under the same Transforms share it
        for s, moves in zip(self.shapes, driven, strict=True):
            if not moves:
                out.append(None)
                continue
            key = s.chain_key
            if key in done:
                out.append(done[key])
                continue
            for n in s.chain:
                if n.name in names and id(n) not in slope:
                    slope[id(n)] = (
                        self._node_matrix(n, posed_up) - self._node_matrix(n, posed_down)
                    ) / (2 * _H)
            total = None
            for i, node in enumerate(s.chain):
                if id(node) not in slope:
                    continue
                m = top
                for j, other in enumerate(s.chain):
                    m = m @ (slope[id(node)] if j == i else local[id(other)])
                total = m if total is None else total + m
            done[key] = total
            out.append(total)
        return out

    def _driven(self, pi: int) -> tuple[set[str], list[bool]]:
        """The DEF names of the Transforms parameter ``pi`` drives, and whether each shape lies
        below one of them (kept by parameter)."""
        if pi not in self._driven_by:
            names = {node for (node, _), t in self.engine.transforms.items() if pi in t.param}
            self._driven_by[pi] = (names, [any(n.name in names for n in s.chain)
                                           for s in self.shapes])  # fmt: skip
        return self._driven_by[pi]

    def _static(self, node: Node) -> np.ndarray:
        key = id(node)
        if key not in self._static_cache:
            self._static_cache[key] = transform_matrix(node)
        return self._static_cache[key]

    def pose(self, params: np.ndarray) -> Pose:
        """The model's :class:`~vtts.face.deform.Pose` for ``params`` (the last one is kept: the
        renderer draws the same pose that the geometry is computed from); the same numbers as
        ``engine.deform(params)``, each mesh's points those of :meth:`mesh_points`."""
        key = np.asarray(params, np.float64).tobytes()
        if self._pose is None or self._pose[0] != key:
            params = np.asarray(params, np.float64)
            points = {name: self.mesh_points(name, params) for name in self.engine.meshes}
            self._pose = (key, Pose(points=points, transforms=self.engine.transform_values(params)))
        return self._pose[1]

    def mesh_points(self, name: str, params: np.ndarray) -> np.ndarray:
        """The posed Coordinate points ``(p, 3)`` of mesh ``name`` for ``params`` (the engine's
        arithmetic, :meth:`~vtts.face.deform.DeformationEngine.points`); kept with the values of
        the parameters that drive the mesh, so that a pose that leaves them (the hair's, the
        ears' while the lips move) does not deform it again."""
        b = self.engine.meshes[name]
        params = np.asarray(params, np.float64)
        key = params[b.param].tobytes()
        kept = self._mesh_points.get(name)
        if kept is None or kept[0] != key:
            moved = self.engine.displacement(b, params).reshape(-1, 3)
            kept = self._mesh_points[name] = (key, b.neutral + moved)
        return kept[1]

    def _shape_local(self, si: int, params: np.ndarray) -> np.ndarray:
        """Shape ``si``'s vertex positions ``(n_s, 3)`` in its own coordinates for ``params``
        (the last pose's are kept)."""
        key = params.tobytes()
        if self._local_shapes is None or self._local_shapes[0] != key:
            self._local_shapes = (key, {})
        done = self._local_shapes[1]
        if si not in done:
            s = self.shapes[si]
            if s.name is not None and s.name in self.engine.meshes:
                done[si] = self.mesh_points(s.name, params)[s.mesh.coord_index]
            else:
                done[si] = s.mesh.positions
        return done[si]

    def _local_of(self, si: int, params: np.ndarray, lv: np.ndarray) -> np.ndarray:
        """``_shape_local(si, params)[lv]`` ``(len(lv), 3)`` for the shape's vertices ``lv``,
        gathered from the mesh's points when the shape's own were not made for this pose."""
        kept = self._local_shapes
        if kept is not None and kept[0] == params.tobytes() and si in kept[1]:
            return kept[1][si][lv]
        s = self.shapes[si]
        if s.name is not None and s.name in self.engine.meshes:
            return self.mesh_points(s.name, params)[s.mesh.coord_index[lv]]
        return s.mesh.positions[lv]

    def local_points(self, params: np.ndarray) -> list[np.ndarray]:
        """Each shape's vertex positions ``(n_s, 3)`` in its own coordinates."""
        params = np.asarray(params, np.float64)
        return [self._shape_local(si, params) for si in range(len(self.shapes))]

    def _world_matrices(self, params: np.ndarray, translation: np.ndarray) -> list[np.ndarray]:
        """:meth:`_matrices` of the pose (the last pose's are kept, with its shapes' world
        positions as :meth:`_shape_world` makes them)."""
        key = (params.tobytes(), np.asarray(translation, np.float64).tobytes())
        if self._world_shapes is None or self._world_shapes[0] != key:
            self._world_shapes = (key, self._matrices(params, translation), {})
        return self._world_shapes[1]

    def _shape_world(self, si: int, params: np.ndarray, translation: np.ndarray):
        """Shape ``si``'s world positions ``(n_s, 3)``, with the world matrices of every shape
        (the last pose's are kept; a shape's positions are made when first asked for)."""
        mats = self._world_matrices(params, translation)
        done = self._world_shapes[2]
        if si not in done:
            m = mats[si]
            done[si] = self._shape_local(si, params) @ m[:3, :3].T + m[:3, 3]
        return done[si], mats

    def _state(self, params: np.ndarray, translation: np.ndarray):
        """Local points, world matrices and world positions for the given pose (the last one is
        kept: the estimator asks for the same pose several times per solve)."""
        key = (params.tobytes(), np.asarray(translation, np.float64).tobytes())
        if self._last is None or self._last[0] != key:
            params = np.asarray(params, np.float64)
            blocks = [self._shape_world(si, params, translation)[0]
                      for si in range(len(self.shapes))]  # fmt: skip
            local = self.local_points(params)
            mats = self._world_shapes[1]
            self._last = (key, local, mats, np.concatenate(blocks))
        return self._last[1:]

    def positions(self, params: np.ndarray, translation: np.ndarray) -> np.ndarray:
        """World positions ``(n_vertices, 3)`` for ``params`` ``(N_PARAMS,)`` and the head
        ``translation`` ``(3,)``."""
        return self._state(params, translation)[2]

    def positions_of(
        self, params: np.ndarray, translation: np.ndarray, vertices: np.ndarray
    ) -> np.ndarray:
        """``positions(params, translation)[vertices]`` ``(*vertices.shape, 3)`` for global
        ``vertices`` (any shape), the same numbers, with only the shapes that hold them posed
        (the landmarks lie on the face's shape and the eyes')."""
        vertices = np.asarray(vertices, dtype=np.int64)
        params = np.asarray(params, np.float64)
        if self._last is not None and self._last[0] == (
            params.tobytes(),
            np.asarray(translation, np.float64).tobytes(),
        ):
            return self._last[3][vertices]
        out = np.empty((*vertices.shape, 3))
        shape_ids = self.shape_of_vertex[vertices]
        mats = self._world_matrices(params, translation)
        done = self._world_shapes[2]
        for si in np.unique(shape_ids).tolist():
            mine = shape_ids == si
            lv = vertices[mine] - self.shapes[si].first_vertex
            if si in done:
                out[mine] = done[si][lv]
            else:  # these vertices only: each row's product is the whole shape's row's
                m = mats[si]
                out[mine] = self._local_of(si, params, lv) @ m[:3, :3].T + m[:3, 3]
        return out

    # ---- linear motion -------------------------------------------------------------------------

    def jacobian(
        self, params: np.ndarray, translation: np.ndarray, vertices: np.ndarray
    ) -> np.ndarray:
        """World motion per unit of each unknown, ``(len(vertices), 3, K)``, of the global
        ``vertices`` ``(n,)`` at ``params`` and ``translation``."""
        vertices = np.asarray(vertices, dtype=np.int64)
        k_count = len(self.unknowns)
        if len(vertices) == 0:
            return np.zeros((0, 3, k_count))
        # by shape, each shape's vertices one contiguous block (a view, not a gather)
        order = np.argsort(vertices, kind="stable")
        ordered = vertices[order]
        # unknown-major while it is filled (each unknown's rows contiguous), (n, 3, K) at the end
        out = np.zeros((k_count, len(vertices), 3))
        shape_ids = self.shape_of_vertex[ordered]
        params = np.asarray(params, np.float64)
        # Transform chains: the derivative of each shape's world matrix (kept for the last pose:
        # a solve asks for the pixels' and the landmarks' motion at the same one)
        key = (np.asarray(params, np.float64).tobytes(),
               np.asarray(translation, np.float64).tobytes())  # fmt: skip
        if self._derivatives is None or self._derivatives[0] != key:
            self._derivatives = (key, {
                j: self._matrix_derivatives(params, translation, u - 1)
                for j, u in enumerate(self.unknowns)
                if not isinstance(u, str) and u - 1 in self._rotating
            })  # fmt: skip
        d_mats: dict[int, list[np.ndarray | None]] = self._derivatives[1]
        for j, u in enumerate(self.unknowns):
            if isinstance(u, str):
                out[j, :, "xyz".index(u[1])] = 1.0
        starts = np.flatnonzero(np.diff(shape_ids, prepend=-1))
        for start, stop in zip(starts, [*starts[1:], len(ordered)], strict=True):
            si = int(shape_ids[start])
            block = out[:, start:stop]
            s = self.shapes[si]
            lv = ordered[start:stop] - s.first_vertex
            pts = self._local_of(si, params, lv)
            rot = self._world_matrices(params, translation)[si][:3, :3]
            for j, dm in d_mats.items():
                d = dm[si]
                if d is not None:
                    block[j] += pts @ d[:3, :3].T + d[:3, 3]
            if s.name is None or s.name not in self.engine.meshes:
                continue
            slopes = self._slopes(s.name, params, s.mesh.coord_index[lv])
            for j, sl in slopes.items():
                block[j] += sl @ rot.T
        out = out.transpose(1, 2, 0)
        if np.all(order[:-1] < order[1:]):
            return np.ascontiguousarray(out)  # asked in order (np.unique's)
        result = np.empty(out.shape)
        result[order] = out
        return result

    def _slopes(self, name: str, params: np.ndarray, points: np.ndarray) -> dict[int, np.ndarray]:
        """Displacement per unit ``(len(points), 3)`` of the Coordinate ``points`` of mesh
        ``name`` for each FAP unknown with an active table interval at ``params``."""
        b = self.engine.meshes[name]
        tables = self._tables.get(name)
        if tables is None:  # each unknown's table columns in this mesh, in column order
            tables = [
                (j, u - 1, np.flatnonzero(b.param == u - 1))
                for j, u in enumerate(self.unknowns)
                if not isinstance(u, str)
            ]
            self._tables[name] = tables = [t for t in tables if t[2].size]
        # the columns gathered at these points, kept for the few point sets a frame asks for
        # again (the landmarks' at every relinearization)
        gathered = self._gathered.setdefault((name, points.tobytes()), {})
        if len(self._gathered) > GATHERED_SETS:
            self._gathered.clear()
            self._gathered[(name, points.tobytes())] = gathered
        out = {}
        for j, pi, cols in tables:
            v = params[pi]
            cols = cols[(b.lo[cols] <= v) & (v < b.hi[cols])]
            if cols.size == 0:
                continue
            col = int(cols[0])
            if col not in gathered:
                gathered[col] = self._column(name, col)[points]
            out[j] = gathered[col]
        return out

    def _column(self, name: str, col: int) -> np.ndarray:
        """Table column ``col`` of mesh ``name`` as dense per-point slopes ``(p, 3)``."""
        key = (name, col)
        if key not in self._columns:
            b = self.engine.meshes[name]
            c = b.csc[:, col]
            dense = np.zeros(b.csc.shape[0])
            dense[c.indices] = c.data
            self._columns[key] = dense.reshape(-1, 3)
        return self._columns[key]
