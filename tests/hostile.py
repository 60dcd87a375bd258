"""Helpers of the hostile-input tests (issue 21): the commands run in a bounded process, and the
mutations the in-process fuzzers apply to real inputs.

A command runs here two ways: the installed console script under the limits (:func:`run_cli`);
or the same, forked from a process that has already started Python and made the imports
(:func:`run_bounded`, a fraction of the processor time). For what a command says and writes
rather than how its process ends, it runs in the test's own process (``tests/in_process.py``).
"""

from __future__ import annotations

import atexit
import io
import json
import os
import resource
import subprocess
import sys
import tempfile
import wave
from pathlib import Path

from hypothesis import strategies as st

DATA = Path(__file__).parent / "data"
#: Address space a command may take (the heaviest legitimate case, a render, stays under 1.5 GB).
MEMORY = 3 << 30
#: Processor seconds a command may take, and the wall-clock seconds it may run.
CPU_SECONDS = 60
TIMEOUT = 60


def limited() -> None:
    """Run in the child before the command starts (``preexec_fn``): bound its memory and its
    processor time; a command beyond them dies with MemoryError or SIGXCPU."""
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY, MEMORY))
    resource.setrlimit(resource.RLIMIT_CPU, (CPU_SECONDS, CPU_SECONDS))


def run_cli(
    tool: str, *args: str, cwd: Path, timeout: float = TIMEOUT
) -> subprocess.CompletedProcess:
    """``tool`` (``vtts`` or ``adi`` of this venv) with ``args`` under :func:`limited`, without the
    model cache, capturing its output as text."""
    exe = Path(sys.executable).with_name(tool)
    env = {**os.environ, "VTTS_CACHE_DIR": ""}
    return subprocess.run(
        [str(exe), *args],
        capture_output=True,
        text=True,
        errors="replace",
        timeout=timeout,
        cwd=cwd,
        env=env,
        preexec_fn=limited,
    )


#: The warm parent of :func:`run_bounded`'s commands (tests/forkserver.py), one per test process.
_server: subprocess.Popen | None = None


def _fork_server() -> subprocess.Popen:
    """The running fork server, started without the model cache on first use."""
    global _server
    if _server is None or _server.poll() is not None:
        env = {**os.environ, "VTTS_CACHE_DIR": ""}
        script = Path(__file__).with_name("forkserver.py")
        _server = subprocess.Popen([sys.executable, str(script)], stdin=subprocess.PIPE,
                                   stdout=subprocess.PIPE, text=True, env=env)  # fmt: skip
        atexit.register(_stop, _server)
        if _server.stdout.readline() != "ready\n":
            raise RuntimeError("the fork server of tests/hostile.py did not start")
    return _server


def _stop(server: subprocess.Popen) -> None:
    """End the fork server and wait for it (its children's processor time is counted then)."""
    server.stdin.close()
    server.wait(TIMEOUT)


def _text(data: bytes) -> str:
    """``data`` as ``subprocess.run(text=True, errors="replace")`` gives a process's output."""
    return io.TextIOWrapper(io.BytesIO(data), errors="replace").read()


def run_bounded(
    tool: str, *args: str, cwd: Path, timeout: float = TIMEOUT
) -> subprocess.CompletedProcess:
    """``tool`` with ``args`` as :func:`run_cli` runs it — a process of its own under the limits
    of :func:`limited`, without the model cache, its output captured as text — forked from a
    process that has made Python's start-up and the commands' imports once
    (tests/forkserver.py): what the process does is the command's, only the start-up of the
    interpreter is not repeated. A run past ``timeout`` seconds raises TimeoutExpired."""
    server = _fork_server()
    with tempfile.TemporaryDirectory() as tmp:
        out, err = Path(tmp, "out"), Path(tmp, "err")
        request = dict(tool=tool, args=list(args), cwd=str(cwd), out=str(out), err=str(err),
                       memory=MEMORY, cpu=CPU_SECONDS, timeout=timeout)  # fmt: skip
        server.stdin.write(json.dumps(request) + "\n")
        server.stdin.flush()
        answer = server.stdout.readline()
        if not answer:
            raise RuntimeError("the fork server of tests/hostile.py ended")
        code = json.loads(answer)["returncode"]
        if code is None:
            raise subprocess.TimeoutExpired([tool, *args], timeout)
        return subprocess.CompletedProcess(
            [tool, *args], code, _text(out.read_bytes()), _text(err.read_bytes())
        )


