#!/usr/bin/env bash
# What `make demo` runs. For now vtts parses, checks and describes a sample model; as the speaking
# pipeline lands this becomes `vtts say` writing out/demo.mp4.
set -euo pipefail
cd "$(dirname "$0")/.."
vtts=.venv/bin/vtts
echo "== vtts check samples/candide3.wrl"
$vtts check samples/candide3.wrl
echo
echo "== vtts info samples/candide3.wrl"
$vtts info samples/candide3.wrl
