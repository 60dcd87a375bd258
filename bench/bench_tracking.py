"""Live tracking (issue 16): the tracking mode (:class:`vtts.analysis.tracker.Tracker`, ``vtts
analyze --track``) against the accurate mode, on the real sequences and on the seeded
synthetic Table 1 runs.

Real sequences (Akiyo CIF, Carphone QCIF), every frame, ``--model auto``, the paper's 17
parameters, as ``vtts analyze - --stream`` runs them: the frames come from the bundled ffmpeg
as it decodes them (``read_video``: a separate process, on the other core), each estimate is
coded into a packet of a streamed ``.fbs`` at once (:class:`vtts.analysis.streaming.
EstimateStream`). Figures:

* frames per second end to end (decode, estimate, encode), from the second frame on (the
  first is the fit of the head, about 12 s, once per session);
* the latency of a frame: from its pixels in hand to its packet written (median, 95th
  percentile and worst);
* the face PSNR of the decoder's view (:mod:`vtts.analysis.quality`, as ``bench_real_video``):
  mean (of the MSE), median and worst, for the tracking mode and for the accurate mode on the
  same frames, and their difference;
* renderings per frame and re-initializations.

Synthetic: Table 1's sequence and the seeded trajectories of ``bench_analysis``
(:data:`SEEDS`), every 5th frame, with the tracking mode: each FAP's relative error (the worst
seed) against the paper's Table 1, and the frames per second (a lit head: the tracker polishes
each frame on renderings of its own, so this is no live speed); and the same over the seeds
kept out of every choice made on the synthetic runs (:data:`HELD_OUT_SEEDS`).

Targets: ≥ 25 frames/s end to end and ≤ 40 ms latency at CIF on the 2-core machine; a mean
face PSNR within 1 dB of the accurate mode; every FAP within the paper on the synthetic runs.
``VTTS_BENCH_FRAMES=N`` limits each real sequence to its first N frames.
"""

from __future__ import annotations

import io
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_analysis as table1  # noqa: E402  (a sibling benchmark: Table 1's settings)
from bench_real_video import SEQUENCES, VIDEOS  # noqa: E402  (the same real sequences)

BENCH = "tracking"
TARGET_FPS = 25.0
TARGET_LATENCY_MS = 40.0
TARGET_DB = 1.0
#: Table 1 (None) and the seeds of :func:`vtts.analysis.synthetic.random_truth` run in the
#: tracking mode (bench_analysis's tuned and held-out seeds).
SEEDS = (None, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12)
#: Seeds no setting of the tracking mode was chosen on (13–20 were run once to check the lit
#: face's mouth search after it was chosen on seeds 4, 9 and 12; 21–28 had not been run).
HELD_OUT_SEEDS = (13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28)


def _row(benchmark: str, case: str, value, unit: str, target: str = "", ok=None) -> dict:
    return {"benchmark": benchmark, "case": case, "value": value, "unit": unit,
            "target": target, "ok": ok}  # fmt: skip


def run() -> list[dict]:
    rows: list[dict] = []
    for label, name in SEQUENCES:
        rows += _sequence(label, VIDEOS / name)
    rows += _synthetic()
    return rows


def _live(path: Path, limit: int | None, tmp: Path):
    """Track ``path`` as ``vtts analyze - --stream`` does; returns the tracked result, the
    frames, per-frame (ready, written) times and the bytes of the stream."""
    from vtts.analysis.streaming import EstimateStream
    from vtts.analysis.track import track
    from vtts.analysis.unknowns import DEFAULT_UNKNOWNS
    from vtts.analysis.video import read_video
    from vtts.face import load_model

    video = read_video(path)
    frames: list[np.ndarray] = []
    ready: list[float] = []
    written: list[float] = []

    def arriving():
        for i, frame in enumerate(video.frames()):
            if limit is not None and i >= limit:
                return
            frames.append(frame)
            ready.append(time.perf_counter())
            yield frame

    sink = io.BytesIO()
    head = tmp / f"{path.stem}-track.wrl"
    stream = EstimateStream(sink, fps=video.fps, unknowns=DEFAULT_UNKNOWNS, name=path.stem,
                            fapu=lambda: load_model(str(head)).fapu)  # fmt: skip

    def packet(estimate) -> None:
        stream(estimate)
        written.append(time.perf_counter())

    tracked = track(arriving(), fps=video.fps, model_path=head, tracking=True,
                    on_estimate=packet)  # fmt: skip
    stream.end()
    return tracked, frames, np.array(ready), np.array(written), video.fps


