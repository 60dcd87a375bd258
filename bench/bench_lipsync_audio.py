"""Lip-sync from the voice alone (issue 43): visemes recognized from audio without its text,
against the truth of speech whose phone times are known.

Three paths, each giving a viseme (silence or one of the 14 MPEG-4 visemes) per 10 ms frame:

(a) **recognized**: ``vtts.speech.recognize.recognize`` (the viseme classifier of
    ``vtts.speech.viseme_classifier``; the energy where it finds no viseme in audible sound) —
    ``vtts say --audio REC``; and for comparison **PocketSphinx** alone, what (a) was before
    the classifier (``RecognizerOptions(classifier=False)``: PocketSphinx allphone);
(b) **aligned**: the transcript aligned to the audio (``vtts.align.align``) — ``vtts say --audio
    REC --text T``, the upper bound;
(c) **energy only**: ``vtts.speech.energy.energy_visemes`` alone — what cheap lip-sync does.

Truth: festival's HTS voice (its utterance's segment times; also faster, and in white noise at
20 dB SNR) and espeak-ng's own phone events with several voices; the visemes of each engine's
phones (``vtts/data/phoneme_visemes.tsv``). Real read speech: Debian's ``pocketsphinx-testdata``
(five LibriVox sentences and five card names, 16 kHz), whose truth is PocketSphinx's own forced
alignment of the transcript at phone level — the same acoustic model as (a), which favours it:
those rows are labelled so.

Figures: **agreement**, the share of 10 ms frames whose viseme is the truth's (all frames, and
the frames where the truth speaks); **bilabial closures**: of the truth's p, b, m, the share whose
centre has a bilabial of the path within one 30 Hz frame (1/30 s); **closures**: the same with
adjacent p b m (of the truth and of the path) one closure each; **false closures**: the path's
closures that overlap none of the truth's p b m widened by 1/30 s; **speed**: recognition's wall
time (the target: what a user waits for, on this machine's cores; a recording of two pieces or
more is decoded in two processes) and CPU time (both processes') as a fraction of the audio's
duration (60 s of festival's speech in one file; 60 s of the real read speech with its words
recognized, the default, and without; 3 s, 7 s, 8 s and 12 s of it, one piece each — from 8 s
its word search in two halves in two processes — each first in its process or with the decoders
the last recognition kept; ``vtts batch --workers 2``
of lip-sync jobs over the ten real recordings three times, 103 s of audio in 30 files of
1.1–7.1 s, and over ten recordings of 9–12 s, each four of them joined, from the command's
start to its exit);
**live latency**: :class:`~vtts.speech.recognize.LiveRecognizer` fed 20 ms chunks in real time
(simulated: each chunk arrives when its last sample would, is processed once it has arrived and
the one before is done, the measured wall time of each ``feed``); a frame's latency is from its
last sample's arrival to the ``feed`` that gives its viseme; for the real speech also (a)
**against (b)'s phones** (vtts's aligner with the transcript, a truth independent of
PocketSphinx's search, which the real speech's truth and the word pass share): agreement and
(b)'s bilabials found; p50, p95 and the share of real time
the processing took. **Recordings of 8 s or more**: path (a) on each part's sentences of a
voice joined in order into files of 8 s or more, and on every two of the part's LibriVox
sentences (one reader) that make 8 s: agreement and bilabials (from 8 s on a recording has its
word search in two halves, which the files of the rows above, 1.1–7.1 s, never do).
**End to end**: ``vtts play --audio - -o -`` (cybatt, 176×144) in its own
process, fed 30 s of the voice at the pace of real time; a frame's latency is from the writing
of the sound of its time to its arrival on stdout (the recognizer, the voice track's 40 ms lead
and the rendering together).

Sentences: :data:`TUNING` and :data:`HELD_OUT`, written and committed before any tuning; the held
out ones (and the real speech's :data:`REAL_HELD_OUT`) are kept out of every tuning run and
reported apart. ``VTTS_BENCH_QUICK=1``: two sentences and two voices.
``VTTS_BENCH_PARTS=tuning`` (or ``held out``): that part alone (synthetic and real speech; the
speed and live rows still run); default both. ``VTTS_BENCH_CLASSIFIER=FILE``: path (a) with the
viseme classifier's weights in ``FILE`` (``RecognizerOptions(weights=FILE)``, e.g. a network of
``scripts/train_viseme_classifier.py --out FILE``) instead of the package's.
``VTTS_BENCH_WORDS=always`` (or ``never``): path (a) recognizes words everywhere (nowhere)
instead of where the classifier is unsure (``RecognizerOptions(words=…)``).
Targets (issue 43): (a) within 15 points of (b) and far above (c); bilabials >= 85 %; speed <=
0.1 of the duration (wall time); live latency p95 <= 150 ms.
"""

