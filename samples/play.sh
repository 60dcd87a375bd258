#!/usr/bin/env bash
# A real MPEG-4 FAP stream (Xface, 25 fps) on both bundled heads, resampled to 30 fps.
set -euo pipefail
cd "$(dirname "$0")/.."
.venv/bin/vtts play samples/fap/xface-joy.fap --model cybatt --model lotta -o out/joy.mp4 \
  --size 640x360
