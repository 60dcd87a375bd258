#!/usr/bin/env bash
# A second voice and reused timings: festival's HTS voice speaks for lotta, with its word and phone
# timings written out; the same speech as an MP3 and those timings then animate cybatt.
set -euo pipefail
cd "$(dirname "$0")/.."
v=.venv/bin/vtts
mkdir -p out
$v say --file samples/texts/welcome.txt --engine festival --model lotta -o out/festival.mp4 \
  --timings-out out/festival.tsv --wav-out out/festival.wav
ffmpeg=$(.venv/bin/python -c 'import imageio_ffmpeg; print(imageio_ffmpeg.get_ffmpeg_exe())')
"$ffmpeg" -hide_banner -loglevel error -y -i out/festival.wav -c:a libmp3lame out/festival.mp3
$v say --file samples/texts/welcome.txt --model cybatt --phonemes out/festival.tsv \
  --audio out/festival.mp3 -o out/festival-cybatt.mp4
