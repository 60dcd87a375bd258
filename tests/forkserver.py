"""The warm parent of the hostile-input tests' bounded commands (``hostile.run_bounded``).

Python's start-up and the imports a command makes are most of a small command's processor time.
This process makes them once — the modules the commands share, never the renderer's OpenGL,
which a child sets up for itself — then forks one child per request. The child is the command
as its console script runs it (``vtts``: :func:`vtts.cli.run`; ``adi``: ``adt_tools.cli.main``
and its exit status; an exception it lets through is printed as Python prints it and exits 1) in
a process of its own, under the request's limits of address space (bytes) and processor time
(seconds), in the request's folder, with stdin from /dev/null and stdout and stderr written to
the request's files.

Requests come one JSON object a line on stdin: ``tool``, ``args``, ``cwd``, ``out``, ``err``,
``memory``, ``cpu`` and ``timeout`` (wall-clock seconds). Each is answered by one line,
``{"returncode": N}`` as :mod:`subprocess` reports it (``-SIGNAL`` for a signal), ``null``
when the child ran past its timeout and was killed. The server ends when its stdin closes.
"""

from __future__ import annotations

import json
import os
import resource
import select
import signal
import sys
import traceback
from pathlib import Path
from typing import NoReturn


def warm() -> None:
    """Import what the commands share: the parsers of ``vtts`` and ``adi``, the readers, the
    face model and the commands' library modules (their imports make no thread and no OpenGL
    context)."""
    import PIL.Image  # noqa: F401

    import vtts.analysis  # noqa: F401
    import vtts.api.analyze  # noqa: F401
    import vtts.api.play  # noqa: F401
    import vtts.api.pose  # noqa: F401
    import vtts.api.render  # noqa: F401
    import vtts.api.say  # noqa: F401
    import vtts.face  # noqa: F401
    import vtts.fap.coding  # noqa: F401
    import vtts.vrml  # noqa: F401
    from adt_tools import build  # noqa: F401
    from adt_tools import cli as adi
    from vtts.cli import _main as cli

    cli.build_parser()
    adi.build_parser()


def exit_status(e: SystemExit) -> int:
    """The status the interpreter gives a process that ends with ``e``."""
    if e.code is None:
        return 0
    if isinstance(e.code, int):
        return e.code
    print(e.code, file=sys.stderr)
    return 1


def command(tool: str) -> int:
    """Run ``tool`` with ``sys.argv`` as its console script does; its exit status."""
    if tool == "vtts":
        from vtts.cli import run

        run()  # leaves the process itself
    from adt_tools.cli import main

    return main()


def child(request: dict) -> NoReturn:
    """The forked child: the limits, the folder and the files, then the command."""
    code = 1
    try:
        for limit, value in ((resource.RLIMIT_AS, request["memory"]),
                             (resource.RLIMIT_CPU, request["cpu"])):  # fmt: skip
            resource.setrlimit(limit, (value, value))
        os.chdir(request["cwd"])
        os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
        for fd, name in ((1, "out"), (2, "err")):
            os.dup2(os.open(request[name], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600), fd)
        sys.stdin = open(0, encoding=sys.stdin.encoding, closefd=False)  # noqa: SIM115
        sys.argv = [str(Path(sys.executable).with_name(request["tool"])), *request["args"]]
        code = command(request["tool"])
    except SystemExit as e:
        code = exit_status(e)
    except BaseException:
        traceback.print_exc()
        code = 1
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(code)


def wait(pid: int, timeout: float) -> int | None:
    """The status of child ``pid`` as subprocess reports it, or None when it runs past
    ``timeout`` seconds (it is killed)."""
    fd = os.pidfd_open(pid)
    try:
        ended, _, _ = select.select([fd], [], [], timeout)
    finally:
        os.close(fd)
    if not ended:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        return None
    return os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])


def serve() -> None:
    warm()
    print("ready", flush=True)
    for line in sys.stdin:
        request = json.loads(line)
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            child(request)
        print(json.dumps({"returncode": wait(pid, request["timeout"])}), flush=True)


if __name__ == "__main__":
    # the console script's path, not this folder's (tests/ holds modules a command must not see)
    sys.path[0] = str(Path(sys.executable).parent)
    serve()
