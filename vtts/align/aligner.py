"""Forced alignment of a transcript to recorded speech, through espeak-ng's synthesis of it.

The method (measured in ``docs/speech.md``, "Lip-sync for recorded speech"):

1. **Reference.** espeak-ng speaks the transcript (the same SSML with one ``<mark/>`` per
   bookmark that ``vtts say`` sends it), which gives its phones, words and marks in its own clock;
   a high voice (median pitch above :data:`HIGH_VOICE_HZ`) is compared with espeak-ng's female
   variant. (Speaking it again at the recording's rate, ``match_rate``, measured no better.)
   Words espeak-ng's dictionary speaks as one (``in the``) are split, so that every word of the
   transcript has a time.
2. **Silence anchoring.** Only the spans from the first to the last speech frame of each are
   warped; the clean reference is raised to the recording's noise floor.
3. **Warping.** MFCC features of both (:mod:`vtts.align.features`) are aligned by dynamic time
   warping in bounded memory (:mod:`vtts.align.dtw`), where a word boundary of the reference may
   rest cheaply on a pause of the recording (silence within :data:`PAUSE_DB` of its quietest
   frames); espeak's own phone times are carried to the recording through the warping path (the
   method of the ``aeneas`` aligner), and a pause the path rested on becomes a pause phone.
4. **Refinement** (:mod:`vtts.align.refine`), for a voice far from espeak-ng's: the reference's
   phones are first put in the phonetic convention (a stop owns its closure, which espeak-ng's
   stop events leave to the phone before; its linking glide is the next vowel's onset); the
   recording's frames under each phone give models of *this* voice's phones; a Viterbi pass of
   the phone sequence over the recording with those models, at a finer frame step and within a
   window around the warped boundaries, moves each boundary to where this voice's spectrum
   changes. The reference is then warped again as this voice would say it (each state of each
   phone its model's mean), and the Viterbi passes run again.
5. **Check.** Each word's warping cost (the mean distance of the frames the path matched) says
   how well the recording and the transcript agree there; runs of words far above a typical
   word are reported as problems naming the words and their time.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from vtts.align.dtw import Pauses, dtw_path
from vtts.align.features import (
    ANALYSIS_RATE,
    MIN_RATE,
    cepstra,
    log_mel,
    median_f0,
)
from vtts.errors import SpeechError
from vtts.speech.audio import resample_in_blocks as resample
from vtts.speech.phonemes import PAUSES, Mark, Phone

#: Frame step of the warping, s.
HOP = 0.010
#: Frame step of the refinement, s.
FINE_HOP = 0.005
#: espeak-ng's default speaking rate, words per minute.
DEFAULT_RATE = 175
#: A frame is speech when its energy is within this many dB of the loud frames (90th percentile).
SPEECH_DB = 30.0
#: ... and this many dB above the quietest frames (the room's noise).
ABOVE_NOISE_DB = 8.0
#: A run of words whose warping cost is this many times a typical word's (the utterance's first
#: quartile), and at least LOCAL_MIN, does not match the recording: between what the words of a
#: right transcript cost and what replaced words cost (docs/speech.md, "Lip-sync for recorded
#: speech").
LOCAL_RATIO = 1.6
LOCAL_MIN = 4.0
#: A single word is reported only above this many times a typical word's cost: another accent
#: says single words differently (docs/speech.md).
SINGLE_RATIO = 3.5
#: Median word cost above which nothing matches: above right transcripts, below noise and tones
#: (docs/speech.md, "Lip-sync for recorded speech").
GLOBAL_COST = 6.1


@dataclass(frozen=True)
class AlignedWord:
    """A word of the transcript in the recording's clock.

    start, end  s (its first phone's start, its last phone's end, pauses left out)
    text        the word as written
    cost        the mean warping cost of its frames (lower is a better match)
    """

    start: float
    end: float
    text: str
    cost: float


@dataclass
class Alignment:
    """What :func:`align` returns.

    phones    every phone of the reference, pauses included, in the recording's clock (s),
              covering it from 0 to its end; ``viseme`` set
    words     the words, in order
    marks     one per ``<mark/>`` of the SSML, in document order, with its aligned time (s)
    rate      the espeak-ng speaking rate the reference was made at, words per minute
    voice     the espeak-ng voice that spoke the reference
    problems  messages about where the alignment breaks down (empty when it holds)
    """

    phones: list[Phone]
    words: list[AlignedWord]
    marks: list[Mark]
    rate: int
    voice: str
    problems: list[str] = field(default_factory=list)


def speech_frames(db: np.ndarray) -> np.ndarray:
    """``(n,)`` bool: frames of ``(n, n_mels)`` log-mel energies that hold speech (within
    :data:`SPEECH_DB` of the loud frames)."""
    energy = 10.0 * np.log10((10.0 ** (db / 10.0)).sum(axis=1))
    # within SPEECH_DB of the loud frames, and clearly above the noise (the quietest frames)
    floor = np.percentile(energy, 5) + ABOVE_NOISE_DB
    return energy > max(
        np.percentile(energy, 90) - SPEECH_DB, min(floor, np.percentile(energy, 50))
    )


#: Median pitch above which the reference is spoken by espeak-ng's female variant, Hz.
HIGH_VOICE_HZ = 160.0
HIGH_VARIANT = "f2"
#: Median word warping cost above which the refinement runs: the recording's voice is far from
#: espeak-ng's, whose warping the refinement improves; a voice near espeak-ng's is warped within
#: a few ms already, and the refinement's 5 ms states and pooled models would only blur it
#: (docs/speech.md, "Lip-sync for recorded speech").
REFINE_ABOVE = 5.0
#: Cost of matching a word boundary of the reference with silence of the recording.
PAUSE_COST = 2.0
#: Shortest pause of the recording that becomes a pause phone where the reference has none, s.
MIN_PAUSE = 0.05
#: A pause reaches down to within this many dB of the recording's quietest frames, not merely
#: far below its loud ones: a weak fricative (f, th) or a vowel's soft onset is quiet but no
#: pause, and a pause taken there moved the word after it late by up to 100 ms (festival's
#: voice).
PAUSE_DB = 3.0
#: Largest ratio between the speech of the transcript (espeak-ng's) and of the recording.
MAX_RATIO = 4.0
#: Frames of pause kept on each side of the speech when warping.
MARGIN = 5


def _speech_span(speech: np.ndarray) -> tuple[int, int]:
    """Frames ``[a, b)`` from the first to the last speech frame, widened by :data:`MARGIN`."""
    idx = np.flatnonzero(speech)
    if len(idx) == 0:
        return 0, len(speech)
    return max(int(idx[0]) - MARGIN, 0), min(int(idx[-1]) + 1 + MARGIN, len(speech))


#: The most words, and characters, of a transcript for each second of its recording: four times
#: what espeak-ng says at its default rate (the alignment refuses a reference speech more than 4
#: times longer than the recording; this refuses it before synthesizing the reference).
MAX_WORDS_PER_S = 4 * 175 / 60
#: (letters of long words: a transcript of one endless "word" is refused too)
MAX_CHARS_PER_S = 8 * MAX_WORDS_PER_S
#: What any recording may carry besides (a short recording of a few long words).
SPARE_WORDS, SPARE_CHARS = 10, 100


def check_transcript(ssml: str, duration: float) -> None:
    """Refuse a transcript far too long for ``duration`` seconds of recording, before its
    reference speech is synthesized (a 100,000-word text would take gigabytes)."""
    text = re.sub(r"<[^>]*>", " ", ssml)
    words, chars = len(text.split()), len("".join(text.split()))
    checks = ((words, "words", MAX_WORDS_PER_S, SPARE_WORDS),
              (chars, "characters", MAX_CHARS_PER_S, SPARE_CHARS))  # fmt: skip
    for count, unit, per_s, spare in checks:
        most = int(per_s * duration) + spare
        if count > most:
            raise SpeechError(
                f"the transcript has {count} {unit} for a recording of {duration:.1f} s: more "
                f"than the {most} that 4 times espeak-ng's rate says in that time; is it the "
                "transcript of this recording?"
            )


def check_rate(rate: int, what: str = "the recording") -> None:
    if not isinstance(rate, int | np.integer) or rate < MIN_RATE:
        raise SpeechError(f"{what} is sampled at {rate} Hz; alignment needs at least {MIN_RATE} Hz")


def align(
    samples: np.ndarray,
    rate: int,
    ssml: str,
    *,
    voice: str = "en-us",
    match_rate: bool = False,
    refine: bool = True,
    baseline: bool = False,
) -> Alignment:
    """Align the SSML transcript ``ssml`` to ``(n,)`` mono ``samples`` at ``rate`` Hz.

    ``voice``: the espeak-ng voice that phonemizes and speaks the reference (its language must be
    the recording's). ``match_rate``: speak the reference again at the recording's rate;
    ``refine``: the Viterbi refinement of :mod:`vtts.align.refine`. ``baseline``: the plain
    method of aeneas instead, for comparison (the voice as given, both signals warped whole, no
    pauses of the recording's own, no refinement). Raises :class:`SpeechError` for a recording
    that is too short, silent, not mono or sampled too low, and a transcript with no phones.
    """
    from vtts.speech.tts import synthesize

    check_rate(int(rate))
    samples = np.asarray(samples)
    check_transcript(ssml, len(samples) / rate)
    if samples.ndim != 1:
        raise SpeechError(f"the recording must be mono samples (n,), got shape {samples.shape}")
    if samples.dtype.kind in "iu":
        samples = samples.astype(np.float32) / np.float32(32768)
    duration = len(samples) / rate
    if duration < 0.1:
        raise SpeechError(f"the recording lasts {duration:.3f} s: too short to align")
    fs = min(ANALYSIS_RATE, int(rate))
    rec = resample(samples, int(rate), fs)
    # one analysis at the refinement's step; every second frame is the warping's
    fine_db = log_mel(rec, fs, FINE_HOP)
    rec_db = fine_db[:: round(HOP / FINE_HOP)]
    if float(np.abs(rec).max(initial=0.0)) < 1e-4:
        raise SpeechError("the recording is silent: there is no speech to align")
    rec_speech = speech_frames(rec_db)

    f0 = median_f0(rec, fs, rec_speech, HOP)  # None: hardly voiced, perhaps not speech
    if "+" not in voice and not baseline and f0 is not None and f0 > HIGH_VOICE_HZ:
        # a high voice is warped better against espeak-ng's female variant (docs/speech.md)
        voice = f"{voice}+{HIGH_VARIANT}"
    ref = synthesize(ssml, voice=voice)
    if not any(p.phoneme not in PAUSES for p in ref.phonemes):
        raise SpeechError("the transcript has nothing to say: no phones to align")
    joined = _split_merged_words(ref, ssml, voice)
    used_rate = DEFAULT_RATE
    if match_rate:
        ref_db = log_mel(
            resample(ref.audio.astype(np.float32) / np.float32(32768), ref.rate, fs), fs, HOP
        )
        ratio = speech_frames(ref_db).sum() / max(rec_speech.sum(), 1)
        wanted = int(np.clip(round(DEFAULT_RATE * ratio), 80, 450))
        if abs(wanted - DEFAULT_RATE) > 0.05 * DEFAULT_RATE:
            used_rate = wanted
            ref = synthesize(ssml, voice=voice, rate=used_rate)
            joined = _split_merged_words(ref, ssml, voice)
    if ref.phonemes[0].phoneme not in PAUSES:
        # the pause before the first word, which the recording may have and espeak may not
        first = ref.phonemes[0]
        ref.phonemes.insert(0, Phone(0.0, 0.0, "_", 0))
        ref.phonemes[1] = Phone(0.0, first.end, first.phoneme, first.viseme, first.ipa)
    ref_db = log_mel(
        resample(ref.audio.astype(np.float32) / np.float32(32768), ref.rate, fs), fs, HOP
    )
    spoken = speech_frames(ref_db).sum() * HOP
    heard = max(rec_speech.sum(), 1) * HOP
    if not 1 / MAX_RATIO <= spoken / heard <= MAX_RATIO:
        raise SpeechError(
            f"the transcript takes {spoken:.1f} s of speech to say and the recording holds "
            f"{heard:.1f} s: more than {MAX_RATIO:g} times apart, it cannot be this recording's "
            "transcript"
        )
    # silence anchoring: only the spans from the first to the last speech frame (and a margin)
    # are warped, so that leading and trailing pauses of any length cost nothing
    ref_span = _speech_span(speech_frames(ref_db)) if not baseline else (0, len(ref_db))
    rec_span = _speech_span(rec_speech) if not baseline else (0, len(rec_db))
    step = round(HOP * fs)
    if not baseline:
        ref_db = _masked(ref_db, rec_db)
    ref_x = cepstra(ref_db[ref_span[0] : ref_span[1]])
    rec_x = cepstra(rec_db[rec_span[0] : rec_span[1]])
    ref_t0, rec_t0 = ref_span[0] * step / fs, rec_span[0] * step / fs
    boundaries = _word_boundaries(ref, ref_t0, len(ref_x), joined) if not baseline else {}
    rows = np.zeros(len(ref_x), bool)
    for b in boundaries:
        rows[max(b - 1, 0) : b + 1] = True
    silent = _pauses(rec_speech, rec_db)[rec_span[0] : rec_span[0] + len(rec_x)]
    silent = np.append(silent, np.ones(len(rec_x) - len(silent), bool))
    pauses = Pauses(rows, silent, PAUSE_COST) if not baseline else None
    path, _ = dtw_path(ref_x, rec_x, pauses=pauses)
    warp = _Warp(path, ref_x, rec_x, ref_t0, rec_t0)
    at = _inserted_pauses(ref, boundaries)
    spans = _pause_spans(boundaries, path, silent, rec_t0)
    inserted = {k: span for k, span in zip(at, spans, strict=True) if span is not None}
    phones = _warped_phones(ref.phonemes, warp, duration, inserted)
    words = _words(ref, phones, warp)
    far = bool(words) and float(np.median([w.cost for w in words])) > REFINE_ABOVE
    if refine and far and not baseline:
        pause_at = (at, boundaries, pauses)
        phones = _refined(ref, rec_x, fine_db, warp, inserted, pause_at, fs, duration)
        words = _words(ref, phones, warp)
    marks = [Mark(m.name, _carry(m.time, ref.phonemes, phones)) for m in ref.marks]
    # the optional pauses at word boundaries that the recording did not make
    phones = [
        p for p in phones if p.duration > 0 or (p.phoneme not in PAUSES and p.phoneme not in LINKS)
    ]
    return Alignment(phones, words, marks, used_rate, voice, _problems(words, f0 is not None))


def _refined(ref, rec_x, fine_db, warp, inserted, pause_at, fs, duration) -> list[Phone]:
    """The warped phones refined against the recording's own voice (:mod:`vtts.align.refine`),
    one per phone of ``ref.phonemes``.

    1. The reference's phones are put in the phonetic convention first: a stop after a sound
       starts at its closure (:func:`_closures`), a linking glide is the next vowel's onset.
    2. One Viterbi pass with models of the recording's phones from those warped phones.
    3. The reference is warped again as the recording's voice speaks it: each state of each phone
       filled with the recording's mean frame of that state (:func:`refine.voice_template`), so
       that the warping compares one voice with itself; then the refinement's passes again."""
    from vtts.align.refine import refine_phones, voice_template

    at, boundaries, pauses = pause_at
    ref_audio = resample(ref.audio.astype(np.float32) / np.float32(32768), ref.rate, fs)
    layout = _linked(_closures(ref.phonemes, log_mel(ref_audio, fs, FINE_HOP, CLOSURE_WINDOW)))
    phones = _warped_phones(layout, warp, duration, inserted)

    def refined(phones: list[Phone], passes: int | None = None) -> list[Phone]:
        return _without_links(
            phones, lambda ps: refine_phones(ps, fine_db, FINE_HOP, duration, passes=passes)
        )

    phones = refined(phones, passes=1)
    template, rec_y = voice_template(
        phones, rec_x, warp.rec_t0, layout, len(warp.target), warp.ref_t0, HOP
    )
    path, _ = dtw_path(template, rec_y, pauses=pauses)
    again = _Warp(path, template, rec_y, warp.ref_t0, warp.rec_t0)
    spans = _pause_spans(boundaries, path, pauses.cols, warp.rec_t0)
    inserted = {k: span for k, span in zip(at, spans, strict=True) if span is not None}
    return refined(_warped_phones(layout, again, duration, inserted))


#: A run of characters of the transcript without spaces or tags (tags blanked out first).
_TOKEN = re.compile(r"\S+")


def _tokens(ssml: str) -> list[tuple[int, int]]:
    """``[start, end)`` in ``ssml`` of each word of the transcript: a run of characters without
    spaces or tags that holds a letter or digit."""
    blank = re.sub(r"<[^>]*>", lambda m: " " * len(m.group()), ssml)
    return [
        (m.start(), m.end())
        for m in _TOKEN.finditer(blank)
        if any(c.isalnum() for c in _unescape(m.group()))
    ]


def _split_merged_words(ref, ssml: str, voice: str) -> set[float]:
    """Give every word of the transcript its own phones in ``ref.words``, in place; returns the
    start times of the words split off (no pause is looked for before them: espeak-ng joins
    only words said without one).

    espeak-ng's dictionary speaks some pairs of function words as one word (``in the`` is
    ``InD@2``, ``of a`` is ``@v@``): their phones all carry the first word's text position, and
    the second word has no word of its own. Each such run is split: the words are spoken again
    apart (a zero-length ``<break/>`` between them keeps the dictionary from joining them) for
    the number of phones of each, and the run's phones are shared out in those proportions, in
    order. A word spoken with no phones at all gets a zero-length word at its place."""
    from vtts.speech.tts import Word, synthesize

    tokens = _tokens(ssml)
    if not ref.words or not tokens:
        return set()
    positions = np.array([w.position for w in ref.words])
    # the word of ref.words each token holds, or -1
    owner = []
    for a, b in tokens:
        k = int(np.searchsorted(positions, a))
        owner.append(k if k < len(positions) and positions[k] < b else -1)
    groups: list[tuple[int, list[int]]] = []  # (index in ref.words, tokens it speaks)
    for t, k in enumerate(owner):
        if k >= 0 and not (groups and groups[-1][0] == k):
            groups.append((k, [t]))
        elif groups:  # no word of its own: spoken with the word before
            groups[-1][1].append(t)
    merged = [(k, ts) for k, ts in groups if len(ts) > 1]
    if not merged:
        return set()
    # each token spoken apart: its number of phones
    pieces = [ssml[tokens[t][0] : tokens[t][1]] for _, ts in merged for t in ts]
    apart = synthesize("<speak>" + ' <break time="0ms"/>'.join(pieces) + "</speak>", voice=voice)
    starts, at = [], len("<speak>")
    for piece in pieces:
        starts.append(at)
        at += len(piece) + len(' <break time="0ms"/>')
    counts = dict.fromkeys(range(len(pieces)), 0)
    phone_starts = np.array([p.start for p in apart.phonemes])
    for w in apart.words:
        i = int(np.searchsorted(starts, w.position, side="right")) - 1
        k0 = int(np.searchsorted(phone_starts, w.start - 1e-9))
        k1 = int(np.searchsorted(phone_starts, (w.end or w.start) - 1e-9))
        counts[i] += sum(1 for p in apart.phonemes[k0:k1] if p.phoneme not in PAUSES)
    words = list(ref.words)
    ref_starts = np.array([p.start for p in ref.phonemes])
    piece = 0
    replace: dict[int, list] = {}
    for k, ts in merged:
        w = words[k]
        k0 = int(np.searchsorted(ref_starts, w.start - 1e-9))
        k1 = int(np.searchsorted(ref_starts, (w.end or w.start) - 1e-9))
        spoken = [p for p in ref.phonemes[k0:k1] if p.phoneme not in PAUSES]
        c = np.array([counts[piece + j] for j in range(len(ts))], float)
        piece += len(ts)
        if c.sum() == 0:
            c[0] = 1.0
        cuts = np.round(len(spoken) * np.cumsum(c) / c.sum()).astype(int)
        cuts = np.minimum(np.maximum.accumulate(np.concatenate([[0], cuts])), len(spoken))
        out = []
        for j, t in enumerate(ts):
            a, b = tokens[t]
            if cuts[j + 1] > cuts[j]:
                t0, t1 = spoken[cuts[j]].start, spoken[cuts[j + 1] - 1].end
            else:  # no phones of its own: a point at its place
                t0 = t1 = spoken[cuts[j] - 1].end if cuts[j] > 0 else w.start
            text = w.text if j == 0 else _word_text(ssml[a:b])
            out.append(Word(t0, a if j else w.position, b - a if j else w.length, t1, text))
        replace[k] = out
    ref.words[:] = [x for k, w in enumerate(words) for x in replace.get(k, [w])]
    return {w.start for out in replace.values() for w in out[1:]}


def _unescape(text: str) -> str:
    for entity, char in (("&lt;", "<"), ("&gt;", ">"), ("&quot;", '"'), ("&apos;", "'")):
        text = text.replace(entity, char)
    return text.replace("&amp;", "&")


def _word_text(token: str) -> str:
    """A token of the SSML as a word's text (entities decoded, punctuation around it
    stripped), as espeak-ng's words are written (:func:`vtts.speech.tts._word_at`)."""
    from vtts.speech.tts import WORD_EDGE

    text = _unescape(token)
    return text.strip(WORD_EDGE) or text


#: espeak-ng's stops and affricates (its English phoneme names).
STOPS = frozenset({"p", "b", "t", "d", "k", "g", "tS", "dZ", "t#", "t2", "d#", "d2", "k2"})
CLOSURE_WINDOW = 0.010
#: How far before a stop's event its closure may begin, s; how deep the closure is, dB.
CLOSURE_SEARCH = 0.08
CLOSURE_DB = 12.0


def _closures(phones: list[Phone], db: np.ndarray) -> list[Phone]:
    """``phones`` of espeak-ng's reference with each stop (or affricate) starting where its
    closure begins: espeak-ng's stop event comes at the release, the closure's silence (30-45
    ms of it) ending the phone before. ``db``: the reference's log-mel energies every
    :data:`FINE_HOP` s. A stop after another stop owns the closure after the first's release;
    one after a pause is left (its closure is the pause's silence)."""
    e = 10.0 * np.log10((10.0 ** (db / 10.0)).sum(axis=1))
    starts = np.array([p.start for p in phones])
    for k in range(1, len(phones)):
        p, j = phones[k], k - 1
        while j > 0 and phones[j].duration <= 0:  # the optional pause before a word
            j -= 1
        prev = phones[j]
        if p.phoneme not in STOPS or prev.phoneme in PAUSES:
            continue
        f1 = int(round(p.start / FINE_HOP))
        f0 = max(int(round(max(p.start - CLOSURE_SEARCH, prev.start) / FINE_HOP)), 0)
        if f1 - f0 < 3 or f1 > len(e):
            continue
        seg = e[f0:f1]
        low = float(seg.min())
        loud = np.flatnonzero(seg >= low + CLOSURE_DB)
        if len(loud) == 0 or loud[-1] == len(seg) - 1:
            continue
        # the closure begins after the last frame still CLOSURE_DB above its floor
        starts[j + 1 : k + 1] = (f0 + loud[-1] + 1) * FINE_HOP
    starts = np.maximum.accumulate(starts)
    ends = np.append(starts[1:], phones[-1].end)
    return [
        Phone(float(a), float(b), p.phoneme, p.viseme, p.ipa)
        for p, a, b in zip(phones, starts, ends, strict=True)
    ]


#: espeak-ng's linking glide between a close front vowel and the next vowel ("the owl": D I2 ;
#: aU): the onset of the next syllable, not a phone of its own.
LINKS = frozenset({";"})


def _linked(phones: list[Phone]) -> list[Phone]:
    """``phones`` with each linking glide made part of the phone after it (zero length at its
    start)."""
    out = list(phones)
    for k in range(len(out) - 2, 0, -1):
        p, q = out[k], out[k + 1]
        if p.phoneme in LINKS and q.phoneme not in LINKS:
            out[k + 1] = Phone(p.start, q.end, q.phoneme, q.viseme, q.ipa)
            out[k] = Phone(p.start, p.start, p.phoneme, p.viseme, p.ipa)
    return out


def _without_links(phones: list[Phone], refine) -> list[Phone]:
    """``refine`` (phones → phones) run on ``phones`` with each linking glide (:data:`LINKS`)
    made part of the phone after it; the glides come back as zero-length phones at that phone's
    start."""
    link = [
        k > 0 and k + 1 < len(phones) and p.phoneme in LINKS and phones[k + 1].phoneme not in LINKS
        for k, p in enumerate(phones)
    ]
    if not any(link):
        return refine(phones)
    kept = []
    for k, p in enumerate(phones):
        if link[k]:
            continue
        if k > 0 and link[k - 1]:
            p = Phone(phones[k - 1].start, p.end, p.phoneme, p.viseme, p.ipa)
        kept.append(p)
    out = iter(refine(kept))
    full: list[Phone | None] = [None if link[k] else next(out) for k in range(len(phones))]
    for k in range(len(phones) - 1, -1, -1):  # each glide: zero length where the next starts
        if link[k]:
            q, g = full[k + 1], phones[k]
            assert q is not None
            full[k] = Phone(q.start, q.start, g.phoneme, g.viseme, g.ipa)
    return [p for p in full if p is not None]


def _pauses(speech: np.ndarray, db: np.ndarray) -> np.ndarray:
    """``(n,)`` bool: frames where the recording may pause: the runs of frames that are not
    ``speech`` and reach down to within :data:`PAUSE_DB` of its quietest frames (the 5th
    percentile of energy of ``(n, n_mels)`` log-mel energies ``db``)."""
    energy = 10.0 * np.log10((10.0 ** (db / 10.0)).sum(axis=1))
    quiet = energy < np.percentile(energy, 5) + PAUSE_DB
    silent = ~speech
    edges = np.flatnonzero(np.diff(np.concatenate([[0], silent.view(np.int8), [0]])))
    out = np.zeros_like(silent)
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if quiet[a:b].any():
            out[a:b] = True
    return out


def _masked(ref_db: np.ndarray, rec_db: np.ndarray) -> np.ndarray:
    """The reference's log-mel energies raised to the recording's noise floor, band by band (its
    10th percentile, relative to the loudest frame): espeak-ng's speech is clean, and where a
    recording's noise hides the quiet parts, the reference must not show them either (measured
    in docs/speech.md, "Lip-sync for recorded speech")."""
    floor = np.percentile(rec_db, 10, axis=0) - rec_db.max()
    return np.maximum(ref_db, ref_db.max() + floor).astype(np.float32)


class _Warp:
    """The warping path as a map from reference time to recording time, and its local costs."""

    def __init__(
        self, path: np.ndarray, ref_x: np.ndarray, rec_x: np.ndarray, ref_t0: float, rec_t0: float
    ) -> None:
        n = len(ref_x)
        self.ref_t0, self.rec_t0 = ref_t0, rec_t0
        diff = ref_x[path[:, 0]] - rec_x[path[:, 1]]
        self.cost = np.sqrt(np.einsum("ij,ij->i", diff, diff))
        self.rows = path[:, 0]
        self.cumcost = np.concatenate([[0.0], np.cumsum(self.cost)])
        counts = np.bincount(path[:, 0], minlength=n)
        # each reference frame maps to the middle of the recording frames it was matched with
        self.target = np.bincount(path[:, 0], weights=path[:, 1], minlength=n) / counts

    def time(self, t: np.ndarray | float) -> np.ndarray:
        """Reference times (s) → recording times (s)."""
        frames = np.arange(len(self.target))
        f = (np.asarray(t) - self.ref_t0) / HOP
        inside = np.interp(f, frames, self.target) * HOP + self.rec_t0
        # before and after the warped spans: the pauses, shifted
        last = len(self.target) - 1
        before = self.rec_t0 + f * HOP
        after = self.rec_t0 + (self.target[-1] + (f - last)) * HOP
        return np.where(f < 0, before, np.where(f > last, after, inside))

    def mean_cost(self, t0: float, t1: float) -> float:
        """Mean local cost of the path cells whose reference frame lies in ``[t0, t1)`` s."""
        f0, f1 = (t0 - self.ref_t0) / HOP, (t1 - self.ref_t0) / HOP
        a, b = np.searchsorted(self.rows, f0), np.searchsorted(self.rows, f1)
        return float((self.cumcost[b] - self.cumcost[a]) / (b - a)) if b > a else 0.0


def _word_boundaries(ref, ref_t0: float, n: int, joined=frozenset()) -> dict[int, float]:
    """Reference frame (in the warped span) → time (s) of every word start after the first that
    no pause of espeak's precedes, except those in ``joined``."""
    out: dict[int, float] = {}
    starts = [p.start for p in ref.phonemes]
    for w in ref.words[1:]:
        if w.start in joined:
            continue
        k = int(np.searchsorted(starts, w.start - 1e-9))
        if 0 < k < len(ref.phonemes) and ref.phonemes[k - 1].phoneme not in PAUSES:
            f = round((w.start - ref_t0) / HOP)
            if 0 < f < n:
                out[f] = w.start
    return out


def _pause_spans(boundaries, path, silent, rec_t0) -> list[tuple | None]:
    """For each word boundary (in order), the pause of the recording the path rested on there:
    (start, end) in the recording (s) of at least :data:`MIN_PAUSE` s of silence, or None."""
    rows = path[:, 0]  # non-decreasing
    found: list[tuple | None] = []
    for b in sorted(boundaries):
        i0, i1 = np.searchsorted(rows, b - 1), np.searchsorted(rows, b, side="right")
        cols = path[i0:i1, 1]
        cols = cols[silent[cols]]
        span = None
        if len(cols):
            # the longest run of consecutive columns
            runs = np.split(cols, np.flatnonzero(np.diff(cols) > 1) + 1)
            run = max(runs, key=len)
            if len(run) * HOP >= MIN_PAUSE:
                span = (rec_t0 + run[0] * HOP, rec_t0 + (run[-1] + 1) * HOP)
        found.append(span)
    return found


def _inserted_pauses(ref, boundaries) -> list[int]:
    """Every word boundary gets a zero-length ``_`` in ``ref.phonemes`` before its first phone
    (where the recording may pause and the reference does not); returns their indices, in the
    order of the boundaries."""
    times = [boundaries[b] for b in sorted(boundaries)]
    starts = np.array([p.start for p in ref.phonemes])
    at = np.searchsorted(starts, np.array(times) - 1e-9)
    phones: list[Phone] = []
    out: list[int] = []
    j = 0
    for k, p in enumerate(ref.phonemes):
        while j < len(times) and at[j] == k:
            out.append(len(phones))
            phones.append(Phone(times[j], times[j], "_", 0))
            j += 1
        phones.append(p)
    ref.phonemes[:] = phones
    return out


def _warped_phones(
    ref: list[Phone], warp: _Warp, duration: float, inserted: dict[int, tuple] | None = None
) -> list[Phone]:
    starts = warp.time(np.array([p.start for p in ref]))
    for k, (a, b) in (inserted or {}).items():
        starts[k] = a
        starts[k + 1] = b
    starts = np.clip(np.maximum.accumulate(starts), 0.0, duration)
    starts[0] = 0.0
    ends = np.append(starts[1:], duration)
    return [
        Phone(float(s), float(e), p.phoneme, p.viseme, p.ipa)
        for p, s, e in zip(ref, starts, ends, strict=True)
    ]


def _carry(t: float, ref: list[Phone], aligned: list[Phone]) -> float:
    """A reference time carried to the recording: the same fraction of the same phone."""
    starts = [p.start for p in ref]
    k = max(0, int(np.searchsorted(starts, t, side="right")) - 1)
    p, q = ref[k], aligned[k]
    f = 0.0 if p.duration <= 0 else min(max((t - p.start) / p.duration, 0.0), 1.0)
    return q.start + f * q.duration


def _words(ref, phones: list[Phone], warp: _Warp) -> list[AlignedWord]:
    """The reference's words (their first to last phone that is not a pause), carried to the
    recording through the aligned phones, with their warping costs; every word of the reference
    is one, in order."""
    ref_starts = np.array([p.start for p in ref.phonemes])
    out: list[AlignedWord] = []
    for word in ref.words:
        end = word.end if word.end is not None else word.start
        k0 = int(np.searchsorted(ref_starts, word.start - 1e-9))
        k1 = int(np.searchsorted(ref_starts, end - 1e-9))
        ks = [k for k in range(k0, k1) if ref.phonemes[k].phoneme not in PAUSES]
        if not ks:  # a word with no phones of its own: a point at its place
            t = phones[k0].start if k0 < len(phones) else phones[-1].end
            out.append(AlignedWord(t, t, word.text, 0.0))
            continue
        a, b = phones[ks[0]], phones[ks[-1]]
        cost = warp.mean_cost(ref.phonemes[ks[0]].start, ref.phonemes[ks[-1]].end)
        out.append(AlignedWord(a.start, b.end, word.text, cost))
    return out


def _problems(words: list[AlignedWord], voiced: bool) -> list[str]:
    """Where the recording does not match the transcript, from the words' warping costs: a run
    of words costing :data:`LOCAL_RATIO` times the utterance's median (and at least
    :data:`LOCAL_MIN`), or a median above :data:`GLOBAL_COST` (nowhere a match)."""
    problems = []
    if not voiced:
        problems.append("the recording has almost no voiced sound: is it speech?")
    if not words:
        return problems
    costs = np.array([w.cost for w in words])
    median = float(np.median(costs))
    typical = float(np.percentile(costs, 25))  # robust to a transcript half wrong
    if median > GLOBAL_COST:
        problems.append(
            f"the recording does not match the transcript anywhere (median word alignment cost "
            f"{median:.1f}, above {GLOBAL_COST:g}): is it the right text, and speech?"
        )
        return problems
    bad = (costs > LOCAL_RATIO * typical) & (costs > LOCAL_MIN)
    k = 0
    while k < len(words):
        if not bad[k]:
            k += 1
            continue
        j = k
        while j + 1 < len(words) and bad[j + 1]:
            j += 1
        run = words[k : j + 1]
        worst = float(costs[k : j + 1].max())
        if len(run) >= 2 or worst > SINGLE_RATIO * typical:
            names = " ".join(w.text for w in run if w.text) or f"{len(run)} word(s)"
            if len(names) > 60:
                names = names[:59] + "…"
            problems.append(
                f"the alignment breaks down at {run[0].start:.2f}–{run[-1].end:.2f} s "
                f'("{names}": word alignment cost up to {worst:.1f}, a typical word\'s '
                f"{typical:.1f}): does the recording say these words?"
            )
        k = j + 1
    return problems
