"""vtts serve with the Python client: the real server (in a thread of this process, on
127.0.0.1) speaking with espeak-ng, one server for the module.

What a clause streams (its audio, its face on the audio's clock, its words and bookmarks), text
in pieces, stop, several sessions at once, and bad input and faults: errors come back as messages
naming what was wrong, and the server and every other session go on.
"""

from __future__ import annotations

import asyncio
import base64
import collections
import contextlib
import itertools
import json
import os
import socket
import struct
import time

import aiohttp
import numpy as np
import pytest

from vtts.errors import ServeError
from vtts.limits import MAX_SERVE_MESSAGE_BYTES, MAX_SERVE_SESSIONS, MAX_SERVE_TEXT_CHARS
from vtts.serve.client import Client

from ..in_process import vtts


@pytest.fixture(scope="module")
def server():
    from vtts.serve.server import Server, load_heads, warm_up

    srv = Server(load_heads(["cybatt"]))
    srv.send_timeout = 1.0
    warm_up(srv)
    with srv.running() as url:
        yield srv, url


def run(coroutine):
    return asyncio.run(asyncio.wait_for(coroutine, 60))


async def said(url: str, text: str, **fields):
    async with Client(url) as c:
        opened = await c.open(**fields)
        await c.say(text)
        return opened, await c.utterance()


def test_a_say_streams_audio_and_a_face_on_the_audio_clock(server):
    _, url = server
    opened, heard = run(said(url, "Hello there, how are you <smile> today?"))
    assert opened["model"] == "cybatt" and opened["version"] == 1
    assert heard.ended == "end" and heard.errors == []
    assert [c["text"] for c in heard.clauses] == ["Hello there,", "how are you <smile> today?"]
    duration = len(heard.audio) / heard.rate
    assert heard.rate == 22050 and 1.0 < duration < 4.0
    assert np.abs(heard.audio.astype(np.int32)).max() > 1000  # speech, not silence
    # every clause's frames start at its first sample and cover its audio at 30 Hz
    for clause in heard.clauses:
        assert clause["start"] == pytest.approx(clause["first"] / clause["rate"])
        assert clause["frames"] == int(np.ceil(clause["samples"] / clause["rate"] * 30 - 1e-9))
    assert len(heard.times) == sum(c["frames"] for c in heard.clauses)
    assert np.all(np.diff(heard.times) > 0) and heard.times[-1] < duration
    assert heard.values.shape == (len(heard.times), len(opened["params"]))
    # the mouth moves: the visemes' values change while it speaks
    visemes = [i for i, p in enumerate(opened["params"]) if 68 < p < 83]
    assert heard.values[:, visemes].max() > 0.5
    words = [w[2] for w in heard.words]
    assert words == ["Hello", "there", "how", "are", "you", "today"]
    assert all(a <= b <= duration for a, b, _ in heard.words)
    ((when, name),) = heard.bookmarks
    assert name == "smile" and heard.words[4][1] <= when + 1e-6 <= heard.words[5][0] + 0.01


def test_appended_pieces_are_spoken_as_clauses_complete(server):
    _, url = server

    async def go():
        async with Client(url) as c:
            await c.open()
            for piece in ["The", " quick brown", " fox,", " jumps over", " the dog."]:
                await c.append(piece)
            first = await c.receive()  # the first clause comes before the text ends
            await c.flush()
            heard = await c.utterance()
            return first, heard

    first, heard = run(go())
    assert first["type"] == "clause" and first["text"] == "The quick brown fox,"
    assert heard.ended == "end"
    assert [c["text"] for c in heard.clauses] == ["jumps over the dog."]
    assert heard.clauses[0]["clause"] == 1 and heard.clauses[0]["first"] > 0


def test_stop_ends_the_utterance_and_the_next_starts_cleanly(server):
    srv, url = server

    async def go():
        async with Client(url) as c:
            await c.open()
            await c.say("This is the first sentence. " * 20)
            m = await c.receive()
            assert m["type"] == "clause"
            start = time.monotonic()
            await c.stop()
            stopped = await c.utterance()
            took = time.monotonic() - start
            await c.say("Next.")
            return stopped, took, await c.utterance()

    stopped, took, after = run(go())
    assert stopped.ended == "stopped" and len(stopped.clauses) < 20
    assert took < 0.5
    assert after.ended == "end" and after.number == stopped.number + 1
    assert [c["text"] for c in after.clauses] == ["Next."] and after.clauses[0]["first"] == 0


