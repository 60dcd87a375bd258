"""The server as an ASGI application (:mod:`vtts.serve.asgi`, what Ray Serve's replicas run) on
uvicorn in a thread of this process, driven by the Python client: the same routes and sessions
as on aiohttp, and the same answers to bad input (binary messages, a message over the limit,
a client that leaves mid-utterance)."""

from __future__ import annotations

import asyncio
import threading
import time
import urllib.error
import urllib.request

import aiohttp
import pytest
import uvicorn  # noqa: F401  (the test extra installs ray[serve], which brings it)

from vtts.limits import MAX_SERVE_MESSAGE_BYTES
from vtts.serve.client import Client


@pytest.fixture(scope="module")
def url():
    from vtts.serve.asgi import asgi_app
    from vtts.serve.server import Server, load_heads, warm_up

    server = Server(load_heads(["cybatt"]))
    warm_up(server)
    config = uvicorn.Config(asgi_app(server), host="127.0.0.1", port=0, log_level="error",
                            lifespan="on", ws_max_size=4 * MAX_SERVE_MESSAGE_BYTES)  # fmt: skip
    uv = uvicorn.Server(config)
    thread = threading.Thread(target=uv.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not uv.started:
        assert time.monotonic() < deadline and thread.is_alive(), "uvicorn did not start"
        time.sleep(0.05)
    port = uv.servers[0].sockets[0].getsockname()[1]
    yield f"http://127.0.0.1:{port}"
    uv.should_exit = True
    thread.join(30)


def run(coroutine):
    return asyncio.run(asyncio.wait_for(coroutine, 60))


def test_the_page_the_heads_and_a_session(url):
    with urllib.request.urlopen(f"{url}/") as r:
        assert b'<meta name="generator" content="vtts serve">' in r.read()
    with urllib.request.urlopen(f"{url}/heads") as r:
        assert r.read() == b'{"heads":["cybatt"]}'
    with urllib.request.urlopen(f"{url}/heads/cybatt.glb") as r:
        assert r.read(4) == b"glTF"
    with urllib.request.urlopen(f"{url}/vtts/client.js") as r:
        assert b"WebSocket" in r.read()
    with pytest.raises(urllib.error.HTTPError, match="404"):
        urllib.request.urlopen(f"{url}/heads/nobody.glb")

    async def session():
        async with Client(url) as c:
            opened = await c.open()
            await c.say("Hello there, how are you <smile> today?")
            return opened, await c.utterance()

    opened, heard = run(session())
    assert opened["model"] == "cybatt" and ":" in opened["server"]
    assert heard.ended == "end" and heard.errors == []
    assert [c["text"] for c in heard.clauses] == ["Hello there,", "how are you <smile> today?"]
    assert heard.values.shape[0] == len(heard.times) > 30 and len(heard.audio) > 22050
    assert [b[1] for b in heard.bookmarks] == ["smile"]


def test_bad_messages_are_errors_and_an_oversized_one_closes_with_1009(url):
    async def session():
        async with Client(url) as c:
            await c.open()
            await c._ws.send_bytes(b"\x00\xff garbage")
            binary = (await c.errors())[0]
            await c.send({"type": "sing"})
            unknown = (await c.errors())[0]
            await c._ws.send_str("x" * (MAX_SERVE_MESSAGE_BYTES + 1))
            msg = await c._ws.receive()
            return binary, unknown, msg.type, c._ws.close_code

    binary, unknown, kind, code = run(session())
    assert binary["code"] == "malformed" and "binary" in binary["message"]
    assert unknown["code"] == "malformed" and "'sing'" in unknown["message"]
    assert kind in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED) and code == 1009


def test_a_client_that_leaves_mid_utterance_leaves_the_others_speaking(url):
    async def leaver():
        c = Client(url)
        await c.connect()
        await c.open()
        await c.say("I start a long sentence and then I leave without a word, " * 3)
        await c.receive()  # its first clause is on its way
        await c.close()

    async def stayer():
        async with Client(url) as c:
            await c.open()
            await c.say("I am still here.")
            return await c.utterance()

    async def both():
        await leaver()
        return await stayer()

    heard = run(both())
    assert heard.ended == "end" and len(heard.audio) > 10_000
