"""vtts batch on worker processes of this machine (no Ray): 6 short jobs on 2 workers, one with
an unknown bookmark, one whose worker is killed (SIGKILL) while it writes the video. The other 5
outputs are byte-identical to the single command's, the bad job is in failures.jsonl with the
command's message, the killed one ran again on a new worker; a re-run does nothing. SIGTERM ends
a batch as Ctrl-C does and leaves no worker behind."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from vtts.batch import run
from vtts.batch.jobs import parse_job
from vtts.batch.pool import Died, LocalPool

from ..in_process import vtts

TEXTS = [
    "Hi.",
    "Hello <frown> you.",  # unknown bookmark: fails as vtts say would
    "Good day.",
    # the job whose worker is killed: long enough to be caught writing its video
    "Good morning and welcome. <smile> I speak for a while, so that you can catch me at it.",
    "See you.",
    "Bye now.",
]
BAD, KILLED = 1, 3
OPTIONS = ["--model", "cybatt", "--size", "160x120"]


def _workers(pid: int) -> list[int]:
    """The pids of ``pid``'s children that are batch workers (a spawned Python process)."""
    found = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            parent = int((proc / "stat").read_text().rsplit(")", 1)[1].split()[1])
            cmdline = (proc / "cmdline").read_bytes()
        except (OSError, ValueError):
            continue
        if parent == pid and b"spawn_main" in cmdline:  # not multiprocessing's resource tracker
            found.append(int(proc.name))
    return found


def _holder(path_glob: str, folder: Path) -> int | None:
    """The pid of the worker whose encoder writes a file matching ``path_glob`` in ``folder``
    (the encoder is the worker's child), or None."""
    parts = [str(p) for p in folder.glob(path_glob)]
    if not parts:
        return None
    workers = _workers(os.getpid())
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            links = [os.readlink(fd) for fd in (proc / "fd").iterdir()]
            if not any(link in parts for link in links):
                continue
            parent = int((proc / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError):
            continue
        if parent in workers:
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


def test_a_batch_on_local_workers(tmp_path, monkeypatch):
    monkeypatch.setenv("LP_NUM_THREADS", "1")
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
        report = run(jobs, out, workers=2)
    finally:
        stop.set()
        watcher.join()
    assert killed, "the watcher never saw the job's video being written"
    assert report.workers == 2 and report.restarts == 1
    assert "5 jobs done, 1 failed, 0 already done" in report.summary()
    assert "1 worker replaced" in report.summary()
    assert not _workers(os.getpid()), "the workers are gone"

    failures = [json.loads(x) for x in (out / "failures.jsonl").read_text().splitlines()]
    assert [(f["id"], f["line"], f["kind"]) for f in failures] == [(f"q{BAD}", BAD + 1, "input")]
    manifest = [json.loads(x) for x in (out / "manifest.jsonl").read_text().splitlines()]
    assert sorted(e["id"] for e in manifest) == sorted(f"q{i}" for i in range(6) if i != BAD)
    assert next(e for e in manifest if e["id"] == f"q{KILLED}")["attempts"] == 2
    assert not list(out.glob(".*part*"))  # the dead worker's temporary is gone

    for i, text in enumerate(TEXTS):
        ref = tmp_path / f"ref{i}.mp4"
        r = vtts("say", text, *OPTIONS, "--quiet", "-o", str(ref))
        if i == BAD:
            assert r.returncode == 1 and not (out / f"q{i}.mp4").exists()
            assert failures[0]["error"] == r.stderr.rstrip("\n")  # what the command printed
            continue
        assert (out / f"q{i}.mp4").read_bytes() == ref.read_bytes(), f"q{i}"

    # a re-run does nothing and starts no worker: the 5 are finished, the bad line unchanged
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    again = run(jobs, out, workers=2)
    assert "0 jobs done, 1 failed, 5 already done" in again.summary()
    assert "1 failed job not run again" in again.summary() and again.workers == 0
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before


def test_a_worker_that_dies_is_replaced_and_its_job_comes_back(tmp_path):
    """Killed while idle or while it works, a worker's job comes back as Died (how it died),
    and a new worker takes its place; a job that dies every time fails as a crash."""
    out = tmp_path / "out"
    out.mkdir()
    job = parse_job({"id": "s", "render": True, "model": "cybatt", "size": "64x48",
                     "output": "s.png"}, out, 1)  # fmt: skip
    with LocalPool(1) as pool:
        pool.ready()
        first = pool.workers[0].process.pid
        os.kill(first, signal.SIGKILL)
        pool.submit(job, str(out), "token")
        token, result = pool.next()
        assert token == "token" and result == Died("killed by SIGKILL")
        assert pool.restarts == 1 and pool.workers[0].process.pid != first
        pool.submit(job, str(out), "again")
        token, result = pool.next()  # the new worker warms up, then runs it
        assert token == "again" and result.ok and (out / "s.png").is_file(), result.message
    jobs = tmp_path / "jobs.jsonl"
    jobs.write_text(json.dumps({"id": "s", "render": True, "model": "cybatt", "size": "64x48",
                                "output": "t.png"}) + "\n")  # fmt: skip
    report = _run_killing_every_worker(jobs, out)
    assert report.restarts == 2
    (failure,) = report.failures
    assert failure["kind"] == "crash" and failure["attempts"] == 2
    assert failure["error"] == (
        "error: the worker running this job died 2 times (given again at most 1): its process "
        "killed by SIGKILL"
    )


def _run_killing_every_worker(jobs: Path, out: Path):
    """:func:`run` with one retry, where every worker is killed as soon as it has a job."""
    from vtts.batch import pool as pool_module

    submit = pool_module.LocalPool.submit

    def submit_and_kill(self, job, out_dir, token):
        submit(self, job, out_dir, token)
        worker = next(w for w in self.workers if w.token is token)
        os.kill(worker.process.pid, signal.SIGKILL)

    pool_module.LocalPool.submit = submit_and_kill
    try:
        return run(jobs, out, workers=1, retries=1)
    finally:
        pool_module.LocalPool.submit = submit


def test_sigterm_ends_a_batch_as_ctrl_c_does_and_leaves_no_worker(tmp_path):
    jobs = tmp_path / "jobs.jsonl"
    lines = [{"say": f"Hello number {i}.", "model": "cybatt", "output": f"{i}.mp4",
              "size": "64x48"} for i in range(30)]  # fmt: skip
    jobs.write_text("".join(json.dumps(j) + "\n" for j in lines))
    out = tmp_path / "out"
    exe = Path(sys.executable).with_name("vtts")
    p = subprocess.Popen([str(exe), "batch", str(jobs), "--out", str(out), "--workers", "2"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while not (out / "manifest.jsonl").exists():  # a job is done
            assert p.poll() is None and time.monotonic() < deadline, p.stderr.read()
            time.sleep(0.05)
        workers = _workers(p.pid)
        assert len(workers) == 2
        p.send_signal(signal.SIGTERM)
        code = p.wait(60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    err = p.stderr.read().decode()
    assert code == 130 and "interrupted" in err, (code, err)
    assert "Traceback" not in err, err
    assert not [pid for pid in workers if Path(f"/proc/{pid}").exists()], "a worker is left"
    assert not list(out.glob(".*part*")), "a job's temporary file is left"
