#!/usr/bin/env bash
# Many clips at once: the jobs of samples/batch.jsonl (say, play and render jobs with the commands'
# own options) on a local Ray instance with two workers, into out/batch/. Run it twice: the second
# run finds every job in out/batch/manifest.jsonl and renders nothing.
set -euo pipefail
cd "$(dirname "$0")/.."
v=.venv/bin/vtts
$v batch samples/batch.jsonl --out out/batch --dry-run
$v batch samples/batch.jsonl --out out/batch --workers 2
