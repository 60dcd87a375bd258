"""Batch jobs: one JSON object per line of a ``.jsonl`` file, each a ``say``, ``play`` or
``render`` command with the command's own options.

``{"id": "q17", "say": "Hello <smile>", "model": ["cybatt"], "voice": "en-us",
"output": "q17.mp4"}`` is ``vtts say "Hello <smile>" --model cybatt --voice en-us -o
DIR/q17.mp4``: the command's key carries its positional argument (the text of ``say``, the
stream of ``play``; ``"render": true``), every other key is one of the command's options by its
long name (``png_dir`` or ``png-dir``), a list repeats it, ``true``/``false`` set or leave out a
flag. A job becomes the command's options dataclass (:data:`COMMANDS`: ``vtts.SayOptions``,
``PlayOptions``, ``RenderOptions``), checked as the command checks it, and runs the library
function the command runs. Outputs (``output``, ``png_dir``, ``fap_out``, ``wav_out``, ``web``,
every ``*_out``) are relative paths under the batch's output folder; input paths mean what they
mean on the command line (relative to the working folder ``vtts batch`` runs in).
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import types
import typing
from collections.abc import Iterable
from dataclasses import dataclass, field, fields
from functools import cache
from pathlib import Path, PurePosixPath

from vtts.errors import VttsError

#: The commands a job may run: the module of each, with its options class and its function.
COMMANDS = {
    "say": ("vtts.api.say", "SayOptions", "say"),
    "play": ("vtts.api.play", "PlayOptions", "play"),
    "render": ("vtts.api.render", "RenderOptions", "render"),
}
#: The field each command's key fills (``render`` has none).
POSITIONAL = {"say": "text", "play": "stream", "render": None}
#: Options that name what a job writes: files (these, the commands' own list of outputs, and
#: every ``*_out`` option), and folders (every file in them).
OUTPUT_FILES = ("output", "fap_out", "wav_out")
OUTPUT_FOLDERS = ("png_dir", "web")
#: The batch's own files in its folder (:mod:`vtts.batch.manifest`), which no job may write.
RESERVED = ("manifest.jsonl", "failures.jsonl")
#: Fields a job may not give: the batch runs its jobs quietly.
NOT_OPTIONS = ("progress",)
#: The most characters of a job id, and of a job line.
MAX_ID = 200
MAX_LINE = 1 << 20


def is_output_file(name: str) -> bool:
    """Whether option ``name`` names a file a command writes."""
    from vtts.api.options import OUTPUT_OPTIONS

    return name in OUTPUT_FILES or name.endswith("_out") or name in OUTPUT_OPTIONS


class JobError(VttsError):
    """A job line that is not a valid job (its ``file`` and ``line`` locate it)."""


@dataclass(frozen=True)
class Job:
    """One checked job.

    ``id``: the job's name (its ``"id"``, else its first output); ``command``: ``say``,
    ``play`` or ``render``; ``options``: the command's options (``vtts.SayOptions``, …), its
    outputs under the batch's folder; ``outputs``: those outputs relative to that folder
    (POSIX paths; folders end in ``/``); ``digest``: the SHA-256 of the job as written (the
    manifest redoes a job whose line changed); ``line``: its line number in the jobs file.
    """

    id: str
    command: str
    options: object = field(compare=False, repr=False)
    outputs: tuple[str, ...] = ()
    digest: str = ""
    line: int | None = None
    spec: dict = field(default_factory=dict, compare=False, repr=False)


def command_function(command: str):
    """The library function a ``command`` job runs (``vtts.say``, ``vtts.play``,
    ``vtts.render_still``)."""
    import importlib

    module, _, function = COMMANDS[command]
    return getattr(importlib.import_module(module), function)


def options_class(command: str) -> type:
    """The options dataclass of a ``command`` job."""
    import importlib

    module, cls, _ = COMMANDS[command]
    return getattr(importlib.import_module(module), cls)


@dataclass(frozen=True)
class OptionSpec:
    """One option a job may give: the options field it fills and what it takes (``flag``: true
    or false; ``list``: one value or a list; ``int``, ``float``, ``str``: one value)."""

    name: str
    kind: str


def option_kind(hint) -> str:
    """What a field annotated ``hint`` takes from a job (see :class:`OptionSpec`)."""
    args = [a for a in typing.get_args(hint) if a is not type(None)]
    if typing.get_origin(hint) in (typing.Union, types.UnionType) and len(args) == 1:
        hint = args[0]
    if hint is bool:
        return "flag"
    if typing.get_origin(hint) is list:
        return "list"
    if hint in (int, float):
        return hint.__name__
    return "str"


@cache
def job_options(command: str) -> dict[str, OptionSpec]:
    """The options a ``command`` job may give, by their long names with ``_`` and with ``-``:
    the fields of the command's options dataclass, but for its positional one (the command's
    key holds that; ``say``'s ``text`` is ``--text``) and :data:`NOT_OPTIONS`."""
    cls = options_class(command)
    hints = typing.get_type_hints(cls)
    names: dict[str, OptionSpec] = {}
    for f in fields(cls):
        if not f.init or f.name in NOT_OPTIONS:
            continue
        spec = OptionSpec(f.name, option_kind(hints[f.name]))
        names[f.name] = names[f.name.replace("_", "-")] = spec
    return names


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


