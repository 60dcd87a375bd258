"""The renderer's output writers: MP4 (through the imageio-ffmpeg binary), PNG sequences, WAV."""

from __future__ import annotations

import subprocess
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest
import soundfile
from PIL import Image

from vtts.errors import RenderError, VttsError
from vtts.media import ffmpeg_exe
from vtts.render.output import (
    FRAME_NAME,
    AacTrack,
    PngSequenceWriter,
    VideoWriter,
    probe_media,
    progress,
    write_png,
    write_wav,
)

W, H = 64, 48
WAV_SECONDS = 1.5
WAV_RATE = 22050


def solid(rgb: tuple[int, int, int], w: int = W, h: int = H) -> np.ndarray:
    frame = np.empty((h, w, 3), np.uint8)
    frame[...] = rgb
    return frame


def moving_frames(n: int, w: int = W, h: int = H) -> list[np.ndarray]:
    """Frames with a bar that moves, so the encoder sees real content, not one repeated frame."""
    frames = []
    for i in range(n):
        f = solid((30, 60, 90), w, h)
        x = (2 * i) % w
        f[:, x : x + 4] = (250, 250, 250)
        frames.append(f)
    return frames


@pytest.fixture
def wav(tmp_path: Path) -> Path:
    """A 1.5 s mono sine at 22.05 kHz, outside the output folder."""
    t = np.arange(int(WAV_SECONDS * WAV_RATE)) / WAV_RATE
    path = tmp_path / "audio" / "sine.wav"
    path.parent.mkdir()
    soundfile.write(path, (0.3 * np.sin(2 * np.pi * 440 * t)).astype(np.float32), WAV_RATE)
    return path


@pytest.fixture
def out(tmp_path: Path) -> Path:
    folder = tmp_path / "out"
    folder.mkdir()
    return folder


def listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def decoded_frames(path: Path) -> list[np.ndarray]:
    gen = imageio_ffmpeg.read_frames(str(path))
    meta = next(gen)
    w, h = meta["size"]
    try:
        return [np.frombuffer(b, np.uint8).reshape(h, w, 3) for b in gen]
    finally:
        gen.close()


# --- MP4 ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("fps", "n", "with_audio"),
    [(30, 45, False), (30, 45, True), (25, 40, False), (25, 30, True), (30000 / 1001, 30, False)],
)
def test_mp4_round_trip(out: Path, wav: Path, fps: float, n: int, with_audio: bool) -> None:
    path = out / "clip.mp4"
    with VideoWriter(path, fps, (W, H), audio=wav if with_audio else None) as video:
        for frame in moving_frames(n):
            video.write(frame)
    assert listing(out) == ["clip.mp4"]  # the temporary file was renamed, nothing else left

    info = probe_media(path)
    assert (info.width, info.height) == (W, H)
    assert info.frames is not None and abs(info.frames - n) <= 1
    assert info.fps == pytest.approx(fps, rel=1e-6)
    assert info.duration_video == pytest.approx(n / fps, abs=1 / fps)
    if with_audio:
        assert info.audio_rate == WAV_RATE
        assert info.audio_channels == 1
        # no -shortest: the audio keeps its own length even when it is longer than the video
        assert info.duration_audio == pytest.approx(WAV_SECONDS, abs=0.05)
    else:
        assert info.duration_audio is None and info.audio_rate is None


def test_mp4_colors_come_back(out: Path) -> None:
    path = out / "red.mp4"
    with VideoWriter(path, 30, (W, H)) as video:
        for _ in range(5):
            video.write(solid((220, 20, 20)))
        for _ in range(5):
            video.write(solid((20, 20, 220)))
    frames = decoded_frames(path)
    assert len(frames) == 10
    r, g, b = frames[0].reshape(-1, 3).mean(axis=0)
    assert r > 190 and g < 50 and b < 50  # H.264 is lossy: reddish, not exact
    r, g, b = frames[-1].reshape(-1, 3).mean(axis=0)
    assert b > 190 and r < 50 and g < 50


def test_mp4_odd_size_is_padded(out: Path) -> None:
    path = out / "odd.mp4"
    with VideoWriter(path, 30, (65, 49)) as video:
        assert video.output_size == (66, 50)
        for _ in range(6):
            video.write(solid((200, 200, 200), 65, 49))
    info = probe_media(path)
    assert (info.width, info.height) == (66, 50)
    frame = decoded_frames(path)[0]
    assert frame[:49, :65].mean() > 180  # the picture
    assert frame[:, 65].mean() < 80 and frame[49, :].mean() < 80  # the black padding