from __future__ import annotations

import os
import re
import time
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

BENCH = "lipsync_audio"
TUNING = [
    "My mother bought a basket of apples at the market on Monday.",
    "The big brown bear ambled past the empty cabin.",
    "Please remember to bring a warm sweater to the lake.",
    "Fifteen players waited patiently for the bus to the stadium.",
    "We watched the ships move slowly through the harbor at sunset.",
    "Bob put the maps and the compass back in the pocket of his bag.",
    "Her favorite movie is about a robot who learns to paint.",
    "Jump over the puddle, then wipe your boots on the mat.",
]
HELD_OUT = [
    "Maybe the baby would sleep better with the lamp turned off.",
    "A thousand birds flew above the village before the storm.",
    "Put the plums and the bread in the blue paper bag.",
    "Amelia plays the trumpet in the school band every Tuesday.",
    "The map shows a path between the mountains and the beach.",
    "Somebody left a bottle of milk by the window all morning.",
    "Bring your problems to the meeting, and we will fix them.",
    "The submarine emerged from the deep water without a sound.",
]
#: (name, engine, voice, rate, pitch, SNR in dB of added white noise or None)
VOICES = [
    ("festival HTS", "festival", None, None, None, None),
    ("festival HTS fast", "festival", None, 210, None, None),
    ("festival HTS in noise (SNR 20 dB)", "festival", None, None, None, 20),
    ("espeak en-us", "espeak", "en-us", None, None, None),
    ("espeak en-us+f3 140 wpm p70", "espeak", "en-us+f3", 140, 70, None),
    ("espeak en-gb 160 wpm p40", "espeak", "en-gb", 160, 40, None),
]
#: pocketsphinx-testdata's real speech: (folder, file id) kept for tuning and held out
REAL_DIR = Path("/usr/share/pocketsphinx/test/data")
REAL_TUNING = [
    ("librivox", "sense_and_sensibility_01_austen_64kb-0870"),
    ("librivox", "sense_and_sensibility_01_austen_64kb-0890"),
    ("librivox", "sense_and_sensibility_01_austen_64kb-0930"),
    ("cards", "001"),
    ("cards", "002"),
]
REAL_HELD_OUT = [
    ("librivox", "sense_and_sensibility_01_austen_64kb-0880"),
    ("librivox", "sense_and_sensibility_01_austen_64kb-0920"),
    ("cards", "003"),
    ("cards", "004"),
    ("cards", "005"),
]
FRAME = 0.010
#: Least length of the recordings joined from a part's sentences (:func:`_joined_rows`), s:
#: from 8 s (two of ``HALF_S``), a recording of one piece has its word search in two halves.
JOINED_S = 8.0
FPS = 30.0
QUICK = bool(os.environ.get("VTTS_BENCH_QUICK"))
PARTS = [p.strip() for p in os.environ.get("VTTS_BENCH_PARTS", "tuning,held out").split(",")]
WORDS = os.environ.get("VTTS_BENCH_WORDS", "auto")
#: The tally of path (a) scored against path (b)'s phones instead of the truth's
AGAINST_ALIGNED = "recognized against aligned"
CLASSIFIER = (
    Path(os.environ["VTTS_BENCH_CLASSIFIER"]) if os.environ.get("VTTS_BENCH_CLASSIFIER") else None
)


def _speak(engine: str, text: str, voice, rate, pitch):
    if engine == "festival":
        from vtts.speech import festival

        return festival.synthesize(text, rate=rate, pitch=pitch)
    from vtts.speech.tts import synthesize

    return synthesize(escape(text), voice=voice, rate=rate, pitch=pitch)


def frames_of(phones, n: int) -> np.ndarray:
    """``(n,)`` int8 viseme per 10 ms frame of phones (``start``, ``end`` s, ``viseme``): the
    phone covering the frame's middle."""
    out = np.zeros(n, np.int8)
    mids = (np.arange(n) + 0.5) * FRAME
    for p in phones:
        a, b = np.searchsorted(mids, [p.start, p.end])
        out[a:b] = p.viseme or 0
    return out


