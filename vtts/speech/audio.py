"""Reading recorded speech: any audio file to mono float samples, bounded in length.

:func:`read_audio` reads WAV, FLAC, OGG (Vorbis, Opus), AIFF and the other formats libsndfile knows
(MP3 too since libsndfile 1.1, as in the ``soundfile`` wheel) with ``soundfile``, in blocks so
that a stereo file never sits in memory whole; anything else (M4A/AAC, WMA, a video's sound track
…, or a file libsndfile opens but cannot decode) is decoded by the ``imageio-ffmpeg`` wheel's
ffmpeg into a temporary 32-bit float WAV first (at the file's own rate, at most
:data:`~vtts.limits.MAX_AUDIO_S` plus a second of it). Channels are averaged, a channel whose
samples run against the loudest one's (wired inverted) turned over first, so that it does not
cancel the speech; when ``rate`` is
given the samples are resampled with a polyphase filter (``scipy.signal.resample_poly``).

The length is checked before decoding where the file states it (a 900 kB FLAC can claim ten hours
of silence) and again while reading (a header may lie), so a hostile file costs at most
:data:`~vtts.limits.MAX_AUDIO_S` of samples.
"""

from __future__ import annotations

import os
import subprocess
import tempfile
from fractions import Fraction
from pathlib import Path

import numpy as np

from vtts.errors import SpeechError
from vtts.limits import MAX_AUDIO_RATE, MAX_AUDIO_S, LimitError
from vtts.media import ffmpeg_exe

__all__ = ["AAC_RATES", "mp4_samples", "read_audio", "read_for_mp4", "resample", "to_int16"]

#: Sample rates ffmpeg's AAC encoder takes (Hz): the MP4 of ``vtts say`` needs one of them.
AAC_RATES = frozenset(
    {7350, 8000, 11025, 12000, 16000, 22050, 24000, 32000, 44100, 48000, 64000, 88200, 96000}
)
#: Frames per block when reading with soundfile (about 1.4 s at 48 kHz).
_BLOCK = 1 << 16


def read_audio(path: str | os.PathLike[str], rate: int | None = None) -> tuple[np.ndarray, int]:
    """The samples of the audio file ``path`` and their rate.

    Returns ``(samples, rate)``: ``samples`` is ``(n,)`` float32, mono (channels averaged), in
    [-1, 1] (louder float samples are clipped, NaN become 0); ``rate`` in Hz is the file's own,
    or ``rate`` when given (the samples are then resampled to it).

    Raises :class:`~vtts.errors.SpeechError` naming the file when it is missing, unreadable, not
    audio or has no samples, and :class:`~vtts.limits.LimitError` when it lasts longer than
    :data:`~vtts.limits.MAX_AUDIO_S` or its rate exceeds :data:`~vtts.limits.MAX_AUDIO_RATE`.
    """
    p = Path(path)
    if rate is not None:
        _check_rate(rate, "the rate asked for", None)
    if not p.exists():
        raise SpeechError("the audio file does not exist", file=str(p))
    if p.is_dir():
        raise SpeechError("the audio file is a folder", file=str(p))
    if not p.is_file():
        # decoding may read it twice (libsndfile, then ffmpeg), and opening a named pipe
        # nobody writes waits for ever
        raise SpeechError(
            "the audio file is not a regular file (a named pipe or a device): give a file",
            file=str(p),
        )
    try:
        if p.is_file() and p.stat().st_size == 0:
            raise SpeechError("the audio file is empty (0 bytes)", file=str(p))
    except OSError as e:
        raise SpeechError(f"cannot read the audio file: {e.strerror}", file=str(p)) from None
    read = _read_soundfile(p)
    if read is None:
        read = _read_ffmpeg(p)
    samples, native = read
    if samples.size == 0:
        raise SpeechError("the audio file holds no samples", file=str(p))
    if rate is not None and rate != native:
        samples = resample(samples, native, rate)
        native = rate
    return samples, native


def read_for_mp4(path: str | os.PathLike[str]) -> tuple[np.ndarray, int]:
    """``(samples, rate)``: ``(n,)`` int16 mono samples of any audio file :func:`read_audio`
    reads, at a rate the MP4's AAC encoder takes (:data:`AAC_RATES`): the file's own when it is
    one, else the next higher one up to 48 kHz. What ``vtts say --audio`` and ``vtts play
    --audio`` mux into the MP4 and the web player (written as a WAV first); errors as
    :func:`read_audio`'s."""
    return mp4_samples(*read_audio(path))


def mp4_samples(samples: np.ndarray, sr: int) -> tuple[np.ndarray, int]:
    """``(samples, rate)`` of :func:`read_audio` as :func:`read_for_mp4` gives them: int16, at
    an AAC rate."""
    if sr not in AAC_RATES:
        to = min([r for r in AAC_RATES if r >= sr] + [48000])
        samples, sr = resample(samples, sr, to), to
    return to_int16(samples), sr


