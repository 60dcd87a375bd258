"""Lip-sync from the voice alone (issue 43): phones recognized by PocketSphinx, the energy's mouth
shapes where none is, the live recognizer and ``vtts say --audio REC`` without a text, with bad
input of every kind (silence, noise, music, clipping, rates, channels, NaN, a 2-hour file)."""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from vtts.errors import SpeechError
from vtts.speech.energy import FRAME_S, EnergyFrames, Levels, energy_frames, energy_visemes
from vtts.speech.recognize import (
    CLOSURE_FRAMES,
    LiveRecognizer,
    RecognizerOptions,
    StreamResampler,
    _cuts,
    merge_energy,
    phone_viseme,
    recognize,
    split_closures,
)

from ..in_process import vtts
from ..scripts import load_script

HEAD = Path(__file__).parents[1] / "data" / "models" / "head.wrl"
TEXT = "Bob bought a map of Boston, and my mother made some plum jam."


@pytest.fixture(scope="module")
def speech():
    """festival's speech of :data:`TEXT` (its HTS voice: a recognizer is no judge of espeak-ng's
    speech, see docs/speech.md): ``(samples float32, rate, phones)``."""
    from vtts.speech.festival import synthesize

    sp = synthesize(TEXT)
    return sp.audio.astype(np.float32) / 32768, int(sp.rate), list(sp.phonemes)


@pytest.fixture(scope="module")
def recognized(speech):
    x, rate, _ = speech
    return recognize(x, rate)


def _truth(phones, n: int) -> np.ndarray:
    out = np.zeros(n, np.int8)
    mids = (np.arange(n) + 0.5) * FRAME_S
    for p in phones:
        a, b = np.searchsorted(mids, [p.start, p.end])
        out[a:b] = p.viseme
    return out


def _tones(rate: int = 16000) -> np.ndarray:
    """Two seconds of music: notes of a scale with attacks and decays, chords of harmonics."""
    t = np.arange(int(0.25 * rate)) / rate
    notes = []
    for f in (262, 294, 330, 349, 392, 440, 494, 523):
        env = np.exp(-4 * t) * np.minimum(t / 0.01, 1)
        notes.append(env * sum(np.sin(2 * np.pi * f * k * t) / k for k in (1, 2, 3)))
    return (0.3 * np.concatenate(notes)).astype(np.float32)


def test_phones_cover_the_audio_and_agree_with_the_truth_better_than_energy(speech, recognized):
    x, rate, phones = speech
    rec = recognized
    assert rec.phones[0].start == 0 and rec.phones[-1].end == pytest.approx(len(x) / rate)
    for a, b in zip(rec.phones, rec.phones[1:], strict=False):
        assert a.end == pytest.approx(b.start) and a.start < a.end
    assert all(0 <= p.viseme <= 14 for p in rec.phones)
    n = rec.visemes.size
    truth = _truth(phones, n)
    energy = energy_visemes(energy_frames(x, rate))[:n]
    speaking = truth != 0
    mine = float(np.mean(rec.visemes[speaking] == truth[speaking]))
    assert mine > 0.3 and mine > float(np.mean(energy[speaking] == truth[speaking])) + 0.15
    # most of the audible speech is recognized, not filled in from the energy
    assert rec.recognized > 3 * rec.filled
    assert any(p.viseme == 1 for p in rec.phones)  # lips closed somewhere in "Bob … map …"


HELD_OUT_TEXT = "Put the plums and the bread in the blue paper bag."
#: Bilabials found and frames agreeing: with the classifier 7 of 8 and 87 % (stop 55's ensemble;
#: its network of seed 45 alone 8 of 8 and 88 %, stop 53's network 8 of 8 and 76 %),
#: PocketSphinx alone 1 of 8 and 42 %, stop 53's weights scrambled 2 of 8 and 21 %.
BILABIALS_MIN = 0.75
AGREEMENT_MIN = 0.65


def test_the_classifier_finds_the_closures_of_a_voice_it_never_heard() -> None:
    """espeak-ng's en-us+f3 (a variant kept out of the classifier's training) speaking a
    sentence of the lip-sync bench's held-out part: the lips close at most of its p, b, m, where
    PocketSphinx alone finds few (docs/speech.md) — fails with the classifier off or its weights
    scrambled."""
    from vtts.speech.tts import synthesize

    sp = synthesize(f"<speak>{HELD_OUT_TEXT}</speak>", voice="en-us+f3", rate=140, pitch=70)
    x, rate, phones = sp.audio.astype(np.float32) / 32768, int(sp.rate), list(sp.phonemes)

    def found(rec) -> tuple[float, float]:
        centres = np.array([(p.start + p.end) / 2 for p in rec.phones if p.viseme == 1])
        mids = [(p.start + p.end) / 2 for p in phones if p.viseme == 1]
        near = [centres.size > 0 and np.min(np.abs(centres - c)) <= 1 / 30 + 1e-9 for c in mids]
        truth = _truth(phones, rec.visemes.size)
        return float(np.mean(near)), float(np.mean(rec.visemes == truth))

    bilabials, agreement = found(recognize(x, rate))
    assert bilabials >= BILABIALS_MIN and agreement >= AGREEMENT_MIN, (bilabials, agreement)
    ps_bilabials, ps_agreement = found(recognize(x, rate, RecognizerOptions(classifier=False)))
    assert ps_bilabials < BILABIALS_MIN or ps_agreement < AGREEMENT_MIN


