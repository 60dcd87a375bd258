"""How many VRML97 files from other projects vtts loads: strict, ``--lenient``, and a peer parser.

usage: .venv/bin/python scripts/wild_vrml.py FOLDER [--peer-python PY] [--json OUT]
                                             [--timeout S] [--memory-mb MB] [--url-root DIR]

Every ``*.wrl`` under FOLDER (recursively) goes through what ``vtts check`` and ``vtts check
--lenient`` do with it (the same function, in this process: load the model, triangulate every
IndexedFaceSet, count triangles), each under a time guard (``--timeout``, SIGALRM) and the whole
run under an address-space cap (``--memory-mb``, RLIMIT_AS), so a hostile file is a counted
failure, not a hang or an exhausted machine. The model cache is a temporary folder of the run.

With ``--peer-python PY`` each file is also given to PyVRML97 (PyPI ``PyVRML97``, module
``vrml.vrml97``) in a subprocess of that interpreter, under the same timeout. It "reads" a file
when ``parser.buildParser().parse(text, processor=ParseProcessor(baseURI=path))`` succeeds and
consumes the whole text, as in bench/bench_vrml.py.

It prints the counts, the files the peer reads that vtts does not load leniently, and the first
error of each file that fails, grouped by kind (the error class and its message with names and
numbers blanked). ``--json OUT`` writes one record per file for later comparison. The corpus is
not part of the repository (licences vary); docs/vrml.md says how the measured one was gathered.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import signal
import subprocess
import sys
import tempfile
import time
import warnings
from collections import defaultdict
from dataclasses import asdict, dataclass
from pathlib import Path

from vtts.api.check import CHECKERS
from vtts.errors import VttsError

#: What the peer's subprocess runs: one file, exit 0 when PyVRML97 reads all of it.
PEER_READ = Path(__file__).parents[1] / "bench" / "pyvrml_read.py"


@dataclass
class Outcome:
    """One file's results: None where it loaded, else the first error's text."""

    file: str
    bytes: int
    strict: str | None = None
    lenient: str | None = None
    lenient_kind: str | None = None
    strict_kind: str | None = None
    warnings: int = 0
    peer: str | None = None  # "ok", an error text, or None when the peer was not run
    seconds: float = 0.0


class _Timeout(Exception):
    pass


def _alarm(signum, frame):  # noqa: ARG001 - signal handler signature
    raise _Timeout


def kind_of(err: BaseException) -> str:
    """The error's class and message with quoted names, numbers and places blanked: files that
    fail for the same reason share a kind."""
    msg = err.message if isinstance(err, VttsError) else str(err)
    msg = re.sub(r"'[^'\s]*'|\"[^\"]*\"", "'…'", msg)
    msg = re.sub(r"(?<![\w-])\d+(\.\d+)?\b", "N", msg)
    msg = re.sub(r"\(.*", "", msg).strip(" ;:,")
    return f"{type(err).__name__}: {msg[:90]}"


def load(path: Path, lenient: bool, timeout: float) -> tuple[str | None, str | None, int]:
    """(error text or None, error kind or None, number of warnings) of one ``vtts check``."""
    signal.setitimer(signal.ITIMER_REAL, timeout)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            CHECKERS[".wrl"](path, lenient)
        return None, None, len(caught)
    except _Timeout:
        return f"took more than {timeout:g} s", "timeout", 0
    except MemoryError:
        return "ran out of memory (cap)", "MemoryError", 0
    except RecursionError:
        return "RecursionError", "RecursionError", 0
    except VttsError as e:
        return str(e), kind_of(e), 0
    except Exception as e:  # a crash is a finding, not the end of the run
        return f"{type(e).__name__}: {e}", f"crash {type(e).__name__}", 0
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)


def peer_reads(python: str, path: Path, timeout: float) -> str:
    """'ok' when PyVRML97 reads the file, else its last line of error."""
    try:
        r = subprocess.run(
            [python, str(PEER_READ), str(path)],
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        return f"took more than {timeout:g} s"
    if r.returncode == 0:
        return "ok"
    lines = [ln for ln in (r.stderr or r.stdout).splitlines() if ln.strip()]
    return lines[-1][:200] if lines else f"exit {r.returncode}"


def measure(folder: Path, args) -> list[Outcome]:
    files = sorted(p for p in folder.rglob("*.wrl") if p.is_file())
    out = []
    for p in files:
        o = Outcome(str(p.relative_to(folder)), p.stat().st_size)
        t0 = time.perf_counter()
        o.strict, o.strict_kind, _ = load(p, False, args.timeout)
        o.lenient, o.lenient_kind, o.warnings = load(p, True, args.timeout)
        o.seconds = time.perf_counter() - t0
        if args.peer_python:
            o.peer = peer_reads(args.peer_python, p, args.timeout)
        out.append(o)
    return out


def report(results: list[Outcome], peer: bool) -> None:
    n = len(results)
    strict = sum(o.strict is None for o in results)
    lenient = sum(o.lenient is None for o in results)
    print(f"files                      {n}")
    print(f"vtts strict loads          {strict}")
    print(f"vtts --lenient loads       {lenient}")
    if peer:
        read_by_peer = [o for o in results if o.peer == "ok"]
        both = sum(o.lenient is None for o in read_by_peer)
        print(f"PyVRML97 reads             {len(read_by_peer)}")
        print(f"  of those, vtts --lenient {both}")
        missed = [o for o in read_by_peer if o.lenient is not None]
        if missed:
            print("\npeer reads, vtts --lenient does not:")
            for o in missed:
                print(f"  {o.file}: {o.lenient}")
        only_vtts = sum(o.peer != "ok" and o.lenient is None for o in results)
        print(f"\nvtts --lenient loads, the peer does not: {only_vtts}")
    for mode in ("lenient", "strict"):
        groups: dict[str, list[Outcome]] = defaultdict(list)
        for o in results:
            if getattr(o, mode) is not None:
                groups[getattr(o, f"{mode}_kind")].append(o)
        if not groups:
            continue
        print(f"\n{mode} failures by kind ({sum(map(len, groups.values()))} files):")
        for kind, items in sorted(groups.items(), key=lambda kv: (-len(kv[1]), kv[0])):
            print(f"  [{len(items)}] {kind}")
            if mode == "lenient":
                for o in items:
                    print(f"      {o.file}: {getattr(o, mode)}")
    if peer:
        groups = defaultdict(list)
        for o in results:
            if o.peer != "ok":
                groups[re.sub(r"\d+", "N", o.peer or "")[:90]].append(o)
        print(f"\npeer failures by kind ({sum(map(len, groups.values()))} files):")
        for kind, items in sorted(groups.items(), key=lambda kv: (-len(kv[1]), kv[0])):
            print(f"  [{len(items)}] {kind}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--peer-python", help="a python with PyVRML97 installed")
    ap.add_argument("--json", type=Path, help="write one record per file here")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per file and parser")
    ap.add_argument("--memory-mb", type=int, default=4096, help="address-space cap of this run")
    ap.add_argument("--url-root", action="append", default=[], help="as vtts --url-root")
    args = ap.parse_args(argv)
    if not args.folder.is_dir():
        ap.error(f"{args.folder} is not a folder")
    cap = args.memory_mb * 1024 * 1024
    hard = resource.getrlimit(resource.RLIMIT_AS)[1]
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)
    resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    signal.signal(signal.SIGALRM, _alarm)
    if args.url_root:  # as vtts --url-root does: every model load sees them
        os.environ["VTTS_URL_ROOT"] = os.pathsep.join(str(Path(d).resolve()) for d in args.url_root)
    with tempfile.TemporaryDirectory(prefix="wild-vrml-cache-") as cache:
        os.environ["VTTS_CACHE_DIR"] = cache  # strict loads are cached: not in the user's cache
        results = measure(args.folder, args)
    report(results, bool(args.peer_python))
    if args.json:
        args.json.write_text(json.dumps([asdict(o) for o in results], indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
