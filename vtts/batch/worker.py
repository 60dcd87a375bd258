"""What runs the jobs: :class:`JobRunner`, one per worker process, running one job at a time by
the command's library function (as the ``vtts`` command would, its messages word for word) and
keeping its heads, EGL context and renderers warm
(:class:`vtts.warm.Warm`) from one job to the next. :mod:`vtts.batch.runner` makes each a Ray
actor; it works as well on its own (the tests run it so).
"""

from __future__ import annotations

import contextlib
import io
import os
import resource
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

from vtts.batch.jobs import Job, check_confined, command_function
from vtts.batch.manifest import OutputFile, output_files


@dataclass
class JobResult:
    """What came of one job.

    ``ok``: the command succeeded and every output is there; ``message``: what the command
    printed on stderr (its error, or its warnings); ``outputs``: the files written, with sizes
    and checksums; ``seconds``: wall time; ``cpu_seconds``: CPU time of the worker and the
    processes it waited for (the encoder, the speech synthesizer); ``max_rss``: the worker's
    peak resident memory so far, bytes; ``pid``: the worker process.
    """

    id: str
    ok: bool
    message: str = ""
    outputs: list[OutputFile] = field(default_factory=list)
    seconds: float = 0.0
    cpu_seconds: float = 0.0
    max_rss: int = 0
    pid: int = 0
    internal: bool = False  # a bug, not bad input (its traceback is in message)


def _cpu_seconds() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _remove_stale_parts(out_dir: Path, job: Job) -> None:
    """Temporary files of this job's outputs left by a worker that died writing them
    (:func:`vtts.atomic.atomic_path` names them ``.NAME.XXXXXXXX.partSUFFIX``)."""
    for rel in job.outputs:
        if rel.endswith("/"):
            continue
        dest = out_dir / rel
        if dest.parent.is_dir():
            for p in dest.parent.glob(f".{dest.name[:40]}.*.part*"):
                with contextlib.suppress(OSError):
                    p.unlink()


class JobRunner:
    """Runs jobs one at a time in this process, as the ``vtts`` command would, with heads and
    renderers kept between them.

    ``cwd``: the folder relative input paths are read from (``vtts batch``'s working folder;
    None: this process's); ``lp_threads``: Mesa llvmpipe's rasterizer threads for this process
    (``LP_NUM_THREADS``, unless the environment sets it; it must be set before the first
    render); ``cpus``: the CPUs a lip-sync job's recognition may count on, this worker's share
    of the machine's (:func:`vtts.speech.recognize.set_cpus`: at 1 it forks no second
    process); None: every CPU the process may run on.
    """

    def __init__(
        self, cwd: str | None = None, lp_threads: int | None = None, cpus: int | None = None
    ) -> None:
        from vtts.speech.recognize import set_cpus
        from vtts.warm import Warm

        if lp_threads is not None:
            os.environ.setdefault("LP_NUM_THREADS", str(lp_threads))
        set_cpus(cpus)
        if cwd is not None:
            os.chdir(cwd)
        self.warm = Warm()
        self.jobs = 0

    def pid(self) -> int:
        """This worker's process id."""
        return os.getpid()

    def warm_up(self) -> float:
        """Load what every job needs (the commands, pyrender, the EGL context) now rather than
        in the first job; returns the seconds it took."""
        t0 = time.perf_counter()
        from vtts.batch.jobs import COMMANDS
        from vtts.render import warm_up

        for command in COMMANDS:
            command_function(command)

        warm_up()
        return time.perf_counter() - t0

    def run(self, job: Job, out_dir: str) -> JobResult:
        """Run ``job`` (its outputs under ``out_dir``): a :class:`JobResult`, never an
        exception."""
        from vtts.api.reporting import run_reported

        self.jobs += 1
        t0, c0 = time.perf_counter(), _cpu_seconds()
        err, out = io.StringIO(), io.StringIO()
        internal = False
        outputs: list[OutputFile] = []
        function = command_function(job.command)

        def command() -> int:
            # again now: a link made in the folder since the jobs were read must not carry an
            # output out of it either
            for rel in job.outputs:
                check_confined(out_dir, rel.rstrip("/"), "output")
            function(job.options)  # which refuses outputs that would replace an input
            return 0

        try:
            _remove_stale_parts(Path(out_dir), job)
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out), self.warm:
                code = run_reported(command)
            outputs = output_files(out_dir, job) if code == 0 else []
        except FileNotFoundError as e:
            code = 1
            err.write(f"error: the command succeeded but wrote no {e.filename or e}\n")
        except Exception:
            code, internal = 1, True
            err.write("error: internal error (a bug in vtts):\n" + traceback.format_exc())
        usage = resource.getrusage(resource.RUSAGE_SELF)
        return JobResult(
            id=job.id,
            ok=code == 0,
            message=err.getvalue(),
            outputs=outputs,
            seconds=time.perf_counter() - t0,
            cpu_seconds=_cpu_seconds() - c0,
            max_rss=usage.ru_maxrss * 1024,
            pid=os.getpid(),
            internal=internal,
        )
