"""``vtts serve``: an HTTP and WebSocket server (aiohttp) that speaks text as it arrives and
streams each clause's audio and face to the page or another client.

- ``GET /`` the page (:mod:`vtts.serve` ``page/``), ``/vtts/…`` its scripts, ``/player/…`` the
  web player's, ``/vendor/…`` three.js, ``/heads/NAME.glb`` a served head's glTF, ``/heads`` the
  heads as JSON;
- ``GET /session`` one WebSocket per session, speaking :mod:`vtts.serve.protocol`.

Each session has its own head, voice, clause cutter, utterance count and seed of the autonomous
behaviour; its clauses are synthesized (espeak-ng, or another of :data:`vtts.api.say.ENGINES`)
through :func:`vtts.api.speak.speak` in a pool of worker threads shared by all sessions, one clause
of a session at a time, and sent as soon as each is ready. A session's failure is an ``error``
message on its socket; nothing a client sends ends the server or another session.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import heapq
import itertools
import json
import logging
import math
import os
import socket
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from aiohttp import WSCloseCode, WSMsgType, web

from vtts.errors import ServeError, VttsError
from vtts.limits import (
    MAX_SERVE_MESSAGE_BYTES,
    MAX_SERVE_SESSIONS,
    MAX_SERVE_TEXT_CHARS,
    SERVE_SEND_TIMEOUT_S,
    SERVE_SOCKET_BUFFER_BYTES,
)
from vtts.serve import protocol
from vtts.serve.clauses import ClauseCutter, has_words
from vtts.serve.heads import ServedHead

__all__ = ["PAGE_DIR", "Server", "ServerOptions", "run_server"]

log = logging.getLogger("vtts.serve")

#: The page and its scripts (package data).
PAGE_DIR = Path(__file__).parent / "page"
#: The web player's folder: its ``head.js`` and the vendored three.js.
PLAYER_DIR = Path(__file__).parents[1] / "export" / "player"
#: Samples of one audio message (0.25 s at 22,050 Hz): the page schedules each as it comes.
AUDIO_CHUNK = 5512
#: Clauses of one session synthesized at once: the next one starts with the one before it.
AHEAD_CLAUSES = 2
#: Seconds of speech a character of text makes, about (espeak-ng's en-us at its default rate),
#: to reckon when a clause started ahead will be needed.
SECONDS_PER_CHAR = 0.065
#: Clauses synthesized at once for all sessions: one per core this process may run on.
#: espeak-ng's workers are started ahead and wait on nothing but the CPU, so more places would
#: only share the cores and slow every clause (4 on this project's 2 cores kept 2 to 4 sessions
#: real-time, 2 kept 16: docs/serve.md).
SYNTH_WORKERS = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 2


@dataclass(frozen=True)
class ServerOptions:
    """How a server speaks: ``engine`` and ``voice`` by default (a session may ask for others),
    ``fps`` of the face, ``seed`` of the first session's autonomous behaviour (each session
    after it gets the next)."""

    engine: str = "espeak"
    voice: str | None = None
    fps: float = 30.0
    seed: int = 0


class ClientError(Exception):
    """A client's message is wrong: ``code`` (a word) and ``message`` go back to it."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code
        self.message = message


