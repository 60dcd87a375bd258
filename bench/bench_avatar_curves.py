"""Curves out: the time to write each ``--curves`` format for the demo utterance, and its size.

The utterance is ``make demo``'s (``samples/texts/welcome.txt``, espeak-ng's default voice, 30 fps,
the timeline ``vtts say`` builds for ``cybatt`` with its default seed). Each format is timed in
process with the timeline built (median of five runs of
:func:`vtts.avatar.curves.write_curves`, from the parameter track and the phones to a renamed
JSON file). A second case times ``arkit`` for a stream of low-level FAPs only (the Xface joy file
of ``samples/fap/``, as ``vtts play`` reads it at 30 fps), where the lips' FAPs make bounded
least-squares problems (:mod:`vtts.avatar.boxls`).

Target (issue 18 asks for the figure; the target is ours): each format ≤ 0.5 s for the demo, so
that the curves add little to a ``vtts say`` that takes seconds.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

BENCH = "avatar curves"
ROOT = Path(__file__).resolve().parents[1]
TEXT = ROOT / "samples" / "texts" / "welcome.txt"
STREAM = ROOT / "samples" / "fap" / "xface-joy.fap"
RUNS = 5
FPS = 30.0
TARGET_S = 0.5


def _demo():
    from vtts.animate.timeline import build_timeline
    from vtts.face import load_model
    from vtts.utterance import prepare_utterance

    model = load_model("cybatt")
    utt = prepare_utterance(TEXT.read_text(encoding="utf-8"))
    tl = build_timeline(model, utt.phones, utt.bookmarks, utt.duration, fps=FPS)
    return tl.params, utt.phones, utt.duration


def _stream():
    from vtts.animate.fapstream import stream_params
    from vtts.face.miap import all_miaps
    from vtts.fap import read_fap

    return stream_params(read_fap(STREAM), all_miaps(), fps=FPS).params


def _time(path: Path, fmt: str, params, phones) -> list[float]:
    from vtts.avatar.curves import write_curves

    times = []
    for _ in range(RUNS):
        t0 = time.perf_counter()
        write_curves(path, fmt, params, FPS, phones)
        times.append(time.perf_counter() - t0)
    return times


def _row(case: str, fmt: str, times: list[float], size: int, judged: bool) -> list[dict]:
    median = statistics.median(times)
    spread = f"median of {RUNS} ({min(times):.3f}–{max(times):.3f})"
    return [
        {
            "benchmark": f"curves out: {fmt} time",
            "case": f"{case}, {spread}",
            "value": round(median, 4),
            "unit": "s",
            "target": f"<= {TARGET_S:g}" if judged else "",
            "ok": median <= TARGET_S if judged else None,
        },
        {
            "benchmark": f"curves out: {fmt} size",
            "case": case,
            "value": round(size / 1e3, 1),
            "unit": "kB",
            "target": "",
            "ok": None,
        },
    ]


def run() -> list[dict]:
    from vtts.avatar.curves import FORMATS

    rows = []
    params, phones, duration = _demo()
    case = f"{duration:.1f} s demo, cybatt, {params.shape[0]} frames"
    with tempfile.TemporaryDirectory() as d:
        for fmt in FORMATS:
            path = Path(d) / f"demo-{fmt}.json"
            times = _time(path, fmt, params, phones)
            rows += _row(case, fmt, times, path.stat().st_size, judged=True)
        stream = _stream()
        path = Path(d) / "joy-arkit.json"
        times = _time(path, "arkit", stream, None)
        case = f"{STREAM.name}, low-level FAPs only, {stream.shape[0]} frames"
        rows += _row(case, "arkit", times, path.stat().st_size, judged=False)
    return rows


if __name__ == "__main__":
    for r in run():
        print(r)