def test_a_closure_over_a_murmur_and_a_silence_is_two_phones() -> None:
    """One bilabial run of 10 frames, a nasal's murmur (-25 dB) then a stop's closure (-45 dB):
    cut where the level steps, the louder part named M, the quieter P|B; a short run, or one
    whose level stays, is left whole; the visemes do not change."""
    vis = np.array([10] * 4 + [1] * 10 + [11] * 4 + [1] * 5 + [1] * 8, np.int8)
    index = np.array([0] * 4 + [1] * 10 + [2] * 4 + [3] * 5 + [4] * 8, np.int32)
    db = np.array([-20.0] * 4 + [-25.0] * 6 + [-45.0] * 4 + [-20.0] * 4 + [-25] * 3 + [-45] * 2
                  + [-30.0] * 8)  # fmt: skip
    names = ["AA", "P|B|M", "EH", "P|B|M", "P|B|M"]
    new_index, new_names = split_closures(vis, index, names, db)
    assert new_names[:5] == ["AA", "M", "EH", "P|B|M", "P|B|M"]
    assert new_names[5:] == ["P|B"] and phone_viseme("P|B") == 1
    assert new_index[4:10].tolist() == [1] * 6 and new_index[10:14].tolist() == [5] * 4
    assert np.array_equal(new_index[14:], index[14:])


def test_a_silent_closure_between_sounds_keeps_the_lips_shut() -> None:
    """A bilabial the classifier hears (p b m 0.9) in silent frames between two vowels — a
    stop's closure, ``b`` of "back" — stays closed, where a phone wholly in silence is
    otherwise a pause; one it does not hear (0.2), one too long for a closure, one with no
    sound before it, and every one without the classifier's probabilities, are pauses."""
    lv = Levels(-10.0, -80.0)  # audible above -45 dB

    def merged(closure_p: float, silent: int = 6, before: int = 5) -> list[int]:
        vis = np.array([0] * 3 + [10] * before + [1] * silent + [11] * 5, np.int8)
        index = np.array([-1] * 3 + [0] * before + [1] * silent + [2] * 5, np.int32)
        loud = np.where(np.isin(vis, (10, 11)), -15.0, -70.0).astype(np.float32)
        frames = EnergyFrames(loud, np.zeros(vis.size, np.float32))
        closure = np.where(vis == 1, closure_p, 0.0).astype(np.float32)
        out, _ = merge_energy(vis, index, frames, lv, fill=False, closure=closure)
        without, _ = merge_energy(vis, index, frames, lv, fill=False)
        assert without[vis == 1].tolist() == [0] * silent
        return out[vis == 1].tolist()

    assert merged(0.9) == [1] * 6
    assert merged(0.2) == [0] * 6
    assert merged(0.9, silent=CLOSURE_FRAMES + 1) == [0] * (CLOSURE_FRAMES + 1)
    assert merged(0.9, before=0) == [0] * 6


def test_silence_is_one_pause_and_noise_no_speech() -> None:
    rate = 16000
    rec = recognize(np.zeros(rate, np.float32), rate)
    assert [(p.phoneme, p.viseme) for p in rec.phones] == [("SIL", 0)]
    rng = np.random.default_rng(0)
    quiet = rng.normal(0, 0.003, rate).astype(np.float32)  # a room's hiss: a still face
    assert all(p.viseme == 0 for p in recognize(quiet, rate).phones)
    loud = rng.normal(0, 0.1, rate).astype(np.float32)  # loud hiss: at most the teeth together
    assert {p.viseme for p in recognize(loud, rate).phones} <= {0, 7}


#: TEXT in white noise at 20 dB SNR: frames agreeing and bilabials found (of 13) with the phone
#: loop left out in noise (stop 56: 0.87 and 11), and with it (stop 55: 0.74 and 8)
NOISY_AGREEMENT_MIN, NOISY_BILABIALS_MIN = 0.8, 10


def test_in_noise_the_classifier_goes_without_the_phone_loop(speech) -> None:
    """Speech in loud white noise: the classifier hears it better with the noise taken out,
    and PocketSphinx's phone loop, which decodes noisy speech poorly, is left out of the
    smoothing — fails with the phone loop's phones as evidence there (stop 55's path)."""
    x, rate, phones = speech
    power = np.mean(x[np.abs(x) > 0.01] ** 2)
    noisy = x + np.random.default_rng(7).normal(0, np.sqrt(power / 100), x.size).astype(np.float32)
    rec = recognize(noisy, rate)
    truth = _truth(phones, rec.visemes.size)
    centres = np.array([(p.start + p.end) / 2 for p in rec.phones if p.viseme == 1])
    bilabials = [(p.start + p.end) / 2 for p in phones if p.viseme == 1]
    found = sum(centres.size > 0 and np.min(np.abs(centres - c)) <= 1 / 30 + 1e-9
                for c in bilabials)  # fmt: skip
    assert len(bilabials) == 13
    assert np.mean(rec.visemes == truth) >= NOISY_AGREEMENT_MIN and found >= NOISY_BILABIALS_MIN


def test_music_moves_the_mouth() -> None:
    """Never a frozen face over audible sound: where nothing is recognized, the energy."""
    x = _tones()
    rec = recognize(x, 16000)
    fr = energy_frames(x, 16000)
    audible = fr.db > fr.db.max() - 30
    assert np.mean(rec.visemes[audible[: rec.visemes.size]] != 0) > 0.8
    off = recognize(x, 16000, RecognizerOptions(fill=False))
    assert off.filled == 0 and rec.filled >= off.filled


def test_clipped_and_nan_samples(speech, recognized) -> None:
    x, rate, _ = speech
    x = x[: int(1.5 * rate)]  # "Bob bought a map of …"
    clipped = np.clip(x * 20, -1, 1)
    rec = recognize(clipped, rate)
    n = rec.visemes.size
    assert np.mean(rec.visemes != 0) > 0.5 * np.mean(recognized.visemes[:n] != 0)
    holed = x.copy()
    holed[::50] = np.nan
    rec = recognize(holed, rate)
    assert all(np.isfinite([p.start for p in rec.phones]))


