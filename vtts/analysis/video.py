"""The camera frames an analysis reads: a video file (through ffmpeg) or a folder of PNGs.

:func:`read_video` checks the input and returns a :class:`Video`: its size, frame rate and
(when known) frame count, and :meth:`Video.frames`, which decodes the frames one at a time as
``(H, W, 3) uint8`` RGB arrays, top row first — never the whole video in memory.

A pipe (:func:`read_pipe`, ``vtts analyze -``) carries raw ``rgb24`` frames, such as
``ffmpeg … -f rawvideo -pix_fmt rgb24 -`` writes: W·H·3 bytes a frame, top row first, with
neither header nor size of its own, so the size is given (``--size``) and the rate too
(``--fps``, default 25). Its frames are read as they arrive, once.

A video file is anything the ffmpeg of the ``imageio-ffmpeg`` wheel reads (MP4, AVI, MKV, …);
its frame count and rate come from the packets' time stamps (:func:`vtts.render.probe_media`).
A folder of PNGs is read in natural name order (``frame_2.png`` before ``frame_10.png``); every
PNG must have the size of the first, and grayscale, palette and RGBA images become RGB (alpha is
dropped). A folder has no frame rate of its own: it is given (``--fps``, default 25).

Every problem is an :class:`~vtts.errors.AnalysisError` whose ``file`` names the file at fault.
"""

from __future__ import annotations

import math
import os
import re
import subprocess
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np

from vtts.errors import AnalysisError, RenderError
from vtts.limits import MAX_IMAGE_PIXELS, LimitError, check_image_size

#: Frame rate of a PNG folder when none is given (frames per second).
DEFAULT_FOLDER_FPS = 25.0

#: File suffix of the frames of a folder (case-insensitive).
PNG_SUFFIX = ".png"


@dataclass(frozen=True)
class Video:
    """A sequence of camera frames, read lazily.

    path      the video file or PNG folder
    size      ``(W, H)`` in pixels
    fps       frames per second
    n_frames  how many frames the file indexes (a damaged file may decode fewer), or None when
              not known before decoding
    kind      ``"video"`` (a file decoded by ffmpeg), ``"png"`` (a folder) or ``"pipe"`` (raw
              frames read as they arrive: :func:`read_pipe`; its frames can be read once)
    """

    path: Path
    size: tuple[int, int]
    fps: float
    n_frames: int | None
    kind: str
    _reader: Callable[[], Iterator[np.ndarray]] = field(repr=False, compare=False)

    @property
    def duration(self) -> float | None:
        """Seconds of video (``n_frames / fps``), None when the frame count is not known."""
        return None if self.n_frames is None else self.n_frames / self.fps

    def frames(self) -> Iterator[np.ndarray]:
        """The frames from the first, each a new ``(H, W, 3) uint8`` RGB array.

        Each call starts reading anew; stopping early releases the decoder."""
        return self._reader()

    def __iter__(self) -> Iterator[np.ndarray]:
        return self.frames()


def read_video(path: str | os.PathLike[str], *, fps: float | None = None) -> Video:
    """Open a video file or a folder of PNGs for reading.

    ``fps`` (frames per second) overrides the rate a video file states and gives a folder its
    rate (default :data:`DEFAULT_FOLDER_FPS`). Raises :class:`~vtts.errors.AnalysisError` for a
    missing path, an empty folder, a PNG of another size than the first, an unreadable file or a
    video without frames.
    """
    p = Path(path)
    if fps is not None and not (math.isfinite(fps) and fps > 0):
        raise AnalysisError(f"the frame rate must be a positive number, got {fps!r}")
    if p.is_dir():
        return _read_folder(p, DEFAULT_FOLDER_FPS if fps is None else float(fps))
    if not p.exists():
        raise AnalysisError("no such video file or PNG folder", file=str(p))
    if not p.is_file():
        raise AnalysisError(
            "not a video file nor a folder of PNGs (a pipe or a device cannot be analyzed)",
            file=str(p),
        )
    return _read_file(p, fps)


#: Frame rate of a pipe of raw frames when none is given (frames per second).
DEFAULT_PIPE_FPS = 25.0
#: The smallest frame side of a pipe, in pixels (what the renderer draws at least).
MIN_PIPE_SIDE = 16


