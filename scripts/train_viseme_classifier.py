"""Train the viseme classifier of ``vtts.speech.viseme_classifier`` and write its weights.

    python scripts/train_viseme_classifier.py [--out vtts/data/viseme_classifier.npz]
                                              [--cache DIR] [--sentences N]

Needs espeak-ng and festival (``scripts/setup.sh``), Piper (the ``piper`` extra) and
scikit-learn (the ``train`` extra: ``pip install -e '.[train,piper]'``). Everything is seeded:
the same packages give the same file. ``--cache DIR`` keeps the synthesized speech (a second
run only augments and trains). The smoothing's parameters (:data:`SWITCH` …) are written into
the file as they are; they were chosen on the lip-sync bench's tuning part.

1. **Sentences**: :func:`sentences` makes ``N`` sentences from the word lists below with a seeded
   generator; any that shares a word trigram with the lip-sync bench's sentences
   (``bench/bench_lipsync_audio.py``, tuning and held out) is dropped, so the bench's
   sentences are never spoken in training.
2. **Speech with exact phone times**: each sentence spoken by espeak-ng (its phone events) with
   a voice of :data:`ESPEAK_VOICES` and a variant of :data:`ESPEAK_VARIANTS` — never ``+f3``,
   which the bench's held-out voice uses — at a random rate and pitch, twice; and every
   :data:`FESTIVAL_EVERY`-th by festival's HTS voice (its segment times) at a random rate and
   pitch — with :data:`FESTIVAL_ALL` every other sentence too (:func:`speak_festival_more`,
   its own seeded rates and pitches) — and every :data:`FESTIVAL_EVERY`-th from the second by
   Piper's joe voice (the network's own durations; needs the ``piper`` extra) at a random
   rate. The truth per 10 ms frame is the viseme of the phone covering the frame's middle.
3. **Augmentation**: every utterance once per entry of :data:`AUGMENTATIONS`, each copy with
   its own draws: resampled to 16 kHz with its formants and tempo scaled (:data:`ALPHA`), a
   random level (−30…0 dB), a fifth low-passed, and for the entry's share of them white or pink
   noise at an SNR in the entry's range, the rest a faint hiss (so that digital silence is
   rare): the first copy half of them at 8–35 dB, the second 60 % at 10–25 dB.
4. **Training**: a multilayer perceptron (scikit-learn's ``MLPClassifier``, Adam, a fixed
   number of passes) on the stacked features for each seed of :data:`NET_SEEDS` (an ensemble:
   ``vtts`` averages their log probabilities); their weights and standardizations, the
   training frames' viseme shares and the smoothing's parameters go to the ``.npz``.
"""

from __future__ import annotations

import argparse
import ast
import re
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from vtts.speech import viseme_classifier as vc  # noqa: E402

SEED = 43
#: The networks' seeds (each one's initial weights and the order of the frames in each pass): an
#: ensemble of three trained on the same frames, whose log probabilities are averaged at run time.
NET_SEEDS = (43, 44, 45)
#: espeak-ng's English voices and variants used in training (the bench speaks en-us, en-gb and
#: en-us+f3: the first two take part with other rates, pitches and sentences, +f3 never).
ESPEAK_VOICES = ["en-us", "en-gb", "en-gb-x-rp", "en-gb-scotland", "en-029", "en-gb-x-gbclan",
                 "en-gb-x-gbcwmd", "en-us-nyc"]  # fmt: skip
ESPEAK_VARIANTS = [None, "m1", "m2", "m3", "m4", "m5", "m6", "m7", "f1", "f2", "f4", "f5",
                   "klatt", "klatt2", "iven", "steph", "Andy", "Mike"]  # fmt: skip
