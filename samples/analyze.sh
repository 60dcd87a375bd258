#!/usr/bin/env bash
# FAPs from video: cybatt performs a real FAP stream, vtts analyze estimates the FAPs back from
# the video (with a report), and lotta performs the estimate.
set -euo pipefail
cd "$(dirname "$0")/.."
v=.venv/bin/vtts
$v play samples/fap/xface-joy.fap --model cybatt --fps 25 -o out/joy-cybatt.mp4
$v analyze out/joy-cybatt.mp4 --model cybatt -o out/joy-estimated.fap --step 2 \
  --report out/joy-report
$v play out/joy-estimated.fap --model lotta -o out/joy-estimated-lotta.mp4
