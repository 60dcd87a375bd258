#!/usr/bin/env bash
# Posing a model: plain VRML97 for other tools, and antialiased stills.
set -euo pipefail
cd "$(dirname "$0")/.."
v=.venv/bin/vtts
$v pose --model cybatt --fap 19=1024,20=1024 --expression joy=0.8 -o out/cybatt-posed.wrl
$v render --model cybatt --viseme 10 --fap 49=-15000 -o out/cybatt-a.png
$v render --model lotta --expression surprise -o out/lotta-surprise.png
$v render --model lotta --expression joy --background transparent -o out/lotta-cutout.png  # RGBA
