#!/usr/bin/env bash
# Sets up what vtts needs on a Debian machine: the Debian packages (installed when missing and we
# are root, otherwise the exact apt-get line is printed) and a .venv with the project and its
# extras, at the versions pinned in constraints.txt (the lock `make lock` writes), so that a fresh
# machine gets what the tests passed with. Re-running is cheap: pip runs again only when
# pyproject.toml or constraints.txt changed, or when more extras are asked for than were installed
# (`make test` after `make demo`); fewer extras than installed (`make demo` after `make test`) run
# nothing.
#
# EXTRAS is a comma-separated list of pyproject.toml's extras, or `core` for none: the demo (`make
# demo`) needs only the core package, espeak-ng and Mesa; the test extras (`test`, `bench`) bring
# the test bench besides (Chromium, festival and its voice, node and the glTF-Validator, Ray …).
#
# The Piper engine (`vtts say --engine piper`) is the extra `piper`: GPL-3.0, unlike vtts (MIT), so
# never part of the default install. VTTS_EXTRAS (a comma-separated list; `make demo PIPER=1` and
# `make setup PIPER=1` set it to piper) adds extras to any target's; the test bench brings it
# besides, as it brings festival, because the tests and benchmarks speak with every engine.
#
# usage: scripts/setup.sh [--dry-run] [EXTRAS]     (EXTRAS defaults to "test"; e.g. "test,bench")
#        --dry-run prints what it would install (Debian packages, the pip requirement, the node
#        tools) and changes nothing.
set -euo pipefail
cd "$(dirname "$0")/.."

dry_run=0
if [ "${1:-}" = --dry-run ]; then
  dry_run=1
  shift
fi
extras="${1:-test}"
if ! [[ "$extras" =~ ^[a-z]+(,[a-z]+)*$ ]]; then
  echo "setup: EXTRAS is a comma-separated list of extras, or core; got '$extras'" >&2
  exit 2
fi
more="${VTTS_EXTRAS:-}"
if [ -n "$more" ]; then
  if ! [[ "$more" =~ ^[a-z]+(,[a-z]+)*$ ]]; then
    echo "setup: VTTS_EXTRAS is a comma-separated list of extras; got '$more'" >&2
    exit 2
  fi
  if [ "$extras" = core ]; then extras="$more"; else extras="$extras,$more"; fi
fi
# the test bench: what the tests and the benchmarks need beyond what vtts itself needs
bench=0
case ",$extras," in
*,test,* | *,bench,*) bench=1 ;;
esac
# the test bench speaks with every engine: Piper's extra too
if ((bench)) && [[ ",$extras," != *,piper,* ]]; then
  extras="$extras,piper"
fi

# espeak-ng: speech with phoneme and mark events. Offscreen rendering with Mesa's software EGL
# (llvmpipe): libegl1 + libegl-mesa0 (the EGL vendor), libgl1 (PyOpenGL loads libGL.so.1 for
# desktop GL), libgl1-mesa-dri (the llvmpipe driver).
deb_packages=(espeak-ng libespeak-ng1 libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libgles2)
# For the test bench: chromium, in which the web player's tests and benchmark load it headless
# (vtts.export.browser); nodejs and npm: the Khronos glTF-Validator the tests check exported
# .glb/.gltf files with (tools/node/); festival and festvox-us-slt-hts: the second voice, `vtts
# say --engine festival` (an HTS voice whose utterance structure gives its own phone and word
# times), and test material for the forced aligner. A user who wants festival installs those two.
# pocketsphinx-testdata: real read speech with transcripts (bench/bench_lipsync_audio.py).
if ((bench)); then
  deb_packages+=(chromium nodejs npm festival festvox-us-slt-hts pocketsphinx-testdata)
fi
if [ "$extras" = core ]; then
  requirement="."
else
  requirement=".[$extras]"
fi
if ((dry_run)); then
  echo "debian: ${deb_packages[*]}"
  echo "python: -e $requirement"
  echo "node: $([ "$bench" = 1 ] && echo tools/node || echo none)"
  exit 0
fi

