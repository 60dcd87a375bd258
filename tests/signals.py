"""Signals sent the way the kernel may deliver them: to a thread of a child process other than its
main one.

A signal sent to a process (``kill PID``, Ctrl-C in a terminal) is handled by whichever of its
threads does not block it. Python runs its handlers only in the main thread, between two
bytecodes; the C-level handler, in whichever thread the kernel chose, only records the signal.
A main thread asleep in a wait that this does not interrupt (a lock, a read) sleeps on: the
race behind a ``vtts play -`` that ignored Ctrl-C once in a loaded ``make test``. The kernel
picks a thread other than the main one only now and then; :func:`signal_other_threads` does it
every time (``tgkill``), so that a test of it fails at once rather than once in a hundred runs.
"""

from __future__ import annotations

import ctypes
import os
import signal
import time

import pytest


def _libc():
    libc = ctypes.CDLL(None, use_errno=True)
    if not hasattr(libc, "tgkill"):  # glibc < 2.30, musl …
        pytest.skip("the C library has no tgkill")
    return libc


def threads(pid: int) -> list[int]:
    """The thread ids of process ``pid``, its main thread (``pid``) first."""
    tids = sorted(int(t) for t in os.listdir(f"/proc/{pid}/task"))
    return [pid] + [t for t in tids if t != pid]


def blocks(pid: int, tid: int, sig: int) -> bool:
    """Whether thread ``tid`` of ``pid`` blocks ``sig`` (Mesa's threads block every signal)."""
    with open(f"/proc/{pid}/task/{tid}/status") as f:
        mask = next(line for line in f if line.startswith("SigBlk:")).split()[1]
    return bool(int(mask, 16) >> (sig - 1) & 1)


def signal_other_threads(pid: int, sig: int = signal.SIGINT) -> int:
    """Send ``sig`` to every thread of ``pid`` but the main one that does not block it, as the
    kernel may hand a signal sent to the process to any of them; how many were signalled."""
    libc = _libc()
    sent = 0
    for tid in threads(pid)[1:]:
        try:
            if blocks(pid, tid, sig):
                continue
        except (OSError, StopIteration):
            continue  # the thread ended meanwhile
        if libc.tgkill(pid, tid, sig) == 0:
            sent += 1
    return sent


def cpu_ticks(pid: int) -> int:
    """The CPU time process ``pid`` has used so far, in clock ticks (user and system)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rpartition(")")[2].split()
    return int(fields[11]) + int(fields[12])


def wait_idle(pid: int, quiet: float = 0.5, within: float = 120.0) -> None:
    """Return once process ``pid`` has used no CPU for ``quiet`` seconds: all its threads
    sleep, waiting (for input, for each other). Fails the test after ``within`` seconds."""
    end = time.monotonic() + within
    last, since = cpu_ticks(pid), time.monotonic()
    while time.monotonic() < end:
        time.sleep(0.05)
        now = cpu_ticks(pid)
        if now != last:
            last, since = now, time.monotonic()
        elif time.monotonic() - since >= quiet:
            return
    pytest.fail(f"process {pid} was still busy after {within:g} s")
