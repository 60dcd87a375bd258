"""Batch jobs: one JSON object per line of a ``.jsonl`` file, each a ``say``, ``play`` or
``render`` command with the command's own options.

``{"id": "q17", "say": "Hello <smile>", "model": ["cybatt"], "voice": "en-us",
"output": "q17.mp4"}`` is ``vtts say "Hello <smile>" --model cybatt --voice en-us -o
DIR/q17.mp4``: the command's key carries its positional argument (the text of ``say``, the
stream of ``play``; ``"render": true``), every other key is one of the command's options by its
long name (``png_dir`` or ``png-dir``), a list repeats it, ``true``/``false`` set or leave out a
flag. A job is checked by the command's own argument parser, so it takes exactly what the
command line takes. Outputs (``output``, ``png_dir``, ``fap_out``, ``wav_out``, ``web``) are
relative paths under the batch's output folder; input paths mean what they mean on the command
line (relative to the working folder ``vtts batch`` runs in).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path, PurePosixPath

from vtts.errors import VttsError

#: The commands a job may run.
COMMANDS = ("say", "play", "render")
#: Options that name what a job writes: files (these, the commands' own list of outputs, and
#: every ``--*-out`` option), and folders (every file in them).
OUTPUT_FILES = ("output", "fap_out", "wav_out")
OUTPUT_FOLDERS = ("png_dir", "web")


def _is_output_file(dest: str) -> bool:
    from vtts import cli

    return dest in OUTPUT_FILES or dest.endswith("_out") or dest in cli.OUTPUT_OPTIONS


#: The batch's own files in its folder (:mod:`vtts.batch.manifest`), which no job may write.
RESERVED = ("manifest.jsonl", "failures.jsonl")
#: Options a job may not give: the batch runs its jobs quietly.
_NOT_OPTIONS = ("help", "quiet", "command", "func", "gltf")
#: The most characters of a job id, and of a job line.
MAX_ID = 200
MAX_LINE = 1 << 20


class JobError(VttsError):
    """A job line that is not a valid job (its ``file`` and ``line`` locate it)."""


@dataclass(frozen=True)
class Job:
    """One checked job.

    ``id``: the job's name (its ``"id"``, else its first output); ``command``: ``say``,
    ``play`` or ``render``; ``argv``: the command line it runs (``vtts`` not included), its
    outputs under the batch's folder; ``outputs``: those outputs relative to that folder
    (POSIX paths; folders end in ``/``); ``digest``: the SHA-256 of the job as written (the
    manifest redoes a job whose line changed); ``line``: its line number in the jobs file.
    """

    id: str
    command: str
    argv: tuple[str, ...]
    outputs: tuple[str, ...]
    digest: str
    line: int | None = None
    spec: dict = field(default_factory=dict, compare=False, repr=False)


@cache
def _parsers() -> dict[str, argparse.ArgumentParser]:
    """The ``vtts`` sub-command parsers of :data:`COMMANDS`, raising :class:`JobError` instead
    of printing usage and exiting."""
    from vtts.cli import build_parser

    top = build_parser()

    def fail(message: str):
        raise JobError(message)

    top.error = fail  # type: ignore[method-assign]
    out = {}
    for action in top._subparsers._group_actions:  # the sub-commands (argparse has no API)
        for name, parser in action.choices.items():
            if name in COMMANDS:
                parser.error = fail  # type: ignore[method-assign]
                out[name] = parser
    out["_top"] = top
    return out


def _options(command: str) -> dict[str, argparse.Action]:
    """The options a ``command`` job may give, by their long names with ``_`` and with ``-``."""
    names: dict[str, argparse.Action] = {}
    for action in _parsers()[command]._actions:
        if not action.option_strings or action.dest in _NOT_OPTIONS:
            continue
        for opt in action.option_strings:
            if opt.startswith("--"):
                names[opt[2:]] = action
                names[opt[2:].replace("-", "_")] = action
    return names


def _flag(action: argparse.Action) -> str:
    return next(o for o in action.option_strings if o.startswith("--"))


def _inside(path: str, key: str) -> str:
    """``path`` of output option ``key`` as a normalized relative POSIX path; refuses absolute
    paths and ones that leave the batch's folder."""
    if not path or "\x00" in path:
        raise JobError(f"'{key}' must name a file under the batch's folder, got {path!r}")
    p = PurePosixPath(path.replace(os.sep, "/"))
    if p.is_absolute() or Path(path).is_absolute():
        raise JobError(
            f"'{key}': outputs are written under the batch's folder (--out): give a relative "
            f"path, got {path!r}"
        )
    parts = [x for x in p.parts if x != "."]
    if ".." in parts or not parts:
        raise JobError(f"'{key}': {path!r} leaves the batch's folder (--out)")
    if len(parts) == 1 and parts[0] in RESERVED:
        raise JobError(f"'{key}': {parts[0]} is the batch's own record in its folder")
    return "/".join(parts)


