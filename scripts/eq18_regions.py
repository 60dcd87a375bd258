"""Where Equation 18's error lies on the face, and what kind of error it is.

    .venv/bin/python scripts/eq18_regions.py tests/data/video/lp_d3.mp4
    .venv/bin/python scripts/eq18_regions.py tests/data/video/akiyo_cif.mp4 --track

Analyzes the video as ``bench/bench_people.py`` does (``--model auto``, the most typical frame as
the anchor, the accurate mode at the frames the 12.5 Hz stream shows — every second frame of a
25 fps video — or ``--track`` every frame, the mean texture, coded at 12.5 Hz with ``vtts
analyze``'s quantizer), decodes the ``.fbs`` through the video's camera and measures Equation
18 (luminance over the camera face's oval, the decoded frame laid over the camera frame:
:mod:`vtts.analysis.landmark_quality`), split, as JSON:

* **by region** of the camera face (:func:`regions`, from its landmarks; each pixel of the oval
  in the first that holds it): the eyes (their contours grown by a tenth of the eye distance:
  lids, lashes, a glasses' rim), the brows, the mouth (the outer lips grown by 6 %), the oval's
  outline band (within 12 % of the eye distance of the oval's edge: the head's silhouette
  against the oval) and the rest (cheeks, nose, forehead, chin) — each region's share of the
  oval's pixels and of its squared error, its own PSNR, and the whole oval's PSNR were that
  region perfect;
* **by kind**: the share of the error that is smooth (the difference low-passed by a Gaussian of
  σ = 3 pixels: shading, light, a colour that changed) and what is left without it; the PSNR
  with a gain and offset of the decoded luminance fitted per frame over the oval (an oracle for
  the light); the best whole-pixel shift of each decoded frame within ±3 pixels (an oracle for
  the head's position); the texture's sharpness against the camera's (the mean squared
  difference from a σ = 1.5 blur over the oval less its outline band, decoded over camera) and
  what blurring the camera frame itself by σ = 1 costs it (the error of a texture exactly that
  much blurrier); the anchor frame's own figure (the frame the head was made from).

See docs/analysis.md, "Where Equation 18's error lies".
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import ndimage

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))  # mc_bound.measure_video

#: The regions, in the order a pixel is given to the first that holds it.
REGIONS = ("eyes", "brows", "mouth", "outline band", "rest")
#: How far (shares of the eye distance) each feature's landmark contour is grown, and the width
#: of the outline band.
GROW = {"eyes": 0.10, "brows": 0.05, "mouth": 0.06}
BAND = 0.12
#: The low-pass (σ, pixels) that splits the error into smooth and detailed parts, and the blur
#: that measures sharpness.
SMOOTH_SIGMA = 3.0
SHARPNESS_SIGMA = 1.5
#: The coded rate (Hz).
RATE = 12.5


def regions(landmarks: np.ndarray, size: tuple[int, int]) -> dict[str, np.ndarray]:
    """The camera face's oval split into :data:`REGIONS`: name -> ``(H, W) bool`` mask, the
    masks disjoint and together the oval (:func:`~vtts.analysis.landmark_quality.oval_mask`) of
    ``landmarks`` ``(468, ≥2)`` pixels in an image of ``size`` (W, H)."""
    from matplotlib.path import Path as Polygon
    from scipy.spatial import ConvexHull

    from vtts.analysis.landmark_quality import eye_distance, oval_mask
    from vtts.fit.landmarks import (
        LEFT_EYE,
        LEFT_EYEBROW,
        LIPS_OUTER,
        RIGHT_EYE,
        RIGHT_EYEBROW,
    )

    w, h = size
    points = np.asarray(landmarks, np.float64)[:, :2]
    scale = eye_distance(points)
    ys, xs = np.mgrid[0:h, 0:w]
    centres = np.column_stack([xs.ravel() + 0.5, ys.ravel() + 0.5])

    def hull(*groups) -> np.ndarray:
        mask = np.zeros((h, w), bool)
        for group in groups:
            p = points[list(group)]
            ring = p[ConvexHull(p).vertices]
            mask |= Polygon(ring).contains_points(centres).reshape(h, w)
        return mask

    def grown(mask: np.ndarray, share: float) -> np.ndarray:
        return ndimage.binary_dilation(mask, iterations=max(1, round(share * scale)))

    oval = oval_mask(points, size)
    inner = ndimage.distance_transform_edt(oval)
    wanted = {
        "eyes": grown(hull(RIGHT_EYE, LEFT_EYE), GROW["eyes"]),
        "brows": grown(hull(RIGHT_EYEBROW, LEFT_EYEBROW), GROW["brows"]),
        "mouth": grown(hull(LIPS_OUTER), GROW["mouth"]),
        "outline band": inner <= BAND * scale,
        "rest": np.ones((h, w), bool),
    }
    out, taken = {}, np.zeros((h, w), bool)
    for name in REGIONS:
        out[name] = oval & wanted[name] & ~taken
        taken |= out[name]
    return out


class Tally:
    """Equation 18's squared error summed over frames, by region and by kind."""

    def __init__(self) -> None:
        self.sse = dict.fromkeys(REGIONS, 0.0)
        self.pixels = dict.fromkeys(REGIONS, 0)
        self.smooth = dict.fromkeys(REGIONS, 0.0)
        self.light = 0.0  # with the oracle gain and offset
        self.shifted = 0.0  # with the oracle shift
        self.sharp_camera = self.sharp_decoded = 0.0
        self.blurred_camera = 0.0
        self.frames: list[tuple[int, float]] = []  # (camera index, Eq. 18 dB)

    def add(self, index: int, frame: np.ndarray, rgba: np.ndarray, landmarks: np.ndarray) -> None:
        """Camera ``frame`` ``(H, W, 3) uint8`` number ``index``, the decoder's ``rgba`` ``(H,
        W, 4) uint8`` and the camera face's ``landmarks`` ``(468, ≥2)``."""
        from vtts.analysis.landmark_quality import lay_over, luminance

        h, w = frame.shape[:2]
        parts = regions(landmarks, (w, h))
        oval = np.logical_or.reduce(list(parts.values()))
        camera, decoded = luminance(frame), luminance(lay_over(frame, rgba))
        diff = camera - decoded
        low = ndimage.gaussian_filter(diff, SMOOTH_SIGMA)
        for name, mask in parts.items():
            self.sse[name] += float((diff[mask] ** 2).sum())
            self.pixels[name] += int(mask.sum())
            self.smooth[name] += float((low[mask] ** 2).sum())
        a = np.column_stack([decoded[oval], np.ones(int(oval.sum()))])
        fit, *_ = np.linalg.lstsq(a, camera[oval], rcond=None)
        self.light += float(((camera[oval] - a @ fit) ** 2).sum())
        self.shifted += min(
            float(((camera - np.roll(decoded, (dy, dx), axis=(0, 1)))[oval] ** 2).sum())
            for dy in range(-3, 4)
            for dx in range(-3, 4)
        )
        inside = oval & ~parts["outline band"] & (np.asarray(rgba)[..., 3] == 255)
        for image, attr in ((camera, "sharp_camera"), (decoded, "sharp_decoded")):
            detail = image - ndimage.gaussian_filter(image, SHARPNESS_SIGMA)
            setattr(self, attr, getattr(self, attr) + float((detail[inside] ** 2).sum()))
        self.blurred_camera += float(((camera - ndimage.gaussian_filter(camera, 1.0))[oval] ** 2)
                                     .sum())  # fmt: skip
        self.frames.append((index, _psnr(float(np.mean(diff[oval] ** 2)))))

    def result(self, anchor: int | None = None) -> dict:
        total, pixels = sum(self.sse.values()), sum(self.pixels.values())
        smooth = sum(self.smooth.values())
        share = max(total, 1e-12)  # the shares of no error at all are 0
        out: dict = {
            "frames": len(self.frames),
            "eq18_pooled_db": _round(_psnr(total / pixels)),
            "eq18_median_frame_db": _round(float(np.median([f[1] for f in self.frames]))),
            "regions": {
                name: {
                    "pixels_pct": round(100 * self.pixels[name] / pixels, 1),
                    "error_pct": round(100 * self.sse[name] / share, 1),
                    "psnr_db": _round(_psnr(self.sse[name] / max(self.pixels[name], 1))),
                    "oval_if_perfect_db": _round(_psnr((total - self.sse[name]) / pixels)),
                    "smooth_pct": round(100 * self.smooth[name] / max(self.sse[name], 1e-12), 1),
                }
                for name in REGIONS
            },
            "smooth_pct": round(100 * smooth / share, 1),
            "without_smooth_db": _round(_psnr(max(total - smooth, 1e-12) / pixels)),
            "oracle_light_db": _round(_psnr(self.light / pixels)),
            "oracle_shift_db": _round(_psnr(self.shifted / pixels)),
            "sharpness_decoded_over_camera": round(self.sharp_decoded / self.sharp_camera, 2),
            "camera_blurred_sigma1_db": _round(_psnr(self.blurred_camera / pixels)),
        }
        if anchor is not None and self.frames:
            k, db = min(self.frames, key=lambda f: abs(f[0] - anchor))
            out["anchor_frame"] = {"index": k, "eq18_db": _round(db)}
        return out


