"""Running a batch: :func:`run`, on worker processes of this machine or on Ray.

The driver (this process) checks the jobs, skips those the manifest says are finished, and hands
each idle worker the next job. Without ``--address`` the workers are processes of this machine
(:class:`~vtts.batch.pool.LocalPool`), started before the jobs are read so that they warm up
meanwhile; with one (or ``ray=True``) they are :class:`~vtts.batch.worker.JobRunner` Ray actors,
one CPU each, on a cluster or a local Ray instance. A worker keeps its heads, EGL context and
renderers from job to job. A job whose command fails is recorded in ``DIR/failures.jsonl`` with
the message the command printed, and the others go on (a re-run does not run it again while its
line is unchanged and failures.jsonl has it); a worker that dies (killed, out of memory, a crash
in a native library) is replaced by a new one and its job given again, at most :data:`RETRIES`
times. Finished jobs go into ``DIR/manifest.jsonl`` as they finish.
"""

from __future__ import annotations

import collections
import contextlib
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from vtts.batch.jobs import Job, JobError, JobsFile, as_jobs, read_jobs
from vtts.batch.manifest import Manifest, read_failures, write_failures
from vtts.batch.pool import Died, LocalPool, default_workers
from vtts.batch.worker import JobResult, JobRunner
from vtts.cluster import import_ray, start_ray
from vtts.errors import VttsError
from vtts.messages import printable

#: How many times a job whose worker died is given again (so it runs at most 1 + RETRIES times).
RETRIES = 2
#: The most workers one batch starts.
MAX_WORKERS = 256


class BatchError(VttsError):
    """The batch cannot run (Ray cannot start, no worker can be made, bad arguments)."""


@dataclass
class BatchReport:
    """What a batch did.

    ``done``: the jobs run to completion in this run; ``skipped``: ids of jobs the manifest
    had as finished; ``failures``: one dict per failed job or bad line, as written to
    ``failures.jsonl`` (``id``, ``line``, ``error``: the message, ``attempts``, ``kind``:
    ``input`` when the command refused its input, ``crash`` when its workers died, ``internal``
    for a bug; ``digest``: the job's); ``unchanged``: ids of jobs that failed on their input in
    an earlier run, not run again (their line is unchanged);
    ``seconds``: the whole run's wall time; ``startup_seconds``: the engine's fixed cost (Ray
    started or joined, the workers made and warmed up: pyrender, the EGL context; the local
    workers warm up while the jobs are read);
    ``workers``: how many ran; ``restarts``: workers replaced after dying.
    """

    out_dir: Path
    done: list[JobResult] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    failures: list[dict] = field(default_factory=list)
    unchanged: list[str] = field(default_factory=list)
    seconds: float = 0.0
    startup_seconds: float = 0.0
    workers: int = 0
    restarts: int = 0

    @property
    def ok(self) -> bool:
        """Whether every job is finished (run now or before)."""
        return not self.failures

    def summary(self) -> str:
        """One line: what was done, how fast, where the failures are."""
        n = len(self.done)
        work = max(self.seconds - self.startup_seconds, 1e-9)
        text = (
            f"{n} job{'s' if n != 1 else ''} done, {len(self.failures)} failed, "
            f"{len(self.skipped)} already done; {self.seconds:.1f} s"
        )
        if self.unchanged:
            k = len(self.unchanged)
            text += (
                f"; {k} failed job{'s' if k != 1 else ''} not run again (unchanged since the "
                "last run: change the line, or remove it from failures.jsonl, to retry)"
            )
        if n:
            text += (
                f" ({n / work * 60:.1f} jobs/min on {self.workers} worker"
                f"{'s' if self.workers != 1 else ''} after {self.startup_seconds:.1f} s start-up)"
            )
        if self.restarts:
            text += f"; {self.restarts} worker{'s' if self.restarts != 1 else ''} replaced"
        if self.failures:
            text += f"; failures in {self.out_dir / 'failures.jsonl'}"
        return text


