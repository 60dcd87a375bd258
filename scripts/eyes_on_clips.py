"""The iris model over the development clips: lid openings, closures and gaze, per clip.

For every frame of each clip: the face mesh (:class:`vtts.fit.landmarks.MediaPipeDetector`),
then the iris model on both eyes (:class:`vtts.fit.iris.IrisModel`, one thread). Prints per
clip the lid opening (middles of the upper and lower lids, over the eye's width) by the iris
model and by the face mesh (landmarks 159/145, 386/374), the runs of frames where the iris
model's opening falls under half its 90th percentile (blinks, eyes cast down), the iris
centre's place in the eye (from the corners' middle, in eye widths) and the iris model's CPU
time a frame.

``--solve`` also fits a head to each clip's first frame and, per frame, places it on the face
mesh (:func:`~vtts.analysis.landmark_pose.landmark_pose`, the eye FAPs held at zero) and solves
FAPs 19–26 alone on the eye observations of :mod:`vtts.analysis.eyes` (a few Gauss–Newton
steps; the pupils weighted by :attr:`~vtts.fit.iris.Eye.visible`, the lid points across the
eye, a weak pull to zero): the FAPs at the ``--frames`` asked for. ``--draw DIR`` writes those
frames' eyes, the iris model's points drawn, as ``DIR/CLIP_eyes.png``.

Only the development clips: the set-aside ones (lp_d9, lp_d18, lp_d20) are refused.

usage: .venv/bin/python scripts/eyes_on_clips.py [CLIP ...] [--solve] [--frames N ...]
       [--draw DIR]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
VIDEOS = ROOT / "tests" / "data" / "video"
DEVELOPMENT = ("akiyo_cif", "carphone_qcif", "lp_d0", "lp_d3", "lp_d12", "lp_d13")
SET_ASIDE = ("lp_d9", "lp_d18", "lp_d20")
EYE_FAPS = (19, 20, 21, 22, 23, 24, 25, 26)
UNKNOWNS = (*EYE_FAPS, 48, 49, 50, "tx", "ty", "tz")
PRIOR = 20000.0  # units of an eye FAP worth one pixel of residual


def place_in_eye(name: str, eye) -> np.ndarray:
    """``(2,)`` the iris centre from the middle of the eye's corners, in eye widths: along the
    corners' line (towards the image's right on an upright face) and across it (down)."""
    first, second = (eye.contour[0, :2], eye.contour[8, :2])[:: 1 if name == "right" else -1]
    along = second - first
    width = np.linalg.norm(along)
    u = along / width
    r = eye.centre - (first + second) / 2
    return np.array([r @ u, r @ np.array([-u[1], u[0]])]) / width


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    edges = np.diff(np.r_[0, mask.astype(int), 0])
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def solver(frame: np.ndarray, detector):
    """A function that solves the eye FAPs of one frame on a head fitted to ``frame``."""
    from vtts.analysis import Estimator
    from vtts.analysis.eyes import eye_points
    from vtts.analysis.landmark_pose import landmark_pose
    from vtts.fit import fit_photo

    head = fit_photo(frame, detector=detector)
    model = head.model(Path(tempfile.mkdtemp()))
    h, w = frame.shape[:2]
    est = Estimator(model, size=(w, h), model_camera=head.shape.camera, unknowns=UNKNOWNS)
    points = eye_points(est)
    slots = np.array(EYE_FAPS) - 1

    def solve(landmarks: np.ndarray, eyes) -> np.ndarray:
        held = est.params[slots].copy()
        est.params[slots] = 0.0  # landmark_pose takes 3.5/3.6 as the eye opening's middle
        landmark_pose(est, landmarks)
        est.params[slots] = held
        pupils, lids = points.targets(eyes)
        normals = points.lid_normals(eyes)
        weights = np.r_[np.repeat([eyes.right.visible, eyes.left.visible], 2), np.ones(len(lids))]
        for _ in range(4):
            xp, jp = points.pupils.project(est)
            xl, jl = points.lids.project(est)
            jl = np.einsum("nd,ndk->nk", normals, jl.reshape(len(lids), 2, -1))
            residual = np.r_[(pupils - xp).ravel(), ((lids - xl) * normals).sum(1)] * weights
            jac = np.vstack([jp, jl])[:, : len(EYE_FAPS)] * weights[:, None]
            a = np.vstack([jac, np.eye(len(EYE_FAPS)) / PRIOR])
            b = np.r_[residual, -est.params[slots] / PRIOR]
            est.params[slots] += np.linalg.lstsq(a, b, rcond=None)[0]
        return est.params[slots].copy()

    return solve


def draw(frames: dict[int, np.ndarray], found: dict[int, tuple], out: Path) -> None:
    from PIL import Image, ImageDraw

    tiles = []
    for i, image in frames.items():
        eyes, landmarks = found[i]
        lids = np.concatenate([eyes.right.lids, eyes.left.lids])
        lo, hi = lids.min(0), lids.max(0)
        half = 0.75 * (hi[0] - lo[0])
        cx, cy = (lo + hi) / 2
        box = tuple(round(v) for v in (cx - half, cy - 0.45 * half, cx + half, cy + 0.45 * half))
        k = 640 / (box[2] - box[0])
        tile = Image.fromarray(image).crop(box)
        tile = tile.resize((640, round(tile.height * k)), Image.Resampling.BICUBIC)
        pen = ImageDraw.Draw(tile)

        def at(p, box=box, k=k):
            return (p[0] - box[0]) * k, (p[1] - box[1]) * k

        for _, eye in eyes:
            for p in eye.lids:
                x, y = at(p)
                pen.ellipse([x - 3, y - 3, x + 3, y + 3], outline=(0, 255, 0))
            x, y = at(eye.centre)
            r = eye.radius * k
            pen.ellipse([x - r, y - r, x + r, y + r], outline=(255, 0, 0))
        for j in (159, 145, 386, 374):  # the face mesh's lid middles
            x, y = at(landmarks[j])
            pen.rectangle([x - 3, y - 3, x + 3, y + 3], outline=(0, 160, 255))
        pen.text((5, 5), f"frame {i}", fill=(255, 255, 0))
        tiles.append(tile)
    sheet = Image.new("RGB", (640, sum(t.height for t in tiles)))
    y = 0
    for tile in tiles:
        sheet.paste(tile, (0, y))
        y += tile.height
    sheet.save(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("clips", nargs="*", default=list(DEVELOPMENT))
    parser.add_argument("--solve", action="store_true")
    parser.add_argument("--frames", type=int, nargs="*", default=[])
    parser.add_argument("--draw", type=Path)
    args = parser.parse_args()
    for clip in args.clips:
        if clip in SET_ASIDE or clip not in DEVELOPMENT:
            parser.error(f"{clip}: not a development clip ({', '.join(DEVELOPMENT)})")

    from vtts.analysis.video import read_video
    from vtts.fit.iris import IrisModel
    from vtts.fit.landmarks import MediaPipeDetector

    detector, iris = MediaPipeDetector(), IrisModel(threads=1)
    for clip in args.clips:
        opening, mesh, place, faps, cpu = [], [], [], {}, []
        shown, found, solve = {}, {}, None
        for i, frame in enumerate(read_video(VIDEOS / f"{clip}.mp4").frames()):
            faces = detector.detect(frame)
            if not faces:
                continue
            landmarks = faces[0].landmarks
            c0 = time.process_time()
            eyes = iris.eyes(frame, landmarks)
            cpu.append(time.process_time() - c0)
            width = np.mean([eyes.right.width, eyes.left.width])
            opening.append(np.mean([eyes.right.opening, eyes.left.opening]) / width)
            lids = landmarks[[159, 386], :2] - landmarks[[145, 374], :2]  # the mesh's middles
            mesh.append(np.linalg.norm(lids, axis=1).mean() / width)
            place.append(np.mean([place_in_eye(n, e) for n, e in eyes], axis=0))
            if args.solve:
                solve = solve or solver(frame, detector)
                values = solve(landmarks, eyes)
                if i in args.frames:
                    faps[i] = values
            if i in args.frames:
                shown[i], found[i] = frame, (eyes, landmarks)
        opening, mesh, place = np.array(opening), np.array(mesh), np.array(place)
        closed = runs(opening < 0.5 * np.percentile(opening, 90))
        print(
            f"{clip}: {len(opening)} frames; opening / eye width: iris model median "
            f"{np.median(opening):.3f} min {opening.min():.3f}, face mesh median "
            f"{np.median(mesh):.3f} min {mesh.min():.3f}; under half: {closed}; iris centre "
            f"along the eye p5–p95 {np.percentile(place[:, 0], 5):+.3f} to "
            f"{np.percentile(place[:, 0], 95):+.3f} eye widths; iris model CPU "
            f"{np.median(cpu) * 1e3:.2f} ms a frame"
        )
        for i, values in sorted(faps.items()):
            pairs = zip(EYE_FAPS, values, strict=True)
            print(f"  frame {i}: " + ", ".join(f"FAP {f} {v:.0f}" for f, v in pairs))
        if args.draw and shown:
            args.draw.mkdir(parents=True, exist_ok=True)
            draw(shown, found, args.draw / f"{clip}_eyes.png")


if __name__ == "__main__":
    main()