def resample(samples: np.ndarray, rate: int, to: int) -> np.ndarray:
    """``(n,)`` float samples at ``rate`` Hz resampled to ``to`` Hz (``(m,)`` float32, clipped to
    [-1, 1]) with ``scipy.signal.resample_poly`` (its Kaiser-windowed anti-aliasing filter)."""
    from scipy.signal import resample_poly

    if rate == to:
        return np.asarray(samples, dtype=np.float32)
    ratio = Fraction(int(to), int(rate))
    out = resample_poly(np.asarray(samples, dtype=np.float32), ratio.numerator, ratio.denominator)
    out = out.astype(np.float32, copy=False)
    return np.clip(out, -1.0, 1.0, out=out)  # in place: 10 minutes at 16 kHz are 38 MB


def resample_in_blocks(samples: np.ndarray, rate: int, target: int) -> np.ndarray:
    """``(n,)`` samples at ``rate`` Hz → float32 at ``target`` Hz (polyphase, anti-aliased, not
    clipped), in blocks of about 30 s so that long audio takes bounded memory."""
    from math import gcd

    from scipy.signal import resample_poly

    x = np.asarray(samples, dtype=np.float32)
    if rate == target:
        return x
    g = gcd(int(rate), int(target))
    # in blocks of about 30 s: resample_poly works in float64 (10 minutes would take 100 MB)
    up, down = target // g, rate // g
    block = down * (30 * rate // down)
    if len(x) <= 2 * block:
        return resample_poly(x, up, down).astype(np.float32)
    pad = down * (rate // (10 * down) + 1)  # 0.1 s of context on each side hides the block edges
    out = []
    for a in range(0, len(x), block):
        lo, hi = max(a - pad, 0), min(a + block + pad, len(x))
        y = resample_poly(x[lo:hi], up, down)
        skip = (a - lo) * up // down
        out.append(y[skip : skip + min(block, len(x) - a) * up // down].astype(np.float32))
    return np.concatenate(out)


def to_int16(samples: np.ndarray) -> np.ndarray:
    """Float samples in [-1, 1] as ``(n,)`` int16 at full scale ±32767 (what the WAV of the MP4
    and ``--wav-out`` hold)."""
    x = np.clip(np.asarray(samples, dtype=np.float32), -1.0, 1.0)
    return np.round(x * 32767.0).astype(np.int16)


# ---- soundfile -----------------------------------------------------------------------------------


def _read_soundfile(p: Path) -> tuple[np.ndarray, int] | None:
    """Samples and rate, or None when libsndfile does not know the format or cannot decode
    the file."""
    import soundfile as sf

    try:
        f = sf.SoundFile(str(p))
    except (sf.LibsndfileError, RuntimeError, TypeError, ValueError):
        return None  # not a format of libsndfile's (or a broken one): ffmpeg tries next
    except OSError as e:
        raise SpeechError(f"cannot read the audio file: {e.strerror or e}", file=str(p)) from None
    with f:
        native = int(f.samplerate)
        _check_rate(native, "the audio's sample rate", p)
        cap = int(MAX_AUDIO_S * native)
        # the length the header states first (before anything is decoded) …
        if f.frames > cap and f.frames < (1 << 62):  # libsndfile says 2^63-1 for "unknown"
            raise _too_long(f.frames / native, p)
        signs = None
        if f.channels > 1 and f.seekable():
            try:
                signs = _channel_signs(f, cap, p)
                f.seek(0)
            except (sf.LibsndfileError, RuntimeError, ValueError):
                return None
        # the stated length (when there is one) sized up front: one array, no concatenation
        stated = f.frames if 0 < f.frames <= cap else 0
        out = np.empty(stated, np.float32)
        blocks: list[np.ndarray] = []  # what comes beyond the stated length (a header may lie)
        total = 0
        try:
            while True:
                block = f.read(_BLOCK, dtype="float32", always_2d=True)
                n = block.shape[0]
                if n == 0:
                    break
                if total + n > cap:  # … and what is really there
                    raise _too_long((total + n) / native, p, more=True)
                mono = _mono(block, signs)
                fits = max(min(n, stated - total), 0)
                out[total : total + fits] = mono[:fits]
                if fits < n:
                    blocks.append(mono[fits:])
                total += n
        except (sf.LibsndfileError, RuntimeError, ValueError):
            # libsndfile opened it but cannot decode it (a FLAC whose header states another
            # length fails to seek): ffmpeg's decoders are more forgiving
            return None
    if blocks:
        samples = np.concatenate([out, *blocks])
    else:  # a header that claimed more than there was: keep only what was read
        samples = out if total == stated else out[:total].copy()
    return samples, native


def _channel_signs(f, cap: int, p: Path) -> np.ndarray:
    """``(channels,)`` ±1: the sign each channel takes in the mix, so that a channel wired the
    other way round (an inverted right channel) adds to the loudest one instead of cancelling
    it. Read through the whole file once (the length checked as it goes); the caller seeks
    back."""
    gram = np.zeros((f.channels, f.channels))
    total = 0
    while True:
        block = f.read(_BLOCK, dtype="float32", always_2d=True)
        if block.shape[0] == 0:
            break
        total += block.shape[0]
        if total > cap:
            raise _too_long(total / f.samplerate, p, more=True)
        x = np.nan_to_num(block.astype(np.float64), nan=0.0, posinf=1.0, neginf=-1.0)
        gram += x.T @ x
    loudest = int(np.argmax(np.diag(gram)))
    return np.where(gram[loudest] < 0, -1.0, 1.0).astype(np.float32)


def _mono(block: np.ndarray, signs: np.ndarray | None = None) -> np.ndarray:
    """``(n, channels)`` float32 → ``(n,)`` float32 in [-1, 1] (NaN → 0): the channels'
    mean, each with its sign in ``signs`` (:func:`_channel_signs`; None: all +1)."""
    if block.shape[1] > 1 and signs is not None:
        block = block * signs
    x = block.mean(axis=1, dtype=np.float32) if block.shape[1] > 1 else block[:, 0]
    x = np.nan_to_num(x, nan=0.0, posinf=1.0, neginf=-1.0)
    return np.clip(x, -1.0, 1.0).astype(np.float32, copy=False)


# ---- ffmpeg --------------------------------------------------------------------------------------


def _read_ffmpeg(p: Path) -> tuple[np.ndarray, int]:
    """Decode with the bundled ffmpeg (MP3, M4A, …) into a temporary float WAV, then read that."""
    with tempfile.TemporaryDirectory(prefix="vtts-audio-") as tmp:
        wav = Path(tmp) / "decoded.wav"
        cmd = [
            ffmpeg_exe(), "-hide_banner", "-nostdin", "-nostats", "-loglevel", "error",
            "-i", str(p), "-map", "0:a:0", "-vn", "-sn", "-dn",
            # at most the limit and a second: a lying header cannot make ffmpeg decode hours; the
            # channels stay (ffmpeg's own downmix is -3 dB per channel, not their mean)
            "-t", f"{MAX_AUDIO_S + 1:g}", "-c:a", "pcm_f32le", "-f", "wav", str(wav),
        ]  # fmt: skip
        try:
            res = subprocess.run(cmd, capture_output=True, timeout=600, check=False)
        except subprocess.TimeoutExpired:
            raise SpeechError("ffmpeg did not decode the audio within 600 s", file=str(p)) from None
        if res.returncode != 0 or not wav.is_file() or wav.stat().st_size == 0:
            reason = _ffmpeg_reason(res.stderr.decode("utf-8", "replace"))
            raise SpeechError(
                f"not an audio file that soundfile or ffmpeg can read ({reason})", file=str(p)
            )
        try:
            decoded = _read_soundfile(wav)
        except LimitError:  # the decoded length stops a second past the limit
            raise _too_long(0.0, p, more=True) from None
        except SpeechError as e:  # name the user's file, not the temporary one
            raise SpeechError(e.message, file=str(p)) from None
    if decoded is None:  # ffmpeg wrote a WAV libsndfile cannot open: say what was asked
        raise SpeechError("ffmpeg decoded the audio into a WAV that cannot be read", file=str(p))
    return decoded


def _ffmpeg_reason(stderr: str) -> str:
    """The line of ffmpeg's messages that says why, without the file name it repeats."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    if not lines:
        return "no audio stream"
    for ln in lines:
        if "does not contain any stream" in ln or "matches no streams" in ln:
            return "it has no audio stream"
    last = lines[-1]
    _, sep, after = last.rpartition(": ")
    return (after if sep else last)[:200]


# ---- limits --------------------------------------------------------------------------------------


def _check_rate(rate, what: str, p: Path | None) -> None:
    if isinstance(rate, bool) or not isinstance(rate, int | np.integer) or rate <= 0:
        raise SpeechError(f"{what} must be a positive integer (Hz), got {rate!r}")
    if rate > MAX_AUDIO_RATE:
        raise LimitError(
            f"{what} is {rate} Hz, more than the limit of {MAX_AUDIO_RATE} Hz (vtts.limits)",
            file=str(p) if p else None,
        )


def _too_long(seconds: float, p: Path, *, more: bool = False) -> LimitError:
    # ``more``: counted while decoding, which stops at the limit
    lasts = "lasts more than the limit" if more else f"lasts {seconds:g} s, more than the limit"
    return LimitError(f"the audio {lasts} of {MAX_AUDIO_S:g} s (vtts.limits)", file=str(p))