def check_confined(out_dir: str | os.PathLike[str], rel: str, key: str) -> None:
    """``rel`` (an output of option ``key``, from :func:`_inside`) stays under ``out_dir`` once
    links are followed: ``clips/link -> /elsewhere`` inside the folder must not carry a job's
    output out of it. Raises :class:`JobError`."""
    # the parts that exist are looked at one by one (a batch of many lines pays one lstat for
    # an output at the top of its folder); only a link among them needs the whole path resolved
    path = Path(out_dir)
    for part in rel.split("/"):
        path = path / part
        try:
            mode = os.lstat(path).st_mode
        except OSError:
            return  # nothing below a missing part exists, so no link either
        if stat.S_ISLNK(mode):
            break
    else:
        return
    try:
        root = Path(out_dir).resolve()
        path = root.joinpath(*rel.split("/")).resolve()
    except (OSError, RuntimeError) as e:  # a loop of links: RuntimeError before Python 3.13
        raise JobError(f"'{key}': {rel!r} cannot be followed to a place: {e}") from None
    if path != root and root not in path.parents:
        raise JobError(
            f"'{key}': {rel!r} leads out of the batch's folder (--out) through a link, to {path}"
        )


def _value(key: str, value, option: OptionSpec):
    """A job's value for option ``key`` as the options field takes it."""
    if option.kind == "flag":
        if not isinstance(value, bool):
            raise JobError(f"'{key}' is a flag: give true or false, got {json.dumps(value)}")
        return value
    items = value if isinstance(value, list) else [value]
    if len(items) > 1 and option.kind != "list":
        raise JobError(f"'{key}' takes one value, got {len(items)}")
    out = []
    for item in items:
        if isinstance(item, bool) or not isinstance(item, str | int | float):
            raise JobError(f"'{key}' takes a string or a number, got {json.dumps(item)}")
        text = str(item)
        try:
            out.append(int(text) if option.kind == "int" else
                       float(text) if option.kind == "float" else text)  # fmt: skip
        except ValueError:
            whole = "a whole number" if option.kind == "int" else "a number"
            raise JobError(f"'{key}' takes {whole}, got {json.dumps(item)}") from None
    if option.kind == "list":
        return out
    return out[0] if out else None


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
    """Check one job (a dict as JSON gives it) and make its command's options, its outputs
    under ``out_dir``. Raises :class:`JobError` naming the key and the rule broken."""
    if not isinstance(spec, dict):
        raise JobError(f"a job is a JSON object, got {type(spec).__name__}")
    commands = [c for c in COMMANDS if c in spec]
    if len(commands) != 1:
        given = " and ".join(f"'{c}'" for c in commands) or "none of them"
        raise JobError(f"a job runs one of 'say', 'play' or 'render'; this one gives {given}")
    (command,) = commands
    options = job_options(command)
    values: dict = {}
    outputs: list[str] = []
    text_option = None
    for key, value in spec.items():
        if _has_nul(value):
            raise JobError(f"'{key}' holds a NUL character, which no command line can")
        if key in ("id", command) or value is None:
            continue
        if command == "say" and key == "text":  # --text: the text as an option
            text_option = _value(key, value, OptionSpec("text", "str"))
            continue
        option = options.get(key)
        if option is None or option.name == POSITIONAL[command]:
            known = sorted({o.name for o in options.values()} - {POSITIONAL[command]})
            if command == "say":
                known = sorted([*known, "text"])
            raise JobError(f"vtts {command} has no option '{key}' (it has: id, {', '.join(known)})")
        if option.name in OUTPUT_FOLDERS or is_output_file(option.name):
            if not isinstance(value, str):
                raise JobError(f"'{key}' takes a path, got {json.dumps(value)}")
            rel = _inside(value, key)
            check_confined(out_dir, rel, key)
            outputs.append(rel + ("/" if option.name in OUTPUT_FOLDERS else ""))
            value = os.path.join(os.fspath(out_dir), *rel.split("/"))
        values[option.name] = _value(key, value, option)
    positional = spec[command]
    if command == "say":
        if positional is not None and not isinstance(positional, str):
            raise JobError(f"'say' takes the text, got {json.dumps(positional)}")
        values["text"] = positional or ""
    elif command == "play":
        if not isinstance(positional, str) or not positional:
            raise JobError(
                f"'play' takes the .fap or .fbs stream to play, got {json.dumps(positional)}"
            )
        if positional == "-":
            raise JobError("'play' in a batch plays a file: '-' (stdin) is for vtts play -")
        values["stream"] = positional
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
    made = job_command_options(command, values, text_option)
    return Job(job_id, command, made, tuple(outputs), job_digest(spec), line, spec)


