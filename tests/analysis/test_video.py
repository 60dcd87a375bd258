"""Reading camera frames for the analysis: PNG folders and video files, and their errors."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from vtts.analysis.video import DEFAULT_FOLDER_FPS, natural_key, read_video
from vtts.errors import AnalysisError
from vtts.media import ffmpeg_exe
from vtts.render.output import VideoWriter

W, H = 64, 48


def pattern(i: int, w: int = W, h: int = H) -> np.ndarray:
    """A ``(h, w, 3) uint8`` frame that differs from frame to frame: a flat background whose red
    tells the frame number, and a bright square that moves right by 2 pixels per frame."""
    f = np.zeros((h, w, 3), np.uint8)
    f[:, :, 0] = 20 + 15 * i
    f[:, :, 1] = 90
    f[:, :, 2] = 40
    f[6:18, 8 + 2 * i : 24 + 2 * i] = (230, 230, 230)  # not symmetric: a flip shows
    return f


def write_pngs(folder: Path, names: list[str], frames: list[np.ndarray]) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for name, frame in zip(names, frames, strict=True):
        Image.fromarray(frame).save(folder / name)


# ---- folders of PNGs -----------------------------------------------------------------------------


def test_folder_frames_in_natural_order_with_exact_pixels(tmp_path):
    frames = [pattern(i) for i in range(12)]
    names = [f"frame_{i}.png" for i in range(12)]  # frame_10 sorts after frame_9
    write_pngs(tmp_path / "seq", names, frames)
    video = read_video(tmp_path / "seq")
    assert video.kind == "png"
    assert video.size == (W, H)
    assert video.n_frames == 12
    assert video.fps == DEFAULT_FOLDER_FPS == 25
    assert video.duration == pytest.approx(12 / 25)
    got = list(video.frames())
    assert len(got) == 12
    for i, (a, b) in enumerate(zip(got, frames, strict=True)):
        assert a.shape == (H, W, 3) and a.dtype == np.uint8
        np.testing.assert_array_equal(a, b, err_msg=f"frame {i}")


def test_folder_fps_is_given(tmp_path):
    write_pngs(tmp_path, ["a.png"], [pattern(0)])
    assert read_video(tmp_path, fps=12.5).fps == 12.5


@pytest.mark.parametrize("fps", [0, -1, float("nan"), float("inf")])
def test_bad_fps(tmp_path, fps):
    write_pngs(tmp_path, ["a.png"], [pattern(0)])
    with pytest.raises(AnalysisError, match="frame rate"):
        read_video(tmp_path, fps=fps)


def test_natural_key():
    names = ["f10.png", "f2.png", "F1.png", "f1b.png", "g.png", "f02.png"]
    assert sorted(names, key=natural_key) == [
        "F1.png",
        "f1b.png",
        "f02.png",
        "f2.png",
        "f10.png",
        "g.png",
    ]


def test_folder_ignores_other_and_hidden_files(tmp_path):
    write_pngs(
        tmp_path, ["b.png", "a.PNG", ".a.png.part.png"], [pattern(1), pattern(0), pattern(9)]
    )
    (tmp_path / "notes.txt").write_text("not a frame")
    (tmp_path / "sub.png").mkdir()
    video = read_video(tmp_path)
    assert video.n_frames == 2
    got = list(video)
    np.testing.assert_array_equal(got[0], pattern(0))
    np.testing.assert_array_equal(got[1], pattern(1))


def test_gray_palette_rgba_and_16_bit_become_rgb(tmp_path):
    rgb = pattern(3)
    gray = np.arange(W * H, dtype=np.uint32).reshape(H, W) % 251
    Image.fromarray(gray.astype(np.uint8), "L").save(tmp_path / "1.png")
    Image.fromarray(np.dstack([rgb, np.full((H, W), 7, np.uint8)]), "RGBA").save(tmp_path / "2.png")
    Image.fromarray(rgb).convert("P", palette=Image.Palette.ADAPTIVE, colors=8).save(
        tmp_path / "3.png"
    )
    Image.fromarray((gray * 257).astype(np.uint16)).save(tmp_path / "4.png")  # 16-bit gray
    got = list(read_video(tmp_path))
    assert [g.shape for g in got] == [(H, W, 3)] * 4
    assert all(g.dtype == np.uint8 for g in got)
    for c in range(3):
        np.testing.assert_array_equal(got[0][:, :, c], gray)
        np.testing.assert_array_equal(got[3][:, :, c], gray)
    np.testing.assert_array_equal(got[1], rgb)  # alpha dropped, colors kept
    palette = np.array(Image.open(tmp_path / "3.png").convert("RGB"))
    np.testing.assert_array_equal(got[2], palette)


def test_mixed_sizes_name_the_file_and_both_sizes(tmp_path):
    write_pngs(tmp_path, ["f1.png", "f2.png"], [pattern(0), pattern(1)])
    write_pngs(tmp_path, ["f10.png"], [pattern(2, w=40, h=30)])
    with pytest.raises(AnalysisError) as info:
        read_video(tmp_path)
    e = info.value
    assert e.file == str(tmp_path / "f10.png")
    assert "40x30" in e.message and f"{W}x{H}" in e.message and "f1.png" in e.message


def test_missing_path(tmp_path):
    with pytest.raises(AnalysisError, match="no such video file or PNG folder") as info:
        read_video(tmp_path / "none.mp4")
    assert info.value.file == str(tmp_path / "none.mp4")


def test_empty_folder(tmp_path):
    with pytest.raises(AnalysisError, match="no .png files") as info:
        read_video(tmp_path)
    assert info.value.file == str(tmp_path)
    (tmp_path / "a.jpg").write_bytes(b"\xff\xd8")
    with pytest.raises(AnalysisError, match="no .png files"):
        read_video(tmp_path)


def test_a_file_that_is_not_a_png(tmp_path):
    write_pngs(tmp_path, ["f1.png"], [pattern(0)])
    (tmp_path / "f2.png").write_text("this is text")
    with pytest.raises(AnalysisError, match="cannot read the PNG") as info:
        read_video(tmp_path)
    assert info.value.file == str(tmp_path / "f2.png")


def test_a_png_of_another_format(tmp_path):
    write_pngs(tmp_path, ["f1.png"], [pattern(0)])
    Image.fromarray(pattern(1)).save(tmp_path / "f2.png", format="BMP")
    with pytest.raises(AnalysisError, match="not a PNG file") as info:
        read_video(tmp_path)
    assert info.value.file == str(tmp_path / "f2.png")


def test_truncated_png_fails_when_its_frame_is_read(tmp_path):
    write_pngs(tmp_path, ["f1.png", "f2.png"], [pattern(0), pattern(1)])
    data = (tmp_path / "f2.png").read_bytes()
    (tmp_path / "f2.png").write_bytes(data[: len(data) // 2])  # the header is intact
    frames = read_video(tmp_path).frames()
    np.testing.assert_array_equal(next(frames), pattern(0))
    with pytest.raises(AnalysisError, match="cannot read the PNG") as info:
        next(frames)
    assert info.value.file == str(tmp_path / "f2.png")


def test_folder_frames_are_read_one_at_a_time(tmp_path):
    write_pngs(tmp_path, ["f1.png", "f2.png", "f3.png"], [pattern(i) for i in range(3)])
    video = read_video(tmp_path)
    frames = video.frames()
    next(frames)
    # a lazy reader has not touched the last file yet: replacing it changes what comes out
    Image.fromarray(pattern(7)).save(tmp_path / "f3.png")
    rest = list(frames)
    np.testing.assert_array_equal(rest[-1], pattern(7))
    assert len(list(video.frames())) == 3  # every call starts anew


# ---- video files ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def mp4(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("video") / "clip.mp4"
    with VideoWriter(path, 25, (W, H), crf=10) as video:
        for i in range(12):
            video.write(pattern(i))
    return path


def test_mp4_size_rate_and_count(mp4):
    video = read_video(mp4)
    assert video.kind == "video"
    assert (video.size, video.fps, video.n_frames) == ((W, H), 25.0, 12)
    assert read_video(mp4, fps=10).fps == 10


def test_mp4_frames_match_within_lossy_tolerance(mp4):
    got = list(read_video(mp4).frames())
    assert len(got) == 12
    for i, frame in enumerate(got):
        assert frame.shape == (H, W, 3) and frame.dtype == np.uint8
        want = pattern(i).astype(int)
        diff = np.abs(frame.astype(int) - want)
        assert diff.mean() < 4, (i, diff.mean())
        # the flat background away from the square and the chroma edges: close everywhere
        assert np.abs(frame[28:44, 2:60].astype(int) - want[28:44, 2:60]).max() <= 6, i
        # frames come in order: the red of the background counts them
        assert abs(int(frame[40, 4, 0]) - (20 + 15 * i)) <= 4


def test_mp4_stopping_early_and_reading_again(mp4):
    video = read_video(mp4)
    frames = video.frames()
    first = next(frames)
    frames.close()  # stops ffmpeg
    again = next(iter(video))
    np.testing.assert_array_equal(first, again)


def _ffmpeg(*args: str) -> None:
    cmd = [ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y", *args]
    subprocess.run(cmd, check=True, capture_output=True, timeout=60)


def test_video_with_zero_frames(tmp_path):
    path = tmp_path / "zero.mp4"
    _ffmpeg("-f", "lavfi", "-i", f"color=c=red:s={W}x{H}:r=25", "-frames:v", "0", str(path))
    assert path.is_file()
    with pytest.raises(AnalysisError, match="has no frames") as info:
        read_video(path)
    assert info.value.file == str(path)


def test_audio_only_file(tmp_path):
    path = tmp_path / "speech.m4a"
    _ffmpeg("-f", "lavfi", "-i", "sine=d=0.3", "-c:a", "aac", str(path))
    with pytest.raises(AnalysisError, match="no video stream"):
        read_video(path)


@pytest.mark.parametrize("content", [b"", b"this is not a video", b"\x00\x00\x00\x18ftypmp42" * 3])
def test_corrupt_video(tmp_path, content):
    path = tmp_path / "broken.mp4"
    path.write_bytes(content)
    with pytest.raises(AnalysisError, match="cannot read the video") as info:
        read_video(path)
    assert info.value.file == str(path)
    assert "\n" not in info.value.message


def test_truncated_video_decodes_the_frames_it_has(tmp_path, mp4):
    # with the index at the front (+faststart), a cut file still opens; it yields fewer frames
    path = tmp_path / "cut.mp4"
    data = mp4.read_bytes()
    path.write_bytes(data[: len(data) * 2 // 3])
    try:
        video = read_video(path)
    except AnalysisError as e:  # or ffmpeg refuses it: then with a clear error
        assert e.file == str(path)
        return
    got = list(video.frames())
    assert len(got) <= 12
    assert all(f.shape == (H, W, 3) for f in got)


def test_reading_a_video_leaks_no_pipes(mp4):
    # the CLI prints every warning: a ResourceWarning per video would reach the user
    code = (
        "import gc, sys; from vtts.analysis.video import read_video\n"
        "v = read_video(sys.argv[1])\n"
        "assert sum(1 for _ in v.frames()) == 12\n"
        "it = v.frames(); next(it); it.close()\n"
        "gc.collect()\n"
    )
    r = subprocess.run(
        [sys.executable, "-W", "always", "-c", code, str(mp4)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    assert "ResourceWarning" not in r.stderr, r.stderr