@pytest.mark.parametrize("rate", [1, 7999])
def test_rates_below_8_khz_are_refused(rate: int) -> None:
    with pytest.raises(SpeechError, match=f"sampled at {rate} Hz; recognizing speech needs"):
        recognize(np.zeros(100, np.float32), rate)
    with pytest.raises(SpeechError, match="at least 8000"):
        LiveRecognizer(rate)


def test_other_weights_for_the_classifier(speech, recognized, tmp_path: Path) -> None:
    """``RecognizerOptions(weights=FILE)`` takes the classifier from ``FILE`` (the lip-sync
    bench's ``VTTS_BENCH_CLASSIFIER``): the package's weights with the first layer's inputs
    scrambled (in each network of the ensemble) recognize other visemes; a missing file is a
    clear error naming it."""
    from vtts.resources import package_data
    from vtts.speech.viseme_classifier import WEIGHTS

    x, rate, _ = speech
    with np.load(package_data(WEIGHTS)) as z:
        arrays = dict(z)
    for key in [k for k in arrays if k == "w0" or k.endswith("_w0")]:  # every network's
        arrays[key] = np.random.default_rng(0).permutation(arrays[key])
    other = tmp_path / "other.npz"
    np.savez(other, **arrays)
    rec = recognize(x, rate, RecognizerOptions(weights=other))
    n = min(rec.visemes.size, recognized.visemes.size)
    assert np.mean(rec.visemes[:n] != recognized.visemes[:n]) > 0.2
    same = recognize(x, rate, RecognizerOptions(weights=package_data(WEIGHTS)))
    assert np.array_equal(same.visemes, recognized.visemes)
    with pytest.raises(SpeechError, match="missing.npz: not a viseme classifier's weights"):
        recognize(x, rate, RecognizerOptions(weights=tmp_path / "missing.npz"))


def test_options_are_checked() -> None:
    with pytest.raises(SpeechError, match="beam must be in"):
        RecognizerOptions(beam=2.0)
    with pytest.raises(SpeechError, match="language_weight"):
        RecognizerOptions(language_weight=0)
    with pytest.raises(SpeechError, match="words must be one of auto, always, never, got 'yes'"):
        RecognizerOptions(words="yes")
    for bad in (0, -1, True, 1.5, "2"):
        with pytest.raises(SpeechError, match="workers must be a whole number of at least 1"):
            RecognizerOptions(workers=bad)


#: pocketsphinx-testdata's real read speech (scripts/setup.sh installs it)
REAL = Path("/usr/share/pocketsphinx/test/data")


def _real(name: str) -> tuple[np.ndarray, np.ndarray]:
    """A recording of pocketsphinx-testdata: ``(float32 samples at 16 kHz, int16 samples)``."""
    path = REAL / name
    assert path.is_file(), f"{path} is missing: scripts/setup.sh installs pocketsphinx-testdata"
    pcm = sf.read(path, dtype="int16")[0] if path.suffix == ".wav" else np.fromfile(path, np.int16)
    return pcm.astype(np.float32) / 32768, pcm


def test_words_where_the_classifier_is_unsure() -> None:
    """Real read speech (a recording of the lip-sync bench's tuning part): the classifier is
    unsure of it, so its words are recognized too and their phones, aligned, lead the
    smoothing — against the transcript's forced alignment (the bench's truth) the frames agree
    far more than without the words (85 against 65 % over the bench's tuning part). Fails with
    the words off, or their phones ignored."""
    bench = load_script("bench/bench_lipsync_audio.py")
    x, pcm = _real("librivox/sense_and_sensibility_01_austen_64kb-0930.wav")
    truth = _truth(bench._forced(pcm, "he might even have been made amiable himself"), 1000)
    agree = {}
    for mode in ("auto", "never"):
        rec = recognize(x, 16000, RecognizerOptions(words=mode))
        n = rec.visemes.size
        agree[mode] = float(np.mean(rec.visemes == truth[:n]))
        if mode == "auto":
            labels = [w.label for w in rec.words]
            assert {"might", "made", "amiable"} <= set(labels), labels
            starts = [w.start for w in rec.words]
            assert starts == sorted(starts) and all(
                0 <= w.start < w.end <= rec.duration for w in rec.words
            )
        else:
            assert rec.words == []
    assert agree["auto"] >= 0.75 and agree["auto"] > agree["never"] + 0.1, agree


def test_words_auto_always_and_never(speech, recognized) -> None:
    """A speech engine's clean voice keeps the phones alone (``auto``: the classifier is sure
    of it), ``always`` recognizes its words too; a real voice outside the bench, whose
    entropy (0.48 nats) lies between the two thresholds, gets its words with ``auto`` (not
    with ``WORDS_ENTROPY_IN_NOISE`` for every piece) and none with ``never``."""
    x, rate, _ = speech
    assert recognized.words == []
    assert len(recognize(x, rate, RecognizerOptions(words="always")).words) >= 8
    real, _ = _real("goforward.raw")
    for mode in ("auto", "always"):
        rec = recognize(real, 16000, RecognizerOptions(words=mode))
        assert [w.label for w in rec.words] == ["go", "forward", "ten", "meters"]
    assert recognize(real, 16000, RecognizerOptions(words="never")).words == []


def test_long_audio_in_pieces_cut_at_quiet_frames_with_progress() -> None:
    db = np.zeros(9500)
    db[2400] = db[4900] = -90  # the quietest frames around the ends of the four even shares
    # the third share has no quieter frame: it is cut where its 5 s begin (7125 - 250)
    assert _cuts(db, 3000, 500) == [2400, 4900, 6875]
    # for two processes, an even number of pieces where each is long enough, else as few
    assert len(_cuts(db[:6000], 3000, 500)) + 1 == 3
    assert len(_cuts(db[:6000], 3000, 500, least=1000)) + 1 == 4
    assert len(_cuts(db[:6000], 3000, 500, least=2000)) + 1 == 3
    assert len(_cuts(db[:2500], 3000, 500, least=1000)) + 1 == 2
    assert _cuts(db[:1500], 3000, 500, least=1000) == []
    seen = []
    recognize(np.zeros(65 * 8000, np.float32), 8000, progress=lambda d, t: seen.append((d, t)))
    assert len(seen) == 4 and seen[-1] == (65.0, 65.0)  # an even number of pieces
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)


