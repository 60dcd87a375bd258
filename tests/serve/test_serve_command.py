"""``vtts serve`` as a process, since the process is the point: the console script starts the
server by itself (no other process), says where it listens, serves the page, the head and a
session, and ends cleanly on SIGTERM."""

from __future__ import annotations

import asyncio
import os
import re
import select
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

from vtts.serve.client import Client

ROOT = Path(__file__).parents[2]


def test_the_command_serves_until_sigterm():
    exe = Path(sys.executable).with_name("vtts")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [str(exe), "serve", "--port", "0", "--model", "cybatt"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        deadline = time.monotonic() + 60
        line = ""
        while time.monotonic() < deadline and "http://" not in line:
            ready, _, _ = select.select([proc.stdout], [], [], 1)
            if ready:
                line = proc.stdout.readline()
            assert proc.poll() is None, proc.stderr.read()
        url = re.search(r"http://127\.0\.0\.1:\d+", line)[0]
        with urllib.request.urlopen(f"{url}/") as r:
            assert r.status == 200 and b'<meta name="generator" content="vtts serve">' in r.read()
        with urllib.request.urlopen(f"{url}/heads/cybatt.glb") as r:
            assert r.read(4) == b"glTF"

        async def say():
            async with Client(url) as c:
                await c.open()
                await c.say("Hi.")
                return await c.utterance()

        heard = asyncio.run(say())
        assert heard.ended == "end" and len(heard.audio) > 0
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    assert "vtts serve: stopped" in out
