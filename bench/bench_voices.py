"""The second voice and recorded audio (issue 19): festival's synthesis speed against espeak-ng's,
and reading 10 minutes of audio in each kind of file.

- Synthesis: wall time over audio duration for a ~10 s text (the 10 s case of ``bench_say``
  without its bookmarks) with espeak-ng and with festival's HTS voice (``festival -b``, process
  start and voice load included), and for 1,000 words with festival (spoken as utterances of 300+
  characters; as one utterance it took 175 s).
- Reading (``vtts.speech.audio.read_audio``): 10 minutes of festival's speech (its 32 kHz mono
  tiled, written as FLAC with soundfile and as MP3 and M4A with the bundled ffmpeg, stereo), read
  and resampled to 16 kHz as an aligner would: seconds per minute of audio, and the peak of
  Python-side memory (tracemalloc; ffmpeg's own process not counted) against the 77 MB of the
  32 kHz mono samples and the 38 MB of the 16 kHz result. SciPy's signal module is imported
  before the first measurement.
"""

from __future__ import annotations

import subprocess
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

BENCH = "voices"
TEXT_10S = (
    "Good morning and welcome to the face animation system. I speak with bookmarked "
    "expressions, I blink when I like, and my lips close for every b, p and m. Thank you for "
    "listening."
)
LONG = "The quick brown fox jumps over the lazy dog while the cat sleeps near the warm fire. "
MINUTES = 10


def _row(benchmark: str, case: str, value: float, unit: str) -> dict:
    return {
        "benchmark": benchmark,
        "case": case,
        "value": round(value, 3),
        "unit": unit,
        "target": "",
        "ok": None,
    }


def _synthesis_rows() -> tuple[list[dict], np.ndarray, int]:
    from vtts.speech import festival, tts

    rows = []
    t0 = time.perf_counter()
    e = tts.synthesize(tts.escape(TEXT_10S))
    wall = time.perf_counter() - t0
    rows.append(
        _row("speech synthesis: wall / audio", f"espeak-ng, {e.duration:.1f} s", wall / e.duration,
             "x duration")
    )  # fmt: skip
    t0 = time.perf_counter()
    f = festival.synthesize(TEXT_10S)
    wall = time.perf_counter() - t0
    rows.append(
        _row("speech synthesis: wall / audio", f"festival HTS, {f.duration:.1f} s",
             wall / f.duration, "x duration")
    )  # fmt: skip
    text = LONG * 60
    t0 = time.perf_counter()
    long = festival.synthesize(text)
    wall = time.perf_counter() - t0
    rows.append(
        _row("speech synthesis: wall / audio",
             f"festival HTS, {len(text.split())} words ({long.duration:.0f} s)",
             wall / long.duration, "x duration")
    )  # fmt: skip
    return rows, f.audio, f.rate


def _reading_rows(speech: np.ndarray, rate: int) -> list[dict]:
    import soundfile as sf

    from vtts.media import ffmpeg_exe
    from vtts.speech.audio import read_audio

    n = MINUTES * 60 * rate
    mono = np.resize(speech.astype(np.float32) / 32768.0, n)
    stereo = np.stack([mono, 0.5 * mono], axis=1)
    rows = []
    with tempfile.TemporaryDirectory(prefix="vtts-bench-voices-") as d:
        flac = Path(d) / "long.flac"
        sf.write(flac, stereo, rate, format="FLAC", subtype="PCM_16")
        files = {"FLAC (soundfile)": flac}
        for suffix, codec in (("mp3", "libmp3lame"), ("m4a", "aac")):
            out = Path(d) / f"long.{suffix}"
            subprocess.run(
                [ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y", "-i", str(flac),
                 "-c:a", codec, "-b:a", "128k", str(out)],
                check=True,
            )  # fmt: skip
            files[f"{suffix.upper()} ({'soundfile' if suffix == 'mp3' else 'ffmpeg'})"] = out
        import scipy.signal  # noqa: F401  (its import is not reading)

        for name, path in files.items():
            tracemalloc.start()
            t0 = time.perf_counter()
            samples, sr = read_audio(path, rate=16000)
            wall = time.perf_counter() - t0
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            case = f"{MINUTES} min stereo {rate // 1000} kHz {name} → 16 kHz mono"
            rows.append(_row("read_audio: time per minute", case, wall / MINUTES, "s"))
            rows.append(_row("read_audio: peak Python memory", case, peak / 1e6, "MB"))
            del samples
    return rows


def run() -> list[dict]:
    rows, speech, rate = _synthesis_rows()
    return rows + _reading_rows(speech, rate)


if __name__ == "__main__":
    for r in run():
        print(r)
