#!/usr/bin/env bash
# Lip-sync for recorded speech: a recording (here festival's HTS voice stands in for a person) and
# its transcript with bookmarks; vtts aligns the transcript's phones to the recording, writes the
# aligned word and phone timings, and animates cybatt with that audio.
set -euo pipefail
cd "$(dirname "$0")/.."
v=.venv/bin/vtts
mkdir -p out
text="Good morning <smile 2s> and welcome. Maybe <nod> you would like to meet my friend Bob."
$v say "$text" --engine festival --model lotta --wav-out out/recording.wav --quiet
$v say "$text" --audio out/recording.wav --model cybatt -o out/aligned.mp4 \
  --timings-out out/aligned.tsv