def _sequence(label: str, path: Path) -> list[dict]:
    from vtts.analysis.quality import sequence_psnr, stream_psnr
    from vtts.analysis.track import track

    limit = int(os.environ.get("VTTS_BENCH_FRAMES", "0")) or None
    rows = []
    with tempfile.TemporaryDirectory(prefix="vtts-bench-") as tmp:
        tracked, frames, ready, written, fps = _live(path, limit, Path(tmp))
        n = len(frames)
        h, w = frames[0].shape[:2]
        base = f"{label}, {n} frames of {w}x{h}, 17 parameters"
        # from the first packet on: the frames after the fit, decode included
        speed = (n - 1) / (written[-1] - written[0])
        latency = 1000 * (written[1:] - ready[1:])
        rows.append(_row("tracking: frames/s end to end (decode, estimate, encode)",
                         base + ", after the first frame", round(speed, 1), "frames/s",
                         f">= {TARGET_FPS:g}", speed >= TARGET_FPS))  # fmt: skip
        worst = float(latency.max())
        for what, value in (
            ("median", np.median(latency)),
            ("95th percentile", np.percentile(latency, 95)),
            ("worst", worst),
        ):
            rows.append(_row("tracking: latency, frame in hand to packet written",
                             f"{base}, {what}", round(float(value), 1), "ms",
                             f"<= {TARGET_LATENCY_MS:g}" if what == "95th percentile" else "",
                             bool(value <= TARGET_LATENCY_MS) if what == "95th percentile"
                             else None))  # fmt: skip
        rows.append(_row("tracking: frames re-initialized from landmarks", base,
                         len(tracked.restarts), "frames"))  # fmt: skip
        model = tracked.model
        stream = tracked.analysis.stream(path.stem, fapu=model.fapu)
        psnr_track = stream_psnr(frames, stream, model, video_fps=fps)
        t0 = time.perf_counter()
        accurate = track(frames, fps=fps, model_path=Path(tmp) / f"{path.stem}-acc.wrl")
        seconds = time.perf_counter() - t0
        rows.append(_row("tracking: the accurate mode's frames/s (same frames, fit included)",
                         base, round(n / seconds, 2), "frames/s"))  # fmt: skip
        stream = accurate.analysis.stream(path.stem, fapu=accurate.model.fapu)
        psnr_acc = stream_psnr(frames, stream, accurate.model, video_fps=fps)
        means = []
        for mode, psnr in (("tracking", psnr_track), ("accurate", psnr_acc)):
            p = psnr[~np.isnan(psnr)]
            means.append(sequence_psnr(p))
            for what, value in (("mean", means[-1]), ("median", float(np.median(p))),
                                ("worst frame", float(p.min()))):  # fmt: skip
                rows.append(
                    _row(
                        "tracking: face PSNR, decoded (uncoded estimates)",
                        f"{base}, {mode} mode, {what}",
                        round(value, 2),
                        "dB",
                    )
                )
        diff = means[0] - means[1]
        rows.append(_row("tracking: face PSNR, tracking minus accurate mode", base + ", mean",
                         round(diff, 2), "dB", f">= -{TARGET_DB:g}",
                         diff >= -TARGET_DB))  # fmt: skip
    return rows


def _synthetic() -> list[dict]:
    from vtts.analysis import TABLE1_FAPS

    errors, count, seconds = _seeded_errors(SEEDS)
    held, _, _ = _seeded_errors(HELD_OUT_SEEDS)
    rows = []
    for name, table in (("Table 1 and 12 seeds", errors),
                        (f"{len(HELD_OUT_SEEDS)} held-out seeds", held)):  # fmt: skip
        for j, fap in enumerate(TABLE1_FAPS):
            paper = table1.PAPER[fap]
            worst = float(table[:, j].max())
            case = (f"FAP {fap} (Table 1: {errors[0, j]:.3f} %)" if table is errors
                    else f"FAP {fap} (seeds {HELD_OUT_SEEDS[0]}-{HELD_OUT_SEEDS[-1]})")  # fmt: skip
            rows.append(_row(f"tracking: synthetic, relative error (worst of {name})", case,
                             round(worst, 3), "%", f"<= {paper} (paper)",
                             worst <= paper))  # fmt: skip
    rows.append(_row("tracking: synthetic, frames/s (a lit head, polished)",
                     f"{len(SEEDS)} sequences of 20 CIF frames", round(count / seconds, 2),
                     "frames/s"))  # fmt: skip
    return rows


def _seeded_errors(seeds) -> tuple[np.ndarray, int, float]:
    """The tracking mode's relative error of each FAP of Table 1 on each of ``seeds`` (None:
    Table 1's own curves) ``(seeds, FAPs)``, with the frames estimated and the seconds taken."""
    import vtts
    from vtts.analysis import TABLE1_FAPS
    from vtts.analysis.synthetic import (
        TABLE1_EXTREMES,
        random_truth,
        relative_errors,
        render_sequence,
        table1_truth,
    )
    from vtts.analysis.tracker import Tracker

    cybatt = vtts.load_model("cybatt")
    idx = [f - 1 for f in TABLE1_FAPS]
    extremes = np.array([TABLE1_EXTREMES[f] for f in TABLE1_FAPS])
    errors, seconds, count = [], 0.0, 0
    for seed in seeds:
        truth = (table1_truth(table1.FRAMES) if seed is None
                 else random_truth(seed, table1.FRAMES))[:: table1.STEP]  # fmt: skip
        frames = render_sequence(cybatt, truth, size=table1.SIZE)
        tracker = Tracker(cybatt, size=table1.SIZE, unknowns=TABLE1_FAPS)
        t0 = time.perf_counter()
        found = np.array([tracker.estimate(f, i * table1.STEP).params
                          for i, f in enumerate(frames)])  # fmt: skip
        seconds += time.perf_counter() - t0
        count += len(frames)
        errors.append(relative_errors(found[:, idx], truth[:, idx], extremes))
    return np.array(errors), count, seconds