def read_pipe(
    source: BinaryIO,
    size: tuple[int, int],
    *,
    fps: float | None = None,
    name: str = "-",
) -> Video:
    """Raw ``rgb24`` frames of ``size`` ``(W, H)`` from the binary file object ``source`` (a pipe:
    ``ffmpeg … -f rawvideo -pix_fmt rgb24 -``), each read when it has arrived whole.

    ``fps`` defaults to :data:`DEFAULT_PIPE_FPS`; ``name`` names the pipe in errors. The frame
    count is not known (``n_frames`` None). A pipe that ends inside a frame is an error naming
    the byte offset where the incomplete frame starts and how many of its bytes came (the size
    is likely wrong), raised after the complete frames were yielded; frames can be read once.
    """
    w, h = (int(v) for v in size)
    if min(w, h) < MIN_PIPE_SIDE:
        raise AnalysisError(
            f"the frame size {w}x{h} is too small: at least {MIN_PIPE_SIDE} pixels a side",
            file=name,
        )
    check_image_size(w, h, file=name, what="frame")
    if fps is not None and not (math.isfinite(fps) and fps > 0):
        raise AnalysisError(f"the frame rate must be a positive number, got {fps!r}")
    rate = DEFAULT_PIPE_FPS if fps is None else float(fps)
    used = [False]

    def frames() -> Iterator[np.ndarray]:
        if used[0]:
            raise AnalysisError("the frames of a pipe can be read once", file=name)
        used[0] = True
        n = w * h * 3
        index = 0
        while True:
            buf = bytearray(n)
            got = _read_into(source, memoryview(buf))
            if got == 0:
                return
            if got < n:
                raise AnalysisError(
                    f"byte {index * n}: the pipe ends inside frame {index} ({got} of its {n} "
                    f"bytes came): are the frames {w}x{h} rgb24 (--size)?",
                    file=name,
                )
            yield np.frombuffer(buf, dtype=np.uint8).reshape(h, w, 3)
            index += 1

    return Video(Path(name), (w, h), rate, None, "pipe", frames)


def _read_into(source: BinaryIO, view: memoryview) -> int:
    """Fill ``view`` from ``source``; fewer bytes only at its end."""
    got = 0
    while got < len(view):
        k = source.readinto(view[got:])  # type: ignore[attr-defined]
        if not k:
            break
        got += k
    return got


# ---- folders of PNGs -----------------------------------------------------------------------------


def natural_key(name: str) -> tuple:
    """Sort key of a file name with its digit runs compared as numbers (2 < 10)."""
    parts = re.split(r"(\d+)", name)
    # digit runs sit at the odd positions of the split, so tuples compare str with str, int with int
    return tuple(int(t) if i % 2 else t.lower() for i, t in enumerate(parts)), name


def _png_files(folder: Path) -> list[Path]:
    try:
        entries = list(folder.iterdir())
    except OSError as e:
        raise AnalysisError(
            f"cannot list the folder: {e.strerror or e}", file=str(folder)
        ) from None
    # hidden files are the temporary files of writers (.frame_000001.png.part) and editors' litter
    pngs = [
        e
        for e in entries
        if e.suffix.lower() == PNG_SUFFIX and not e.name.startswith(".") and e.is_file()
    ]
    return sorted(pngs, key=lambda e: natural_key(e.name))


def _png_size(path: Path) -> tuple[int, int]:
    """``(W, H)`` from a PNG's header, without decoding its pixels."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as img:
            if img.format != "PNG":
                raise AnalysisError(
                    f"not a PNG file (Pillow reads it as {img.format})", file=str(path)
                )
            check_image_size(*img.size, file=str(path), what="frame")
            return img.size
    except Image.DecompressionBombError as e:
        raise _too_large(e, path) from None
    except (OSError, UnidentifiedImageError, ValueError) as e:
        raise AnalysisError(f"cannot read the PNG: {_reason(e)}", file=str(path)) from None


def _read_folder(folder: Path, fps: float) -> Video:
    files = _png_files(folder)
    if not files:
        raise AnalysisError(
            f"the folder has no {PNG_SUFFIX} files (a folder input is a sequence of PNG frames)",
            file=str(folder),
        )
    size = _png_size(files[0])
    # every header is checked before the analysis starts: a bad frame should not cost the
    # minutes of estimation before it
    for f in files[1:]:
        other = _png_size(f)
        if other != size:
            raise AnalysisError(
                f"the frame is {other[0]}x{other[1]} pixels but the first frame, {files[0].name}, "
                f"is {size[0]}x{size[1]}: every PNG of a folder must have the same size",
                file=str(f),
            )

    def frames() -> Iterator[np.ndarray]:
        for f in files:
            yield load_png(f, size)

    return Video(folder, size, fps, len(files), "png", frames)


def load_png(path: str | os.PathLike[str], size: tuple[int, int] | None = None) -> np.ndarray:
    """One PNG as an ``(H, W, 3) uint8`` RGB array; ``size`` ``(W, H)`` is checked when given.

    Grayscale and palette images are expanded, alpha is dropped, 16-bit samples keep their 8
    most significant bits."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as img:
            check_image_size(*img.size, file=str(path), what="frame")
            if size is not None and img.size != tuple(size):
                raise AnalysisError(
                    f"the frame is {img.size[0]}x{img.size[1]} pixels, expected "
                    f"{size[0]}x{size[1]}",
                    file=str(path),
                )
            if img.mode.startswith("I"):  # 16-bit (or 32-bit integer) grayscale
                gray = (np.asarray(img, dtype=np.int64) >> 8).clip(0, 255).astype(np.uint8)
                return np.repeat(gray[:, :, None], 3, axis=2)
            return np.array(img.convert("RGB"), dtype=np.uint8)
    except Image.DecompressionBombError as e:
        raise _too_large(e, path) from None
    except (OSError, UnidentifiedImageError, ValueError, SyntaxError) as e:
        raise AnalysisError(f"cannot read the PNG: {_reason(e)}", file=str(path)) from None


