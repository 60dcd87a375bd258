"""``vtts say`` speed: the ratio of wall time to audio duration for a ~5 s and a ~10 s utterance
(and a longer one), end to end, the time to the first rendered frame, and where a short
utterance's time goes.

Model: the bundled ``cybatt`` when it is installed, otherwise the test head. The utterances are
fixed English texts with bookmarks (5.0, 10.6 and 15.8 s with espeak-ng 1.51's default voice).
The model cache (``vtts.face.cache``) is warm for the command: the in-process measurement loads
the model first (``VTTS_CACHE_DIR= make bench`` measures without it).

Targets (issues 6 and 21): at least 2x faster than real time at 352x288 for 10 s (``vtts say`` as
a subprocess: startup, synthesis, timeline, rendering and encoding included; the median of three
runs, with their range); wall time at most 0.4 of the audio's duration for 5 s utterances and
0.35 for 10 s.

The breakdown runs the steps of ``vtts say`` one after the other in a fresh interpreter (this
file as a script), timing each: interpreter start, imports, model load, synthesis, renderer
(pyrender's import, the EGL context, the scene), timeline, the first frame, the other frames,
and the muxing (ffmpeg finishing the H.264 and AAC streams after the last frame). The command
itself overlaps synthesis with the renderer's set-up, so its wall time is less than the sum.
"""

from __future__ import annotations

import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BENCH = "say"
#: Runs of each command; the table gives the median (this shared machine varies by ±15 %).
RUNS = 3
ROOT = Path(__file__).resolve().parents[1]
TEXT = (
    "Good morning <smile 3s> and welcome to the face animation system. "
    "I speak with bookmarked expressions, <surprise 1s 0.6> I blink when I like, "
    "and my lips close for every b, p and m. <blink> Maybe you would like to meet my friend, "
    "who smiles in her own way. <nod> Thank you for listening, and have a pleasant day."
)
#: The issue's case: about 10 s of speech (its first two sentences and the last).
TEXT_10S = (
    "Good morning <smile 3s> and welcome to the face animation system. "
    "I speak with bookmarked expressions, <surprise 1s 0.6> I blink when I like, "
    "and my lips close for every b, p and m. <blink> Thank you for listening."
)

#: A short answer, the common case for an assistant (about 5 s).
TEXT_5S = (
    "Good morning <smile 3s> and welcome to the face animation system. <blink> "
    "Thank you for listening to me."
)
#: The steps of the breakdown, in order: (key, what it covers).
STEPS = (
    ("interpreter", "Python start until the first vtts import"),
    ("import", "imports on the vtts say path (vtts.cli, vtts.api.say and what say imports)"),
    ("model", "model load"),
    ("tts", "synthesis (espeak-ng worker process)"),
    ("pyrender", "pyrender and PyOpenGL import"),
    ("egl", "EGL context"),
    ("scene", "scene: the model's meshes (simplified for the view), materials, camera, lights"),
    ("timeline", "timeline"),
    ("first_frame", "first frame (shaders compiled, buffers uploaded)"),
    ("frames", "the other frames, rendered and piped to ffmpeg"),
    ("mux", "muxing: ffmpeg finishing after the last frame"),
)


def _model() -> str:
    from vtts.face import bundled_models

    return "cybatt" if "cybatt" in bundled_models() else str(ROOT / "tests/data/models/head.wrl")


