"""vtts serve, live (issue 42): a real server (in this process, on 127.0.0.1) and its page in
Debian's headless Chromium (WebGL on llvmpipe), the machine's two cores shared by both.

- **first sound**: from ``vtts.say(text)`` in the page to the first sample of the utterance played
  (the ``audiostart`` event's time, from the AudioContext's output timestamp), one sentence,
  :data:`FIRST_SOUND_RUNS` times: p50 and p95 (targets 250 and 400 ms);
- **stop → silence**: ``vtts.stop()`` 0.3 s into each of those utterances until the page's audio
  output (an AnalyserNode of its last 256 samples) is all zeros: p95 (target 100 ms);
- **sync**: a minute of streamed speech (the demo's text, five times); for every frame the page
  draws, the streamed face frame's time against the audio clock's: the largest lead (target: none,
  ≤ 0) and lag (target ≤ one frame, 33 ms), and the audio underruns;
- **rate**: bytes per second on the socket of face messages and of audio messages;
- **screenshot**: the page held at a frame of that speech (a parameter vector the server
  streamed) against ``vtts render`` of the same vector: silhouette IoU (target ≥ 0.99);
- **sustained sessions**: N sessions at once, each speaking the demo's text twice (27 s), as
  Python clients that schedule the audio as the page does (first sample 20 ms after it arrives,
  each chunk at its place on the utterance's clock): for each N, the audio underruns (a chunk that
  came after its time) and the p95 of the N first sounds. N pages in Chromium would measure the
  software rasterizer drawing N heads, not the server. The largest N without underruns is
  reported (target ≥ 8);
- **first audio per engine** (issue 44): a server warmed up with each installed engine, a Python
  client saying one sentence :data:`ENGINE_RUNS` times: p50 and p95 to its first audio chunk;
- **voice to face** (issue 43, :func:`listen_rows`): a session's voice sent in real time, its face
  frames back: p50 and p95 latency, alone and next to speaking sessions (target p95 ≤ 150 ms);
- **Ray Serve** (:func:`ray_rows`): ``vtts serve --replicas 2`` on a local Ray, 8 sessions at once
  through Ray's proxy, then one replica killed while they speak.
"""

from __future__ import annotations

import asyncio
import collections
import json
import os
import time
from pathlib import Path

import numpy as np

BENCH = "serve"
ROOT = Path(__file__).resolve().parents[1]
DEMO = (ROOT / "samples" / "texts" / "welcome.txt").read_text(encoding="utf-8").strip()
SENTENCES = [
    "Hello there, how are you today?",
    "The weather is lovely this morning.",
    "Could you pass me the salt, please?",
    "I will be back in five minutes.",
    "This is a short test of the live head.",
]
FIRST_SOUND_RUNS = 20
SESSIONS = (1, 2, 4, 6, 8, 10, 12, 16, 20, 24)
SIZE = (352, 288)
LEAD = 0.02  # s, as the page's client.js


def _row(benchmark, case, value, unit, target="", ok=None) -> dict:
    return {"benchmark": f"serve: {benchmark}", "case": case, "value": value, "unit": unit,
            "target": target, "ok": ok}  # fmt: skip


FIRST_AND_STOP = """(text) => new Promise((resolve) => {
  const s = vtts.session; s.handlers.clear();
  const t0 = performance.now(); const out = {};
  vtts.on('error', (e) => resolve({ error: e.message }));
  vtts.on('audiostart', (e) => {
    out.first = e.at - t0;
    const u = s.utterances.get(e.utterance);
    out.face = u !== undefined && u.faces.length > 0 && u.faces[0].start === 0;
    setTimeout(() => {
      out.level = vtts.level(); const t = performance.now(); vtts.stop();
      const poll = () => {
        if (vtts.level() === 0) { out.silence = performance.now() - t; resolve(out); }
        else setTimeout(poll, 1);
      };
      poll();
    }, Math.max(0, e.at - performance.now()) + 300);
  });
  vtts.say(text);
})"""

