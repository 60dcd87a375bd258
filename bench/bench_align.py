"""Forced alignment of recorded speech (issue 19): phone-boundary error against the truth of other
engines' own timings, how often a bilabial closure lands in its 30 Hz frame, speed and memory.

Truth: festival's HTS voice (``cmu_us_slt_arctic_hts``, its utterance's segment times, at two
rates, and with white noise at 20 dB SNR) and espeak-ng voices, rates and pitches other than the
aligner's reference (``en-us`` at 175 words per minute, or its ``+f2`` variant for a high
voice): ``en-us+f3`` slow and high,
``en-us+m3`` fast and low, ``en-us+klatt`` (another synthesis method), ``en-gb`` (another accent:
some words are other phones). Each speaks 20 sentences of varied text (279 words): the aligner's
constants were tuned on :data:`TUNED`, :data:`HELD_OUT` was kept out, and both are reported.
A boundary is compared where the aligned phone and the truth's phone were matched (broad classes,
:mod:`vtts.align.score`); errors are in ms, median, 90th percentile and worst, over all texts.
The baseline rows are aeneas's plain method (``align(..., baseline=True)``).

Speed: alignment wall time per minute of audio for 1 and 10 minutes of espeak-ng speech
(``en-us+m3``), synthesis of the reference included; peak memory: the growth of the process's
peak RSS while aligning 10 minutes, in a fresh interpreter (this file run as a script).

Reduced mode for a quick check: ``VTTS_BENCH_QUICK=1`` (3 sentences, two voices, 1 minute).
Targets (issue 19): median <= 20 ms, p90 <= 50 ms; <= 2 s per minute of audio on 2 cores.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

BENCH = "align"
ROOT = Path(__file__).resolve().parents[1]

TUNED = [
    "The quick brown fox jumps over the lazy dog.",
    "Please call Stella and ask her to bring these things with her from the store.",
    "Six spoons of fresh snow peas, five thick slabs of blue cheese, and maybe a snack for her "
    "brother Bob.",
    "We also need a small plastic snake and a big toy frog for the kids.",
    "She can scoop these things into three red bags, and we will go meet her Wednesday at the "
    "train station.",
    "My mother bought a map of Boston before the trip.",
    "When the sunlight strikes raindrops in the air, they act as a prism and form a rainbow.",
    "Peter Piper picked a peck of pickled peppers.",
    "Good morning! How are you doing today? I hope the weather is fine where you are.",
    "The museum opens at nine in the morning, but the bakery across the street is already busy.",
]
HELD_OUT = [
    "A large number of people gathered in the market square to hear the mayor speak about the "
    "new budget.",
    "Bring me the blue box from the bottom shelf, please.",
    "Although it was raining, the marathon runners kept a steady pace through the hills.",
    "Imagine a world where every child can read and write by the age of seven.",
    "The committee will publish its findings in a report next month.",
    "Maybe the parrot simply mimics the sounds it hears from the television.",
    "Jupiter is the largest planet in our solar system, with dozens of moons.",
    "He opened the window, breathed the cool air, and smiled at the empty beach.",
    "Remember to back up your files before you update the computer.",
    "Fresh bread, warm soup and a bowl of berries made a perfect lunch.",
]
#: Sentences written for issue 45 (item 4), after the constants above were tuned: NEW_TUNING may be
#: tuned on; NEVER_TUNED is kept out of every tuning run and reported apart (names, numbers spelled
#: out, questions, clusters, long and short words).
NEW_TUNING = [
    "Did Margaret really drive twelve hundred miles to Albuquerque last spring, or was it a rumor?",
    "Thirty-three thirsty thinkers thought through the theory on Thursday.",
    "Strong gusts scattered crisp brown leaves across the empty schoolyard.",
    "Oh, I see, you wanted the yellow one, not the orange one!",
    "Professor Nakamura explained the extraordinary complexity of mitochondrial genetics to a "
    "sleepy audience.",
    "Why would anybody leave a perfectly good umbrella in the back of a taxi?",
    "Seventeen sheep grazed quietly beside the old stone bridge at dawn.",
    "Judge Harrison asked the jury whether the witness had seemed truthful and calm.",
    "It's eight forty-five, and the plane to Vancouver hasn't even started boarding yet.",
    "Hush, said Lisa, as the owl glided silently over the frozen valley.",
    "Ask Gwendolyn whether the sixth graders have already eaten their lunch, because the bus "
    "leaves at noon.",
    "Quick, grab the flashlight: the basement lights just went out again!",
]
NEVER_TUNED = [
    "Could you please spell your surname for me, Mister Okonkwo?",
    "Forty-two glimpses of splendid sculptures amazed the visitors from Zurich.",
    "Every evening, Uncle Ahmed reads the newspaper aloud to his seven grandchildren.",
    "The twins sprinted, stumbled, and scrambled up the steep gravel path behind the church.",
    "Is it true that an octopus has three hearts and blue blood?",
    "Nine hundred and sixty volunteers cleaned the sandy beaches of Lake Michigan.",
    "Anxious about the exam, Priya stayed awake until half past two in the morning.",
    "Wow, what a view!",
    "Unbelievably, the old refrigerator still hums along after thirty years of service.",
    "Charlotte measured the width of the window with a yellow tape, then ordered new curtains.",
    "My neighbor's dog, a cheerful beagle named Rufus, barks whenever the postman walks past "
    "the gate.",
    "Which of these six strange jars holds the vanilla extract, and which holds the glue?",
]
#: (name, engine, voice, rate, pitch, SNR in dB of added white noise or None) of the truth.
VOICES = [
    ("festival HTS", "festival", None, None, None, None),
    ("festival HTS fast", "festival", None, 210, None, None),
    ("festival HTS in noise (SNR 20 dB)", "festival", None, None, None, 20),
    ("espeak en-us+f3 140 wpm p70", "espeak", "en-us+f3", 140, 70, None),
    ("espeak en-us+m3 220 wpm p30", "espeak", "en-us+m3", 220, 30, None),
    ("espeak en-us+klatt p80", "espeak", "en-us+klatt", None, 80, None),
    ("espeak en-gb 160 wpm p40", "espeak", "en-gb", 160, 40, None),
]
QUICK = bool(os.environ.get("VTTS_BENCH_QUICK"))


def _speak(engine: str, text: str, voice, rate, pitch):
    if engine == "festival":
        from vtts.speech import festival

        return festival.synthesize(text, rate=rate, pitch=pitch)
    from vtts.speech.tts import synthesize

    return synthesize(escape(text), voice=voice, rate=rate, pitch=pitch)


def _floats(audio: np.ndarray) -> np.ndarray:
    return audio.astype(np.float32) / np.float32(32768)


def _measure(texts: list[str], voice: tuple, baseline: bool = False):
    """Boundary errors (s) and bilabial hits of every text spoken by ``voice``."""
    from vtts.align import align
    from vtts.align.score import boundary_errors

    _, engine, name, rate, pitch, snr = voice
    errors, hits, matched, signed = [], [], [], []
    rng = np.random.default_rng(0)
    for text in texts:
        speech = _speak(engine, text, name, rate, pitch)
        samples = _floats(speech.audio)
        if snr is not None:  # white noise at snr dB below the speech's power
            power = np.mean(samples[np.abs(samples) > 0.01] ** 2)
            sigma = np.sqrt(power / 10 ** (snr / 10))
            samples = samples + rng.normal(0, sigma, len(samples)).astype(np.float32)
        found = align(samples, speech.rate, f"<speak>{escape(text)}</speak>", baseline=baseline)
        be = boundary_errors(found.phones, speech.phonemes, fps=30)
        errors.append(be.errors)
        signed.append(be.signed)
        hits.append(be.bilabials)
        matched.append(be.matched / be.total)
    bias = float(np.median(np.concatenate(signed))) * 1000
    return np.concatenate(errors) * 1000, np.concatenate(hits), float(np.mean(matched)), bias


def _rows_for(case: str, errors, hits, matched: float, bias: float) -> list[dict]:
    med, p90 = float(np.median(errors)), float(np.percentile(errors, 90))
    return [
        _row(f"{case}: boundary median ({len(errors)} boundaries)", med, "ms", "<= 20", med <= 20),
        _row(f"{case}: boundary p90", p90, "ms", "<= 50", p90 <= 50),
        _row(f"{case}: boundary worst", float(errors.max()), "ms"),
        _row(f"{case}: bilabial centre in its 30 Hz frame", 100 * float(hits.mean()), "%"),
        _row(f"{case}: truth phones matched", 100 * matched, "%"),
        _row(f"{case}: median of aligned - true (bias)", bias, "ms"),
    ]


def _row(case: str, value: float, unit: str, target: str = "", ok=None) -> dict:
    # judged on the value as shown: festival's times are on a 5 ms grid, and 50.000000001 is 50
    if ok is not None and target.startswith("<= "):
        ok = round(value, 2) <= float(target[3:])
    return {
        "benchmark": BENCH,
        "case": case,
        "value": round(value, 2),
        "unit": unit,
        "target": target,
        "ok": ok,
    }


def _long_text(minutes: float) -> tuple[str, object]:
    """A text of about ``minutes`` of espeak-ng en-us+m3 speech (the sentences repeated), and
    that speech."""
    from vtts.speech.tts import synthesize

    text = " ".join(TUNED + HELD_OUT)
    once = synthesize(escape(text), voice="en-us+m3", rate=165, ssml=False).duration
    full = " ".join([text] * max(1, int(np.ceil(minutes * 60 / once))))
    return full, synthesize(f"<speak>{escape(full)}</speak>", voice="en-us+m3", rate=165)


def _speed(minutes: float) -> float:
    from vtts.align import align

    text, speech = _long_text(minutes)
    t = time.perf_counter()
    align(_floats(speech.audio), speech.rate, f"<speak>{escape(text)}</speak>")
    return (time.perf_counter() - t) / (speech.duration / 60)


def _memory(minutes: float) -> dict:
    """Peak RSS growth (MiB) while aligning, in a fresh interpreter."""
    with tempfile.TemporaryDirectory() as tmp:
        text, speech = _long_text(minutes)
        import soundfile as sf

        sf.write(Path(tmp) / "rec.wav", speech.audio, speech.rate)
        (Path(tmp) / "rec.txt").write_text(text, encoding="utf-8")
        r = subprocess.run(
            [sys.executable, __file__, "--memory", tmp],
            capture_output=True,
            text=True,
            check=True,
            timeout=600,
        )
    return json.loads(r.stdout.strip().splitlines()[-1])


def _memory_child(folder: str) -> None:
    import soundfile as sf

    from vtts.align import align

    samples, rate = sf.read(Path(folder) / "rec.wav", dtype="float32")
    text = (Path(folder) / "rec.txt").read_text(encoding="utf-8")
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t = time.perf_counter()
    align(samples, rate, f"<speak>{escape(text)}</speak>")
    seconds = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps({"mib": (after - before) / 1024, "minutes": len(samples) / rate / 60,
                      "seconds": seconds}))  # fmt: skip


def run() -> list[dict]:
    rows: list[dict] = []
    voices = [VOICES[0], VOICES[4]] if QUICK else VOICES
    tuned, held = (TUNED[:2], HELD_OUT[:1]) if QUICK else (TUNED, HELD_OUT)
    words = sum(len(t.split()) for t in tuned + held)
    rows.append(_row("words of text per voice (tuned on + held out)", words, "words"))
    for voice in voices:
        e_t, h_t, m_t, b_t = _measure(tuned, voice)
        e_h, h_h, m_h, b_h = _measure(held, voice)
        rows += _rows_for(voice[0], np.concatenate([e_t, e_h]), np.concatenate([h_t, h_h]),
                          (m_t + m_h) / 2, (b_t + b_h) / 2)  # fmt: skip
        med, p90 = float(np.median(e_h)), float(np.percentile(e_h, 90))
        rows.append(_row(f"{voice[0]}: held-out texts only, boundary median", med, "ms", "<= 20",
                         med <= 20))  # fmt: skip
        rows.append(_row(f"{voice[0]}: held-out texts only, boundary p90", p90, "ms", "<= 50",
                         p90 <= 50))  # fmt: skip
    for voice in voices[:1] if QUICK else [VOICES[0], VOICES[3]]:
        e, h, m, b = _measure(tuned + held, voice, baseline=True)
        rows += _rows_for(f"baseline (aeneas's DTW) {voice[0]}", e, h, m, b)[:4]
    per_minute = _speed(1.0)
    rows.append(_row("alignment time, 1 minute of audio", per_minute, "s/min", "<= 2",
                     per_minute <= 2))  # fmt: skip
    if not QUICK:
        mem = _memory(10.0)
        rows.append(_row(f"alignment time, {mem['minutes']:.1f} minutes of audio",
                         mem["seconds"] / mem["minutes"], "s/min", "<= 2",
                         mem["seconds"] / mem["minutes"] <= 2))  # fmt: skip
        rows.append(_row(f"peak memory growth, {mem['minutes']:.1f} minutes", mem["mib"], "MiB"))
    return rows


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--memory":
        _memory_child(sys.argv[2])
    else:
        for row in run():
            print(f"{row['case']:70s} {row['value']:>9} {row['unit']:6s} {row['target']}")
