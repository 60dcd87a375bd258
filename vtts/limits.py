"""Every limit on the size of an input, in one place (``docs/limits.md`` explains them).

A hostile or mistaken input must fail with a clear message naming the value, the limit and the
file, never drive the process out of memory or into a loop that does not end. Each constant below
bounds one such size; the readers check them before they allocate, and read files with
:func:`read_bytes_capped` (at most the limit plus one byte, so a device or a pipe without end is
refused too).
"""

from __future__ import annotations

import os
from pathlib import Path

from vtts.errors import VttsError

# ---- files ---------------------------------------------------------------------------------------

#: A VRML97 model or scene (the bundled heads are 0.65 MB).
MAX_VRML_BYTES = 64 << 20
#: An ``.adt`` table file (the bundled heads' are 4.5 MB; parsing takes up to 30 bytes a byte).
MAX_ADT_BYTES = 64 << 20
#: A cache entry of a parsed model (the bundled heads' are 5 MB).
MAX_CACHE_ENTRY_BYTES = 1 << 30
#: A text file: ``say --file``, a phoneme table (``--phonemes``), a ``.fap`` file.
MAX_TEXT_BYTES = 64 << 20
#: A FAP bitstream (``.fbs``): an hour at 30 Hz with every FAP is well under this.
MAX_FBS_BYTES = 64 << 20
#: A ``vtts batch`` jobs file (a million jobs of 250 bytes).
MAX_JOBS_BYTES = 256 << 20
#: The most jobs of one ``vtts batch`` file: every job is checked before the first runs, and a
#: job's check (its options, as the command's) costs a fraction of a millisecond.
MAX_JOBS = 100_000
#: A glTF or GLB file (with its buffers).
MAX_GLTF_BYTES = 512 << 20

# ---- values -------------------------------------------------------------------------------------

#: The largest FAP value a command line or bookmark may give, in FAP units (FAPU or AU): a
#: thousand of a face's own distances, or ten radians.
MAX_FAP_VALUE = 1e6

# ---- time ----------------------------------------------------------------------------------------

#: The longest animation, in seconds (an utterance, a FAP file, a decoded stream).
MAX_DURATION_S = 3600.0
#: The longest audio file ``vtts say --audio`` reads (30 minutes: 330 MB of float samples at
#: 48 kHz), checked before decoding where the file states its length and while decoding.
MAX_AUDIO_S = 1800.0
#: The highest sample rate of an audio file, Hz.
MAX_AUDIO_RATE = 192_000
#: The most frames of one animation (an hour at 60 Hz).
MAX_FRAMES = 216_000
#: Frame rates a FAP file or stream may declare, in frames per second (with the duration limit,
#: a slow rate cannot make many frames at 30 Hz).
MIN_FPS, MAX_FPS = 0.01, 1000.0

# ---- images --------------------------------------------------------------------------------------

#: The largest side of a rendered image, a video frame or a texture, in pixels.
MAX_IMAGE_SIDE = 4096
#: The most pixels of one image (a video frame, a texture): 16 megapixels. ``adi fit`` takes larger
#: photos (up to 16384 pixels on a side) and scales them down.
MAX_IMAGE_PIXELS = 16 << 20
#: The most pixels of a photo ``adi fit`` reads (checked from its header, before decoding; a
#: 61-megapixel camera's photos are within it). A JPEG larger than the fit's working size is
#: decoded at a fraction of its size.
MAX_PHOTO_PIXELS = 64 << 20
#: The most pixels of a rendered image (4K UHD): rendering takes about 400 bytes a pixel.
MAX_RENDER_PIXELS = 3840 * 2160

# ---- geometry ------------------------------------------------------------------------------------

