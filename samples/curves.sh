#!/usr/bin/env bash
# Curves out: cybatt's lip-sync and expressions as the curves other avatar engines play
# (docs/avatars.md): 52 ARKit blendshape weights per frame, the 15 Oculus visemes per frame,
# Azure-style SAPI viseme events and TalkingHead's viseme track, with the speech beside them;
# and a real FAP file as ARKit weights.
set -euo pipefail
cd "$(dirname "$0")/.."
v=.venv/bin/vtts
text="Hello <smile>, I speak for your own avatar now. <blink>"
$v say "$text" --model cybatt --curves-out out/hello-arkit.json --wav-out out/hello.wav
for format in oculus azure talkinghead; do
  $v say "$text" --model cybatt --curves-out "out/hello-$format.json" --curves "$format"
done
$v play samples/fap/xface-joy.fap --model cybatt --curves-out out/joy-arkit.json
