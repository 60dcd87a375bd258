"""Output writers of the renderer: MP4 (H.264 + AAC), PNG sequences, single PNGs and WAV files.

Frames are ``(H, W, 3) uint8`` RGB arrays, top row first, as the renderer returns them; PNGs also
take ``(H, W, 4)`` RGBA frames (a renderer with a transparent background), video does not.

Video goes through the ffmpeg binary that the ``imageio-ffmpeg`` wheel carries (it has libx264 and
the native AAC encoder), so no system package is needed. Raw ``rgb24`` frames are piped to its
stdin; an optional WAV is muxed as AAC.

Nothing is ever half-written: every output is written under a temporary name beside its
destination (see :mod:`vtts.atomic`) and renamed when complete. An exception or Ctrl-C inside a
writer's ``with`` block kills the encoder and removes the temporary file or folder.

:func:`probe_media` reads back what was written (frame count, durations, size, audio rate) with
the same binary, since the wheel carries no ffprobe.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from types import TracebackType
from typing import IO, Any

import numpy as np

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

from vtts.atomic import atomic_path, current_umask, replace_folder
from vtts.errors import RenderError
from vtts.media import ffmpeg_exe

__all__ = [
    "AAC_ARGS",
    "FRAME_NAME",
    "AacTrack",
    "MediaInfo",
    "PngSequenceWriter",
    "ProgressBar",
    "VideoWriter",
    "probe_media",
    "progress",
    "write_png",
    "write_wav",
]

#: File name of frame ``i`` in a PNG sequence folder.
FRAME_NAME = "frame_{:06d}.png"

#: ffmpeg's encoder settings of an MP4's sound: its native AAC encoder at 128 kbit/s.
AAC_ARGS = ("-c:a", "aac", "-b:a", "128k")

#: How many lines of ffmpeg's stderr a :class:`RenderError` quotes.
_STDERR_TAIL_LINES = 12


def _check_frame(frame: Any, shape: tuple[int, int, int] | None, rgba: bool = False) -> np.ndarray:
    """Return ``frame`` as a C-contiguous ``(H, W, 3) uint8`` array (or ``(H, W, 4)`` RGBA where
    ``rgba`` allows it) or raise RenderError.

    ``shape`` is the expected ``(H, W, C)``; None accepts any height and width.
    """
    arr = np.asarray(frame)
    channels = (3, 4) if rgba else (3,)
    ok = arr.dtype == np.uint8 and arr.ndim == 3 and arr.shape[2] in channels
    if ok and shape is not None:
        ok = arr.shape == shape
    if not ok:
        if shape is not None:
            want = f"a {shape} uint8 array"
        elif rgba:
            want = "an (H, W, 3) uint8 RGB or (H, W, 4) RGBA array"
        else:
            want = "an (H, W, 3) uint8 RGB array"
        why = " (video has no alpha)" if not rgba and arr.shape[-1:] == (4,) else ""
        raise RenderError(f"frame must be {want}, got {arr.shape} {arr.dtype}{why}")
    return np.ascontiguousarray(arr)


def _tail(text: str, n: int = _STDERR_TAIL_LINES) -> str:
    lines = [line for line in text.strip().splitlines() if line.strip()]
    return "\n".join(lines[-n:])


def _check_audio(audio: str | os.PathLike[str]) -> Path:
    """Return ``audio`` as a Path after checking that soundfile can read it."""
    import soundfile

    path = Path(audio)
    if not path.is_file():
        raise RenderError(f"audio file {str(path)!r} does not exist")
    try:
        soundfile.info(str(path))
    except (soundfile.SoundFileError, RuntimeError, OSError) as exc:
        raise RenderError(f"audio file {str(path)!r} cannot be read: {exc}") from exc
    return path


def _rate_arg(fps: float) -> str:
    """ffmpeg's spelling of a frame rate: exact fractions for NTSC-style rates (30000/1001)."""
    frac = Fraction(fps).limit_denominator(10000)
    return str(frac.numerator) if frac.denominator == 1 else f"{frac.numerator}/{frac.denominator}"


def _popen_group_kwargs() -> dict[str, Any]:
    # ffmpeg runs in its own process group so that the terminal's Ctrl-C reaches Python only:
    # the writer then kills ffmpeg itself and removes the temporary file, instead of racing
    # ffmpeg's own SIGINT handler, which would finish a truncated file.
    if os.name == "posix":
        return {"process_group": 0}
    return {"creationflags": getattr(subprocess, "CREATE_NEW_PROCESS_GROUP", 0)}