def _too_large(e: Exception, path: str | os.PathLike[str]) -> LimitError:
    """Pillow refuses to open an image of over 179 million pixels, before its size is known."""
    return LimitError(
        f"the frame is larger than the limit of {MAX_IMAGE_PIXELS} pixels ({e})", file=str(path)
    )


# ---- video files ---------------------------------------------------------------------------------


def _read_file(path: Path, fps: float | None) -> Video:
    from vtts.render.output import probe_media

    if not os.access(path, os.R_OK):
        raise AnalysisError("cannot read the video: permission denied", file=str(path))
    try:
        info = probe_media(path)
    except RenderError as e:
        if "does not contain any stream" in e.message:  # a container without streams
            raise AnalysisError(
                "the video has no frames (the file holds no stream at all)", file=str(path)
            ) from None
        raise AnalysisError(
            f"cannot read the video (ffmpeg: {_ffmpeg_reason(e.message)})", file=str(path)
        ) from None
    if info.frames is None or info.width is None or info.height is None:
        raise AnalysisError("the file has no video stream", file=str(path))
    if info.frames == 0:
        raise AnalysisError("the video has no frames", file=str(path))
    rate = fps if fps is not None else info.fps
    if rate is None or not (math.isfinite(rate) and rate > 0):
        raise AnalysisError("the video states no frame rate: give one (--fps)", file=str(path))
    size = (info.width, info.height)
    check_image_size(*size, file=str(path), what="video frame")

    def frames() -> Iterator[np.ndarray]:
        yield from _decode(path, size)

    return Video(path, size, float(rate), info.frames, "video", frames)


def _decode(path: Path, size: tuple[int, int]) -> Iterator[np.ndarray]:
    """Decode ``path`` frame by frame with the wheel's ffmpeg (RGB, the stored size)."""
    import imageio_ffmpeg

    w, h = size
    # -vsync passthrough: one output frame per decoded frame, never duplicated or dropped to
    # match a nominal rate; the frame index is then the index in the file
    gen = imageio_ffmpeg.read_frames(
        str(path), pix_fmt="rgb24", output_params=["-fps_mode", "passthrough"]
    )
    process = None
    try:
        try:
            meta = next(gen)
        except (OSError, RuntimeError, StopIteration) as e:
            raise AnalysisError(f"cannot decode the video: {_reason(e)}", file=str(path)) from None
        # read_frames closes ffmpeg's pipes only when it stops ffmpeg early, not after ffmpeg
        # ended by itself (a ResourceWarning per video): keep its process to close them
        frame = gen.gi_frame
        process = frame.f_locals.get("process") if frame is not None else None
        if tuple(meta.get("size", size)) != (w, h):
            raise AnalysisError(
                f"ffmpeg decodes the video at {meta['size'][0]}x{meta['size'][1]} pixels, "
                f"its stream states {w}x{h}",
                file=str(path),
            )
        index = 0
        while True:
            try:
                data = next(gen)
            except StopIteration:
                return
            except (OSError, RuntimeError) as e:
                raise AnalysisError(
                    f"cannot decode frame {index} of the video: {_reason(e)}", file=str(path)
                ) from None
            yield np.frombuffer(data, dtype=np.uint8).reshape(h, w, 3).copy()
            index += 1
    finally:
        gen.close()  # stops ffmpeg when the reader stops early
        if isinstance(process, subprocess.Popen):
            for pipe in (process.stdin, process.stdout):
                if pipe is not None and not pipe.closed:
                    pipe.close()


def _reason(e: BaseException) -> str:
    text = getattr(e, "strerror", None) or str(e) or type(e).__name__
    return _ffmpeg_reason(text)


def _ffmpeg_reason(text: str) -> str:
    """The informative part of an ffmpeg or imageio-ffmpeg message: its last line, without the
    ``[component @ address]`` prefix."""
    lines = [_FFMPEG_PREFIX.sub("", line).strip() for line in text.strip().splitlines()]
    lines = [line for line in lines if line and not line.startswith("===")]
    return lines[-1] if lines else "unknown error"


# "[in#0 @ 0x55c04fb74d80] " before ffmpeg's messages
_FFMPEG_PREFIX = re.compile(r"^\[[^\]]* @ 0x[0-9a-f]+\]\s*")
