"""The batch test_pool and test_ray run, on worker processes and on Ray: six short ``say`` jobs
on 2 workers, one with an unknown bookmark, one whose worker is killed (SIGKILL) while it writes
its video — found through /proc (Linux) as the parent of the encoder that holds the job's
temporary file open — and what it must leave."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from ..in_process import vtts

#: The options of every job, and of the single command each is compared with (10 frames a
#: second: the jobs' frames are what the tests pay for).
OPTIONS = ["--model", "cybatt", "--size", "160x120", "--fps", "10"]


def say_jobs(folder: Path, texts: list[str]) -> tuple[Path, Path]:
    """``folder/jobs.jsonl``, job ``qI`` saying ``texts[I]`` into ``qI.mp4`` with
    :data:`OPTIONS`; and the empty folder ``folder/out`` for the batch's outputs."""
    jobs, out = folder / "jobs.jsonl", folder / "out"
    out.mkdir()
    lines = [
        {
            "id": f"q{i}",
            "say": t,
            "model": ["cybatt"],
            "size": "160x120",
            "fps": 10,
            "output": f"q{i}.mp4",
        }
        for i, t in enumerate(texts)
    ]
    jobs.write_text("".join(json.dumps(x) + "\n" for x in lines))
    return jobs, out


def references(folder: Path, texts: list[str], bad: int) -> dict[int, subprocess.CompletedProcess]:
    """``vtts say`` of each text with the jobs' options, in this process: ``folder/refI.mp4``
    and what the command printed (the bad one's failure as it prints it, without --quiet)."""
    refs = {}
    for i, text in enumerate(texts):
        quiet = ["--quiet"] if i != bad else []
        args = ("say", text, *OPTIONS, *quiet, "-o", str(folder / f"ref{i}.mp4"))
        refs[i] = vtts(*args, cwd=folder, env={"LP_NUM_THREADS": "1"})
    return refs


def check_outputs(out: Path, refs: dict[int, subprocess.CompletedProcess], bad: int,
                  killed: int) -> None:  # fmt: skip
    """What the batch of :func:`say_jobs` must leave in ``out``, job ``bad`` refused and
    ``killed``'s worker killed: the bad job in failures.jsonl with the command's message, the
    others in manifest.jsonl (the killed one ran again on a new worker), no temporary file,
    each video byte-identical to the single command's (``refs``: :func:`references` in the
    folder of ``out``)."""
    failures = [json.loads(x) for x in (out / "failures.jsonl").read_text().splitlines()]
    assert [(f["id"], f["line"], f["kind"]) for f in failures] == [(f"q{bad}", bad + 1, "input")]
    manifest = [json.loads(x) for x in (out / "manifest.jsonl").read_text().splitlines()]
    assert sorted(e["id"] for e in manifest) == sorted(f"q{i}" for i in refs if i != bad)
    assert next(e for e in manifest if e["id"] == f"q{killed}")["attempts"] == 2
    assert not list(out.glob(".*part*"))  # the dead worker's temporary is gone
    for i, r in refs.items():
        if i == bad:
            assert r.returncode == 1 and not (out / f"q{i}.mp4").exists()
            assert failures[0]["error"] == r.stderr.rstrip("\n")  # what the command printed
            continue
        assert r.returncode == 0, r.stderr
        ref = out.parent / f"ref{i}.mp4"
        assert (out / f"q{i}.mp4").read_bytes() == ref.read_bytes(), f"q{i}"


def parent_pid(proc: Path) -> int:
    """The pid of the parent of the process ``/proc/PID`` (OSError or ValueError once it has
    gone)."""
    return int((proc / "stat").read_text().rsplit(")", 1)[1].split()[1])


def holder(path_glob: str, folder: Path, is_worker: Callable[[int], bool]) -> int | None:
    """The pid of the worker whose encoder (its child) writes a file matching ``path_glob`` in
    ``folder``, a worker being a pid for which ``is_worker`` is true; or None."""
    parts = [str(p) for p in folder.glob(path_glob)]
    if not parts:
        return None
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            links = [os.readlink(fd) for fd in (proc / "fd").iterdir()]
            if any(link in parts for link in links) and is_worker(parent := parent_pid(proc)):
                return parent
        except (OSError, ValueError):
            continue
    return None


@contextlib.contextmanager
def killing_while_writing(
    folder: Path, path_glob: str, is_worker: Callable[[int], bool]
) -> Iterator[list[int]]:
    """While the block runs, a thread watches ``folder`` and kills the worker (``is_worker``)
    that writes a file matching ``path_glob`` as soon as it does, once; yields the list that
    receives the killed worker's pid."""
    stop, killed = threading.Event(), []

    def watch() -> None:
        while not stop.is_set():
            pid = holder(path_glob, folder, is_worker)
            if pid is not None:
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
                return
            time.sleep(0.005)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        yield killed
    finally:
        stop.set()
        watcher.join()