def test_mp4_replaces_existing_file_only_on_success(out: Path) -> None:
    path = out / "clip.mp4"
    path.write_bytes(b"old")
    with pytest.raises(RuntimeError), VideoWriter(path, 30, (W, H)) as video:
        video.write(solid((1, 2, 3)))
        raise RuntimeError("boom")
    assert path.read_bytes() == b"old" and listing(out) == ["clip.mp4"]
    with VideoWriter(path, 30, (W, H)) as video:
        video.write(solid((1, 2, 3)))
    assert probe_media(path).frames == 1


def test_mp4_exception_leaves_nothing(out: Path) -> None:
    with pytest.raises(ValueError, match="boom"), VideoWriter(out / "c.mp4", 30, (W, H)) as video:
        for frame in moving_frames(10):
            video.write(frame)
        raise ValueError("boom")
    assert listing(out) == []


def test_mp4_keyboard_interrupt_kills_ffmpeg_and_leaves_nothing(out: Path) -> None:
    video = VideoWriter(out / "c.mp4", 30, (W, H))
    with pytest.raises(KeyboardInterrupt), video:
        proc = video._proc
        assert proc is not None
        video.write(solid((9, 9, 9)))
        raise KeyboardInterrupt
    assert proc.poll() is not None  # ffmpeg is gone, not left encoding in the background
    assert listing(out) == []


@pytest.mark.parametrize(
    ("frame", "actual"),
    [
        (np.zeros((H, W - 1, 3), np.uint8), "(48, 63, 3) uint8"),
        (np.zeros((H, W), np.uint8), "(48, 64) uint8"),
        (np.zeros((H, W, 3), np.float32), "(48, 64, 3) float32"),
    ],
)
def test_mp4_bad_frame(out: Path, frame: np.ndarray, actual: str) -> None:
    with pytest.raises(RenderError) as err, VideoWriter(out / "c.mp4", 30, (W, H)) as video:
        video.write(solid((0, 0, 0)))
        video.write(frame)
    assert "(48, 64, 3) uint8" in str(err.value) and actual in str(err.value)
    assert listing(out) == []


def test_mp4_missing_or_unreadable_audio(out: Path) -> None:
    missing = out / "nope.wav"
    with pytest.raises(RenderError, match="nope.wav.*does not exist"):
        VideoWriter(out / "c.mp4", 30, (W, H), audio=missing)
    junk = out / "junk.wav"
    junk.write_text("not a wave file")
    with pytest.raises(RenderError, match="junk.wav.*cannot be read"):
        VideoWriter(out / "c.mp4", 30, (W, H), audio=junk)
    assert listing(out) == ["junk.wav"]


