#!/usr/bin/env bash
# The ADI: export deformed poses of a model, rebuild its tables from them, and summarize.
set -euo pipefail
cd "$(dirname "$0")/.."
v=.venv/bin/vtts
mkdir -p out/adi
cp tests/data/models/head.wrl out/adi/neutral.wrl
$v pose --model tests/data/models/head.wrl --fap 19=512 -o out/adi/close_t_l_eyelid@512.wrl
$v pose --model tests/data/models/head.wrl --fap 19=1024 -o out/adi/close_t_l_eyelid@1024.wrl
$v pose --model tests/data/models/head.wrl --expression joy=1 -o out/adi/joy@1.wrl
.venv/bin/adi build out/adi/neutral.wrl out/adi/*@*.wrl -o out/adi/rebuilt.adt
.venv/bin/adi show out/adi/rebuilt.adt