FESTIVAL_EVERY = 3
#: Festival also speaks the sentences that are not every FESTIVAL_EVERY-th (its own seeded
#: rates and pitches: :func:`speak_festival_more`).
FESTIVAL_ALL = True
#: The range of the formant and tempo scale of the augmentation.
ALPHA = (0.88, 1.12)
#: The augmented copies of every utterance, each with its own random draws: per copy the share
#: of the utterances with added noise (the rest: a faint hiss) and the range of its SNR, dB.
AUGMENTATIONS = ((0.5, (8.0, 35.0)), (0.6, (10.0, 25.0)))
#: Share of the added noise that is white (the rest pink).
WHITE_SHARE = 0.5
#: Passes over the training frames.
EPOCHS = 7
#: The smoothing's parameters and PocketSphinx's weight (chosen on the bench's tuning part,
#: docs/speech.md).
MIN_FRAMES = {0: 3, 1: 3}
DEFAULT_MIN_FRAMES = 2
SWITCH = 7.0
PRIOR_WEIGHT = 0.5
BIAS = {1: 2.0}
#: Added to a viseme's score times the network's probability of it (p b m).
BOOST = {1: 2.0}
#: What PocketSphinx's viseme for a frame adds to that viseme's score: EVIDENCE plus
#: EVIDENCE_PER_NAT times the network's entropy there (nats, averaged over 11 frames).
EVIDENCE = 3.0
EVIDENCE_PER_NAT = 4.0

SUBJECTS = """man woman boy girl baby farmer teacher pilot doctor captain mayor neighbor singer
painter plumber butcher barber baker mother father brother sister grandmother monkey puppy
rabbit beaver tiger camel lamb pony zebra dolphin penguin robin pigeon mouse moose bishop
cowboy judge nurse policeman mechanic musician student professor driver waiter chef""".split()
OBJECTS = """apple basket bottle blanket bucket button cabbage camera candle carpet chimney
compass cupboard drum feather fiddle hammer helmet jacket ladder lemon map mirror needle
notebook oven paddle pepper piano pillow pipe plate pocket pumpkin puzzle ribbon robe saddle
shovel sponge stamp suitcase teapot thimble umbrella whistle window wagon banjo bubble parcel
pebble muffin biscuit sandwich potato tomato broom comb boat bike bus plum peach pear bean
bread jam soup milk honey bamboo balloon microphone""".split()
PLACES = """market museum harbor chapel library kitchen garden stable bakery temple palace
campus bridge pier pub theater office farm beach hospital pharmacy cabin barn mountain
meadow swamp valley village shop hotel basement bedroom lobby playground""".split()
VERBS_PAST = """bought brought dropped grabbed kept opened painted packed pushed pulled
polished moved borrowed buried combed cleaned fixed found hid lifted mended passed placed
remembered shipped showed sold swapped tapped threw tossed washed wrapped weighed bumped
carried chopped climbed dumped filled hugged jumped kicked licked melted mopped nibbled
patted picked poured pumped rubbed scrubbed slapped stamped stopped stuffed whipped""".split()
VERBS_INTR = """slept sang smiled shouted laughed waited wandered whispered mumbled jumped
vanished danced hummed stumbled paused blinked yawned swam sneezed shivered""".split()
ADJECTIVES = """big small bumpy brave bright brown purple pink black blue plump empty happy
sleepy muddy shabby simple humble famous modern lumpy damp smooth warm rough thick thin
yellow orange golden silver wooden broken heavy tiny pretty sharp cheap expensive
beautiful terrible wonderful comfortable""".split()
ADVERBS = """quickly slowly happily probably simply suddenly promptly calmly boldly gently
proudly barely nearly completely politely patiently""".split()
TIMES = """on Monday|on Tuesday|on Wednesday|on Thursday|on Friday|in the morning|in the
evening|at midnight|before breakfast|after lunch|last summer|every week|in September|in
November|in February|by the afternoon|at noon|yesterday|tomorrow|many times|a moment ago
""".replace("\n", " ").split("|")
PREPOSITIONS = """in|on|by|behind|beside|under|above|near|from|into|past|beyond|up|up to|
below|between the boxes and|opposite""".replace("\n", " ").split("|")
NAMES = """Bob Pam Tom Jim Emma Bill Pete Amber Sam Mabel Paul Molly Ben Bobby Jimmy Maria
Peggy Ruth Jack Simon Hope Imogen Maxwell Bertha Philip Robert Abby Ophelia""".split()
QUESTIONS = ["Why did the {s} {ve} the {o} {t}?", "Did {n} {ve} the {o} {t}?",
             "Where is the {a} {o}?", "Who {vp} my {o}?",
             "Can you help me {ve} the {o}?"]  # fmt: skip
