"""A Python client of ``vtts serve`` (:class:`Client`): for tests, benchmarks and programs that
feed a head text from elsewhere, such as a language model's tokens (``samples/serve_llm.py``).

    async with Client("http://127.0.0.1:8080") as c:
        await c.open(model="cybatt")
        await c.say("Hello there, how are you?")
        said = await c.utterance()          # its audio, face frames, words, bookmarks
"""

from __future__ import annotations

import asyncio
import json
import time
from dataclasses import dataclass, field

import aiohttp
import numpy as np

from vtts.errors import ServeError
from vtts.serve import protocol
from vtts.serve.protocol import AudioChunk, FaceFrames

__all__ = ["Client", "Heard"]


@dataclass
class Heard:
    """An utterance as a client received it.

    number     its number in the session
    audio      ``(n,)`` int16, every clause's samples in order, at ``rate`` Hz
    times      ``(F,)`` float64: each face frame's time on the audio's clock, s
    values     ``(F, K)`` float32: the session's parameters (``opened["params"]``) per frame
    clauses    the ``clause`` messages, in order (none for a voice the client sent)
    errors     the ``error`` messages that came meanwhile
    ended      ``"end"``, or ``"stopped"`` when a ``stop`` cut it short
    first_audio_at  ``time.monotonic()`` when its first audio arrived (None: none did)
    """

    number: int
    rate: int = 0
    audio: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int16))
    times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    values: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.float32))
    clauses: list[dict] = field(default_factory=list)
    errors: list[dict] = field(default_factory=list)
    ended: str = ""
    first_audio_at: float | None = None

    @property
    def words(self) -> list[list]:
        """``[start s, end s, word]`` of every word, on the utterance's clock."""
        return [w for c in self.clauses for w in c["words"]]

    @property
    def bookmarks(self) -> list[list]:
        """``[time s, name]`` of every bookmark, on the utterance's clock."""
        return [b for c in self.clauses for b in c["bookmarks"]]


