"""Candide-3 (Jörgen Ahlberg, Image Coding Group, Linköping University) as the bundled heads'
control mesh: reading the ``.wfm`` file and refining it by Loop subdivision.

The refined face is a fixed linear map of Candide's vertices, ``face = S @ candide`` (Eisert &
Girod, Equation 1: every vertex of their model is a linear combination of control points), so
any displacement of Candide's vertices — an animation unit, a shape unit, a FAP — becomes a
smooth displacement of the refined face through the same matrix ``S``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from vtts.resources import models_dir

#: Candide's eyeball and pupil vertices: the bundled heads have real eyeballs instead.
EYE_SURFACE_VERTICES = frozenset(range(67, 75))
#: Levels of Loop subdivision from Candide to the bundled heads' ``FACE``.
LEVELS = 3
#: Candide vertices that subdivision keeps in place: the mouth and eye corners (so the lips stay
#: separate and the mouth can open).
SUBDIVISION_CORNERS = frozenset({88, 89, 20, 23, 53, 56})


def wfm_path() -> Path:
    """``candide3.wfm`` as shipped with vtts (``models/src/``)."""
    return models_dir() / "src" / "candide3.wfm"


@dataclass
class Unit:
    """An animation or shape unit: a name (and the FAPU of a FAP unit) and a displacement per
    Candide vertex ``(113, 3)`` (zero for the vertices it does not move)."""

    name: str
    fapu: str | None
    displacement: np.ndarray

    @property
    def fap(self) -> int | None:
        """The FAP number of a ``# FAP n name`` unit, else None."""
        words = self.name.replace("FAP", "FAP ").split()
        if words[0] == "FAP" and words[1].isdigit():
            return int(words[1])
        return None


@dataclass
class Candide:
    """The parsed ``.wfm``: ``vertices (113, 3)``, ``faces (184, 3)`` (Candide's own winding),
    animation and shape units by name."""

    vertices: np.ndarray
    faces: np.ndarray
    animation_units: dict[str, Unit] = field(default_factory=dict)
    shape_units: dict[str, Unit] = field(default_factory=dict)

    def fap_unit(self, number: int) -> Unit | None:
        for u in self.animation_units.values():
            if u.fap == number:
                return u
        return None

    def au(self, prefix: str) -> np.ndarray:
        """The displacement of the animation unit whose name starts with (or, after an ``AUVn``
        tag, reads) ``prefix``."""
        for name, u in self.animation_units.items():
            bare = name.split(None, 1)[1] if name.startswith("AUV") else name
            if name.startswith(prefix) or bare.startswith(prefix):
                return u.displacement
        raise KeyError(prefix)


def read_wfm(path: Path | None = None) -> Candide:
    """Parse a Candide ``.wfm`` file (Latin-1 text; layout in ``models/src/README.md``); the
    shipped ``candide3.wfm`` by default."""
    path = wfm_path() if path is None else path
    lines = [ln.rstrip() for ln in path.read_text(encoding="latin-1").splitlines()]
    k = 0

    def skip_to(title: str) -> None:
        nonlocal k
        while not lines[k].startswith(title):
            k += 1
        k += 1

    def next_data() -> list[str]:
        nonlocal k
        while not lines[k].strip() or lines[k].startswith("#"):
            k += 1
        k += 1
        return lines[k - 1].split()

    skip_to("# VERTEX LIST")
    n = int(next_data()[0])
    vertices = np.array([[float(x) for x in next_data()[:3]] for _ in range(n)])
    skip_to("# FACE LIST")
    m = int(next_data()[0])
    faces = np.array([[int(x) for x in next_data()[:3]] for _ in range(m)], dtype=np.int64)

    def units(title: str) -> dict[str, Unit]:
        nonlocal k
        skip_to(title)
        count = int(next_data()[0])
        out: dict[str, Unit] = {}
        for _ in range(count):
            comments = []
            while not lines[k].strip() or lines[k].startswith("#"):
                if lines[k].startswith("#"):
                    comments.append(lines[k][1:].strip())
                k += 1
            name = comments[-2] if len(comments) >= 2 and comments[-1].isupper() else comments[-1]
            fapu = comments[-1] if name != comments[-1] else None
            rows = int(lines[k].split()[0])
            k += 1
            d = np.zeros((n, 3))
            for _ in range(rows):
                w = next_data()
                d[int(w[0])] += [float(x) for x in w[1:4]]
            out[name] = Unit(name, fapu, d)
        return out

    animation = units("# ANIMATION UNITS LIST")
    shape = units("# SHAPE UNITS LIST")
    return Candide(vertices, faces, animation, shape)