def job_command_options(command: str, values: dict, text_option: str | None = None):
    """The options dataclass of a ``command`` job from its ``values`` by field (what the
    command would refuse, the job refuses: a :class:`JobError` naming the command)."""
    try:
        options = options_class(command)(**values)
        if command == "say":
            from vtts.api.say import merged_text

            options.text = merged_text(options.text, text_option, options.file)
    except VttsError as e:
        where = e.location()
        raise JobError(f"vtts {command}: {where + ': ' if where else ''}{e.message}") from None
    return options


@dataclass
class JobsFile:
    """The jobs of a file: the valid ones, and an error for each bad line (with its number)."""

    jobs: list[Job]
    errors: list[JobError]


def check_unique(jobs: list[Job], errors: list[JobError], file: str | None = None) -> list[Job]:
    """The jobs without those whose id or an output an earlier job already has (an error each
    in ``errors``)."""
    ids: dict[str, Job] = {}
    written = Written()
    kept = []
    for job in jobs:
        if job.id in ids:
            first = ids[job.id]
            where = f"line {first.line}" if first.line is not None else "an earlier job"
            errors.append(
                JobError(f"id '{job.id}' is also the id on {where}", file=file, line=job.line)
            )
            continue
        own = Written()
        try:
            for o in job.outputs:
                for earlier in (written, own):
                    clash = earlier.clash(o)
                    if clash is not None:
                        path, first = clash
                        where = (
                            "this job's other output" if first is None
                            else f"line {first.line}" if first.line is not None
                            else f"job '{first.id}'"
                        )  # fmt: skip
                        raise JobError(f"'{path}' is also written by {where}")
                own.add(o, None)
        except JobError as e:
            e.file, e.line = file, job.line
            errors.append(e)
            continue
        ids[job.id] = job
        for o in job.outputs:
            written.add(o, job)
        kept.append(job)
    return kept


class Written:
    """The outputs of the jobs so far (relative POSIX paths, folders ending in ``/``), to find
    a clash: the same path, or a path inside a folder output (a ``web`` folder's ``index.html``
    is written by the job that writes the folder) or inside another output however given."""

    def __init__(self) -> None:
        self.paths: dict[str, Job | None] = {}
        # every folder above an output, with the job of one output under it
        self.above: dict[str, Job | None] = {}

    def add(self, output: str, job: Job | None) -> None:
        key = output.rstrip("/")
        self.paths[key] = job
        parts = key.split("/")
        for n in range(1, len(parts)):
            self.above.setdefault("/".join(parts[:n]), job)

    def clash(self, output: str) -> tuple[str, Job | None] | None:
        """(the path two outputs share, the earlier job) when ``output`` clashes, else None."""
        key = output.rstrip("/")
        if key in self.paths:
            return key, self.paths[key]
        if key in self.above:  # an earlier output lies inside this one
            return key, self.above[key]
        parts = key.split("/")
        for n in range(1, len(parts)):
            folder = "/".join(parts[:n])
            if folder in self.paths:  # this one lies inside an earlier output
                return key, self.paths[folder]
        return None