LONG = """(text) => new Promise((resolve) => {
  const s = vtts.session; s.handlers.clear();
  const before = vtts.sync(); const underruns = vtts.underruns;
  vtts.on('error', (e) => resolve({ error: e.message }));
  vtts.on('end', () => resolve({ sync: vtts.sync(), before,
    underruns: vtts.underruns - underruns }));
  vtts.say(text);
})"""


def page_figures(server, url) -> list[dict]:
    from vtts.export.browser import Chromium

    rows = []
    with Chromium(SIZE, autoplay=True, transparent=True) as browser:
        browser.load(f"{url}/?bar=0&background=transparent", timeout=120)
        renderer = "llvmpipe" if "llvmpipe" in browser.webgl_renderer() else "other WebGL"
        load = os.getloadavg()[0]
        firsts, silences, faces = [], [], 0
        for k in range(FIRST_SOUND_RUNS):
            out = browser.evaluate(
                f"({FIRST_AND_STOP})({json.dumps(SENTENCES[k % 5])})", timeout=60
            )
            if "error" in out:
                raise RuntimeError(out["error"])
            firsts.append(out["first"])
            faces += bool(out["face"])
            silences.append(out["silence"])
            time.sleep(0.2)
        case = (
            f"one sentence, page in Chromium ({renderer}), {FIRST_SOUND_RUNS} runs, load {load:.1f}"
        )
        p50, p95 = np.percentile(firsts, [50, 95])
        rows.append(_row("first sound p50", case, round(p50), "ms", "<= 250", p50 <= 250))
        rows.append(_row("first sound p95", case, round(p95), "ms", "<= 400", p95 <= 400))
        rows.append(_row("face's first frame there at the first sound", case, faces, "utterances",
                         f"{FIRST_SOUND_RUNS}", faces == FIRST_SOUND_RUNS))  # fmt: skip
        s95 = float(np.percentile(silences, 95))
        rows.append(_row("stop → silence p95", case, round(s95, 1), "ms", "<= 100", s95 <= 100))

        long_text = " ".join([DEMO] * 5)
        load = os.getloadavg()[0]
        out = browser.evaluate(f"({LONG})({json.dumps(long_text)})", timeout=300)
        if "error" in out:
            raise RuntimeError(out["error"])
        sync = out["sync"]
        drawn = sync["frames"] - out["before"]["frames"]
        case = f"demo text ×5 (about 65 s) streamed, {drawn} frames drawn, load {load:.1f}"
        ahead = max(sync["maxAhead"], 0.0) * 1000
        behind = sync["maxBehind"] * 1000
        rows.append(
            _row("face ahead of audio, largest", case, round(ahead, 2), "ms", "<= 0", ahead <= 1e-3)
        )
        rows.append(
            _row(
                "face behind audio, largest",
                case,
                round(behind, 1),
                "ms",
                "<= 33.3",
                behind <= 1000 / 30 + 1e-3,
            )
        )
        rows.append(
            _row(
                "audio underruns in the page",
                case,
                out["underruns"],
                "underruns",
                "0",
                out["underruns"] == 0,
            )
        )
        rows += screenshot_rows(server, browser)
    return rows


def screenshot_rows(server, browser) -> list[dict]:
    import io

    from PIL import Image

    from vtts.api.speak import speak
    from vtts.render import FaceRenderer

    model = server.heads["cybatt"].model
    spoken = speak("Bob opened a warm box.", model, seed=3)
    rows = []
    values = []
    for k in (10, 20, 30):
        params = np.zeros_like(spoken.params[k])
        sent = server.heads["cybatt"].params
        params[sent] = spoken.params[k][sent].astype(np.float32)  # what the socket carries
        browser.evaluate(
            f"new Promise((r) => {{ vtts.hold({json.dumps(params.tolist())}); "
            "requestAnimationFrame(() => requestAnimationFrame(r)); })"
        )
        shot = np.asarray(Image.open(io.BytesIO(browser.screenshot())).convert("RGBA"))
        with FaceRenderer([model], size=SIZE, background="transparent") as renderer:
            ours = renderer.render([params])
        a, b = ours[..., 3] >= 128, shot[..., 3] >= 128
        values.append(float(np.logical_and(a, b).sum() / np.logical_or(a, b).sum()))
    browser.evaluate("vtts.hold(null)")
    worst = min(values)
    case = "cybatt, frames 10, 20, 30 of a streamed clause (worst)"
    rows.append(_row("screenshot vs vtts render, silhouette IoU", case, round(worst, 4), "IoU",
                     ">= 0.99", worst >= 0.99))  # fmt: skip
    return rows