def _bilabials(truth_phones, path_phones, *, closures: bool = False) -> tuple[int, int]:
    """(found, total) truth bilabials with a path bilabial's centre within 1/30 s of theirs;
    ``closures``: adjacent truth bilabials (``m p`` in "empty", ``b p`` in "Bob put") count as
    one closure, centred on the middle of the two, and so do the path's (a recognizer that
    names the two phones of one closure has one closure there)."""
    runs = _closures(path_phones) if closures else [
        (p.start, p.end) for p in path_phones if p.viseme == 1]  # fmt: skip
    centres = np.array([0.5 * (a + b) for a, b in runs])
    spans: list[list[float]] = []
    previous = None
    for p in truth_phones:
        if p.viseme == 1:
            if closures and previous is not None and previous.viseme == 1 and spans:
                spans[-1][1] = p.end
            else:
                spans.append([p.start, p.end])
        previous = p
    found = 0
    for a, b in spans:
        c = 0.5 * (a + b)
        found += bool(centres.size and np.min(np.abs(centres - c)) <= 1.0 / FPS + 1e-9)
    return found, len(spans)


def _closures(phones) -> list[tuple[float, float]]:
    """The (start, end) of each run of adjacent bilabial phones (one closure of the lips)."""
    runs: list[list[float]] = []
    for p in phones:
        if p.viseme != 1:
            continue
        if runs and abs(runs[-1][1] - p.start) < 1e-6:
            runs[-1][1] = p.end
        else:
            runs.append([p.start, p.end])
    return [(a, b) for a, b in runs]


def _false_closures(truth_phones, path_phones) -> tuple[int, int]:
    """(false, total) closures of the path (runs of adjacent bilabials) that overlap no truth
    p, b or m widened by 1/30 s on each side: lips shut where the speaker's were not."""
    truth = [(p.start, p.end) for p in truth_phones if p.viseme == 1]
    runs = _closures(path_phones)
    w = 1.0 / FPS
    false = sum(not any(a - w < te and ts < b + w for ts, te in truth) for a, b in runs)
    return false, len(runs)


def _phones_of(vis: np.ndarray):
    """Runs of a per-frame viseme array as phones (for the energy path's bilabials: none)."""
    from vtts.speech.phonemes import Phone

    edges = np.concatenate([[0], np.flatnonzero(np.diff(vis)) + 1, [vis.size]])
    runs = zip(edges[:-1], edges[1:], strict=True)
    return [Phone(a * FRAME, b * FRAME, "", int(vis[a])) for a, b in runs]


class Tally:
    """Frames agreeing, frames, speech frames agreeing, speech frames, bilabials found/total,
    closures found/total, false closures/closures of the path."""

    def __init__(self) -> None:
        self.same = self.n = self.speech_same = self.speech = self.bil = self.bil_total = 0
        self.clo = self.clo_total = self.false = self.false_total = 0

    def merge(self, other: Tally) -> None:
        """Add ``other``'s counts to this tally's."""
        for k in vars(other):
            setattr(self, k, getattr(self, k) + getattr(other, k))

    def add(self, truth: np.ndarray, got: np.ndarray, bil: tuple[int, int],
            clo: tuple[int, int] = (0, 0), false: tuple[int, int] = (0, 0)) -> None:  # fmt: skip
        n = min(truth.size, got.size)
        t, g = truth[:n], got[:n]
        self.same += int(np.sum(t == g))
        self.n += n
        self.speech_same += int(np.sum((t == g) & (t != 0)))
        self.speech += int(np.sum(t != 0))
        self.bil += bil[0]
        self.bil_total += bil[1]
        self.clo += clo[0]
        self.clo_total += clo[1]
        self.false += false[0]
        self.false_total += false[1]


def _paths(samples: np.ndarray, rate: int, ssml: str | None, truth_phones) -> dict:
    """The three paths' (frames, phones) for one recording."""
    from vtts.align import align
    from vtts.speech.audio import resample
    from vtts.speech.energy import energy_frames, energy_visemes
    from vtts.speech.recognize import RecognizerOptions, recognize

    n = int(np.ceil(len(samples) / rate / FRAME))
    rec = recognize(samples, rate, RecognizerOptions(weights=CLASSIFIER, words=WORDS))
    out = {"recognized": (frames_of(rec.phones, n), rec.phones)}
    ps = recognize(samples, rate, RecognizerOptions(classifier=False))
    out["pocketsphinx"] = (frames_of(ps.phones, n), ps.phones)
    if ssml is not None:
        al = align(samples, rate, ssml)
        out["aligned"] = (frames_of(al.phones, n), al.phones)
    ev = energy_visemes(energy_frames(resample(samples, rate, 16000), 16000))[:n]
    out["energy only"] = (ev, _phones_of(ev))
    return out


