#!/usr/bin/env bash
# Re-vendors the three.js files the web player needs (vtts say/play --web) into vtts's package
# data, vtts/export/player/vendor/, from the npm package `three` at the version pinned here. The
# player loads nothing from the network at run time: these files are all it has.
#
# usage: scripts/vendor_three.sh            (needs npm; run it after changing THREE_VERSION, and
#                                            check the player with tests/export/test_web_browser.py)
#
# What is copied: the core build (three.module.min.js and the three.core.min.js it imports), the
# GLTFLoader and OrbitControls add-ons and every add-on file they import (followed here, so a new
# three.js release that imports one more file fails loudly instead of shipping a broken player),
# and three's LICENSE. The tarball's sha512 must be the one pinned: a republished or tampered
# package is refused.
set -euo pipefail
cd "$(dirname "$0")/.."

THREE_VERSION=0.182.0
THREE_INTEGRITY="sha512-GbHabT+Irv+ihI1/f5kIIsZ+Ef9Sl5A1Y7imvS5RQjWgtTPfPnZ43JmlYI7NtCRDK9zir20lQpfg8/9Yd02OvQ=="
dest=vtts/export/player/vendor

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
(cd "$work" && npm pack --silent "three@$THREE_VERSION" >/dev/null)
tarball="$work/three-$THREE_VERSION.tgz"
got="sha512-$(openssl dgst -sha512 -binary "$tarball" | base64 -w0)"
if [ "$got" != "$THREE_INTEGRITY" ]; then
  echo "vendor_three: three@$THREE_VERSION has integrity $got, expected $THREE_INTEGRITY" >&2
  exit 1
fi
tar -xzf "$tarball" -C "$work"
pkg="$work/package"

rm -rf "$dest.new"
mkdir -p "$dest.new/addons"
cp "$pkg/build/three.module.min.js" "$pkg/build/three.core.min.js" "$dest.new/"
cp "$pkg/LICENSE" "$dest.new/LICENSE"

# The modules an ES module file imports: its import statements' specifiers (lines that begin with
# `import` or close an import list with `} from`; doc comments that show imports are not code).
imports() {
  grep -E "^(import|\}) .*from '[^']+';?\s*$|^import '[^']+';?\s*$" "${1:-/dev/stdin}" |
    sed -E "s/.*'([^']+)'.*/\1/"
}

# the add-ons, and what they import relatively (BufferGeometryUtils, SkeletonUtils, ...)
queue=(loaders/GLTFLoader.js controls/OrbitControls.js)
while ((${#queue[@]})); do
  rel="${queue[0]}"
  queue=("${queue[@]:1}")
  [ -f "$dest.new/addons/$rel" ] && continue
  mkdir -p "$(dirname "$dest.new/addons/$rel")"
  cp "$pkg/examples/jsm/$rel" "$dest.new/addons/$rel"
  while read -r imported; do
    resolved="$(realpath -m --relative-to="$pkg/examples/jsm" \
      "$pkg/examples/jsm/$(dirname "$rel")/$imported")"
    queue+=("$resolved")
  done < <(imports "$pkg/examples/jsm/$rel" | grep -E '^\.{1,2}/' || true)
done
# every bare import must be 'three' itself, which the player's import map resolves
if find "$dest.new/addons" -name '*.js' -print0 | xargs -0 cat | imports | grep -vE '^(three|\.{1,2}/.*)$'
then
  echo "vendor_three: an add-on imports a package other than three (above)" >&2
  exit 1
fi
echo "$THREE_VERSION" >"$dest.new/VERSION"

rm -rf "$dest"
mv "$dest.new" "$dest"
echo "vendored three@$THREE_VERSION into $dest:"
(cd "$dest" && find . -type f | sort | sed 's/^\.\//  /')