VERBS_BASE = """open move pack paint push pull fix find hide lift mend pass place ship show
sell wrap weigh carry chop fill pick pour pump rub scrub stamp stop stuff whip bring buy keep
""".split()
TEMPLATES = [
    "The {a} {s} {vp} the {o} {p} the {l} {t}.",
    "{n} {vp} a {a} {o} and {vp} it {p} the {l}.",
    "My {s} {vi} {r} {p} the {a} {l}.",
    "{n} and {n2} {vp} the {o} {t}, then they {vi}.",
    "A {a} {s} {vi} while the {s2} {vp} the {o}.",
    "Please {ve} the {a} {o} {p} the {l}.",
    "Maybe the {s} {vp} the {o} because it was {a}.",
    "There was a {a} {o} {p} the {l} {t}.",
    "{n} {r} {vp} {num} {a} {o}s {t}.",
    "The {o} and the {o2} were both {a} {t}.",
    "If you {ve} the {o}, the {s} will be {a}.",
    "We {vi} {p} the {l} and {vp} a {o}.",
    "Nobody {vp} the {a} {o} {p} the {l}.",
    "{n} thinks the {l} is {a} {t}.",
    "Someone {r} {vp} the {s}'s {o}.",
]
NUMBERS = """two three four five six seven eight nine ten eleven twelve twenty fifty
a hundred""".replace("a hundred", "a_hundred").split()


def sentences(n: int, seed: int = SEED) -> list[str]:
    """``n`` seeded sentences from :data:`TEMPLATES`, none sharing a word trigram with the
    lip-sync bench's sentences."""
    rng = np.random.default_rng(seed)
    pick = lambda words: str(words[rng.integers(len(words))])  # noqa: E731
    banned = _bench_trigrams()
    out: list[str] = []
    seen: set[str] = set()
    while len(out) < n:
        kind = rng.random()
        if kind < 0.1:
            t = pick(QUESTIONS)
        else:
            t = pick(TEMPLATES)
        s = t.format(a=pick(ADJECTIVES), s=pick(SUBJECTS), s2=pick(SUBJECTS), o=pick(OBJECTS),
                     o2=pick(OBJECTS), p=pick(PREPOSITIONS), l=pick(PLACES), t=pick(TIMES),
                     vp=pick(VERBS_PAST), vi=pick(VERBS_INTR), ve=pick(VERBS_BASE),
                     r=pick(ADVERBS), n=pick(NAMES), n2=pick(NAMES),
                     num=pick(NUMBERS).replace("_", " "))  # fmt: skip
        s = s[0].upper() + s[1:]
        if s in seen or _trigrams(s) & banned:
            continue
        seen.add(s)
        out.append(s)
    return out


def _trigrams(text: str) -> set[tuple[str, ...]]:
    w = re.findall(r"[a-z']+", text.lower())
    return {tuple(w[i : i + 3]) for i in range(len(w) - 2)}


def _bench_trigrams() -> set[tuple[str, ...]]:
    """The word trigrams of the bench's sentences (read from its source, not imported)."""
    tree = ast.parse((ROOT / "bench" / "bench_lipsync_audio.py").read_text())
    out: set[tuple[str, ...]] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and any(
            getattr(t, "id", "") in ("TUNING", "HELD_OUT") for t in node.targets
        ):
            for s in ast.literal_eval(node.value):
                out |= _trigrams(s)
    return out


def frame_truth(phones, n: int) -> np.ndarray:
    """``(n,)`` int8 viseme of the phone covering each 10 ms frame's middle."""
    out = np.zeros(n, np.int8)
    mids = (np.arange(n) + 0.5) * 0.010
    for p in phones:
        a, b = np.searchsorted(mids, [p.start, p.end])
        out[a:b] = p.viseme or 0
    return out