def decoded_audio(path: Path) -> bytes:
    """The sound of a media file as ffmpeg decodes it (16-bit PCM)."""
    cmd = [ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-i", str(path), "-vn"]
    return subprocess.run([*cmd, "-f", "s16le", "-"], capture_output=True, check=True).stdout


def test_mp4_with_an_aac_track_encoded_beforehand(out: Path, wav: Path, tmp_path: Path) -> None:
    """An :class:`AacTrack` (the sound encoded in the background before the frames) is copied
    into the MP4: the same samples and durations as the WAV encoded beside the frames."""
    frames = moving_frames(30)
    with VideoWriter(out / "wav.mp4", 30, (W, H), audio=wav) as video:
        for frame in frames:
            video.write(frame)
    folder = tmp_path / "track"
    folder.mkdir()
    with AacTrack(wav, folder) as track:
        with VideoWriter(out / "aac.mp4", 30, (W, H), audio=track) as video:
            for frame in frames:
                video.write(frame)
        assert track.result() == folder / "sine.m4a"
    a, b = probe_media(out / "wav.mp4"), probe_media(out / "aac.mp4")
    assert (b.frames, b.audio_rate, b.audio_channels) == (a.frames, a.audio_rate, a.audio_channels)
    assert b.duration_audio == a.duration_audio == pytest.approx(WAV_SECONDS, abs=0.05)
    sound = decoded_audio(out / "aac.mp4")
    assert len(sound) > 2 * WAV_RATE and sound == decoded_audio(out / "wav.mp4")
    assert listing(out) == ["aac.mp4", "wav.mp4"]


def test_aac_track_bad_input(out: Path, wav: Path, tmp_path: Path) -> None:
    with pytest.raises(RenderError, match="nope.wav.*does not exist"):
        AacTrack(out / "nope.wav", out)
    junk = out / "junk.wav"
    junk.write_text("not a wave file")
    with pytest.raises(RenderError, match="junk.wav.*cannot be read"):
        AacTrack(junk, out)
    # ffmpeg cannot write the track: its own words are quoted, and no MP4 is made of it
    track = AacTrack(wav, tmp_path / "no-such-folder")
    with pytest.raises(RenderError, match="could not encode the sound") as err:
        track.result()
    assert "no-such-folder" in str(err.value)
    with pytest.raises(RenderError, match="could not encode"):
        VideoWriter(out / "c.mp4", 30, (W, H), audio=track).open()
    # a track stopped before it was used
    stopped = AacTrack(wav, out)
    stopped.close()
    with pytest.raises(RenderError, match="stopped"):
        stopped.result()
    assert not (out / "c.mp4").exists()


def test_mp4_ffmpeg_failure_is_reported(out: Path) -> None:
    with (
        pytest.raises(RenderError, match="ffmpeg") as err,
        VideoWriter(out / "c.mp4", 30, (W, H), preset="no-such-preset") as video,
    ):
        for frame in moving_frames(5):
            video.write(frame)
    assert "preset" in str(err.value).lower()  # ffmpeg's own words are quoted
    assert isinstance(err.value, VttsError)
    assert listing(out) == []


def test_mp4_without_frames_is_an_error(out: Path) -> None:
    with pytest.raises(RenderError, match="no frames"), VideoWriter(out / "c.mp4", 30, (W, H)):
        pass
    assert listing(out) == []


@pytest.mark.parametrize(
    ("fps", "size"), [(0, (W, H)), (float("nan"), (W, H)), (30, (0, H)), (30, (W,))]
)
def test_mp4_bad_arguments(out: Path, fps: float, size: tuple[int, int]) -> None:
    with pytest.raises(RenderError):
        VideoWriter(out / "c.mp4", fps, size)


def test_mp4_encoder_threads(out: Path) -> None:
    """Small frames encode on one libx264 thread (the renderer has the cores), large ones on
    libx264's own choice; both decode the same picture."""

    def threads(writer: VideoWriter) -> str:
        cmd = writer.command(out / "x.mp4")
        return cmd[cmd.index("-threads") + 1]

    assert threads(VideoWriter(out / "a.mp4", 30, (352, 288))) == "1"
    assert threads(VideoWriter(out / "a.mp4", 30, (1280, 720))) == "0"
    assert threads(VideoWriter(out / "a.mp4", 30, (352, 288), threads=4)) == "4"
    with pytest.raises(RenderError, match="threads"):
        VideoWriter(out / "a.mp4", 30, (W, H), threads=-1)
    frames = {}
    for n in (1, 0):
        path = out / f"t{n}.mp4"
        with VideoWriter(path, 30, (W, H), threads=n) as video:
            for _ in range(4):
                video.write(solid((200, 60, 30)))
        frames[n] = decoded_frames(path)
    assert len(frames[1]) == len(frames[0]) == 4
    assert np.abs(frames[1][0].astype(int) - frames[0][0].astype(int)).max() <= 2


def test_probe_rejects_missing_and_non_media_files(out: Path) -> None:
    with pytest.raises(RenderError, match="does not exist"):
        probe_media(out / "none.mp4")
    (out / "text.mp4").write_text("hello")
    with pytest.raises(RenderError, match="cannot read"):
        probe_media(out / "text.mp4")


# --- PNG ------------------------------------------------------------------------------------


def random_frames(n: int, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (H, W, 3), dtype=np.uint8) for _ in range(n)]


def test_png_sequence_is_lossless(out: Path) -> None:
    frames = random_frames(4)
    with PngSequenceWriter(out / "seq") as seq:
        for f in frames:
            seq.write(f)
    names = [FRAME_NAME.format(i) for i in range(4)]
    assert listing(out / "seq") == names == [f"frame_00000{i}.png" for i in range(4)]
    for name, f in zip(names, frames, strict=True):
        assert np.array_equal(np.asarray(Image.open(out / "seq" / name)), f)
    assert listing(out) == ["seq"]


