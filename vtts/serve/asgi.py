"""The server as an ASGI application (Starlette): what Ray Serve's replicas run
(:mod:`vtts.serve.ray_serve`), and any ASGI server can (uvicorn, hypercorn).

The routes are :meth:`vtts.serve.server.Server.app`'s — the page, its scripts, the heads and one
WebSocket per session at ``/session`` — and a session is the same
:class:`~vtts.serve.server.Session`: :class:`AsgiSocket` gives Starlette's WebSocket the face of
aiohttp's that the session speaks to. Starlette comes with ``ray[serve]`` (the extra
``vtts[rayserve]``); plain ``vtts serve`` runs on aiohttp and does not need it.
"""

from __future__ import annotations

import contextlib
from typing import NamedTuple

from aiohttp import WSMsgType

from vtts.errors import ServeError
from vtts.limits import MAX_SERVE_MESSAGE_BYTES

try:
    from starlette.applications import Starlette
    from starlette.requests import Request
    from starlette.responses import HTMLResponse, JSONResponse, PlainTextResponse, Response
    from starlette.routing import Mount, Route, WebSocketRoute
    from starlette.staticfiles import StaticFiles
    from starlette.websockets import WebSocket, WebSocketDisconnect
except ImportError:  # pragma: no cover - the message is the test
    raise ServeError(
        "serving on Ray Serve needs the extra vtts[rayserve] (ray[serve], which brings "
        "starlette): pip install 'vtts[rayserve]'"
    ) from None

from vtts.serve.server import PAGE_DIR, PLAYER_DIR, Server

__all__ = ["AsgiSocket", "asgi_app"]

#: WebSocket close code of a message over :data:`~vtts.limits.MAX_SERVE_MESSAGE_BYTES`
MESSAGE_TOO_BIG = 1009


class Message(NamedTuple):
    """A received message, as aiohttp gives one: ``type`` TEXT, BINARY or ERROR, ``data``."""

    type: WSMsgType
    data: str | bytes | None


class AsgiSocket:
    """An accepted Starlette ``WebSocket`` as :class:`~vtts.serve.server.Session` uses aiohttp's
    ``WebSocketResponse``: ``closed``, ``close_code``, ``send_str``/``send_bytes`` (raising
    ``ConnectionResetError`` once the client is gone), ``close(code=, message=)``, and the
    client's messages by ``async for`` (a text over :data:`~vtts.limits.MAX_SERVE_MESSAGE_BYTES`
    ends them with an ERROR and close code 1009, as aiohttp's ``max_msg_size`` does)."""

    def __init__(self, ws: WebSocket) -> None:
        self._ws = ws
        self.closed = False
        self.close_code: int | None = None

    async def _send(self, message: dict) -> None:
        if self.closed:
            raise ConnectionResetError("the socket is closed")
        try:
            await self._ws.send(message)
        except (WebSocketDisconnect, RuntimeError, OSError) as e:
            self.closed = True
            raise ConnectionResetError(f"the client went away: {e!r}") from None

    async def send_str(self, text: str) -> None:
        await self._send({"type": "websocket.send", "text": text})

    async def send_bytes(self, data: bytes) -> None:
        await self._send({"type": "websocket.send", "bytes": bytes(data)})

    async def close(self, code: int = 1000, message: bytes = b"") -> None:
        if self.closed:
            return
        self.closed = True
        reason = message.decode("utf-8", "replace") if isinstance(message, bytes) else message
        with contextlib.suppress(WebSocketDisconnect, RuntimeError, OSError):
            await self._ws.close(code=code, reason=reason or None)

    def __aiter__(self):
        return self._messages()

    async def _messages(self):
        while not self.closed:
            try:
                m = await self._ws.receive()
            except (WebSocketDisconnect, RuntimeError, OSError):
                self.closed = True
                return
            if m["type"] == "websocket.disconnect":
                self.closed = True
                self.close_code = m.get("code", 1005)
                return
            text, data = m.get("text"), m.get("bytes")
            size = len(data) if data is not None else len(text or "")
            if size > MAX_SERVE_MESSAGE_BYTES or (
                text is not None and len(text.encode("utf-8")) > MAX_SERVE_MESSAGE_BYTES
            ):
                self.close_code = MESSAGE_TOO_BIG
                yield Message(WSMsgType.ERROR, None)
                return
            if text is not None:
                yield Message(WSMsgType.TEXT, text)
            elif data is not None:
                yield Message(WSMsgType.BINARY, data)


def asgi_app(server: Server) -> Starlette:
    """``server``'s routes as a Starlette application (its sessions run on the application's
    event loop; its synthesis pool is the server's)."""

    async def page(request: Request) -> Response:
        return HTMLResponse(server.page_html())

    async def head_list(request: Request) -> Response:
        return JSONResponse({"heads": list(server.heads)})

    async def head_glb(request: Request) -> Response:
        name = request.path_params["name"]
        head = server.heads.get(name)
        if head is None:
            return PlainTextResponse(f"no model {name!r} here", status_code=404)
        return Response(head.glb, media_type="model/gltf-binary")

    async def session(ws: WebSocket) -> None:
        await ws.accept()
        await server.serve_socket(AsgiSocket(ws))

    routes = [
        Route("/", page),
        Route("/index.html", page),
        Route("/heads", head_list),
        Route("/heads/{name}.glb", head_glb),
        WebSocketRoute("/session", session),
        Mount("/vtts", StaticFiles(directory=PAGE_DIR)),
        Mount("/player", StaticFiles(directory=PLAYER_DIR)),
    ]

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette):
        try:
            yield
        finally:
            for s in list(server.sessions):
                await s.ws.close(code=1001, message=b"server shutdown")
            server.close()

    return Starlette(routes=routes, lifespan=lifespan)