def _synthetic(texts: list[str], voice: tuple, tallies: dict, kept: list | None = None) -> None:
    """Each path's tally of ``voice`` speaking ``texts``, one file each, added to ``tallies``;
    each ``(samples, rate, truth phones)`` appended to ``kept`` where given."""
    _, engine, name, rate, pitch, snr = voice
    rng = np.random.default_rng(0)
    for text in texts:
        speech = _speak(engine, text, name, rate, pitch)
        samples = speech.audio.astype(np.float32) / np.float32(32768)
        if snr is not None:
            power = np.mean(samples[np.abs(samples) > 0.01] ** 2)
            sigma = np.sqrt(power / 10 ** (snr / 10))
            samples = samples + rng.normal(0, sigma, len(samples)).astype(np.float32)
        _tally(tallies, samples, int(speech.rate), text, list(speech.phonemes))
        if kept is not None:
            kept.append((samples, int(speech.rate), list(speech.phonemes)))


def _tally(tallies: dict, samples: np.ndarray, rate: int, text: str, truth_phones: list) -> None:
    """Each path's agreement, bilabials and false closures on ``samples`` ``(n,)`` float32 at
    ``rate`` Hz, of ``text``, against ``truth_phones``, added to ``tallies`` (by path)."""
    truth = frames_of(truth_phones, int(np.ceil(len(samples) / rate / FRAME)))
    paths = _paths(samples, rate, f"<speak>{escape(text)}</speak>", truth_phones)
    if "aligned" in paths:  # (a) against (b): a second truth, independent of PocketSphinx's
        (b_frames, b_phones), (got, phones) = paths["aligned"], paths["recognized"]
        tallies.setdefault(AGAINST_ALIGNED, Tally()).add(
            b_frames, got, _bilabials(b_phones, phones), (0, 0), _false_closures(b_phones, phones)
        )
    for path, (got, phones) in paths.items():
        tallies.setdefault(path, Tally()).add(
            truth,
            got,
            _bilabials(truth_phones, phones),
            _bilabials(truth_phones, phones, closures=True),
            _false_closures(truth_phones, phones),
        )


def _transcripts() -> dict[tuple[str, str], str]:
    out = {}
    for folder, name in (("librivox", "transcription"), ("cards", "cards.transcription")):
        for line in (REAL_DIR / folder / name).read_text().splitlines():
            m = re.match(r"\s*<s>(.*)</s>\s*\((\S+)\)", line)
            if m:
                out[(folder, m[2])] = " ".join(m[1].split())
    return out


def _forced(samples_i16: np.ndarray, text: str):
    """PocketSphinx's phone-level forced alignment of ``text`` (the truth of the real speech)."""
    from pocketsphinx import Decoder, get_model_path

    from vtts.speech.phonemes import Phone
    from vtts.speech.recognize import phone_viseme

    root = os.path.join(get_model_path(), "en-us")
    d = Decoder(hmm=os.path.join(root, "en-us"), dict=os.path.join(root, "cmudict-en-us.dict"),
                lm=None, loglevel="FATAL", logfn=os.devnull)  # fmt: skip
    d.set_align_text(text)
    for _ in range(2):  # the words, then (set_alignment) the phones
        d.start_utt()
        d.process_raw(samples_i16.tobytes(), full_utt=True)
        d.end_utt()
        if _ == 0:
            d.set_alignment()
    phones = []
    for w in d.get_alignment():
        for p in w:
            start, end = p.start * FRAME, (p.start + p.duration) * FRAME
            phones.append(Phone(start, end, p.name, phone_viseme(p.name)))
    return phones


def _real(items, tallies: dict, kept: list | None = None) -> None:
    """Each path's tally of the real recordings ``items``, added to ``tallies``; the LibriVox
    ones' ``(samples, rate, truth phones)`` (one reader) appended to ``kept`` where given."""
    import soundfile as sf

    texts = _transcripts()
    for folder, name in items:
        x, rate = sf.read(str(REAL_DIR / folder / f"{name}.wav"), dtype="int16")
        text = texts[(folder, name)]
        truth_phones = _forced(x, text)
        samples = x.astype(np.float32) / np.float32(32768)
        _tally(tallies, samples, rate, text, truth_phones)
        if kept is not None and folder == "librivox":
            kept.append((samples, rate, truth_phones))