def speak_all(texts: list[str], seed: int = SEED) -> list[tuple[np.ndarray, int, list, str]]:
    """``(samples float32, rate, phones, label)`` of every training utterance (step 2)."""
    from xml.sax.saxutils import escape

    from vtts.speech import festival
    from vtts.speech.tts import synthesize

    rng = np.random.default_rng(seed + 1)
    out = []
    for k, text in enumerate(texts):
        for _ in range(2):
            voice = str(rng.choice(ESPEAK_VOICES))
            variant = ESPEAK_VARIANTS[rng.integers(len(ESPEAK_VARIANTS))]
            name = voice if variant is None else f"{voice}+{variant}"
            rate, pitch = int(rng.integers(120, 260)), int(rng.integers(15, 85))
            sp = synthesize(f"<speak>{escape(text)}</speak>", voice=name, rate=rate, pitch=pitch)
            out.append(_utterance(sp, f"espeak {name} {rate} {pitch}"))
        if k % FESTIVAL_EVERY == 0:
            rate, pitch = int(rng.integers(140, 235)), int(rng.integers(30, 70))
            sp = festival.synthesize(text, rate=rate, pitch=pitch)
            out.append(_utterance(sp, f"festival {rate} {pitch}"))
        if k % 50 == 0:
            print(f"  spoken {k + 1}/{len(texts)} sentences", file=sys.stderr, flush=True)
    return out


def _utterance(sp, label: str) -> tuple[np.ndarray, int, list, str]:
    """A synthesized ``Speech`` as ``(samples float32, rate, phones, label)``."""
    return sp.audio.astype(np.float32) / 32768, int(sp.rate), list(sp.phonemes), label


def _speak_every(
    texts: list[str], wanted, say, who: str
) -> list[tuple[np.ndarray, int, list, str]]:
    """``say(text)`` → ``(Speech, label)`` for each sentence whose index ``wanted(k)`` takes, in
    order (so each speaker's seeded draws come in the same order), with a progress line."""
    out = []
    for k, text in enumerate(texts):
        if not wanted(k):
            continue
        out.append(_utterance(*say(text)))
        if k % 50 == 1:
            print(f"  {who} spoke {k + 1}/{len(texts)} sentences", file=sys.stderr, flush=True)
    return out


def speak_piper(texts: list[str], seed: int = SEED) -> list[tuple[np.ndarray, int, list, str]]:
    """Every :data:`FESTIVAL_EVERY`-th sentence (from the second) by Piper's joe voice at a
    random rate: its phones' times are the network's own durations (``vtts.speech.piper``)."""
    from vtts.speech.bookmarks import parse_bookmarks
    from vtts.speech.piper import PiperEngine

    rng = np.random.default_rng(seed + 3)
    engine = PiperEngine()

    def say(text: str):
        rate = int(rng.integers(130, 230))
        return engine.speak(parse_bookmarks(text), rate=rate).speech, f"piper {rate}"

    return _speak_every(texts, lambda k: k % FESTIVAL_EVERY == 1, say, "Piper")


def speak_festival_more(
    texts: list[str], seed: int = SEED
) -> list[tuple[np.ndarray, int, list, str]]:
    """Festival's HTS voice on every sentence that :func:`speak_all` does not give it (not a
    :data:`FESTIVAL_EVERY`-th), at a random rate and pitch from its own seeded generator."""
    from vtts.speech import festival

    rng = np.random.default_rng(seed + 4)

    def say(text: str):
        rate, pitch = int(rng.integers(140, 235)), int(rng.integers(30, 70))
        return festival.synthesize(text, rate=rate, pitch=pitch), f"festival {rate} {pitch}"

    return _speak_every(texts, lambda k: k % FESTIVAL_EVERY != 0, say, "festival")