def _psnr(mse: float) -> float:
    return math.inf if mse <= 0 else 10 * math.log10(255.0**2 / mse)


def _round(v: float):
    return None if not math.isfinite(v) else round(v, 2)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("video", type=Path)
    ap.add_argument("--track", action="store_true", help="the tracking mode, every frame")
    from mc_bound import measure_video

    return measure_video("eq18_regions", ap.parse_args(argv), _measure)


def _measure(args: argparse.Namespace, video, frames: list[np.ndarray]) -> dict:
    """The figures of the module's docstring for ``frames`` of ``video``, as a dict."""
    from vtts.analysis.anchor import choose_anchor
    from vtts.analysis.landmark_quality import camera_landmarks
    from vtts.analysis.quality import decoded_frames
    from vtts.analysis.steps import analysis_steps
    from vtts.analysis.texture import retexture
    from vtts.analysis.track import track
    from vtts.api.analyze import QUANTIZER
    from vtts.fap.coding import decode, encode

    h, w = frames[0].shape[:2]
    at = {"step": 1} if args.track else {"rate": RATE}  # bench_people's frames
    anchor = choose_anchor(frames, video.fps, len(frames), **at)
    tally = Tally()
    with tempfile.TemporaryDirectory(prefix="vtts-eq18-") as tmp:
        tracked = track(frames, fps=video.fps, model_path=Path(tmp) / "m.wrl", **at,
                        tracking=args.track, anchor=anchor)  # fmt: skip
        model = retexture(tracked, frames, (w, h))
        stream = tracked.analysis.stream(args.video.stem, fapu=model.fapu)
        steps = analysis_steps(tracked.analysis, model, (w, h))
        decoded = decode(encode(stream, rate=RATE, steps=steps, quantizer=QUANTIZER))
        for i, rgba in enumerate(decoded_frames(decoded, model, (w, h))):
            k = round(i / decoded.fps * video.fps)
            if k >= len(frames):
                break
            landmarks = camera_landmarks(frames[k])
            if landmarks is not None:
                tally.add(k, frames[k], rgba, landmarks)
    result = {"video": args.video.name, "mode": "tracking" if args.track else "accurate",
              "anchor": anchor}  # fmt: skip
    result.update(tally.result(anchor))
    return result


if __name__ == "__main__":
    sys.exit(main())
