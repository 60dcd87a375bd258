"""Where the landmark detector's points lie on the bundled heads' FACE (the table
``vtts/data/fit/face_landmarks.tsv`` that ``adi fit`` reads).

usage: python models/src/landmark_map.py [--out PATH]

The bundled heads are rendered from several directions (yaw and pitch up to ±15°), the detector
(:mod:`vtts.fit.landmarks`) finds its 468 landmarks on each rendering, and each landmark's pixel
is traced back to the point of ``FACE`` it shows (the renderer's triangle numbers and the pixel's
ray). The points are carried to cybatt's neutral face through their triangles and barycentric
weights (all heads share FACE's topology), their median over views and heads is taken, and the
nearest point of cybatt's FACE gives the landmark's triangle and weights. Landmarks on the face's
outline (``FACE_OVAL``) slide over the surface as the head turns: only the frontal views count
for them and the fit weighs them less. Landmarks that fall off FACE (onto the back of the head)
are left out.

Deterministic: the renderer and the detector give the same numbers run to run.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]

from vtts import load_model  # noqa: E402
from vtts.fit.generic import LANDMARK_TABLE  # noqa: E402
from vtts.fit.landmarks import FACE_OVAL, MediaPipeDetector  # noqa: E402
from vtts.mesh import ray_barycentrics  # noqa: E402
from vtts.render import FaceRenderer  # noqa: E402
from vtts.render.camera import Camera, look_at  # noqa: E402
from vtts.vrml import triangulate  # noqa: E402

HEADS = ("cybatt", "lotta")
SIZE = 512
#: (yaw, pitch) in degrees of the views.
#: A landmark whose pixel shows another part (an eyeball at the eye's corner, the back of the
#: head at the outline) counts when FACE is at most this far (model units; the face is about 1.2
#: wide).
MAX_OFF_FACE = 0.04
#: The same for the outline's landmarks, which the detector puts on the silhouette: under the
#: chin and at the temples that is the neck or the back of the head, next to FACE's border.
MAX_OFF_FACE_OVAL = 0.15
OVAL = frozenset(FACE_OVAL)
VIEWS = [(y, p) for p in (-10, 0, 10) for y in (-15, 0, 15)]


def views_of(name: str, detector) -> list[tuple[int, int, np.ndarray, np.ndarray]]:
    """For each view: (yaw, pitch, FACE vertex ids (468, 3) or -1, barycentrics (468, 3))."""
    model = load_model(name)
    face_pts = model.neutral_points("FACE")
    tm = triangulate(model.scene.node("FACE"))
    surface = Surface(face_pts, tm.coord_index[tm.faces])
    lo, hi = face_pts.min(axis=0), face_pts.max(axis=0)
    target = (lo + hi) / 2
    f = SIZE * 1.4
    out = []
    for yaw, pitch in VIEWS:
        a, b = math.radians(yaw), math.radians(pitch)
        dist = 6.0
        eye = target + dist * np.array([math.sin(a) * math.cos(b), math.sin(b),
                                        math.cos(a) * math.cos(b)])  # fmt: skip
        cam = Camera(f, f, SIZE / 2, SIZE / 2, look_at(eye, target), znear=0.5, zfar=20)
        with FaceRenderer(model, size=(SIZE, SIZE), camera=cam) as r:
            # the renderer centres the model in its world: look through cam from there
            r.set_view(dataclasses.replace(cam, pose=r.model_matrix(0) @ cam.pose))
            img, numbers = r.render(model.params(), triangles=True)
            sets = r.triangle_sets
        faces = detector.detect(img)
        if not faces:
            print(f"{name} {yaw:+d}/{pitch:+d}: no face found", file=sys.stderr)
            continue
        lm = faces[0].landmarks[:, :2]
        col = np.clip(lm[:, 0].astype(int), 0, SIZE - 1)
        row = np.clip(lm[:, 1].astype(int), 0, SIZE - 1)
        num = numbers[row, col]
        # the 3-D point each landmark's pixel shows, on whatever part it falls
        hit = np.full((len(lm), 3), np.nan)
        on_face = np.zeros(len(lm), bool)
        for node, first, count in sets:
            sel = (num >= first) & (num < first + count)
            if not sel.any():
                continue
            tm = triangulate(node)  # neutral: every Transform above a part is the identity
            tri = tm.faces[num[sel] - first]
            lam, _ = ray_barycentrics(lm[sel], cam, tm.positions[tri])
            hit[sel] = np.einsum("ij,ijk->ik", lam, tm.positions[tri])
            if node.name == "FACE":
                on_face[sel] = True
        ids = np.full((len(lm), 3), -1)
        bary = np.zeros((len(lm), 3))
        for j in np.flatnonzero(~np.isnan(hit[:, 0])):
            v, w = surface.nearest(hit[j])
            limit = MAX_OFF_FACE_OVAL if j in OVAL else MAX_OFF_FACE
            if on_face[j] or np.linalg.norm(w @ face_pts[v] - hit[j]) < limit:
                ids[j], bary[j] = v, w
        out.append((yaw, pitch, ids, bary))
    return out


class Surface:
    """A triangle mesh to find the points nearest to others on: ``points (n, 3)`` and ``faces (m,
    3)`` vertex ids, with each vertex's triangles listed once for all."""

    def __init__(self, points: np.ndarray, faces: np.ndarray) -> None:
        self.points, self.faces = points, faces
        # each vertex's rows of faces, ascending: the vertex ids sorted, stable
        order = np.argsort(faces.ravel(), kind="stable")
        counts = np.bincount(faces.ravel(), minlength=len(points))
        self.around = np.split(order // faces.shape[1], np.cumsum(counts)[:-1])

    def nearest(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The triangle ``(3,)`` vertex ids and barycentric weights ``(3,)`` of the point of the
        mesh nearest ``p`` (``p`` lies on or near the surface: the triangles around its four
        nearest vertices are searched)."""
        points = self.points
        d = np.linalg.norm(points - p, axis=1)
        part = np.argpartition(d, 4)
        nearest = part[:4]
        if d[nearest].max() >= d[part[4]]:  # a tie at the fourth: broken as argsort breaks it
            nearest = np.argsort(d)[:4]
        cand = self.faces[np.unique(np.concatenate([self.around[v] for v in nearest]))]
        w = trimesh.triangles.points_to_barycentric(points[cand], np.repeat(p[None], len(cand), 0))
        w = np.clip(w, 0, None)
        w /= w.sum(axis=1, keepdims=True)
        q = np.einsum("ij,ijk->ik", w, points[cand])
        d = np.linalg.norm(q - p, axis=1)
        # a point on an edge or a vertex lies in several triangles at the same distance, to
        # rounding that varies from run to run: of those, the triangle with the smallest vertex
        # ids
        ties = np.flatnonzero(d <= d.min() + 1e-9 * max(1.0, float(np.abs(p).max())))
        best = int(ties[np.lexsort(np.sort(cand[ties], axis=1).T[::-1])[0]])
        return cand[best], w[best]


def build(out: Path) -> None:
    detector = MediaPipeDetector()
    reference = load_model("cybatt").neutral_points("FACE")
    tm = triangulate(load_model("cybatt").scene.node("FACE"))
    ref_surface = Surface(reference, tm.coord_index[tm.faces])
    oval = np.zeros(468, bool)
    oval[list(FACE_OVAL)] = True
    samples: list[list[np.ndarray]] = [[] for _ in range(468)]
    for name in HEADS:
        for yaw, pitch, ids, bary in views_of(name, detector):
            for j in range(468):
                if ids[j, 0] < 0 or (oval[j] and (yaw, pitch) != (0, 0)):
                    continue
                samples[j].append(bary[j] @ reference[ids[j]])
    rows = []
    for j in range(468):
        if len(samples[j]) < 2:
            continue
        pts = np.array(samples[j])
        p = np.median(pts, axis=0)
        spread = float(np.median(np.linalg.norm(pts - p, axis=1)))
        v, w = ref_surface.nearest(p)
        rows.append(f"{j}\t{v[0]}\t{v[1]}\t{v[2]}\t{w[0]:.6f}\t{w[1]:.6f}\t{w[2]:.6f}\t"
                    f"{'oval' if oval[j] else 'inner'}\t{spread:.4f}")  # fmt: skip
    header = (
        "# Where MediaPipe's face-mesh landmarks lie on the bundled heads' FACE "
        "(models/src/landmark_map.py)\n"
        "# spread: median distance of the views' points from the chosen one (model units)\n"
        "# landmark\tv0\tv1\tv2\tw0\tw1\tw2\tgroup\tspread\n"
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(header + "\n".join(rows) + "\n", encoding="utf-8")
    print(f"{out}: {len(rows)} of 468 landmarks mapped")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "vtts" / "data" / LANDMARK_TABLE)
    args = ap.parse_args(argv)
    build(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
