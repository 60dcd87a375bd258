"""The "professional modeler" of Ostermann & Haratsch (Figure 2) for the bundled heads.

It builds a whole head from Candide-3 and a :class:`~personalities.Personality`, deforms it for
every MIAP the way a modeler would by hand, and exports the neutral and the deformed scenes as
VRML97 files — ``neutral.wrl`` and ``NAME@AMPLITUDE.wrl`` — for the ADI (``adi build``) to turn
into Animation Definition Tables.

The head (the scene graph of Ostermann & Haratsch, Figure 11)::

    HEAD_YAW (FAP 49) > HEAD_PITCH (FAP 48) > HEAD_ROLL (FAP 50), rotating about the neck
        FACE         Candide-3 refined by three levels of Loop subdivision (S @ candide)
        HAIR         the back of the head, swept from the face's border to the back
        NECK, L_EAR, R_EAR
        UPPER_TEETH, LOWER_TEETH, TONGUE, MOUTH (the dark cavity behind the lips)
        L_EYE (thrust, FAP 27) > L_EYE_YAW (FAP 23) > L_EYE_PITCH (FAP 25) > L_EYEBALL
        R_EYE (FAP 28) > R_EYE_YAW (FAP 24) > R_EYE_PITCH (FAP 26) > R_EYEBALL
        SOCKETS      the pink behind the eyes

Every vertex of the face, and of the parts that follow it, is a fixed linear combination of
Candide's vertices (Eisert–Girod, Equation 1), so a displacement of Candide's vertices — its
MPEG-4 FAP units combined with its regional animation units — is a smooth displacement of the
head. Jaw, tongue, eyelids and eyes move by their own rules (rigid jaw about the jaw joint, lids
sliding over the eyeball).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
from candide import (
    LEVELS,
    SUBDIVISION_CORNERS,
    Candide,
    boundary_loops,
    compact,
    face_triangles,
    subdivision_matrix,
)
from skin import SKIN_FAPS, skin_field
from texture import (
    EAR_TILE,
    EYE_POWER,
    EYE_TILE,
    TEETH_TILE,
    TONGUE_TILE,
    seam_split,
    skin_chart,
    tile_uv,
)

from vtts.fap import Fapu, fap

# ---- Candide vertex numbers (left = the face's left = +x) ------------------------------------

L, R = 0, 1
#: Upper and lower eyelid boundary vertices of each eye (middle first), and the eye corners.
UPPER_LID = ((21, 97, 105), (54, 98, 106))
LOWER_LID = ((22, 99, 107), (55, 100, 108))
EYE_CORNERS = ((20, 23), (53, 56))  # outer, inner
MOUTH_CORNERS = (88, 89)

#: MPEG-4 feature points on Candide's vertices (the FAPU points and those of the FAPs).
FEATURE_VERTICES = {
    "2.1": 10, "2.2": 87, "2.3": 40, "2.4": 88, "2.5": 89, "2.6": 81, "2.7": 82, "2.8": 83,
    "2.9": 84, "2.10": 9, "3.1": 21, "3.2": 54, "3.3": 22, "3.4": 55, "4.1": 17, "4.2": 50,
    "4.3": 16, "4.4": 49, "4.5": 15, "4.6": 48, "5.1": 90, "5.2": 91, "5.3": 27, "5.4": 60,
    "8.1": 7, "8.2": 8, "8.3": 31, "8.4": 64, "8.5": 79, "8.6": 80, "8.7": 85, "8.8": 86,
    "9.1": 26, "9.2": 59, "9.3": 5, "9.15": 6,
}  # fmt: skip

#: How much of the jaw's rigid motion each Candide vertex takes (the rest stays with the skull).
JAW_WEIGHTS = {
    40: 1.0, 8: 1.0, 83: 1.0, 84: 1.0, 85: 1.0, 86: 1.0, 9: 1.0, 10: 1.0, 32: 1.0, 65: 1.0,
    30: 0.9, 63: 0.9, 88: 0.55, 89: 0.55, 31: 0.5, 64: 0.5, 90: 0.4, 91: 0.4, 28: 0.35,
    61: 0.35, 27: 0.08, 60: 0.08,
}  # fmt: skip


def mirror(v: int) -> int:
    """The Candide vertex mirrored across the face's midline (itself on the midline)."""
    return _MIRROR[v]


_MIRROR: dict[int, int] = {}


#: Twins that position alone cannot tell: the inner lip contours of both lips coincide on a
#: closed mouth (81 = 83 and 82 = 84 in space), so the upper lip's twin is the upper lip's.
_TWIN = {81: 82, 82: 81, 83: 84, 84: 83}


def _build_mirror(vertices: np.ndarray) -> None:
    flipped = vertices * [-1, 1, 1]
    for i, p in enumerate(vertices):
        if i in _TWIN:
            _MIRROR[i] = _TWIN[i]
            continue
        if p[0] == 0:  # on the midline (87 and 40 coincide too: each is its own twin)
            _MIRROR[i] = i
            continue
        d = np.linalg.norm(flipped - p, axis=1)
        d[[4, 35, 36, 37, 38, 39, 41, 42, 43]] = np.inf  # Candide's unused duplicates
        _MIRROR[i] = int(np.argmin(d)) if d.min() < 1e-6 else i


# ---- small geometry helpers -------------------------------------------------------------------


def smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((np.asarray(x, dtype=np.float64) - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def rotation(axis, angle: float) -> np.ndarray:
    """``(3, 3)`` rotation about ``axis`` by ``angle`` (right-handed, radians)."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def grid_faces(rows: int, cols: int, *, wrap: bool) -> np.ndarray:
    """Triangles of a ``rows × cols`` vertex grid (row-major), wrapping around the columns."""
    out = []
    cmax = cols if wrap else cols - 1
    for r in range(rows - 1):
        for c in range(cmax):
            a, b = r * cols + c, r * cols + (c + 1) % cols
            d, e = a + cols, b + cols
            out += [(a, d, b), (b, d, e)]
    return np.array(out, dtype=np.int64)


def outward(points: np.ndarray, faces: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """``faces`` turned so that most normals point away from ``centre``."""
    p = points[faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    if np.einsum("ij,ij->", n, p.mean(axis=1) - centre) < 0:
        return faces[:, [0, 2, 1]]
    return faces


# ---- the head ---------------------------------------------------------------------------------


@dataclass
class Part:
    """One IndexedFaceSet: DEF ``name``, neutral ``points (p, 3)``, ``faces (m, 3)``,
    ``texcoords (t, 2)`` with ``tex_faces (m, 3)`` (None: per vertex), the appearance it uses
    and whether it is ``solid`` (back faces culled)."""

    name: str
    points: np.ndarray
    faces: np.ndarray
    texcoords: np.ndarray | None
    appearance: str
    tex_faces: np.ndarray | None = None
    solid: bool = True


@dataclass
class State:
    """What a pose asks of the head, additive over FAPs (a viseme or expression is a sum).

    candide  ``(113, 3)`` skin displacement of Candide's vertices (lips, brows, cheeks, nose)
    lids     FAPs 19–22 (IRISD units): eyelids slide over the eyeball, non-linearly
    jaw      FAPs 3, 14, 15 (FAP units): rigid jaw about the jaw joint
    tongue   FAPs 43–47 (FAP units)
    eyes     per eye: yaw, pitch (AU), thrust (ES units), pupil dilation (IRISD units)
    head     FAPs 48, 49, 50 (AU)
    ears     per ear: raise, pull (ENS units)
    """

    candide: np.ndarray = field(default_factory=lambda: np.zeros((113, 3)))
    lids: np.ndarray = field(default_factory=lambda: np.zeros(4))
    jaw: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tongue: np.ndarray = field(default_factory=lambda: np.zeros(5))
    eyes: np.ndarray = field(default_factory=lambda: np.zeros((2, 4)))
    head: np.ndarray = field(default_factory=lambda: np.zeros(3))
    ears: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))

    def __add__(self, other: State) -> State:
        return State(*(getattr(self, f) + getattr(other, f) for f in self.__dataclass_fields__))


@dataclass
class Posed:
    """A posed head: points per IndexedFaceSet and Transform fields (rotation ``(4,)``,
    translation ``(3,)``) per Transform."""

    points: dict[str, np.ndarray]
    transforms: dict[str, dict[str, np.ndarray]]


#: Transforms of the scene: DEF name → (parent, rotation axis); the head's three rotate about
#: the neck pivot, the eyes' about the eyeball centres.
HEAD_TRANSFORMS = (("HEAD_YAW", (0, 1, 0)), ("HEAD_PITCH", (1, 0, 0)), ("HEAD_ROLL", (0, 0, 1)))
EYE_NAMES = ("L", "R")


class Head:
    """A bundled head built from Candide-3 and a personality (see the module docstring)."""

    def __init__(self, candide: Candide, person) -> None:
        self.person = person
        _build_mirror(candide.vertices)
        self.candide = candide
        c = candide.vertices.copy()
        for name, w in person.shape_units.items():
            c += w * candide.shape_units[name].displacement
        for v, d in person.tweaks.items():
            c[v] += d
            if mirror(v) != v:
                c[mirror(v)] += np.asarray(d) * [-1, 1, 1]
        self.control = c
        tris = face_triangles(candide)
        s, f = subdivision_matrix(tris, len(c), LEVELS, set(SUBDIVISION_CORNERS))
        self.S, self.face_faces, keep = compact(s, f)
        self.candide_index = {int(k): i for i, k in enumerate(keep) if k < len(c)}
        self.parts: dict[str, Part] = {}
        self.face = self.S @ c
        self._build_eyes()
        self._build_cap()
        self._build_neck_and_ears()
        self._build_mouth()
        self.fapu = self._fapu()
        self._texture_coordinates()

    # ---- geometry --------------------------------------------------------------------------

    def face_point(self, v: int) -> np.ndarray:
        """Neutral position of Candide vertex ``v`` on the refined face."""
        return self.face[self.candide_index[v]]

    def _build_eyes(self) -> None:
        p = self.person
        self.eye_centre = []
        self.eye_radius = p.eye_radius
        for side in (L, R):
            up, lo = UPPER_LID[side][0], LOWER_LID[side][0]
            outer, inner = EYE_CORNERS[side]
            x = 0.5 * (self.face_point(outer)[0] + self.face_point(inner)[0]) + p.eye_shift[0] * (
                1 if side == L else -1
            )
            y = 0.5 * (self.face_point(up)[1] + self.face_point(lo)[1]) + p.eye_shift[1]
            front = max(self.face_point(up)[2], self.face_point(lo)[2]) - p.eye_depth
            self.eye_centre.append(np.array([x, y, front - self.eye_radius]))
        # an eyeball: rings of constant angle from the front pole (the pupil), one ring on the
        # pupil's edge and one on the iris's, so the texture's circles are exact and the pupil
        # can dilate by moving one ring
        self.pupil_angle, self.iris_angle = p.pupil_angle, p.iris_angle
        alphas = np.r_[
            self.pupil_angle,
            np.linspace(self.pupil_angle, self.iris_angle, 3)[1:],
            np.linspace(self.iris_angle, 0.62 * np.pi, 5)[1:],
        ]  # the back of the eyeball is never seen: it stays open
        nb = 28
        beta = np.arange(nb) * 2 * np.pi / nb
        a, b = np.meshgrid(alphas, beta, indexing="ij")
        unit = np.stack([np.sin(a) * np.cos(b), np.sin(a) * np.sin(b), np.cos(a)], axis=-1)
        unit = np.vstack([[0, 0, 1], unit.reshape(-1, 3)])
        self.eye_alpha = np.r_[0.0, a.ravel()]
        self.eye_beta = np.r_[0.0, b.ravel()]
        faces = [(0, 1 + (k + 1) % nb, 1 + k) for k in range(nb)]
        grid = grid_faces(len(alphas), nb, wrap=True) + 1
        faces = np.vstack([faces, grid[:, [0, 2, 1]]])
        # texture: azimuthal projection around the pupil into the atlas's eye tile
        uv = (
            0.5
            + 0.5
            * ((self.eye_alpha / np.pi) ** EYE_POWER)[:, None]
            * np.c_[np.cos(self.eye_beta), np.sin(self.eye_beta)]
        )
        uv = tile_uv(EYE_TILE, uv)
        for side, name in zip((L, R), EYE_NAMES, strict=True):
            pts = self.eye_centre[side] + self.eye_radius * unit
            f = outward(pts, faces, self.eye_centre[side])
            self.parts[f"{name}_EYEBALL"] = Part(f"{name}_EYEBALL", pts, f, uv, "EYE")

    def _build_cap(self) -> None:
        """The back of the head: from each vertex of the face's border a meridian runs over the
        skull ellipsoid to a pole at the back, starting exactly on the border (so the two
        meshes join) and settling onto the ellipsoid within a few rings."""
        p = self.person
        loops = boundary_loops(self.face_faces)
        border = max(loops, key=len)
        self.border = np.array(border)
        centre, axes = np.asarray(p.skull_centre), np.asarray(p.skull_axes)
        b = (self.face[self.border] - centre) / axes
        rho = np.linalg.norm(b, axis=1)
        u = b / rho[:, None]
        pole = np.array([0.0, -0.25, -1.0])
        pole /= np.linalg.norm(pole)
        k_rings = p.cap_rings
        s = np.linspace(0, 1, k_rings + 1)[1:-1] ** 0.9
        rows = []
        for sk in s:
            omega = np.arccos(np.clip(u @ pole, -1, 1))
            so = np.sin(omega)
            w0 = np.sin((1 - sk) * omega) / so
            w1 = np.sin(sk * omega) / so
            d = w0[:, None] * u + w1[:, None] * pole
            settle = smoothstep(0.0, 0.35, sk)
            r = rho + (1 - rho) * settle
            rows.append(centre + axes * (d * r[:, None]))
        # leave the border along the face's own surface (no crease at the seam): bend the first
        # rings towards the face's outward tangent at each border vertex
        nb = [[] for _ in range(len(self.face))]
        for a, b_, c_ in self.face_faces:
            nb[a] += [b_, c_]
            nb[b_] += [a, c_]
            nb[c_] += [a, b_]
        on_border = np.zeros(len(self.face), bool)
        on_border[self.border] = True
        tangent = np.array(
            [self.face[v] - self.face[[u for u in nb[v] if not on_border[u]]].mean(axis=0)
             for v in self.border]
        )  # fmt: skip
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        start = self.face[self.border]
        first = rows[0] - start
        agree = np.einsum("ij,ij->i", tangent, first / np.linalg.norm(first, axis=1)[:, None])
        agree = np.clip(agree, 0, 1) ** 2 * smoothstep(-0.45, -0.15, start[:, 1])
        agree = agree[:, None]  # only above the jaw: under the chin the face turns inwards
        for k, sk in enumerate(s):
            dist = np.linalg.norm(rows[k] - start, axis=1, keepdims=True)
            w = (1 - smoothstep(0.0, 0.22, sk)) * agree
            rows[k] = (1 - w) * rows[k] + w * (start + dist * tangent)
        # full resolution while the cap follows the face's border, every other column beyond
        n = len(border)
        fine = int(np.searchsorted(s, 0.3)) + 1  # rows 0 .. fine-1 (row 0 is the border)
        cols = np.arange(n)
        coarse = cols[::2]
        m = len(coarse)
        pts = [self.face[self.border]] + rows[: fine - 1] + [r[coarse] for r in rows[fine - 1 :]]
        index = [cols] * fine + [coarse] * (len(rows) - fine + 1)
        faces = list(grid_faces(fine, n, wrap=True))
        top = (fine - 1) * n  # first vertex of the last fine row
        low = fine * n  # first vertex of the first coarse row
        for k in range(m):
            f0, f1, f2 = top + 2 * k, top + (2 * k + 1) % n, top + (2 * k + 2) % n
            c0, c1 = low + k, low + (k + 1) % m
            faces += [(f0, c0, f1), (f1, c0, c1), (f1, c1, f2)]
        n_coarse = len(rows) - fine + 1
        faces += list(grid_faces(n_coarse, m, wrap=True) + low)
        pts = np.vstack([*pts, centre + axes * pole])
        tip = len(pts) - 1
        last = low + (n_coarse - 1) * m
        faces += [(last + (k + 1) % m, last + k, tip) for k in range(m)]
        faces = outward(pts, np.array(faces, dtype=np.int64), centre)
        follow = np.r_[1.0, (1 - smoothstep(0, 0.3, s)) ** 2]
        self.cap_border_index = np.r_[np.concatenate(index), 0]
        self.cap_follow = np.r_[np.repeat(follow[:fine], n), np.repeat(follow[fine:], m), 0.0]
        self.parts["HAIR"] = Part("HAIR", pts, faces, None, "SKIN")

    def _build_neck_and_ears(self) -> None:
        p = self.person
        ys = np.linspace(p.neck_bottom, p.neck_top, 8)
        nb = 32
        t = np.arange(nb) * 2 * np.pi / nb
        flare = 1 + 0.22 * smoothstep(p.neck_bottom + 0.35, p.neck_bottom, ys)
        pts = np.concatenate(
            [
                np.c_[
                    p.neck_radii[0] * fl * np.sin(t),
                    np.full(nb, y),
                    p.neck_centre_z + p.neck_radii[1] * fl * np.cos(t),
                ]
                for y, fl in zip(ys, flare, strict=True)
            ]
        )
        faces = grid_faces(len(ys), nb, wrap=True)
        faces = outward(pts, faces, np.array([0, pts[:, 1].mean(), p.neck_centre_z]))
        self.parts["NECK"] = Part("NECK", pts, faces, None, "SKIN")
        # ears: a flattened, slightly cupped ellipsoid on each side of the skull
        nu, nv = 12, 18
        a = np.linspace(0.04, np.pi - 0.04, nu)
        b = np.arange(nv) * 2 * np.pi / nv
        aa, bb = np.meshgrid(a, b, indexing="ij")
        h, w, d = p.ear_size
        local = np.stack(
            [d * np.sin(aa) * np.cos(bb), h * np.cos(aa), w * np.sin(aa) * np.sin(bb)], axis=-1
        ).reshape(-1, 3)
        # cup: the outer face (x > 0) is hollow in the middle
        hollow = np.exp(-((local[:, 1] / (0.55 * h)) ** 2 + (local[:, 2] / (0.5 * w)) ** 2) * 2)
        local[:, 0] -= np.where(local[:, 0] > 0, 1.4 * d * hollow, 0.0)
        local = np.vstack([local, [0, h, 0], [0, -h, 0]])
        faces = grid_faces(nu, nv, wrap=True)
        top, bottom = len(local) - 2, len(local) - 1
        faces = np.vstack(
            [
                faces,
                [(top, (k + 1) % nv, k) for k in range(nv)],
                [(bottom, (nu - 1) * nv + k, (nu - 1) * nv + (k + 1) % nv) for k in range(nv)],
            ]
        )
        ear_uv_x = 0.5 + 0.5 * local[:, 2] / w
        ear_uv_y = 0.5 + 0.5 * local[:, 1] / h
        self.ear_centre = []
        uv = tile_uv(EAR_TILE, np.c_[ear_uv_x, ear_uv_y])
        for side, name in zip((L, R), EYE_NAMES, strict=True):
            sign = 1 if side == L else -1
            rot = rotation((0, 1, 0), sign * p.ear_angle) @ rotation((1, 0, 0), -0.12)
            pts = (local * [sign, 1, 1]) @ rot.T + np.asarray(p.ear_centre) * [sign, 1, 1]
            f = faces if side == L else faces[:, [0, 2, 1]]
            cen = np.asarray(p.ear_centre) * [sign, 1, 1]
            self.ear_centre.append(cen)
            self.parts[f"{name}_EAR"] = Part(f"{name}_EAR", pts, f, uv, "SKIN")

    def _build_mouth(self) -> None:
        """Teeth along the inner lip contour, a tongue on the mouth's floor, a dark cavity."""
        p = self.person
        lip = self.face[[self.candide_index[v] for v in (87, 81, 88)]]
        y_mouth = lip[0, 1]
        # dental arch: through points behind the inner lip contour, bending back at the corners
        z0 = lip[0, 2] - p.teeth_gap
        half = 0.9 * lip[2, 0]
        arch_x = np.linspace(-1, 1, 29)
        x = half * np.sin(arch_x * np.pi / 2 * 1.0)
        z = z0 - p.arch_depth * (1 - np.cos(arch_x * np.pi / 2)) - 0.06 * arch_x**4
        xs = np.c_[x, z]
        tangent = np.gradient(xs, axis=0)
        normal = np.c_[tangent[:, 1], -tangent[:, 0]]
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        normal *= np.sign(normal[len(x) // 2, 1])  # point forward (+z) at the middle
        arc = np.r_[0, np.cumsum(np.linalg.norm(np.diff(xs, axis=0), axis=1))]
        arc /= arc[-1]

        def teeth(top: float, edge: float, back: float, lower: bool):
            # cross-section: front face from the gum down to the edge, the edge, the back face
            prof = [(0.0, top), (0.0, edge + 0.012), (-0.006, edge), (-back + 0.006, edge),
                    (-back, edge + 0.012), (-back, top)]  # fmt: skip
            if lower:
                prof = [(o, 2 * edge - yy) for o, yy in prof]
            steps = np.linalg.norm(np.diff(np.array(prof), axis=0), axis=1)
            prof_v = np.r_[0, np.cumsum(steps)] / steps.sum()
            pts, uv = [], []
            for i in range(len(x)):
                for (off, yy), pv in zip(prof, prof_v, strict=True):
                    px = xs[i] + normal[i] * off
                    pts.append((px[0], yy, px[1]))
                    uv.append((arc[i], pv * 0.5 + (0.0 if lower else 0.5)))
            pts = np.array(pts)
            faces = grid_faces(len(x), len(prof), wrap=False)
            # the front face's first triangle at the middle of the arch must face forward
            ref = faces[2 * (len(prof) - 1) * (len(x) // 2)]
            q = pts[ref]
            if np.cross(q[1] - q[0], q[2] - q[0])[2] < 0:
                faces = faces[:, [0, 2, 1]]
            return pts, faces, tile_uv(TEETH_TILE, np.array(uv))

        up_edge = y_mouth - p.teeth_show
        pts, faces, uv = teeth(up_edge + 0.13, up_edge, 0.03, False)
        self.parts["UPPER_TEETH"] = Part("UPPER_TEETH", pts, faces, uv, "TEETH")
        lo_edge = up_edge + 0.01
        pts, faces, uv = teeth(lo_edge + 0.12, lo_edge, 0.028, True)
        pts[:, 2] -= 0.026  # behind the upper teeth (overbite)
        pts[:, 0] *= 0.95
        self.parts["LOWER_TEETH"] = Part("LOWER_TEETH", pts, faces, uv, "TEETH")
        # tongue: a flattened ellipsoid on the floor of the mouth, tip behind the lower teeth
        nu, nv = 12, 16
        a = np.linspace(0, np.pi, nu)[1:-1]
        b = np.arange(nv) * 2 * np.pi / nv
        aa, bb = np.meshgrid(a, b, indexing="ij")
        tl, tw, th = p.tongue_size
        tip_z = z0 - 0.07
        tc = np.array([0.0, lo_edge - 0.062, tip_z - tl])
        local = np.stack(
            [tw * np.sin(aa) * np.cos(bb), th * np.sin(aa) * np.sin(bb), tl * np.cos(aa)], -1
        ).reshape(-1, 3)
        local = np.vstack([local, [0, 0, tl], [0, 0, -tl]])
        pts = tc + local
        faces = grid_faces(nu - 2, nv, wrap=True)
        front, back = len(pts) - 2, len(pts) - 1
        faces = np.vstack(
            [faces, [(front, k, (k + 1) % nv) for k in range(nv)],
             [(back, (nu - 3) * nv + (k + 1) % nv, (nu - 3) * nv + k) for k in range(nv)]]
        )  # fmt: skip
        faces = outward(pts, faces, tc)
        self.tongue_along = np.clip((pts[:, 2] - (tc[2] - tl)) / (2 * tl), 0, 1)  # 0 back, 1 tip
        self.tongue_centre = tc
        tuv = tile_uv(TONGUE_TILE, np.c_[0.5 + 0.5 * local[:, 0] / tw, self.tongue_along])
        self.parts["TONGUE"] = Part("TONGUE", pts, faces, tuv, "TONGUE")
        # the cavity: a bowl open to the front, behind the lips
        cav_c = np.array([0.0, y_mouth - 0.06, lip[2, 2] - 0.09])
        ax = np.array([lip[2, 0] + 0.04, 0.17, 0.3])
        psi = np.linspace(0, np.pi / 2 + 0.05, 8)
        phi = np.arange(24) * 2 * np.pi / 24
        pp, ff = np.meshgrid(psi, phi, indexing="ij")
        pts = cav_c + ax * np.stack(
            [np.sin(pp) * np.cos(ff), np.sin(pp) * np.sin(ff), -np.cos(pp)], -1
        ).reshape(-1, 3)
        faces = grid_faces(len(psi), len(phi), wrap=True)
        self.parts["MOUTH"] = Part("MOUTH", pts, faces, None, "MOUTH", solid=False)
        self.cavity_jaw = smoothstep(cav_c[1] + 0.08, cav_c[1] - 0.08, pts[:, 1])
        # eye sockets: bowls behind the eyeballs, so nothing shows beside them
        sock = []
        sfaces = []
        for side in (L, R):
            c = self.eye_centre[side]
            rad = self.eye_radius * np.array([1.25, 1.1, 1.0])
            psi = np.linspace(0, np.pi / 2 + 0.15, 6)
            pp, ff = np.meshgrid(psi, phi, indexing="ij")
            pts = c + rad * np.stack(
                [np.sin(pp) * np.cos(ff), np.sin(pp) * np.sin(ff), -np.cos(pp)], -1
            ).reshape(-1, 3)
            sfaces.append(grid_faces(len(psi), len(phi), wrap=True) + sum(len(s) for s in sock))
            sock.append(pts)
        self.parts["SOCKETS"] = Part(
            "SOCKETS", np.vstack(sock), np.vstack(sfaces), None, "SOCKET", solid=False
        )

    def _texture_coordinates(self) -> None:
        """The skin chart for face, back of the head and neck (one continuous unwrap)."""
        p = self.person
        self.skin_y_range = (p.neck_bottom, p.skull_centre[1] + p.skull_axes[1])
        self.parts["FACE"] = Part("FACE", self.face, self.face_faces, None, "SKIN")
        self.skin_uv = {}
        # the eyelids' skin is charted where it lies when the lids are mostly closed, so that
        # a closing lid stretches a real stretch of texture, not the sliver it covers when open
        chart = {"FACE": self.realize(State(lids=np.array([650.0, 650, 250, 250]))).points["FACE"]}
        for name in ("FACE", "HAIR", "NECK"):
            part = self.parts[name]
            uv = skin_chart(chart.get(name, part.points), p.skull_centre[2], self.skin_y_range)
            self.skin_uv[name] = uv
            part.texcoords, tex_faces = seam_split(uv, part.faces)
            if not np.array_equal(tex_faces, part.faces):
                part.tex_faces = tex_faces

    def _fapu(self) -> Fapu:
        return Fapu.from_feature_points(self.feature_positions())

    def feature_positions(self) -> dict[str, np.ndarray]:
        pts = {k: self.face_point(v) for k, v in FEATURE_VERTICES.items()}
        for side, k in ((L, "3.5"), (R, "3.6")):
            pts[k] = self.parts[f"{EYE_NAMES[side]}_EYEBALL"].points[0]
        return pts

    def feature_points(self) -> list[tuple[str, str, int]]:
        """(feature point, IndexedFaceSet, vertex) for the ``#FeaturePoints`` section."""
        out = [(k, "FACE", self.candide_index[v]) for k, v in FEATURE_VERTICES.items()]
        out += [("3.5", "L_EYEBALL", 0), ("3.6", "R_EYEBALL", 0)]
        return sorted(out, key=lambda t: tuple(int(x) for x in t[0].split(".")))

    # ---- deformation -------------------------------------------------------------------------

    def jaw_motion(self, jaw: np.ndarray, pts: np.ndarray) -> np.ndarray:
        """Displacement ``(n, 3)`` of ``pts`` under the rigid jaw motion: open_jaw rotates about
        the jaw joint with a forward glide of the condyle, thrust_jaw and shift_jaw
        translate."""
        p = self.person
        opening, thrust, shift = jaw
        pivot = np.asarray(p.jaw_pivot)
        chin = self.face_point(10)
        # open_jaw is in MNS: the chin (2.1) drops by MNS per unit at the start of the motion
        angle = opening * self.fapu.mns / (chin[2] - pivot[2])
        rot = rotation((1, 0, 0), angle)
        moved = (pts - pivot) @ rot.T + pivot
        glide = np.array([0.0, -0.05, p.jaw_glide]) * angle
        return moved - pts + glide + [-shift * self.fapu.mw, 0.0, thrust * self.fapu.mns]

    def lid_positions(self, lids: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Candide control points ``c`` with the eyelids moved for FAPs 19–22 (IRISD): each lid
        vertex slides over a sphere about the eyeball's centre, down (or up) by the fraction
        value/1024 of the gap to its opposite lid — 1024 closes the eye, as MPEG-4 defines
        IRISD. Upper lids ride slightly outside, lower lids slightly inside, so when both close
        the lower one tucks behind the upper one."""
        out = c.copy()
        for side in (L, R):
            centre = self.eye_centre[side]
            for k, (up, lo) in enumerate(zip(UPPER_LID[side], LOWER_LID[side], strict=True)):
                gap = c[up, 1] - c[lo, 1]
                for v, value, sign, push in (
                    (up, lids[side], -1.0, self.person.lid_push),
                    (lo, lids[2 + side], 1.0, -self.person.lid_push),
                ):
                    frac = value / 1024.0
                    if frac == 0:
                        continue
                    # the middle vertex travels the whole gap; the side ones a little less,
                    # following the lid's curve
                    travel = gap * (1.06 if k == 0 else 1.04)
                    y = c[v, 1] + sign * frac * travel
                    r0 = np.linalg.norm(c[v] - centre)
                    r = r0 + push * min(abs(frac), 1.0)
                    dx = c[v, 0] - centre[0]
                    dz2 = r * r - dx * dx - (y - centre[1]) ** 2
                    z = centre[2] + np.sqrt(max(dz2, 1e-8))
                    out[v] = (c[v, 0], y, z)
        return out

    def tongue_motion(self, t: np.ndarray, pts: np.ndarray) -> np.ndarray:
        """Displacement of the tongue for FAPs 43–47 (shift, raise and thrust the tip, raise
        the body, roll the sides up)."""
        shift, raise_tip, thrust, raise_all, roll = t
        f = self.fapu
        tip = smoothstep(0.35, 1.0, self.tongue_along)[:, None]
        body = (1 - 0.5 * self.tongue_along)[:, None]
        d = tip * np.array([-shift * f.mw, raise_tip * f.mns, thrust * f.mw])
        d = d + body * np.array([0.0, raise_all * f.mns, 0.0])
        x = pts[:, 0] - self.tongue_centre[0]
        d[:, 1] += np.abs(x) * roll * 1e-5 * (0.4 + 0.6 * self.tongue_along)
        return d

    def realize(self, st: State) -> Posed:
        """The posed scene for a state."""
        c = self.control + st.candide
        c = self.lid_positions(st.lids, c)
        w = np.zeros(len(c))
        for v, wt in JAW_WEIGHTS.items():
            w[v] = wt
        if np.any(st.jaw):
            c = c + w[:, None] * self.jaw_motion(st.jaw, self.control)
        face = self.S @ c
        pts: dict[str, np.ndarray] = {"FACE": face}
        hair = self.parts["HAIR"]
        moved = face[self.border] - self.face[self.border]
        pts["HAIR"] = hair.points + moved[self.cap_border_index] * self.cap_follow[:, None]
        for name in ("LOWER_TEETH", "TONGUE", "MOUTH"):
            pts[name] = self.parts[name].points.copy()
        pts["TONGUE"] = pts["TONGUE"] + self.tongue_motion(st.tongue, pts["TONGUE"])
        if np.any(st.jaw):
            for name in ("LOWER_TEETH", "TONGUE"):
                pts[name] = pts[name] + self.jaw_motion(st.jaw, pts[name])
            cav = pts["MOUTH"]
            pts["MOUTH"] = cav + self.cavity_jaw[:, None] * self.jaw_motion(st.jaw, cav)
        for side, name in enumerate(EYE_NAMES):
            eb = self.parts[f"{name}_EYEBALL"].points.copy()
            dil = st.eyes[side, 3]
            if dil:
                # the pupil's ring slides outwards over the sphere: the pupil's diameter grows
                # by IRISD per unit
                ring = np.isclose(self.eye_alpha, self.pupil_angle)
                a = self.pupil_angle + dil * self.fapu.irisd / 2 / self.eye_radius
                b = self.eye_beta[ring]
                u = np.c_[np.sin(a) * np.cos(b), np.sin(a) * np.sin(b), np.full(len(b), np.cos(a))]
                eb[ring] = self.eye_centre[side] + self.eye_radius * u
            pts[f"{name}_EYEBALL"] = eb
            ear = self.parts[f"{name}_EAR"].points
            sign = 1 if side == L else -1
            pts[f"{name}_EAR"] = ear + [
                sign * st.ears[side, 1] * self.fapu.ens,
                st.ears[side, 0] * self.fapu.ens,
                0.0,
            ]
        tr: dict[str, dict[str, np.ndarray]] = {}
        for (name, axis), angle in zip(HEAD_TRANSFORMS, st.head[[1, 0, 2]], strict=True):
            tr[name] = {"rotation": np.r_[axis, angle * 1e-5]}
        for side, name in enumerate(EYE_NAMES):
            yaw, pitch, thrust, _ = st.eyes[side]
            tr[f"{name}_EYE"] = {"translation": np.array([0.0, 0.0, thrust * self.fapu.es])}
            tr[f"{name}_EYE_YAW"] = {"rotation": np.array([0, 1, 0, yaw * 1e-5])}
            tr[f"{name}_EYE_PITCH"] = {"rotation": np.array([1, 0, 0, pitch * 1e-5])}
        return Posed(pts, tr)

    def neutral(self) -> Posed:
        return self.realize(State())

    # ---- FAPs as the modeler sculpts them --------------------------------------------------

    def fap_state(self, number: int, value: float) -> State:
        """The state of one low-level FAP at ``value`` (its own units)."""
        st = State()
        if value == 0:
            return st
        if 19 <= number <= 22:
            st.lids[number - 19] = value
        elif number in (3, 14, 15):
            st.jaw[{3: 0, 14: 1, 15: 2}[number]] = value
        elif 43 <= number <= 47:
            st.tongue[number - 43] = value
        elif 23 <= number <= 30:
            side = (number - 23) % 2
            kind = (number - 23) // 2  # yaw, pitch, thrust, dilate
            st.eyes[side, kind] = value
        elif 48 <= number <= 50:
            st.head[number - 48] = value
        elif 65 <= number <= 68:
            side = (number - 65) % 2
            st.ears[side, (number - 65) // 2] = value
        else:
            region, unit = skin_field(number, mirror)
            st.candide = region * value * getattr(self.fapu, unit)
        return st


# ---- recipes: visemes and expressions as the modeler dials them in ---------------------------


def recipe_state(head: Head, recipe) -> State:
    """The state of a viseme or expression recipe: FAP values through the head's own FAP
    deformations plus Candide's regional animation units."""
    st = State()
    for number, value in recipe.faps.items():
        st = st + head.fap_state(number, value)
    for name, weight in recipe.au.items():
        st.candide = st.candide + weight * head.candide.au(name)
    return st


# ---- exports -----------------------------------------------------------------------------------

#: The deformed exports of each low-level FAP: the amplitudes (FAP units) of its phases.
#: Linear motions need one; the eyelids close in two phases (half, fully) and open wider below
#: 0; the jaw swings on an arc; the pupil's ring slides over the sphere.
FAP_PHASES: dict[int, tuple[float, ...]] = {
    **{n: (1000.0,) for n in range(4, 69)},
    3: (500.0, 1000.0),
    **{n: (-256.0, 512.0, 1024.0) for n in (19, 20, 21, 22)},
    **{n: (100000.0,) for n in (23, 24, 25, 26, 48, 49, 50)},
    29: (-300.0, 300.0),
    30: (-300.0, 300.0),
    47: (50000.0,),
}


def exports(head: Head) -> list[tuple[str, State]]:
    """Every deformed export the ADI needs: ``(NAME@AMPLITUDE, state)``."""
    out = []
    faps = sorted({*SKIN_FAPS, 3, 14, 15, *range(19, 31), *range(43, 51), *range(65, 69)})
    for number in faps:
        for amp in FAP_PHASES[number]:
            out.append((f"{fap(number).name}@{_num(amp)}", head.fap_state(number, amp)))
    for v, recipe in sorted(head.person.visemes.items()):
        out.append((f"viseme{v}@1", recipe_state(head, recipe)))
    for name, recipe in head.person.expressions.items():
        out.append((f"{name}@1", recipe_state(head, recipe)))
    return out


def _num(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else repr(float(x))


def fmt(a: np.ndarray, decimals: int = 5) -> np.ndarray:
    """Numbers as short fixed-point text (``0.25``, ``-1``, ``0``), rounded to ``decimals``."""
    a = np.round(np.asarray(a, dtype=np.float64), decimals) + 0.0
    # str's % per number: numpy's char.mod makes the same text, several times slower
    form = f"%.{decimals}f"
    words = [(form % x).rstrip("0").rstrip(".") for x in a.ravel().tolist()]
    return np.array([w if w not in ("-0", "") else "0" for w in words], dtype=str).reshape(a.shape)


#: Trailing zeros of a "%.Nf" number's fraction, then a point left with no fraction.
_ZEROS = re.compile(r"0+(?=[ ,\n]|$)")
_BARE_POINT = re.compile(r"\.(?=[ ,\n]|$)")


def fmt_rows(a: np.ndarray, decimals: int = 5, sep: str = ",\n") -> str:
    """The rows of ``a`` (``(n, k)``, or one row ``(k,)``) as :func:`fmt` writes their numbers,
    space-separated, rows joined by ``sep``: one %-format per row and two trims over the whole
    text (the exports' text took 3.5 s a head number by number)."""
    a = np.round(np.asarray(a, dtype=np.float64), decimals) + 0.0
    rows = a.reshape(1, -1) if a.ndim == 1 else a
    if not rows.size:
        return "" if a.ndim == 1 else sep.join("" for _ in range(rows.shape[0]))
    row_format = " ".join([f"%.{decimals}f"] * rows.shape[1])
    text = sep.join([row_format % tuple(row) for row in rows.tolist()])
    return _BARE_POINT.sub("", _ZEROS.sub("", text))  # no "-0": rounded numbers plus 0.0


def fmt_faces(f: np.ndarray) -> str:
    return "\n".join(f"{a} {b} {c} -1" for a, b, c in f.tolist())


class SceneWriter:
    """Writes the head's scene (Figure 11) with any pose's points and Transform fields. The
    parts that do not change between poses keep their text."""

    APPEARANCES = {
        "SKIN": "material Material {{ diffuseColor 1 1 1 shininess 0.12 }}\n"
        '      texture ImageTexture {{ url "{url}" }}',
        "EYE": "material Material {{ diffuseColor 1 1 1 shininess 0.75 "
        "specularColor 0.6 0.6 0.6 }}\n"
        '      texture ImageTexture {{ url "{url}" }}',
        "TEETH": "material Material {{ diffuseColor 0.95 0.95 0.95 shininess 0.4 }}\n"
        '      texture ImageTexture {{ url "{url}" }}',
        "TONGUE": "material Material {{ diffuseColor 0.9 0.9 0.9 shininess 0.45 }}\n"
        '      texture ImageTexture {{ url "{url}" }}',
        "MOUTH": "material Material {{ diffuseColor 0.11 0.025 0.03 shininess 0 }}",
        "SOCKET": "material Material {{ diffuseColor 0.5 0.26 0.24 shininess 0.3 }}",
    }
    CREASE = {"UPPER_TEETH": 1.0, "LOWER_TEETH": 1.0}
    #: Parts in the head's Transform, in file order; eyeballs go under their eye Transforms.
    ORDER = ("FACE", "HAIR", "NECK", "L_EAR", "R_EAR", "MOUTH", "UPPER_TEETH", "LOWER_TEETH",
             "TONGUE", "SOCKETS")  # fmt: skip

    def __init__(self, head: Head, texture_url: str, world_info: list[tuple[str, list[str]]]):
        self.head = head
        self.url = texture_url
        self.world_info = world_info
        self.neutral = head.neutral()
        self._static = {n: self._ifs_tail(p) for n, p in head.parts.items()}
        self._points = {n: fmt_rows(p) for n, p in self.neutral.points.items()}
        self._points.update(
            {n: fmt_rows(p.points) for n, p in head.parts.items() if n not in self._points}
        )

    def _ifs_tail(self, part: Part) -> str:
        lines = [f"      coordIndex [\n{fmt_faces(part.faces)}\n      ]"]
        if part.texcoords is not None:
            lines.append(
                "      texCoord TextureCoordinate { point [\n"
                f"{fmt_rows(part.texcoords, 5)}\n      ] }}"
            )
            if part.tex_faces is not None:
                lines.append(f"      texCoordIndex [\n{fmt_faces(part.tex_faces)}\n      ]")
        lines.append(f"      creaseAngle {self.CREASE.get(part.name, 3.2)}")
        if not part.solid:
            lines.append("      solid FALSE")
        return "\n".join(lines)

    def _shape(self, name: str, points: np.ndarray | None, used: set[str]) -> str:
        part = self.head.parts[name]
        app = part.appearance
        if app in used:
            appearance = f"USE {app}"
        else:
            used.add(app)
            appearance = (
                f"DEF {app} Appearance {{\n      "
                + self.APPEARANCES[app].format(url=self.url)
                + "\n    }"
            )
        if points is None or np.array_equal(points, self.neutral.points.get(name, part.points)):
            text = self._points[name]
        else:
            text = fmt_rows(points)
        return (
            f"Shape {{\n    appearance {appearance}\n    geometry DEF {name} IndexedFaceSet {{\n"
            f"      coord Coordinate {{ point [\n{text}\n      ] }}\n"
            f"{self._static[name]}\n    }}\n  }}"
        )

    def text(self, posed: Posed, comment: str) -> str:
        h = self.head
        out = ["#VRML V2.0 utf8", f"# {comment}"]
        for title, info in self.world_info:
            strings = ",\n  ".join(f'"{s}"' for s in info)
            out.append(f'WorldInfo {{\n  title "{title}"\n  info [\n  {strings}\n  ]\n}}')
        used: set[str] = set()
        pivot = " ".join(fmt(np.asarray(h.person.head_pivot)).tolist())
        opening = []
        for name, _ in HEAD_TRANSFORMS:
            rot = " ".join(fmt(posed.transforms[name]["rotation"], 9).tolist())
            opening.append(
                f"DEF {name} Transform {{\n  center {pivot}\n  rotation {rot}\n  children ["
            )
        body = [self._shape(n, posed.points.get(n), used) for n in self.ORDER]
        for side, e in enumerate(EYE_NAMES):
            c = " ".join(fmt(h.eye_centre[side]).tolist())
            t = posed.transforms
            tr = " ".join(fmt(t[f"{e}_EYE"]["translation"], 9).tolist())
            yaw = " ".join(fmt(t[f"{e}_EYE_YAW"]["rotation"], 9).tolist())
            pitch = " ".join(fmt(t[f"{e}_EYE_PITCH"]["rotation"], 9).tolist())
            ball = self._shape(f"{e}_EYEBALL", posed.points.get(f"{e}_EYEBALL"), used)
            body.append(
                f"DEF {e}_EYE Transform {{\n  translation {tr}\n  children [\n"
                f"DEF {e}_EYE_YAW Transform {{\n  center {c}\n  rotation {yaw}\n  children [\n"
                f"DEF {e}_EYE_PITCH Transform {{\n  center {c}\n  rotation {pitch}\n"
                f"  children [\n  {ball}\n  ]\n}}\n  ]\n}}\n  ]\n}}"
            )
        out += opening
        out.append("  " + "\n  ".join(body))
        out.append("\n".join("  ]\n}" for _ in HEAD_TRANSFORMS))
        return "\n".join(out) + "\n"