#: The most elements (vertices, indices) one glTF accessor may hold.
MAX_ACCESSOR_COUNT = 50_000_000
#: The most elements of a glTF accessor without a bufferView (zeros, and its sparse values: memory
#: without bytes in the file) where nothing else in the file fixes its count: a primitive's
#: POSITION or triangle indices. Its normals, texture coordinates and morph targets must have as
#: many elements as its POSITION, a skin's inverse bind matrices one for each of its joints.
MAX_UNBACKED_COUNT = 1_000_000
#: The most morph targets one glTF mesh primitive may have (an ARKit avatar has 52, with the
#: Oculus visemes 67; each target is a copy of the mesh's positions in memory).
MAX_MORPH_TARGETS = 1024
#: The most objects of one glTF file (nodes, meshes, accessors … : the lengths of its top-level
#: arrays together); pygltflib decodes each into a dataclass, a fraction of a millisecond each.
MAX_GLTF_OBJECTS = 20_000


class LimitError(VttsError):
    """An input exceeds one of the limits above."""


def read_bytes_capped(path: str | os.PathLike[str], limit: int, *, what: str = "file") -> bytes:
    """The bytes of ``path``, refusing more than ``limit`` of them.

    Reads at most ``limit + 1`` bytes, so ``/dev/zero`` or an endless pipe fails as fast as a
    large file. Raises :class:`LimitError` naming the file and the limit; ``OSError`` passes
    through for the caller to word.
    """
    p = Path(path)
    with open(p, "rb") as f:
        data = f.read(limit + 1)
    if len(data) > limit:
        raise LimitError(
            f"{what} is larger than the limit of {_size(limit)} (vtts.limits)", file=str(p)
        )
    return data


def check_limit(value: float, limit: float, what: str, *, file: str | None = None) -> None:
    """Raise :class:`LimitError` when ``value`` exceeds ``limit`` (or is not a number)."""
    if not value <= limit:  # also catches nan
        raise LimitError(f"{what} is {value:g}, more than the limit of {limit:g}", file=file)


def _size(n: int) -> str:
    for unit, shift in (("GiB", 30), ("MiB", 20), ("KiB", 10)):
        if n >= 1 << shift and n % (1 << shift) == 0:
            return f"{n >> shift} {unit}"
    return f"{n} bytes"


def check_image_size(
    width: int, height: int, *, file: str | None = None, what: str = "image"
) -> None:
    """Raise :class:`LimitError` for an image beyond :data:`MAX_IMAGE_SIDE` on a side or
    :data:`MAX_IMAGE_PIXELS` in all — before its pixels are decoded (a small PNG can inflate to
    gigabytes)."""
    if max(width, height) > MAX_IMAGE_SIDE or width * height > MAX_IMAGE_PIXELS:
        raise LimitError(
            f"the {what} is {width}x{height} pixels, more than the limit of {MAX_IMAGE_SIDE} "
            f"pixels on a side and {MAX_IMAGE_PIXELS} in all",
            file=file,
        )


# ---- vtts serve ----------------------------------------------------------------------------------

#: The largest WebSocket message a client may send ``vtts serve`` (a longer one closes its
#: socket with code 1009, naming this limit): a text of a thousand sentences.
MAX_SERVE_MESSAGE_BYTES = 1 << 20
#: The most characters of text one session may have waiting to be spoken (about 25 minutes of
#: speech): more is refused with an error message, and the session goes on.
MAX_SERVE_TEXT_CHARS = 20_000
#: The most sessions (open WebSockets) of one server at once; the next socket is told the server
#: is full and closed (code 1013, try again later).
MAX_SERVE_SESSIONS = 200
#: The kernel's send buffer of a session's socket (Linux doubles it), bytes: what a client that
#: does not read can leave waiting in the kernel (besides aiohttp's 64 KiB), 5 s of speech and
#: face; the kernel's own tuning would let it grow to megabytes.
SERVE_SOCKET_BUFFER_BYTES = 128 << 10
#: How long a client may leave the server's messages unread (its socket's buffers full) before
#: its session is closed, s: a client that never reads holds no more than those buffers.
SERVE_SEND_TIMEOUT_S = 20.0
