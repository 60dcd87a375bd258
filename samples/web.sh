#!/usr/bin/env bash
# The web player: cybatt says hello in a page that plays offline (out/hello/), and both heads play
# a real FAP file in another (out/joy-web/, no sound: the stream has none). Serve either folder
# with any static server and open it in a browser.
set -euo pipefail
cd "$(dirname "$0")/.."
v=.venv/bin/vtts
$v say "Hello <smile>, I live in your browser now. <blink>" --model cybatt --web out/hello/
$v play samples/fap/xface-joy.fap --model cybatt --model lotta --web out/joy-web/
echo "serve one:  python3 -m http.server -d out/hello   then open http://localhost:8000/"