def test_sessions_are_independent(server):
    """Two sessions at once, each with its own seed: each gets its own utterance; the same seed
    gives the same face."""
    _, url = server

    async def go():
        return await asyncio.gather(
            said(url, "Look at me now.", seed=1),
            said(url, "Look at me now.", seed=2),
            said(url, "Look at me now.", seed=1),
        )

    (_, a), (_, b), (_, c) = run(go())
    np.testing.assert_array_equal(a.audio, b.audio)  # the same speech …
    np.testing.assert_array_equal(a.values, c.values)
    assert not np.array_equal(a.values, b.values)  # … with its own blinks and head motion


@pytest.mark.parametrize(
    "message, code, words",
    [
        (
            {"type": "open", "model": "nobody"},
            "model",
            "no model 'nobody' here; this server has cybatt",
        ),
        ({"type": "open", "version": 2}, "version", "protocol version 1, not 2"),
        ({"type": "open", "model": [1]}, "malformed", "model must be a name (a string)"),
        ({"type": "open", "rate": "fast"}, "malformed", "rate must be a whole number"),
        ({"type": "open", "engine": "x"}, "engine", "unknown speech engine 'x'"),
        ({"type": "open", "seed": -1}, "malformed", "seed must be a whole number"),
        ({"type": "say", "text": "hi"}, "not-open", "open a session before say"),
        ({"type": "shout"}, "malformed", "unknown message type 'shout'"),
        ({"type": "open", "colour": 1}, "malformed", "open has no field 'colour'"),
        ([1, 2], "malformed", "must be a JSON object"),
    ],
)
def test_a_bad_message_is_answered_with_an_error_naming_it(server, message, code, words):
    _, url = server

    async def go():
        async with Client(url) as c:
            await c.send(message)
            (error,) = await c.errors()
            await c.open()  # the session is still there
            return error

    error = run(go())
    assert error["code"] == code and words in error["message"]


def test_bad_text_and_garbage(server):
    _, url = server

    async def go():
        async with Client(url) as c:
            await c.open()
            await c.say("Hello <frown> there")
            await c._ws.send_bytes(bytes(range(256)) * 4)
            await c._ws.send_str("{not json")
            await c.say("x" * (MAX_SERVE_TEXT_CHARS + 1))
            await c.say(" <smile> ")
            errors = await c.errors(5)
            await c.say("Still here.")
            return errors, await c.utterance()

    errors, heard = run(go())
    codes = [e["code"] for e in errors]
    assert codes == ["bookmark", "malformed", "malformed", "too-long", "empty"]
    assert "column 7: unknown bookmark <frown>" in errors[0]["message"]
    assert "not binary (1024 bytes ignored)" in errors[1]["message"]
    assert "MAX_SERVE_TEXT_CHARS" in errors[3]["message"]
    assert heard.ended == "end" and heard.clauses[0]["text"] == "Still here."


def test_ten_megabytes_of_text_close_that_socket_only(server):
    _, url = server

    async def go():
        async with Client(url) as c:
            await c.open()
            try:
                await c.say("word " * (2 << 20))  # 10 MiB
            except ServeError as e:  # the server closed the socket while the client still sent
                assert "the session is closed" in str(e)
            else:
                with pytest.raises(ServeError, match="code 1009"):
                    while True:
                        await c.receive()
        return await said(url, "Fine.")

    assert MAX_SERVE_MESSAGE_BYTES < 10 << 20
    _, heard = run(go())
    assert heard.ended == "end"


def test_a_client_that_leaves_mid_utterance_or_never_reads(server):
    """One client disconnects while its utterance is spoken, another never reads its socket:
    the never-reader's session stops synthesizing once its socket's buffers are full and is
    closed after the send timeout, and a third session is served meanwhile."""
    srv, url = server

    before = srv.spoken_clauses_total

    async def go():
        async with Client(url) as gone:
            await gone.open()
            await gone.say("Going away now. " * 10)
            await gone.receive()
        never = never_reader(url, [{"type": "open"}, {"type": "say", "text": "On and on. " * 300}])
        try:
            _, heard = await said(url, "Meanwhile, hello.")
            deadline = time.monotonic() + 10
            while srv.sessions and time.monotonic() < deadline:
                await asyncio.sleep(0.1)
            return heard, srv.spoken_clauses_total - before
        finally:
            never.close()

    heard, spoken = run(go())
    assert heard.ended == "end"
    assert not srv.sessions  # both gone: one closed, one timed out
    assert spoken < 30  # of the never-reader's 300 clauses, only what the buffers held


