"""vtts batch on a local Ray instance: 10 short jobs on 2 workers, one with an unknown bookmark,
one whose worker is killed (SIGKILL) while it writes the video. The other 9 outputs are complete
and byte-identical to the single command's, the bad job is in failures.jsonl with the command's
message, the killed one ran again on a new worker; a re-run does nothing."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import ray  # noqa: F401  (the test extra installs it: without it this test fails, loudly)

from vtts import cli

TEXTS = [
    "Hi.",
    "Hello there.",
    "Good day.",
    "Hello <frown> you.",  # unknown bookmark: fails as vtts say would
    "Nice to meet you.",
    "See you.",
    "Thank you.",
    # the job whose worker is killed: long enough to be caught writing its video
    "Good morning and welcome. <smile> I speak for a while, so that you can catch me at it.",
    "Bye now.",
    "Good night.",
]
BAD, KILLED = 3, 7
OPTIONS = ["--model", "cybatt", "--size", "160x120"]


def _holder(path_glob: str, folder: Path) -> int | None:
    """The pid of the Ray worker whose encoder writes a file matching ``path_glob`` in
    ``folder`` (the encoder is the worker's child), or None."""
    parts = [str(p) for p in folder.glob(path_glob)]
    if not parts:
        return None
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            links = [os.readlink(fd) for fd in (proc / "fd").iterdir()]
            if not any(link in parts for link in links):
                continue
            stat = (proc / "stat").read_text()
            parent = int(stat.rsplit(")", 1)[1].split()[1])
            cmdline = (Path("/proc") / str(parent) / "cmdline").read_bytes()
        except (OSError, ValueError):
            continue
        if b"ray::" in cmdline or b"default_worker" in cmdline:
            return parent
    return None


def _kill_when_writing(folder: Path, stop: threading.Event, killed: list) -> None:
    while not stop.is_set():
        pid = _holder(f".q{KILLED}.mp4.*.part*", folder)
        if pid is not None:
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)
            return
        time.sleep(0.005)


def _batch(jobs: Path, out: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "LP_NUM_THREADS": "1"}
    command = [sys.executable, "-m", "vtts.cli", "batch", str(jobs), "--out", str(out)]
    return subprocess.run(
        [*command, "--workers", "2"], env=env, capture_output=True, text=True, timeout=240
    )


def test_batch_on_local_ray(tmp_path):
    jobs = tmp_path / "jobs.jsonl"
    out = tmp_path / "out"
    out.mkdir()
    lines = [
        {"id": f"q{i}", "say": t, "model": ["cybatt"], "size": "160x120", "output": f"q{i}.mp4"}
        for i, t in enumerate(TEXTS)
    ]
    jobs.write_text("".join(json.dumps(x) + "\n" for x in lines))
    stop, killed = threading.Event(), []
    watcher = threading.Thread(target=_kill_when_writing, args=(out, stop, killed), daemon=True)
    watcher.start()
    try:
        first = _batch(jobs, out)
    finally:
        stop.set()
        watcher.join()
    assert first.returncode == 1, first.stderr
    assert killed, "the watcher never saw the job's video being written"
    assert "9 jobs done, 1 failed, 0 already done" in first.stdout, first.stdout
    assert "1 worker replaced" in first.stdout

    failures = [json.loads(x) for x in (out / "failures.jsonl").read_text().splitlines()]
    assert [(f["id"], f["line"]) for f in failures] == [(f"q{BAD}", BAD + 1)]
    manifest = [json.loads(x) for x in (out / "manifest.jsonl").read_text().splitlines()]
    assert sorted(e["id"] for e in manifest) == sorted(f"q{i}" for i in range(10) if i != BAD)
    assert next(e for e in manifest if e["id"] == f"q{KILLED}")["attempts"] == 2
    assert not list(out.glob(".*part*"))  # the dead worker's temporary is gone

    os.environ.setdefault("LP_NUM_THREADS", "1")
    for i, text in enumerate(TEXTS):
        ref = tmp_path / f"ref{i}.mp4"
        code = cli.main(["say", text, *OPTIONS, "--quiet", "-o", str(ref)])
        if i == BAD:
            assert code == 1 and not (out / f"q{i}.mp4").exists()
            continue
        assert (out / f"q{i}.mp4").read_bytes() == ref.read_bytes(), f"q{i}"
    # the failure is what the command printed
    bad = subprocess.run(
        [
            sys.executable,
            "-m",
            "vtts.cli",
            "say",
            TEXTS[BAD],
            *OPTIONS,
            "-o",
            str(tmp_path / "x.mp4"),
        ],
        capture_output=True,
        text=True,
    )
    assert failures[0]["error"] == bad.stderr.rstrip("\n")

    assert failures[0]["kind"] == "input"

    # a re-run does nothing: the 9 are finished, the bad job's line is unchanged
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    again = _batch(jobs, out)
    assert again.returncode == 1  # the batch is still not complete
    assert "0 jobs done, 1 failed, 9 already done" in again.stdout, again.stdout
    assert "1 failed job not run again" in again.stdout and "start-up" not in again.stdout
    assert f"q{BAD}: error: column 7: unknown bookmark <frown>" in again.stderr
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before
