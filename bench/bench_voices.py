"""The voices (issues 19 and 44): every engine's timing, speed and intelligibility; festival's
synthesis speed against espeak-ng's; reading 10 minutes of audio in each kind of file.

Per engine (espeak-ng; festival and Piper where installed), :func:`engine_rows`:

- **Mouth closure**: for every p, b and m of bilabial-rich texts (``bench_lipsync``'s, tuned and
  held apart), the closure heard in the engine's own audio
  (:func:`vtts.animate.lipsync.lip_closures`: from the fall to the rise of the energy above
  1 kHz; adjacent bilabials are one closure) and whether the timeline (cybatt, 30 Hz, the
  engine's lead and bilabial timing, no autonomous motion) has the lips closed in the frame of
  that closure's centre: the lip gap within 10 % of the utterance's widest. Target ≥ 90 %. Also
  with the frame before allowed (the mouth leads the sound by design, up to a frame).
- **Speed**: ``vtts say`` wall time / audio duration (``bench_say``'s 5 s and 10 s texts, cybatt,
  352×288 MP4, median of 3 runs; a fresh process each, so Piper's voice load, 1–1.7 s, is in
  every run); and the **first audio** of a two-sentence text from the engine's
  :meth:`~vtts.speech.engine.Engine.sentences` in a process that has spoken before (a server):
  the time until the first sentence's audio is there.
- **Intelligibility** (a proxy for listening): pocketsphinx 5.1.1's word error rate, its bundled
  US English model, on the engine's rendering of 20 held-out sentences (Harvard sentences, lists
  1 and 2 of IEEE 1969; never used to choose anything), resampled to 16 kHz. No target.

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


def _row(benchmark: str, case: str, value: float | None, unit: str) -> dict:
    return {
        "benchmark": benchmark,
        "case": case,
        "value": None if value is None else round(float(value), 3),
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


#: Harvard sentences, lists 1 and 2 (IEEE Recommended Practice for Speech Quality Measurements,
#: 1969): the held-out intelligibility set.
HARVARD = (
    "The birch canoe slid on the smooth planks.",
    "Glue the sheet to the dark blue background.",
    "It's easy to tell the depth of a well.",
    "These days a chicken leg is a rare dish.",
    "Rice is often served in round bowls.",
    "The juice of lemons makes fine punch.",
    "The box was thrown beside the parked truck.",
    "The hogs were fed chopped corn and garbage.",
    "Four hours of steady work faced us.",
    "A large size in stockings is hard to sell.",
    "The boy was there when the sun rose.",
    "A rod is used to catch pink salmon.",
    "The source of the huge river is the clear spring.",
    "Kick the ball straight and follow through.",
    "Help the woman get back to her feet.",
    "A pot of tea helps to pass the evening.",
    "Smoky fires lack flame and heat.",
    "The soft cushion broke the man's fall.",
    "The salt breeze came across from the sea.",
    "The girl at the booth sold fifty bonds.",
)
#: Lips closed: a lip gap within this fraction of the utterance's widest.
CLOSED = 0.10
MODEL = "cybatt"


def engines() -> list[str]:
    """The engines that can speak here."""
    from vtts.speech.engine import ENGINES, installed_voices

    found, _ = installed_voices(list(ENGINES))
    return [e for e in ENGINES if any(v.engine == e for v in found)]


def closure_hits(model, utt, engine: str, fps: float = 30.0) -> tuple[list[bool], list[bool]]:
    """For each bilabial phone of ``utt``: are the lips closed in the frame of its closure in
    the audio (:func:`vtts.animate.lipsync.lip_closures`: the frame showing the closure's
    centre); and in that frame or the one before. The timeline is ``engine``'s (its lead and
    bilabial timing)."""
    from vtts.animate.lipsync import lip_closures, lip_gaps
    from vtts.animate.timeline import build_timeline, speech_bilabials, speech_lead

    tl = build_timeline(model, utt.phones, [], utt.duration, fps=fps, autonomous=False,
                        lead=speech_lead(engine), bilabials=speech_bilabials(engine))  # fmt: skip
    gap = lip_gaps(model, tl.params)
    closed = gap <= CLOSED * gap.max()
    own, lead_ok = [], []
    for c in lip_closures(utt.audio, utt.rate, utt.phones):
        k = int(np.clip(np.floor(c.centre * fps), 0, len(gap) - 1))
        for _ in range(c.first, c.last + 1):
            own.append(bool(closed[k]))
            lead_ok.append(bool(closed[k] or (k > 0 and closed[k - 1])))
    return own, lead_ok


def word_error_rate(reference: str, hypothesis: str) -> tuple[int, int]:
    """(word errors: substitutions, deletions, insertions; reference words), case and
    punctuation ignored."""
    import re

    def words(s: str) -> list[str]:
        return re.findall(r"[a-z']+", s.lower())

    ref, hyp = words(reference), words(hypothesis)
    d = list(range(len(hyp) + 1))
    for i, r in enumerate(ref, 1):
        prev, d[0] = d[0], i
        for j, h in enumerate(hyp, 1):
            prev, d[j] = d[j], min(d[j] + 1, d[j - 1] + 1, prev + (r != h))
    return d[len(hyp)], len(ref)


def _recognize(decoder, audio: np.ndarray, rate: int) -> str:
    from scipy.signal import resample_poly

    x = resample_poly(audio.astype(np.float64), 16000, rate) if rate != 16000 else audio
    pcm = np.clip(np.round(x), -32768, 32767).astype(np.int16)
    decoder.start_utt()
    decoder.process_raw(pcm.tobytes(), full_utt=True)
    decoder.end_utt()
    hyp = decoder.hyp()
    return hyp.hypstr if hyp is not None else ""


def engine_rows(which: list[str] | None = None) -> list[dict]:
    import statistics
    import sys

    from bench_lipsync import HELD, TUNED  # noqa: I001  (bench/ is on the path in bench/run.py)

    from vtts.face import load_model
    from vtts.speech.bookmarks import parse_bookmarks
    from vtts.speech.engine import load_engine
    from vtts.utterance import prepare_utterance

    model = load_model(MODEL)
    rows: list[dict] = []
    try:
        from pocketsphinx import Decoder

        decoder = Decoder(loglevel="FATAL")
    except Exception as e:  # not installed: say so, measure the rest
        decoder = None
        rows.append(_row("intelligibility", f"not measured: {e}"[:80], None, ""))
    vtts = Path(sys.executable).with_name("vtts")
    for name in which or engines():
        own: list[bool] = []
        led: list[bool] = []
        for group, texts in (("tuned", TUNED), ("held apart", HELD)):
            hits = [closure_hits(model, prepare_utterance(t, engine=name), name) for t in texts]
            o = [h for a, _ in hits for h in a]
            lead_ok = [h for _, b in hits for h in b]
            own += o
            led += lead_ok
            rows.append(_judged(f"mouth closure of p, b, m in its 30 Hz frame: {name}",
                                f"{group} texts, {len(o)} bilabials", 100 * np.mean(o), "%",
                                ">= 90", 100 * np.mean(o) >= 90))  # fmt: skip
            rows.append(_row(f"mouth closure, its frame or the one before: {name}",
                             f"{group} texts", 100 * np.mean(lead_ok), "%"))  # fmt: skip
        for text, label in ((TEXT_5S, "5 s"), (TEXT_10S_SAY, "10 s")):
            duration = prepare_utterance(text, engine=name).duration
            walls = []
            for _ in range(3):
                with tempfile.TemporaryDirectory() as d:
                    t0 = time.perf_counter()
                    subprocess.run(
                        [str(vtts), "say", text, "--engine", name, "--model", MODEL, "-o",
                         str(Path(d) / "s.mp4"), "--quiet"],
                        check=True, capture_output=True,
                    )  # fmt: skip
                    walls.append(time.perf_counter() - t0)
            rows.append(_row(f"vtts say, wall / audio duration: {name}",
                             f"{label} text ({duration:.1f} s), cybatt 352x288, median of 3 "
                             f"({min(walls) / duration:.2f}–{max(walls) / duration:.2f})",
                             statistics.median(walls) / duration, "x duration"))  # fmt: skip
        engine = load_engine(name)
        bt = parse_bookmarks(FIRST_AUDIO_TEXT)
        next(iter(engine.sentences(bt)))  # warm: the voice loaded, as in a server
        t0 = time.perf_counter()
        first = next(iter(engine.sentences(bt)))
        rows.append(_row(f"first audio of a sentence: {name}",
                         f"warm process, first of 2 sentences ({first.speech.duration:.1f} s)",
                         time.perf_counter() - t0, "s"))  # fmt: skip
        if decoder is not None:
            errors = total = 0
            for sentence in HARVARD:
                u = prepare_utterance(sentence, engine=name)
                e, n = word_error_rate(sentence, _recognize(decoder, u.audio, u.rate))
                errors, total = errors + e, total + n
            rows.append(_row(f"intelligibility (pocketsphinx WER, a proxy): {name}",
                             f"20 Harvard sentences, {total} words", 100 * errors / total,
                             "% words wrong"))  # fmt: skip
    return rows


def _judged(benchmark: str, case: str, value: float, unit: str, target: str, ok: bool) -> dict:
    return {**_row(benchmark, case, value, unit), "target": target, "ok": bool(ok)}


#: bench_say's texts, bookmarks and all.
TEXT_5S = (
    "Good morning <smile 3s> and welcome to the face animation system. <blink> "
    "Thank you for listening to me."
)
TEXT_10S_SAY = (
    "Good morning <smile 3s> and welcome to the face animation system. "
    "I speak with bookmarked expressions, <surprise 1s 0.6> I blink when I like, "
    "and my lips close for every b, p and m. <blink> Thank you for listening."
)
FIRST_AUDIO_TEXT = (
    "Good morning and welcome to the face animation system. "
    "I speak with bookmarked expressions, and I blink when I like."
)


def run() -> list[dict]:
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    rows = engine_rows()
    more, speech, rate = _synthesis_rows()
    return rows + more + _reading_rows(speech, rate)


if __name__ == "__main__":
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    for r in engine_rows(sys.argv[1:] or None) if len(sys.argv) > 1 else run():
        print(r)