def _joined(recordings: list) -> Tally:
    """Path (a)'s tally over ``recordings``, each a list of ``(samples, rate, truth phones)``
    joined into one file (one speaker, each at least :data:`JOINED_S`: one piece, whose word
    search, where it runs, runs in two halves)."""
    from vtts.speech.phonemes import Phone
    from vtts.speech.recognize import RecognizerOptions, recognize

    tally = Tally()
    for parts in recordings:
        rate = parts[0][1]
        truth, t = [], 0.0
        for samples, _, phones in parts:
            truth += [Phone(p.start + t, p.end + t, p.phoneme, p.viseme) for p in phones]
            t += len(samples) / rate
        x = np.concatenate([samples for samples, _, _ in parts])
        rec = recognize(x, rate, RecognizerOptions(weights=CLASSIFIER, words=WORDS))
        n = int(np.ceil(t / FRAME))
        tally.add(frames_of(truth, n), frames_of(rec.phones, n), _bilabials(truth, rec.phones))
    return tally


def _long(kept: list) -> list[list]:
    """``kept``'s ``(samples, rate, truth phones)`` joined in order, as many at a time as make
    :data:`JOINED_S` (what is left over, shorter, dropped)."""
    out, group = [], []
    for item in kept:
        group.append(item)
        if sum(len(samples) / rate for samples, rate, _ in group) >= JOINED_S:
            out.append(group)
            group = []
    return out


def _joined_rows(label: str, voices: dict[str, list], real: list) -> list[dict]:
    """Path (a) on recordings of :data:`JOINED_S` or more (:func:`_joined`): each voice's
    sentences of the part joined in order (:func:`_long`), and every two of the part's
    LibriVox sentences (one reader) that make that long; agreement per voice, and agreement
    and bilabials of the synthetic voices together and of the real speech."""
    import itertools

    rows: list[dict] = []
    every = Tally()
    case = f"{label}, recordings of {JOINED_S:.0f} s or more (sentences joined, one file each)"
    for voice, kept in voices.items():
        recordings = _long(kept)
        if not recordings:
            continue
        t = _joined(recordings)
        every.merge(t)
        rows.append(_row(f"{case}, {voice}: recognized: agreement ({len(recordings)} files, "
                         f"{t.n} frames)", 100.0 * t.same / max(t.n, 1), "%"))  # fmt: skip
    sets = [("all synthetic voices", every)] if every.n else []
    pairs = [list(p) for p in itertools.combinations(real, 2)
             if sum(len(samples) / rate for samples, rate, _ in p) >= JOINED_S]  # fmt: skip
    if pairs:
        sets.append((f"real speech ({len(pairs)} files)", _joined(pairs)))
    for name, t in sets:
        rows.append(_row(f"{case}, {name}: recognized: agreement ({t.n})",
                         100.0 * t.same / max(t.n, 1), "%"))  # fmt: skip
        rows.append(_row(f"{case}, {name}: recognized: bilabials within 1/30 s (of "
                         f"{t.bil_total})", 100.0 * t.bil / max(t.bil_total, 1), "%", "≥ 85",
                         t.bil >= 0.85 * t.bil_total))  # fmt: skip
    return rows


def _speed_audio(seconds: float) -> tuple[np.ndarray, int]:
    """About ``seconds`` of festival's speech of the tuning sentences, repeated."""
    from vtts.speech import festival

    sp = festival.synthesize(" ".join(TUNING[:4]))
    x = sp.audio.astype(np.float32) / np.float32(32768)
    reps = int(np.ceil(seconds * sp.rate / len(x)))
    return np.tile(x, reps)[: int(seconds * sp.rate)], int(sp.rate)


def _real_speed_audio(seconds: float) -> np.ndarray:
    """About ``seconds`` of the real read speech (all ten recordings, repeated) at 16 kHz."""
    import soundfile as sf

    x = np.concatenate([
        sf.read(str(REAL_DIR / folder / f"{name}.wav"), dtype="float32")[0]
        for folder, name in REAL_TUNING + REAL_HELD_OUT
    ])  # fmt: skip
    return np.tile(x, int(np.ceil(seconds * 16000 / len(x))))[: int(seconds * 16000)]


def _speed(
    x: np.ndarray, rate: int, words: str = "auto", *, kept: bool = False
) -> tuple[float, float]:
    """Wall and CPU time (this process's and its workers') of recognizing ``(n,)`` samples at
    ``rate``, each a fraction of their duration: as the first recognition in a process (its
    decoders made), or where ``kept`` with the decoders the last one kept (a batch's next
    file)."""
    import resource

    from vtts.speech.recognize import RecognizerOptions, recognize, release_decoders

    if not kept:
        release_decoders()

    def workers() -> float:
        used = resource.getrusage(resource.RUSAGE_CHILDREN)
        return used.ru_utime + used.ru_stime

    w, c, k = time.perf_counter(), time.process_time(), workers()
    recognize(x, rate, RecognizerOptions(words=words))
    d = len(x) / rate
    cpu = time.process_time() - c + workers() - k
    return (time.perf_counter() - w) / d, cpu / d


