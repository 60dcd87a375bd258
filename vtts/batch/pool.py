"""The workers of a batch on this machine without Ray: :class:`LocalPool`.

Each worker is a process of its own (started fresh, not forked: the driver's state stays its
own) running a :class:`~vtts.batch.worker.JobRunner`, which keeps its heads, EGL context and
renderers warm from one job to the next, exactly as a Ray actor does. The driver talks to each
over a pipe: a job goes in, a :class:`~vtts.batch.worker.JobResult` comes back. A worker that
dies (killed, out of memory, a crash in a native library) is seen at once — its pipe closes and
its process ends — and is replaced by a new one.

The workers start when the pool is made and warm up (imports, pyrender, the EGL context) while
the driver reads and checks the jobs; they ignore Ctrl-C, which the driver turns into the end of
the batch (:meth:`LocalPool.close` stops them).
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait

from vtts.batch.worker import JobResult, JobRunner

#: Seconds a worker has to leave after it is told to, before it is terminated.
STOP_TIMEOUT_S = 5.0


@dataclass
class Died:
    """A worker that ended while it ran a job: ``reason`` says how (``killed by SIGKILL``,
    ``exited with status 1``)."""

    reason: str


def _serve(conn: Connection, cwd: str | None, lp_threads: int | None) -> None:
    """A worker process: warm up, say so, then run the jobs the driver sends until it sends
    None or its pipe closes. SIGTERM ends the job as it ends the ``vtts`` command (its
    temporary files removed); Ctrl-C is the driver's to handle."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        runner = JobRunner(cwd=cwd, lp_threads=lp_threads, cpus=lp_threads)
        conn.send(("ready", runner.warm_up()))
        while (message := conn.recv()) is not None:
            job, out_dir = message
            conn.send(("done", runner.run(job, out_dir)))
    except (KeyboardInterrupt, EOFError, OSError):  # stopped, or the driver is gone
        return


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


class _Worker:
    """One worker process and the driver's end of its pipe."""

    def __init__(self, context, cwd: str | None, lp_threads: int | None) -> None:
        self.conn, theirs = context.Pipe()
        self.process = context.Process(
            target=_serve, args=(theirs, cwd, lp_threads), name="vtts-batch-worker", daemon=True
        )
        self.process.start()
        theirs.close()
        self.ready = False
        self.warm_up_seconds = 0.0
        self.token = None  # what the driver gave with the job it runs; None when idle

    def reason(self) -> str:
        """How the worker's process ended."""
        self.process.join(STOP_TIMEOUT_S)
        code = self.process.exitcode
        if code is None:
            return "stopped answering"
        if code < 0:
            try:
                return f"killed by {signal.Signals(-code).name}"
            except ValueError:
                return f"killed by signal {-code}"
        return f"exited with status {code}"


