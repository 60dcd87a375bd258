"""Lip sync: does the mouth lead the sound (issue 45, item 7)?

For bilabial-rich texts, each engine (espeak-ng; festival's HTS voice and Piper where installed)
and each way vtts shows speech, the cross-correlation of how open the mouth is with the speech's RMS
per 30 Hz frame (over each frame's display interval), and the lag of its peak in frames
(:mod:`vtts.animate.lipsync`): positive when the mouth comes after the sound, negative when it
leads. Target: 0 or −1 (the lips and jaw move before the sound they shape).

- **timeline**: the lip gap of the timeline's frames (the model deformed, no rendering), at
  30 Hz and at 200 Hz (the latter in ms: the lag without the frame's quantization);
- **say MP4**: ``vtts say --no-autonomous -o x.mp4`` decoded back by ffmpeg, pictures and sound
  (ffmpeg applies the MP4's edit list, which trims the AAC encoder's priming, as players do):
  the darkness of the mouth region (an open mouth shows its dark inside), the region being the
  pixels of the lower face that change most over the clip; also the offset of the MP4's sound
  against the WAV it was made from;
- **play .fap**: the same for ``vtts play x.fap --audio x.wav -o y.mp4`` of the say's stream;
- **web player**: the say's ``--web`` folder in headless Chromium, each frame's time sought
  (``vttsPlayer.seek``) and the mouth region's darkness read from a screenshot, against the
  speech's RMS (espeak-ng, the first text only: a screenshot per frame is slow).

The texts ``TUNED`` are those the engines' leads (:attr:`vtts.speech.engine.Engine.lead`) were
chosen on;
``HELD`` were written afterwards and never used for choosing (reported separately).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

BENCH = "lipsync"
ROOT = Path(__file__).resolve().parents[1]
FPS = 30.0
MODEL = "cybatt"
TUNED = (
    "Bob bought a big blue map, and Pam put my maple pie by the bamboo bench. "
    "Baby bumblebees buzz by the pebbles.",
    "My mom bought a big map, maybe a bamboo boat, by the pub.",
    "Peter picked a peck of pickled peppers; a peck of pickled peppers Peter picked.",
)
HELD = (
    "Maybe the plumber brought a purple umbrella to the boat club.",
    "Bill and Mabel swam by the pier, then ate plums and buns at the pub.",
)


def _row(benchmark: str, case: str, value, unit: str, ok=None, target: str = "0 or -1") -> dict:
    return {"benchmark": benchmark, "case": case, "value": value, "unit": unit,
            "target": target, "ok": ok}  # fmt: skip


def _lag_row(what: str, case: str, lag: int) -> dict:
    return _row(f"lip sync: {what}", case, lag, "frames (+ late)", lag in (0, -1))


def _vtts(*args: str) -> None:
    exe = Path(sys.executable).with_name("vtts")
    r = subprocess.run([str(exe), *args, "--quiet"], capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        raise RuntimeError(f"vtts {args[0]} failed: {r.stderr.strip()[-400:]}")


def _decode(mp4: Path, rate: int) -> tuple[np.ndarray, np.ndarray]:
    """(gray frames (n, H, W) uint8, mono float sound at ``rate``) of ``mp4``, as ffmpeg
    decodes them."""
    from vtts.media import ffmpeg_exe
    from vtts.render import probe_media

    info = probe_media(mp4)
    w, h = info.width, info.height
    video = subprocess.run(
        [ffmpeg_exe(), "-v", "error", "-i", str(mp4), "-f", "rawvideo", "-pix_fmt", "gray", "-"],
        capture_output=True, check=True,
    ).stdout  # fmt: skip
    frames = np.frombuffer(video, np.uint8).reshape(-1, h, w)
    sound = subprocess.run(
        [ffmpeg_exe(), "-v", "error", "-i", str(mp4), "-vn", "-ac", "1", "-ar", str(rate),
         "-f", "f32le", "-"],
        capture_output=True, check=True,
    ).stdout  # fmt: skip
    return frames, np.frombuffer(sound, np.float32).astype(np.float64)


def mouth_darkness(frames: np.ndarray) -> np.ndarray:
    """Mean darkness per frame of the mouth region: the pixels of the lower half that change
    most over the clip (the head is still: no autonomous motion)."""
    g = frames.astype(np.float64)
    spread = g.std(axis=0)
    spread[: spread.shape[0] // 2] = 0.0
    region = spread > 0.3 * spread.max()
    return (255.0 - g[:, region]).mean(axis=1)


def _offset_ms(a: np.ndarray, b: np.ndarray, rate: int) -> float:
    """How far ``a`` is behind ``b`` (ms), by the cross-correlation of their first seconds."""
    n = min(a.size, b.size, 3 * rate)
    fa = np.fft.rfft(a[:n], 2 * n)
    fb = np.fft.rfft(b[:n], 2 * n)
    c = np.fft.irfft(fa * np.conj(fb))
    k = int(np.argmax(c))
    k = k - 2 * n if k > n else k
    return 1000.0 * k / rate


def _video_lag(mp4: Path, rate: int) -> tuple[int, np.ndarray]:
    from vtts.animate.lipsync import peak_lag, rms_per_frame

    frames, sound = _decode(mp4, rate)
    dark = mouth_darkness(frames)
    return peak_lag(dark, rms_per_frame(sound, rate, FPS, len(dark))), sound


def _web_lag(folder: Path, audio: np.ndarray, rate: int, n: int) -> int:
    import io

    from PIL import Image

    from vtts.animate.lipsync import peak_lag, rms_per_frame
    from vtts.export.browser import Chromium, serve

    shots = []
    with serve(folder) as base, Chromium((352, 288)) as browser:
        browser.load(f"{base}/index.html?paused=1", timeout=120)
        wait = "new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))"
        for i in range(n):
            browser.evaluate(f"vttsPlayer.seek({i / FPS!r}); {wait}")
            png = browser.screenshot()
            shots.append(np.asarray(Image.open(io.BytesIO(png)).convert("L")))
    dark = mouth_darkness(np.stack(shots))
    return peak_lag(dark, rms_per_frame(audio, rate, FPS, n))


def _timeline_rows(engine: str, case: str, text: str) -> list[dict]:
    from vtts.animate.lipsync import lip_gaps, peak_lag, rms_per_frame
    from vtts.animate.timeline import build_timeline, speech_bilabials, speech_lead
    from vtts.face import load_model
    from vtts.utterance import prepare_utterance

    model = load_model(MODEL)
    utt = prepare_utterance(text, engine=engine)
    rows = []
    for fps in (FPS, 200.0):
        tl = build_timeline(model, utt.phones, [], utt.duration, fps=fps, autonomous=False,
                            lead=speech_lead(engine),
                            bilabials=speech_bilabials(engine))  # fmt: skip
        gap = lip_gaps(model, tl.params)
        rms = rms_per_frame(utt.audio, utt.rate, fps, tl.n_frames)
        lag = peak_lag(gap, rms, max_lag=int(round(0.2 * fps)))
        if fps == FPS:
            rows.append(_lag_row("timeline", case, lag))
        else:
            ms = round(1000.0 * lag / fps)
            rows.append(_row("lip sync: timeline, 200 Hz", case, ms, "ms (+ late)", ms <= 0,
                             "< 0"))  # fmt: skip
    return rows


def run() -> list[dict]:
    import soundfile

    from vtts.speech.engine import installed_voices

    engines = ["espeak"] + (["festival"] if shutil.which("festival") else [])
    engines += ["piper"] if installed_voices(["piper"])[0] else []
    rows: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="vtts-bench-lipsync-") as tmp:
        out = Path(tmp)
        for engine in engines:
            texts = [("tuned", k, t) for k, t in enumerate(TUNED)]
            texts += [("held apart", k, t) for k, t in enumerate(HELD)]
            for group, k, text in texts:
                case = f"{engine}, {group} text {k + 1}: {text[:28]}…"
                rows += _timeline_rows(engine, case, text)
                stem = out / f"{engine}-{group[0]}{k}"
                mp4, wav, fap = (stem.with_suffix(s) for s in (".mp4", ".wav", ".fap"))
                web = (engine, group, k) == ("espeak", "tuned", 0)
                _vtts("say", text, "--model", MODEL, "--engine", engine, "--no-autonomous",
                      "-o", str(mp4), "--wav-out", str(wav), "--fap-out", str(fap),
                      *(["--web", str(stem)] if web else []))  # fmt: skip
                speech, rate = soundfile.read(wav)
                lag, sound = _video_lag(mp4, rate)
                rows.append(_lag_row("say MP4", case, lag))
                ms = _offset_ms(sound, speech, rate)
                rows.append(_row("lip sync: MP4 sound vs its WAV", case, round(ms, 1),
                                 "ms (+ late)", abs(ms) <= 1.0, "0"))  # fmt: skip
                played = stem.with_name(stem.name + "-play.mp4")
                _vtts("play", str(fap), "--model", MODEL, "--audio", str(wav), "-o", str(played))
                rows.append(_lag_row("play .fap MP4", case, _video_lag(played, rate)[0]))
                if web:
                    try:
                        n = int(np.ceil(len(speech) / rate * FPS))
                        rows.append(_lag_row("web player", case, _web_lag(stem, speech, rate, n)))
                    except Exception as e:  # no Chromium here: say so, measure the rest
                        rows.append(_row("lip sync: web player", case, None, "", None,
                                         f"not measured: {e}"[:80]))  # fmt: skip
    return rows