class Client:
    """One session of the server at ``url`` (``http://HOST:PORT``), as an async context manager.

    :meth:`open` opens the session; :meth:`say`, :meth:`append`, :meth:`flush` and :meth:`stop`
    send the protocol's messages; :meth:`receive` gives the next message (a dict, an
    :class:`~vtts.serve.protocol.AudioChunk` or a :class:`~vtts.serve.protocol.FaceFrames`);
    :meth:`utterance` collects the next utterance whole."""

    def __init__(self, url: str, *, timeout: float = 60.0) -> None:
        self.url = url.rstrip("/")
        self.timeout = timeout
        self.opened: dict | None = None
        self._http: aiohttp.ClientSession | None = None
        self._ws: aiohttp.ClientWebSocketResponse | None = None
        self._pending: list = []

    async def __aenter__(self) -> Client:
        await self.connect()
        return self

    async def __aexit__(self, *exc) -> None:
        await self.close()

    async def connect(self) -> None:
        """Open the WebSocket (``/session``)."""
        self._http = aiohttp.ClientSession()
        ws_url = "ws" + self.url[4:] if self.url.startswith("http") else self.url
        try:
            self._ws = await self._http.ws_connect(f"{ws_url}/session", max_msg_size=64 << 20)
        except (aiohttp.ClientError, OSError) as e:
            await self._http.close()
            raise ServeError(f"cannot reach vtts serve at {self.url}: {e}") from None

    async def close(self) -> None:
        """Close the socket (the server ends the session)."""
        if self._ws is not None:
            await self._ws.close()
        if self._http is not None:
            await self._http.close()

    # ---- sending ------------------------------------------------------------------------------

    async def send(self, message: dict) -> None:
        """Send one control message as it is. Raises :class:`~vtts.errors.ServeError` when the
        session's socket is closed (the server ended it, or went away)."""
        try:
            await self._ws.send_str(json.dumps(message))
        except (aiohttp.ClientError, ConnectionError) as e:
            code = self._ws.close_code
            said = f" (code {code})" if code else ""
            raise ServeError(f"the session is closed{said}: {e}") from None

    async def open(self, model: str | None = None, **fields) -> dict:
        """Open the session with ``model`` (the server's first when None) and ``fields``
        (``voice``, ``engine``, ``rate``, ``pitch``, ``seed``); returns the ``opened`` message.
        Raises :class:`~vtts.errors.ServeError` with the server's message when it refuses."""
        message = {"type": "open", "version": protocol.VERSION, **fields}
        if model is not None:
            message["model"] = model
        await self.send(message)
        reply = await self.receive()
        if not isinstance(reply, dict) or reply.get("type") != "opened":
            said = reply.get("message") if isinstance(reply, dict) else reply
            raise ServeError(f"the server did not open the session: {said}")
        self.opened = reply
        return reply

    async def say(self, text: str) -> None:
        """Speak ``text`` (with bookmarks) and end the utterance there."""
        await self.send({"type": "say", "text": text})

    async def append(self, text: str) -> None:
        """Add ``text`` to the utterance; its complete clauses are spoken as they complete."""
        await self.send({"type": "append", "text": text})

    async def flush(self) -> None:
        """Speak what was appended and not yet spoken, and end the utterance."""
        await self.send({"type": "flush"})

    async def listen(self, rate: int, *, autonomous: bool = True) -> None:
        """Start an utterance of this client's voice at ``rate`` Hz: send its PCM with
        :meth:`send_audio` as it comes, then :meth:`flush` (or :meth:`stop`). The server sends
        back the face as the voice is recognized, and the voice with it (for a player's clock)."""
        await self.send({"type": "listen", "rate": rate, "autonomous": autonomous})

    async def send_audio(self, samples: np.ndarray | bytes) -> None:
        """The next piece of the voice: ``(n,)`` int16 mono samples (or their s16le bytes)."""
        data = samples if isinstance(samples, bytes) else np.asarray(samples, "<i2").tobytes()
        try:
            await self._ws.send_bytes(data)
        except (aiohttp.ClientError, ConnectionError) as e:
            raise ServeError(f"the session is closed: {e}") from None

    async def stop(self) -> None:
        """Stop speaking: the rest of the utterance is dropped."""
        await self.send({"type": "stop"})

    # ---- receiving ----------------------------------------------------------------------------

    async def receive(self, timeout: float | None = None) -> dict | AudioChunk | FaceFrames:
        """The next message from the server. Raises :class:`~vtts.errors.ServeError` when the
        socket closes and ``TimeoutError`` after ``timeout`` s (the client's default)."""
        if self._pending:
            return self._pending.pop(0)
        async with asyncio.timeout(timeout or self.timeout):
            msg = await self._ws.receive()
        if msg.type == aiohttp.WSMsgType.TEXT:
            return json.loads(msg.data)
        if msg.type == aiohttp.WSMsgType.BINARY:
            return protocol.unpack(msg.data)
        code = self._ws.close_code
        reason = msg.extra if isinstance(msg.extra, str) else ""
        raise ServeError(
            f"the server closed the session (code {code}{': ' + reason if reason else ''})"
        )

    async def utterance(self, timeout: float | None = None) -> Heard:
        """Every message of the next utterance until its ``end`` or ``stopped``, gathered."""
        deadline = time.monotonic() + (timeout or self.timeout)
        heard: Heard | None = None
        audio: list[np.ndarray] = []
        faces: list[FaceFrames] = []
        errors: list[dict] = []
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("the utterance did not end in time")
            m = await self.receive(left)
            if isinstance(m, dict):
                kind = m.get("type")
                if kind == "error":
                    errors.append(m)
                    continue
                number = m.get("utterance")
                if heard is None and kind in ("clause", "listening", "end", "stopped"):
                    heard = Heard(number)
                if heard is None or number != heard.number:
                    continue
                if kind == "clause":
                    heard.clauses.append(m)
                    heard.rate = m["rate"]
                elif kind == "listening":
                    heard.rate = m["rate"]
                elif kind in ("end", "stopped"):
                    heard.ended = kind
                    break
            elif heard is not None and m.utterance == heard.number:
                if isinstance(m, AudioChunk):
                    if heard.first_audio_at is None:
                        heard.first_audio_at = time.monotonic()
                    audio.append(m.samples)
                else:
                    faces.append(m)
        heard.errors = errors
        if audio:
            heard.audio = np.concatenate(audio)
        if faces:
            heard.times = np.concatenate([f.times() for f in faces])
            heard.values = np.concatenate([f.values for f in faces])
        return heard

    async def errors(self, count: int = 1, timeout: float | None = None) -> list[dict]:
        """The next ``count`` error messages (other messages are skipped)."""
        found = []
        while len(found) < count:
            m = await self.receive(timeout)
            if isinstance(m, dict) and m.get("type") == "error":
                found.append(m)
        return found
