#!/usr/bin/env bash
# What `make demo` runs: cybatt, a bundled personalized head, says a bookmarked text — it smiles,
# blinks, is surprised and closes its lips on every b, p and m — into out/demo.mp4.
set -euo pipefail
cd "$(dirname "$0")/.."
echo "== vtts say --file samples/texts/welcome.txt --model cybatt -o out/demo.mp4"
cat samples/texts/welcome.txt
.venv/bin/vtts say --file samples/texts/welcome.txt --model cybatt -o out/demo.mp4 \
  --fap-out out/demo.fap
echo "the video is in $(pwd)/out/demo.mp4"
