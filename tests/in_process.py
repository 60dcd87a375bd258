"""The ``vtts`` and ``adi`` commands run inside the test's process: :func:`vtts` and :func:`adi`
return what :func:`subprocess.run` would (a :class:`subprocess.CompletedProcess` with the exit
status and the text of stdout and stderr), without the second of a new interpreter's start-up
and imports.

They run the commands' own entry points (``vtts.cli._main.main``, ``adt_tools.cli.main``): the
argument parser, the command, and :func:`vtts.api.reporting.run_reported`, which turns bad input
into one line on stderr and an exit status. What only a real process shows — the console
script's exit (``vtts.cli._main.run``), signals, pipes on stdin and stdout, resource limits, a
traceback that would reach the user — is tested with subprocesses (``tests/hostile.py``); a
command that raises here fails the test with the exception, as its traceback would.

The command sees an empty stdin (no terminal, no pipe), its working folder is ``cwd`` for the
call, the environment has ``env``'s additions, and the SIGTERM and SIGHUP handlers the command
installs are put back afterwards.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path


def vtts(*args: str | os.PathLike, cwd: Path | None = None,
         env: dict[str, str] | None = None) -> subprocess.CompletedProcess:  # fmt: skip
    """``vtts ARGS`` in this process."""
    from vtts.cli._main import main

    return _run(main, "vtts", args, cwd, env)


def adi(*args: str | os.PathLike, cwd: Path | None = None,
        env: dict[str, str] | None = None) -> subprocess.CompletedProcess:  # fmt: skip
    """``adi ARGS`` in this process."""
    from adt_tools.cli import main

    return _run(main, "adi", args, cwd, env)


def _run(
    main: Callable[[list[str]], int], tool: str, args, cwd, env
) -> subprocess.CompletedProcess:
    argv = [os.fspath(a) for a in args]
    out, err = _Capture(), _Capture()
    with _folder(cwd), _environment(env or {}), _signals_kept(), _streams(out, err):
        try:
            code = main(argv)
        except SystemExit as e:  # argparse: --help, --version, a usage error
            code = e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
    return subprocess.CompletedProcess([tool, *argv], code, out.text(), err.text())


class _Capture(io.TextIOWrapper):
    """A text stream with a binary ``buffer`` beneath (commands that write bytes to stdout use
    ``sys.stdout.buffer``), read back as a subprocess's ``text=True, errors="replace"``."""

    def __init__(self) -> None:
        super().__init__(io.BytesIO(), encoding="utf-8", errors="surrogateescape",
                         write_through=True)  # fmt: skip

    def isatty(self) -> bool:
        return False

    def text(self) -> str:
        self.flush()
        return self.buffer.getvalue().decode("utf-8", errors="replace")


@contextlib.contextmanager
def _streams(out: _Capture, err: _Capture) -> Iterator[None]:
    saved = sys.stdin, sys.stdout, sys.stderr
    sys.stdin = io.TextIOWrapper(io.BytesIO(b""), encoding="utf-8")
    sys.stdout, sys.stderr = out, err
    try:
        yield
    finally:
        sys.stdin, sys.stdout, sys.stderr = saved


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
