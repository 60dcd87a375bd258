"""Tracking- and accurate-mode speed on one machine, for a head already fitted to a video.

usage: python scripts/tracking_speed.py VIDEO HEAD.wrl [--accurate N] [--json OUT.json]

``HEAD.wrl`` is a head ``vtts analyze VIDEO`` fitted (``OUT-model.wrl``; its ``photo``
Viewpoint is the video's camera), so no fitting runs here: this measures the estimators alone,
e.g. on a GPU machine that lacks the fitting's landmark detector (docs/analysis.md, "Tracking
mode"). The video is read with the bundled ffmpeg, or with OpenCV where the imageio-ffmpeg
wheel is not installed. Prints, for the tracking mode over every frame (two passes, the second
timed) and the accurate mode over the first N (default 40; as ``vtts analyze`` runs it,
``Tracker(finish=True)``, and the whole pyramid of renderings, ``Estimator``): frames per second
after the first frame, the tracking mode's latency per frame (median, 95th percentile, worst),
its renderings per frame, and one rendering of the face's window.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _frames(path: str) -> list[np.ndarray]:
    try:
        from vtts.analysis.video import read_video

        return list(read_video(path).frames())
    except ImportError:  # no imageio-ffmpeg here
        import cv2

        cap, out = cv2.VideoCapture(path), []
        while True:
            ok, frame = cap.read()
            if not ok:
                return out
            out.append(np.ascontiguousarray(frame[:, :, ::-1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("video")
    ap.add_argument("head")
    ap.add_argument("--accurate", type=int, default=40, metavar="N")
    ap.add_argument("--json", metavar="OUT.json")
    args = ap.parse_args()

    from vtts.analysis.estimator import Estimator
    from vtts.analysis.track import FITTED_IGNORED
    from vtts.analysis.tracker import Tracker
    from vtts.face import load_model
    from vtts.render.camera import Camera, find_viewpoint

    frames = _frames(args.video)
    h, w = frames[0].shape[:2]
    model = load_model(args.head)
    node, matrix = find_viewpoint(model.scene, "photo")
    camera = Camera.from_viewpoint(node, (w, h), matrix)
    options = dict(size=(w, h), model_camera=camera, ignore=FITTED_IGNORED, robust=True)
    for _ in range(2):  # the first pass warms up (shaders, caches); the second is timed
        tracker = Tracker(model, **options)
        tracker.estimate(frames[0], 0)
        latency, renderings = [], 0
        start = time.perf_counter()
        for i in range(1, len(frames)):
            t = time.perf_counter()
            tracker.estimate(frames[i], i, i / 25)
            latency.append(1000 * (time.perf_counter() - t))
            renderings += tracker.renderings
            tracker.between_frames()
        seconds = time.perf_counter() - start
    x0, y0, ww, wh = tracker._box
    window = replace(tracker.camera, cx=tracker.camera.cx - x0, cy=tracker.camera.cy - y0)
    tracker._synthesize(window, (ww, wh), triangles=True)
    t = time.perf_counter()
    for _ in range(50):
        tracker.params[47] += 10.0  # a new pose each time
        tracker._synthesize(window, (ww, wh), triangles=True)
    render_ms = (time.perf_counter() - t) / 50 * 1000
    n = min(args.accurate, len(frames) - 1)
    fps = {}
    # the accurate mode as `vtts analyze` runs it, and the whole pyramid of renderings alone
    for name, accurate in (("accurate_fps", Tracker(model, finish=True, **options)),
                           ("pyramid_fps", Estimator(model, **options))):  # fmt: skip
        accurate.estimate(frames[0], 0)
        t = time.perf_counter()
        for i in range(1, n + 1):
            accurate.estimate(frames[i], i, i / 25)
        fps[name] = n / (time.perf_counter() - t)
    lat = np.array(latency)
    result = {
        "frames": len(frames) - 1,
        "tracking_fps": (len(frames) - 1) / seconds,
        "latency_ms_median": float(np.median(lat)),
        "latency_ms_p95": float(np.percentile(lat, 95)),
        "latency_ms_worst": float(lat.max()),
        "renderings_per_frame": renderings / (len(frames) - 1),
        "window_rendering_ms": render_ms,
        **fps,
        "accurate_frames": n,
    }
    print(json.dumps(result, indent=1))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
