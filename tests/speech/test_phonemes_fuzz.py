"""Fuzzing what ``vtts say --phonemes FILE --audio WAV`` reads (issue 21): Polly speech marks
(JSON lines), ``start end phoneme`` tables, ``--timings-out`` tables (issue 19) and the audio.
Whatever the bytes, the only exception is SpeechError (or LimitError) naming the file; what is
accepted has phones in order with visemes, within the duration limit.
"""

from __future__ import annotations

import io
import json
import math
import wave
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vtts.errors import SpeechError
from vtts.limits import MAX_AUDIO_S, MAX_DURATION_S, LimitError
from vtts.speech.audio import read_for_mp4
from vtts.speech.phonemes import PhonemeFile, read_phoneme_file

from ..fuzzing import examples
from ..hostile import byte_mutations, mutate, mutate_bytes, mutations

POLLY = "\n".join(
    json.dumps(e)
    for e in [
        {"time": 0, "type": "sentence", "start": 0, "end": 23, "value": "Mary had a little lamb."},
        {"time": 6, "type": "word", "start": 0, "end": 4, "value": "Mary"},
        {"time": 6, "type": "viseme", "value": "p"},
        {"time": 73, "type": "viseme", "value": "E"},
        {"time": 180, "type": "viseme", "value": "r"},
        {"time": 266, "type": "ssml", "start": 5, "end": 29, "value": "b0"},
        {"time": 266, "type": "viseme", "value": "i"},
        {"time": 400.5, "type": "viseme", "value": "sil"},
    ]
)
TABLE = """# from an aligner
0 0.08 h
0.08 0.2 @
0.2 0.31 l
mark 0.25 b0
0.31 0.5 oU
0.5 0.6 _
"""
ARPABET = """# alphabet: arpabet
0.0 0.1 HH
0.1 0.25 AH0
0.25 0.3 L
0.3 0.52 OW1
"""
IPA = "# alphabet: ipa\n0 0.1 h\n0.1 0.2 ə\n0.2 0.3 ˈloʊ\n"
TIMINGS = """kind	start	end	label	viseme
phone	0.0000	0.0120	_	0
word	0.0120	0.3059	Hello	-
phone	0.0120	0.0630	h	5
phone	0.0630	0.3059	oU	13
"""
CORPUS = [POLLY, TABLE, ARPABET, IPA, TIMINGS]

FUZZ = settings(
    max_examples=examples(150), deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("phonemes")


def read_or_speech_error(path: Path, data: bytes) -> PhonemeFile | None:
    path.write_bytes(data)
    try:
        pf = read_phoneme_file(path)
    except (SpeechError, LimitError) as e:
        assert e.file == str(path) and e.message, str(e)
        return None
    assert pf.phones
    for a, b in zip(pf.phones, pf.phones[1:], strict=False):
        assert a.start <= a.end <= b.start + 1e-6
    for p in pf.phones:
        assert math.isfinite(p.start) and 0 <= p.start <= p.end <= MAX_DURATION_S
        assert p.viseme is not None and 0 <= p.viseme <= 14
    assert all(0 <= m.time <= MAX_DURATION_S for m in pf.marks)
    assert all(0 <= w.start <= w.end <= MAX_DURATION_S for w in pf.words)
    return pf


def test_the_corpus_reads(folder: Path) -> None:
    for text in CORPUS:
        assert read_or_speech_error(folder / "c.txt", text.encode())


@FUZZ
@given(st.binary(max_size=500))
def test_random_bytes(folder: Path, data: bytes) -> None:
    read_or_speech_error(folder / "r.txt", data)
    read_or_speech_error(folder / "r.json", b'{"time": 0, "type": "viseme", "value": "p"}\n' + data)


@FUZZ
@given(st.sampled_from(CORPUS), mutations)
def test_mutated_files(folder: Path, text: str, ops: list[tuple[str, int, int, str]]) -> None:
    read_or_speech_error(folder / "m.txt", mutate(text, ops).encode("utf-8", "surrogatepass"))


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner),
    max_leaves=6,
)