#: Times the batch of real speech is repeated (:func:`batch_of_files`).
BATCH_ROUNDS = 3


def batch_of_files(rounds: int = BATCH_ROUNDS, joined: bool = False) -> tuple[float, float, int]:
    """``vtts batch --workers 2`` of lip-sync jobs (``say`` with ``--audio`` and no text,
    timings only, ``cybatt``'s timeline) over the ten real recordings — or, ``joined``, ten
    recordings of 9–12 s, each four of them one after another cut at 12 s (one piece each,
    whose word search runs in halves) — ``rounds`` times: the command's wall time from start to exit
    (its start-up, each worker's decoders made, the jobs), the audio's seconds, and the
    jobs."""
    import json
    import subprocess
    import sys
    import tempfile

    import soundfile as sf

    exe = str(Path(sys.executable).with_name("vtts"))
    files = [REAL_DIR / folder / f"{name}.wav" for folder, name in REAL_TUNING + REAL_HELD_OUT]
    with tempfile.TemporaryDirectory(prefix="vtts-bench-lipsync-batch-") as tmp:
        if joined:
            pcm = [sf.read(str(f), dtype="int16")[0] for f in files]
            files = []
            for k in range(len(pcm)):
                x = np.concatenate([pcm[(k + i) % len(pcm)] for i in range(4)])[: 12 * 16000]
                files.append(Path(tmp, f"joined-{k}.wav"))
                sf.write(str(files[-1]), x, 16000)
        audio = rounds * sum(sf.info(str(f)).duration for f in files)
        jobs = [
            {
                "id": f"{f.stem}-{r}",
                "say": None,
                "audio": str(f),
                "model": "cybatt",
                "timings_out": f"{f.stem}-{r}.tsv",
            }
            for r in range(rounds)
            for f in files
        ]
        Path(tmp, "jobs.jsonl").write_text("".join(json.dumps(j) + "\n" for j in jobs))
        t = time.perf_counter()
        subprocess.run([exe, "batch", "jobs.jsonl", "--out", "out", "--workers", "2"], cwd=tmp,
                       check=True, capture_output=True)  # fmt: skip
        wall = time.perf_counter() - t
        assert len(list(Path(tmp, "out").glob("*.tsv"))) == len(jobs)
    return wall, audio, len(jobs)


def live_latency(x: np.ndarray, rate: int, chunk_s: float = 0.02) -> dict:
    """Latency of :class:`LiveRecognizer` fed ``chunk_s`` chunks in simulated real time (see
    the module docstring): ``p50``, ``p95`` (s) and ``load`` (processing / duration)."""
    from vtts.speech.recognize import LiveRecognizer

    pcm = np.round(np.clip(x, -1, 1) * 32767).astype(np.int16)
    live = LiveRecognizer(rate)
    step = int(round(chunk_s * rate))
    clock = 0.0  # when the processing of the previous chunk ended, in the stream's time
    busy = 0.0
    lat: list[float] = []
    for a in range(0, len(pcm), step):
        arrived = min(a + step, len(pcm)) / rate
        start = max(arrived, clock)
        t = time.perf_counter()
        out = live.feed(pcm[a : a + step])
        spent = time.perf_counter() - t
        busy += spent
        clock = start + spent
        first = live.frames_out - out.size
        ends = (np.arange(first, live.frames_out) + 1) * FRAME
        lat += (clock - np.minimum(ends, arrived)).tolist()
    e = np.asarray(lat)
    return {"p50": float(np.median(e)), "p95": float(np.percentile(e, 95)),
            "load": busy / (len(pcm) / rate)}  # fmt: skip


