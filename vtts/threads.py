"""Threads: one BLAS thread for the analysis's small dense algebra (:func:`one_blas_thread`), and
waits that a signal ends (:func:`result`, :class:`PipeReader`).

The estimator solves, per frame and pyramid level, normal equations of a few unknowns over tens
of thousands of pixels (``(N, k)`` by ``(N, k)`` products with ``k`` ≈ 17–25). OpenBLAS splits
such products over all cores and its threads spin while they wait for work; beside Mesa's
rasterizer threads, which the same estimator keeps busy, that made the analysis of Akiyo's first
16 frames take 26.6 s instead of 13.9 s on the 2-core machine (measured 2026-11-25, both
orders). The split also changes the order of the sums from run to run, so that two analyses of
the same video drifted apart by a few FAP units within eight frames; with one thread they are
identical. :func:`one_blas_thread` limits every BLAS library loaded (NumPy's and SciPy's
OpenBLAS) to one thread while its block runs, with threadpoolctl.

Python runs a signal's handler (Ctrl-C's ``KeyboardInterrupt``, and vtts's for SIGTERM and
SIGHUP) only in the main thread, between two bytecodes; the C-level handler, run in whichever
thread the kernel hands a process's signal to, only records it. A main thread asleep in a
wait nothing interrupts then sleeps on: a signal the kernel gave another thread (a worker
blocked reading a pipe, a BLAS thread), or one that came just before the main thread began to
wait, does not wake a lock's wait or a read. So the main thread never waits on a worker or a
pipe for ever in one go: :func:`result` and :class:`PipeReader` wake every
:data:`SIGNAL_SLICE` seconds, and a recorded signal's handler runs then.
"""

from __future__ import annotations

import contextlib
import os
import select
from collections.abc import Iterator
from concurrent.futures import Future
from typing import BinaryIO, TypeVar

T = TypeVar("T")

#: The longest the main thread sleeps in a wait before it runs the handler of a signal that
#: came meanwhile, in seconds (a signal ends a command within about that).
SIGNAL_SLICE = 0.1

_controller = None


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with one thread in every BLAS library loaded; the previous limits after."""
    global _controller
    from threadpoolctl import ThreadpoolController

    if _controller is None:  # the libraries loaded now: NumPy's and SciPy's are, once imported
        import scipy.linalg  # noqa: F401  (loads SciPy's OpenBLAS, if it is not yet)

        _controller = ThreadpoolController()
    with _controller.limit(limits=1, user_api="blas"):
        yield


def result(future: Future[T]) -> T:
    """``future.result()``, waited for in slices of :data:`SIGNAL_SLICE` so that a signal ends
    the wait (see the module's notes); the future's exception is raised as ``result()`` does."""
    while True:
        try:
            # exception(), unlike result(), returns what the call raised: a TimeoutError here
            # is the slice's end, never the call's own
            future.exception(timeout=SIGNAL_SLICE)
        except TimeoutError:
            continue
        return future.result()


class PipeReader:
    """The binary file ``file`` (a pipe: stdin), read without its buffer: each ``read(n)``
    waits for data in slices of :data:`SIGNAL_SLICE` (so that a signal ends the wait: see the
    module's notes), then returns what has arrived, up to ``n`` bytes (``b""`` at the end), as
    a raw file's read does (``readinto`` alike). Where the platform cannot poll a pipe, reads
    block as usual."""

    def __init__(self, file: BinaryIO) -> None:
        self.file = file
        self._fd = file.fileno()
        self._poll = None
        if hasattr(select, "poll"):
            self._poll = select.poll()
            self._poll.register(self._fd, select.POLLIN | select.POLLPRI)

    def fileno(self) -> int:
        return self._fd

    def read(self, n: int = -1) -> bytes:
        """Up to ``n`` bytes (``n`` < 0: all, to the end), waiting for the first to arrive."""
        if n < 0:
            chunks = []
            while chunk := self.read(1 << 16):
                chunks.append(chunk)
            return b"".join(chunks)
        if n == 0:
            return b""
        self._wait()
        return os.read(self._fd, n)

    def readinto(self, buffer: memoryview | bytearray) -> int:
        """Fill the start of ``buffer`` with what has arrived, waiting for the first byte; how
        many bytes (0 at the end)."""
        if len(buffer) == 0:
            return 0
        self._wait()
        return os.readv(self._fd, [buffer])

    def _wait(self) -> None:
        if self._poll is not None:
            # POLLHUP and POLLERR are reported too: a closed pipe reads as its end (or its error)
            while not self._poll.poll(SIGNAL_SLICE * 1000):
                pass
