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
import time
from pathlib import Path

from vtts.batch import run
from vtts.batch.jobs import parse_job
from vtts.batch.pool import Died, LocalPool

from .killed_batch import check_outputs, killing_while_writing, parent_pid, references, say_jobs

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


def _workers(pid: int) -> list[int]:
    """The pids of ``pid``'s children that are batch workers (a spawned Python process)."""
    found = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            parent = parent_pid(proc)
            cmdline = (proc / "cmdline").read_bytes()
        except (OSError, ValueError):
            continue
        if parent == pid and b"spawn_main" in cmdline:  # not multiprocessing's resource tracker
            found.append(int(proc.name))
    return found


def _is_worker(pid: int) -> bool:
    """Whether ``pid`` is a batch worker of this process."""
    return pid in _workers(os.getpid())


def test_a_batch_on_local_workers(tmp_path, monkeypatch):
    monkeypatch.setenv("LP_NUM_THREADS", "1")
    jobs, out = say_jobs(tmp_path, TEXTS)
    with killing_while_writing(out, f".q{KILLED}.mp4.*.part*", _is_worker) as killed:
        report = run(jobs, out, workers=2)
    assert killed, "the watcher never saw the job's video being written"
    assert report.workers == 2 and report.restarts == 1
    assert "5 jobs done, 1 failed, 0 already done" in report.summary()
    assert "1 worker replaced" in report.summary()
    assert not _workers(os.getpid()), "the workers are gone"

    check_outputs(out, references(tmp_path, TEXTS, BAD), BAD, KILLED)

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