def never_reader(url: str, messages: list[dict]) -> socket.socket:
    """A WebSocket client (a plain socket with a 4 KiB receive buffer) that sends ``messages``
    and never reads what the server sends."""
    host, port = url.removeprefix("http://").split(":")
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect((host, int(port)))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        f"GET /session HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n".encode()
    )
    answer = b""
    while b"\r\n\r\n" not in answer:
        answer += sock.recv(1)  # the upgrade's answer, nothing more
    assert answer.startswith(b"HTTP/1.1 101")
    for m in messages:
        data = json.dumps(m).encode()
        mask = os.urandom(4)
        size = (
            bytes([0x80 | len(data)]) if len(data) < 126 else b"\xfe" + struct.pack(">H", len(data))
        )
        head = b"\x81" + size
        sock.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data)))
    return sock


def test_a_thousand_sockets(server):
    """1,000 sockets at once: the first MAX_SERVE_SESSIONS are sessions, the rest are told the
    server is full; once they close, a session is served as before."""
    srv, url = server

    async def go():
        async with aiohttp.ClientSession(connector=aiohttp.TCPConnector(limit=0)) as http:
            sockets = await asyncio.gather(
                *[http.ws_connect(url.replace("http", "ws") + "/session") for _ in range(1000)]
            )

            # which sockets became sessions is the order they reached the server in, not the
            # list's: each is asked to open, and answers "opened" or was told "full"
            async def first_answer(ws) -> str:
                with contextlib.suppress(ConnectionError):
                    await ws.send_str(json.dumps({"type": "open"}))
                m = await ws.receive(timeout=30)
                if m.type != aiohttp.WSMsgType.TEXT:
                    return str(m.type)
                m = json.loads(m.data)
                return m.get("code", m["type"])

            answers = await asyncio.gather(*[first_answer(ws) for ws in sockets])
            full = answers.count("full")
            sessions = len(srv.sessions)
            assert answers.count("opened") == MAX_SERVE_SESSIONS, collections.Counter(answers)
            await asyncio.gather(*[ws.close() for ws in sockets])
        for _ in range(100):
            if not srv.sessions:
                break
            await asyncio.sleep(0.05)
        return full, sessions, await said(url, "Hello again.")

    full, sessions, (_, heard) = run(go())
    assert sessions == MAX_SERVE_SESSIONS and full == 1000 - MAX_SERVE_SESSIONS
    assert heard.ended == "end"


def test_http_routes(server):
    _, url = server

    async def go():
        async with aiohttp.ClientSession() as http:
            out = {}
            for path in ("/", "/heads", "/heads/cybatt.glb", "/heads/nobody.glb",
                         "/vtts/serve.js", "/player/head.js", "/vtts/../server.py"):  # fmt: skip
                async with http.get(url + path) as r:
                    out[path] = (r.status, await r.read())
            return out

    out = run(go())
    assert out["/"][0] == 200 and b'"heads": ["cybatt"]' in out["/"][1]
    assert json.loads(out["/heads"][1]) == {"heads": ["cybatt"]}
    assert out["/heads/cybatt.glb"][0] == 200 and out["/heads/cybatt.glb"][1][:4] == b"glTF"
    assert out["/heads/nobody.glb"][0] == 404
    assert out["/vtts/serve.js"][0] == 200 and out["/player/head.js"][0] == 200
    assert out["/vtts/../server.py"][0] in (403, 404)


@pytest.mark.parametrize(
    "args, words",
    [
        (["--port", "70000"], "--port must be within 0 to 65535, got 70000"),
        (["--model", "nosuch"], "no model 'nosuch'"),
        (["--engine", "x"], "--engine must be one of"),
        (["--fps", "0"], "--fps"),
    ],
)
def test_the_command_refuses_bad_options(args, words):
    result = vtts("serve", *args)
    assert result.returncode == 1 and words in result.stderr


