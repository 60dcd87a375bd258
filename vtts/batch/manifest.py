"""The batch's record of finished jobs, ``DIR/manifest.jsonl``, and of failed ones,
``DIR/failures.jsonl``.

Each finished job appends one line: its id, the digest of the job as written, and each output's
path (relative to DIR), size and SHA-256. A job counts as finished when its last line has the
job's digest and every output is there with that size and checksum; anything else (no line, a
changed job, an output missing, cut short or changed) runs it again. Lines are appended and
flushed one at a time by the one process that drives the batch, so a batch stopped at any moment
leaves at worst a cut-off last line, which reading skips.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

from vtts.atomic import write_text
from vtts.batch.jobs import Job

MANIFEST = "manifest.jsonl"
FAILURES = "failures.jsonl"


@dataclass(frozen=True)
class OutputFile:
    """One file a job wrote: ``path`` relative to the batch's folder (POSIX), ``size`` in
    bytes, ``sha256`` hex."""

    path: str
    size: int
    sha256: str

    def as_dict(self) -> dict:
        return {"path": self.path, "size": self.size, "sha256": self.sha256}


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            h.update(chunk)
    return h.hexdigest()


def output_files(out_dir: str | os.PathLike[str], job: Job) -> list[OutputFile]:
    """The files ``job`` wrote under ``out_dir`` (every file of an output folder, sorted), with
    their sizes and checksums; a missing output raises :class:`FileNotFoundError`."""
    root = Path(out_dir)
    found: list[OutputFile] = []
    for rel in job.outputs:
        path = root / rel
        if rel.endswith("/"):
            if not path.is_dir():
                raise FileNotFoundError(f"no output folder {path}")
            files = sorted(p for p in path.rglob("*") if p.is_file())
        else:
            files = [path]
        for f in files:
            st = f.stat()
            found.append(OutputFile(f.relative_to(root).as_posix(), st.st_size, file_sha256(f)))
    return found


class Manifest:
    """``DIR/manifest.jsonl``: which jobs are finished (see the module)."""

    def __init__(self, out_dir: str | os.PathLike[str]) -> None:
        self.dir = Path(out_dir)
        self.path = self.dir / MANIFEST
        self.entries: dict[str, dict] = {}
        self._read()

    def _read(self) -> None:
        try:
            text = self.path.read_text(encoding="utf-8", errors="replace")
        except FileNotFoundError:
            return
        for line in text.splitlines():
            try:
                entry = json.loads(line)
            except json.JSONDecodeError:
                continue  # a line cut off when the batch was stopped
            if isinstance(entry, dict) and isinstance(entry.get("id"), str):
                self.entries[entry["id"]] = entry

    def finished(self, job: Job) -> bool:
        """Whether ``job`` is finished: recorded with its digest, every output as recorded."""
        entry = self.entries.get(job.id)
        if entry is None or entry.get("digest") != job.digest:
            return False
        recorded = entry.get("outputs")
        if not isinstance(recorded, list) or not recorded:
            return False
        try:
            now = output_files(self.dir, job)
        except OSError:
            return False
        return [f.as_dict() for f in now] == recorded

    def record(self, job: Job, outputs: list[OutputFile], **facts) -> None:
        """Append ``job`` as finished with its ``outputs`` (and any ``facts``: seconds, …)."""
        entry = {
            "id": job.id,
            "digest": job.digest,
            "outputs": [f.as_dict() for f in outputs],
            **facts,
        }
        self.dir.mkdir(parents=True, exist_ok=True)
        with open(self.path, "a", encoding="utf-8") as f:
            f.write(json.dumps(entry, ensure_ascii=False) + "\n")
            f.flush()
            os.fsync(f.fileno())
        self.entries[job.id] = entry


def write_failures(out_dir: str | os.PathLike[str], failures: list[dict]) -> Path:
    """``DIR/failures.jsonl``: one line per failed job (written whole, atomically, when it
    changed); removed when there is none."""
    path = Path(out_dir) / FAILURES
    if not failures:
        path.unlink(missing_ok=True)
        return path
    text = "".join(json.dumps(f, ensure_ascii=False) + "\n" for f in failures)
    try:
        if path.read_text(encoding="utf-8") == text:
            return path
    except (OSError, UnicodeDecodeError):
        pass
    write_text(path, text)
    return path


def read_failures(out_dir: str | os.PathLike[str]) -> dict[str, dict]:
    """The failed jobs ``DIR/failures.jsonl`` records, by id (bad lines, which have none, and
    lines that do not read are left out)."""
    try:
        text = (Path(out_dir) / FAILURES).read_text(encoding="utf-8", errors="replace")
    except OSError:
        return {}
    out = {}
    for line in text.splitlines():
        try:
            entry = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(entry, dict) and isinstance(entry.get("id"), str):
            out[entry["id"]] = entry
    return out
