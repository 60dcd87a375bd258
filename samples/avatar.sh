#!/usr/bin/env bash
# adi import: an ARKit-blendshape glTF head becomes a personalized model that every vtts command
# takes. No such avatar ships with vtts, so the script first writes one: lotta exported with her
# ARKit shapes and Oculus visemes as morph targets (out/avatar/lotta-arkit.glb, by
# vtts.export.avatar); give your own Ready Player Me, VRoid or Character Creator .glb instead.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p out/avatar
.venv/bin/python -c 'from vtts.face import load_model
from vtts.export.avatar import write_arkit_avatar
write_arkit_avatar("out/avatar/lotta-arkit.glb", load_model("lotta"))'
.venv/bin/adi import out/avatar/lotta-arkit.glb -o out/avatar/lotta-imported.wrl
.venv/bin/adi show out/avatar/lotta-imported.wrl | sed -n 1,4p
.venv/bin/vtts say "Hello <smile 2s>, I came in as an ARKit avatar. <blink>" \
  --model out/avatar/lotta-imported.wrl -o out/avatar/hello.mp4
