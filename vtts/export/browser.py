"""Headless Chromium driven over its DevTools pipe: load a page, wait until it says it is ready,
take a screenshot, evaluate JavaScript.

The web player's tests and benchmark look at the player in a real browser with this. It talks the
Chrome DevTools Protocol over ``--remote-debugging-pipe`` (JSON messages ending in a NUL byte on
file descriptors 3 and 4), so it needs no WebSocket client, no Selenium or Playwright and no
browser download: only Debian's ``chromium``, which ``scripts/setup.sh`` installs. WebGL runs
through ANGLE on EGL, which is Mesa's llvmpipe (software) on machines without a GPU, or on
Chromium's SwiftShader where EGL is missing (:meth:`Chromium.webgl_renderer` says which).

    with Chromium(size=(352, 288)) as browser:
        browser.load("http://127.0.0.1:8000/index.html?t=1.5&paused=1")   # waits for "ready"
        png = browser.screenshot()                                         # PNG bytes
"""

from __future__ import annotations

import base64
import contextlib
import functools
import http.server
import json
import os
import select
import shutil
import subprocess
import tempfile
import threading
import time
from collections.abc import Iterator
from typing import Any

from vtts.errors import VttsError

__all__ = ["BrowserError", "Chromium", "find_chromium", "serve"]

#: Names of the Chromium binary, in the order they are looked for on PATH.
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "chrome")


class BrowserError(VttsError):
    """Chromium is missing, failed to start, or a page failed (the message says which)."""


def find_chromium() -> str | None:
    """The Chromium binary: ``$VTTS_CHROMIUM`` if set, else the first of :data:`CHROMIUM_NAMES`
    on PATH; None when there is none."""
    given = os.environ.get("VTTS_CHROMIUM")
    if given:
        return given
    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    return None


