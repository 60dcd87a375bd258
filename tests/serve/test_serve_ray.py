"""``vtts serve --replicas 2``: the server on Ray Serve, a local Ray of this machine, as a
process (the command starts Ray and Serve itself). Four sessions through Ray's HTTP proxy spread
over the two replicas; one replica is killed (SIGKILL): its sessions end with the client's
error, the other replica's sessions speak on; the page comes through the proxy; SIGTERM ends
the command and its Ray."""

from __future__ import annotations

import asyncio
import os
import signal
import socket
import subprocess
import urllib.request
from pathlib import Path

import pytest

from vtts.errors import ServeError
from vtts.serve.client import Client

from .serving import start_serving

ROOT = Path(__file__).parents[2]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def ray_serve(one_ray_at_a_time):
    """``(url, the command's process)``: ``vtts serve --replicas 2`` once it says it serves."""
    port = _free_port()
    args = ["--replicas", "2", "--port", str(port), "--model", "cybatt"]
    url, line, proc = start_serving(args, 180)
    try:
        assert f"http://127.0.0.1:{port}/" in line and "2 Ray Serve replicas" in line, line
        yield url, proc
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.communicate(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.communicate()


async def _sessions(url: str) -> list[str]:
    """Four sessions: each says a sentence; then the replica of the first is killed and each
    says another. Returns, per session, its replica and what became of the second sentence."""
    clients = [Client(url, timeout=60) for _ in range(4)]
    for c in clients:
        await c.connect()
    try:
        servers = [(await c.open())["server"] for c in clients]
        for c in clients:
            await c.say("Hello there.")
        for c in clients:
            heard = await c.utterance()
            assert heard.ended == "end" and len(heard.audio) > 10_000
        victim = int(servers[0].rsplit(":", 1)[1])
        os.kill(victim, signal.SIGKILL)
        outcome = []
        for c, server in zip(clients, servers, strict=True):
            try:
                await c.say("Good morning to you all.")
                heard = await c.utterance(timeout=30)
                outcome.append((server, f"{heard.ended} {len(heard.audio) > 20_000}"))
            except ServeError as e:
                outcome.append((server, f"closed: {e}"))
        return outcome
    finally:
        for c in clients:
            await c.close()


def test_sessions_spread_over_replicas_and_a_killed_one_ends_only_its_own(ray_serve):
    url, proc = ray_serve
    with urllib.request.urlopen(f"{url}/", timeout=30) as r:
        assert r.status == 200 and b'<meta name="generator" content="vtts serve">' in r.read()
    with urllib.request.urlopen(f"{url}/heads/cybatt.glb", timeout=30) as r:
        assert r.read(4) == b"glTF"
    outcome = asyncio.run(asyncio.wait_for(_sessions(url), 180))
    servers = {server for server, _ in outcome}
    assert len(servers) == 2, f"the sessions did not spread over the replicas: {outcome}"
    victim = outcome[0][0]
    for server, what in outcome:
        if server == victim:
            assert what.startswith("closed: "), outcome
        else:
            assert what == "end True", outcome

    # Ray starts another replica in the dead one's place: a new session is served
    async def again() -> str:
        async with Client(url, timeout=60) as c:
            opened = await c.open()
            await c.say("Hi.")
            heard = await c.utterance()
            return f"{opened['server'] != victim} {heard.ended}"

    assert asyncio.run(asyncio.wait_for(again(), 120)) == "True end"
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err[-3000:]
    assert "Traceback" not in err, err[-3000:]
    assert "vtts serve: stopped" in out