def test_random_control_messages_never_end_the_session(server):
    """200 messages of random shapes (types, fields and values of every JSON kind): each is
    answered with an error or taken; the session then opens and speaks as usual."""
    _, url = server
    rng = np.random.default_rng(42)
    values = [None, True, -1, 0, 2**70, 1.5, float("1e308"), "", "x", "<", "<smile", [], [1], {},
              {"a": 1}, "\x00", "é" * 3]  # fmt: skip
    kinds = ["open", "say", "append", "flush", "stop", "nope", None, 7]
    fields = ["type", "model", "version", "text", "seed", "rate", "pitch", "voice", "engine", "x"]

    def message():
        m = {"type": kinds[rng.integers(len(kinds))]}
        for _ in range(rng.integers(0, 4)):
            m[fields[rng.integers(len(fields))]] = values[rng.integers(len(values))]
        return m

    async def go():
        async with Client(url) as c:
            for _ in range(200):
                m = message()
                if m.get("type") == "open":
                    m["model"] = "nobody"  # stays unopened: every later message is checked too
                await c.send(m)
            await c.send({"type": "open"})
            while True:  # the answers to the random messages, then the session's
                m = await c.receive()
                if isinstance(m, dict) and m["type"] == "opened":
                    break
                assert isinstance(m, dict) and m["type"] == "error", m
                assert m["code"] != "internal", m
            await c.say("Still fine.")
            return await c.utterance()

    heard = run(go())
    assert heard.ended == "end" and len(heard.audio) > 0


def test_a_voice_sent_in_pieces_comes_back_with_its_face(server):
    """``listen``: a voice (espeak-ng's, 22,050 Hz) sent in pieces of odd sizes (one ending
    inside a sample) comes back whole, with a face frame per 1/30 s that opens the mouth while
    it speaks and closes it for the m of "mom"; meanwhile text is refused; a stop ends it."""
    from vtts.animate.lipsync import lip_gaps
    from vtts.api.speak import speak
    from vtts.face import load_model

    model = load_model("cybatt")
    spoken = speak("Mom, may I go out and play?", model, seed=0)
    pcm = spoken.audio.astype("<i2").tobytes()

    async def go():
        async with Client(url) as c:
            opened = await c.open()
            await c.listen(spoken.rate)
            cuts = [0, 1, 4411, 9000, 20001, *range(30000, len(pcm), 8821), len(pcm)]
            for a, b in itertools.pairwise(cuts):
                await c.send_audio(pcm[a:b])
            await c.flush()
            heard = await c.utterance()
            await c.listen(16000)
            await c.send_audio(np.zeros(1600, np.int16))
            await c.say("Hello.")
            busy = (await c.errors())[0]
            await c.stop()
            stopped = await c.utterance()
            await c.say("Fine.")
            return opened, busy, heard, stopped, await c.utterance()

    _, url = server
    opened, busy, heard, stopped, after = run(go())
    assert busy["code"] == "busy" and "listening" in busy["message"]
    assert heard.ended == "end" and heard.rate == spoken.rate and heard.clauses == []
    assert np.array_equal(heard.audio, spoken.audio)
    duration = len(spoken.audio) / spoken.rate
    assert np.allclose(heard.times, np.arange(len(heard.times)) / 30.0)
    assert abs(len(heard.times) - duration * 30) <= 2
    params = np.zeros((len(heard.values), 90))
    params[:, opened["params"]] = heard.values
    gap = lip_gaps(model, params)
    assert gap.max() > 0.3 * abs(gap).max() and (gap > 0.3 * gap.max()).mean() > 0.25
    first_m = int(spoken.words[0][0] * 30)  # the m of "Mom": lips shut within 2 frames
    assert gap[max(first_m - 2, 0) : first_m + 3].min() < 0.1 * gap.max()
    assert stopped.ended == "stopped" and after.ended == "end" and len(after.audio) > 0


@pytest.mark.parametrize(
    "message, words",
    [
        ({"type": "listen"}, "listen needs a rate"),
        ({"type": "listen", "rate": 1}, "8000–192000 Hz, got 1"),
        ({"type": "listen", "rate": 16000.5}, "got 16000.5"),
        ({"type": "listen", "rate": 16000, "autonomous": "yes"}, "autonomous must be"),
    ],
)
def test_a_bad_listen_is_an_error(server, message, words):
    async def go():
        async with Client(url) as c:
            await c.open()
            await c.send(message)
            error = (await c.errors())[0]
            await c.send_audio(np.zeros(100, np.int16))  # not listening: binary is an error
            return error, (await c.errors())[0]

    _, url = server
    error, binary = run(go())
    assert error["code"] == "malformed" and words in error["message"], error
    assert binary["code"] == "malformed" and "binary" in binary["message"]