def test_a_one_piece_recording_is_cut_for_its_word_search_near_the_middle() -> None:
    """The cut of a one-piece recording's word search: in the middle of the longest quiet run
    of the eighth of its frames around the middle (not one further off, however long), else
    at the quietest of those frames."""
    from vtts.speech.recognize import _half

    db = np.linspace(-20.0, -30.0, 800)
    quiet = np.zeros(800, bool)
    assert _half(db, quiet) == 449  # no quiet frame: the quietest, at the window's end
    quiet[100:300] = True  # long, but far from the middle
    quiet[380:384] = quiet[410:420] = True
    assert _half(db, quiet) == 415


def test_a_one_piece_recording_has_its_word_search_in_two_halves(monkeypatch) -> None:
    """A recording of one piece and 8 s or more (two of ``HALF_S``) has its words searched
    for in two halves, each hearing ``CONTEXT_FRAMES`` of the other, the second in a forked
    worker (its CPU time among this process's children); what is found is what one process
    finds, frame for frame and word for word, each word once, in order. Under 8 s, one
    search."""
    import resource

    from vtts.speech import recognize as module

    x = np.concatenate([_real("librivox/sense_and_sensibility_01_austen_64kb-0870.wav")[0],
                        _real("goforward.raw")[0]])  # fmt: skip
    n = len(x) // 160
    spans = []
    words = module._Pieces._words
    monkeypatch.setattr(module._Pieces, "_words", lambda self, pcm, a, b: (
        spans.append((a, b)), words(self, pcm, a, b))[1])  # fmt: skip
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime
    from vtts.speech.viseme_classifier import VisemeClassifier

    fork, judge, events = os.fork, VisemeClassifier.warped_log_posteriors, []
    monkeypatch.setattr(os, "fork", lambda: (events.append("fork"), fork())[1])
    monkeypatch.setattr(VisemeClassifier, "warped_log_posteriors",
                        lambda self, x: (events.append("classify"), judge(self, x))[1])  # fmt: skip
    two = recognize(x, 16000, RecognizerOptions(workers=2))
    assert resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime - before > 0.2
    assert events == ["fork", "classify"]  # the second half searched while this one classifies
    c = module.CONTEXT_FRAMES
    assert len(spans) == 1  # the worker's half is not seen here
    ((a, b),) = spans
    assert a == 0 and abs(b - c - n // 2) <= n // 16
    spans.clear()
    alone = recognize(x, 16000, RecognizerOptions(workers=1))
    assert spans[0] == (0, b) and spans[1][0] == b - 2 * c and abs(spans[1][1] - n) <= 1
    assert np.array_equal(two.visemes, alone.visemes)
    assert two.phones == alone.phones and two.words == alone.words
    labels = [w.label for w in two.words]
    assert labels[:4] == ["and", "mr", "john", "dashwood"]
    assert labels[-4:] == ["go", "forward", "ten", "meters"]
    assert all(u.end <= v.start for u, v in zip(two.words, two.words[1:], strict=False))
    spans.clear()
    recognize(x[: 7 * 16000], 16000, RecognizerOptions(workers=2))
    assert spans == [(0, 700)]


def test_the_second_half_is_searched_while_the_piece_is_classified(speech, monkeypatch) -> None:
    """The worker of a one-piece recording's second half is forked before the classifier
    judges the piece, so that its search runs meanwhile (with the words of real speech, the
    test above); where the classifier then wants no words (a speech engine's clean voice) the
    worker is ended, and the phones are one process's; with ``words="never"`` none is
    forked."""
    from vtts.speech import recognize as module
    from vtts.speech.viseme_classifier import VisemeClassifier

    events: list[str] = []
    fork, judge, cancel = os.fork, VisemeClassifier.warped_log_posteriors, module._Workers.cancel
    monkeypatch.setattr(os, "fork", lambda: (events.append("fork"), fork())[1])
    monkeypatch.setattr(VisemeClassifier, "warped_log_posteriors",
                        lambda self, x: (events.append("classify"), judge(self, x))[1])  # fmt: skip
    monkeypatch.setattr(module._Workers, "cancel",
                        lambda self: (events.append("cancel"), cancel(self))[1])  # fmt: skip
    x, rate, _ = speech
    x = np.concatenate([x, x, x])  # over 8 s: festival's voice, which the classifier is sure of
    two = recognize(x, rate, RecognizerOptions(workers=2))
    assert events == ["fork", "classify", "cancel"] and two.words == []
    events.clear()
    alone = recognize(x, rate, RecognizerOptions(workers=1))
    assert "fork" not in events
    assert np.array_equal(two.visemes, alone.visemes) and two.phones == alone.phones
    events.clear()
    recognize(x, rate, RecognizerOptions(workers=2, words="never"))
    assert "fork" not in events and "classify" in events


@pytest.fixture
def four_pieces(monkeypatch):
    """Two real recordings one after the other, 6.1 s, cut into four pieces (pieces of at
    most 3 s for the test, of at least 1 s for the workers): ``(float32 samples at 16 kHz,
    what recognize found in one process)``."""
    from vtts.speech import recognize as module

    monkeypatch.setattr(module, "PIECE_S", 3.0)
    monkeypatch.setattr(module, "CUT_WINDOW_S", 1.0)
    monkeypatch.setattr(module, "MIN_PIECE_S", 1.0)
    x = np.concatenate([_real("librivox/sense_and_sensibility_01_austen_64kb-0930.wav")[0],
                        _real("goforward.raw")[0]])  # fmt: skip
    return x, recognize(x, 16000, RecognizerOptions(workers=1))


def test_pieces_in_two_processes(four_pieces) -> None:
    """With two workers, every other piece is decoded in a second process (its CPU time
    shows among this process's children), and what is found is what one process finds, frame
    for frame and word for word: each piece's decoders start anew."""
    import resource

    from vtts.speech import recognize as module

    x, alone = four_pieces
    least = 2 * module.MIN_PIECE_S  # two pieces of MIN_PIECE_S (1 s in this test)
    assert module.workers(RecognizerOptions(), least - 0.1) == 1
    assert module.workers(RecognizerOptions(workers=3), 1.0) == 3
    assert module.workers(RecognizerOptions(), least) == min(2, len(os.sched_getaffinity(0)))
    seen = []
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime
    two = recognize(x, 16000, RecognizerOptions(workers=2), progress=lambda d, t: seen.append(d))
    assert resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime - before > 0.2
    assert len(seen) == 4 and seen == sorted(seen) and seen[-1] == len(x) / 16000
    assert np.array_equal(two.visemes, alone.visemes)
    assert two.phones == alone.phones and two.words == alone.words
    assert {"go", "forward"} <= {w.label for w in two.words if w.start >= 3.3}


def test_a_worker_that_cannot_start_or_dies_leaves_its_pieces_here(four_pieces, monkeypatch):
    """No worker process (the fork failed) or one that died: this process decodes the
    worker's pieces too, and finds what it finds with the worker."""
    from vtts.speech import recognize as module

    x, alone = four_pieces

    def cannot(*args):
        raise OSError(11, "Resource temporarily unavailable")

    with monkeypatch.context() as m:
        m.setattr(module.os, "fork", cannot)
        rec = recognize(x, 16000, RecognizerOptions(workers=2))
    assert np.array_equal(rec.visemes, alone.visemes) and rec.words == alone.words
    options = RecognizerOptions()
    jobs = [(x[a:b], np.ones((b - a) // 160, bool)) for a, b in ((0, 48000), (48000, 97000))]
    found = {}
    for dies in (False, True):
        with module._Workers(2, module._Pieces(options, True, True).piece, jobs) as pool:
            if dies:
                proc = pool._links[0][0]
                proc.kill()
                proc.wait()
            found[dies] = list(pool.results())
    assert [f.names for f in found[True]] == [f.names for f in found[False]]
    assert [f.words for f in found[True]] == [f.words for f in found[False]]
    assert {"go", "forward"} <= {w for w, _, _ in found[True][1].words}


def test_a_forked_worker_never_returns_into_its_parent(four_pieces, monkeypatch, tmp_path):
    """A worker is forked from the recognizing process: whatever it raises — even what is not
    an ``Exception`` — it ends there (``os._exit``), and never goes on with its parent's code;
    its parent decodes its pieces. Recognizing in a thread that is not the main one forks too."""
    import threading

    from vtts.speech import recognize as module

    x, alone = four_pieces
    parent = os.getpid()

    def dies(link, pieces, jobs):
        raise KeyboardInterrupt

    escaped = tmp_path / "escaped"
    with monkeypatch.context() as m:
        m.setattr(module, "_serve", dies)
        try:
            rec = recognize(x, 16000, RecognizerOptions(workers=2))
        finally:
            if os.getpid() != parent:  # only a worker that came back into this test
                escaped.write_text(str(os.getpid()))
                os._exit(0)
    assert not escaped.exists()
    assert np.array_equal(rec.visemes, alone.visemes) and rec.words == alone.words
    found = []
    thread = threading.Thread(
        target=lambda: found.append(recognize(x, 16000, RecognizerOptions(workers=2)))
    )
    thread.start()
    thread.join(120)
    assert found and np.array_equal(found[0].visemes, alone.visemes)


def test_a_forked_worker_ends_on_the_signals_its_parent_handles_and_ignores_the_others(
    four_pieces, monkeypatch, tmp_path
) -> None:
    """The parent's signal handlers are not the worker's: where the parent handles a signal
    (Ctrl-C's KeyboardInterrupt, a CLI's SIGTERM handler) the worker ends on it; where the
    parent ignores one (started with ``nohup``, or in the background of a script), so does
    the worker."""
    import signal

    from vtts.speech import recognize as module

    x, alone = four_pieces
    seen = tmp_path / "signals"

    def report(link, pieces, jobs):
        seen.write_text(" ".join(str(signal.getsignal(s)) for s in (signal.SIGTERM, signal.SIGHUP)))
        raise RuntimeError("reported")

    with monkeypatch.context() as m:
        m.setattr(module, "_serve", report)
        old = (
            signal.signal(signal.SIGTERM, lambda *a: None),
            signal.signal(signal.SIGHUP, signal.SIG_IGN),
        )
        try:
            rec = recognize(x, 16000, RecognizerOptions(workers=2))
        finally:
            signal.signal(signal.SIGTERM, old[0])
            signal.signal(signal.SIGHUP, old[1])
    assert seen.read_text() == f"{signal.SIG_DFL} {signal.SIG_IGN}"
    assert np.array_equal(rec.visemes, alone.visemes)  # its pieces decoded here


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_a_forked_worker_dies_with_the_thread_that_forked_it(tmp_path) -> None:
    """A command ended by SIGTERM or SIGKILL does not wait for the thread recognizing its
    speech: the worker that thread forked is killed when it ends, not left decoding as an
    orphan (here the thread ends once the worker has begun its job, and sleeps in it)."""
    import threading
    import time

    from vtts.speech import recognize as module

    pools = []
    begun = tmp_path / "begun"

    def job(i: int) -> None:
        begun.touch()
        time.sleep(30)

    def fork_and_go() -> None:  # the thread ends with its worker still busy
        pools.append(module._Workers(2, job, [(0,), (1,)]).__enter__())
        end = time.monotonic() + 10
        while not begun.exists() and time.monotonic() < end:
            time.sleep(0.01)

    thread = threading.Thread(target=fork_and_go)
    thread.start()
    thread.join()
    child = pools[0]._links[0][0]
    try:
        end = time.monotonic() + 10
        while child.poll() is None and time.monotonic() < end:
            time.sleep(0.02)
        assert child.returncode == -signal.SIGKILL
    finally:
        child.kill()
        child.wait()


def test_the_word_search_loads_the_language_models_words_and_finds_the_same(
    tmp_path, monkeypatch
) -> None:
    """The word decoder's dictionary is the wheel's cut to its language model's words (their
    other pronunciations kept), made once in the user's cache; a decoder with the whole
    dictionary finds the same words and phones. With the cache off, or a file there that is
    not the user's own, the whole dictionary (an untrusted file is made anew, never read)."""
    import stat

    from vtts.speech import recognize as module

    monkeypatch.setenv("VTTS_CACHE_DIR", str(tmp_path / "cache"))
    hmm, _ = module.model_paths()
    root = os.path.dirname(hmm)
    whole, lm = os.path.join(root, "cmudict-en-us.dict"), os.path.join(root, "en-us.lm.bin")
    cut = module.word_dictionary(whole, lm)
    assert Path(cut).parent == tmp_path / "cache" / "speech"
    entries = {line.split(maxsplit=1)[0] for line in Path(cut).read_text().splitlines()}
    assert 70_000 < len(entries) < 90_000
    assert {"been", "been(2)", "forward", "meters"} <= entries
    assert entries < {line.split(maxsplit=1)[0] for line in open(whole) if line.strip()}
    assert module.word_dictionary(whole, lm) == cut  # made once
    bad = tmp_path / "bad.lm"
    bad.write_bytes(b"not a language model")
    for lm_file in (bad, tmp_path / "missing.lm"):  # the decoder reports what is wrong
        assert module.word_dictionary(whole, str(lm_file)) == whole
    go, _ = _real("goforward.raw")
    other, _ = _real("librivox/sense_and_sensibility_01_austen_64kb-0930.wav")
    decoders = [module.make_word_decoder(RecognizerOptions())]
    monkeypatch.setenv("VTTS_CACHE_DIR", "")
    assert module.word_dictionary(whole, lm) == whole
    decoders.append(module.make_word_decoder(RecognizerOptions()))
    for x in (go, other):
        pcm = np.round(x * 32767).astype(np.int16).tobytes()
        found = []
        for d in decoders:
            d.reinit_feat()
            found.append(module.decode_words(d, pcm))
        assert found[0] == found[1] and found[0][0]
    monkeypatch.setenv("VTTS_CACHE_DIR", str(tmp_path / "cache"))
    Path(cut).write_text("go G OW\n")
    os.chmod(cut, 0o666)  # writable by others: planted, not trusted
    assert module.word_dictionary(whole, lm) == cut
    assert not os.stat(cut).st_mode & stat.S_IWOTH
    assert len(Path(cut).read_text().splitlines()) > 70_000


def test_a_damaged_pocketsphinx_installation_is_named_without_a_traceback(
    tmp_path, monkeypatch, capfd
) -> None:
    """A file of the wheel that PocketSphinx cannot read (a damaged installation): a
    SpeechError naming it and how to mend it, none of PocketSphinx's own complaints on stderr;
    ``vtts say --audio`` says so in one line. The phone loop's language model too, which
    PocketSphinx would silently go without; the acoustic model, named with the dictionary."""
    from vtts.speech import recognize as module

    hmm, phone_lm = module.model_paths()
    fake = tmp_path / "en-us"
    fake.mkdir()
    (fake / "en-us").symlink_to(hmm)
    (fake / "en-us-phone.lm.bin").symlink_to(phone_lm)
    (fake / "cmudict-en-us.dict").symlink_to(Path(hmm).parent / "cmudict-en-us.dict")
    (fake / "en-us.lm.bin").write_bytes(b"not a language model")
    paths = (str(fake / "en-us"), str(fake / "en-us-phone.lm.bin"))
    monkeypatch.setattr(module, "model_paths", lambda: paths)
    monkeypatch.setenv("VTTS_CACHE_DIR", str(tmp_path / "cache"))
    module.release_decoders()  # none of those a recognition before kept
    mend = "reinstall it: pip install --force-reinstall pocketsphinx==5.1.1"
    with pytest.raises(SpeechError) as e:
        module.make_word_decoder(RecognizerOptions())
    assert (
        str(e.value)
        == f"PocketSphinx cannot read its language model {fake / 'en-us.lm.bin'}: {mend}"
    )
    x, _ = _real("goforward.raw")
    wav = tmp_path / "go.wav"
    sf.write(wav, x, 16000)
    r = vtts("say", "--audio", wav, "--words", "always", "--model", HEAD, "--timings-out",
             tmp_path / "t.tsv")  # fmt: skip
    assert r.returncode == 1 and f"{fake / 'en-us.lm.bin'}: {mend}" in r.stderr, r.stderr
    assert not (tmp_path / "t.tsv").exists()
    (fake / "en-us-phone.lm.bin").unlink()
    (fake / "en-us-phone.lm.bin").write_bytes(b"not a phone model")
    with pytest.raises(SpeechError, match="cannot read its language model .*en-us-phone.lm.bin"):
        module.make_decoder(RecognizerOptions())
    (fake / "en-us-phone.lm.bin").unlink()
    (fake / "en-us-phone.lm.bin").symlink_to(phone_lm)
    (fake / "en-us.lm.bin").unlink()
    (fake / "en-us.lm.bin").symlink_to(Path(hmm).parent / "en-us.lm.bin")
    (fake / "en-us").unlink()
    (fake / "en-us").mkdir()  # no acoustic model in it
    with pytest.raises(SpeechError) as e:
        module.make_word_decoder(RecognizerOptions())
    assert str(e.value).startswith(f"PocketSphinx cannot load {fake / 'en-us'} and ")
    assert str(e.value).endswith(f".dict: {mend}")
    assert capfd.readouterr().err == ""


def test_decoders_kept_between_recognitions_find_what_new_ones_do(monkeypatch) -> None:
    """A recognition keeps its decoders for the next one in the process, which uses them
    (none is made: making one fails here) and finds what new ones find, frame for frame and
    word for word, whatever was recognized between; two recognitions at once each have their
    own; :func:`release_decoders` drops them (the next recognition makes new ones)."""
    import threading

    from vtts.speech import recognize as module

    module.release_decoders()
    go, _ = _real("goforward.raw")
    other, _ = _real("librivox/sense_and_sensibility_01_austen_64kb-0930.wav")
    first = recognize(go, 16000)
    assert ("words", True) in module._KEPT
    recognize(other, 16000, RecognizerOptions(words="never"))  # the phone loop's decoder too

    def no_new(options):
        raise AssertionError("a decoder was made, not taken from those kept")

    with monkeypatch.context() as m:
        m.setattr(module, "make_word_decoder", no_new)
        m.setattr(module, "make_decoder", no_new)
        again = recognize(go, 16000)
        assert np.array_equal(again.visemes, first.visemes)
        assert again.phones == first.phones and again.words == first.words
        assert recognize(other, 16000, RecognizerOptions(words="never")).phones
    found = [None, None]

    def run(i: int) -> None:
        found[i] = recognize(go, 16000)

    threads = [threading.Thread(target=run, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for rec in found:
        assert np.array_equal(rec.visemes, first.visemes) and rec.words == first.words
    assert module.release_decoders() == 2 and module._KEPT == {}
    with monkeypatch.context() as m:
        m.setattr(module, "make_word_decoder", no_new)
        with pytest.raises(AssertionError, match="was made"):
            recognize(go, 16000)


def test_stream_resampler_has_no_seams() -> None:
    x = np.random.default_rng(1).normal(0, 0.1, 44100).astype(np.float32)
    whole = StreamResampler(44100, 16000)(x)
    r = StreamResampler(44100, 16000)
    cuts = [0, 1, 2, 441, 1000, 1001, 30000, 44100]
    parts = np.concatenate([r(x[a:b]) for a, b in zip(cuts, cuts[1:], strict=False)])
    assert parts.size == whole.size and np.allclose(parts, whole, atol=1e-6)
    assert abs(whole.size - 16000) <= 1


def test_live_gives_every_frame_once_and_follows_the_file(speech, recognized) -> None:
    x, rate, phones = speech
    pcm = np.round(x * 32767).astype(np.int16)
    live = LiveRecognizer(rate)
    step = rate // 50
    out = [live.feed(pcm[a : a + step]) for a in range(0, len(pcm), step)]
    # (a chunk of nothing and one of a single sample are fine)
    out += [live.feed(pcm[:0]), live.feed(pcm[:1]), live.finish()]
    vis = np.concatenate(out)
    n = int(np.ceil((len(pcm) + 1) / rate / FRAME_S))
    assert abs(vis.size - n) <= 1 and live.frames_out == vis.size
    truth = _truth(phones, vis.size)
    assert np.mean(vis == truth) > 0.3
    assert np.mean((vis != 0) == (truth != 0)) > 0.8  # the mouth moves where the voice speaks


# ---- vtts say --audio REC, vtts play --audio - --------------------------------------------------


@pytest.fixture(scope="module")
def wav(speech, tmp_path_factory) -> Path:
    x, rate, _ = speech
    path = tmp_path_factory.mktemp("rec") / "rec.wav"
    sf.write(path, x, rate)
    return path


def test_say_without_text_writes_the_recognized_timings(wav: Path, tmp_path: Path) -> None:
    tsv = tmp_path / "t.tsv"
    r = vtts("say", "--audio", wav, "--model", HEAD, "--timings-out", tsv, "--fap-out",
             tmp_path / "f.fap", "--quiet")  # fmt: skip
    assert r.returncode == 0, r.stderr
    rows = [ln.split("\t") for ln in tsv.read_text().splitlines()[1:]]
    assert rows and all(row[0] == "phone" for row in rows)  # phones, no words
    # a closure, named by PocketSphinx's phone where it agrees, else by the classifier's class
    assert {"B", "M", "P", "P|B|M"} & {row[3] for row in rows if row[4] == "1"}
    # the table reads back as a phoneme file, visemes as written
    r = vtts("say", "x", "--phonemes", tsv, "--audio", wav, "--model", HEAD, "--timings-out",
             tmp_path / "again.tsv", "--quiet")  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "again.tsv").read_text().count("\tphone") == 0
    assert [r[4] for r in rows] == [
        ln.split("\t")[4] for ln in (tmp_path / "again.tsv").read_text().splitlines()[1:]
    ]


def test_say_without_text_writes_the_recognized_words(tmp_path: Path) -> None:
    """``--words always`` writes the recognized words to ``--timings-out`` (each before its
    phones); ``--words never`` only phones; ``--words`` with a text is refused."""
    x, _ = _real("goforward.raw")
    wav = tmp_path / "go.wav"
    sf.write(wav, x, 16000)
    for mode, expected in (("always", ["go", "forward", "ten", "meters"]), ("never", [])):
        tsv = tmp_path / f"{mode}.tsv"
        r = vtts("say", "--audio", wav, "--words", mode, "--model", HEAD, "--timings-out", tsv,
                 "--quiet")  # fmt: skip
        assert r.returncode == 0, r.stderr
        rows = [ln.split("\t") for ln in tsv.read_text().splitlines()[1:]]
        assert [row[3] for row in rows if row[0] == "word"] == expected
    r = vtts("say", "go", "--audio", wav, "--words", "never", "--model", HEAD, "--timings-out",
             tmp_path / "t.tsv")  # fmt: skip
    assert r.returncode == 1 and "--words never applies to a recording without its text" in (
        r.stderr
    ), r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "t.tsv").exists()
    r = vtts("say", "--audio", wav, "--words", "often", "--model", HEAD, "--timings-out",
             tmp_path / "t.tsv")  # fmt: skip
    assert r.returncode == 2 and "invalid choice: 'often'" in r.stderr


def test_the_commands_word_modes_are_the_recognizers() -> None:
    """``vtts say --words`` offers :data:`WORD_MODES`, which its parser spells out (so that
    parsing a command line does not import the recognizer)."""
    import argparse

    from vtts.cli.say import add_parser
    from vtts.speech.recognize import WORD_MODES

    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers())
    say = parser._subparsers._group_actions[0].choices["say"]
    (words,) = [a for a in say._actions if "--words" in a.option_strings]
    assert tuple(words.choices) == WORD_MODES and words.default == WORD_MODES[0]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--voice", "de"], "--voice do not apply to a recording without its text"),
        (["--rate", "120"], "--rate do not apply"),
        (["--engine", "festival"], "--engine festival do not apply"),
    ],
)
def test_say_without_text_refuses_what_shapes_speech(wav, tmp_path, args, message) -> None:
    r = vtts("say", "--audio", wav, "--model", HEAD, "--timings-out", tmp_path / "t.tsv", *args)
    assert r.returncode == 1 and message in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "t.tsv").exists()


