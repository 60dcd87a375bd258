#!/usr/bin/env bash
# Sets up everything vtts needs on a Debian machine: the Debian packages (installed when missing and
# we are root, otherwise the exact apt-get line is printed) and a .venv with the project and its
# extras. Re-running is cheap: pip runs again only when pyproject.toml changed.
#
# usage: scripts/setup.sh [EXTRAS]     (EXTRAS defaults to "test"; e.g. "test,bench")
set -euo pipefail
cd "$(dirname "$0")/.."

extras="${1:-test}"
# espeak-ng: speech with phoneme and mark events. Offscreen rendering with Mesa's software EGL
# (llvmpipe): libegl1 + libegl-mesa0 (the EGL vendor), libgl1 (PyOpenGL loads libGL.so.1 for
# desktop GL), libgl1-mesa-dri (the llvmpipe driver).
deb_packages=(espeak-ng libespeak-ng1 libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libgles2)

missing=()
for p in "${deb_packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
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
stamp=".venv/.vtts-setup-$(echo "$extras" | tr ',' '-')"
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  echo "setup: installing vtts[$extras] into .venv"
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e ".[$extras]"
  touch "$stamp"
fi
# Byte-compile vtts itself (an editable install is not compiled, and PYTHONDONTWRITEBYTECODE=1
# would have every command compile it again at startup); up-to-date files are skipped.
.venv/bin/python -m compileall -q vtts adt_tools >/dev/null
