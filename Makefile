# The README's commands. Every target sets up first (Debian packages + .venv), so each works on a
# fresh Debian machine with Python 3.11: the demo what it needs (espeak-ng, Mesa, the core
# package), the others the test bench besides (scripts/setup.sh says what that is).
# PIPER=1 (`make demo PIPER=1`, `make setup PIPER=1`) also installs the Piper engine, the optional
# extra vtts[piper] (GPL-3.0; `make test` and `make bench` install it anyway, for their tests)
ifeq ($(PIPER),1)
export VTTS_EXTRAS := piper
endif
VENV := .venv
PY := $(VENV)/bin/python
VTTS := $(VENV)/bin/vtts

.PHONY: setup demo test bench lint lock models golden clean

setup:
	@bash scripts/setup.sh test

demo:
	@bash scripts/setup.sh core
	@bash samples/demo.sh

# The suite runs on pytest-xdist workers, a test file per worker so that a file's fixtures are
# made once: one per core and two more, since the files that start Ray, a server or a browser
# spend much of their time waiting on those processes (on 2 cores 3 workers took 298 s where 2
# took 339 s, 2026-11-29 04:50; 4 workers 239 s where 3 took 263 s, 11:35, the files that
# start a local Ray taking turns: tests/conftest.py's one_ray_at_a_time). WORKERS=N overrides it. Files are handed out in collection order
# (--no-loadscope-reorder: not most tests first), which tests/conftest.py starts with the
# slowest files (SLOW_FIRST), so that none of them is left alone at the end.
#
# PYTHONDONTWRITEBYTECODE is cleared for the run: where it is set (this workplace's shells set it), no
# Python process caches what it compiles, and setup installs packages without byte-compiling
# them (scripts/setup.sh), so each of the suite's workers and its hundreds of `vtts`
# subprocesses compiled numpy, scipy, pyrender, ray … from source again: 3.5 s of CPU for a
# process that imports the renderer. Cleared, each module is compiled once, by the first
# process that imports it.
WORKERS ?= $(shell echo $$(( $$(nproc 2>/dev/null || echo 1) + 2 )))
test: setup
	PYTHONDONTWRITEBYTECODE= $(PY) -m pytest -q -n $(WORKERS) --dist loadfile --no-loadscope-reorder

lint: setup
	$(VENV)/bin/ruff check .

bench:
	@bash scripts/setup.sh test,bench
	PYTHONDONTWRITEBYTECODE= $(PY) bench/run.py

# Re-resolve pyproject.toml's dependencies (with the test and bench extras) in a fresh venv and pin
# them all in constraints.txt, which setup installs from; run `make test` and commit the lock.
lock:
	@bash scripts/lock.sh

# Rebuild the bundled heads (models/*.wrl, *.adt, *-face.png) from models/src with the ADI, and
# their progressive meshes (models/lod/: the triangles small frames leave out).
models: setup
	$(PY) models/src/build_models.py
	$(PY) models/src/build_lod.py

# Regenerate the golden images on purpose; look at them (git diff) before committing.
golden: setup
	VTTS_REGENERATE_GOLDEN=1 $(PY) -m pytest -q -k golden tests
	$(PY) models/src/contact_sheet.py
	@echo "golden images rewritten in tests/golden/: inspect them before committing"

clean:
	rm -rf $(VENV) out dist build .pytest_cache .ruff_cache .hypothesis
