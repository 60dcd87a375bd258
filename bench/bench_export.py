"""glTF export: the time to write the animated ``.glb`` of the 13 s demo utterance and its size.

The utterance is ``make demo``'s (``samples/texts/welcome.txt``, espeak-ng's default voice, 30 fps,
the timeline ``vtts say`` builds with its default seed), spoken by the bundled ``cybatt``; then by
``cybatt`` and ``lotta`` side by side (each with its own timeline). The export is timed in process
with the models loaded and the timelines built (median of five runs: :func:`vtts.export.write_gltf`
from parameter tracks to a renamed file), and end to end as the command
``vtts say --file welcome.txt --model cybatt -o demo.glb`` (startup, synthesis and timeline
included; median of three).

Targets (issue 17): export ≤ 1 s and ``.glb`` ≤ 5 MB (10⁶ bytes) for one head.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BENCH = "export"
ROOT = Path(__file__).resolve().parents[1]
TEXT = ROOT / "samples" / "texts" / "welcome.txt"
RUNS = 5
CLI_RUNS = 3
TARGET_S = 1.0
TARGET_MB = 5.0


def _timelines(names: list[str]):
    from vtts.animate.timeline import build_timeline
    from vtts.face import load_model
    from vtts.utterance import prepare_utterance

    models = [load_model(n) for n in names]
    utt = prepare_utterance(TEXT.read_text(encoding="utf-8"))
    params = [
        build_timeline(m, utt.phones, utt.bookmarks, utt.duration, fps=30.0).params for m in models
    ]
    return models, params, utt.duration


def _export(models, params, path: Path) -> list[float]:
    from vtts.export import write_gltf

    times = []
    for _ in range(RUNS):
        t0 = time.perf_counter()
        write_gltf(path, models, params, 30.0)
        times.append(time.perf_counter() - t0)
    return times


def run() -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for names in (["cybatt"], ["cybatt", "lotta"]):
            models, params, duration = _timelines(names)
            heads = " + ".join(names)
            case = f"{duration:.1f} s demo, {heads}, {params[0].shape[0]} frames"
            one = len(names) == 1
            for suffix in (".glb", ".gltf"):
                path = Path(d) / f"demo{suffix}"
                times = _export(models, params, path)
                size = path.stat().st_size / 1e6
                median = statistics.median(times)
                if suffix == ".glb":
                    rows.append(
                        {
                            "benchmark": "glTF export: time",
                            "case": f"{case}, median of {RUNS} ({min(times):.2f}–{max(times):.2f})",
                            "value": round(median, 3),
                            "unit": "s",
                            "target": f"<= {TARGET_S:g}" if one else "",
                            "ok": median <= TARGET_S if one else None,
                        }
                    )
                rows.append(
                    {
                        "benchmark": f"glTF export: {suffix} size",
                        "case": case,
                        "value": round(size, 3),
                        "unit": "MB",
                        "target": f"<= {TARGET_MB:g}" if one and suffix == ".glb" else "",
                        "ok": size <= TARGET_MB if one and suffix == ".glb" else None,
                    }
                )
        rows.append(_command_row(Path(d)))
    return rows


def _command_row(folder: Path) -> dict:
    vtts = Path(sys.executable).with_name("vtts")
    walls = []
    for _ in range(CLI_RUNS):
        t0 = time.perf_counter()
        subprocess.run(
            [str(vtts), "say", "--file", str(TEXT), "--model", "cybatt", "-o",
             str(folder / "cli.glb"), "--quiet"],
            check=True,
            capture_output=True,
        )  # fmt: skip
        walls.append(time.perf_counter() - t0)
    return {
        "benchmark": "glTF export: vtts say -o demo.glb",
        "case": f"cybatt, startup, synthesis and timeline included, median of {CLI_RUNS} "
        f"({min(walls):.2f}–{max(walls):.2f})",
        "value": round(statistics.median(walls), 3),
        "unit": "s",
        "target": "",
        "ok": None,
    }


if __name__ == "__main__":  # pragma: no cover
    for row in run():
        print(row)