def _widen_pipe(fd: int, size: int) -> None:
    """Let the pipe ``fd`` hold ``size`` bytes where the system allows (Linux; up to
    ``/proc/sys/fs/pipe-max-size``, 1 MiB by default). A frame then goes to ffmpeg in one write
    instead of a handful of 64 KiB turns between the two processes, which costs both of them
    about a millisecond per frame."""
    set_size = getattr(fcntl, "F_SETPIPE_SZ", None) if fcntl is not None else None
    if set_size is None:
        return
    try:
        limit = int(Path("/proc/sys/fs/pipe-max-size").read_text())
    except (OSError, ValueError):
        limit = 1 << 20
    with contextlib.suppress(OSError):
        fcntl.fcntl(fd, set_size, min(size, limit))


def _finish_or_abort(
    self,
    exc_type: type[BaseException] | None,
    exc: BaseException | None,
    tb: TracebackType | None,
) -> None:
    """``__exit__`` of the writers: complete the output, or leave nothing when the block failed
    (an exception or Ctrl-C)."""
    if exc_type is None:
        self.close()
    else:
        self.abort()


#: The largest frame (pixels) a :class:`VideoWriter` encodes on one thread by default (VGA).
ONE_THREAD_PIXELS = 640 * 480


class AacTrack:
    """A sound file encoded as an MP4's AAC track (:data:`AAC_ARGS`) by ffmpeg in the
    background, for a :class:`VideoWriter` to copy instead of encoding it while the frames
    arrive; the decoded samples are the same either way.

    ``vtts say`` starts it as soon as the speech is synthesized: the encoding then runs while
    the renderer is set up, on a core the start-up leaves idle, instead of beside the frames,
    which keep both cores of a small machine busy (docs/rendering.md, "Speed"). ``source`` is
    any file soundfile reads; the track is written into ``folder`` (which must outlive it).
    :meth:`result` waits for the encoding and gives the track's path; :meth:`close` (or leaving
    a ``with`` block) stops an encoding still running."""

    def __init__(self, source: str | os.PathLike[str], folder: str | os.PathLike[str]) -> None:
        self.source = _check_audio(source)
        self.path = Path(folder) / f"{self.source.stem}.m4a"
        self._stderr: IO[bytes] | None = tempfile.TemporaryFile()
        self._done, self._error = False, None
        cmd = [
            ffmpeg_exe(), "-hide_banner", "-nostats", "-loglevel", "error", "-y",
            "-i", str(self.source), "-vn", *AAC_ARGS, "-f", "mp4", str(self.path),
        ]  # fmt: skip
        try:
            self._proc: subprocess.Popen[bytes] | None = subprocess.Popen(
                cmd,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=self._stderr,
                **_popen_group_kwargs(),
            )
        except OSError as exc:
            self.close()
            raise RenderError(f"{self.source}: cannot start ffmpeg: {exc}") from exc

    def result(self) -> Path:
        """Wait for the encoding; the track's path. RenderError if ffmpeg failed."""
        if self._done:
            return self.path
        if self._error is not None:
            raise self._error
        if self._proc is None:
            raise RenderError(f"{self.source}: the AAC encoding was stopped")
        rc = self._proc.wait()
        if rc != 0:
            message = ""
            if self._stderr is not None:
                self._stderr.seek(0)
                message = _tail(self._stderr.read().decode("utf-8", "replace"))
            self.close()
            self._error = RenderError(f"{self.source}: ffmpeg could not encode the sound "
                                      f"(exit status {rc}):\n{message}")  # fmt: skip
            raise self._error
        self._done = True
        return self.path

    def close(self) -> None:
        """Stop the encoding if it still runs (the file it wrote is the folder owner's)."""
        proc, self._proc = getattr(self, "_proc", None), None
        if proc is not None and proc.poll() is None:
            with contextlib.suppress(OSError):
                proc.kill()
            proc.wait()
        if self._stderr is not None:
            self._stderr.close()
            self._stderr = None

    def __enter__(self) -> AacTrack:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class VideoWriter:
    """Write frames to an MP4 file (H.264, yuv420p, optionally with a WAV muxed as AAC).

    Use it as a context manager::

        with VideoWriter("out.mp4", fps=30, size=(352, 288), audio="speech.wav") as video:
            for frame in frames:          # (288, 352, 3) uint8
                video.write(frame)

    ``size`` is ``(W, H)`` in pixels and every frame must be ``(H, W, 3) uint8``. H.264 in yuv420p
    needs even dimensions: an odd width or height is padded with one black column on the right or
    one black row at the bottom (``output_size`` gives the size in the file). ``fps`` is frames
    per second; the video lasts ``frames_written / fps`` seconds.

    ``audio`` is any file soundfile reads (WAV, FLAC, ...); it is encoded as AAC at 128 kbit/s
    and muxed whole. An :class:`AacTrack` is that encoding made beforehand: it is copied into
    the file as it is (the same samples). The video is never cut to the audio nor the audio to
    the video (no ``-shortest``, which can drop the last video frames): each stream keeps its
    own length.

    ``crf`` (0–51, lower is better) and ``preset`` are libx264's quality and speed settings.
    ``threads``: libx264's threads (0: its own choice, 1.5 per core). The default is one for
    frames up to :data:`ONE_THREAD_PIXELS` and libx264's choice above: a small frame encodes
    quickly on one core, while the rasterizer keeps both cores of a small machine busy, and
    libx264's threads then only contend with it (the same video quality, less CPU time:
    docs/rendering.md, "Speed").

    On a clean exit ffmpeg is closed and the temporary file renamed to ``path``; on an exception
    (including KeyboardInterrupt) ffmpeg is killed and neither ``path`` nor the temporary file is
    left. An existing ``path`` is replaced only on success.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        fps: float,
        size: tuple[int, int],
        audio: str | os.PathLike[str] | AacTrack | None = None,
        crf: int = 18,
        preset: str = "veryfast",
        threads: int | None = None,
    ) -> None:
        self.path = Path(path)
        if not (np.isfinite(fps) and fps > 0):
            raise RenderError(f"fps must be a positive number, got {fps!r}")
        if len(size) != 2 or not all(isinstance(v, int | np.integer) and v > 0 for v in size):
            raise RenderError(f"size must be (W, H) with positive integers, got {size!r}")
        if not 0 <= crf <= 51:
            raise RenderError(f"crf must be in 0..51, got {crf}")
        self.fps = float(fps)
        self.size = (int(size[0]), int(size[1]))
        self._track = audio if isinstance(audio, AacTrack) else None
        if self._track is not None:
            self.audio: Path | None = self._track.source
        else:
            self.audio = _check_audio(audio) if audio is not None else None
        self.crf = int(crf)
        self.preset = preset
        if threads is None:
            threads = 1 if self.size[0] * self.size[1] <= ONE_THREAD_PIXELS else 0
        if threads < 0:
            raise RenderError(f"threads must be 0 (libx264's choice) or more, got {threads}")
        self.threads = int(threads)
        self.frames_written = 0
        self._shape = (self.size[1], self.size[0], 3)
        self._proc: subprocess.Popen[bytes] | None = None
        self._stderr: IO[bytes] | None = None
        self._stack: contextlib.ExitStack | None = None
        self._tmp: Path | None = None

    @property
    def output_size(self) -> tuple[int, int]:
        """``(W, H)`` of the encoded video: ``size`` rounded up to even numbers."""
        w, h = self.size
        return (w + w % 2, h + h % 2)

    @property
    def duration(self) -> float:
        """Seconds of video written so far."""
        return self.frames_written / self.fps

    def command(self, output: str | os.PathLike[str]) -> list[str]:
        """The ffmpeg command line that encodes stdin to ``output``."""
        w, h = self.size
        cmd = [
            ffmpeg_exe(), "-hide_banner", "-nostats", "-loglevel", "error", "-y",
            "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{w}x{h}",
            "-r", _rate_arg(self.fps), "-i", "-",
        ]  # fmt: skip
        if self._track is not None:
            cmd += ["-i", str(self._track.result())]  # encoded already: copied as it is
        elif self.audio is not None:
            cmd += ["-i", str(self.audio)]
        cmd += ["-map", "0:v:0"]
        if self.audio is not None:
            cmd += ["-map", "1:a:0"]
        cmd += [
            "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2",
            "-c:v", "libx264", "-threads", str(self.threads), "-preset", self.preset,
            "-crf", str(self.crf),
            "-pix_fmt", "yuv420p",
        ]  # fmt: skip
        if self.audio is not None:
            cmd += ["-c:a", "copy"] if self._track is not None else list(AAC_ARGS)
        cmd += ["-movflags", "+faststart", "-f", "mp4", str(output)]
        return cmd

    def open(self) -> VideoWriter:
        """Start ffmpeg writing to a temporary file beside ``path`` (``__enter__`` calls it)."""
        if self._proc is not None:
            raise RenderError(f"{self.path}: the video writer is already open")
        stack = contextlib.ExitStack()
        try:
            self._tmp = stack.enter_context(atomic_path(self.path))
            self._stderr = stack.enter_context(tempfile.TemporaryFile())
            self._proc = subprocess.Popen(
                self.command(self._tmp),
                stdin=subprocess.PIPE,
                stdout=subprocess.DEVNULL,
                stderr=self._stderr,
                bufsize=0,
                **_popen_group_kwargs(),
            )
        except BaseException as exc:
            stack.__exit__(type(exc), exc, exc.__traceback__)
            if isinstance(exc, OSError):
                raise RenderError(f"{self.path}: cannot start ffmpeg: {exc}") from exc
            raise
        assert self._proc.stdin is not None
        frame_bytes = int(np.prod(self._shape))
        _widen_pipe(self._proc.stdin.fileno(), 3 * frame_bytes)  # room for a few frames
        self._stack = stack
        self.frames_written = 0
        return self

    def write(self, frame: np.ndarray) -> None:
        """Append one ``(H, W, 3) uint8`` RGB frame."""
        if self._proc is None or self._proc.stdin is None:
            raise RenderError(f"{self.path}: write() on a video writer that is not open")
        arr = _check_frame(frame, self._shape)
        try:
            self._proc.stdin.write(memoryview(arr).cast("B"))
        except OSError as exc:  # BrokenPipeError: ffmpeg died
            message = self._failure_message()
            self.abort()
            raise RenderError(f"{self.path}: ffmpeg stopped reading frames: {message}") from exc
        self.frames_written += 1

    def close(self) -> None:
        """Finish the encoding and rename the temporary file to ``path``.

        Raises RenderError (and leaves no file) when no frame was written or ffmpeg fails.
        """
        if self._proc is None:
            return
        try:
            if self.frames_written == 0:
                raise RenderError(f"{self.path}: no frames were written")
            proc = self._proc
            assert proc.stdin is not None
            with contextlib.suppress(BrokenPipeError):
                proc.stdin.close()
            rc = proc.wait()
            if rc != 0:
                raise RenderError(
                    f"{self.path}: ffmpeg failed (exit status {rc}):\n{self._failure_message()}"
                )
        except BaseException:
            self.abort()
            raise
        stack, self._stack, self._proc = self._stack, None, None
        assert stack is not None
        stack.close()  # renames the temporary file; closes the stderr file

    def abort(self) -> None:
        """Kill ffmpeg and remove the temporary file; ``path`` is left untouched."""
        proc, stack = self._proc, self._stack
        self._proc, self._stack = None, None
        if proc is not None:
            with contextlib.suppress(OSError):
                proc.kill()
            with contextlib.suppress(OSError):
                if proc.stdin is not None:
                    proc.stdin.close()
            proc.wait()
        if stack is not None:
            # atomic_path removes its temporary file when it sees an exception.
            stop = _Aborted()
            stack.__exit__(_Aborted, stop, None)

    def _failure_message(self) -> str:
        if self._stderr is None:
            return ""
        if self._proc is not None:
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._proc.wait(timeout=5)
        self._stderr.seek(0)
        return _tail(self._stderr.read().decode("utf-8", "replace")) or "(no message)"

    def __enter__(self) -> VideoWriter:
        return self.open()

    __exit__ = _finish_or_abort


class _Aborted(Exception):
    """Internal signal thrown into :func:`atomic_path` so that it removes its temporary file."""


def _move_into(tmp: Path, dest: Path) -> None:
    """Move the files of the folder ``tmp`` (inside ``dest``) into ``dest`` and remove it; on a
    failure the files moved so far go back, so ``dest`` is left as it was."""
    moved: list[str] = []
    try:
        for f in sorted(tmp.iterdir()):
            os.replace(f, dest / f.name)
            moved.append(f.name)
    except BaseException:
        for name in moved:
            with contextlib.suppress(OSError):
                os.replace(dest / name, tmp / name)
        raise
    tmp.rmdir()


class PngSequenceWriter:
    """Write frames losslessly as ``DIR/frame_000000.png``, ``frame_000001.png``, ...

    Frames go to a temporary sibling folder ``.DIR.XXXX.part`` which is renamed to ``DIR`` when
    the ``with`` block ends cleanly; on an exception or Ctrl-C it is removed and ``DIR`` is
    untouched. An existing empty ``DIR`` (``.`` too) is kept: the temporary folder is made
    inside it and the frames are moved out of it at the end. An existing non-empty ``DIR`` is
    an error unless ``overwrite=True``; then it is
    replaced at the end by two renames (old folder aside, new folder in), so that ``DIR`` is
    either the old or the new sequence, never a mixture.

    Every frame must be ``(H, W, 3) uint8`` RGB (or ``(H, W, 4)`` RGBA, written with its alpha)
    with the size and channels of the first one. ``compress_level``
    is zlib's level (1 is fast, 9 small; PNG is lossless at every level).
    """

    def __init__(
        self,
        directory: str | os.PathLike[str],
        overwrite: bool = False,
        compress_level: int = 1,
    ) -> None:
        self._inside = False
        self.directory = Path(directory)
        self.overwrite = overwrite
        self.compress_level = compress_level
        self.frames_written = 0
        self._shape: tuple[int, int, int] | None = None
        self._tmp: Path | None = None

    def _check_destination(self) -> None:
        d = self.directory
        if d.exists() and not d.is_dir():
            raise RenderError(f"{d} exists and is not a folder")
        own = self._tmp.name if self._tmp is not None else None
        if d.is_dir() and any(e.name != own for e in d.iterdir()) and not self.overwrite:
            raise RenderError(
                f"folder {d} exists and is not empty: give a new or empty folder for the frames"
            )

    def open(self) -> PngSequenceWriter:
        """Create the temporary folder (``__enter__`` calls it)."""
        self._check_destination()  # fail before rendering anything
        d = self.directory
        # an empty folder is written into, not replaced: it stays the folder it is (``.``, the
        # one a shell is in, cannot be renamed), its frames moved in from a hidden folder
        self._inside = d.is_dir() and not any(d.iterdir())
        parent = d if self._inside else d.parent
        parent.mkdir(parents=True, exist_ok=True)
        self._tmp = Path(tempfile.mkdtemp(prefix=f".{d.name}.", suffix=".part", dir=parent))
        os.chmod(self._tmp, 0o777 & ~current_umask())  # mkdtemp's 0700 is for the temp only
        self.frames_written = 0
        self._shape = None
        return self

    @property
    def next_path(self) -> Path:
        """Where the next frame goes, under its final folder name."""
        return self.directory / FRAME_NAME.format(self.frames_written)

    def write(self, frame: np.ndarray) -> None:
        """Append one ``(H, W, 3) uint8`` RGB or ``(H, W, 4)`` RGBA frame as the next PNG."""
        from PIL import Image

        if self._tmp is None:
            raise RenderError(f"{self.directory}: write() on a PNG writer that is not open")
        arr = _check_frame(frame, self._shape, rgba=True)
        self._shape = arr.shape  # type: ignore[assignment]
        name = self._tmp / FRAME_NAME.format(self.frames_written)
        Image.fromarray(arr).save(name, format="PNG", compress_level=self.compress_level)
        self.frames_written += 1

    def close(self) -> None:
        """Move the finished sequence to its folder."""
        tmp = self._tmp
        if tmp is None:
            return
        try:
            self._check_destination()
            if self._inside:
                _move_into(tmp, self.directory)
            else:
                replace_folder(tmp, self.directory)
        except BaseException:
            self.abort()
            raise
        self._tmp = None

    def abort(self) -> None:
        """Remove the temporary folder; the destination is untouched."""
        tmp, self._tmp = self._tmp, None
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)

    def __enter__(self) -> PngSequenceWriter:
        return self.open()

    __exit__ = _finish_or_abort


def write_png(path: str | os.PathLike[str], frame: np.ndarray, compress_level: int = 6) -> None:
    """Write one ``(H, W, 3) uint8`` RGB or ``(H, W, 4)`` RGBA frame to ``path`` as a PNG
    (lossless, atomic)."""
    from PIL import Image

    arr = _check_frame(frame, None, rgba=True)
    with atomic_path(path) as tmp:
        Image.fromarray(arr).save(tmp, format="PNG", compress_level=compress_level)


_WAV_SUBTYPES = {
    np.dtype(np.int16): "PCM_16",
    np.dtype(np.int32): "PCM_32",
    np.dtype(np.float32): "FLOAT",
    np.dtype(np.float64): "DOUBLE",
}


def write_wav(
    path: str | os.PathLike[str],
    samples: np.ndarray,
    rate: int,
    subtype: str | None = None,
) -> None:
    """Write ``samples`` to ``path`` as a WAV file (atomic).

    ``samples`` is ``(n,)`` (mono) or ``(n, channels)``; ``int16`` samples are full scale at
    ±32767, float samples at ±1.0. ``rate`` is in Hz. By default the WAV keeps the array's
    sample type (int16 → PCM_16, float32 → 32-bit float), so reading it back gives the same
    numbers; pass ``subtype="PCM_16"`` for the most widely readable file.
    """
    import soundfile

    arr = np.asarray(samples)
    if arr.ndim not in (1, 2) or arr.shape[0] == 0 or (arr.ndim == 2 and arr.shape[1] == 0):
        raise RenderError(f"samples must be (n,) or (n, channels) with n > 0, got {arr.shape}")
    if arr.dtype not in _WAV_SUBTYPES:
        raise RenderError(f"samples must be int16, int32, float32 or float64, got {arr.dtype}")
    if int(rate) != rate or rate <= 0:
        raise RenderError(f"sample rate must be a positive integer (Hz), got {rate!r}")
    with atomic_path(path) as tmp:
        soundfile.write(
            str(tmp), arr, int(rate), subtype=subtype or _WAV_SUBTYPES[arr.dtype], format="WAV"
        )


@dataclass(frozen=True)
class MediaInfo:
    """What a media file holds, as :func:`probe_media` measured it.

    Durations are in seconds, ``fps`` in frames per second, ``audio_rate`` in Hz; fields are None
    when the file has no such stream. ``duration_video`` is ``frames / fps`` for a constant frame
    rate (from the packets' time stamps, so it is exact); ``duration_audio`` is the number of
    decoded samples (encoder priming and padding already removed by the decoder) over the rate.
    """

    duration_video: float | None
    frames: int | None
    fps: float | None
    width: int | None
    height: int | None
    duration_audio: float | None
    audio_rate: int | None
    audio_samples: int | None = None
    audio_channels: int | None = None


_HEADER = re.compile(r"^#(\w+) (\d+): (.*)$")


def probe_media(path: str | os.PathLike[str]) -> MediaInfo:
    """Measure the first video and the first audio stream of a media file.

    Runs the wheel's ffmpeg once with its ``framecrc`` muxer: the video packets are copied
    (not decoded), which gives the exact frame count and time stamps; the audio is decoded to
    16-bit PCM, which gives the exact number of samples after the decoder dropped the AAC
    priming. Raises RenderError when the file does not exist or ffmpeg cannot read it.
    """
    p = Path(path)
    if not p.is_file():
        raise RenderError(f"media file {str(p)!r} does not exist")
    cmd = [
        ffmpeg_exe(), "-hide_banner", "-nostdin", "-nostats", "-loglevel", "error",
        "-i", str(p),
        "-map", "0:v:0?", "-c:v", "copy",
        "-map", "0:a:0?", "-c:a", "pcm_s16le",
        "-f", "framecrc", "-",
    ]  # fmt: skip
    res = subprocess.run(cmd, capture_output=True, check=False)
    if res.returncode != 0:
        message = _tail(res.stderr.decode("utf-8", "replace")) or "(no message)"
        raise RenderError(f"ffmpeg cannot read media file {str(p)!r}: {message}")

    headers: dict[int, dict[str, str]] = {}
    packets: dict[int, list[tuple[int, int, int]]] = {}  # stream → (pts, duration, size)
    for line in res.stdout.decode("utf-8", "replace").splitlines():
        if line.startswith("#"):
            m = _HEADER.match(line)
            if m:
                headers.setdefault(int(m[2]), {})[m[1]] = m[3].strip()
            continue
        fields = [f.strip() for f in line.split(",")]
        if len(fields) >= 5 and fields[0].isdigit():
            stream = int(fields[0])
            packets.setdefault(stream, []).append((int(fields[2]), int(fields[3]), int(fields[4])))

    info: dict[str, Any] = {}
    for stream, head in headers.items():
        num, _, den = head.get("tb", "1/1").partition("/")
        tb = Fraction(int(num), int(den or 1))
        pkts = packets.get(stream, [])
        kind = head.get("media_type")
        if kind == "video" and "frames" not in info:
            info["frames"] = len(pkts)
            if pkts:
                start = min(pts for pts, _, _ in pkts)
                end = max(pts + dur for pts, dur, _ in pkts)
                info["duration_video"] = float((end - start) * tb)
                step = int(np.median([dur for _, dur, _ in pkts]))
                info["fps"] = float(1 / (step * tb)) if step > 0 else None
            dims = head.get("dimensions", "")
            if "x" in dims:
                w, h = dims.split("x")
                info["width"], info["height"] = int(w), int(h)
        elif kind == "audio" and "audio_rate" not in info:
            rate = int(head.get("sample_rate", "0")) or None
            samples = sum(dur for _, dur, _ in pkts)
            nbytes = sum(size for _, _, size in pkts)
            info["audio_rate"] = rate
            info["audio_samples"] = samples
            # pcm_s16le: 2 bytes per sample and channel
            info["audio_channels"] = nbytes // (2 * samples) if samples else None
            info["duration_audio"] = float(samples * tb)
    return MediaInfo(
        duration_video=info.get("duration_video"),
        frames=info.get("frames"),
        fps=info.get("fps"),
        width=info.get("width"),
        height=info.get("height"),
        duration_audio=info.get("duration_audio"),
        audio_rate=info.get("audio_rate"),
        audio_samples=info.get("audio_samples"),
        audio_channels=info.get("audio_channels"),
    )


class ProgressBar:
    """A progress counter; draws a rich bar on stderr when it is enabled."""

    def __init__(self, total: int, description: str, enabled: bool) -> None:
        self.total = total
        self.description = description
        self.enabled = enabled
        self.completed = 0
        self._progress: Any = None
        self._task: Any = None

    def advance(self, n: int = 1) -> None:
        """Count ``n`` more units (frames) as done."""
        self.completed += n
        if self._progress is not None:
            self._progress.advance(self._task, n)


def terminal_progress(*extra_columns: str, eta_label: str = ""):
    """A transient rich ``Progress`` on stderr — description, bar, done/total, each of
    ``extra_columns`` (rich text templates such as ``"{task.fields[rate]} jobs/min"``), elapsed
    time and time remaining (after ``eta_label``, when given) — or None when stderr is not a
    terminal (CI logs and redirected output get no progress lines)."""
    from rich.console import Console

    console = Console(file=sys.stderr)
    if not console.is_terminal or console.is_dumb_terminal:
        return None
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns = [TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn()]
    columns += [TextColumn(c) for c in extra_columns]
    columns.append(TimeElapsedColumn())
    if eta_label:
        columns.append(TextColumn(eta_label))
    columns.append(TimeRemainingColumn())
    return Progress(*columns, console=console, transient=True)


@contextlib.contextmanager
def progress(total: int, description: str, quiet: bool = False) -> Iterator[ProgressBar]:
    """A progress bar for ``total`` units of work (frames), shown on stderr.

    The bar is drawn only when ``quiet`` is False and stderr is an interactive terminal, so
    CI logs and redirected output never receive progress lines; it is removed when done
    (``transient``). The yielded object counts either way (``.completed``)::

        with progress(len(frames), "rendering", quiet=args.quiet) as bar:
            for frame in frames:
                ...
                bar.advance()
    """
    from vtts.messages import printable

    description = printable(description)  # it names the user's file (analyzing NAME)
    bar = ProgressBar(total, description, enabled=False)
    prog = None if quiet else terminal_progress()
    if prog is None:
        yield bar
        return
    with prog:
        bar.enabled = True
        bar._progress = prog
        bar._task = prog.add_task(description, total=total)
        try:
            yield bar
        finally:
            bar._progress = None
