"""``vtts batch`` throughput.

Against a shell loop (issue 45, item 5): 8 short ``say`` clips made by a loop of ``vtts say``
commands, one after the other, and by ``vtts batch --workers 2`` on this machine's worker
processes (and ``--ray``, a local Ray instance, for comparison), each a command timed from start
to exit (start-up included), llvmpipe as it comes (no ``LP_NUM_THREADS``), the best of 2 runs.
Target: the batch at least 1.5x faster than the loop on the 2-core machine.

Warm workers: 20 short ``say`` jobs with 1 and with 2 workers, llvmpipe limited to one rasterizer
thread per worker (``LP_NUM_THREADS=1``). Figures: clips per minute once the workers are up
(jobs done / (wall time − start-up)), the speed-up of 2 workers over 1 (target, issue 20: at least
1.7x on the 2-core machine), the fixed start-up cost (the workers made and warmed up: pyrender,
the EGL context), and for sizing a cluster: a job's wall time, its CPU-seconds (the worker, its
encoder and its speech synthesizer), a worker's peak memory, and clips per hour per core
(3600 / CPU-seconds per job).

Jobs: cybatt at 352x288 (the default size), different sentences of about 2 s each.
``VTTS_BENCH_BATCH_JOBS=N`` runs N warm-worker jobs instead of 20 (a quick check).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
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


#: Clips of the comparison with a shell loop, and how often each side runs (the best counts).
LOOP_CLIPS = 8
LOOP_RUNS = 2
LOOP_TARGET = 1.5


def _timed(argv: list[str], cwd: Path) -> float:
    """Wall seconds of one command, from start to exit (raises if it fails)."""
    env = {k: v for k, v in os.environ.items() if k != "LP_NUM_THREADS"}
    t0 = time.perf_counter()
    subprocess.run(argv, cwd=cwd, env=env, check=True, capture_output=True)
    return time.perf_counter() - t0


def against_a_loop() -> list[dict]:
    """The batch of :data:`LOOP_CLIPS` clips against a shell loop of ``vtts say``."""
    exe = str(Path(sys.executable).with_name("vtts"))
    jobs = _jobs(LOOP_CLIPS)
    best: dict[str, float] = {}
    for _ in range(LOOP_RUNS):
        with tempfile.TemporaryDirectory(prefix="vtts-bench-loop-") as tmp:
            folder = Path(tmp)
            t = sum(
                _timed(
                    [exe, "say", j["say"], "--model", "cybatt", "-o", j["output"], "--quiet"],
                    folder,
                )  # fmt: skip
                for j in jobs
            )
            best["loop"] = min(best.get("loop", t), t)
            (folder / "jobs.jsonl").write_text("".join(json.dumps(j) + "\n" for j in jobs))
            for engine, extra in (("batch", []), ("batch --ray", ["--ray"])):
                argv = [exe, "batch", "jobs.jsonl", "--out", engine.replace(" --", "-"),
                        "--workers", "2", *extra]  # fmt: skip
                t = _timed(argv, folder)
                best[engine] = min(best.get(engine, t), t)
    n = LOOP_CLIPS
    rows = [
        _row(f"a shell loop of vtts say, {n} clips", best["loop"], "s"),
        _row(f"vtts batch --workers 2, {n} clips (start-up included)", best["batch"], "s"),
        _row(f"vtts batch --workers 2 --ray, {n} clips", best["batch --ray"], "s"),
    ]
    for engine in ("batch", "batch --ray"):
        ratio = best["loop"] / best[engine]
        ok = ratio >= LOOP_TARGET if engine == "batch" else None
        target = f">= {LOOP_TARGET}x" if engine == "batch" else ""
        rows.append(_row(f"vtts {engine} --workers 2 over the loop", ratio, "x", target, ok))
    return rows


def run() -> list[dict]:
    from vtts.batch import run as run_batch

    rows = against_a_loop()
    os.environ["LP_NUM_THREADS"] = "1"  # the workers inherit it (a local Ray's raylet does)
    n = int(os.environ.get("VTTS_BENCH_BATCH_JOBS", "20"))
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
            _row(f"{label}: start-up (workers warmed)", report.startup_seconds, "s"),
            _row(f"{label}: wall time per job", wall, "s"),
            _row(f"{label}: CPU time per job", cpu, "s"),
            _row(f"{label}: clips per hour per core", 3600 / cpu, "clips/h"),
            _row(f"{label}: worker peak memory", rss, "MiB"),
        ]
    speedup = rates[2] / rates[1]
    rows.append(_row("speed-up, 2 workers over 1", speedup, "x", ">= 1.7", speedup >= 1.7))
    return rows