def augment(
    x: np.ndarray,
    rate: int,
    rng: np.random.Generator,
    noise_share: float = 0.5,
    snr_db: tuple[float, float] = (8.0, 35.0),
) -> tuple[np.ndarray, float]:
    """Step 3: at 16 kHz, a random level, noise or a faint hiss; the formants and tempo scaled
    by a random ``alpha`` (the samples taken for ``alpha`` times their rate: a shorter or
    longer vocal tract), and a fifth of them low-passed (3.5–7.5 kHz). Noise (for a share
    ``noise_share``) is white or pink (white a share :data:`WHITE_SHARE`) at an SNR (dB) drawn
    from ``snr_db``. Returns the samples and ``alpha`` (the phones' times are divided by
    it)."""
    from scipy.signal import butter, sosfilt

    from vtts.speech.audio import resample

    # a rate in steps of 400 Hz: a short polyphase filter to 16 kHz
    taken = int(round(rate * float(rng.uniform(*ALPHA)) / 400)) * 400
    alpha = taken / rate
    y = resample(x, taken, vc.RATE).astype(np.float32)
    if rng.random() < 0.2:
        sos = butter(8, rng.uniform(3500, 7500), fs=vc.RATE, output="sos")
        y = sosfilt(sos, y).astype(np.float32)
    y *= np.float32(10 ** (rng.uniform(-30, 0) / 20))
    power = float(np.mean(y[np.abs(y) > 0.01 * np.abs(y).max()] ** 2)) if y.size else 0.0
    if rng.random() < noise_share:
        snr = rng.uniform(*snr_db)
        noise = rng.normal(0, 1, y.size)
        if rng.random() < 1.0 - WHITE_SHARE:  # pink: white through a first-order low-pass
            from scipy.signal import lfilter

            noise = lfilter([1.0], [1.0, -0.95], noise)
            noise /= noise.std() + 1e-12
        y = y + (np.sqrt(power / 10 ** (snr / 10)) * noise).astype(np.float32)
    else:
        y = y + rng.normal(0, np.sqrt(power) * 10 ** (-rng.uniform(50, 70) / 20), y.size).astype(
            np.float32
        )
    return np.clip(y, -1, 1), alpha


def dataset(utterances, seed: int = SEED) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per utterance its ``(frames, d)`` features and ``(frames,)`` truth."""
    from vtts.speech.phonemes import Phone

    rng = np.random.default_rng(seed + 2)
    feats, truths = [], []
    for noise_share, snr_db in AUGMENTATIONS:
        for x, rate, phones, _ in utterances:
            y, alpha = augment(x, rate, rng, noise_share, snr_db)
            f = vc.frame_features(y)
            feats.append(f)
            scaled = [Phone(p.start / alpha, p.end / alpha, "", p.viseme or 0) for p in phones]
            truths.append(frame_truth(scaled, f.shape[0]))
    return feats, truths


def train(feats, truths, seeds=NET_SEEDS, hidden=(256, 128), snapshot=None) -> dict:
    """Fit one network per seed of ``seeds`` (step 4): :data:`EPOCHS` passes of Adam over the
    frames in a seeded order (the seed also draws the initial weights); the arrays of the
    ``.npz``, the networks in the order of ``seeds`` (``snapshot(arrays, "SEED.PASS")`` with one
    network's arrays after each of its passes, when given)."""
    from sklearn.neural_network import MLPClassifier

    X = np.concatenate([vc.stack(f, 0, f.shape[0]) for f in feats]).astype(np.float32)
    y = np.concatenate(truths).astype(int)
    mean, scale = X.mean(axis=0), X.std(axis=0) + 1e-3
    X = (X - mean) / scale
    print(f"  {X.shape[0]} frames, {X.shape[1]} features", file=sys.stderr, flush=True)
    arrays: dict = {}
    for j, seed in enumerate(seeds):
        net = MLPClassifier(hidden_layer_sizes=hidden, activation="relu", solver="adam",
                            alpha=1e-4, batch_size=512, learning_rate_init=1e-3,
                            random_state=seed)  # fmt: skip
        for epoch in range(EPOCHS):
            net.partial_fit(X, y, classes=np.arange(15))
            print(f"  seed {seed}, epoch {epoch + 1}: loss {net.loss_:.4f}", file=sys.stderr,
                  flush=True)  # fmt: skip
            if snapshot is not None:
                snapshot(_arrays(net, mean, scale, y), f"{seed}.{epoch + 1}")
        one = _arrays(net, mean, scale, y)
        if j == 0:
            arrays = one
        else:  # the other networks' own arrays under "n{j}_" (vc.load_classifier)
            own = ["mean", "scale", *(f"{p}{i}" for i in range(int(one["layers"])) for p in "wb")]
            arrays.update({f"n{j}_{k}": one[k] for k in own})
    arrays["networks"] = np.int64(len(seeds))
    return arrays


def _arrays(net, mean: np.ndarray, scale: np.ndarray, y: np.ndarray) -> dict:
    """The ``.npz``'s arrays of the network ``net``."""
    counts = np.bincount(y, minlength=15).astype(float)
    arrays = {"layers": np.int64(len(net.coefs_)), "mean": mean.astype(np.float32),
              "scale": scale.astype(np.float32),
              "log_prior": np.log(counts / counts.sum()).astype(np.float32),
              "prior_weight": np.float32(PRIOR_WEIGHT), "switch": np.float32(SWITCH),
              "bias": np.array([BIAS.get(v, 0.0) for v in range(15)], np.float32),
              "boost": np.array([BOOST.get(v, 0.0) for v in range(15)], np.float32),
              "evidence": np.float32(EVIDENCE),
              "evidence_per_nat": np.float32(EVIDENCE_PER_NAT),
              "min_frames": np.array([MIN_FRAMES.get(v, DEFAULT_MIN_FRAMES) for v in range(15)],
                                     np.int8)}  # fmt: skip
    for i, (w, b) in enumerate(zip(net.coefs_, net.intercepts_, strict=True)):
        arrays[f"w{i}"] = w.astype(np.float16)
        arrays[f"b{i}"] = b.astype(np.float32)
    return arrays


def _save_speech(path: Path, utterances) -> None:
    arrays: dict = {"count": len(utterances)}
    for i, (x, rate, phones, label) in enumerate(utterances):
        arrays[f"x{i}"] = np.round(x * 32767).astype(np.int16)
        arrays[f"r{i}"] = rate
        arrays[f"p{i}"] = np.array([(p.start, p.end, p.viseme or 0) for p in phones], float)
        arrays[f"l{i}"] = label
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **arrays)