class Session:
    """One client's session: its head and voice, the text not yet spoken and the utterance being
    spoken. The reader (:meth:`handle`) and the speaker (:meth:`_speak`) are two tasks."""

    def __init__(self, server: Server, ws: web.WebSocketResponse, number: int, transport=None):
        self.server = server
        self.ws = ws
        self.transport = transport
        self.number = number
        self.head: ServedHead | None = None
        self.engine = server.options.engine
        self.voice = server.options.voice
        self.rate: int | None = None
        self.pitch: int | None = None
        self.seed = server.options.seed + number
        self.cutter = ClauseCutter()
        self.utterance = 0  # the current utterance's number; 0 before the first
        self.open_utterance = False  # text of the current utterance may still come
        self.queue: asyncio.Queue = asyncio.Queue()
        self.queued_chars = 0
        self.speaker: asyncio.Task | None = None
        self.send_lock = asyncio.Lock()
        self.clauses_spoken = 0
        self.listener = None  # a Listener while the client's voice is the utterance

    # ---- sending ------------------------------------------------------------------------------

    async def send(self, data: bytes | dict) -> None:
        """Send one message; a client that leaves its socket unread for
        :data:`SERVE_SEND_TIMEOUT_S` has its session closed."""
        async with self.send_lock:
            if self.ws.closed:
                raise ConnectionResetError("the socket is closed")
            try:
                # asyncio.timeout, not wait_for: wait_for of Python 3.11 can swallow the
                # cancellation of a stop that comes as the send completes
                async with asyncio.timeout(self.server.send_timeout):
                    if isinstance(data, dict):
                        await self.ws.send_str(json.dumps(data, allow_nan=False))
                    else:
                        await self.ws.send_bytes(data)
            except TimeoutError:
                # a close frame would wait behind the unread messages: the connection is cut
                if self.transport is not None:
                    self.transport.abort()
                raise ConnectionResetError("the client does not read") from None

    async def error(self, code: str, message: str) -> None:
        with contextlib.suppress(ConnectionResetError, ConnectionError, RuntimeError):
            await self.send({"type": "error", "code": code, "message": message})

    # ---- the reader ---------------------------------------------------------------------------

    async def handle(self) -> None:
        """Read the client's messages until it closes the socket."""
        try:
            async for msg in self.ws:
                if msg.type == WSMsgType.TEXT:
                    try:
                        await self.control(msg.data)
                    except ClientError as e:
                        await self.error(e.code, e.message)
                    except (ConnectionResetError, ConnectionError):
                        break  # an answer could not be sent: the client is gone
                elif msg.type == WSMsgType.BINARY and self.listener is not None:
                    try:
                        await self.hear(msg.data)
                    except (ConnectionResetError, ConnectionError):
                        break  # the client went away, or does not read what it is sent
                elif msg.type == WSMsgType.BINARY:
                    await self.error(
                        "malformed",
                        "clients send JSON text messages, not binary "
                        f"({len(msg.data)} bytes ignored)",
                    )  # fmt: skip
                elif msg.type == WSMsgType.ERROR:
                    break
        finally:
            await self._stop_speaking()

    async def control(self, raw: str) -> None:
        try:
            message = json.loads(raw)
        except (ValueError, RecursionError):
            raise ClientError("malformed", "a control message must be one JSON object") from None
        if not isinstance(message, dict):
            raise ClientError("malformed", "a control message must be a JSON object")
        kind = message.get("type")
        if not isinstance(kind, str) or kind not in protocol.CLIENT_MESSAGES:
            known = ", ".join(protocol.CLIENT_MESSAGES)
            raise ClientError("malformed", f"unknown message type {kind!r}; known: {known}")
        extra = set(message) - protocol.CLIENT_MESSAGES[kind] - {"type"}
        if extra:
            raise ClientError("malformed", f"{kind} has no field {sorted(extra)[0]!r}")
        if kind == "open":
            await self.open(message)
            return
        if self.head is None:
            raise ClientError("not-open", f"open a session before {kind}")
        if self.listener is not None and kind in ("say", "append", "listen"):
            raise ClientError(
                "busy", f"the session is listening: flush (or stop) its voice before {kind}"
            )
        if kind == "listen":
            await self.listen(message)
            return
        if self.listener is not None:  # flush ends the voice, stop drops it
            await (self.end_listening() if kind == "flush" else self.stop())
            return
        if kind in ("say", "append"):
            text = message.get("text")
            if not isinstance(text, str):
                raise ClientError("malformed", f"{kind} needs a text (a string)")
            if kind == "say":
                if not has_words(self.cutter.pending + text):
                    raise ClientError("empty", "nothing to say: the text has no words")
                self.check_bookmarks(text)
            await self.add_text(text, final=kind == "say")
        elif kind == "flush":
            await self.add_text("", final=True)
        elif kind == "stop":
            await self.stop()

    async def open(self, message: dict) -> None:
        if self.head is not None:
            raise ClientError("malformed", "this session is open already")
        version = message.get("version", protocol.VERSION)
        if version != protocol.VERSION:
            raise ClientError(
                "version",
                f"this server speaks protocol version {protocol.VERSION}, not {version!r}",
            )
        heads = self.server.heads
        name = message.get("model") or next(iter(heads))
        if not isinstance(name, str):
            raise ClientError("malformed", f"model must be a name (a string), got {name!r}")
        if name not in heads:
            raise ClientError(
                "model", f"no model {name!r} here; this server has {', '.join(heads)}"
            )
        from vtts.api.say import ENGINES

        engine = message.get("engine") or self.server.options.engine
        if engine not in ENGINES:
            raise ClientError(
                "engine", f"unknown speech engine {engine!r}; known: {', '.join(ENGINES)}"
            )
        for key in ("rate", "pitch"):
            value = message.get(key)
            if value is not None and (isinstance(value, bool) or not isinstance(value, int)):
                raise ClientError("malformed", f"{key} must be a whole number, got {value!r}")
        voice = message.get("voice")
        if voice is not None and not isinstance(voice, str):
            raise ClientError("malformed", f"voice must be a string, got {voice!r}")
        seed = message.get("seed")
        if seed is not None:
            if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
                raise ClientError(
                    "malformed", f"seed must be a whole number 0 to 2**63 - 1, got {seed!r}"
                )
            self.seed = seed
        self.head = heads[name]
        self.engine = engine
        self.voice = voice or self.server.options.voice
        self.rate, self.pitch = message.get("rate"), message.get("pitch")
        await self.send(
            {
                "type": "opened",
                "version": protocol.VERSION,
                "session": self.number,
                "server": self.server.name,
                "model": name,
                "glb": f"/heads/{name}.glb",
                "fps": self.server.options.fps,
                "params": [int(p) for p in self.head.params],
                "rig": self.head.rig,
            }
        )

    def check_bookmarks(self, text: str) -> None:
        """A whole text's bookmarks, checked before any of it is spoken."""
        from vtts.errors import BookmarkError
        from vtts.speech.bookmarks import parse_bookmarks

        if len(text) > MAX_SERVE_TEXT_CHARS:
            return  # add_text refuses it, without parsing it first
        known = {x.name for x in self.head.model.tables.adts if x.kind == "expression"}
        try:
            parse_bookmarks(text, known)
        except BookmarkError as e:
            raise ClientError("bookmark", f"nothing said: {e}") from None

    async def add_text(self, text: str, *, final: bool) -> None:
        waiting = self.queued_chars + len(self.cutter) + len(text)
        if waiting > MAX_SERVE_TEXT_CHARS:
            raise ClientError(
                "too-long",
                f"the text waiting to be spoken would be {waiting:,} "
                f"characters, more than the limit of {MAX_SERVE_TEXT_CHARS:,} (vtts.limits."
                "MAX_SERVE_TEXT_CHARS); the text was not taken",
            )
        clauses = self.cutter.feed(text)
        if final:
            clauses += self.cutter.flush()
        if not clauses and not final:
            return
        if not self.open_utterance and clauses:
            self.utterance += 1
            self.open_utterance = True
        if self.speaker is None or self.speaker.done():
            self.speaker = asyncio.create_task(self._speak(self.queue))
        for clause in clauses:
            self.queued_chars += len(clause)
            self.queue.put_nowait(("clause", self.utterance, clause))
        if final and self.open_utterance:
            self.queue.put_nowait(("end", self.utterance, ""))
            self.open_utterance = False

    # ---- the client's voice ----------------------------------------------------------------

    async def listen(self, message: dict) -> None:
        """Start an utterance of the client's voice: the binary messages that follow are its PCM
        (s16le mono at ``rate``), until a ``flush`` (or ``stop``)."""
        from vtts.serve.listen import Listener

        if self.open_utterance:
            raise ClientError("busy", "an utterance of text is open: flush (or stop) it first")
        rate = message.get("rate")
        lo, hi = protocol.LISTEN_RATES
        if isinstance(rate, bool) or not isinstance(rate, int) or not lo <= rate <= hi:
            raise ClientError(
                "malformed", f"listen needs a rate, a whole number {lo}–{hi} Hz, got {rate!r}"
            )
        autonomous = message.get("autonomous", True)
        if not isinstance(autonomous, bool):
            raise ClientError("malformed", f"autonomous must be true or false, got {autonomous!r}")
        seed = (self.seed + self.clauses_spoken) % 2**63
        self.clauses_spoken += 1
        decoder = await self.server.decoder()
        self.listener = await asyncio.to_thread(
            Listener, self.head.model, self.head.params, rate, self.server.options.fps, seed,
            autonomous, decoder,
        )  # fmt: skip
        self.utterance += 1
        await self.send({"type": "listening", "utterance": self.utterance, "rate": rate,
                         "fps": self.server.options.fps})  # fmt: skip

    async def hear(self, data: bytes) -> None:
        """The next piece of the client's voice: its face and sound sent back as they are known."""
        listener = self.listener
        await self._send_heard(await asyncio.to_thread(listener.feed, data))

    async def end_listening(self) -> None:
        listener, self.listener = self.listener, None
        await self._send_heard(await asyncio.to_thread(listener.finish))
        samples = listener.samples_in
        await self.send({"type": "end", "utterance": self.utterance, "samples": samples,
                         "duration": samples / listener.rate})  # fmt: skip

    async def _send_heard(self, heard) -> None:
        u, fps = self.utterance, self.server.options.fps
        if len(heard.face):
            await self.send(protocol.pack_face(u, 0, heard.first_frame / fps, fps, heard.face))
        for k in range(0, heard.audio.shape[0], AUDIO_CHUNK):
            await self.send(protocol.pack_audio(u, 0, heard.first_sample + k,
                                                heard.audio[k : k + AUDIO_CHUNK]))  # fmt: skip

    async def stop(self) -> None:
        """Forget the text not yet spoken (or the voice), end the utterance and say so."""
        stopped = self.utterance
        self.listener = None
        await self._stop_speaking()
        self.cutter.clear()
        self.open_utterance = False
        await self.send({"type": "stopped", "utterance": stopped})

    async def _stop_speaking(self) -> None:
        if self.speaker is not None:
            self.speaker.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self.speaker
            self.speaker = None
        self.queue = asyncio.Queue()
        self.queued_chars = 0

    # ---- the speaker --------------------------------------------------------------------------

    async def _speak(self, queue: asyncio.Queue) -> None:
        """Speak the queued clauses in order, each utterance on its own audio clock."""
        try:
            await self._speak_queue(queue)
        except (ConnectionResetError, ConnectionError, RuntimeError):
            return  # the client went away: nothing left to tell it
        except Exception as e:  # a bug: this session ends, the server goes on
            log.exception("session %d failed while speaking", self.number)
            await self.error("internal", f"the server failed in this session: {e!r}")
            if self.transport is not None:
                self.transport.close()

    async def _speak_queue(self, queue: asyncio.Queue) -> None:
        # utterance -> (samples so far, clauses so far, sample rate)
        clock: dict[int, tuple[int, int, int]] = {}
        started: dict[int, float] = {}  # utterance -> when its first audio was sent
        # the queue's next items, each clause's synthesis started: the next clause is spoken
        # while the one before it is, so a short first clause is not followed by a gap
        ahead: collections.deque = collections.deque()
        try:
            while True:
                if not ahead:
                    ahead.append(self._start(await queue.get(), clock, started, ahead))
                while len(ahead) < AHEAD_CLAUSES and not queue.empty():
                    ahead.append(self._start(queue.get_nowait(), clock, started, ahead))
                (kind, utterance, text), job = ahead.popleft()
                samples, count, rate = clock.get(utterance, (0, 0, 0))
                if kind == "end":
                    await self.send({"type": "end", "utterance": utterance, "samples": samples,
                                     "duration": samples / rate if rate else 0.0})  # fmt: skip
                    clock.pop(utterance, None)
                    started.pop(utterance, None)
                    continue
                try:
                    spoken = await job
                except VttsError as e:
                    await self.error(_error_code(e), f"clause {text!r}: {e}")
                    continue
                started.setdefault(utterance, time.monotonic())
                await self._send_clause(utterance, count, text, samples, spoken)
                clock[utterance] = (samples + spoken.audio.shape[0], count + 1, spoken.rate)
        finally:
            jobs = [job for _, job in ahead if job is not None]
            for job in jobs:
                job.cancel()
            # their text leaves the count before a stop resets it
            await asyncio.gather(*jobs, return_exceptions=True)

    def _start(self, item: tuple, clock: dict, started: dict, ahead) -> tuple:
        """``(item, the task synthesizing its clause)`` (None for an ``end``). The clause is
        needed when the audio before it has played: that of the utterance sent so far, and the
        clauses started ahead of it, reckoned at :data:`SECONDS_PER_CHAR`; a first clause now."""
        kind, utterance, text = item
        if kind != "clause":
            return item, None
        samples, _, rate = clock.get(utterance, (0, 0, 0))
        began = started.get(utterance)
        deadline = time.monotonic() if began is None else began + samples / rate
        deadline += SECONDS_PER_CHAR * sum(
            len(t) for (k, u, t), _ in ahead if k == "clause" and u == utterance
        )
        seed = (self.seed + self.clauses_spoken) % 2**63
        self.clauses_spoken += 1
        self.server.spoken_clauses_total += 1
        return item, asyncio.create_task(self._synthesize(text, seed, deadline))

    async def _synthesize(self, text: str, seed: int, deadline: float):
        """One clause spoken in the server's pool, once a place is free for its deadline."""
        loop = asyncio.get_running_loop()
        try:
            await self.server.slots.acquire(deadline)
            job = self.server.pool.submit(
                self.server.speak_clause, text, self.head, self.engine, self.voice,
                self.rate, self.pitch, seed,
            )  # fmt: skip
            # the place is free when the synthesis ends, also when a stop stops waiting for it
            job.add_done_callback(lambda _: loop.call_soon_threadsafe(self.server.slots.release))
            return await asyncio.wrap_future(job)
        finally:
            self.queued_chars -= len(text)

    async def _send_clause(
        self, utterance: int, clause: int, text: str, first: int, spoken
    ) -> None:
        start = first / spoken.rate
        head = self.head
        values = spoken.params[:, head.params].astype(np.float32)
        await self.send(
            {
                "type": "clause",
                "utterance": utterance,
                "clause": clause,
                "text": text,
                "start": start,
                "first": first,
                "samples": int(spoken.audio.shape[0]),
                "rate": spoken.rate,
                "frames": int(values.shape[0]),
                "fps": spoken.fps,
                "words": [[start + a, start + b, w] for a, b, w in spoken.words],
                "bookmarks": [[start + t, name] for t, name in spoken.bookmarks],
            }
        )
        # the face first: the page has it before the sound it goes with
        for k in range(0, max(len(values), 1), 65535):
            part = values[k : k + 65535]
            await self.send(protocol.pack_face(utterance, clause, start + k / spoken.fps,
                                               spoken.fps, part))  # fmt: skip
        audio = spoken.audio
        for k in range(0, audio.shape[0], AUDIO_CHUNK):
            await self.send(protocol.pack_audio(utterance, clause, first + k,
                                                audio[k : k + AUDIO_CHUNK]))  # fmt: skip


