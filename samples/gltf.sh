#!/usr/bin/env bash
# The animation as glTF 2.0: cybatt says hello into out/hello.glb (the speech beside it, a glTF
# has no sound), and both heads play a real FAP file into out/joy.gltf (JSON, everything inside).
# Drop either into Blender (File > Import > glTF 2.0), three.js or any glTF viewer; docs/web.md
# says how the ADTs are encoded.
set -euo pipefail
cd "$(dirname "$0")/.."
v=.venv/bin/vtts
$v say "Hello <smile>, I am a glTF file now. <blink>" --model cybatt -o out/hello.glb \
  --wav-out out/hello.wav
$v play samples/fap/xface-joy.fap --model cybatt --model lotta -o out/joy.gltf