def read_jobs(path: str | os.PathLike[str], out_dir: str | os.PathLike[str]) -> JobsFile:
    """The jobs of a ``.jsonl`` file (blank lines skipped), each checked by :func:`parse_job`;
    a bad line becomes a :class:`JobError` with its line (and, for bad JSON, column) instead of
    stopping the others. Raises :class:`JobError` when the file cannot be read."""
    from vtts.limits import MAX_JOBS, MAX_JOBS_BYTES, LimitError, read_bytes_capped

    name = os.fspath(path)
    try:
        data = read_bytes_capped(path, MAX_JOBS_BYTES, what="the jobs file")
    except LimitError as e:
        raise JobError(e.message, file=name) from None
    except OSError as e:
        raise JobError(f"cannot read the jobs: {e.strerror or e}", file=name) from None
    lines = data.split(b"\n")
    count = sum(1 for raw in lines if not raw.isspace() and raw)
    if count > MAX_JOBS:
        raise JobError(
            f"{count} jobs in one file, more than the limit of {MAX_JOBS}: split it into "
            "several batches",
            file=name,
        )
    jobs: list[Job] = []
    errors: list[JobError] = []
    for n, raw in enumerate(lines, 1):
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
    kept = []
    for job in jobs:
        if any(_is_file(os.path.join(out_dir, o), name) for o in job.outputs):
            errors.append(
                JobError("an output of this job is the jobs file", file=name, line=job.line)
            )
        else:
            kept.append(job)
    errors.sort(key=lambda e: e.line or 0)
    return JobsFile(kept, errors)


def _is_file(output: str, jobs_file: str) -> bool:
    """Whether ``output`` is the file ``jobs_file`` (through any link): an output that does not
    exist yet is not, so that most cost one ``stat``, not a path resolved part by part."""
    try:
        return os.path.samefile(output, jobs_file)
    except OSError:
        return False


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
    """What can be checked of ``job`` without running it, beyond its options: what the command
    checks before it starts (its outputs against each other and its inputs, its pose's
    values), the files it reads are there, its heads load, and a ``say`` text's bookmarks are
    ones its heads know.
    ``models`` keeps loaded heads between calls. Raises :class:`JobError` with the message the
    command would give."""
    from vtts.api.options import check_io
    from vtts.face import load_model
    from vtts.limits import MAX_TEXT_BYTES, read_bytes_capped
    from vtts.speech.bookmarks import parse_bookmarks

    models = {} if models is None else models
    options = job.options
    try:
        check_io(options)
        if hasattr(options, "pose_values"):
            options.pose_values()
        for key in INPUT_FILES:
            name = getattr(options, key, None)
            if name and not Path(name).is_file():
                raise VttsError("no such file", file=name)
        heads = []
        for m in options.model:
            key = (m, tuple(options.url_root or ()))
            if key not in models:
                models[key] = load_model(m, url_root=options.url_root)
            heads.append(models[key])
        if job.command == "say":
            text = options.text
            if options.file:
                raw = read_bytes_capped(options.file, MAX_TEXT_BYTES, what="text")
                text = raw.decode("utf-8", errors="replace")
            # the heads' expressions, once per set of heads (a batch has many jobs, few heads)
            heads_key = ("expressions", *(id(h) for h in heads))
            if heads_key not in models:
                models[heads_key] = {
                    x.name for h in heads for x in h.tables.adts if x.kind == "expression"
                }
            parse_bookmarks(text or "", models[heads_key])
    except VttsError as e:
        where = e.location()
        raise JobError(f"vtts {job.command}: {where + ': ' if where else ''}{e.message}") from None


def dry_run(path: str | os.PathLike[str], out_dir: str | os.PathLike[str]) -> JobsFile:
    """The jobs of a ``.jsonl`` file checked as far as they can be without running them
    (:func:`read_jobs`, then :func:`preflight` each): the valid ones, and every error sorted by
    line."""
    checked = read_jobs(path, out_dir)
    models: dict = {}
    kept = []
    for job in checked.jobs:
        try:
            preflight(job, models)
        except JobError as e:
            e.file, e.line = os.fspath(path), job.line
            checked.errors.append(e)
        else:
            kept.append(job)
    checked.jobs = kept
    checked.errors.sort(key=lambda e: e.line or 0)
    return checked
