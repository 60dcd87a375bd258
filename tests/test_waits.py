"""Waits that a signal ends (vtts.threads.result, PipeReader), whichever thread the kernel hands
the signal to."""

from __future__ import annotations

import os
import signal
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from vtts.threads import SIGNAL_SLICE, PipeReader, result


class Heard(Exception):
    """What the test's handler raises in the main thread."""


@pytest.fixture
def heard():
    """SIGUSR1's handler raises :class:`Heard` while the test runs (SIGINT's would stop
    pytest)."""

    def handler(signum, frame):
        raise Heard

    old = signal.signal(signal.SIGUSR1, handler)
    yield
    signal.signal(signal.SIGUSR1, old)


def signal_this_thread_later(delay: float = 0.3) -> None:
    time.sleep(delay)  # the main thread is asleep in its wait by then
    signal.pthread_kill(threading.get_ident(), signal.SIGUSR1)


def test_result_ends_on_a_signal_a_worker_took(heard):
    """The worker takes the signal: Python's C handler records it there, and the main thread,
    asleep on the future, must still run the handler (an endless ``result()`` slept on)."""
    gate = threading.Event()

    def work():
        signal_this_thread_later()
        gate.wait(30)
        return "late"

    with ThreadPoolExecutor(max_workers=1) as pool:
        t0 = time.monotonic()
        with pytest.raises(Heard):
            result(pool.submit(work))
        waited = time.monotonic() - t0
        gate.set()
    assert waited < 10, waited  # the worker ends only after 30 s: the signal ended the wait


def test_result_returns_and_raises_what_the_call_did():
    with ThreadPoolExecutor(max_workers=1) as pool:
        assert result(pool.submit(lambda: time.sleep(2 * SIGNAL_SLICE) or 7)) == 7

        def late_timeout():
            time.sleep(2 * SIGNAL_SLICE)
            raise TimeoutError("the call's own")

        with pytest.raises(TimeoutError, match="the call's own"):  # not taken for a slice's end
            result(pool.submit(late_timeout))


def test_pipe_reader_ends_on_a_signal_another_thread_took(heard):
    r, w = os.pipe()
    try:
        helper = threading.Thread(target=signal_this_thread_later)
        helper.start()
        t0 = time.monotonic()
        with pytest.raises(Heard), open(r, "rb", closefd=False) as f:
            PipeReader(f).read(10)  # nothing is ever written
        helper.join()
        assert time.monotonic() - t0 < 10
    finally:
        os.close(r)
        os.close(w)


def test_pipe_reader_reads_what_arrived_and_the_end():
    r, w = os.pipe()
    with open(r, "rb") as f:
        pipe = PipeReader(f)
        os.write(w, b"abc")
        assert pipe.read(10) == b"abc"  # what has arrived, as a raw read
        os.write(w, b"defgh")
        buf = bytearray(3)
        assert pipe.readinto(buf) == 3 and buf == b"def"
        assert pipe.read(0) == b"" and pipe.readinto(bytearray()) == 0
        os.write(w, b"ij")
        os.close(w)
        assert pipe.read() == b"ghij"
        assert pipe.read(5) == b"" and pipe.readinto(bytearray(2)) == 0