def _load_speech(path: Path) -> list:
    from vtts.speech.phonemes import Phone

    out = []
    with np.load(path) as z:
        for i in range(int(z["count"])):
            phones = [Phone(a, b, "", int(v)) for a, b, v in z[f"p{i}"]]
            out.append((z[f"x{i}"].astype(np.float32) / 32768, int(z[f"r{i}"]), phones,
                        str(z[f"l{i}"])))  # fmt: skip
    return out


def _write(path: Path, arrays: dict) -> None:
    tmp = path.with_name(path.name + ".part.npz")
    np.savez_compressed(tmp, **arrays)
    tmp.replace(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "vtts" / "data" / vc.WEIGHTS)
    ap.add_argument("--cache", type=Path, default=None,
                    help="keep the speech here (a second run trains without speaking)")  # fmt: skip
    ap.add_argument("--sentences", type=int, default=600)
    ap.add_argument("--snapshot", type=Path, default=None,
                    help="write the weights after each pass here too ({} is the pass)")  # fmt: skip
    args = ap.parse_args()
    t0 = time.perf_counter()
    utterances = []
    sources = [("speech", speak_all), ("piper", speak_piper)]
    if FESTIVAL_ALL:
        sources.append(("festival-more", speak_festival_more))
    for name, speak in sources:
        cached = args.cache / f"{name}-{args.sentences}.npz" if args.cache else None
        if cached is not None and cached.exists():
            utterances += _load_speech(cached)
        else:
            spoken = speak(sentences(args.sentences))
            if cached is not None:
                _save_speech(cached, spoken)
            utterances += spoken
    feats, truths = dataset(utterances)
    print(f"  features ready after {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    keep = args.snapshot
    arrays = train(feats, truths, snapshot=(lambda a, k: _write(Path(str(keep).format(k)), a))
                   if keep else None)  # fmt: skip
    _write(args.out, arrays)
    print(f"wrote {args.out} ({args.out.stat().st_size} bytes) after "
          f"{time.perf_counter() - t0:.0f} s")  # fmt: skip


if __name__ == "__main__":
    main()
