"""The web player's frame rate in headless Chromium on this machine (issue 17).

The demo's text (``samples/texts/welcome.txt``, about 13 s) is spoken with the bundled ``cybatt``,
and with ``cybatt`` and ``lotta`` side by side, into a web folder (``write_web``, as
``vtts say --web`` writes it). Debian's Chromium, headless (:class:`vtts.export.browser.Chromium`:
WebGL on Mesa's llvmpipe, the software rasterizer of a machine without a GPU; the case names the
renderer and the machine's load average), loads it from 127.0.0.1 at 352x288 and plays it with
its audio; the player counts the frames it draws (``vttsPlayer.framesDrawn``) over
:data:`SECONDS` of playback, a few seconds in. Also reported: the largest gap between the
animation's time and the audio's ``currentTime`` seen while playing (the player extrapolates the
audio clock by at most 0.1 s between its updates; 0 where Chromium updates it every frame).

Target: the animation's own rate, 30 frames/s (a frame drawn for every frame of the stream). The
browser draws at most 60 frames/s (its display rate, headless too). Chromium, like vtts's
renderer, shares the machine's two cores (with whatever else runs: see the load).
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

BENCH = "web"
ROOT = Path(__file__).resolve().parents[1]
TEXT = ROOT / "samples" / "texts" / "welcome.txt"
SIZE = (352, 288)
FPS = 30.0
#: Seconds of playback measured, after WARMUP seconds of playing.
SECONDS = 4.0
WARMUP = 1.0


def _web_folder(names: list[str], out: Path) -> tuple[Path, float]:
    """The demo spoken by the models ``names`` as a web folder; (folder, audio seconds)."""
    from vtts.animate.timeline import build_timeline
    from vtts.export.web import write_web
    from vtts.face import load_model
    from vtts.render import write_wav
    from vtts.utterance import prepare_utterance

    models = [load_model(n) for n in names]
    known = {x.name for m in models for x in m.tables.adts if x.kind == "expression"}
    utt = prepare_utterance(TEXT.read_text(encoding="utf-8"), known=known)
    params = [
        build_timeline(m, utt.phones, utt.bookmarks, utt.duration, fps=FPS).params for m in models
    ]
    wav = out.with_suffix(".wav")
    write_wav(wav, utt.audio, utt.rate)
    write_web(out, models, params, FPS, audio=wav, size=SIZE)
    return out, utt.duration


def measure(folder: Path) -> tuple[float, float, str]:
    """(frames drawn per second while playing, largest |animation time − audio time| in s, the
    WebGL renderer's name)."""
    from vtts.export.browser import Chromium, serve

    with serve(folder) as base, Chromium(SIZE, autoplay=True) as browser:
        browser.load(f"{base}/index.html?paused=1", timeout=120)
        renderer = browser.webgl_renderer()
        browser.evaluate("vttsPlayer.play()")
        time.sleep(WARMUP)
        sample = (
            "[vttsPlayer.framesDrawn, performance.now() / 1000, vttsPlayer.time(), "
            "document.getElementById('audio').currentTime, vttsPlayer.playing]"
        )
        first = browser.evaluate(sample)
        gap = 0.0
        end = time.monotonic() + SECONDS
        while time.monotonic() < end:
            time.sleep(0.25)
            _, _, t, audio, playing = browser.evaluate(sample)
            if playing:
                gap = max(gap, abs(t - audio))
        last = browser.evaluate(sample)
    if not last[4]:
        raise RuntimeError("the player stopped before the measurement ended")
    return (last[0] - first[0]) / (last[1] - first[1]), gap, renderer


def _short(renderer: str) -> str:
    """``llvmpipe`` or ``SwiftShader`` (or the name as it is) of a WebGL renderer's name."""
    for name in ("llvmpipe", "SwiftShader"):
        if name.lower() in renderer.lower():
            return name
    return renderer


def run() -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory(prefix="vtts-bench-web-") as tmp:
        for names in (["cybatt"], ["cybatt", "lotta"]):
            folder, seconds = _web_folder(names, Path(tmp) / "-".join(names))
            load = os.getloadavg()[0]
            fps, gap, renderer = measure(folder)
            case = (
                f"{' + '.join(names)}, {seconds:.1f} s demo, {SIZE[0]}x{SIZE[1]}, "
                f"{_short(renderer)}, load {load:.1f}"
            )
            rows.append(
                {
                    "benchmark": "web player: frames drawn while playing",
                    "case": case,
                    "value": round(fps, 1),
                    "unit": "frames/s",
                    "target": f">= {FPS:g}",
                    "ok": fps >= FPS,
                }
            )
            rows.append(
                {
                    "benchmark": "web player: animation vs audio clock",
                    "case": case,
                    "value": round(gap * 1000, 1),
                    "unit": "ms (largest gap)",
                    "target": "<= 100",
                    "ok": gap <= 0.1,
                }
            )
    return rows