class Chromium:
    """One headless Chromium with one page of ``size`` (W, H) CSS pixels at device scale 1.

    ``transparent`` makes the page's default background transparent, so a page that paints no
    background gives screenshots whose alpha is what it drew. ``autoplay`` lets media play
    without a user gesture (the benchmark's playback). ``fake_microphone`` grants a page's
    ``getUserMedia`` without asking and gives it Chromium's test signal (a beep) as the
    microphone. Use it as a context manager: the browser
    and its profile folder are removed on exit."""

    def __init__(
        self,
        size: tuple[int, int] = (352, 288),
        *,
        transparent: bool = False,
        autoplay: bool = False,
        fake_microphone: bool = False,
        binary: str | None = None,
    ) -> None:
        binary = binary or find_chromium()
        if binary is None:
            raise BrowserError(
                "no Chromium found (looked for $VTTS_CHROMIUM, "
                + ", ".join(CHROMIUM_NAMES)
                + "): scripts/setup.sh installs Debian's chromium"
            )
        self.size = (int(size[0]), int(size[1]))
        self._profile = tempfile.mkdtemp(prefix="vtts-chromium-")
        # its log goes to a file: a pipe nobody reads would stall it once full
        self._log = tempfile.TemporaryFile()
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()
        args = [
            binary,
            "--headless=new",
            "--remote-debugging-pipe",
            f"--user-data-dir={self._profile}",
            # root (containers, CI) cannot use Chromium's sandbox
            "--no-sandbox",
            # WebGL through ANGLE on EGL: on these machines without a GPU that is Mesa's llvmpipe,
            # the software rasterizer vtts's own renderer uses (two to three times faster than
            # Chromium's SwiftShader, which stays allowed as the fallback); the blocklist would
            # refuse llvmpipe as a software renderer
            "--use-angle=gl-egl",
            "--ignore-gpu-blocklist",
            "--enable-unsafe-swiftshader",
            "--no-first-run",
            "--no-default-browser-check",
            "--disable-extensions",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
            "--mute-audio",
            f"--window-size={self.size[0]},{self.size[1]}",
        ]
        if autoplay:
            args.append("--autoplay-policy=no-user-gesture-required")
        if fake_microphone:
            # getUserMedia granted without asking, its microphone Chromium's own test signal
            args += ["--use-fake-ui-for-media-stream", "--use-fake-device-for-media-stream"]
        args.append("about:blank")

        def child_fds() -> None:
            # fds 3 and 4 are the DevTools pipe's ends in the browser; dup2 leaves them open
            # across exec, while Python's own descriptors are all close-on-exec (PEP 446)
            os.dup2(to_browser_r, 3)
            os.dup2(from_browser_w, 4)

        try:
            self._proc = subprocess.Popen(
                args,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=self._log,
                preexec_fn=child_fds,
                close_fds=False,
            )
        except OSError as e:
            shutil.rmtree(self._profile, ignore_errors=True)
            self._log.close()
            raise BrowserError(f"cannot start {binary}: {e.strerror or e}") from None
        finally:
            os.close(to_browser_r)
            os.close(from_browser_w)
        self._buffer = b""
        self._next_id = 0
        self._session: str | None = None
        #: console messages and uncaught exceptions of the page, in order
        self.console: list[str] = []
        try:
            self._open_page(transparent)
        except BaseException:
            self.close()
            raise

    # ---- the protocol --------------------------------------------------------------------------

    def _send(self, method: str, params: dict | None = None, session: bool = True) -> int:
        self._next_id += 1
        message: dict[str, Any] = {"id": self._next_id, "method": method, "params": params or {}}
        if session and self._session is not None:
            message["sessionId"] = self._session
        data = json.dumps(message).encode() + b"\0"
        try:
            while data:
                data = data[os.write(self._to_browser, data) :]
        except BrokenPipeError:
            raise BrowserError(f"Chromium went away{self._stderr_tail()}") from None
        return self._next_id

    def _receive(self, deadline: float) -> dict:
        while b"\0" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError
            ready, _, _ = select.select([self._from_browser], [], [], left)
            if not ready:
                raise TimeoutError
            chunk = os.read(self._from_browser, 1 << 20)
            if not chunk:
                raise BrowserError(f"Chromium went away{self._stderr_tail()}")
            self._buffer += chunk
        raw, _, self._buffer = self._buffer.partition(b"\0")
        message = json.loads(raw)
        self._note_event(message)
        return message

    def _note_event(self, message: dict) -> None:
        method = message.get("method")
        params = message.get("params", {})
        if method == "Runtime.consoleAPICalled":
            words = [str(a.get("value", a.get("description", ""))) for a in params.get("args", [])]
            self.console.append(f"console.{params.get('type')}: {' '.join(words)}")
        elif method == "Runtime.exceptionThrown":
            details = params.get("exceptionDetails", {})
            text = details.get("exception", {}).get("description") or details.get("text")
            self.console.append(f"uncaught: {text}")

    def call(
        self, method: str, params: dict | None = None, *, timeout: float = 30.0, session=True
    ) -> dict:
        """Send one DevTools command and return its result (events that come meanwhile are
        kept in :attr:`console` where they are console output or uncaught exceptions)."""
        wanted = self._send(method, params, session)
        deadline = time.monotonic() + timeout
        while True:
            try:
                message = self._receive(deadline)
            except TimeoutError:
                raise BrowserError(f"Chromium did not answer {method} in {timeout:g} s") from None
            if message.get("id") == wanted:
                if "error" in message:
                    raise BrowserError(f"{method} failed: {message['error'].get('message')}")
                return message.get("result", {})

    def _open_page(self, transparent: bool) -> None:
        targets = self.call("Target.getTargets", session=False, timeout=60)["targetInfos"]
        page = next((t for t in targets if t["type"] == "page"), None)
        if page is None:
            page_id = self.call("Target.createTarget", {"url": "about:blank"}, session=False)
            target_id = page_id["targetId"]
        else:
            target_id = page["targetId"]
        attached = self.call(
            "Target.attachToTarget", {"targetId": target_id, "flatten": True}, session=False
        )
        self._session = attached["sessionId"]
        self.call("Page.enable")
        self.call("Runtime.enable")
        w, h = self.size
        self.call(
            "Emulation.setDeviceMetricsOverride",
            {"width": w, "height": h, "deviceScaleFactor": 1, "mobile": False},
        )
        if transparent:
            self.call(
                "Emulation.setDefaultBackgroundColorOverride",
                {"color": {"r": 0, "g": 0, "b": 0, "a": 0}},
            )

    # ---- pages ---------------------------------------------------------------------------------

    def evaluate(self, expression: str, *, timeout: float = 30.0) -> Any:
        """The value of a JavaScript expression in the page (promises are awaited)."""
        result = self.call(
            "Runtime.evaluate",
            {"expression": expression, "returnByValue": True, "awaitPromise": True},
            timeout=timeout,
        )
        if "exceptionDetails" in result:
            details = result["exceptionDetails"]
            text = details.get("exception", {}).get("description") or details.get("text")
            raise BrowserError(f"JavaScript failed: {text}")
        return result.get("result", {}).get("value")

    def webgl_renderer(self) -> str:
        """The WebGL renderer's name in the current page (e.g. ``ANGLE (Mesa/X.org, llvmpipe
        …)``), or ``"none"`` without WebGL."""
        return self.evaluate(
            "(() => { const gl = document.createElement('canvas').getContext('webgl2');"
            " if (!gl) return 'none';"
            " const info = gl.getExtension('WEBGL_debug_renderer_info');"
            " return gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER); })()"
        )

    def load(self, url: str, *, ready: str = "ready", timeout: float = 60.0) -> None:
        """Open ``url`` and wait until the page's ``document.title`` is ``ready``. A title that
        starts with ``error`` (the player's way of failing), or the timeout, raises
        :class:`BrowserError` with the page's console output."""
        self.console.clear()
        self.call("Page.navigate", {"url": url})
        deadline = time.monotonic() + timeout
        title = None
        while time.monotonic() < deadline:
            title = self.evaluate("document.title")
            if title == ready:
                return
            if isinstance(title, str) and title.startswith("error"):
                break
            time.sleep(0.05)
        said = "\n".join(self.console[-20:])
        raise BrowserError(
            f"{url} did not become {ready!r} in {timeout:g} s (title {title!r})"
            + (f"; the page said:\n{said}" if said else "")
        )

    def screenshot(self) -> bytes:
        """The page as PNG bytes, ``size`` pixels (RGBA where the page is transparent)."""
        w, h = self.size
        result = self.call(
            "Page.captureScreenshot",
            {
                "format": "png",
                "clip": {"x": 0, "y": 0, "width": w, "height": h, "scale": 1},
                "captureBeyondViewport": False,
            },
        )
        return base64.b64decode(result["data"])

    # ---- the browser ---------------------------------------------------------------------------

    def _stderr_tail(self) -> str:
        self._log.seek(0)
        lines = self._log.read()[-8192:].decode("utf-8", "replace").strip().splitlines()
        return (": " + "\n".join(lines[-8:])) if lines else ""

    def close(self) -> None:
        """End the browser and remove its profile."""
        if self._proc.poll() is None:
            try:
                self._send("Browser.close", session=False)
                self._proc.wait(timeout=10)
            except (BrowserError, subprocess.TimeoutExpired, OSError):
                self._proc.kill()
                self._proc.wait()
        self._log.close()
        for fd in (self._to_browser, self._from_browser):
            try:
                os.close(fd)
            except OSError:
                pass
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self) -> Chromium:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:
        pass


@contextlib.contextmanager
def serve(folder: str | os.PathLike[str]) -> Iterator[str]:
    """Serve ``folder`` over HTTP on 127.0.0.1 (a free port) while the block runs, as any static
    server would serve a web player's folder; yields the base URL (``http://127.0.0.1:PORT``)."""
    handler = functools.partial(_QuietHandler, directory=str(folder))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_port}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join()