async def _session(url: str, text: str) -> dict:
    """One session speaking ``text`` as the page would play it: (first sound s, underruns,
    face bytes, audio bytes, audio seconds)."""
    import aiohttp

    from vtts.serve import protocol

    async with aiohttp.ClientSession() as http:
        ws = await http.ws_connect(url.replace("http", "ws") + "/session", max_msg_size=64 << 20)
        await ws.send_str(json.dumps({"type": "open"}))
        await ws.receive()
        t0 = time.monotonic()
        await ws.send_str(json.dumps({"type": "say", "text": text}))
        start = None
        underruns = 0
        face = audio = 0
        rate = 22050
        while True:
            msg = await ws.receive()
            now = time.monotonic()
            if msg.type == aiohttp.WSMsgType.TEXT:
                m = json.loads(msg.data)
                if m["type"] == "clause":
                    rate = m["rate"]
                if m["type"] in ("end", "error"):
                    samples = m.get("samples", 0)
                    break
                continue
            if msg.type != aiohttp.WSMsgType.BINARY:
                raise RuntimeError(f"the session closed: {msg}")
            media = protocol.unpack(msg.data)
            if isinstance(media, protocol.FaceFrames):
                face += len(msg.data)
                continue
            audio += len(msg.data)
            if start is None:
                start = now + LEAD
                first = start - t0
            due = start + media.first / rate
            if now > due - 0.005:
                underruns += 1
                start += now + 0.005 - due
        await ws.close()
    return {"first": first, "underruns": underruns, "face": face, "audio": audio,
            "seconds": samples / rate}  # fmt: skip


def _cpu() -> float:
    """CPU seconds of this process and its finished children (espeak-ng's workers)."""
    import resource

    me, children = (
        resource.getrusage(resource.RUSAGE_SELF),
        resource.getrusage(resource.RUSAGE_CHILDREN),
    )
    return me.ru_utime + me.ru_stime + children.ru_utime + children.ru_stime


def sustained_rows(url: str) -> list[dict]:
    text = " ".join([DEMO] * 2)

    async def many(n: int):
        return await asyncio.gather(*[_session(url, text) for _ in range(n)])

    rows = []
    best = 0
    curve = []
    for n in SESSIONS:
        load = os.getloadavg()[0]
        cpu0 = _cpu()
        results = asyncio.run(many(n))
        cpu = _cpu() - cpu0
        under = sum(r["underruns"] for r in results)
        p95 = float(np.percentile([r["first"] for r in results], 95)) * 1000
        curve.append(f"{n}: {round(p95)} ms{'' if under == 0 else f' ({under} underruns)'}")
        case = f"Python clients, demo ×2 each, underruns {under}, load {load:.1f}"
        rows.append(_row(f"{n} sessions at once: first sound p95", case, round(p95), "ms"))
        if under:
            break  # sustained: every N up to it without an underrun
        best = n
        if n == 1:
            r = results[0]
            per = cpu / r["seconds"]
            case = ("server, its espeak-ng workers and the client, one session; "
                    f"2 cores / this = {2 / per:.0f} sessions if nothing else ran")  # fmt: skip
            rows.append(_row("CPU per second of speech", case, round(per, 3), "CPU s / s"))
            audio_rate = r["audio"] / r["seconds"] / 1000
            case = f"cybatt, 86 parameters as float32 at 30 Hz; audio {audio_rate:.1f} kB/s"
            rows.append(
                _row("face bytes/s on the socket", case, round(r["face"] / r["seconds"]), "B/s")
            )
            rows.append(
                _row(
                    "face bytes / audio bytes",
                    "the same session",
                    round(r["face"] / r["audio"], 3),
                    "ratio",
                    "",
                    None,
                )
            )
    case = "largest N such that N and every N before it had no underrun; first sound p95 by N: "
    case += ", ".join(curve)
    rows.append(_row("sessions sustained in real time", case, best, "sessions", ">= 8", best >= 8))
    return rows


