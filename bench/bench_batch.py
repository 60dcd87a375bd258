"""``vtts batch`` throughput: 20 short ``say`` jobs on a local Ray instance with 1 and with 2
workers, llvmpipe limited to one rasterizer thread per worker (``LP_NUM_THREADS=1``).

Figures: clips per minute once the workers are up (jobs done / (wall time − start-up)), the
speed-up of 2 workers over 1 (target, issue 20: at least 1.7x on the 2-core machine), the fixed
start-up cost of the engine (Ray started, the workers made and warmed up: pyrender, the EGL
context), and for sizing a cluster: a job's wall time, its CPU-seconds (the worker, its encoder
and its speech synthesizer), a worker's peak memory, and clips per hour per core
(3600 / CPU-seconds per job).

Jobs: cybatt at 352x288 (the default size), 20 different sentences of about 2 s each.
``VTTS_BENCH_BATCH_JOBS=N`` runs N jobs instead of 20 (a quick check).
"""

from __future__ import annotations

import os
import statistics
import tempfile
from pathlib import Path

BENCH = "batch"
SENTENCES = [
    "Good morning, how are you?",
    "Thank you for calling.",
    "Your order has shipped.",
    "Please hold the line.",
    "Welcome to the course.",
    "Let us begin with a question.",
    "That is a good point.",
    "See you next week.",
    "The answer is forty two.",
    "Have a pleasant day.",
]


def _jobs(n: int) -> list[dict]:
    return [
        {
            "id": f"j{i}",
            "say": f"{SENTENCES[i % len(SENTENCES)]} <smile> Number {i}.",
            "model": ["cybatt"],
            "output": f"j{i}.mp4",
        }
        for i in range(n)
    ]


def _row(case: str, value, unit: str, target: str = "", ok=None) -> dict:
    return {"benchmark": BENCH, "case": case, "value": value, "unit": unit, "target": target,
            "ok": ok}  # fmt: skip


def run() -> list[dict]:
    from vtts.batch import run as run_batch

    os.environ["LP_NUM_THREADS"] = "1"  # the workers inherit it (a local Ray's raylet does)
    n = int(os.environ.get("VTTS_BENCH_BATCH_JOBS", "20"))
    rows: list[dict] = []
    rates: dict[int, float] = {}
    for workers in (1, 2):
        with tempfile.TemporaryDirectory(prefix="vtts-bench-batch-") as tmp:
            report = run_batch(_jobs(n), Path(tmp) / "out", workers=workers)
        if not report.ok or len(report.done) != n:
            raise RuntimeError(f"batch failed: {report.failures[:1]}")
        work = report.seconds - report.startup_seconds
        rates[workers] = len(report.done) / work * 60
        cpu = statistics.mean(r.cpu_seconds for r in report.done)
        wall = statistics.mean(r.seconds for r in report.done)
        rss = max(r.max_rss for r in report.done) / 2**20
        label = f"{workers} worker{'s' if workers > 1 else ''}"
        rows += [
            _row(f"{label}: clips per minute ({n} jobs)", rates[workers], "clips/min"),
            _row(f"{label}: start-up (Ray, workers warmed)", report.startup_seconds, "s"),
            _row(f"{label}: wall time per job", wall, "s"),
            _row(f"{label}: CPU time per job", cpu, "s"),
            _row(f"{label}: clips per hour per core", 3600 / cpu, "clips/h"),
            _row(f"{label}: worker peak memory", rss, "MiB"),
        ]
    speedup = rates[2] / rates[1]
    rows.append(_row("speed-up, 2 workers over 1", speedup, "x", ">= 1.7", speedup >= 1.7))
    return rows
