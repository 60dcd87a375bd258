#!/usr/bin/env bash
# What `make demo` runs. Until the bundled heads and `vtts say` land, it checks and describes the
# test head and plays a real MPEG-4 FAP stream on it into out/demo.mp4.
set -euo pipefail
cd "$(dirname "$0")/.."
vtts=.venv/bin/vtts
head=tests/data/models/head.wrl
echo "== vtts check $head tests/data/fap/xface-joy.fap"
$vtts check "$head" tests/data/fap/xface-joy.fap
echo
echo "== vtts info $head"
$vtts info "$head" | tail -n 12
echo
echo "== vtts play tests/data/fap/xface-joy.fap --model $head -o out/demo.mp4"
$vtts play tests/data/fap/xface-joy.fap --model "$head" -o out/demo.mp4
echo "the video is in $(pwd)/out/demo.mp4"