def _bad_line(e: JobError) -> dict:
    return {"id": None, "line": e.line, "error": f"{e.location()}: error: {e.message}"}


def run(
    jobs: str | os.PathLike[str] | Iterable[Job | dict],
    out_dir: str | os.PathLike[str],
    workers: int | None = None,
    address: str | None = None,
    *,
    retries: int = RETRIES,
    show_progress: bool = False,
    ray: bool = False,
) -> BatchReport:
    """Run ``jobs`` — a ``.jsonl`` file (:mod:`vtts.batch.jobs`) or an iterable of
    :class:`~vtts.batch.jobs.Job` or job dicts — with their outputs under ``out_dir``.

    ``workers``: worker processes (default: one per CPU of this machine, or of the cluster);
    ``address``: an existing Ray cluster (``ray://HOST:10001``, ``HOST:6379`` or ``auto``;
    default: worker processes of this machine, no Ray); ``ray``: without ``address``, a local
    Ray instance started for this batch and stopped after it (as a cluster would run it);
    ``retries``: how often a job whose worker died is given again; ``show_progress``: a
    progress bar (jobs done, jobs/min, ETA, failures) and each failure on stderr.

    Bad jobs and failed commands do not stop the others: they are in the report's
    ``failures`` and ``DIR/failures.jsonl``. Raises :class:`BatchError` when the batch cannot
    run at all."""
    t0 = time.perf_counter()
    if workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise BatchError(f"--workers must be within 1–{MAX_WORKERS}, got {workers}")
    if not 0 <= retries <= 10:
        raise BatchError(f"retries must be within 0–10, got {retries}")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise BatchError("the output folder is a file", file=str(out))
    if address or ray:
        return _run(jobs, out, t0, None, workers, address, retries, show_progress)
    n = workers or default_workers()
    # the workers warm up while the jobs are read and checked (as many as the cores, for now:
    # how many jobs there are to run is not known yet)
    with LocalPool(min(n, default_workers()), os.getcwd(), _lp_threads(n)) as pool:
        return _run(jobs, out, t0, pool, n, address, retries, show_progress)


