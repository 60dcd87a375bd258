"""Many clips at once: ``vtts batch JOBS.jsonl --out DIR`` on worker processes of this machine, or
on Ray.

- :mod:`~vtts.batch.jobs` — a job line (a ``say``, ``play`` or ``render`` command with the
  command's options) made into the command's options dataclass, checked as the command checks
  it: :func:`read_jobs`, :func:`parse_job`, :func:`dry_run`;
- :mod:`~vtts.batch.manifest` — ``DIR/manifest.jsonl`` (finished jobs: each output's size and
  SHA-256; a re-run skips them) and ``DIR/failures.jsonl``;
- :mod:`~vtts.batch.worker` — :class:`JobRunner`: a worker running jobs one after the other by
  the command's library function, its heads and renderers kept warm (:class:`vtts.warm.Warm`);
- :mod:`~vtts.batch.pool` — :class:`LocalPool`: the workers as processes of this machine;
- :mod:`~vtts.batch.runner` — :func:`run`: the jobs on a :class:`LocalPool`, or on Ray actors
  (a cluster, or a local Ray instance), failures isolated, dead workers replaced, a progress
  bar; :class:`BatchReport`.

Ray is imported only when a batch runs on it (the ``batch`` extra installs it).
"""

from vtts.batch.jobs import Job, JobError, dry_run, parse_job, read_jobs
from vtts.batch.manifest import Manifest
from vtts.batch.runner import BatchError, BatchReport, run
from vtts.batch.worker import JobResult, JobRunner

__all__ = [
    "BatchError",
    "BatchReport",
    "Job",
    "JobError",
    "JobResult",
    "JobRunner",
    "Manifest",
    "dry_run",
    "parse_job",
    "read_jobs",
    "run",
]
