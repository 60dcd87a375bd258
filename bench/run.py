"""Run the benchmarks under ``bench/`` and print one table of figures.

usage: .venv/bin/python bench/run.py [FILTER ...]

Every ``bench/bench_*.py`` module (in name order, or only those whose name contains one of the
FILTERs, e.g. ``bench/run.py vrml``) exposes ``run() -> list[dict]``; each row has the keys
``benchmark``, ``case``, ``value``, ``unit``, ``target`` (a string, may be empty) and ``ok``
(True, False or None when there is nothing to judge). Benchmarks report, they don't fail the
build: this script exits 0 whatever the figures are. A module that raises is reported as one row.
"""

from __future__ import annotations

import datetime
import importlib.util
import os
import platform
import sys
import time
import traceback
from pathlib import Path

BENCH_DIR = Path(__file__).resolve().parent
COLUMNS = ("benchmark", "case", "value", "unit", "target", "ok")


def discover(filters: list[str]) -> list[Path]:
    """The ``bench_*.py`` modules, sorted, keeping those matching any filter (all if none)."""
    paths = sorted(BENCH_DIR.glob("bench_*.py"))
    if filters:
        paths = [p for p in paths if any(f in p.stem for f in filters)]
    return paths


def load(path: Path):
    name = f"_vtts_bench_{path.stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # as an import would (dataclasses and pickling look it up)
    spec.loader.exec_module(module)
    return module


def cpu_model() -> str:
    """The CPU's model name where Linux tells it, else ``platform.processor()``."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown cpu"


def machine_header() -> str:
    cpu = cpu_model()
    now = datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    return (
        f"vtts benchmarks  |  {cpu} ({platform.machine()}), {os.cpu_count()} CPUs  |  "
        f"Python {platform.python_version()} ({platform.python_implementation()})  |  "
        f"{platform.system()} {platform.release()}  |  {now}"
    )


def format_value(v) -> str:
    if isinstance(v, float):
        if v == 0:
            return "0"
        a = abs(v)
        if a >= 1000:
            return f"{v:,.0f}"
        if a >= 100:
            return f"{v:.1f}"
        if a >= 1:
            return f"{v:.3f}"
        return f"{v:.4g}"
    if v is None:
        return "-"
    return str(v)


def format_ok(ok) -> str:
    return {True: "yes", False: "NO", None: ""}.get(ok, str(ok))


def table(rows: list[dict]) -> str:
    cells = [
        (
            str(r.get("benchmark", "")),
            str(r.get("case", "")),
            format_value(r.get("value")),
            str(r.get("unit", "")),
            str(r.get("target", "") or ""),
            format_ok(r.get("ok")),
        )
        for r in rows
    ]
    widths = [
        max(len(h), *(len(c[i]) for c in cells)) if cells else len(h) for i, h in enumerate(COLUMNS)
    ]
    right = {2}  # numbers right-aligned

    def line(values) -> str:
        parts = [
            v.rjust(w) if i in right else v.ljust(w)
            for i, (v, w) in enumerate(zip(values, widths, strict=True))
        ]
        return "  ".join(parts).rstrip()

    out = [line(COLUMNS), line(["-" * w for w in widths])]
    out += [line(c) for c in cells]
    return "\n".join(out)


def main(argv: list[str]) -> int:
    filters = argv[1:]
    paths = discover(filters)
    print(machine_header())
    if not paths:
        print(f"no benchmark module matches {filters!r} in {BENCH_DIR}")
        return 0
    rows: list[dict] = []
    t0 = time.perf_counter()
    for path in paths:
        t = time.perf_counter()
        try:
            rows += load(path).run()
        except Exception as e:  # a broken benchmark is reported, not fatal
            traceback.print_exc(file=sys.stderr)
            rows.append(
                {
                    "benchmark": path.stem.removeprefix("bench_"),
                    "case": "(module failed)",
                    "value": None,
                    "unit": f"{type(e).__name__}: {e}",
                    "target": "",
                    "ok": None,
                }
            )
        print(f"  ran {path.name} in {time.perf_counter() - t:.1f} s", file=sys.stderr)
    print()
    print(table(rows))
    print()
    judged = [r for r in rows if r.get("ok") is not None]
    met = sum(1 for r in judged if r["ok"])
    print(f"{met}/{len(judged)} targets met; total {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