#: Sentences each engine's server speaks for its first audio (:func:`engine_rows`).
ENGINE_RUNS = 12


async def _first_audio(url: str, runs: int) -> list[float]:
    """Seconds from each ``say`` of one sentence to its first audio chunk at a Python client."""
    from vtts.serve import Client
    from vtts.serve.protocol import AudioChunk

    firsts = []
    async with Client(url) as c:
        await c.open(model="cybatt", seed=7)
        for i in range(runs):
            start, first = time.perf_counter(), None
            await c.say(SENTENCES[i % len(SENTENCES)])
            while True:
                m = await c.receive()
                if first is None and isinstance(m, AudioChunk):
                    first = time.perf_counter() - start
                if isinstance(m, dict) and m.get("type") in ("end", "error"):
                    break
            firsts.append(first if first is not None else float("nan"))
    return firsts


def engine_rows() -> list[dict]:
    """First audio of a sentence in ``vtts serve`` per installed engine (issue 44): a server
    warmed up with that engine, a Python client (no page: the engine's share alone)."""
    from vtts.serve.server import Server, ServerOptions, load_heads, warm_up
    from vtts.speech.engine import installed_voices

    voices, _ = installed_voices()
    engines = list(dict.fromkeys(v.engine for v in voices))
    rows = []
    for engine in engines:
        server = Server(load_heads(["cybatt"]), ServerOptions(engine=engine))
        warm_up(server)
        with server.running() as url:
            firsts = np.array(asyncio.run(_first_audio(url, ENGINE_RUNS))) * 1000
        load = os.getloadavg()[0]
        case = f"{engine}, one sentence, {ENGINE_RUNS} runs, Python client, load {load:.1f}"
        for q in (50, 95):
            value = round(float(np.percentile(firsts, q)))
            rows.append(_row(f"first audio p{q}, {engine}", case, value, "ms"))
    return rows


#: Voices a listening session hears (:func:`listen_rows`), each sent in real time.
LISTEN_TEXTS = [
    "Maybe baby, bob my mom's pop music by the beach.",
    "The birch canoe slid on the smooth planks.",
    "Please pass me the blue box before the bus comes.",
]
#: Say sessions speaking meanwhile, in the loaded case.
LISTEN_LOAD = 4


async def _listened(url: str, audio: np.ndarray, rate: int) -> list[float]:
    """One ``listen`` of ``audio`` sent in 20 ms pieces at its own pace: for each face frame, the
    seconds from the piece holding the sample its mouth shows (frame time + the lead) being sent
    to the frame arriving."""
    from vtts.animate.timeline import LEAD as MOUTH_LEAD
    from vtts.serve import Client
    from vtts.serve.protocol import FaceFrames

    async with Client(url, timeout=60) as c:
        await c.open()
        await c.listen(rate)
        piece = int(rate * 0.02)
        sent: list[tuple[int, float]] = []
        t0 = time.monotonic()

        async def sender() -> None:
            for k in range(0, len(audio), piece):
                await asyncio.sleep(max(0.0, t0 + k / rate - time.monotonic()))
                sent.append((k + piece, time.monotonic()))
                await c.send_audio(audio[k : k + piece])
            await c.flush()

        task = asyncio.create_task(sender())
        latencies = []
        while True:
            m = await c.receive()
            now = time.monotonic()
            if isinstance(m, dict) and m.get("type") == "end":
                break
            if isinstance(m, FaceFrames):
                for t in m.times():
                    s = int((t + MOUTH_LEAD) * rate)
                    when = next((w for end, w in sent if end >= s), None)
                    if when is not None:
                        latencies.append(now - when)
        await task
    return latencies