def orient_front(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Turn every triangle so that its normal points away from a centre behind the face (+z
    faces the viewer); Candide's triangles have mixed winding."""
    centre = np.array([0.0, 0.0, -1.0])
    p = vertices[faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    inward = np.einsum("ij,ij->i", n, p.mean(axis=1) - centre) < 0
    out = faces.copy()
    out[inward] = out[inward][:, [0, 2, 1]]
    return out


def orient_consistently(faces: np.ndarray, seed: int) -> np.ndarray:
    """Flip triangles so that neighbours cross their shared edge in opposite directions,
    spreading from triangle ``seed`` (whose winding is kept)."""
    out = faces.copy()
    by_edge: dict[tuple[int, int], list[int]] = {}
    for t, tri in enumerate(out):
        for s in range(3):
            a, b = int(tri[s]), int(tri[(s + 1) % 3])
            by_edge.setdefault((min(a, b), max(a, b)), []).append(t)
    done = {seed}
    todo = [seed]
    while todo:
        t = todo.pop()
        tri = out[t]
        for s in range(3):
            a, b = int(tri[s]), int(tri[(s + 1) % 3])
            for u in by_edge[(min(a, b), max(a, b))]:
                if u in done:
                    continue
                other = [(int(out[u][k]), int(out[u][(k + 1) % 3])) for k in range(3)]
                if (a, b) in other:  # same direction: flip the neighbour
                    out[u] = out[u][[0, 2, 1]]
                done.add(u)
                todo.append(u)
    return out


def face_triangles(candide: Candide) -> np.ndarray:
    """Candide's skin triangles, front facing +z, without the eyeball and pupil surfaces
    (``(156, 3)`` into Candide's vertex numbering).

    The outward test of :func:`orient_front` is unreliable on the lips (their triangles face up
    and down), so the winding of the nose tip's triangles spreads over the mesh instead."""
    faces = orient_front(candide.vertices, candide.faces)
    keep = ~np.isin(faces, list(EYE_SURFACE_VERTICES)).any(axis=1)
    faces = faces[keep]
    nose_tip = int(np.flatnonzero((faces == 5).any(axis=1))[0])
    return orient_consistently(faces, nose_tip)


def _edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique undirected edges ``(e, 2)``, the edge of each triangle side ``(m, 3)`` (sides
    ab, bc, ca) and the number of triangles on each edge ``(e,)``."""
    sides = np.stack([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]], axis=1)
    flat = np.sort(sides.reshape(-1, 2), axis=1)
    edges, inverse, counts = np.unique(flat, axis=0, return_inverse=True, return_counts=True)
    return edges, inverse.reshape(-1, 3), counts


def boundary_loops(faces: np.ndarray) -> list[list[int]]:
    """The boundary loops of a triangle mesh, each ordered along the boundary so that the mesh
    lies on its left (the direction of the triangles' own sides)."""
    sides = np.stack([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]], axis=1).reshape(-1, 2)
    directed = {(int(a), int(b)) for a, b in sides}
    nxt = {a: b for a, b in directed if (b, a) not in directed}
    loops, seen = [], set()
    for start in sorted(nxt):
        if start in seen:
            continue
        loop, v = [], start
        while v not in seen:
            seen.add(v)
            loop.append(v)
            v = nxt[v]
        loops.append(loop)
    return loops


def loop_subdivide(
    faces: np.ndarray, n_vertices: int, corners: set[int]
) -> tuple[sp.csr_matrix, np.ndarray, set[int]]:
    """One level of Loop subdivision as a matrix.

    Returns ``M`` ``(n_vertices + edges, n_vertices)`` with new points ``M @ points``, the new
    triangles ``(4 m, 3)`` (same orientation) and the new corner set. Old vertex ``i`` keeps
    index ``i``; boundaries follow the cubic B-spline rule and ``corners`` stay where they are,
    so separate lips stay separate and the mouth can open."""
    edges, side_edge, counts = _edges(faces)
    ne = len(edges)
    rows, cols, vals = [], [], []

    def add(r, c, v):
        rows.append(np.asarray(r).ravel())
        cols.append(np.asarray(c).ravel())
        vals.append(np.broadcast_to(v, np.asarray(r).shape).ravel().astype(np.float64))

    # odd (edge) vertices
    opposite = [[] for _ in range(ne)]
    for t, tri in enumerate(faces):
        for s in range(3):
            opposite[side_edge[t, s]].append(tri[(s + 2) % 3])
    e_idx = np.arange(ne)
    interior = counts == 2
    add(n_vertices + e_idx[~interior], edges[~interior, 0], 0.5)
    add(n_vertices + e_idx[~interior], edges[~interior, 1], 0.5)
    ii = e_idx[interior]
    opp = np.array([opposite[e] for e in ii], dtype=np.int64).reshape(-1, 2)
    add(n_vertices + ii, edges[ii, 0], 3 / 8)
    add(n_vertices + ii, edges[ii, 1], 3 / 8)
    add(n_vertices + ii, opp[:, 0], 1 / 8)
    add(n_vertices + ii, opp[:, 1], 1 / 8)

    # even vertices
    neighbours = [set() for _ in range(n_vertices)]
    boundary_nb = [[] for _ in range(n_vertices)]
    for (a, b), c in zip(edges, counts, strict=True):
        neighbours[a].add(b)
        neighbours[b].add(a)
        if c == 1:
            boundary_nb[a].append(b)
            boundary_nb[b].append(a)
    used = np.unique(faces)
    for v in used:
        v = int(v)
        if v in corners:
            add([v], [v], 1.0)
        elif boundary_nb[v]:
            b1, b2 = boundary_nb[v]
            add([v, v, v], [v, b1, b2], np.array([0.75, 0.125, 0.125]))
        else:
            nb = sorted(neighbours[v])
            k = len(nb)
            beta = (5 / 8 - (3 / 8 + np.cos(2 * np.pi / k) / 4) ** 2) / k
            add([v] * (k + 1), [v, *nb], np.array([1 - k * beta] + [beta] * k))
    m = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(n_vertices + ne, n_vertices),
    )
    ab, bc, ca = (n_vertices + side_edge[:, s] for s in range(3))
    a, b, c = faces[:, 0], faces[:, 1], faces[:, 2]
    new_faces = np.concatenate(
        [np.stack(x, axis=1) for x in ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))]
    )
    return m, new_faces, set(corners)