def run() -> list[dict]:
    from vtts.animate.timeline import build_timeline
    from vtts.face import load_model
    from vtts.render import DETAIL_PX, FaceRenderer
    from vtts.utterance import prepare_utterance

    model_name = _model()
    stem = Path(model_name).stem
    t0 = time.perf_counter()
    model = load_model(model_name)
    utt = prepare_utterance(TEXT)
    tl = build_timeline(model, utt.phones, utt.bookmarks, utt.duration)
    with FaceRenderer(model, detail=DETAIL_PX) as r:
        next(iter(r.frames([tl.params[0]])))
    first = time.perf_counter() - t0
    rows = [
        {
            "benchmark": "vtts say: time to first frame",
            "case": f"in process, {stem}, {utt.duration:.1f} s utterance",
            "value": round(first, 3),
            "unit": "s",
            "target": "",
            "ok": None,
        }
    ]
    rows += _detail_rows(model, stem)
    rows += _breakdown_rows(model_name)
    vtts = Path(sys.executable).with_name("vtts")
    targets = {TEXT_5S: 0.4, TEXT_10S: 0.35}
    for text in (TEXT_5S, TEXT_10S, TEXT):
        duration = prepare_utterance(text).duration
        walls = []
        for _ in range(RUNS):
            with tempfile.TemporaryDirectory() as d:
                t0 = time.perf_counter()
                subprocess.run(
                    [str(vtts), "say", text, "--model", model_name, "-o", str(Path(d) / "s.mp4"),
                     "--quiet"],
                    check=True,
                    capture_output=True,
                )  # fmt: skip
                walls.append(time.perf_counter() - t0)
        wall = statistics.median(walls)
        case = (
            f"{duration:.1f} s, {stem}, 352x288, startup included, median of {RUNS} "
            f"(runs {min(walls) / duration:.2f}–{max(walls) / duration:.2f})"
        )
        target = targets.get(text)
        rows.append(
            {
                "benchmark": "vtts say (end to end): wall / audio duration",
                "case": case,
                "value": round(wall / duration, 3),
                "unit": "x duration",
                "target": "" if target is None else f"<= {target}",
                "ok": None if target is None else wall / duration <= target,
            }
        )
        if text is TEXT_10S:
            rows.append(
                {
                    "benchmark": "vtts say (end to end)",
                    "case": case,
                    "value": round(duration / wall, 2),
                    "unit": "x real time",
                    "target": ">= 2x",
                    "ok": duration / wall >= 2.0,
                }
            )
    return rows


def _detail_rows(model, stem: str) -> list[dict]:
    """The level of detail (``FaceRenderer(detail=...)``): the ~10 s utterance's frames drawn
    with every triangle and with the command's default :data:`~vtts.render.DETAIL_PX`, in one
    process (rendering only, the median of :data:`RUNS` passes each, alternating), the worst
    and the median frame's PSNR between the two, and what making the progressive meshes costs
    (a head's first use with a detail, unless it is bundled)."""
    import numpy as np

    from vtts.animate.timeline import build_timeline
    from vtts.render import DETAIL_PX, FaceRenderer
    from vtts.render.renderer import lod_key, make_progressive
    from vtts.utterance import prepare_utterance

    utt = prepare_utterance(TEXT_10S)
    tl = build_timeline(model, utt.phones, utt.bookmarks, utt.duration)
    with FaceRenderer(model) as r:  # what a head that is not bundled costs at its first use
        t0 = time.perf_counter()
        for inst in r.instances:
            for am in inst.meshes:
                make_progressive(*lod_key(inst, am)[1:])
        cold = time.perf_counter() - t0
    renderers = {None: FaceRenderer(model), DETAIL_PX: FaceRenderer(model, detail=DETAIL_PX)}
    frames, triangles, times = {}, {}, {k: [] for k in renderers}
    try:
        for k, r in renderers.items():
            frames[k] = [f.copy() for f in r.frames(tl.params)]
            triangles[k] = sum(len(am.faces if am.faces is not None else am.template.faces)
                               for inst in r.instances for am in inst.meshes)  # fmt: skip
        for _ in range(RUNS):
            for k, r in renderers.items():
                t0 = time.perf_counter()
                for _frame in r.frames(tl.params):
                    pass
                times[k].append((time.perf_counter() - t0) / tl.n_frames)
    finally:
        for r in renderers.values():
            r.close()
    psnr = []
    for a, b in zip(frames[None], frames[DETAIL_PX], strict=True):
        mse = float(np.mean((a.astype(np.float64) - b) ** 2))
        psnr.append(math.inf if mse == 0 else 10 * math.log10(255**2 / mse))
    case = f"{utt.duration:.1f} s utterance, {stem}, 352x288, rendering only, median of {RUNS}"
    every, fewer = (statistics.median(times[k]) * 1000 for k in renderers)
    drawn = f"{triangles[None]} -> {triangles[DETAIL_PX]} triangles"
    return [
        {
            "benchmark": "vtts say: per frame, every triangle (--detail 0)",
            "case": case,
            "value": round(every, 2),
            "unit": "ms",
            "target": "",
            "ok": None,
        },
        {
            "benchmark": f"vtts say: per frame, the default detail ({DETAIL_PX:g} px)",
            "case": f"{case}; {drawn}",
            "value": round(fewer, 2),
            "unit": "ms",
            "target": "",
            "ok": None,
        },
        {
            "benchmark": "vtts say: the default detail against every triangle, worst frame",
            "case": f"{case}; median frame {statistics.median(psnr):.1f} dB",
            "value": round(min(psnr), 1),
            "unit": "dB PSNR",
            "target": "",
            "ok": None,
        },
        {
            "benchmark": "vtts say: the progressive meshes made (a head's first use)",
            "case": f"{stem}, every animated mesh (bundled heads ship theirs)",
            "value": round(cold, 2),
            "unit": "s",
            "target": "",
            "ok": None,
        },
    ]