def listen_rows(server, url: str) -> list[dict]:
    """Issue 43's live latency in ``vtts serve``: a session's voice (espeak-ng's, sent in real
    time in 20 ms pieces) to its face frames at the client, p50/p95 over every frame of
    :data:`LISTEN_TEXTS`, alone and with :data:`LISTEN_LOAD` say sessions speaking meanwhile.
    The server's first ``listen`` (which starts the recognizer) is a warm-up, not counted."""
    from vtts.api.speak import speak

    model = next(iter(server.heads.values())).model
    voices = [speak(t, model, seed=0) for t in LISTEN_TEXTS]
    asyncio.run(_listened(url, voices[0].audio[:4410], voices[0].rate))  # warm-up

    async def loaded() -> list[float]:
        talk = [asyncio.create_task(_session(url, DEMO)) for _ in range(LISTEN_LOAD)]
        await asyncio.sleep(0.5)
        out = []
        for v in voices:
            out += await _listened(url, v.audio, v.rate)
        await asyncio.gather(*talk)
        return out

    async def alone() -> list[float]:
        out = []
        for v in voices:
            out += await _listened(url, v.audio, v.rate)
        return out

    rows = []
    for case, run_case in (("alone", alone), (f"{LISTEN_LOAD} say sessions speaking", loaded)):
        lat = np.array(asyncio.run(run_case())) * 1000
        for q, target in ((50, None), (95, 150)):
            value = round(float(np.percentile(lat, q)))
            rows.append(_row(f"voice to face p{q} (listen)", f"{case}; {len(lat)} frames", value,
                             "ms", f"<= {target}" if target else "",
                             None if target is None else value <= target))  # fmt: skip
    return rows


#: Ray Serve (:func:`ray_rows`): replicas, and sessions speaking at once through its proxy.
RAY_REPLICAS = 2
RAY_SESSIONS = 8


async def _spoken_through(url: str, text: str, kill=None) -> list[dict]:
    """:data:`RAY_SESSIONS` sessions at once, each saying ``text``; ``kill(servers)`` is called
    once every session has its first audio. Per session: its replica, first sound (s), how it
    ended (``end`` or the client's error) and its audio underruns (scheduled as the page does)."""
    from vtts.errors import ServeError
    from vtts.serve import Client
    from vtts.serve.protocol import AudioChunk

    heard_first = asyncio.Event()
    firsts: list[float] = []

    async def one() -> dict:
        async with Client(url, timeout=120) as c:
            opened = await c.open()
            t0 = time.monotonic()
            await c.say(text)
            start, underruns, first = None, 0, None
            try:
                while True:
                    m = await c.receive()
                    now = time.monotonic()
                    if isinstance(m, dict) and m.get("type") == "end":
                        return {"server": opened["server"], "first": first, "ended": "end",
                                "underruns": underruns}  # fmt: skip
                    if isinstance(m, AudioChunk):
                        if start is None:
                            start = now + LEAD
                            first = start - t0
                            firsts.append(first)
                            if len(firsts) == RAY_SESSIONS:
                                heard_first.set()
                        due = start + m.first / 22050
                        if now > due - 0.005:
                            underruns += 1
                            start += now + 0.005 - due
            except ServeError as e:
                return {"server": opened["server"], "first": first, "ended": str(e),
                        "underruns": underruns}  # fmt: skip

    tasks = [asyncio.create_task(one()) for _ in range(RAY_SESSIONS)]
    if kill is not None:
        await asyncio.wait_for(heard_first.wait(), 120)
        kill()
    return await asyncio.gather(*tasks)