def live_end_to_end(x: np.ndarray, rate: int, size: str = "176x144") -> dict:
    """``vtts play --audio - --model cybatt -o -`` fed ``x`` in 20 ms chunks at the pace of
    real time (a thread writes each chunk when its last sample would exist): each frame's
    latency is from when the sound of its time (frame ``i`` at ``i / 30`` s) was written to when
    the frame arrived on stdout — the recognizer, the voice track's lead and the rendering
    together. ``p50``, ``p95`` and ``late`` (the last frame's, s)."""
    import subprocess
    import sys
    import threading

    w, h = (int(v) for v in size.split("x"))
    pcm = np.round(np.clip(x, -1, 1) * 32767).astype("<i2")
    exe = [sys.executable, "-c", "from vtts.cli import run; run()"]
    cmd = [*exe, "play", "--audio", "-", "--rate", str(rate), "--model", "cybatt",
           "--size", size, "--quiet", "-o", "-"]  # fmt: skip
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    step = rate // 50
    # wait for the process to start (imports, the model, the renderer) before the voice begins
    time.sleep(4.0)
    start = time.perf_counter()

    def feed() -> None:
        for a in range(0, len(pcm), step):
            due = start + min(a + step, len(pcm)) / rate
            time.sleep(max(due - time.perf_counter(), 0))
            proc.stdin.write(pcm[a : a + step].tobytes())
            proc.stdin.flush()
        proc.stdin.close()

    t = threading.Thread(target=feed, daemon=True)
    t.start()
    frame = w * h * 3
    arrived = []
    while chunk := proc.stdout.read(frame):
        if len(chunk) < frame:
            break
        arrived.append(time.perf_counter() - start)
    proc.wait()
    t.join()
    lat = np.array(arrived) - np.arange(len(arrived)) / 30.0
    live_end_to_end.last = lat
    return {"p50": float(np.median(lat)), "p95": float(np.percentile(lat, 95)),
            "late": float(lat[-1]), "frames": len(arrived)}  # fmt: skip


def _row(case: str, value, unit: str, target: str = "", ok=None) -> dict:
    return {"benchmark": BENCH, "case": case, "value": value, "unit": unit, "target": target,
            "ok": ok}  # fmt: skip


def _agreement_rows(label: str, tallies: dict) -> list[dict]:
    rows = []
    t = tallies.get(AGAINST_ALIGNED)
    if t is not None and "real" in label:
        case = f"{label}: recognized against (b)'s phones"
        rows.append(_row(f"{case}: agreement, all frames ({t.n})", 100.0 * t.same / max(t.n, 1),
                         "%"))  # fmt: skip
        rows.append(_row(f"{case}: (b)'s bilabials within 1/30 s (of {t.bil_total})",
                         100.0 * t.bil / max(t.bil_total, 1), "%"))  # fmt: skip
    b = tallies.get("aligned")
    for path in ("recognized", "pocketsphinx", "aligned", "energy only"):
        t = tallies.get(path)
        if t is None:
            continue
        pct = 100.0 * t.same / max(t.n, 1)
        target, ok = "", None
        if path == "recognized" and b is not None:
            gap = 100.0 * b.same / max(b.n, 1) - pct
            target, ok = "within 15 of aligned", gap <= 15
        rows.append(_row(f"{label}: {path}: agreement, all frames ({t.n})", pct, "%", target, ok))
        sp = 100.0 * t.speech_same / max(t.speech, 1)
        rows.append(_row(f"{label}: {path}: agreement, speech frames ({t.speech})", sp, "%"))
        if path != "energy only":
            bil = 100.0 * t.bil / max(t.bil_total, 1)
            tgt, ok = ("≥ 85", bil >= 85) if path == "recognized" else ("", None)
            rows.append(
                _row(
                    f"{label}: {path}: bilabials within 1/30 s (of {t.bil_total})",
                    bil,
                    "%",
                    tgt,
                    ok,
                )  # fmt: skip
            )
            clo = 100.0 * t.clo / max(t.clo_total, 1)
            rows.append(
                _row(
                    f"{label}: {path}: closures (adjacent p b m one) within 1/30 s "
                    f"(of {t.clo_total})",
                    clo,
                    "%",
                )  # fmt: skip
            )
            fa = 100.0 * t.false / max(t.false_total, 1)
            rows.append(
                _row(
                    f"{label}: {path}: false closures, none of the truth's within 1/30 s "
                    f"({t.false} of {t.false_total})",
                    fa,
                    "%",
                )  # fmt: skip
            )
    return rows