def _breakdown_rows(model_name: str) -> list[dict]:
    """The start-up breakdown of the ~5 s utterance: each step's median over :data:`RUNS` fresh
    processes (see :func:`breakdown`)."""
    runs = [breakdown(TEXT_5S, model_name) for _ in range(RUNS)]
    n, duration = runs[0]["n_frames"], runs[0]["duration"]
    case = f"{duration:.1f} s utterance ({n} frames), {Path(model_name).stem}, median of {RUNS}"
    rows = []
    for key, what in STEPS:
        values = [r[key] for r in runs]
        rows.append(
            {
                "benchmark": f"vtts say breakdown: {what}",
                "case": case,
                "value": round(statistics.median(values), 3),
                "unit": "s",
                "target": "",
                "ok": None,
            }
        )
    per_frame = [r["frames"] / max(r["n_frames"] - 1, 1) for r in runs]
    start = [sum(r[k] for k, _ in STEPS if k not in ("frames", "mux")) for r in runs]
    rows += [
        {
            "benchmark": "vtts say breakdown: per frame (after the first)",
            "case": case,
            "value": round(statistics.median(per_frame) * 1000, 2),
            "unit": "ms",
            "target": "",
            "ok": None,
        },
        {
            "benchmark": "vtts say breakdown: start-up (everything up to the first frame)",
            "case": case + ", steps one after the other",
            "value": round(statistics.median(start), 3),
            "unit": "s",
            "target": "",
            "ok": None,
        },
        {
            "benchmark": "vtts say breakdown: the steps' process, end to end",
            "case": case,
            "value": round(statistics.median(r["wall"] for r in runs), 3),
            "unit": "s",
            "target": "",
            "ok": None,
        },
    ]
    return rows


def breakdown(text: str, model_name: str) -> dict:
    """Where ``vtts say`` spends its time: each step of :func:`_say_steps` timed in a fresh
    interpreter (s), plus ``n_frames``, ``duration`` (s of audio) and ``wall`` (the whole
    process, as the parent measured it)."""
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        out = subprocess.run(
            [sys.executable, __file__, text, model_name, str(Path(d) / "s.mp4"), repr(time.time())],
            check=True,
            capture_output=True,
            text=True,
        )
        wall = time.perf_counter() - t0
    import json

    result = json.loads(out.stdout.splitlines()[-1])
    result["wall"] = wall
    return result


def _say_steps(text: str, model_name: str, output: str, started: float) -> dict:
    """The steps of ``vtts.say`` for one model and an MP4, one after the other."""
    t = {"interpreter": time.time() - started}
    mark = time.perf_counter()

    def lap(key: str) -> None:
        nonlocal mark
        now = time.perf_counter()
        t[key] = now - mark
        mark = now

    import vtts.api.say  # noqa: F401
    import vtts.cli  # noqa: F401
    from vtts.animate.timeline import build_timeline
    from vtts.face import load_model
    from vtts.fap import write_fap  # noqa: F401
    from vtts.render import DETAIL_PX, FaceRenderer, VideoWriter, write_wav
    from vtts.render.pyrender_adapter import load_pyrender, offscreen
    from vtts.utterance import prepare_utterance

    lap("import")
    model = load_model(model_name)
    lap("model")
    known = {x.name for x in model.tables.adts if x.kind == "expression"}
    utt = prepare_utterance(text, known=known)
    lap("tts")
    load_pyrender()
    lap("pyrender")
    offscreen()
    lap("egl")
    renderer = FaceRenderer([model], detail=DETAIL_PX)  # as the command draws
    lap("scene")
    tl = build_timeline(model, utt.phones, utt.bookmarks, utt.duration)
    lap("timeline")
    with tempfile.TemporaryDirectory() as d:
        wav = Path(d) / "speech.wav"
        write_wav(wav, utt.audio, utt.rate)
        with renderer, VideoWriter(output, 30.0, renderer.size, audio=wav) as video:
            frames = renderer.frames([tl.params[i]] for i in range(tl.n_frames))
            video.write(next(frames))
            lap("first_frame")
            for frame in frames:
                video.write(frame)
            lap("frames")
        lap("mux")
    t.update(n_frames=tl.n_frames, duration=utt.duration)
    return t


if __name__ == "__main__":
    import json
    import os

    result = _say_steps(sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4]))
    sys.stdout.write(json.dumps(result) + "\n")
    sys.stdout.flush()
    os._exit(0)  # as vtts.cli.run: no interpreter teardown