def _bad(tmp_path: Path, name: str, data: np.ndarray, rate: int, **kw) -> Path:
    path = tmp_path / name
    sf.write(path, data, rate, **kw)
    return path


@pytest.mark.parametrize("case", ["1 Hz", "384 kHz", "2 hours"])
def test_say_without_text_bad_recordings_are_clear_errors(tmp_path: Path, case: str) -> None:
    if case == "1 Hz":
        path, message = _bad(tmp_path, "a.wav", np.zeros(10, np.float32), 1), "sampled at 1 Hz"
    elif case == "384 kHz":
        path, message = _bad(tmp_path, "a.wav", np.zeros(100, np.float32), 384000), "384000 Hz"
    else:  # two hours of silence (a FLAC of 500 Hz: small, quick to write)
        path = tmp_path / "long.flac"
        with sf.SoundFile(path, "w", 500, 1, format="FLAC") as f:
            for _ in range(120):
                f.write(np.zeros(500 * 60, np.int16))
        message = "lasts 7200 s, more than the limit"
    r = vtts("say", "--audio", path, "--model", HEAD, "--timings-out", tmp_path / "t.tsv")
    assert r.returncode == 1 and message in r.stderr and str(path) in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "t.tsv").exists()


def test_say_without_text_six_channels_nan_and_music(speech, tmp_path: Path) -> None:
    x, rate, _ = speech
    six = np.stack([x, -x, x, 0 * x, x, x], axis=1)
    six[::100, 2] = np.nan
    path = _bad(tmp_path, "six.wav", six, rate, subtype="FLOAT")
    tsv = tmp_path / "t.tsv"
    r = vtts("say", "--audio", path, "--model", HEAD, "--timings-out", tsv, "--quiet")
    assert r.returncode == 0, r.stderr
    assert tsv.read_text().count("\t1\n") >= 1  # a bilabial
    music = _bad(tmp_path, "m.wav", _tones(), 16000)
    r = vtts("say", "--audio", music, "--model", HEAD, "--timings-out", tsv, "--quiet")
    assert r.returncode == 0, r.stderr
    assert "~" in tsv.read_text() or "\t10\n" in tsv.read_text()