# node and npm installed another way count too (NodeSource's nodejs package carries npm and
# conflicts with Debian's npm package)
provided() {
  case "$1" in
    nodejs) command -v node >/dev/null ;;
    npm) command -v npm >/dev/null ;;
    *) return 1 ;;
  esac
}
missing=()
for p in "${deb_packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" &&
    ! provided "$p"; then
    missing+=("$p")
  fi
done
if ((${#missing[@]})); then
  line="apt-get install -y --no-install-recommends ${missing[*]}"
  if [ "$(id -u)" = 0 ]; then
    echo "setup: installing Debian packages: ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    # shellcheck disable=SC2086
    $line >/dev/null
  else
    echo "setup: missing Debian packages. Run as root:" >&2
    echo "  sudo apt-get update && sudo $line" >&2
    exit 1
  fi
fi

python="${PYTHON:-python3}"
if ! "$python" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
  echo "setup: vtts needs Python >= 3.11; $python is $("$python" --version 2>&1)" >&2
  exit 1
fi
if [ ! -x .venv/bin/python ]; then
  "$python" -m venv .venv
fi
# A stamp per set of extras holds a digest of what the install was made from: a changed
# pyproject.toml or lock (an edit, a pull, a checkout) installs again, whatever the files' times
# say. A stamp of the same digest for a superset of the extras asked for (test,bench for test; any
# for core) means there is nothing to install.
digest="$(cat pyproject.toml constraints.txt | sha256sum | cut -d' ' -f1)"
stamp=".venv/.vtts-setup-$(echo "$extras" | tr ',' '-')"
covered() {
  local have f
  for f in .venv/.vtts-setup-*; do
    [ -f "$f" ] && [ "$(cat "$f")" = "$digest" ] || continue
    have="-${f#.venv/.vtts-setup-}-"
    local e ok=1
    for e in ${extras//,/ }; do
      [ "$e" = core ] || [[ "$have" == *"-$e-"* ]] || ok=0
    done
    ((ok)) && return 0
  done
  return 1
}
if ! covered; then
  echo "setup: installing vtts$([ "$extras" = core ] || echo "[$extras]") into .venv" \
    "(versions from constraints.txt)"
  # --no-compile: byte-compiling every installed module took half of pip's time, for modules
  # most commands never import; Python compiles those a command imports once, at their first
  # import — unless PYTHONDONTWRITEBYTECODE is set, which `make test` and `make bench` clear.
  # uv (pinned in the lock too) installs the packages: the same versions from the same lock in
  # a third of pip's time (it downloads in parallel and resolves faster; it does not compile
  # either). Should it fail (an index it cannot reach that pip's configuration names), pip
  # installs them.
  .venv/bin/python -m pip install -q --no-compile -c constraints.txt --upgrade pip uv
  # every package, transitive ones and the build backend (hatchling) too, at its locked version;
  # a dependency the lock lacks would come unpinned (tests/test_lock.py says so: `make lock`)
  if ! .venv/bin/uv pip install -q --python .venv/bin/python -c constraints.txt \
    --build-constraints constraints.txt -e "$requirement"; then
    echo "setup: uv could not install vtts's packages; pip installs them" >&2
    .venv/bin/python -m pip install -q --no-compile -c constraints.txt \
      --build-constraint constraints.txt -e "$requirement"
  fi
  echo "$digest" >"$stamp"
fi
# The test bench's node tools (the glTF-Validator) at the versions tools/node/package-lock.json
# pins, into the git-ignored tools/node/node_modules; again only when package.json or the lock
# changed.
if ((bench)); then
  node_stamp="tools/node/node_modules/.vtts-setup"
  node_digest="$(cat tools/node/package.json tools/node/package-lock.json | sha256sum | cut -d' ' -f1)"
  if [ ! -f "$node_stamp" ] || [ "$(cat "$node_stamp")" != "$node_digest" ]; then
    echo "setup: installing the node tools (tools/node: npm ci)"
    (cd tools/node && npm ci --no-audit --no-fund --loglevel=error >/dev/null)
    echo "$node_digest" >"$node_stamp"
  fi
fi
# Byte-compile vtts itself (an editable install is not compiled, and PYTHONDONTWRITEBYTECODE=1
# would have every command compile it again at startup); up-to-date files are skipped.
.venv/bin/python -m compileall -q vtts adt_tools >/dev/null