def _values(key: str, value, action: argparse.Action) -> list[str]:
    """A job's value for option ``key`` as the command-line words ``--KEY=VALUE``."""
    flag = _flag(action)
    if action.nargs == 0:  # store_true
        if not isinstance(value, bool):
            raise JobError(f"'{key}' is a flag: give true or false, got {json.dumps(value)}")
        return [flag] if value else []
    items = value if isinstance(value, list) else [value]
    if len(items) > 1 and not isinstance(action, argparse._AppendAction):
        raise JobError(f"'{key}' takes one value, got {len(items)}")
    words = []
    for item in items:
        if isinstance(item, bool) or not isinstance(item, str | int | float):
            raise JobError(f"'{key}' takes a string or a number, got {json.dumps(item)}")
        words.append(f"{flag}={item}")
    return words


def _has_nul(value) -> bool:
    if isinstance(value, str):
        return "\x00" in value
    if isinstance(value, list):
        return any(_has_nul(v) for v in value)
    if isinstance(value, dict):
        return any(_has_nul(k) or _has_nul(v) for k, v in value.items())
    return False


def job_digest(spec: dict) -> str:
    """The SHA-256 of a job as written (keys sorted): the manifest's way to tell a changed job."""
    text = json.dumps(spec, sort_keys=True, ensure_ascii=False, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def parse_job(spec, out_dir: str | os.PathLike[str], line: int | None = None) -> Job:
    """Check one job (a dict as JSON gives it) and make its command line, its outputs under
    ``out_dir``. Raises :class:`JobError` naming the rule broken."""
    if not isinstance(spec, dict):
        raise JobError(f"a job is a JSON object, got {type(spec).__name__}")
    commands = [c for c in COMMANDS if c in spec]
    if len(commands) != 1:
        given = " and ".join(f"'{c}'" for c in commands) or "none of them"
        raise JobError(f"a job runs one of 'say', 'play' or 'render'; this one gives {given}")
    (command,) = commands
    options = _options(command)
    argv: list[str] = [command]
    outputs: list[str] = []
    for key, value in spec.items():
        if _has_nul(value):
            raise JobError(f"'{key}' holds a NUL character, which no command line can")
        if key in ("id", command) or value is None:
            continue
        action = options.get(key)
        if action is None:
            known = ", ".join(sorted({a.dest for a in options.values()}))
            raise JobError(f"vtts {command} has no option '{key}' (it has: id, {known})")
        if action.dest in OUTPUT_FOLDERS or _is_output_file(action.dest):
            if not isinstance(value, str):
                raise JobError(f"'{key}' takes a path, got {json.dumps(value)}")
            rel = _inside(value, key)
            outputs.append(rel + ("/" if action.dest in OUTPUT_FOLDERS else ""))
            value = os.path.join(os.fspath(out_dir), *rel.split("/"))
        argv += _values(key, value, action)
    if command in ("say", "play"):
        argv.append("--quiet")
    positional = spec[command]
    if command == "say":
        if positional is not None and not isinstance(positional, str):
            raise JobError(f"'say' takes the text, got {json.dumps(positional)}")
        if positional:
            argv += ["--", positional]
    elif command == "play":
        if not isinstance(positional, str) or not positional:
            raise JobError(
                f"'play' takes the .fap or .fbs stream to play, got {json.dumps(positional)}"
            )
        if positional == "-":
            raise JobError("'play' in a batch plays a file: '-' (stdin) is for vtts play -")
        argv += ["--", positional]
    elif positional not in (True, None, {}):
        raise JobError(
            "'render' takes true (its options are the job's other keys), got "
            + json.dumps(positional)
        )
    if not outputs:
        raise JobError(
            f"the job writes nothing: give 'output' (or another output of vtts {command})"
        )
    job_id = spec.get("id", outputs[0])
    if not isinstance(job_id, str) or not job_id or len(job_id) > MAX_ID:
        raise JobError(f"'id' is a string of 1 to {MAX_ID} characters, got {json.dumps(job_id)}")
    if not job_id.isprintable():
        raise JobError(f"'id' must be printable, got {json.dumps(job_id)}")
    parse_argv(argv)  # what the command line would refuse, the job refuses
    return Job(job_id, command, tuple(argv), tuple(outputs), job_digest(spec), line, spec)


def parse_argv(argv: Iterable[str]) -> argparse.Namespace:
    """A job's command line parsed by ``vtts``'s own parser (:class:`JobError` for what it
    refuses)."""
    argv = list(argv)
    try:
        return _parsers()["_top"].parse_args(argv)
    except JobError as e:
        raise JobError(f"vtts {argv[0]}: {e.message}") from None


@dataclass
class JobsFile:
    """The jobs of a file: the valid ones, and an error for each bad line (with its number)."""

    jobs: list[Job]
    errors: list[JobError]


def check_unique(jobs: list[Job], errors: list[JobError], file: str | None = None) -> list[Job]:
    """The jobs without those whose id or an output an earlier job already has (an error each
    in ``errors``)."""
    ids: dict[str, Job] = {}
    written: dict[str, Job] = {}
    kept = []
    for job in jobs:
        if job.id in ids:
            first = ids[job.id]
            where = f"line {first.line}" if first.line is not None else "an earlier job"
            errors.append(
                JobError(f"id '{job.id}' is also the id on {where}", file=file, line=job.line)
            )
            continue
        clash = next((o for o in job.outputs if _key(o) in written), None)
        if clash is not None:
            first = written[_key(clash)]
            where = f"line {first.line}" if first.line is not None else f"job '{first.id}'"
            errors.append(
                JobError(
                    f"'{clash.rstrip('/')}' is also written by {where}", file=file, line=job.line
                )
            )
            continue
        ids[job.id] = job
        for o in job.outputs:
            written[_key(o)] = job
        kept.append(job)
    return kept


def _key(output: str) -> str:
    return output.rstrip("/")


def read_jobs(path: str | os.PathLike[str], out_dir: str | os.PathLike[str]) -> JobsFile:
    """The jobs of a ``.jsonl`` file (blank lines skipped), each checked by :func:`parse_job`;
    a bad line becomes a :class:`JobError` with its line (and, for bad JSON, column) instead of
    stopping the others. Raises :class:`JobError` when the file cannot be read."""
    from vtts.limits import MAX_JOBS_BYTES, LimitError, read_bytes_capped

    name = os.fspath(path)
    try:
        data = read_bytes_capped(path, MAX_JOBS_BYTES, what="the jobs file")
    except LimitError as e:
        raise JobError(e.message, file=name) from None
    except OSError as e:
        raise JobError(f"cannot read the jobs: {e.strerror or e}", file=name) from None
    jobs: list[Job] = []
    errors: list[JobError] = []
    for n, raw in enumerate(data.split(b"\n"), 1):
        if not raw.strip():
            continue
        try:
            if len(raw) > MAX_LINE:
                raise JobError(f"a job line is at most {MAX_LINE} bytes, this one has {len(raw)}")
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError:
                raise JobError("not UTF-8 text") from None
            try:
                spec = json.loads(text)
            except json.JSONDecodeError as e:
                raise JobError(f"not JSON: {e.msg}", column=e.colno) from None
            except RecursionError:
                raise JobError("not a job: its JSON is nested too deeply") from None
            jobs.append(parse_job(spec, out_dir, line=n))
        except JobError as e:
            e.file, e.line = name, n
            errors.append(e)
    jobs = check_unique(jobs, errors, name)
    for job in list(jobs):
        if any(Path(out_dir, o).resolve() == Path(path).resolve() for o in job.outputs):
            errors.append(
                JobError("an output of this job is the jobs file", file=name, line=job.line)
            )
            jobs.remove(job)
    errors.sort(key=lambda e: e.line or 0)
    return JobsFile(jobs, errors)


def as_jobs(jobs: Iterable, out_dir: str | os.PathLike[str]) -> JobsFile:
    """Jobs given to the library: :class:`Job` objects or dicts (checked as lines are; an error
    names the job's place, 1-based)."""
    out: list[Job] = []
    errors: list[JobError] = []
    for n, item in enumerate(jobs, 1):
        if isinstance(item, Job):
            out.append(item)
            continue
        try:
            out.append(parse_job(item, out_dir, line=n))
        except JobError as e:
            e.line = n
            errors.append(e)
    return JobsFile(check_unique(out, errors), errors)


#: Options of a job that name a file it reads.
INPUT_FILES = ("file", "stream", "audio", "phonemes")


def preflight(job: Job, models: dict | None = None) -> None:
    """What can be checked of ``job`` without running it, beyond its options: the files it
    reads are there, its heads load, and a ``say`` text's bookmarks are ones its heads know.
    ``models`` keeps loaded heads between calls. Raises :class:`JobError` with the message the
    command would give."""
    from vtts.face import load_model
    from vtts.limits import MAX_TEXT_BYTES, read_bytes_capped
    from vtts.speech.bookmarks import parse_bookmarks

    models = {} if models is None else models
    args = parse_argv(job.argv)
    try:
        for key in INPUT_FILES:
            name = getattr(args, key, None)
            if name and not Path(name).is_file():
                raise VttsError("no such file", file=name)
        heads = []
        for m in args.model:
            key = (m, tuple(args.url_root or ()))
            if key not in models:
                models[key] = load_model(m, url_root=args.url_root)
            heads.append(models[key])
        if job.command == "say":
            text = args.text or args.text_option
            if args.file:
                raw = read_bytes_capped(args.file, MAX_TEXT_BYTES, what="text")
                text = raw.decode("utf-8", errors="replace")
            known = {x.name for h in heads for x in h.tables.adts if x.kind == "expression"}
            parse_bookmarks(text or "", known)
    except VttsError as e:
        where = e.location()
        raise JobError(f"vtts {job.command}: {where + ': ' if where else ''}{e.message}") from None
