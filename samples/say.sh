#!/usr/bin/env bash
# Two personalities, one text: they speak together but smile and blink in their own ways.
set -euo pipefail
cd "$(dirname "$0")/.."
v=.venv/bin/vtts
$v say --file samples/texts/conference.txt --model cybatt --model lotta -o out/conference.mp4 \
  --size 640x360
$v say --file samples/texts/bookmarks.txt --model cybatt -o out/bookmarks.mp4 \
  --fap-out out/bookmarks.fap --wav-out out/bookmarks.wav
