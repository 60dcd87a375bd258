"""``vtts serve`` started as a process by the tests that need the process itself."""

from __future__ import annotations

import os
import re
import select
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).parents[2]


def start_serving(args: list[str], timeout: float) -> tuple[str, str, subprocess.Popen]:
    """``vtts serve ARGS`` started; returns (its base URL, the line that announced it, the
    process) once it says where it serves, within ``timeout`` s (an assertion otherwise, with
    its stderr if it ended)."""
    exe = Path(sys.executable).with_name("vtts")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONUNBUFFERED": "1", "LP_NUM_THREADS": "1"}
    proc = subprocess.Popen([str(exe), "serve", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)  # fmt: skip
    deadline = time.monotonic() + timeout
    line = ""
    try:
        while "http://" not in line:
            assert time.monotonic() < deadline, (
                f"vtts serve {' '.join(args)}: no address in {timeout} s"
            )
            ready, _, _ = select.select([proc.stdout], [], [], 1)
            if ready:
                line = proc.stdout.readline()
            assert proc.poll() is None, proc.stderr.read()
    except BaseException:
        proc.kill()
        proc.communicate()
        raise
    return re.search(r"http://127\.0\.0\.1:\d+", line)[0], line, proc
