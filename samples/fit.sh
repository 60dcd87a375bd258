#!/usr/bin/env bash
# adi fit: a personalized head from one photograph, then it speaks and is rendered over its photo.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p out/fit
.venv/bin/adi fit tests/data/photos/akiyo_frame0.png -o out/fit/akiyo.wrl --report out/fit/report
.venv/bin/vtts say "Hello <smile 1s> I am a head made from one photo." --model out/fit/akiyo.wrl \
  -o out/fit/akiyo.mp4
.venv/bin/vtts render --model out/fit/akiyo.wrl --viewpoint photo --size 352x288 \
  -o out/fit/over-photo.png