class LocalPool:
    """``n`` worker processes on this machine, started at once.

    ``cwd``: the folder relative input paths are read from; ``lp_threads``: each worker's share
    of the machine's cores: Mesa llvmpipe's rasterizer threads (``LP_NUM_THREADS``, unless the
    environment sets it) and the CPUs a recognition counts on (``JobRunner(cpus=…)``).

    :meth:`submit` gives a job to an idle worker with a token of the caller's; :meth:`next`
    waits for a worker to finish and returns ``(token, JobResult)``, or ``(token, Died)`` when
    its worker died (a new one takes its place). :meth:`ready` waits for every worker's warm-up.
    """

    def __init__(self, n: int, cwd: str | None = None, lp_threads: int | None = None) -> None:
        self._context = multiprocessing.get_context("spawn")
        self._cwd = cwd
        self._lp_threads = lp_threads
        self.workers: list[_Worker] = []
        self.restarts = 0
        try:
            for _ in range(n):
                self.workers.append(_Worker(self._context, cwd, lp_threads))
        except BaseException:
            self.close()
            raise

    def __enter__(self) -> LocalPool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- start-up ----------------------------------------------------------------------------

    def ready(self) -> None:
        """Wait until every worker has warmed up. Raises :class:`RuntimeError` naming how a
        worker ended when one dies on the way (its start-up is broken: a new one would be too)."""
        for w in self.workers:
            if not w.ready:
                self._await_ready(w)

    def _await_ready(self, w: _Worker) -> None:
        try:
            kind, value = w.conn.recv()
        except (EOFError, OSError):
            raise RuntimeError(f"a worker {w.reason()} while it started") from None
        w.ready, w.warm_up_seconds = kind == "ready", value

    # ---- jobs --------------------------------------------------------------------------------

    def idle(self) -> int:
        """How many workers wait for a job."""
        return sum(w.token is None for w in self.workers)

    def busy(self) -> int:
        """How many workers run a job."""
        return len(self.workers) - self.idle()

    def submit(self, job, out_dir: str, token) -> None:
        """Give ``job`` (outputs under ``out_dir``) to an idle worker; ``token`` comes back with
        its result."""
        w = next(w for w in self.workers if w.token is None)
        w.token = token
        try:
            w.conn.send((job, out_dir))
        except OSError:  # it died while idle: next() finds it
            pass

    def next(self) -> tuple[object, JobResult | Died]:
        """Wait for a busy worker to finish its job: ``(token, result)``; a worker that died
        instead is replaced, and its job comes back as ``(token, Died(...))``."""
        busy = [w for w in self.workers if w.token is not None]
        if not busy:
            raise RuntimeError("no job is running")
        while True:
            ends = {w.conn: w for w in busy} | {w.process.sentinel: w for w in busy}
            for ready in wait(list(ends)):
                w = ends[ready]
                outcome = self._collect(w)
                if outcome is None:  # its warm-up's message: the result is still to come
                    continue
                token, w.token = w.token, None
                if isinstance(outcome, Died):
                    self._replace(w)
                return token, outcome

    def _collect(self, w: _Worker) -> JobResult | Died | None:
        """What ``w`` has to say: its job's result, Died, or None (only its warm-up's end)."""
        try:
            if not w.conn.poll():
                # its process ended and left nothing to read
                return Died(w.reason())
            kind, value = w.conn.recv()
        except (EOFError, OSError):
            return Died(w.reason())
        if kind == "ready":
            w.ready, w.warm_up_seconds = True, value
            return None
        return value

    def _replace(self, dead: _Worker) -> None:
        dead.conn.close()
        self.restarts += 1
        self.workers[self.workers.index(dead)] = _Worker(self._context, self._cwd,
                                                         self._lp_threads)  # fmt: skip

    # ---- the end -----------------------------------------------------------------------------

    def resize(self, n: int) -> None:
        """Start workers up to ``n``, or stop those beyond the first ``n`` (fewer jobs than
        workers); before any job is given."""
        while len(self.workers) < n:
            self.workers.append(_Worker(self._context, self._cwd, self._lp_threads))
        extra, self.workers = self.workers[n:], self.workers[:n]
        _stop(extra)

    def close(self) -> None:
        """Stop every worker (:func:`_stop`)."""
        workers, self.workers = self.workers, []
        _stop(workers)


def _stop(workers: list[_Worker]) -> None:
    """Stop ``workers``: an idle one is told to leave, a busy one (Ctrl-C, an error of the
    driver) gets SIGTERM, which ends its job as it ends the ``vtts`` command; one still there
    after :data:`STOP_TIMEOUT_S` is killed."""
    for w in workers:
        try:
            if w.token is None:
                w.conn.send(None)
            else:
                w.process.terminate()
        except OSError:
            pass
        w.conn.close()  # a busy worker's result has nowhere to go: it leaves
    deadline = time.monotonic() + STOP_TIMEOUT_S
    for w in workers:
        w.process.join(max(0.0, deadline - time.monotonic()))
        if w.process.is_alive():
            w.process.kill()
            w.process.join()


def default_workers() -> int:
    """One worker per CPU this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1
