"""`make demo` sets up what the demo needs, `make test` the test bench besides (issue 45)."""

from __future__ import annotations

import re
import subprocess
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
#: What only the tests and benchmarks use: Debian packages, and Python distributions.
BENCH_DEBS = {
    "chromium", "nodejs", "npm", "festival", "festvox-us-slt-hts", "pocketsphinx-testdata"
}  # fmt: skip
BENCH_PYTHON = {"ray", "pytest", "hypothesis", "pytest-xdist", "ruff", "build", "pyvrml97"}


def dry_run(extras: str) -> dict[str, str]:
    """What ``scripts/setup.sh --dry-run EXTRAS`` says it would install, by line."""
    return dry_run_env(extras, {})


def dry_run_env(extras: str, env: dict[str, str]) -> dict[str, str]:
    """:func:`dry_run` with ``env`` added to the environment (VTTS_EXTRAS removed otherwise)."""
    import os

    base = {k: v for k, v in os.environ.items() if k != "VTTS_EXTRAS"}
    r = subprocess.run(
        ["bash", str(ROOT / "scripts/setup.sh"), "--dry-run", extras],
        capture_output=True, text=True, timeout=60, check=True, env={**base, **env},
    )  # fmt: skip
    return dict(line.split(": ", 1) for line in r.stdout.splitlines())


def recipe(target: str) -> str:
    """The Makefile's recipe of ``target``, with its prerequisites line."""
    text = (ROOT / "Makefile").read_text()
    m = re.search(rf"^{target}:(.*?)\n((?:\t.*\n?)*)", text, re.M)
    assert m, f"no {target} target in the Makefile"
    return m[1] + "\n" + m[2]


def setup_extras(target: str) -> str:
    """The extras the Makefile's ``target`` sets up with (following a ``setup`` prerequisite)."""
    r = recipe(target)
    m = re.search(r"scripts/setup\.sh\s+(\S+)", r)
    if m:
        return m[1]
    assert re.search(r"\bsetup\b", r.split("\n")[0]), f"{target} does not set up"
    return setup_extras("setup")


def test_the_demo_sets_up_without_the_test_bench():
    extras = setup_extras("demo")
    assert extras == "core"
    plan = dry_run(extras)
    debs = set(plan["debian"].split())
    assert {"espeak-ng", "libegl-mesa0", "libgl1-mesa-dri"} <= debs
    assert not debs & BENCH_DEBS
    assert plan["python"] == "-e ."  # the core package, no extras
    assert plan["node"] == "none"
    core = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    names = {re.split(r"[<>=!~\[; ]", d, maxsplit=1)[0].lower() for d in core}
    assert not names & BENCH_PYTHON


@pytest.mark.parametrize("target", ["test", "bench"])
def test_the_tests_set_up_the_whole_bench(target):
    extras = setup_extras(target)
    assert "test" in extras.split(",")
    plan = dry_run(extras)
    assert BENCH_DEBS <= set(plan["debian"].split())
    # the test bench speaks with every engine: Piper's extra (GPL-3.0, never in the demo) too
    assert plan["python"] == f"-e .[{extras},piper]"
    assert plan["node"] == "tools/node"


def test_piper_is_a_switch_for_the_demo():
    """``make demo PIPER=1``: the core package with the piper extra, and no test bench."""
    r = subprocess.run(
        ["make", "-n", "demo", "PIPER=1"], cwd=ROOT, capture_output=True, text=True, timeout=60,
        check=True,
    )  # fmt: skip
    assert "scripts/setup.sh core" in r.stdout
    plan = dry_run_env("core", {"VTTS_EXTRAS": "piper"})
    assert plan["python"] == "-e .[piper]"
    assert not set(plan["debian"].split()) & BENCH_DEBS
    assert dry_run("core")["python"] == "-e ."


def test_setup_refuses_odd_extras():
    r = subprocess.run(
        ["bash", str(ROOT / "scripts/setup.sh"), "--dry-run", "test;rm"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert r.returncode == 2 and "comma-separated" in r.stderr


@pytest.mark.parametrize("target", ["test", "bench"])
def test_the_suite_and_the_bench_keep_what_python_compiles(target):
    """Setup installs packages without byte-compiling them; where PYTHONDONTWRITEBYTECODE is set,
    every process of the suite would compile what it imports from source again (3.5 s of CPU for
    one that imports the renderer): the recipes clear it."""
    assert re.search(r"^\tPYTHONDONTWRITEBYTECODE= \$\(PY\) ", recipe(target), re.M)
