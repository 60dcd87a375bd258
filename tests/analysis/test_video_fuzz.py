"""Fuzzing what ``vtts analyze`` reads (issue 21): folders of PNG frames and video files.

PNGs written by vtts's own writer (RGB, and grayscale, palette, RGBA and 16-bit ones through
Pillow) are mutated inside their chunks with the chunk CRCs recomputed, so that the damage
reaches the decoder; MP4s written by vtts's VideoWriter are mutated as they are (ffmpeg runs per
example, so there are fewer). Whatever the bytes, the only exception is AnalysisError (or
LimitError) naming the file; a frame that is read is an ``(H, W, 3) uint8`` array of the
declared size, and writes and reads back the same.
"""

from __future__ import annotations

import io
import shutil
import struct
import tempfile
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from PIL import Image

from vtts.analysis.video import load_png, read_video
from vtts.errors import AnalysisError
from vtts.limits import LimitError
from vtts.render import VideoWriter, write_png

from ..fuzzing import examples
from ..hostile import byte_mutations, mutate_bytes

DATA = Path(__file__).resolve().parents[1] / "data"
_FRAME = np.asarray(
    Image.open(DATA / "photos" / "akiyo_frame0.png").convert("RGB").resize((40, 32))
)

FUZZ = settings(
    max_examples=examples(150), deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
FEW = settings(
    max_examples=examples(12), deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


def _pngs() -> list[bytes]:
    """The test frame as vtts writes it (RGB), and grayscale, palette, RGBA and 16-bit."""
    with tempfile.TemporaryDirectory() as tmp:
        write_png(Path(tmp) / "rgb.png", _FRAME)
        out = [(Path(tmp) / "rgb.png").read_bytes()]
    img = Image.fromarray(_FRAME)
    for mode in ("L", "P", "RGBA", "I;16"):
        buf = io.BytesIO()
        (img.convert("L").convert(mode) if mode == "I;16" else img.convert(mode)).save(buf, "PNG")
        out.append(buf.getvalue())
    return out


def _mp4() -> bytes:
    """Five frames as vtts's VideoWriter writes them."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "tiny.mp4"
        with VideoWriter(path, 10, (40, 32)) as video:
            for k in range(5):
                video.write(np.roll(_FRAME, 3 * k, axis=1))
        return path.read_bytes()


# module constants rather than fixtures: hypothesis prints a failing example's fixtures whole
PNGS = _pngs()
MP4 = _mp4()


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("video")


def chunks(data: bytes) -> list[tuple[bytes, bytes]]:
    """The (type, data) chunks of a PNG."""
    out, pos = [], 8
    while pos + 8 <= len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        out.append((data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + length]))
        pos += 12 + length
    return out


def png(parts: list[tuple[bytes, bytes]]) -> bytes:
    """A PNG of ``parts`` with the lengths and CRCs right."""
    out = bytearray(b"\x89PNG\r\n\x1a\n")
    for kind, body in parts:
        out += struct.pack(">I", len(body)) + kind + body
        out += struct.pack(">I", zlib.crc32(kind + body))
    return bytes(out)


def load_or_analysis_error(path: Path, data: bytes) -> np.ndarray | None:
    path.write_bytes(data)
    try:
        frame = load_png(path)
    except (AnalysisError, LimitError) as e:
        assert e.file == str(path) and e.message, str(e)
        return None
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    with Image.open(path) as img:
        assert frame.shape[:2] == (img.size[1], img.size[0])
    write_png(path.with_name("again.png"), frame)
    assert np.array_equal(load_png(path.with_name("again.png")), frame)
    return frame


def test_the_pngs_read(folder: Path) -> None:
    for data in PNGS:
        assert load_or_analysis_error(folder / "f.png", data) is not None
        assert png(chunks(data)) == data


@FUZZ
@given(st.integers(0, 4), st.data(), byte_mutations)
def test_mutated_chunks(folder: Path, which: int, data, ops) -> None:
    parts = chunks(PNGS[which])
    k = data.draw(st.integers(0, len(parts) - 1))
    kind, body = parts[k]
    parts[k] = (kind, mutate_bytes(body, ops))
    load_or_analysis_error(folder / "c.png", png(parts))


@FUZZ
@given(st.integers(0, 4), byte_mutations)
def test_mutated_bytes(folder: Path, which: int, ops) -> None:
    load_or_analysis_error(folder / "b.png", mutate_bytes(PNGS[which], ops))


@FUZZ
@given(st.integers(0, 4), st.integers(0, 2**31 - 1), st.integers(0, 2**31 - 1))
@example(0, 829, 215_871)  # Pillow's DecompressionBombError escaped as a traceback
def test_declared_sizes(folder: Path, which: int, w: int, h: int) -> None:
    """Any width and height in the header (a small file may declare gigapixels)."""
    parts = chunks(PNGS[which])
    kind, body = parts[0]
    parts[0] = (kind, struct.pack(">II", w, h) + body[8:])
    load_or_analysis_error(folder / "s.png", png(parts))


@FEW
@given(st.lists(st.integers(0, 4), min_size=1, max_size=3), byte_mutations)
def test_folders(folder: Path, which: list[int], ops) -> None:
    """A folder of frames, the last one damaged: read_video and every frame."""
    frames = folder / "frames"
    shutil.rmtree(frames, ignore_errors=True)
    frames.mkdir()
    for k, i in enumerate(which):
        data = PNGS[i] if k + 1 < len(which) else mutate_bytes(PNGS[i], ops)
        (frames / f"frame_{k}.png").write_bytes(data)
    try:
        video = read_video(frames)
        got = list(video.frames())
    except (AnalysisError, LimitError) as e:
        assert e.file and e.message
        return
    assert len(got) == video.n_frames == len(which)


def read_or_analysis_error(path: Path, data: bytes) -> None:
    path.write_bytes(data)
    try:
        video = read_video(path)
        frames = list(video.frames())
    except (AnalysisError, LimitError) as e:
        assert e.file == str(path) and e.message, str(e)
        return
    w, h = video.size
    assert all(f.shape == (h, w, 3) and f.dtype == np.uint8 for f in frames)


def test_the_mp4_reads(folder: Path) -> None:
    (folder / "ok.mp4").write_bytes(MP4)
    assert len(list(read_video(folder / "ok.mp4").frames())) == 5


@FEW
@given(byte_mutations)
def test_mutated_mp4(folder: Path, ops) -> None:
    read_or_analysis_error(folder / "m.mp4", mutate_bytes(MP4, ops))


@FEW
@given(st.binary(max_size=300))
def test_random_video_bytes(folder: Path, data: bytes) -> None:
    read_or_analysis_error(folder / "r.mp4", data)