def test_png_sequence_failure_leaves_no_half_directory(out: Path) -> None:
    with pytest.raises(KeyboardInterrupt), PngSequenceWriter(out / "seq") as seq:
        for f in random_frames(3):
            seq.write(f)
        raise KeyboardInterrupt
    assert listing(out) == []


def test_png_sequence_refuses_non_empty_folder(out: Path) -> None:
    (out / "seq").mkdir()
    (out / "seq" / "keep.txt").write_text("mine")
    with pytest.raises(RenderError, match="not empty"), PngSequenceWriter(out / "seq"):
        pass
    assert listing(out / "seq") == ["keep.txt"]


def test_png_sequence_overwrite(out: Path) -> None:
    (out / "seq").mkdir()
    (out / "seq" / "old.txt").write_text("old")
    with pytest.raises(RuntimeError), PngSequenceWriter(out / "seq", overwrite=True) as seq:
        seq.write(random_frames(1)[0])
        raise RuntimeError("fail")
    assert listing(out / "seq") == ["old.txt"]  # a failed overwrite keeps the old folder
    with PngSequenceWriter(out / "seq", overwrite=True) as seq:
        seq.write(random_frames(1)[0])
    assert listing(out / "seq") == ["frame_000000.png"]
    assert listing(out) == ["seq"]


def test_png_sequence_into_empty_folder_and_size_change(out: Path) -> None:
    (out / "seq").mkdir()
    with PngSequenceWriter(out / "seq") as seq:
        seq.write(random_frames(1)[0])
    assert listing(out / "seq") == ["frame_000000.png"]
    with pytest.raises(RenderError, match=r"\(48, 64, 3\)"), PngSequenceWriter(out / "b") as seq:
        seq.write(random_frames(1)[0])
        seq.write(np.zeros((10, 10, 3), np.uint8))
    assert listing(out) == ["seq"]


def test_write_png(out: Path) -> None:
    frame = random_frames(1)[0]
    write_png(out / "one.png", frame)
    assert np.array_equal(np.asarray(Image.open(out / "one.png")), frame)
    with pytest.raises(RenderError):
        write_png(out / "bad.png", frame[..., :2])
    assert listing(out) == ["one.png"]


# --- WAV ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("dtype", "channels"), [(np.float32, None), (np.int16, 2), (np.float64, 1)]
)
def test_wav_round_trip(out: Path, dtype: type, channels: int | None) -> None:
    rng = np.random.default_rng(1)
    shape = (1000,) if channels is None else (1000, channels)
    if dtype is np.int16:
        samples = rng.integers(-30000, 30000, shape).astype(np.int16)
    else:
        samples = rng.uniform(-1, 1, shape).astype(dtype)
    write_wav(out / "a.wav", samples, 16000)
    back, rate = soundfile.read(out / "a.wav", dtype=np.dtype(dtype).name)
    assert rate == 16000 and back.dtype == dtype
    assert np.array_equal(back.reshape(samples.shape), samples)  # soundfile squeezes (n, 1)
    info = probe_media(out / "a.wav")
    assert info.audio_samples == 1000 and info.audio_rate == 16000
    assert info.audio_channels == (channels or 1) and info.frames is None


@pytest.mark.parametrize(
    ("samples", "rate"),
    [
        (np.zeros(0, np.float32), 16000),
        (np.zeros((10, 2, 2), np.float32), 16000),
        (np.zeros(10, np.uint8), 16000),
        (np.zeros(10, np.float32), 0),
    ],
)
def test_wav_bad_input(out: Path, samples: np.ndarray, rate: int) -> None:
    with pytest.raises(RenderError):
        write_wav(out / "a.wav", samples, rate)
    assert listing(out) == []


# --- progress -------------------------------------------------------------------------------


@pytest.mark.parametrize("quiet", [True, False])
def test_progress_never_prints_off_terminal(quiet: bool, capsys: pytest.CaptureFixture) -> None:
    with progress(10, "rendering", quiet=quiet) as bar:
        for _ in range(10):
            bar.advance()
        bar.advance(2)
    assert bar.completed == 12 and not bar.enabled
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""
