"""How a command's failure is told, the same from the ``vtts`` command and from ``vtts
batch``'s workers: bad input as one ``FILE:LINE:COL: error: MESSAGE`` line on stderr and an exit
status, never a traceback (:func:`run_reported`)."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable

from vtts.errors import VttsError
from vtts.messages import echo, print_error, reported_warnings

#: Exit statuses: bad input (or an output that cannot be written), Ctrl-C (128 + SIGINT), and
#: a reader that went away (128 + SIGPIPE).
EXIT_ERROR = 1
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 141


def run_reported(call: Callable[[], int]) -> int:
    """``call()``'s exit status, its warnings printed on stderr as they are from the command
    line; a :class:`~vtts.errors.VttsError`, an interruption, a closed pipe or an unwritable
    output is printed as one line and becomes its status."""
    try:
        with reported_warnings():
            return call()
    except VttsError as e:
        print_error(e)
        return EXIT_ERROR
    except KeyboardInterrupt:
        echo("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # the reader went away (``vtts check … | head``): not an error worth a traceback
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except OSError as e:
        # an output that cannot be written (permissions, a full disk, a missing folder)
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        echo(f"{where}error: {e.strerror or e}", file=sys.stderr)
        return EXIT_ERROR
