#!/usr/bin/env bash
# A real camera video (the paper's second experiment): a head is fitted to Akiyo's first frame,
# tracked and coded at 12.5 Hz; the decoder rebuilds the video from the bitstream alone, and
# cybatt performs what Akiyo did. The first 50 frames, to keep it short.
set -euo pipefail
cd "$(dirname "$0")/.."
v=.venv/bin/vtts
mkdir -p out/camera
ffmpeg=$(.venv/bin/python -c "import imageio_ffmpeg; print(imageio_ffmpeg.get_ffmpeg_exe())")
"$ffmpeg" -loglevel error -y -i tests/data/video/akiyo_cif.mp4 -frames:v 50 out/camera/akiyo50.mp4
$v analyze out/camera/akiyo50.mp4 -o out/camera/akiyo.fbs --rate 12.5 --report out/camera/report
$v check out/camera/akiyo.fbs
$v play out/camera/akiyo.fbs --model out/camera/akiyo-model.wrl --viewpoint photo --size 352x288 \
  -o out/camera/decoded.mp4
$v play out/camera/akiyo.fbs --model cybatt -o out/camera/puppet.mp4