def _error_code(e: VttsError) -> str:
    from vtts.errors import BookmarkError, SpeechError

    if isinstance(e, BookmarkError):
        return "bookmark"
    if isinstance(e, SpeechError):
        return "speech"
    return "text"


class DeadlineSlots:
    """:data:`SYNTH_WORKERS` places to synthesize in, given to the waiting clause whose audio is
    needed first (earliest deadline first): a new utterance's first clause goes before the later
    clauses of utterances whose earlier audio is still playing. Used on the event loop only."""

    def __init__(self, slots: int) -> None:
        self.free = slots
        self.waiting: list[tuple[float, int, asyncio.Future]] = []
        self._order = itertools.count()

    async def acquire(self, deadline: float) -> None:
        """Wait for a place; the clause's ``deadline`` is a ``time.monotonic()`` time."""
        if self.free > 0 and not self.waiting:
            self.free -= 1
            return
        future = asyncio.get_running_loop().create_future()
        heapq.heappush(self.waiting, (deadline, next(self._order), future))
        try:
            await future
        except asyncio.CancelledError:
            if future.done() and not future.cancelled():
                self.release()  # given a place just as it was cancelled: pass it on
            raise

    def release(self) -> None:
        while self.waiting:
            _, _, future = heapq.heappop(self.waiting)
            if not future.done():
                future.set_result(None)
                return
        self.free += 1


