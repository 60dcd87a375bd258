"""The ``vtts`` and ``adi`` commands run inside the test's process: :func:`vtts` and :func:`adi`
return what :func:`subprocess.run` would (a :class:`subprocess.CompletedProcess` with the exit
status and stdout and stderr, as text or, with ``text=False``, bytes), without the second of a
new interpreter's start-up and imports. A test that runs a command in its own process uses them
rather than calling ``main`` and capturing its output by hand.

They run the commands' own entry points (``vtts.cli._main.main``, ``adt_tools.cli.main``): the
argument parser, the command, and :func:`vtts.api.reporting.run_reported`, which turns bad input
into one line on stderr and an exit status. What only a real process shows — the console
script's exit (``vtts.cli._main.run``), signals, resource limits, a traceback that would reach
the user — is tested with subprocesses (``tests/hostile.py``); a command that raises here fails
the test with the exception, as its traceback would.

The command reads ``stdin`` from an OS pipe, as a process in a pipeline does (empty by default);
it writes to ``sys.stdout`` and ``sys.stderr`` (and their binary ``buffer``), which are captured:
what a library's C++ or a child process writes to the file descriptors themselves is not (pytest
keeps it with the test's own output). Its working folder is ``cwd`` for the call, the environment
has ``env``'s additions, and the SIGTERM and SIGHUP handlers the command installs are put back
afterwards.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path


def vtts(*args: str | os.PathLike, cwd: Path | None = None, env: dict[str, str] | None = None,
         stdin: bytes = b"", text: bool = True) -> subprocess.CompletedProcess:  # fmt: skip
    """``vtts ARGS`` in this process."""
    from vtts.cli._main import main

    return _run(main, "vtts", args, cwd, env, stdin, text)


def adi(*args: str | os.PathLike, cwd: Path | None = None, env: dict[str, str] | None = None,
        stdin: bytes = b"", text: bool = True) -> subprocess.CompletedProcess:  # fmt: skip
    """``adi ARGS`` in this process."""
    from adt_tools.cli import main

    return _run(main, "adi", args, cwd, env, stdin, text)


def _run(
    main: Callable[[list[str]], int], tool: str, args, cwd, env, stdin: bytes, text: bool
) -> subprocess.CompletedProcess:
    argv = [os.fspath(a) for a in args]
    out, err = _Capture(), _Capture()
    with (
        _folder(cwd),
        _environment(env or {}),
        _signals_kept(),
        _stdin_pipe(stdin),
        _streams(out, err),
    ):
        try:
            code = main(argv)
        except SystemExit as e:  # argparse: --help, --version, a usage error
            # as the interpreter ends a process with it
            code = e.code if isinstance(e.code, int) else int(e.code is not None)
            if not isinstance(e.code, int | None):
                print(e.code, file=sys.stderr)
    return subprocess.CompletedProcess([tool, *argv], code, out.output(text), err.output(text))


class _Capture(io.TextIOWrapper):
    """A text stream with a binary ``buffer`` beneath (commands that write bytes to stdout use
    ``sys.stdout.buffer``), read back as a subprocess's output."""

    def __init__(self) -> None:
        super().__init__(io.BytesIO(), encoding="utf-8", errors="surrogateescape",
                         write_through=True)  # fmt: skip

    def isatty(self) -> bool:
        return False

    def output(self, text: bool) -> str | bytes:
        """What was written: bytes, or text as ``subprocess.run(text=True, errors="replace")``
        reads it (UTF-8, universal newlines)."""
        self.flush()
        data = self.buffer.getvalue()
        if not text:
            return data
        return io.TextIOWrapper(io.BytesIO(data), encoding="utf-8", errors="replace").read()


@contextlib.contextmanager
def _streams(out: _Capture, err: _Capture) -> Iterator[None]:
    saved = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = out, err
    try:
        yield
    finally:
        sys.stdout, sys.stderr = saved


@contextlib.contextmanager
def _stdin_pipe(data: bytes) -> Iterator[None]:
    """``sys.stdin`` the read end of an OS pipe that carries ``data``, then ends; a thread writes
    what the pipe's buffer cannot hold at once."""
    read, write = os.pipe()
    feeder = threading.Thread(target=_feed, args=(write, data), daemon=True)
    feeder.start()  # with no data, it only closes the pipe
    saved = sys.stdin
    sys.stdin = open(read, encoding="utf-8")  # noqa: SIM115 (closed below)
    try:
        yield
    finally:
        sys.stdin.close()  # a command that did not read it all: the feeder's write fails
        sys.stdin = saved
        feeder.join()


def _feed(fd: int, data: bytes) -> None:
    try:
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view) :]
    except BrokenPipeError:
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def _folder(cwd: Path | None) -> Iterator[None]:
    before = os.getcwd()
    if cwd is not None:
        os.chdir(cwd)
    try:
        yield
    finally:
        os.chdir(before)


@contextlib.contextmanager
def _environment(extra: dict[str, str]) -> Iterator[None]:
    saved = {k: os.environ.get(k) for k in extra}
    os.environ.update(extra)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextlib.contextmanager
def _signals_kept() -> Iterator[None]:
    saved = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for s, handler in saved.items():
            signal.signal(s, handler)
