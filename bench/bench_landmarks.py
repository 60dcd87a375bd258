"""Face landmarks (issue 14, adi fit): time per frame of the offline detector.

:class:`vtts.fit.landmarks.MediaPipeDetector` with 2 threads on the two test photographs: the
whole ``detect`` (detector, face mesh and any extra mesh passes), the median of 50 runs after 5
warm-up runs. Also the same photos rolled by 90 degrees, where the mesh crops again from its own
eye corners until the crop stops turning. Target: about 3 ms a frame (MediaPipe's models measured
at 2.8 ms here, see docs/fitting.md).

Then the iris model (issue 40, :class:`vtts.fit.iris.IrisModel`, 1 thread) on both eyes of the
same photos' faces: wall and CPU time, medians of 50 runs after 5 warm-up runs.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from PIL import Image

from vtts.fit.iris import IrisModel
from vtts.fit.landmarks import MediaPipeDetector

PHOTOS = Path(__file__).resolve().parents[1] / "tests" / "data" / "photos"
RUNS = 50
TARGET_MS = 3.5
IRIS_TARGET_MS = 4.0


def median_ms(detector: MediaPipeDetector, image: np.ndarray) -> float:
    for _ in range(5):
        detector.detect(image)
    times = np.empty(RUNS)
    for i in range(RUNS):
        t0 = time.perf_counter()
        detector.detect(image)
        times[i] = time.perf_counter() - t0
    return float(np.median(times) * 1e3)


def run() -> list[dict]:
    detector = MediaPipeDetector(threads=2)
    rows = []
    for name in ("akiyo_frame0", "astronaut"):
        image = np.asarray(Image.open(PHOTOS / f"{name}.png").convert("RGB"))
        h, w = image.shape[:2]
        for case, frame, target in (
            (f"{name} ({w}x{h})", image, True),
            (f"{name} rolled 90 degrees", np.ascontiguousarray(np.rot90(image)), False),
        ):
            ms = median_ms(detector, frame)
            rows.append(
                {
                    "benchmark": "face landmarks (detect + 468-point mesh)",
                    "case": case,
                    "value": round(ms, 3),
                    "unit": "ms/frame",
                    "target": f"< {TARGET_MS} ms" if target else "",
                    "ok": ms < TARGET_MS if target else None,
                }
            )
    iris = IrisModel(threads=1)
    for name in ("akiyo_frame0", "astronaut"):
        image = np.asarray(Image.open(PHOTOS / f"{name}.png").convert("RGB"))
        landmarks = detector.detect(image)[0].landmarks
        for _ in range(5):
            iris.eyes(image, landmarks)
        wall, cpu = np.empty(RUNS), np.empty(RUNS)
        for i in range(RUNS):
            t0, c0 = time.perf_counter(), time.process_time()
            iris.eyes(image, landmarks)
            wall[i], cpu[i] = time.perf_counter() - t0, time.process_time() - c0
        for clock, times in (("wall", wall), ("CPU", cpu)):
            ms = float(np.median(times) * 1e3)
            rows.append(
                {
                    "benchmark": "iris model (both eyes)",
                    "case": f"{name}, {clock}",
                    "value": round(ms, 3),
                    "unit": "ms/frame",
                    "target": f"< {IRIS_TARGET_MS} ms",
                    "ok": ms < IRIS_TARGET_MS,
                }
            )
    return rows