class Server:
    """The server of ``heads`` (name → :class:`ServedHead`, the first the default)."""

    def __init__(self, heads: dict[str, ServedHead], options: ServerOptions | None = None) -> None:
        if not heads:
            raise ServeError("a server needs at least one model")
        self.heads = heads
        self.options = options or ServerOptions()
        self.sessions: set[Session] = set()
        #: :data:`~vtts.limits.SERVE_SEND_TIMEOUT_S` (tests shorten it)
        self.send_timeout = SERVE_SEND_TIMEOUT_S
        #: clauses synthesized since the server started, all sessions together
        self.spoken_clauses_total = 0
        self.pool = ThreadPoolExecutor(max_workers=SYNTH_WORKERS, thread_name_prefix="vtts-speak")
        self.slots = DeadlineSlots(SYNTH_WORKERS)
        self._numbers = itertools.count(1)
        # a recognizer's decoder being made ahead for the next listen (a Future), and its thread
        self._spare = None
        self._decoders = ThreadPoolExecutor(max_workers=1, thread_name_prefix="vtts-decoder")
        #: which server process a session reached (``HOST:PID``, the ``opened`` message's
        #: ``server``): behind a proxy of several servers (Ray Serve's) a session stays on one
        self.name = f"{socket.gethostname()}:{os.getpid()}"

    async def decoder(self):
        """A speech recognizer's decoder for a ``listen`` (:mod:`vtts.serve.listen`): the one
        made ahead, and the next one started, so that a voice's first samples wait for none
        (but the server's first ``listen``, which starts the recognizer: 1.3 s)."""
        from vtts.speech.recognize import RecognizerOptions, make_decoder

        spare = self._spare
        if spare is None:
            spare = self._decoders.submit(make_decoder, RecognizerOptions())
        decoder = await asyncio.wrap_future(spare)
        self._spare = self._decoders.submit(make_decoder, RecognizerOptions())
        return decoder

    def speak_clause(self, text, head, engine, voice, rate, pitch, seed):
        """One clause spoken (in a worker thread): :func:`vtts.api.speak.speak`."""
        from vtts.api.speak import speak

        return speak(text, head.model, engine=engine, voice=voice, rate=rate, pitch=pitch,
                     seed=seed, fps=self.options.fps)  # fmt: skip

    def app(self) -> web.Application:
        """The aiohttp application."""
        app = web.Application(client_max_size=MAX_SERVE_MESSAGE_BYTES)
        app.router.add_get("/", self.page)
        app.router.add_get("/index.html", self.page)
        app.router.add_get("/heads", self.head_list)
        app.router.add_get("/heads/{name}.glb", self.head_glb)
        app.router.add_get("/session", self.session)
        app.router.add_static("/vtts/", PAGE_DIR, follow_symlinks=False)
        app.router.add_static("/player/", PLAYER_DIR, follow_symlinks=False)
        app.on_shutdown.append(self._close_sessions)
        return app

    def page_html(self) -> str:
        """The page, its configuration (protocol version, heads, fps) written in."""
        from string import Template

        from vtts.export.web import script_json

        config = {"version": protocol.VERSION, "heads": list(self.heads), "fps": self.options.fps}
        return Template((PAGE_DIR / "index.html").read_text(encoding="utf-8")).substitute(
            config=script_json(config)
        )

    async def page(self, request: web.Request) -> web.Response:
        return web.Response(text=self.page_html(), content_type="text/html")

    async def head_list(self, request: web.Request) -> web.Response:
        return web.json_response({"heads": list(self.heads)})

    async def head_glb(self, request: web.Request) -> web.Response:
        head = self.heads.get(request.match_info["name"])
        if head is None:
            raise web.HTTPNotFound(text=f"no model {request.match_info['name']!r} here")
        return web.Response(body=head.glb, content_type="model/gltf-binary")

    async def session(self, request: web.Request) -> web.StreamResponse:
        ws = web.WebSocketResponse(max_msg_size=MAX_SERVE_MESSAGE_BYTES, compress=False)
        sock = request.transport.get_extra_info("socket") if request.transport else None
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SERVE_SOCKET_BUFFER_BYTES)
        await ws.prepare(request)
        await self.serve_socket(ws, request.transport)
        return ws

    async def serve_socket(self, ws, transport=None) -> None:
        """One session on the open WebSocket ``ws`` until it closes: aiohttp's
        ``WebSocketResponse``, or another socket with its face (``closed``, ``close_code``,
        ``send_str``, ``send_bytes``, ``close(code=, message=)``, and its messages by ``async
        for``: :class:`vtts.serve.asgi.AsgiSocket`). ``transport`` (aiohttp's) is cut when the
        client does not read."""
        if len(self.sessions) >= MAX_SERVE_SESSIONS:
            with contextlib.suppress(ConnectionError, RuntimeError):
                await ws.send_str(json.dumps({
                    "type": "error", "code": "full",
                    "message": f"the server has {MAX_SERVE_SESSIONS} sessions, its limit "
                               "(vtts.limits.MAX_SERVE_SESSIONS): try again later",
                }))  # fmt: skip
            await ws.close(code=WSCloseCode.TRY_AGAIN_LATER, message=b"server full")
            return
        session = Session(self, ws, next(self._numbers), transport)
        self.sessions.add(session)
        try:
            await session.handle()
        except Exception as e:  # a session's bug must not end the server: tell and log it
            log.exception("session %d failed", session.number)
            await session.error("internal", f"the server failed in this session: {e!r}")
        finally:
            self.sessions.discard(session)
            if not ws.closed:
                code = ws.close_code
                await ws.close(code=WSCloseCode.MESSAGE_TOO_BIG if code == 1009 else WSCloseCode.OK)

    async def _close_sessions(self, app: web.Application) -> None:
        for session in list(self.sessions):
            with contextlib.suppress(Exception):
                await session.ws.close(code=WSCloseCode.GOING_AWAY, message=b"server shutdown")

    def close(self) -> None:
        from vtts.speech.tts import keep_workers_ready

        self.pool.shutdown(wait=False, cancel_futures=True)
        self._decoders.shutdown(wait=False, cancel_futures=True)
        keep_workers_ready(0)

    @contextlib.contextmanager
    def running(self, host: str = "127.0.0.1", port: int = 0) -> Iterator[str]:
        """Serve in a thread of this process while the block runs; yields the base URL
        (``http://HOST:PORT``). For tests, benchmarks and programs that embed a server."""
        loop = asyncio.new_event_loop()
        started: dict = {}
        ready = threading.Event()

        async def start() -> web.AppRunner:
            runner = web.AppRunner(self.app(), handle_signals=False)
            await runner.setup()
            site = web.TCPSite(runner, host, port)
            await site.start()
            started["port"] = site._server.sockets[0].getsockname()[1]  # noqa: SLF001
            return runner

        def main() -> None:
            asyncio.set_event_loop(loop)
            try:
                started["runner"] = loop.run_until_complete(start())
            except BaseException as e:
                started["error"] = e
                ready.set()
                return
            ready.set()
            loop.run_forever()

        thread = threading.Thread(target=main, name="vtts-serve", daemon=True)
        thread.start()
        ready.wait()
        if "error" in started:
            raise ServeError(f"cannot serve on {host}:{port}: {started['error']}")
        try:
            yield f"http://{_url_host(host)}:{started['port']}"
        finally:
            asyncio.run_coroutine_threadsafe(started["runner"].cleanup(), loop).result(30)
            loop.call_soon_threadsafe(loop.stop)
            thread.join(30)
            loop.close()
            self.close()


