"""The environment the renderer sets up for Mesa before OpenGL is loaded."""

from __future__ import annotations

import os
import subprocess
import sys

from vtts.render.renderer import LLVMPIPE_MIN_THREADS, llvmpipe_threads


def test_llvmpipe_gets_at_least_the_minimum_of_threads():
    assert llvmpipe_threads() == max(LLVMPIPE_MIN_THREADS, os.cpu_count() or 1)


def _lp_after_loading(env: dict) -> str:
    code = (
        "import os; from vtts.render.renderer import _pr; _pr(); "
        "print(os.environ['LP_NUM_THREADS'])"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    return out.stdout.strip()


def test_llvmpipe_threads_are_set_unless_the_caller_chose():
    env = {k: v for k, v in os.environ.items() if k != "LP_NUM_THREADS"}
    assert _lp_after_loading(env) == str(llvmpipe_threads())
    assert _lp_after_loading({**env, "LP_NUM_THREADS": "1"}) == "1"  # e.g. one per batch worker