def ray_rows() -> list[dict]:
    """``vtts serve --replicas 2`` (:func:`vtts.serve.ray_serve.run_on_ray`, a local Ray of this
    machine): start-up, :data:`RAY_SESSIONS` sessions at once through Ray's proxy (spread,
    first sound, underruns), then the same with one replica killed (SIGKILL) once all of them
    speak: its sessions end with the client's error, the others' speech ends whole, and a new
    session is served."""
    import signal
    import socket
    import threading

    from vtts.serve import Client
    from vtts.serve.ray_serve import run_on_ray

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    url = f"http://127.0.0.1:{port}"
    done, up = threading.Event(), threading.Event()
    t0 = time.monotonic()
    thread = threading.Thread(
        target=run_on_ray, args=(["cybatt"],),
        kwargs=dict(replicas=RAY_REPLICAS, port=port, announce=lambda _: up.set(), wait=done.wait),
    )  # fmt: skip
    thread.start()
    rows = []
    try:
        if not up.wait(300):
            raise RuntimeError("Ray Serve did not start within 300 s")
        case = f"local Ray, {RAY_REPLICAS} replicas of cybatt, each warmed up"
        rows.append(_row("Ray Serve start-up", case, round(time.monotonic() - t0, 1), "s"))
        results = asyncio.run(_spoken_through(url, DEMO))
        spread = sorted(collections.Counter(r["server"] for r in results).values())
        under = sum(r["underruns"] for r in results)
        firsts = [r["first"] for r in results]
        case = (f"{RAY_SESSIONS} sessions at once through the proxy, the demo each; sessions per "
                f"replica {spread}; underruns {under}")  # fmt: skip
        for q in (50, 95):
            value = round(float(np.percentile(firsts, q)) * 1000)
            rows.append(_row(f"Ray Serve first sound p{q}", case, value, "ms"))
        ok = all(r["ended"] == "end" for r in results) and under == 0
        rows.append(_row("Ray Serve sessions real-time", case, sum(r["ended"] == "end" and
                         r["underruns"] == 0 for r in results), "sessions",
                         f"== {RAY_SESSIONS}", ok))  # fmt: skip

        victim: list[str] = []

        def kill() -> None:
            servers = sorted({r for r in (x["server"] for x in results)})
            victim.append(servers[0])
            os.kill(int(servers[0].rsplit(":", 1)[1]), signal.SIGKILL)

        killed = asyncio.run(_spoken_through(url, DEMO, kill))
        own = [r for r in killed if r["server"] == victim[0]]
        others = [r for r in killed if r["server"] != victim[0]]
        own_errors = sum(r["ended"] != "end" for r in own)
        others_whole = sum(r["ended"] == "end" for r in others)
        case = (f"one of {RAY_REPLICAS} replicas killed (SIGKILL) while {RAY_SESSIONS} sessions "
                f"spoke: its {len(own)} sessions ended with the client's error "
                f"({own[0]['ended'] if own else '-'}); the others' underruns "
                f"{sum(r['underruns'] for r in others)}")  # fmt: skip
        rows.append(_row("Ray Serve: the killed replica's sessions ended with an error", case,
                         own_errors, "sessions", f"== {len(own)}",
                         own_errors == len(own)))  # fmt: skip
        rows.append(_row("Ray Serve: the other replica's sessions spoke to the end", case,
                         others_whole, "sessions", f"== {len(others)}",
                         others_whole == len(others) > 0))  # fmt: skip

        async def new_session() -> str:
            async with Client(url, timeout=120) as c:
                opened = await c.open()
                await c.say("Hi.")
                return (await c.utterance()).ended + (" " + opened["server"])

        t1 = time.monotonic()
        served = asyncio.run(new_session())
        case = f"a new session after the kill: {served}"
        rows.append(_row("Ray Serve: a new session after the kill, served in", case,
                         round(time.monotonic() - t1, 2), "s"))  # fmt: skip
    finally:
        done.set()
        thread.join(120)
    return rows


def run() -> list[dict]:
    from vtts.serve.server import Server, load_heads, warm_up

    server = Server(load_heads(["cybatt"]))
    warm_up(server)
    with server.running() as url:
        rows = page_figures(server, url)
        rows += sustained_rows(url)
        rows += listen_rows(server, url)
    return rows + engine_rows() + ray_rows()


if __name__ == "__main__":
    for row in run():
        print(row)
