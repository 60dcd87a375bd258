"""The ``vtts`` command: its argument parser (one sub-command per module of :mod:`vtts.cli`),
:func:`main`, :func:`execute` and the console script's :func:`run`.

Input errors are printed as ``FILE:LINE:COL: error: MESSAGE`` and exit with status 1 (usage
errors: 2); no Python traceback reaches the user for bad input.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import os
import sys
from typing import NoReturn

from vtts import __version__
from vtts.api.options import check_io
from vtts.messages import argument_parser


def build_parser() -> argparse.ArgumentParser:
    from vtts.cli import (
        analyze,
        batch,
        check,
        coding,
        info,
        models,
        play,
        pose,
        render,
        say,
        serve,
        voices,
    )

    p = argument_parser(
        prog="vtts",
        description="MPEG-4 face animation: talking heads, FAP playback, analysis and coding.",
    )
    p.add_argument("--version", action="version", version=f"vtts {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    # in the order --help lists them
    for add in (
        check.add_parser,
        info.add_parser,
        pose.add_parser,
        render.add_parser,
        play.add_parser,
        models.add_parser,
        say.add_parser,
        analyze.add_parser,
        batch.add_parser,
        serve.add_parser,
        voices.add_parser,
        coding.add_parser,
    ):
        add(sub)
    return p


def _check_io(args: argparse.Namespace) -> None:
    """Outputs that would replace an input, each other, a link or a device are refused before
    the command starts (:func:`vtts.api.options.check_io`)."""
    check_io(args)


def _terminate_as_interrupt(signum, frame) -> None:
    """SIGTERM and SIGHUP end a command as Ctrl-C does: temporary files are removed and no
    output is left half-written."""
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, _terminate_as_interrupt)
    return execute(args)


def execute(args: argparse.Namespace) -> int:
    """Run the command ``args`` (from :func:`build_parser`) as ``vtts`` does: its exit status,
    with bad input printed on stderr as one clear message."""
    from vtts.api.options import url_roots_set
    from vtts.api.reporting import run_reported

    if getattr(args, "command", None) not in ("say", "play"):
        _startup_done()
    # say and play end their start-up with their first frame
    args.first_frame = _startup_done

    def command() -> int:
        # --url-root is set here for the whole command, so the options leave url_root empty
        with url_roots_set(getattr(args, "url_root", None)):
            _check_io(args)
            return args.func(args)

    return run_reported(command)


#: Whether :func:`run` paused Python's cyclic garbage collector for the command's start-up.
_GC_PAUSED = False


def _startup_done() -> None:
    """The command's start-up is over: the objects it made (modules, the model, OpenGL's and
    pyrender's) are frozen out of every later collection and the collector runs again. The
    little garbage start-up leaves in cycles is frozen with them: it stays until the command
    ends."""
    global _GC_PAUSED
    if _GC_PAUSED:
        _GC_PAUSED = False
        gc.freeze()
        gc.enable()


def run() -> NoReturn:
    """The ``vtts`` command: :func:`main`, then leave without the interpreter's teardown.

    Every output is complete and closed when :func:`main` returns (writers rename their files
    only when done, and wait for their encoders), so what is left at exit is the interpreter's
    own cleanup: several garbage collections over the objects of OpenGL, pyrender and the
    model. Library users calling :func:`main` keep the normal exit.

    The cyclic garbage collector is paused while a command starts: importing NumPy, SciPy,
    PyOpenGL and pyrender and setting up a scene makes hundreds of thousands of objects and
    almost no garbage cycles, and the collector would walk them all again and again. ``vtts
    say`` and ``vtts play`` resume it after their first frame, every other command before it
    starts (:func:`_startup_done`); the frames make no cyclic garbage."""
    global _GC_PAUSED
    gc.disable()
    _GC_PAUSED = True
    code = main()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):
            stream.flush()
    os._exit(code)
