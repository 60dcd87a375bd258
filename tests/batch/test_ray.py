"""vtts batch on a local Ray instance: 6 short jobs on 2 workers, one with an unknown bookmark,
one whose worker is killed (SIGKILL) while it writes the video. The other 5 outputs are complete
and byte-identical to the single command's, the bad job is in failures.jsonl with the command's
message, the killed one ran again on a new worker; a re-run does nothing.

Six jobs are enough for all of it: each worker runs several (the heads and renderers it keeps
from job to job make the later outputs), and the batch goes on past the bad job and the kill."""

from __future__ import annotations

import concurrent.futures
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import ray  # noqa: F401  (the test extra installs it: without it this test fails, loudly)

from ..in_process import vtts
from .killed_batch import check_outputs, killing_while_writing, parent_pid, references, say_jobs

TEXTS = [
    "Hi.",
    "Hello there.",
    "Hello <frown> you.",  # unknown bookmark: fails as vtts say would
    # the job whose worker is killed: long enough to be caught writing its video
    "Good morning and welcome. <smile> I speak for a while, so that you can catch me at it.",
    "See you.",
    "Good night.",
]
BAD, KILLED = 2, 3
#: the suite's local Rays start one at a time (tests/conftest.py)
pytestmark = pytest.mark.usefixtures("one_ray_at_a_time")


def _is_worker(pid: int) -> bool:
    """Whether ``pid`` is a Ray worker process."""
    cmdline = (Path("/proc") / str(pid) / "cmdline").read_bytes()
    return b"ray::" in cmdline or b"default_worker" in cmdline


def _start(jobs: Path, out: Path) -> subprocess.Popen:
    """``vtts batch JOBS --out OUT --workers 2 --ray``, started."""
    env = {**os.environ, "LP_NUM_THREADS": "1"}
    command = [sys.executable, "-m", "vtts.cli", "batch", str(jobs), "--out", str(out)]
    return subprocess.Popen([*command, "--workers", "2", "--ray"], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip


def _finish(p: subprocess.Popen) -> subprocess.CompletedProcess:
    """What the batch ``p`` printed, when it has ended (within 240 s)."""
    try:
        stdout, stderr = p.communicate(timeout=240)
    except subprocess.TimeoutExpired:
        p.kill()
        p.communicate()
        raise
    return subprocess.CompletedProcess(p.args, p.returncode, stdout, stderr)


def _batch(jobs: Path, out: Path) -> subprocess.CompletedProcess:
    return _finish(_start(jobs, out))


def test_batch_on_local_ray(tmp_path):
    jobs, out = say_jobs(tmp_path, TEXTS)
    with killing_while_writing(out, f".q{KILLED}.mp4.*.part*", _is_worker) as killed:
        batch = _start(jobs, out)
        try:
            # the references are made while the batch runs (Ray's start-up is mostly waiting)
            with concurrent.futures.ThreadPoolExecutor(1) as pool:
                ended = pool.submit(_finish, batch)
                refs = references(tmp_path, TEXTS, BAD)
                first = ended.result()
        finally:
            if batch.poll() is None:
                batch.kill()
                batch.wait()
    assert first.returncode == 1, first.stderr
    assert killed, "the watcher never saw the job's video being written"
    assert "5 jobs done, 1 failed, 0 already done" in first.stdout, first.stdout
    assert "1 worker replaced" in first.stdout

    check_outputs(out, refs, BAD, KILLED)

    # a re-run does nothing: the 5 are finished, the bad job's line is unchanged
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    again = _batch(jobs, out)
    assert again.returncode == 1  # the batch is still not complete
    assert "0 jobs done, 1 failed, 5 already done" in again.stdout, again.stdout
    assert "1 failed job not run again" in again.stdout and "start-up" not in again.stdout
    assert f"q{BAD}: error: column 7: unknown bookmark <frown>" in again.stderr
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before


EXE = Path(sys.executable).with_name("vtts")


def test_an_address_nothing_answers_fails_at_once_naming_it(tmp_path):
    """Ray retried 127.0.0.1:1 for minutes, deaf to Ctrl-C and SIGTERM, and its warning named
    another address."""
    jobs = tmp_path / "jobs.jsonl"
    jobs.write_text(json.dumps({"say": "Hi.", "model": "cybatt", "output": "a.mp4"}) + "\n")
    for address, message, connects in [
        ("127.0.0.1:1", "cannot reach the Ray cluster at 127.0.0.1:1: connection refused", True),
        ("ray://127.0.0.1:1", "cannot reach the Ray cluster at ray://127.0.0.1:1: connection",
         True),
        ("127.0.0.1", "--address is HOST:PORT, ray://HOST:PORT or auto, got '127.0.0.1'", False),
        ("h:99999", "--address is HOST:PORT", False),
    ]:  # fmt: skip
        args = ["batch", str(jobs), "--out", str(tmp_path / "out"), f"--address={address}"]
        if connects:  # a process of its own: were the address not checked, Ray would hang
            r = subprocess.run([str(EXE), *args], capture_output=True, text=True, timeout=120)
        else:  # refused before Ray starts: the message, in this process
            r = vtts(*args, cwd=tmp_path)
        assert r.returncode == 1 and message in r.stderr and "Traceback" not in r.stderr, r.stderr


def _has_worker(pid: int) -> bool:
    """Whether a process below ``pid`` is a JobRunner actor: the batch's driver made it after
    ``ray.init`` had returned."""
    children: dict[int, list[int]] = {}
    for proc in Path("/proc").iterdir():
        try:
            children.setdefault(parent_pid(proc), []).append(int(proc.name))
        except (OSError, ValueError):
            continue
    below = list(children.get(pid, []))
    while below:
        child = below.pop()
        try:
            if b"ray::JobRunner" in (Path("/proc") / str(child) / "cmdline").read_bytes():
                return True
        except OSError:
            continue
        below += children.get(child, [])
    return False


def test_sigterm_ends_a_batch_as_ctrl_c_does(tmp_path):
    """ray.init made SIGTERM exit at once with status 15, two native stack dumps of Ray's and
    no "interrupted"; the command's handler is put back after it. The signal comes once Ray
    runs a worker of the batch (ray.init has returned), while the driver waits for it."""
    jobs = tmp_path / "jobs.jsonl"
    lines = [{"say": f"Hello number {i}.", "model": "cybatt", "output": f"{i}.mp4",
              "size": "64x48"} for i in range(30)]  # fmt: skip
    jobs.write_text("".join(json.dumps(j) + "\n" for j in lines))
    out = tmp_path / "out"
    p = subprocess.Popen([str(EXE), "batch", str(jobs), "--out", str(out), "--workers", "1",
                          "--ray"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    try:
        deadline = time.monotonic() + 240
        while not _has_worker(p.pid):  # Ray runs
            assert p.poll() is None and time.monotonic() < deadline, p.stderr.read()
            time.sleep(0.2)
        p.send_signal(signal.SIGTERM)
        code = p.wait(60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    err = p.stderr.read().decode()
    assert code == 130 and "interrupted" in err, (code, err)
    assert "SIGTERM received" not in err and "Traceback" not in err, err