def _url_host(host: str) -> str:
    return f"[{host}]" if ":" in host else host


def load_heads(models: list[str], fps: float = 30.0) -> dict[str, ServedHead]:
    """The :class:`ServedHead` of each model name or ``.wrl`` file (a repeated name once)."""
    from vtts.face import load_model
    from vtts.serve.heads import served_head

    heads: dict[str, ServedHead] = {}
    for name in models:
        model = load_model(name)
        if model.name not in heads:
            heads[model.name] = served_head(model, fps)
    return heads


def warm_up(server: Server) -> None:
    """One clause spoken before the first session, so that its first sound waits for no
    start-up (imports, the engine's first run), and espeak-ng's workers kept started ahead of
    their clauses (one per synthesis place)."""
    from vtts.speech.tts import keep_workers_ready

    keep_workers_ready(SYNTH_WORKERS)
    head = next(iter(server.heads.values()))
    server.speak_clause("Hello.", head, server.options.engine, server.options.voice, None, None, 0)


def run_server(models: list[str], *, host: str = "127.0.0.1", port: int = 8080,
               options: ServerOptions | None = None, announce=print) -> None:  # fmt: skip
    """Load ``models`` and serve them until interrupted (``vtts serve``)."""
    if not 0 <= port <= 65535 or not math.isfinite(port):
        raise ServeError(f"--port must be within 0 to 65535, got {port}")
    options = options or ServerOptions()
    server = Server(load_heads(models, options.fps), options)
    warm_up(server)

    async def main() -> None:
        runner = web.AppRunner(server.app(), handle_signals=False)
        await runner.setup()
        site = web.TCPSite(runner, host, port)
        try:
            await site.start()
        except OSError as e:
            await runner.cleanup()
            raise ServeError(f"cannot serve on {host}:{port}: {e.strerror or e}") from None
        bound = site._server.sockets[0].getsockname()[1]  # noqa: SLF001
        announce(f"vtts serve: http://{_url_host(host)}:{bound}/ ({', '.join(server.heads)}); "
                 "Ctrl-C ends it")  # fmt: skip
        try:
            await asyncio.Event().wait()
        finally:
            await runner.cleanup()

    try:
        asyncio.run(main())
    finally:
        server.close()