def subdivision_matrix(
    faces: np.ndarray, n_vertices: int, levels: int, corners: set[int]
) -> tuple[sp.csr_matrix, np.ndarray]:
    """``levels`` of Loop subdivision: ``S`` ``(p, n_vertices)`` and the refined triangles.
    Unused control vertices get rows too (they are dropped later by the caller)."""
    s = sp.identity(n_vertices, format="csr")
    f, n, c = faces, n_vertices, corners
    for _ in range(levels):
        m, f, c = loop_subdivide(f, n, c)
        s = m @ s
        n = m.shape[0]
    return s.tocsr(), f


def compact(s: sp.csr_matrix, faces: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    """Drop the rows of vertices no triangle uses: (S, faces renumbered, kept old indices)."""
    keep = np.unique(faces)
    renumber = np.full(s.shape[0], -1, dtype=np.int64)
    renumber[keep] = np.arange(len(keep))
    return s[keep], renumber[faces], keep


@dataclass(frozen=True)
class RefinedFace:
    """The bundled heads' ``FACE`` as a fixed linear map of Candide's vertices.

    S         ``(p, 113)`` sparse: ``face = S @ candide`` (p = 5150 refined vertices)
    faces     ``(m, 3)`` the refined triangles, front facing +z, in ``FACE``'s vertex numbering
    candide_index  Candide vertex → its own refined vertex (old vertices keep a row of their own)
    """

    S: sp.csr_matrix
    faces: np.ndarray
    candide_index: dict[int, int]


@cache
def refined_face() -> RefinedFace:
    """Candide-3 refined by :data:`LEVELS` of Loop subdivision, as the bundled heads' ``FACE``
    (the same matrix for every head: vertex i means the same point of every face)."""
    candide = read_wfm()
    tris = face_triangles(candide)
    n = len(candide.vertices)
    s, f = subdivision_matrix(tris, n, LEVELS, set(SUBDIVISION_CORNERS))
    s, f, keep = compact(s, f)
    index = {int(k): i for i, k in enumerate(keep) if k < n}
    return RefinedFace(s, f, index)