def run() -> list[dict]:
    rows: list[dict] = []
    voices = VOICES[:1] + VOICES[3:4] if QUICK else VOICES
    spoken: dict[str, dict[str, list]] = {}  # by part, by voice: the speech, for _joined_rows
    for label, texts in (("tuning", TUNING), ("held out", HELD_OUT)):
        if label not in PARTS:
            continue
        texts = texts[:2] if QUICK else texts
        every: dict = {}
        for voice in voices:
            tallies: dict = {}
            _synthetic(texts, voice, tallies, spoken.setdefault(label, {}).setdefault(voice[0], []))
            rows += _agreement_rows(f"{label}, {voice[0]}", tallies)
            for path, t in tallies.items():
                every.setdefault(path, Tally()).merge(t)
        rows += _agreement_rows(f"{label}, all synthetic voices", every)
    if REAL_DIR.is_dir():
        for label, items in (("tuning", REAL_TUNING), ("held out", REAL_HELD_OUT)):
            if label not in PARTS:
                continue
            tallies = {}
            librivox: list = []
            _real(items[:2] if QUICK else items, tallies, librivox)
            rows += _agreement_rows(
                f"{label}, real speech (truth: pocketsphinx's forced alignment)", tallies
            )
            rows += _joined_rows(label, spoken.get(label, {}), librivox)
    else:
        rows.append(_row("real speech: pocketsphinx-testdata not installed", None, ""))
    x, rate = _speed_audio(20.0 if QUICK else 60.0)
    wall, cpu = _speed(x, rate)
    d = len(x) / rate
    # the target is on the time a user waits, on this machine's cores (the pieces of a long
    # recording in two processes); CPU time, both processes', beside it
    rows.append(_row(f"speed: recognize {d:.0f} s of speech, wall", wall, "× duration", "≤ 0.1",
                     wall <= 0.1))  # fmt: skip
    rows.append(_row(f"speed: recognize {d:.0f} s of speech, CPU", cpu, "× duration"))
    if REAL_DIR.is_dir():  # the word search runs where the classifier is unsure: real speech
        real = _real_speed_audio(20.0 if QUICK else 60.0)
        for words in ("auto", "never"):
            wall, cpu = _speed(real, 16000, words)
            case = f"speed: recognize {len(real) / 16000:.0f} s of real speech, words {words}"
            rows.append(_row(f"{case}, wall", wall, "× duration", "≤ 0.1", wall <= 0.1))
            rows.append(_row(f"{case}, CPU", cpu, "× duration"))
        # under 20 s one piece: the decoders' making (some 0.25 s) counts for more; a process
        # recognizing one file after another (batch, serve) makes them once. Under 8 s one
        # word search in one process, from 8 s its two halves in two
        from vtts.speech.recognize import HALF_S

        for seconds in (3, 7, 8, 12):
            for kept in (False, True):
                wall, cpu = _speed(real[: seconds * 16000], 16000, kept=kept)
                search = "its word search in two halves" if seconds >= 2 * HALF_S else "one search"
                case = f"speed: recognize {seconds} s of real speech (one piece, {search}), " + (
                    "decoders kept from the last file" if kept else "first in its process"
                )
                rows.append(_row(f"{case}, wall", wall, "× duration", "≤ 0.1", wall <= 0.1))
                rows.append(_row(f"{case}, CPU", cpu, "× duration"))
        # files one after another on both cores, as a user lip-syncs a game's lines; the
        # longer ones recognized in each worker's own process (its share of the cores)
        for joined in (False, True):
            wall, audio, jobs = batch_of_files(1 if QUICK or joined else BATCH_ROUNDS, joined)
            kind = "real recordings of 9–12 s (joined)" if joined else "real recordings"
            case = f"speed: vtts batch --workers 2 of {jobs} {kind} ({audio:.0f} s), wall"
            rows.append(_row(case, wall / audio, "× duration", "≤ 0.1", wall / audio <= 0.1))
    lat = live_latency(x, rate)
    rows.append(_row("live: latency p50 (20 ms chunks)", 1000 * lat["p50"], "ms"))
    rows.append(_row("live: latency p95 (20 ms chunks)", 1000 * lat["p95"], "ms", "≤ 150",
                     lat["p95"] <= 0.150))  # fmt: skip
    rows.append(_row("live: processing / real time", lat["load"], "×", "< 1", lat["load"] < 1))
    e2e = live_end_to_end(x[: int((10.0 if QUICK else 30.0) * rate)], rate)
    rows.append(_row(f"live, vtts play --audio - -o - ({e2e['frames']} frames): frame latency p50",
                     1000 * e2e["p50"], "ms"))  # fmt: skip
    rows.append(_row("live, vtts play --audio - -o -: frame latency p95", 1000 * e2e["p95"],
                     "ms"))  # fmt: skip
    return rows


if __name__ == "__main__":
    for r in run():
        v = r["value"]
        print(
            f"{r['case']:<95} {v if not isinstance(v, float) else round(v, 3)!s:>8} {r['unit']}"
            f"  {r['target']}  {'' if r['ok'] is None else ('ok' if r['ok'] else 'MISSED')}"
        )
