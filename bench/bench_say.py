"""``vtts say`` speed: the real-time factor for a 10 s utterance (and a longer one), end to end,
and the time to the first rendered frame.

Model: the bundled ``cybatt`` when it is installed, otherwise the test head. The utterance is a
fixed English paragraph with bookmarks (15.8 s with espeak-ng 1.51's default voice). The model
cache (``vtts.face.cache``) is warm for the command: the in-process measurement loads the model
first (``VTTS_CACHE_DIR= make bench`` measures without it).

Targets (issue 6): at least 2x faster than real time at 352x288 (``vtts say`` as a subprocess:
startup, synthesis, timeline, rendering and encoding included; the median of three runs, with
their range); time to the first frame reported.
"""

from __future__ import annotations

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


def _model() -> str:
    from vtts.face import bundled_models

    return "cybatt" if "cybatt" in bundled_models() else str(ROOT / "tests/data/models/head.wrl")


def run() -> list[dict]:
    from vtts.animate.timeline import build_timeline
    from vtts.face import load_model
    from vtts.render import FaceRenderer
    from vtts.speech.say import prepare_utterance

    model_name = _model()
    t0 = time.perf_counter()
    model = load_model(model_name)
    utt = prepare_utterance(TEXT)
    tl = build_timeline(model, utt.phones, utt.bookmarks, utt.duration)
    with FaceRenderer(model) as r:
        next(iter(r.frames([tl.params[0]])))
    first = time.perf_counter() - t0
    rows = [
        {
            "benchmark": "vtts say: time to first frame",
            "case": f"in process, {Path(model_name).stem}, {utt.duration:.1f} s utterance",
            "value": round(first, 3),
            "unit": "s",
            "target": "",
            "ok": None,
        }
    ]
    vtts = Path(sys.executable).with_name("vtts")
    for text in (TEXT_10S, TEXT):
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
        rtf = duration / statistics.median(walls)
        spread = f"{duration / max(walls):.2f}–{duration / min(walls):.2f}"
        judged = text is TEXT_10S
        rows.append(
            {
                "benchmark": "vtts say (end to end)",
                "case": f"{duration:.1f} s, {Path(model_name).stem}, 352x288, startup included, "
                f"median of {RUNS} (runs {spread})",
                "value": round(rtf, 2),
                "unit": "x real time",
                "target": ">= 2x" if judged else "",
                "ok": rtf >= 2.0 if judged else None,
            }
        )
    return rows
