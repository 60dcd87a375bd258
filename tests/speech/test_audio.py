"""Reading recorded speech (issue 19): WAV, FLAC and OGG with soundfile, MP3 and M4A with the
bundled ffmpeg, stereo mixed to mono, resampling, the length limit and clear errors; and
``vtts say --phonemes … --audio FILE.mp3`` muxing that audio into the MP4."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from vtts.errors import SpeechError
from vtts.limits import MAX_AUDIO_RATE, LimitError
from vtts.media import ffmpeg_exe
from vtts.render import probe_media
from vtts.speech.audio import read_audio, read_for_mp4, resample, to_int16

from ..in_process import vtts

HEAD = Path(__file__).parents[1] / "data" / "models" / "head.wrl"
RATE = 44100
SECONDS = 0.5
TONE = 440.0


def _stereo() -> np.ndarray:
    """``(n, 2)`` float32: a 440 Hz tone at 0.5 on the left, silence on the right."""
    t = np.arange(int(RATE * SECONDS)) / RATE
    left = 0.5 * np.sin(2 * np.pi * TONE * t)
    return np.stack([left, np.zeros_like(left)], axis=1).astype(np.float32)


def _peak_hz(x: np.ndarray, rate: int) -> float:
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    return float(np.argmax(spectrum) * rate / x.size)


def _ffmpeg(src: Path, dst: Path, *extra: str) -> Path:
    cmd = [ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y", "-i", str(src), *extra]
    subprocess.run([*cmd, str(dst)], check=True, capture_output=True, timeout=60)
    return dst


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("audio")
    x = _stereo()
    out = {}
    for name, fmt, subtype in [
        ("wav", "WAV", "PCM_16"),
        ("flac", "FLAC", "PCM_16"),
        ("ogg", "OGG", "VORBIS"),
    ]:
        out[name] = d / f"tone.{name}"
        sf.write(out[name], x, RATE, format=fmt, subtype=subtype)
    out["mp3"] = _ffmpeg(out["wav"], d / "tone.mp3", "-c:a", "libmp3lame", "-b:a", "96k")
    out["m4a"] = _ffmpeg(out["wav"], d / "tone.m4a", "-c:a", "aac", "-b:a", "96k")
    return out


@pytest.mark.parametrize("kind", ["wav", "flac", "ogg", "mp3", "m4a"])
def test_formats_read_as_mono_float(files: dict[str, Path], kind: str) -> None:
    samples, rate = read_audio(files[kind])
    assert rate == RATE
    assert samples.dtype == np.float32 and samples.ndim == 1
    # MP3 and AAC decoders add up to ~50 ms of padding; the lossless ones are exact
    exact = kind in ("wav", "flac")
    assert abs(samples.size - RATE * SECONDS) <= (0 if exact else 0.06 * RATE)
    assert np.abs(samples).max() <= 1.0
    # the left channel's 0.5 averaged with the right's silence: amplitude 0.25, the same tone
    middle = samples[samples.size // 4 : 3 * samples.size // 4]
    assert np.sqrt(np.mean(middle**2)) == pytest.approx(0.25 / np.sqrt(2), rel=0.05)
    assert _peak_hz(middle, rate) == pytest.approx(TONE, abs=5)


@pytest.mark.parametrize("to", [16000, 22050, 48000])
def test_resampled_to_the_rate_asked_for(files: dict[str, Path], to: int) -> None:
    samples, rate = read_audio(files["flac"], rate=to)
    assert rate == to
    assert abs(samples.size - to * SECONDS) <= 1
    assert _peak_hz(samples, rate) == pytest.approx(TONE, abs=5)


def test_resample_and_int16_helpers() -> None:
    x = np.array([0.0, 1.0, -1.0, 2.0, np.float32(-0.5)], dtype=np.float32)
    assert to_int16(x).tolist() == [0, 32767, -32767, 32767, -16384]
    assert resample(x, 8000, 8000) is not None and resample(x, 8000, 16000).size == 10


def test_float_wav_beyond_full_scale_is_clipped_and_nan_silenced(tmp_path: Path) -> None:
    x = np.array([0.0, 3.0, -3.0, np.nan, 0.25] * 100, dtype=np.float32)
    sf.write(tmp_path / "loud.wav", x, 8000, subtype="FLOAT")
    samples, _ = read_audio(tmp_path / "loud.wav")
    assert samples[:5].tolist() == [0.0, 1.0, -1.0, 0.0, 0.25]


def test_mp4_reader_gives_int16_at_an_aac_rate(tmp_path: Path) -> None:
    # 20 kHz is no AAC rate: the next higher one (22.05 kHz) is taken
    sf.write(tmp_path / "odd.wav", np.zeros(2000, np.float32), 20000)
    samples, rate = read_for_mp4(tmp_path / "odd.wav")
    assert samples.dtype == np.int16 and rate == 22050 and abs(samples.size - 2205) <= 1


# ---- bad input -----------------------------------------------------------------------------------


def test_missing_empty_folder_and_not_audio(tmp_path: Path) -> None:
    (tmp_path / "empty.wav").write_bytes(b"")
    (tmp_path / "notes.mp3").write_text("this is text, not sound\n" * 20)
    (tmp_path / "noise.bin").write_bytes(np.random.default_rng(0).bytes(4000))
    cases = [
        ("missing.wav", "does not exist"),
        ("empty.wav", "empty"),
        (".", "is a folder"),
        ("notes.mp3", "not an audio file that soundfile or ffmpeg can read"),
        ("noise.bin", "not an audio file"),
    ]
    for name, fragment in cases:
        path = tmp_path / name
        with pytest.raises(SpeechError, match=fragment) as err:
            read_audio(path)
        assert err.value.file == str(path)


def test_a_named_pipe_or_a_device_is_refused_at_once(tmp_path: Path) -> None:
    """``say --audio FIFO`` waited for ever for a writer, deaf to Ctrl-C and SIGTERM (its
    reader thread was joined); a pipe cannot be decoded twice (libsndfile, then ffmpeg) anyway."""
    fifo = tmp_path / "speech.wav"
    os.mkfifo(fifo)
    for path in (fifo, Path("/dev/zero")):
        with pytest.raises(SpeechError, match="not a regular file .a named pipe or a device.") as e:
            read_audio(path)
        assert e.value.file == str(path)
    exe = Path(sys.executable).with_name("vtts")
    cmd = [str(exe), "say", "--text", "hello", "--audio", str(fifo), "--model", str(HEAD)]
    cmd += ["--fap-out", str(tmp_path / "x.fap")]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)  # hung before
    assert r.returncode == 1 and "not a regular file" in r.stderr and "Traceback" not in r.stderr
    assert str(fifo) in r.stderr and not (tmp_path / "x.fap").exists()


def test_video_without_sound_has_no_audio_stream(tmp_path: Path) -> None:
    video = tmp_path / "silent.mp4"
    cmd = [ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-f", "lavfi"]
    cmd += ["-i", "color=c=black:s=32x32:d=0.2", "-c:v", "libx264", str(video)]
    subprocess.run(cmd, check=True, capture_output=True, timeout=60)
    with pytest.raises(SpeechError, match="no audio stream") as err:
        read_audio(video)
    assert err.value.file == str(video)


def test_no_samples(tmp_path: Path) -> None:
    sf.write(tmp_path / "none.wav", np.zeros((0, 1), np.float32), 8000)
    with pytest.raises(SpeechError, match="holds no samples"):
        read_audio(tmp_path / "none.wav")


def test_rates_out_of_bounds(tmp_path: Path, files: dict[str, Path]) -> None:
    with pytest.raises(SpeechError, match="must be a positive integer"):
        read_audio(files["wav"], rate=0)
    with pytest.raises(LimitError, match=f"limit of {MAX_AUDIO_RATE} Hz"):
        read_audio(files["wav"], rate=MAX_AUDIO_RATE + 1)
    # a header claiming 384 kHz (soundfile writes what it is told)
    sf.write(tmp_path / "fast.wav", np.zeros(100, np.float32), 384000)
    with pytest.raises(LimitError, match="384000 Hz") as err:
        read_audio(tmp_path / "fast.wav")
    assert err.value.file == str(tmp_path / "fast.wav")


def test_m4a_longer_than_the_limit_stops_decoding(tmp_path: Path, monkeypatch) -> None:
    import vtts.speech.audio as audio

    monkeypatch.setattr(audio, "MAX_AUDIO_S", 0.2)  # the tone lasts 0.5 s
    src = tmp_path / "t.wav"
    sf.write(src, _stereo(), RATE)
    m4a = _ffmpeg(src, tmp_path / "t.m4a", "-c:a", "aac")  # decoded by ffmpeg, up to 1.2 s
    with pytest.raises(LimitError, match="lasts more than the limit of 0.2 s") as err:
        read_audio(m4a)
    assert err.value.file == str(m4a)
    with pytest.raises(LimitError, match="lasts 0.5 s, more than the limit of 0.2 s"):
        read_audio(src)


# ---- vtts say ------------------------------------------------------------------------------------


def test_say_muxes_an_mp3_into_the_mp4(tmp_path: Path, files: dict[str, Path]) -> None:
    table = tmp_path / "p.txt"
    table.write_text("0 0.1 _\n0.1 0.2 m\n0.2 0.4 a\n0.4 0.5 _\n")
    out = tmp_path / "out.mp4"
    cmd = ["say", "Ma", "--phonemes", str(table), "--audio", str(files["mp3"])]
    cmd += ["--model", str(HEAD), "--size", "160x120", "--quiet", "-o", str(out)]
    r = vtts(*cmd)
    assert r.returncode == 0, r.stderr
    info = probe_media(out)
    assert info.audio_rate == RATE and info.duration_audio == pytest.approx(SECONDS, abs=0.07)


@pytest.mark.parametrize("claimed", [0, 100, 8000, 20000])
def test_flac_whose_header_states_another_length(tmp_path: Path, claimed: int) -> None:
    # STREAMINFO's 36-bit sample count: 0 means unknown; the decoder may trust it or not
    buf = io.BytesIO()
    x = (0.5 * np.sin(np.arange(8000) * 0.1)).astype(np.float32)
    sf.write(buf, x, 8000, format="FLAC", subtype="PCM_16")
    data = bytearray(buf.getvalue())
    bits = int.from_bytes(data[18:26], "big") & ~((1 << 36) - 1) | claimed
    data[18:26] = bits.to_bytes(8, "big")
    (tmp_path / "c.flac").write_bytes(bytes(data))
    samples, rate = read_audio(tmp_path / "c.flac")
    assert rate == 8000 and samples.size in (claimed, 8000)
    assert np.allclose(samples[:100], x[:100], atol=1e-3)


# ---- channels that cancel, rates below alignment's (issue 45) ------------------------------------


def _tone(seconds: float = SECONDS, rate: int = RATE) -> np.ndarray:
    t = np.arange(int(rate * seconds)) / rate
    return (0.5 * np.sin(2 * np.pi * TONE * t)).astype(np.float32)


@pytest.mark.parametrize(
    "channels, rms",
    [
        (lambda x: [x, -x], 0.5),  # an inverted right channel: the mean was silence
        (lambda x: [-x, x], 0.5),
        (lambda x: [x, -0.5 * x], 0.375),  # inverted and quieter: turned over, then averaged
        (lambda x: [x, x], 0.5),  # in phase: the mean, as before
        (lambda x: [x, 0 * x], 0.25),
        (lambda x: [x, -x, x, -x], 0.5),
        (lambda x: [0 * x, 0 * x], 0.0),
    ],
    ids=["L -L", "-L L", "L -L/2", "L L", "L 0", "4 channels", "silence"],
)
@pytest.mark.parametrize("fmt", ["WAV", "FLAC"])
def test_channels_wired_against_each_other_do_not_cancel(
    tmp_path: Path, channels, rms: float, fmt: str
) -> None:
    """A stereo recording with an inverted right channel was called silent."""
    x = _tone()
    path = tmp_path / f"c.{fmt.lower()}"
    sf.write(path, np.stack(channels(x), axis=1), RATE, format=fmt)
    samples, _ = read_audio(path)
    peak = float(np.abs(samples).max())
    assert peak == pytest.approx(rms, abs=2e-3)


def test_an_inverted_channel_through_ffmpeg_does_not_cancel(tmp_path: Path) -> None:
    x = _tone()
    wav = tmp_path / "inv.wav"
    sf.write(wav, np.stack([x, -x], axis=1), RATE)
    m4a = _ffmpeg(wav, tmp_path / "inv.m4a", "-c:a", "aac", "-b:a", "128k")
    samples, _ = read_audio(m4a)
    assert float(np.sqrt(np.mean(samples**2))) > 0.25


@pytest.mark.parametrize("rate", [100, 4000, 7350, 7999])
def test_say_refuses_a_recording_below_8_khz(tmp_path: Path, rate: int) -> None:
    """4000 and 100 Hz were reported as "7350 Hz" (the MP4's conversion), 7999 Hz accepted."""
    from vtts.cli import main

    path = tmp_path / f"r{rate}.wav"
    sf.write(path, _tone(1.0, rate), rate)
    code = main(["say", "hello there", "--audio", str(path), "--model", str(HEAD), "--wav-out",
                 str(tmp_path / "out.wav")])  # fmt: skip
    assert code == 1
    assert not (tmp_path / "out.wav").exists()


@pytest.mark.parametrize("rate", [100, 4000, 7999])
def test_the_rate_error_names_the_recording(tmp_path: Path, capsys, rate: int) -> None:
    from vtts.cli import main

    path = tmp_path / f"r{rate}.wav"
    sf.write(path, _tone(1.0, rate), rate)
    main(["say", "hello there", "--audio", str(path), "--model", str(HEAD), "--wav-out",
          str(tmp_path / "out.wav")])  # fmt: skip
    err = capsys.readouterr().err
    assert f"{path}: error: the recording is sampled at {rate} Hz; alignment needs at least" in err