def _lp_threads(workers: int) -> int:
    """llvmpipe's rasterizer threads per worker of this machine: the workers share the cores
    (a caller's LP_NUM_THREADS stands)."""
    return max(1, (os.cpu_count() or 1) // workers)


def _run(
    jobs,
    out: Path,
    t0: float,
    pool: LocalPool | None,
    workers: int | None,
    address: str | None,
    retries: int,
    show_progress: bool,
) -> BatchReport:
    """:func:`run` once the engine is chosen: ``pool``, or Ray when None."""
    parsed: JobsFile = (
        read_jobs(jobs, out) if isinstance(jobs, str | os.PathLike) else as_jobs(jobs, out)
    )
    report = BatchReport(out_dir=out)
    report.failures = [_bad_line(e) for e in parsed.errors]
    out.mkdir(parents=True, exist_ok=True)
    manifest = Manifest(out)
    before = read_failures(out)
    todo = []
    for job in parsed.jobs:
        failed = before.get(job.id)
        if manifest.finished(job):
            report.skipped.append(job.id)
        elif failed and failed.get("digest") == job.digest and failed.get("kind") == "input":
            # the command refused this very job: running it again would say the same
            report.unchanged.append(job.id)
            report.failures.append({**failed, "line": job.line})
        else:
            todo.append(job)
    write_failures(out, report.failures)
    with _bar(len(todo), show_progress and bool(todo)) as bar:
        for entry in report.failures:
            bar.failed(entry, counted=False, show=show_progress)
        if todo and pool is not None:
            _run_local(pool, todo, out, manifest, report, t0, workers, retries, bar)
        elif todo:
            _run_on_ray(todo, out, manifest, report, workers, address, retries, bar)
    report.seconds = time.perf_counter() - t0
    write_failures(out, report.failures)
    return report


def _start(ray, workers: int | None, address: str | None, temp_dir: str) -> int:
    """Start a local Ray instance of ``workers`` CPUs, or join the cluster at ``address``;
    returns how many workers to make."""
    start_ray(ray, cpus=workers, address=address, temp_dir=temp_dir, error=BatchError)
    if workers:
        return workers
    return max(1, int(ray.cluster_resources().get("CPU", 1)))


def _run_on_ray(
    todo: list[Job],
    out: Path,
    manifest: Manifest,
    report: BatchReport,
    workers: int | None,
    address: str | None,
    retries: int,
    bar,
) -> None:
    ray = import_ray(
        BatchError,
        "vtts batch needs Ray: install vtts with its 'batch' extra (pip install 'vtts[batch]')",
    )
    t0 = time.perf_counter()
    # short: Ray's Unix sockets live in it (a socket path has at most 107 characters)
    temp_dir = tempfile.mkdtemp(prefix="vtts-ray-", dir="/tmp" if os.path.isdir("/tmp") else None)
    try:
        n = _start(ray, workers, address, temp_dir)
    except BaseException:
        shutil.rmtree(temp_dir, ignore_errors=True)
        raise
    try:
        n = min(n, len(todo))
        report.workers = n
        lp = _lp_threads(n) if not address else None
        actor_class = ray.remote(num_cpus=1, max_restarts=0, max_task_retries=0)(JobRunner)

        def new_actor():
            # an actor holds one CPU of Ray's (num_cpus=1): its recognitions count on that one
            # where the machine's share is not known (a cluster)
            actor = actor_class.remote(cwd=os.getcwd(), lp_threads=lp, cpus=lp or 1)
            return actor, actor.warm_up.remote()

        started = [new_actor() for _ in range(n)]
        try:
            ray.get([w for _, w in started])
        except ray.exceptions.RayError as e:
            raise BatchError(f"cannot start the workers: {_first_line(e)}") from None
        report.startup_seconds = time.perf_counter() - t0
        bar.started()
        idle = [a for a, _ in started]
        queue: collections.deque[tuple[Job, int]] = collections.deque((j, 1) for j in todo)
        running: dict = {}  # ObjectRef -> (actor, job, attempt)
        while queue or running:
            while idle and queue:
                actor = idle.pop()
                job, attempt = queue.popleft()
                running[actor.run.remote(job, str(out))] = (actor, job, attempt)
            done, _ = ray.wait(list(running), num_returns=1)
            for ref in done:
                actor, job, attempt = running.pop(ref)
                try:
                    result: JobResult = ray.get(ref)
                except (ray.exceptions.RayActorError, ray.exceptions.WorkerCrashedError) as e:
                    with contextlib.suppress(Exception):
                        ray.kill(actor, no_restart=True)
                    report.restarts += 1
                    idle.append(new_actor()[0])
                    if attempt <= retries:
                        queue.appendleft((job, attempt + 1))
                        continue
                    _fail(report, out, bar, job, attempt, _crash_message(attempt, e), "crash")
                    continue
                except ray.exceptions.RayError as e:
                    idle.append(actor)
                    message = f"error: {_first_line(e)}\n"
                    _fail(report, out, bar, job, attempt, message, "internal")
                    continue
                idle.append(actor)
                _finished(report, out, manifest, bar, job, attempt, result)
    finally:
        with contextlib.suppress(Exception):
            ray.shutdown()
        shutil.rmtree(temp_dir, ignore_errors=True)


def _run_local(
    pool: LocalPool,
    todo: list[Job],
    out: Path,
    manifest: Manifest,
    report: BatchReport,
    t0: float,
    workers: int,
    retries: int,
    bar,
) -> None:
    """The jobs on ``pool``'s workers (started before the jobs were read), ``workers`` of
    them at most."""
    pool.resize(min(workers, len(todo)))
    report.workers = len(pool.workers)
    try:
        pool.ready()
    except RuntimeError as e:
        raise BatchError(f"cannot start the workers: {e}") from None
    report.startup_seconds = time.perf_counter() - t0
    bar.started()
    queue: collections.deque[tuple[Job, int]] = collections.deque((j, 1) for j in todo)
    while queue or pool.busy():
        while pool.idle() and queue:
            job, attempt = queue.popleft()
            pool.submit(job, str(out), (job, attempt))
        (job, attempt), result = pool.next()
        if isinstance(result, Died):
            report.restarts += 1
            if attempt <= retries:
                queue.appendleft((job, attempt + 1))
                continue
            message = _crash_message(attempt, f"its process {result.reason}")
            _fail(report, out, bar, job, attempt, message, "crash")
            continue
        _finished(report, out, manifest, bar, job, attempt, result)


def _finished(
    report: BatchReport, out: Path, manifest: Manifest, bar, job: Job, attempt: int,
    result: JobResult,
) -> None:  # fmt: skip
    """A job's worker came back with ``result``: recorded in the manifest, or as a failure."""
    if result.ok:
        manifest.record(
            job,
            result.outputs,
            seconds=round(result.seconds, 3),
            cpu_seconds=round(result.cpu_seconds, 3),
            attempts=attempt,
        )
        report.done.append(result)
        bar.done()
    else:
        kind = "internal" if result.internal else "input"
        _fail(report, out, bar, job, attempt, result.message, kind)


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


def _crash_message(attempts: int, e: BaseException | str) -> str:
    why = e if isinstance(e, str) else _first_line(e)
    return (
        f"error: the worker running this job died {attempts} times (given again at most "
        f"{attempts - 1}): {why}\n"
    )


def _fail(
    report: BatchReport, out: Path, bar, job: Job, attempts: int, message: str, kind: str
) -> None:
    entry = {
        "id": job.id,
        "line": job.line,
        "error": message.rstrip("\n"),
        "attempts": attempts,
        "kind": kind,
        "digest": job.digest,
    }
    report.failures.append(entry)
    write_failures(out, report.failures)
    bar.failed(entry)


class _Bar:
    """The batch's progress on stderr: a rich bar on a terminal (jobs done, jobs/min, ETA,
    failures), each failure as a line; nothing but the failures elsewhere."""

    def __init__(self, total: int, show: bool) -> None:
        self.total = total
        self.show = show
        self.n_done = 0
        self.n_failed = 0
        self.t0 = time.perf_counter()
        self.progress = None
        self.task = None

    def started(self) -> None:
        self.t0 = time.perf_counter()
        if self.progress is not None:
            self.progress.update(self.task, description="batch")
        self._update()

    def done(self) -> None:
        self.n_done += 1
        self._update()

    def failed(self, entry: dict, counted: bool = True, show: bool | None = None) -> None:
        """A failure: shown (``show``, default: as the bar is), ``counted`` among the jobs of
        the bar."""
        if counted:
            self.n_failed += 1
        if self.show if show is None else show:
            lines = entry["error"].splitlines() or [""]
            text = next((x for x in lines if "error:" in x), lines[0])
            if entry["id"] is not None:  # a bad line's message names its line
                text = f"{entry['id']}: {text}"
            text = printable(text)  # a bad line's key or value, quoted as the user wrote it
            if self.progress is not None:
                self.progress.console.print(text, markup=False, highlight=False)
            else:
                print(text, file=sys.stderr)
        self._update()

    def _update(self) -> None:
        if self.progress is None:
            return
        finished = self.n_done + self.n_failed
        minutes = (time.perf_counter() - self.t0) / 60
        rate = self.n_done / minutes if minutes > 0 and self.n_done else 0.0
        self.progress.update(
            self.task, completed=finished, rate=f"{rate:.1f}", failed=self.n_failed
        )


@contextlib.contextmanager
def _bar(total: int, show: bool) -> Iterator[_Bar]:
    from vtts.render.output import terminal_progress

    bar = _Bar(total, show)
    prog = None
    if show:
        prog = terminal_progress(
            "{task.fields[rate]} jobs/min", "{task.fields[failed]} failed", eta_label="ETA"
        )
    if prog is None:
        yield bar
        return
    with prog:
        bar.progress = prog
        bar.task = prog.add_task("starting workers", total=total, rate="0.0", failed=0)
        yield bar