@FUZZ
@given(
    st.lists(
        st.fixed_dictionaries(
            {},
            optional={
                "time": st.one_of(JSON_VALUES, st.integers(-1, 10**7), st.floats()),
                "type": st.one_of(st.sampled_from(["viseme", "ssml", "word"]), JSON_VALUES),
                "value": st.one_of(st.sampled_from(["p", "E", "sil", "b0", "x"]), JSON_VALUES),
            },
        ),
        min_size=1,
        max_size=5,
    )
)
def test_polly_entries(folder: Path, entries: list[dict]) -> None:
    """Speech marks of every JSON type in every field (NaN and Infinity as Python writes them)."""
    read_or_speech_error(folder / "p.json", "\n".join(map(json.dumps, entries)).encode())


# ---- the WAV -------------------------------------------------------------------------------------


def _wav(channels: int = 1, width: int = 2, rate: int = 16000, seconds: float = 0.05) -> bytes:
    buf = io.BytesIO()
    with wave.open(buf, "wb") as w:
        w.setnchannels(channels)
        w.setsampwidth(width)
        w.setframerate(rate)
        n = int(rate * seconds)
        w.writeframes(np.arange(n * channels * width, dtype=np.uint8).tobytes())
    return buf.getvalue()


WAVS = [_wav(), _wav(2, 2, 8000), _wav(1, 1, 22050), _wav(1, 3, 44100), _wav(2, 4, 48000)]


def read_audio_or_speech_error(path: Path, data: bytes) -> None:
    path.write_bytes(data)
    try:
        samples, rate = read_for_mp4(path)
    except (SpeechError, LimitError) as e:
        assert e.file == str(path) and e.message, str(e)
        return
    assert samples.dtype == np.int16 and samples.ndim == 1
    assert rate > 0 and samples.size / rate <= MAX_AUDIO_S + 0.01


def test_the_wavs_read(folder: Path) -> None:
    for data in WAVS:
        (folder / "w.wav").write_bytes(data)
        samples, rate = read_for_mp4(folder / "w.wav")
        assert samples.size > 0 and rate > 0


@FUZZ
@given(st.sampled_from(WAVS), byte_mutations, st.sampled_from([0, 44]))
def test_mutated_wavs(
    folder: Path, data: bytes, ops: list[tuple[int, str, int]], start: int
) -> None:
    read_audio_or_speech_error(folder / "m.wav", mutate_bytes(data[:300], ops, start=start))


@FUZZ
@given(st.binary(max_size=200))
def test_random_wav_bytes(folder: Path, data: bytes) -> None:
    read_audio_or_speech_error(folder / "r.wav", data)
    read_audio_or_speech_error(folder / "h.wav", WAVS[0][:44] + data)


def _flac_claiming(seconds: int, rate: int = 8000) -> bytes:
    """A short FLAC whose STREAMINFO claims ``seconds`` of audio (its 36-bit sample count)."""
    import soundfile as sf

    buf = io.BytesIO()
    sf.write(buf, np.zeros(800, dtype=np.int16), rate, format="FLAC")
    data = bytearray(buf.getvalue())
    bits = int.from_bytes(data[18:26], "big")
    bits = bits & ~((1 << 36) - 1) | rate * seconds
    data[18:26] = bits.to_bytes(8, "big")
    return bytes(data)


def test_audio_longer_than_the_limit_is_refused_before_decoding(folder: Path) -> None:
    # a 900 kB FLAC of ten hours of silence ran say for over ten minutes at 1.5 GB
    path = folder / "long.flac"
    path.write_bytes(_flac_claiming(36_000))
    with pytest.raises(LimitError, match="the audio lasts 36000 s, more than the limit of 1800 s"):
        read_for_mp4(path)