def test_play_follows_a_voice_on_stdin_that_stops_mid_sample(speech, tmp_path: Path) -> None:
    x, rate, _ = speech
    part = np.round(x[: rate // 2] * 32767).astype("<i2").tobytes() + b"\x07"  # half a sample
    r = vtts("play", "--audio", "-", "--rate", str(rate), "--model", HEAD, "--size", "64x48",
             "--png-dir", tmp_path / "png", "--quiet", stdin=part)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "ended inside a sample" in r.stderr
    assert len(list((tmp_path / "png").glob("*.png"))) == 15  # 0.5 s at 30 fps
    # half a sample and nothing more: no voice at all (an error, no empty video)
    r = vtts("play", "--audio", "-", "--model", HEAD, "-o", tmp_path / "none.mp4", stdin=b"\x01")
    assert r.returncode == 1 and "no voice came on stdin" in r.stderr, r.stderr
    assert not (tmp_path / "none.mp4").exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (["x.fap", "--audio", "-"], "give no stream"),
        (["--rate", "16000", "-o", "o.mp4"], "give --audio - with it"),
        (["--audio", "-", "--rate", "4000", "-o", "o.mp4"], "within 8000–192000"),
        (["--audio", "-", "--web", "w", "-o", "o.mp4"], "--web need the whole stream"),
        (["-o", "o.mp4"], "give the stream to play"),
    ],
)
def test_play_voice_options(tmp_path: Path, args, message) -> None:
    r = vtts("play", *args, "--model", HEAD, cwd=tmp_path)
    assert r.returncode != 0 and message in r.stderr, r.stderr


def test_pocketsphinx_is_not_imported_by_the_other_commands() -> None:
    """The recognizer's start-up is paid only by a recognition."""
    import subprocess
    import sys

    code = ("import sys, vtts.cli._main, vtts.api.say, vtts.api.play, vtts.utterance\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('pocketsphinx', 'sounddevice') or m == 'vtts.speech.recognize'))")  # fmt: skip
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "[]"
