"""``vtts serve`` as a process, since the process is the point: the console script starts the
server by itself (no other process), says where it listens, serves the page, the head and a
session, and ends cleanly on SIGTERM."""

from __future__ import annotations

import asyncio
import signal
import urllib.request
from pathlib import Path

from vtts.serve.client import Client

from .serving import start_serving

ROOT = Path(__file__).parents[2]


def test_the_command_serves_until_sigterm():
    url, _, proc = start_serving(["--port", "0", "--model", "cybatt"], 60)
    try:
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