# ---- mutations -----------------------------------------------------------------------------------

#: Pieces that break parsers: signs, exponents, special numbers, separators, line ends of every
#: kind, invisible characters, a long number.
INTERESTING = [
    "0", "1", "2", "-1", "+1", "1.5", ".", "-", "e", "1e999", "nan", "inf", "#", " ", "\t", "\n",
    "\r", "\r\n", "\x0b", "\x0c", "\xa0", "\x85", "\u2028", "\ufeff", "\x00", "x", "2.0", "2.1",
    "9" * 30, "1_0", "²", "٣", "<", ">", "=", ":", ",", '"', "{", "}", "[", "]", "(", ")", "@",
]  # fmt: skip

OPS = ("insert", "delete", "replace", "drop_line", "dup_line", "swap_lines", "truncate")

#: A few edits of a text or bytes: (operation, position, second position or length, piece).
mutations = st.lists(
    st.tuples(
        st.sampled_from(OPS),
        st.integers(0, 10**6),
        st.integers(0, 10**6),
        st.sampled_from(INTERESTING),
    ),
    min_size=1,
    max_size=4,
)


def mutate(text: str, ops: list[tuple[str, int, int, str]]) -> str:
    """``text`` with the edits ``ops`` (from :data:`mutations`) applied in turn; positions wrap
    around the text's length, line operations act on ``\\n``-separated lines."""
    for op, a, b, s in ops:
        if op in ("insert", "delete", "replace", "truncate"):
            i = a % (len(text) + 1)
            if op == "insert":
                text = text[:i] + s + text[i:]
            elif op == "delete":
                text = text[:i] + text[i + 1 + b % 5 :]
            elif op == "replace":
                j = i + 1 + b % 4
                text = text[:i] + s + text[j:]
            else:
                text = text[:i]
        else:
            lines = text.split("\n")
            i, j = a % len(lines), b % len(lines)
            if op == "drop_line":
                del lines[i]
            elif op == "dup_line":
                lines.insert(i, lines[i])
            else:
                lines[i], lines[j] = lines[j], lines[i]
            text = "\n".join(lines)
    return text


#: Edits of binary data: (position, kind, value) with kind one of flip (xor a byte), set (a byte
#: to a value), insert, delete (up to 16 bytes) or truncate.
byte_mutations = st.lists(
    st.tuples(
        st.integers(0, 10**9),
        st.sampled_from(["flip", "set", "insert", "delete", "truncate"]),
        st.integers(0, 255),
    ),
    min_size=1,
    max_size=6,
)


def mutate_bytes(data: bytes, ops: list[tuple[int, str, int]], *, start: int = 0) -> bytes:
    """``data`` with the edits ``ops`` (from :data:`byte_mutations`) applied at or after byte
    ``start`` (to keep a header whole when the damage should reach what follows it)."""
    out = bytearray(data)
    for pos, kind, value in ops:
        span = len(out) - start
        i = start + (pos % span if span > 0 else 0)
        if kind == "flip" and i < len(out):
            out[i] ^= value or 0x80
        elif kind == "set" and i < len(out):
            out[i] = value
        elif kind == "insert":
            out[i:i] = bytes([value]) * (1 + pos % 4)
        elif kind == "delete":
            del out[i : i + 1 + value % 16]
        elif kind == "truncate":
            del out[i:]
    return bytes(out)


def wav(path: Path, seconds: float = 0.5) -> Path:
    """A silent 16 kHz mono WAV of ``seconds`` at ``path``."""
    with wave.open(str(path), "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(16000)
        w.writeframes(b"\0\0" * int(16000 * seconds))
    return path
