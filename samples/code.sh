#!/usr/bin/env bash
# FAP stream coding: the paper's 17 FAPs at 12.5 Hz, then decoding and playing the bitstream.
set -euo pipefail
cd "$(dirname "$0")/.."
v=.venv/bin/vtts
$v say --file samples/texts/welcome.txt --model cybatt --fap-out out/welcome.fap
$v encode out/welcome.fap -o out/welcome.fbs --faps paper17,1 --rate 12.5
$v decode out/welcome.fbs -o out/welcome-decoded.fap
$v play out/welcome.fbs --model cybatt -o out/welcome-decoded.mp4
