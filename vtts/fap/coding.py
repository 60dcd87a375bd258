"""FAP stream coding below 0.6 kbit/s: the ``.fbs`` bitstream (Eisert & Girod's FAP coder).

The scheme of the paper ("Camera sequences"): every FAP is predicted from the previous *decoded*
frame, the prediction error is quantized with a per-FAP step, and the quantized error is entropy
coded — Huffman, as in the paper, or adaptive binary arithmetic coding.

Quantizer
    A low-level FAP k is coded on the grid of its step ``step_k = base_k · quantizer``: ``base_k``
    is the FAP's ``quant_step`` of ISO/IEC 14496-2 (``vtts/data/faps.tsv``: 4 for open_jaw,
    170 AU for the head rotations, …) and ``quantizer`` a global factor like MPEG-4's
    ``fap_quant`` (1 = the standard's steps, 2 = twice as coarse, fewer bits). Both are stored in
    the bitstream, so a decoder never depends on the table it has. A value x is sent as the
    index ``round(x / step)``; the prediction is the previous *decoded* index of the same FAP
    (held over frames that do not set it, 0 before the first), so the quantized prediction error
    is ``q = index − previous index``. Because the prediction lies on the grid, this is exactly
    closed-loop DPCM: quantizing the error ``x − decoded`` gives the same q, the encoder tracks
    exactly what the decoder reconstructs, and errors never accumulate. The reconstruction is
    ``index · step`` and ``|x − reconstruction| ≤ step / 2`` for every value, whatever the jump
    (no clamp anywhere). :func:`reconstruct` returns it without coding.

Huffman mode (the paper's)
    q is a 7-bit symbol: −63…63 directly, and −64 is an escape followed by a sign bit and the
    Exp-Golomb code of ``|q| − 64`` for larger jumps. The canonical code (lengths ≤ 15 bits) is
    built from the stream's own symbol counts (two passes) and its code lengths are stored in the
    header. One table serves all FAPs, as in the paper.

Arithmetic mode
    An adaptive binary range coder (LZMA's carry-propagating coder, 32-bit, 16-bit probabilities
    estimated from halved counts) with context modelling, so no table is sent: q is binarized as
    zero? / sign / magnitude class (unary) / mantissa bits, each decision with its own adaptive
    probability per FAP, conditioned on the previous error of the same FAP and on whether the
    FAP coded just before it in the frame moved. A FAP may also be predicted from another FAP's
    error in the same frame (the encoder picks, per FAP, the earlier FAP of the same unit and step
    that lowers its estimated cost most, e.g. the right eyebrow from the left, FAP 54 from 53):
    the pairs are listed in the header. No library is used: entropy-coding libraries such as
    constriction take the probabilities as given, so the adaptive modelling would be ours anyway,
    and the binary range coder under it is a few dozen lines of exact integer arithmetic.

Head translation
    The paper's six head-motion parameters include a translation, which MPEG-4 has no FAP for
    (the scene's Transform moves a head). When a stream carries one
    (:attr:`FapStream.translation`, ES units), its three axes are coded in every frame exactly
    like three more low-level FAPs, after them: closed-loop DPCM on the grid of
    :data:`TRANSLATION_BASE_STEP` (4 ES units, about 0.23 pixels of a CIF head) times the
    quantizer, the base steps stored in the header, the errors through the same Huffman tables
    or adaptive contexts. A header flag says so; a stream without translation codes to the
    bytes it always did, and bitstreams made before translation existed decode as they did.

High-level FAPs 1 (viseme) and 2 (expression) are lossless: a "same as before" decision, then the
changed fields (raw bits in Huffman mode, differences in arithmetic mode). Frames whose mask of
coded FAPs differs from the previous frame's send the new mask (unless the header says the mask is
constant). The byte-by-byte layout is in ``docs/fap-coding.md`` and :func:`read_header`.

Every problem in a bitstream is a :class:`~vtts.errors.CodingError` carrying the byte offset where
it was found. Two CRC-32s (header, frame data) make sure corruption is reported, never decoded
into a silently different stream; truncation is reported at the byte where the data ends.
"""

from __future__ import annotations

import heapq
import math
import re
import struct
import zlib
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from typing import BinaryIO

import numpy as np

from vtts.errors import CodingError, FapError
from vtts.fap.stream import (
    EXPRESSION_FIELDS,
    MAX_RESAMPLED_FRAMES,
    MAX_TRANSLATION,
    TRANSLATION_AXES,
    VISEME_FIELDS,
    FapStream,
)
from vtts.fap.table import FAPS, N_FAPS
from vtts.fap.table import fap as fap_def
from vtts.limits import MAX_DURATION_S, MAX_FPS, MIN_FPS

MAGIC = b"VFBS"
VERSION = 1
#: Coder names and their ids in the header.
CODERS: dict[str, int] = {"huffman": 0, "arithmetic": 1}
_CODER_NAMES = {v: k for k, v in CODERS.items()}

#: The 17 FAPs of Eisert & Girod's camera experiment in MPEG-4 numbering. The paper estimated six
#: global head-motion parameters (3 rotations, 3 translations), four eyebrow and seven mouth
#: parameters. MPEG-4 has FAPs for the three head rotations only (48–50): head translation is the
#: scene's Transform, not a FAP. The three translation slots are taken by the eye parameters a
#: talking head sends alongside head motion: both upper eyelids (19, 20: blinks) and the gaze
#: (23, yaw of the left eyeball; a decoder derives 24 from it by the left/right FIT rule).
#: Eyebrows: inner and outer raisers, left and right (31, 32, 35, 36). Mouth: jaw (3), the mid
#: lips (4, 5), the lip corners' stretch (6, 7) and raise (12, 13).
PAPER_17: tuple[int, ...] = (48, 49, 50, 19, 20, 23, 31, 32, 35, 36, 3, 4, 5, 6, 7, 12, 13)

#: Named FAP sets for ``--faps``.
FAP_SETS: dict[str, tuple[int, ...]] = {
    "paper17": PAPER_17,
    "all": tuple(range(1, N_FAPS + 1)),
    "low": tuple(range(3, N_FAPS + 1)),
}

#: Huffman mode: symbols −63…63 are errors sent directly, −64 escapes a larger one.
ESCAPE = -64
SYMBOL_MAX = 63
MAX_CODE_LENGTH = 15
#: ``|value / step|`` must stay below this (2^40): indices and errors fit any machine integer.
MAX_INDEX = 1 << 40
#: A magnitude needs at most this many bits (errors between FAPs reach 2^42).
_MAX_MAGNITUDE_BITS = 43
#: Limits a decoder enforces on a header, so that no input can make it allocate without bound.
MAX_FRAMES = MAX_RESAMPLED_FRAMES
MAX_NAME_BYTES = 4096
MAX_BASE_STEP = 1 << 20
QUANTIZER_RANGE = (2.0**-6, 2.0**12)

_FIXED = struct.Struct(">4sBBBdII9sf")  # magic … quantizer: 36 bytes
_VISEME_BITS = tuple(hi.bit_length() for _, _, hi in VISEME_FIELDS)
_EXPRESSION_BITS = tuple(hi.bit_length() for _, _, hi in EXPRESSION_FIELDS)
_FLAG_CONSTANT_MASK = 0x01
_FLAG_TRANSLATION = 0x02
_FLAG_STREAM = 0x04
_FLAGS = _FLAG_CONSTANT_MASK | _FLAG_TRANSLATION | _FLAG_STREAM

#: The base step of the head translation's three axes, in ES units (ES0 / 1024), sent in the
#: header like the FAPs' base steps. On a CIF head (ES0 ≈ 60 pixels) 4 ES units are 0.23 pixels,
#: the order of the image motion of the FAPs' own steps (170 AU of head rotation moves a point
#: one ES from the axis by 0.1 pixels, 4 MNS units of the jaw 0.08 pixels): at quantizer 1 the
#: head lands within 0.12 pixels of where it was, at quantizer 4 within 0.47.
TRANSLATION_BASE_STEP = 4


# --- FAP selection ------------------------------------------------------------------------------


def fap_set(text: str | Iterable[int | str]) -> tuple[int, ...]:
    """FAP numbers from a list such as ``"3,4,5"``, ``"3-13 48"``, ``"open_jaw,head_yaw"`` or a
    named set (``paper17``, ``low``: 3–68, ``all``: 1–68); sorted, without duplicates."""
    items = re.split(r"[,\s]+", text.strip()) if isinstance(text, str) else list(text)
    out: set[int] = set()
    for item in items:
        if isinstance(item, str):
            word = item.strip()
            if not word:
                continue
            if word.lower() in FAP_SETS:
                out.update(FAP_SETS[word.lower()])
                continue
            # ASCII digits, few enough for int() (it refuses 4,300)
            m = re.fullmatch(r"([0-9]{1,18})-([0-9]{1,18})", word)
            if m:
                lo, hi = int(m.group(1)), int(m.group(2))
                if not 1 <= lo <= hi <= N_FAPS:
                    raise FapError(f"FAP range {word!r} must be within 1-{N_FAPS}, low to high")
                out.update(range(lo, hi + 1))
                continue
        out.add(fap_def(item).number)
    if not out:
        raise FapError(f"no FAPs selected by {text!r}")
    return tuple(sorted(out))


# --- what the encoder sends and the decoder reconstructs ---------------------------------------


def _float32(x: float) -> float:
    return float(np.float32(x))


def _check_quantizer(quantizer: float) -> float:
    try:
        q = float(quantizer)
    except (TypeError, ValueError):
        raise FapError(f"quantizer must be a number, got {quantizer!r}") from None
    lo, hi = QUANTIZER_RANGE
    if not (math.isfinite(q) and lo <= q <= hi):
        raise FapError(f"quantizer must be within {lo:g}–{hi:g}, got {quantizer!r}")
    return _float32(q)


@dataclass(frozen=True)
class _Plan:
    """A stream ready to code: the FAPs to send, their steps and quantization indices."""

    source: FapStream  # the stream after FAP selection and resampling
    faps: tuple[int, ...]  # coded FAPs, ascending (1 and 2 included when coded)
    low: tuple[int, ...]  # coded low-level FAPs
    base_steps: tuple[int, ...]
    quantizer: float  # as stored (float32)
    mask: np.ndarray  # (n, len(faps)) bool
    index: np.ndarray  # (n, len(low)) int64, 0 where not set
    reconstruction: FapStream
    translation_steps: tuple[int, ...] = ()  # base steps of tx, ty, tz; () when not sent
    translation_index: np.ndarray | None = None  # (n, 3) int64 when sent


def _steps(base_steps: Iterable[int], quantizer: float) -> np.ndarray:
    """``(k,) float64``: step = base · quantizer, the same arithmetic in encoder and decoder."""
    return np.array([float(b) for b in base_steps], dtype=np.float64) * np.float64(quantizer)


def _assemble(
    fps: float,
    name: str,
    first_frame: int,
    faps: tuple[int, ...],
    low: tuple[int, ...],
    steps: np.ndarray,
    mask: np.ndarray,
    index: np.ndarray,
    viseme: np.ndarray,
    expression: np.ndarray,
    translation_steps: np.ndarray | None = None,
    translation_index: np.ndarray | None = None,
) -> FapStream:
    """The decoded stream: ``index · step`` for the low-level FAPs and the head translation
    (when sent), the rest as sent."""
    n = mask.shape[0]
    full_mask = np.zeros((n, N_FAPS), dtype=bool)
    full_mask[:, [k - 1 for k in faps]] = mask
    values = np.zeros((n, N_FAPS), dtype=np.float64)
    if low:
        values[:, [k - 1 for k in low]] = index.astype(np.float64) * steps
    translation = None
    if translation_index is not None:
        translation = translation_index.astype(np.float64) * translation_steps
    return FapStream(
        fps=fps,
        name=name,
        values=values,
        mask=full_mask,
        viseme=viseme,
        expression=expression,
        first_frame=first_frame,
        translation=translation,
    )


def _quantize(stream: FapStream, low: tuple[int, ...], steps: np.ndarray) -> np.ndarray:
    """``(n, L) int64``: the grid index of each low-level FAP of ``low`` (steps ``(L,)``) in
    each frame, 0 where the frame does not set it; a value too large to code is an error."""
    with np.errstate(over="ignore", invalid="ignore"):
        ratio = stream.values[:, [k - 1 for k in low]] / steps
    bad = ~(np.abs(ratio) < MAX_INDEX - 1)
    if np.any(bad):
        i, j = (int(x) for x in np.argwhere(bad)[0])
        raise CodingError(
            f"FAP {low[j]} = {stream.values[i, low[j] - 1]!r} in frame {i} is too large to code "
            f"with step {steps[j]:g}: |value / step| must stay below 2^40"
        )
    low_mask = stream.mask[:, [k - 1 for k in low]]
    return np.where(low_mask, np.rint(ratio), 0.0).astype(np.int64)


def _quantize_translation(translation: np.ndarray, t_steps: np.ndarray) -> np.ndarray:
    """``(n, 3) int64``: the grid index of the head translation (ES units) on each axis."""
    t_index = np.rint(translation / t_steps).astype(np.int64)
    # |t| ≤ MAX_TRANSLATION keeps |t / step| far below MAX_INDEX; its grid point may lie
    # beyond the bound only within half a step of it
    beyond = ~(np.abs(t_index * t_steps) <= MAX_TRANSLATION)
    if np.any(beyond):
        i, a = (int(x) for x in np.argwhere(beyond)[0])
        value = float(translation[i, a])
        raise CodingError(
            f"head translation {TRANSLATION_AXES[a]} = {value!r} in frame "
            f"{i} is too large to code with step {t_steps[a]:g}: its reconstruction would "
            f"leave ±{MAX_TRANSLATION:g} ES units"
        )
    return t_index


def _check_steps(steps: Mapping[int | str, int] | None) -> dict[int | str, int]:
    """``steps`` of :func:`encode`, checked: FAP numbers 3–68 and ``tx``/``ty``/``tz`` to whole
    base steps within 1–:data:`MAX_BASE_STEP`."""
    if steps is None:
        return {}
    if not isinstance(steps, Mapping):
        raise FapError(f"steps must map FAPs to base steps, got {type(steps).__name__}")
    out: dict[int | str, int] = {}
    for key, value in steps.items():
        if not (key in TRANSLATION_AXES or (isinstance(key, int) and 3 <= key <= N_FAPS)):
            raise FapError(
                f"steps: {key!r} is not a low-level FAP (3–{N_FAPS}) nor a translation axis "
                f"({', '.join(TRANSLATION_AXES)})"
            )
        if isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise FapError(f"steps: the base step of {key} must be a whole number, got {value!r}")
        if not 1 <= value <= MAX_BASE_STEP:
            raise FapError(f"steps: the base step of {key} must be within 1–{MAX_BASE_STEP}, "
                           f"got {value}")  # fmt: skip
        out[key] = int(value)
    return out


def _prepare(
    stream: FapStream,
    faps: Iterable[int | str] | str | None,
    rate: float | None,
    quantizer: float,
    translation: bool = True,
    steps: Mapping[int | str, int] | None = None,
) -> _Plan:
    if not isinstance(stream, FapStream):
        raise FapError(f"expected a FapStream, got {type(stream).__name__}")
    q32 = _check_quantizer(quantizer)
    own = _check_steps(steps)
    wanted = set(range(1, N_FAPS + 1)) if faps is None else set(fap_set(faps))
    if rate is not None and float(rate) != stream.fps:
        stream = stream.resample(rate)
    n = stream.n_frames
    if n > MAX_FRAMES:
        raise CodingError(f"the stream has {n} frames; at most {MAX_FRAMES} can be coded")
    if stream.first_frame >= 1 << 32:
        raise CodingError(f"first frame number {stream.first_frame} must be below 2^32")
    name_bytes = len(stream.name.encode("utf-8"))
    if name_bytes > MAX_NAME_BYTES:
        raise CodingError(f"the stream's name has {name_bytes} bytes; at most {MAX_NAME_BYTES}")
    present = stream.mask.any(axis=0)
    coded = tuple(k for k in range(1, N_FAPS + 1) if present[k - 1] and k in wanted)
    low = tuple(k for k in coded if k >= 3)
    base = tuple(own.get(k, FAPS[k - 1].quant_step) for k in low)
    grid = _steps(base, q32)
    mask = stream.mask[:, [k - 1 for k in coded]]
    index = _quantize(stream, low, grid)
    viseme = stream.viseme if 1 in coded else None
    expression = stream.expression if 2 in coded else None
    t_base: tuple[int, ...] = ()
    t_steps = t_index = None
    if translation and stream.translation is not None:
        t_base = tuple(own.get(a, TRANSLATION_BASE_STEP) for a in TRANSLATION_AXES)
        t_steps = _steps(t_base, q32)
        t_index = _quantize_translation(stream.translation, t_steps)
    recon = _assemble(
        stream.fps,
        stream.name,
        stream.first_frame,
        coded,
        low,
        grid,
        mask,
        index,
        np.zeros((n, 4), np.int64) if viseme is None else viseme,
        np.zeros((n, 6), np.int64) if expression is None else expression,
        t_steps,
        t_index,
    )
    return _Plan(stream, coded, low, base, q32, mask, index, recon, t_base, t_index)


def reconstruct(
    stream: FapStream,
    *,
    faps: Iterable[int | str] | str | None = None,
    rate: float | None = None,
    quantizer: float = 1.0,
    translation: bool = True,
    steps: Mapping[int | str, int] | None = None,
) -> FapStream:
    """The stream a decoder reconstructs from ``encode(stream, …)`` with the same arguments
    (either coder): the selected FAPs at ``rate``, low-level values on their quantizer grid, the
    head translation (when the stream has one and ``translation``) on its grid.

    ``decode(encode(s, **kw)) == reconstruct(s, **kw)`` holds exactly (same arrays, name, rate,
    first frame; version 2.1).
    """
    return _prepare(stream, faps, rate, quantizer, translation, steps).reconstruction


def source_stream(
    stream: FapStream,
    *,
    faps: Iterable[int | str] | str | None = None,
    rate: float | None = None,
    translation: bool = True,
) -> FapStream:
    """What the encoder codes before quantization: ``stream`` resampled to ``rate`` with only the
    selected FAPs (those masked in some frame) kept, and its head translation if it is sent.
    Compare a decoded stream with this one."""
    plan = _prepare(stream, faps, rate, 1.0, translation)
    s = plan.source
    keep = np.zeros(N_FAPS, dtype=bool)
    keep[[k - 1 for k in plan.faps]] = True
    mask = s.mask & keep
    return FapStream(
        fps=s.fps,
        name=s.name,
        values=np.where(mask, s.values, 0.0),
        mask=mask,
        viseme=s.viseme if keep[0] else None,
        expression=s.expression if keep[1] else None,
        first_frame=s.first_frame,
        translation=s.translation if plan.translation_steps else None,
    )


def error_stats(reference: FapStream, decoded: FapStream) -> dict[int | str, tuple[float, float]]:
    """Per low-level FAP set in ``decoded``: ``(max, rms)`` of ``|decoded − reference|`` in FAP
    units over the frames that set it; and when ``decoded`` carries a head translation, the same
    for each of its axes (keys ``"tx"``, ``"ty"``, ``"tz"``, ES units, every frame). The streams
    must have the same frames (and both a translation, or ``decoded`` none)."""
    if reference.n_frames != decoded.n_frames:
        raise FapError(
            f"the streams have {reference.n_frames} and {decoded.n_frames} frames: "
            "compare a decoded stream with source_stream() of the original"
        )
    if decoded.translation is not None and reference.translation is None:
        raise FapError(
            "the decoded stream carries a head translation, the reference none: "
            "compare a decoded stream with source_stream() of the original"
        )
    out: dict[int | str, tuple[float, float]] = {}
    for k in range(3, N_FAPS + 1):
        m = decoded.mask[:, k - 1]
        if m.any():
            d = np.abs(decoded.values[m, k - 1] - reference.values[m, k - 1])
            out[k] = (float(d.max()), float(np.sqrt(np.mean(d * d))))
    if decoded.translation is not None and decoded.n_frames:
        for a, axis in enumerate(TRANSLATION_AXES):
            d = np.abs(decoded.translation[:, a] - reference.translation[:, a])  # type: ignore[index]
            out[axis] = (float(d.max()), float(np.sqrt(np.mean(d * d))))
    return out


# --- the header ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class FbsHeader:
    """What a ``.fbs`` header says (see ``docs/fap-coding.md`` for the bytes).

    Attributes:
        coder: ``"huffman"`` or ``"arithmetic"``.
        fps: frame rate of the coded stream, Hz.
        first_frame: the number of the first frame (as in a ``.fap`` file).
        n_frames: number of frames.
        faps: the coded FAPs, ascending.
        quantizer: the global step factor (float32).
        base_steps: the base step of each coded low-level FAP, in order.
        constant_mask: every frame sets every coded FAP (no mask is sent per frame).
        name: the stream's name.
        huffman_tables: Huffman mode: up to 4 codes, each the code length (bits) of each
            symbol −64…63 it has (−64 = escape).
        huffman_table_of: Huffman mode: the table of each coded low-level FAP, in order, then
            of each translation axis (when sent).
        translation_base_steps: the base steps of the head translation's axes tx, ty, tz (ES
            units; :data:`TRANSLATION_BASE_STEP`), or ``()`` when the stream carries none.
        predictors: arithmetic mode: FAP → the earlier FAP whose error in the same frame
            predicts its error.
        header_size, payload_size: bytes of the header (with its CRC) and of the frame data
            (without its CRC); the file has ``header_size + payload_size + 4`` bytes. For a
            stream (``stream``), the frame data are the packets and the end marker before its
            CRC, and both are known only once the whole stream was read (0 before).
        stream: a streamed bitstream (header flag bit 2): the frames follow as packets, each
            decodable as soon as it arrives, and an end marker (:class:`StreamEncoder`);
            ``n_frames`` is then the count of the end marker (0 when only the header was read).
    """

    coder: str
    fps: float
    first_frame: int
    n_frames: int
    faps: tuple[int, ...]
    quantizer: float
    base_steps: tuple[int, ...]
    constant_mask: bool
    name: str
    huffman_tables: tuple[dict[int, int], ...] = ()
    huffman_table_of: tuple[int, ...] = ()
    predictors: dict[int, int] = field(default_factory=dict)
    version: int = VERSION
    header_size: int = 0
    payload_size: int = 0
    translation_base_steps: tuple[int, ...] = ()
    stream: bool = False

    @property
    def low(self) -> tuple[int, ...]:
        """The coded low-level FAPs (3–68)."""
        return tuple(k for k in self.faps if k >= 3)

    @property
    def translation(self) -> bool:
        """Whether the bitstream carries the head translation."""
        return bool(self.translation_base_steps)

    @property
    def steps(self) -> dict[int | str, float]:
        """Quantizer step of each coded low-level FAP, in its FAP units, and of each head
        translation axis (``"tx"``, ``"ty"``, ``"tz"``; ES units) when it is sent."""
        out: dict[int | str, float] = {}
        out.update(zip(self.low, _steps(self.base_steps, self.quantizer).tolist(), strict=True))
        t = _steps(self.translation_base_steps, self.quantizer).tolist()
        out.update(zip(TRANSLATION_AXES[: len(t)], t, strict=True))
        return out

    @property
    def size(self) -> int:
        """Bytes of the whole bitstream."""
        return self.header_size + self.payload_size + 4

    @property
    def bits_per_frame(self) -> float:
        """Bits of the whole bitstream (header included) per frame."""
        return 8 * self.size / self.n_frames if self.n_frames else 0.0

    @property
    def kbit_per_s(self) -> float:
        """Bit rate of the whole bitstream, kbit/s."""
        return self.bits_per_frame * self.fps / 1000


def _varint(value: int) -> bytes:
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        if value:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


def _mask_bytes(faps: Iterable[int]) -> bytes:
    bits = 0
    for k in faps:
        bits |= 1 << (71 - (k - 1))  # FAP 1 is the first (most significant) bit
    return bits.to_bytes(9, "big")


def _zigzag(s: int) -> int:
    return 2 * s if s >= 0 else -2 * s - 1


def _unzigzag(z: int) -> int:
    return z >> 1 if not z & 1 else -((z + 1) >> 1)


def _pack_table(lengths: dict[int, int]) -> bytes:
    """A code's lengths: the count n of entries, then 4-bit lengths of the escape and of the
    symbols 0, −1, 1, −2, 2, … (n of them), two per byte."""
    n = max((_zigzag(s) + 1 for s in lengths if s != ESCAPE), default=0)
    nibbles = [lengths.get(ESCAPE, 0)] + [lengths.get(_unzigzag(z), 0) for z in range(n)]
    if len(nibbles) % 2:
        nibbles.append(0)
    pairs = zip(nibbles[::2], nibbles[1::2], strict=True)
    return bytes([n]) + bytes((a << 4) | b for a, b in pairs)


def _pack_header(h: FbsHeader, payload_size: int) -> bytes:
    flags = _FLAG_CONSTANT_MASK if h.constant_mask else 0
    if h.translation:
        flags |= _FLAG_TRANSLATION
    if h.stream:
        flags |= _FLAG_STREAM
    out = bytearray(
        _FIXED.pack(
            MAGIC,
            VERSION,
            CODERS[h.coder],
            flags,
            h.fps,
            h.first_frame,
            0 if h.stream else h.n_frames,
            _mask_bytes(h.faps),
            h.quantizer,
        )
    )
    for b in (*h.base_steps, *h.translation_base_steps):
        out += _varint(b)
    name = h.name.encode("utf-8")
    out += _varint(len(name)) + name
    if h.coder == "huffman":
        out.append(len(h.huffman_tables))
        if len(h.huffman_tables) > 1:
            bits = 0
            for t in h.huffman_table_of:
                bits = (bits << 2) | t
            nbytes = (2 * len(h.huffman_table_of) + 7) // 8
            out += (bits << (8 * nbytes - 2 * len(h.huffman_table_of))).to_bytes(nbytes, "big")
        for table in h.huffman_tables:
            out += _pack_table(table)
    else:
        out.append(len(h.predictors))
        for k in sorted(h.predictors):
            out += bytes([k, h.predictors[k]])
    out += struct.pack(">I", payload_size)
    out += struct.pack(">I", zlib.crc32(out))
    return bytes(out)


class _Cursor:
    """Reads the header's fields, reporting where data ends or a field is wrong. With a
    ``source`` (a binary file object), ``data`` grows by what is read from it as needed."""

    def __init__(self, data: bytes, file: str | None, source: BinaryIO | None = None) -> None:
        self.data = data
        self.pos = 0
        self.file = file
        self.source = source

    def error(self, message: str, offset: int | None = None) -> CodingError:
        return CodingError(message, offset=self.pos if offset is None else offset, file=self.file)

    def take(self, n: int, what: str) -> bytes:
        if self.source is not None and self.pos + n > len(self.data):
            self.data += _read_up_to(self.source, self.pos + n - len(self.data))
        if self.pos + n > len(self.data):
            raise self.error(
                f"unexpected end of data inside the {what} ({n} bytes from byte {self.pos}): "
                "the file is truncated (or a length before it is damaged)",
                len(self.data),
            )
        chunk = self.data[self.pos : self.pos + n]
        self.pos += n
        return chunk

    def varint(self, what: str, limit: int) -> tuple[int, int]:
        start = self.pos
        value = shift = 0
        while True:
            byte = self.take(1, what)[0]
            value |= (byte & 0x7F) << shift
            shift += 7
            if not byte & 0x80:
                break
            if shift > 28:
                raise self.error(f"{what} is not a varint of at most 5 bytes", start)
        if value > limit:
            raise self.error(f"{what} must be at most {limit}, got {value}", start)
        return value, start


def _read_up_to(source: BinaryIO, n: int) -> bytes:
    """Up to ``n`` bytes of ``source``: fewer only at its end (a pipe's reads may be short)."""
    out = b""
    while len(out) < n:
        chunk = source.read(n - len(out))
        if not chunk:
            break
        out += chunk
    return out


def read_header(data: bytes, *, file: str | None = None) -> FbsHeader:
    """Parse and check the header of a ``.fbs`` bitstream, and the framing of the whole.

    Checks, in this order, each failure a :class:`CodingError` at the byte concerned: magic,
    version, coder, flags, frame rate, frame count and FAP mask; the variable fields' extents; the
    header CRC; the fields' values (steps, name, Huffman code, predictors); the file's length
    against the announced frame data; the frame data's CRC. Frames are not decoded.
    """
    if not isinstance(data, bytes | bytearray | memoryview):
        raise CodingError(f"expected bytes, got {type(data).__name__}", file=file)
    data = bytes(data)
    cur = _Cursor(data, file)
    h = _parse_header(cur)
    if h.stream:
        packets = _Packets(cur, h)
        for _ in packets:
            pass
        return replace(h, n_frames=packets.count, payload_size=packets.end - h.header_size)
    return _check_whole(cur, h)


def _parse_header(cur: _Cursor) -> FbsHeader:
    """The header at the start of ``cur``, checked up to its CRC and its fields' values."""
    if cur.source is not None:
        cur.data += _read_up_to(cur.source, 4)
    data = cur.data
    head = data[:4]
    if head != MAGIC[: len(head)]:
        raise cur.error(f"not a vtts FAP bitstream: expected the magic {MAGIC!r}, got {head!r}", 0)
    magic, version, coder_id, flags, fps, first_frame, n_frames, mask, quantizer = _FIXED.unpack(
        cur.take(_FIXED.size, "fixed header")
    )
    del magic
    if version != VERSION:
        raise cur.error(f"unsupported bitstream version {version} (this decoder reads 1)", 4)
    if coder_id not in _CODER_NAMES:
        raise cur.error(f"unknown coder {coder_id} (0 = Huffman, 1 = arithmetic)", 5)
    if flags & ~_FLAGS:
        raise cur.error(f"unknown flags 0x{flags:02x} (only bits 0 to 2 are defined)", 6)
    stream = bool(flags & _FLAG_STREAM)
    if stream and coder_id != CODERS["arithmetic"]:
        raise cur.error("a streamed bitstream (flag bit 2) needs the arithmetic coder", 5)
    if stream and n_frames:
        raise cur.error(
            f"a streamed bitstream's header counts no frames (its end marker does), got {n_frames}",
            19,
        )
    if not (math.isfinite(fps) and fps > 0):
        raise cur.error(f"frame rate must be finite and > 0, got {fps!r}", 7)
    if not MIN_FPS <= fps <= MAX_FPS:
        raise cur.error(f"frame rate {fps:g} is outside the limits {MIN_FPS:g}–{MAX_FPS:g}", 7)
    if n_frames > MAX_FRAMES:
        raise cur.error(f"{n_frames} frames exceed the decoder's limit of {MAX_FRAMES}", 19)
    if n_frames / fps > MAX_DURATION_S:
        raise cur.error(
            f"{n_frames} frames at {fps:g} Hz last {n_frames / fps:g} s, more than the limit of "
            f"{MAX_DURATION_S:g} s",
            19,
        )
    bits = int.from_bytes(mask, "big")
    if bits & 0xF:
        raise cur.error("FAP mask sets bits past FAP 68", 31)
    faps = tuple(k for k in range(1, N_FAPS + 1) if bits >> (71 - (k - 1)) & 1)
    lo_q, hi_q = QUANTIZER_RANGE
    if not (math.isfinite(quantizer) and lo_q <= quantizer <= hi_q):
        raise cur.error(f"quantizer must be within {lo_q:g}–{hi_q:g}, got {quantizer!r}", 32)
    coder = _CODER_NAMES[coder_id]
    low = tuple(k for k in faps if k >= 3)

    # variable fields: extents now, values once the CRC vouches for them
    steps = [cur.varint(f"base step of FAP {k}", MAX_BASE_STEP) for k in low]
    sent = TRANSLATION_AXES if flags & _FLAG_TRANSLATION else ()
    steps += [cur.varint(f"base step of the head translation's {a}", MAX_BASE_STEP) for a in sent]
    # the channels whose errors are coded: the low-level FAPs, then the translation's axes
    channels = [f"FAP {k}" for k in low] + [f"head translation {a}" for a in sent]
    name_len, name_at = cur.varint("name length", MAX_NAME_BYTES)
    name_at = cur.pos
    name_raw = cur.take(name_len, "name")
    table_at = cur.pos
    raw_tables: list[tuple[int, int, bytes]] = []
    assignment = b""
    if coder == "huffman":
        count = cur.take(1, "Huffman table count")[0]
        if count > 4:
            raise cur.error(f"at most 4 Huffman tables, got {count}", table_at)
        if count > 1:
            assignment = cur.take((2 * len(channels) + 7) // 8, "Huffman table assignment")
        for _ in range(count):
            at = cur.pos
            n = cur.take(1, "Huffman table")[0]
            if n > 2 * SYMBOL_MAX + 1:
                raise cur.error(f"a Huffman table has at most 127 symbols, got {n}", at)
            raw_tables.append((at, n, cur.take((n + 2) // 2, "Huffman table")))
        table = b""
    else:
        count = cur.take(1, "predictor list")[0]
        table = cur.take(2 * count, "predictor list")
    size_at = cur.pos
    (payload_size,) = struct.unpack(">I", cur.take(4, "frame data length"))
    crc_at = cur.pos
    (stored,) = struct.unpack(">I", cur.take(4, "header CRC"))
    data = cur.data
    computed = zlib.crc32(data[:crc_at])
    if stored != computed:
        raise cur.error(
            f"header CRC-32 mismatch (stored 0x{stored:08x}, computed 0x{computed:08x}): "
            f"bytes 0–{crc_at - 1} are corrupt",
            crc_at,
        )
    header_size = cur.pos
    if stream and payload_size:
        raise cur.error(
            f"a streamed bitstream's header announces no frame data length, got {payload_size}",
            size_at,
        )

    base_steps = []
    for value, at in steps:
        if value < 1:
            raise cur.error("a base step must be ≥ 1, got 0", at)
        base_steps.append(value)
    try:
        name = name_raw.decode("utf-8")
        FapStream(fps=fps, name=name, values=np.zeros((0, N_FAPS)), mask=np.zeros((0, N_FAPS)))
    except (UnicodeDecodeError, FapError) as e:
        raise cur.error(f"invalid stream name {name_raw!r}: {e}", name_at) from None
    tables: list[dict[int, int]] = []
    table_of: list[int] = []
    predictors: dict[int, int] = {}
    if coder == "huffman":
        for at, n, raw in raw_tables:
            nibbles = [x for b in raw for x in (b >> 4, b & 0xF)][: n + 1]
            lengths = {ESCAPE: nibbles[0]} | {_unzigzag(z): x for z, x in enumerate(nibbles[1:])}
            lengths = {s: x for s, x in lengths.items() if x}
            kraft = sum(1 << (MAX_CODE_LENGTH - x) for x in lengths.values())
            single = len(lengths) == 1 and next(iter(lengths.values())) == 1
            if kraft != 1 << MAX_CODE_LENGTH and not single:
                raise cur.error("Huffman code lengths do not form a complete prefix code", at)
            tables.append(lengths)
        nc = len(channels)
        if len(tables) > 1:
            bits = int.from_bytes(assignment, "big") >> (8 * len(assignment) - 2 * nc)
            table_of = [(bits >> (2 * (nc - 1 - j))) & 3 for j in range(nc)]
            for j, x in enumerate(table_of):
                if x >= len(tables):
                    raise cur.error(
                        f"{channels[j]} uses Huffman table {x} of {len(tables)}",
                        table_at + 1 + j // 4,
                    )
        else:
            table_of = [0] * nc if tables else []
    elif coder == "arithmetic":
        low_set = set(low)
        for i in range(count):
            k, p = table[2 * i], table[2 * i + 1]
            at = table_at + 1 + 2 * i
            if k not in low_set or p not in low_set or p >= k or k in predictors:
                raise cur.error(
                    f"predictor entry {k} ← {p}: both must be coded low-level FAPs, the "
                    "predicting one earlier, each FAP listed once",
                    at,
                )
            predictors[k] = p
    return FbsHeader(
        coder=coder,
        fps=fps,
        first_frame=first_frame,
        n_frames=n_frames,
        faps=faps,
        quantizer=quantizer,
        base_steps=tuple(base_steps[: len(low)]),
        constant_mask=bool(flags & _FLAG_CONSTANT_MASK),
        name=name,
        huffman_tables=tuple(tables),
        huffman_table_of=tuple(table_of),
        predictors=predictors,
        version=version,
        header_size=header_size,
        payload_size=payload_size,
        translation_base_steps=tuple(base_steps[len(low) :]),
        stream=stream,
    )


def _check_whole(cur: _Cursor, h: FbsHeader) -> FbsHeader:
    """The framing of a whole (not streamed) bitstream: its length and frame data CRC."""
    data, header_size, payload_size = cur.data, h.header_size, h.payload_size
    end = header_size + payload_size
    if end + 4 > len(data):
        raise cur.error(
            f"unexpected end of data: the header announces {payload_size} bytes of frame data "
            f"and a CRC ending at byte {end + 4}, the file ends at byte {len(data)}: "
            "the file is truncated",
            len(data),
        )
    if end + 4 < len(data):
        raise cur.error(
            f"{len(data) - end - 4} unexpected bytes after the end of the bitstream", end + 4
        )
    (stored,) = struct.unpack(">I", data[end : end + 4])
    computed = zlib.crc32(data[header_size:end])
    if stored != computed:
        raise cur.error(
            f"frame data CRC-32 mismatch (stored 0x{stored:08x}, computed 0x{computed:08x}): "
            f"bytes {header_size}–{end - 1} are corrupt",
            end,
        )
    return h


# --- the frame syntax, shared by encoder and decoder -------------------------------------------


class _Io:
    """One coder's way of sending the syntax elements. Each method sends ``value`` and returns
    it when encoding (``value`` given), and returns the value read when decoding (``None``)."""

    def begin_frame(self) -> None:
        pass

    def flag(self, ctx: tuple, bit: int | None) -> int:
        raise NotImplementedError

    def field(self, channel: int, nbits: int, value: int | None, prev: int) -> int:
        raise NotImplementedError

    def residual(self, channel: int, value: int | None) -> int:
        raise NotImplementedError

    def offset(self) -> int:
        """Byte offset (in the whole bitstream) of the data being read, for error messages."""
        return 0

    def error(self, message: str) -> CodingError:
        return CodingError(message, offset=self.offset(), file=getattr(self, "file", None))


class _FrameSyntax:
    """The frame syntax, one frame at a time: what encoder and decoder carry from frame to frame
    (the current mask, each FAP's last index, the high-level fields, the translation's last
    index). :func:`_syntax` runs it over a whole stream, :class:`StreamEncoder` and
    :class:`StreamDecoder` frame by frame, so that both forms send the very same decisions.

    Channels (a coder's error statistics and contexts): the low-level FAPs 0 … L−1, the
    translation's axes L … L+T−1 (T = 3 when sent, else 0), then the viseme fields (4) and the
    expression fields (6). Without translation they are numbered as in the first bitstreams."""

    def __init__(self, h: FbsHeader) -> None:
        self.h = h
        faps, low = h.faps, h.low
        self.nk, self.nl = len(faps), len(low)
        self.nt = len(h.translation_base_steps)
        self.pos = {k: i for i, k in enumerate(faps)}
        self.low_pos = [self.pos[k] for k in low]
        self.pred = [low.index(h.predictors[k]) if k in h.predictors else -1 for k in low]
        hl = self.nl + self.nt  # the first high-level field's channel
        self.v_fields = [
            (VISEME_FIELDS, _VISEME_BITS, hl),
            (EXPRESSION_FIELDS, _EXPRESSION_BITS, hl + 4),
        ]
        self.t_steps = _steps(h.translation_base_steps, h.quantizer).tolist()
        self.t_last = [0] * self.nt
        self.cur = [True] * self.nk
        self.last = [0] * self.nl
        self.last_high = [[0] * 4, [0] * 6]

    def frame(
        self,
        io: _Io,
        i: int,
        row: tuple | None = None,
    ) -> tuple[list[bool], list[int], list[int], list[int], list[int]]:
        """Send frame ``i`` (``row`` = ``(mask, index, viseme, expression, translation)``: the
        ``(K,)`` mask of the coded FAPs, the ``(L,)`` indices, the 4 viseme and 6 expression
        fields and the ``(T,)`` translation indices) or read it (``row`` None); return the row
        as the decoder sees it (high-level fields and indices held where not set)."""
        h, nk, nl, cur, pos = self.h, self.nk, self.nl, self.cur, self.pos
        low = h.low
        io.begin_frame()
        if not h.constant_mask:
            want = None if row is None else [bool(x) for x in row[0]]
            changed = io.flag(("mask?",), None if want is None else int(want != cur))
            if changed:
                for j in range(nk):
                    cur[j] = bool(io.flag(("mask", j, cur[j]), None if want is None else want[j]))
        mask = list(cur)
        high_rows = []
        for which in (0, 1):
            prev = self.last_high[which]
            if (which + 1) not in pos or not cur[pos[which + 1]]:
                high_rows.append([0] * len(prev))  # 0 where not set, as reconstruct() has it
                continue
            fields, widths, channel = self.v_fields[which]
            want = None if row is None else [int(x) for x in row[2 + which]]
            same = io.flag(("same", which), None if want is None else int(want == prev))
            if not same:
                for f, (label, lo, hi) in enumerate(fields):
                    value = io.field(
                        channel + f, widths[f], None if want is None else want[f], prev[f]
                    )
                    if not lo <= value <= hi:
                        raise io.error(f"{label} {value} in frame {i} is outside {lo}–{hi}")
                    prev[f] = value
            high_rows.append(list(prev))
        q_now = [0] * nl
        index = [0] * nl
        for j in range(nl):
            if not cur[self.low_pos[j]]:
                continue
            p = self.pred[j]
            base = q_now[p] if p >= 0 and cur[self.low_pos[p]] else 0
            q = None if row is None else int(row[1][j]) - self.last[j]
            v = io.residual(j, None if q is None else q - base)
            q = v + base
            value = self.last[j] + q
            if not -MAX_INDEX < value < MAX_INDEX:
                raise io.error(f"FAP {low[j]} leaves the codable range in frame {i}")
            self.last[j] = value
            q_now[j] = q
            index[j] = value
        t_row = [0] * self.nt
        for a in range(self.nt):
            q = None if row is None else int(row[4][a]) - self.t_last[a]
            value = self.t_last[a] + io.residual(nl + a, q)
            if not abs(value * self.t_steps[a]) <= MAX_TRANSLATION:
                raise io.error(
                    f"the head translation's {TRANSLATION_AXES[a]} leaves ±{MAX_TRANSLATION:g} "
                    f"ES units in frame {i}"
                )
            self.t_last[a] = value
            t_row[a] = value
        return mask, index, high_rows[0], high_rows[1], t_row


def _syntax(io: _Io, h: FbsHeader, plan: _Plan | None) -> tuple[np.ndarray, ...]:
    """Send (``plan`` given) or read the frames; return ``(mask, index, viseme, expression,
    translation)`` as the decoder sees them: ``(n, K) bool``, ``(n, L) int64``, ``(n, 4)`` and
    ``(n, 6) int64``, and the translation's indices ``(n, 3) int64`` (``(n, 0)`` when not sent).
    The channels are :class:`_FrameSyntax`'s."""
    n = h.n_frames
    nk, nl, nt = len(h.faps), len(h.low), len(h.translation_base_steps)
    syntax = _FrameSyntax(h)
    t_index = np.zeros((n, nt), dtype=np.int64)
    mask = np.zeros((n, nk), dtype=bool)
    index = np.zeros((n, nl), dtype=np.int64)
    high = [np.zeros((n, 4), dtype=np.int64), np.zeros((n, 6), dtype=np.int64)]
    for i in range(n):
        row = None if plan is None else _plan_row(plan, i)
        m, x, v, e, t = syntax.frame(io, i, row)
        mask[i], index[i], high[0][i], high[1][i], t_index[i] = m, x, v, e, t
    if plan is not None:
        assert np.array_equal(mask, plan.mask) and np.array_equal(index, plan.index)
        assert nt == 0 or np.array_equal(t_index, plan.translation_index)
    return mask, index, high[0], high[1], t_index


def _plan_row(plan: _Plan, i: int) -> tuple:
    """Frame ``i`` of ``plan`` as :meth:`_FrameSyntax.frame` sends it. Where FAP 1 or 2 is not
    coded its fields are not read."""
    src = plan.source
    return (
        plan.mask[i].tolist(),
        plan.index[i].tolist(),
        None if src.viseme is None else src.viseme[i].tolist(),
        None if src.expression is None else src.expression[i].tolist(),
        () if plan.translation_index is None else plan.translation_index[i].tolist(),
    )


# --- Huffman mode -------------------------------------------------------------------------------


def _symbol(q: int, lengths: dict[int, int] | None = None) -> int:
    """The symbol that sends error ``q``: q itself, or the escape for |q| > 63 and for errors
    the table has no code for."""
    if -SYMBOL_MAX <= q <= SYMBOL_MAX and (lengths is None or q in lengths):
        return q
    return ESCAPE


def _exp_golomb_bits(x: int) -> int:
    return 2 * (x + 1).bit_length() - 1


def huffman_lengths(counts: dict[int, int], limit: int = MAX_CODE_LENGTH) -> dict[int, int]:
    """Code lengths of a Huffman code for symbol ``counts`` (ties broken by symbol, so the
    result is deterministic), no longer than ``limit`` bits: if the optimal code is deeper, the
    counts are halved until it fits. A single symbol gets length 1."""
    items = sorted((s, c) for s, c in counts.items() if c > 0)
    if not items:
        return {}
    if len(items) == 1:
        return {items[0][0]: 1}
    while True:
        heap = [(c, i, [s]) for i, (s, c) in enumerate(items)]
        heapq.heapify(heap)
        depth = dict.fromkeys((s for s, _ in items), 0)
        order = len(heap)
        while len(heap) > 1:
            c1, _, s1 = heapq.heappop(heap)
            c2, _, s2 = heapq.heappop(heap)
            for s in s1 + s2:
                depth[s] += 1
            heapq.heappush(heap, (c1 + c2, order, s1 + s2))
            order += 1
        if max(depth.values()) <= limit:
            return depth
        items = [(s, (c + 1) // 2) for s, c in items]


def _code_cost(errors: dict[int, int], lengths: dict[int, int]) -> float:
    """Bits to send the errors (error → count) with a code; inf if it cannot."""
    bits = 0
    for q, c in errors.items():
        s = _symbol(q, lengths)
        if s not in lengths:
            return math.inf
        bits += c * lengths[s]
        if s == ESCAPE:
            bits += c * _exp_golomb_bits(_zigzag(q))
    return bits


def _group_code(errors: list[dict[int, int]], escape: bool, trim: bool = False) -> dict[int, int]:
    """The Huffman code for a group of FAPs' errors. ``escape``: give the escape a code even if
    no error needs it (so that any FAP can use the table). ``trim``: also choose how many
    symbols the table lists, the rarer large errors going through the escape, for the fewest
    bits of table plus data."""
    merged: dict[int, int] = {}
    for e in errors:
        for q, c in e.items():
            merged[q] = merged.get(q, 0) + c
    cutoffs = [2 * SYMBOL_MAX + 1]
    if trim:
        cutoffs = sorted({_zigzag(q) + 1 for q in merged if -SYMBOL_MAX <= q <= SYMBOL_MAX})
        cutoffs = [0, *cutoffs]
    best: tuple[float, dict[int, int]] | None = None
    for n in cutoffs:
        counts: dict[int, int] = {ESCAPE: 1} if escape else {}
        escaped = 0
        for q, c in merged.items():
            s = q if -SYMBOL_MAX <= q <= SYMBOL_MAX and _zigzag(q) < n else ESCAPE
            counts[s] = counts.get(s, 0) + c
            if s == ESCAPE:
                escaped += c * _exp_golomb_bits(_zigzag(q))
        lengths = huffman_lengths(counts)
        if not trim:
            return lengths
        bits = escaped + sum(c * lengths[s] for s, c in counts.items())
        bits += 8 * len(_pack_table(lengths))
        if best is None or bits < best[0]:
            best = (bits, lengths)
    return best[1] if best else {}


def _choose_tables(errors: list[dict[int, int]]) -> tuple[tuple[dict[int, int], ...], tuple]:
    """Huffman tables for the FAPs' errors (``errors[j]``: error → count of low-level FAP j) and
    the table of each FAP: 1 to 4 tables, the FAPs grouped by k-means on their code cost, the
    number that needs the fewest bits with the tables' header bytes counted."""
    used = [j for j, e in enumerate(errors) if e]
    if not used:
        return (), ()
    single = _group_code(errors, escape=False, trim=True)
    best = (_code_cost_all(errors, [single], [0] * len(errors)), (single,), (0,) * len(errors))
    # start groups: FAPs ordered by how often they do not move
    order = sorted(used, key=lambda j: -errors[j].get(0, 0) / sum(errors[j].values()))
    for n_tables in range(2, min(4, len(used)) + 1):
        assign = [0] * len(errors)
        for rank, j in enumerate(order):
            assign[j] = rank * n_tables // len(order)
        for _ in range(10):
            groups = [[errors[j] for j in used if assign[j] == t] for t in range(n_tables)]
            if not all(groups):
                break
            tables = [_group_code(g, escape=True) for g in groups]
            new = list(assign)
            for j in used:
                costs = [_code_cost(errors[j], tb) for tb in tables]
                new[j] = costs.index(min(costs))
            if new == assign:
                break
            assign = new
        groups = [[errors[j] for j in used if assign[j] == t] for t in range(n_tables)]
        if not all(groups):
            continue
        tables = [_group_code(g, escape=True, trim=True) for g in groups]
        bits = _code_cost_all(errors, tables, assign) + 8 * ((2 * len(errors) + 7) // 8)
        if bits < best[0]:
            best = (bits, tuple(tables), tuple(assign))
    return best[1], best[2]


def _code_cost_all(errors: list[dict[int, int]], tables: list, assign: list[int]) -> float:
    data = sum(_code_cost(e, tables[assign[j]]) for j, e in enumerate(errors) if e)
    return data + 8 * sum(len(_pack_table(t)) for t in tables)


def _canonical(lengths: dict[int, int]) -> tuple[dict[int, tuple[int, int]], list[int], list[int]]:
    """Canonical codes ``symbol → (code, length)``, and for decoding the number of codes of each
    length (index 0…15) and the symbols in code order."""
    order = sorted(lengths, key=lambda s: (lengths[s], s))
    codes = {}
    code = prev = 0
    for s in order:
        code <<= lengths[s] - prev
        prev = lengths[s]
        codes[s] = (code, prev)
        code += 1
    counts = [0] * (MAX_CODE_LENGTH + 1)
    for n in lengths.values():
        counts[n] += 1
    return codes, counts, order


class _ErrorCounter(_Io):
    """First pass of the Huffman encoder: counts each FAP's errors."""

    def __init__(self, n_low: int) -> None:
        self.errors: list[dict[int, int]] = [{} for _ in range(n_low)]

    def flag(self, ctx: tuple, bit: int | None) -> int:
        return int(bit)  # type: ignore[arg-type]

    def field(self, channel: int, nbits: int, value: int | None, prev: int) -> int:
        return int(value)  # type: ignore[arg-type]

    def residual(self, channel: int, value: int | None) -> int:
        q = int(value)  # type: ignore[arg-type]
        e = self.errors[channel]
        e[q] = e.get(q, 0) + 1
        return q


class _HuffmanWriter(_Io):
    def __init__(self, tables: tuple[dict[int, int], ...], table_of: tuple[int, ...]) -> None:
        self.tables = [(lengths, _canonical(lengths)[0]) for lengths in tables]
        self.table_of = table_of
        self.out = bytearray()
        self.acc = 0
        self.nbits = 0

    def bits(self, value: int, n: int) -> None:
        self.acc = (self.acc << n) | value
        self.nbits += n
        while self.nbits >= 8:
            self.nbits -= 8
            self.out.append((self.acc >> self.nbits) & 0xFF)
        self.acc &= (1 << self.nbits) - 1

    def flag(self, ctx: tuple, bit: int | None) -> int:
        self.bits(int(bit), 1)  # type: ignore[arg-type]
        return int(bit)  # type: ignore[arg-type]

    def field(self, channel: int, nbits: int, value: int | None, prev: int) -> int:
        self.bits(int(value), nbits)  # type: ignore[arg-type]
        return int(value)  # type: ignore[arg-type]

    def residual(self, channel: int, value: int | None) -> int:
        q = int(value)  # type: ignore[arg-type]
        lengths, codes = self.tables[self.table_of[channel]]
        s = _symbol(q, lengths)
        self.bits(*codes[s])
        if s == ESCAPE:  # Exp-Golomb (order 0) of the zigzagged error
            x = _zigzag(q) + 1
            n = x.bit_length()
            self.bits(0, n - 1)
            self.bits(x, n)
        return q

    def finish(self) -> bytes:
        if self.nbits:
            self.bits(0, 8 - self.nbits)
        return bytes(self.out)


class _HuffmanReader(_Io):
    def __init__(
        self,
        data: bytes,
        base: int,
        tables: tuple[dict[int, int], ...],
        table_of: tuple[int, ...],
        file: str | None,
    ) -> None:
        self.tables = [_canonical(lengths)[1:] for lengths in tables]
        self.table_of = table_of
        self.data = data
        self.end = 8 * len(data)
        self.pos = 0
        self.base = base
        self.file = file

    def offset(self) -> int:
        return self.base + min(self.pos, self.end) // 8

    def bit(self) -> int:
        pos = self.pos
        if pos >= self.end:
            raise self.error("unexpected end of the frame data")
        self.pos = pos + 1
        return (self.data[pos >> 3] >> (7 - (pos & 7))) & 1

    def read(self, n: int) -> int:
        value = 0
        for _ in range(n):
            value = (value << 1) | self.bit()
        return value

    def flag(self, ctx: tuple, bit: int | None) -> int:
        return self.bit()

    def field(self, channel: int, nbits: int, value: int | None, prev: int) -> int:
        return self.read(nbits)

    def residual(self, channel: int, value: int | None) -> int:
        start = self.offset()
        if not self.tables:
            raise self.error("a frame sends a FAP error but the header has no Huffman table")
        counts, symbols = self.tables[self.table_of[channel]]
        code = first = index = 0
        for length in range(1, MAX_CODE_LENGTH + 1):
            code |= self.bit()
            count = counts[length]
            if code - first < count:
                s = symbols[index + code - first]
                break
            index += count
            first = (first + count) << 1
            code <<= 1
        else:
            raise CodingError("invalid Huffman code", offset=start, file=self.file)
        if s != ESCAPE:
            return s
        zeros = 0
        while not self.bit():
            zeros += 1
            if zeros > _MAX_MAGNITUDE_BITS:
                raise self.error("escape code longer than any codable error")
        return _unzigzag(((1 << zeros) | self.read(zeros)) - 1)

    def finish(self) -> None:
        if self.end - self.pos >= 8:
            raise self.error(f"{(self.end - self.pos) // 8} unused bytes after the last frame")
        if self.pos < self.end and self.read(self.end - self.pos):
            raise self.error("non-zero padding bits after the last frame")


# --- arithmetic mode ----------------------------------------------------------------------------

_PROB_BITS = 16
_PROB_ONE = 1 << _PROB_BITS
_PROB_MIN = 32
_HALF = _PROB_ONE // 2
_COUNT_LIMIT = 60  # counts are halved beyond this: the estimate follows changes in the stream
_TOP = 1 << 24
_MANTISSA_CONTEXT_BITS = 8  # magnitudes up to 2^8 have adaptive mantissa bits, larger bypass


def _magnitude_class(v: int) -> int:
    v = abs(v)
    return 0 if v == 0 else 1 if v == 1 else 2 if v < 4 else 3


class _Adaptive(_Io):
    """The context modelling of the arithmetic mode over an abstract binary coder ``code``."""

    def __init__(self) -> None:
        self.models: dict[tuple, list[int]] = {}
        self.prev: dict[int, int] = {}
        self.active = 0

    def code(self, bit: int | None, p0: int) -> int:
        raise NotImplementedError

    def bit(self, ctx: tuple | None, bit: int | None) -> int:
        if ctx is None:
            return self.code(bit, _HALF)
        m = self.models.get(ctx)
        if m is None:
            m = self.models[ctx] = [0, 0]
        n0, n1 = m
        p0 = ((2 * n0 + 1) << _PROB_BITS) // (2 * (n0 + n1) + 2)
        p0 = min(max(p0, _PROB_MIN), _PROB_ONE - _PROB_MIN)
        b = self.code(bit, p0)
        m[b] += 1
        if n0 + n1 >= _COUNT_LIMIT:
            m[0] = (m[0] + 1) // 2
            m[1] = (m[1] + 1) // 2
        return b

    def begin_frame(self) -> None:
        self.active = 0

    def flag(self, ctx: tuple, bit: int | None) -> int:
        return self.bit(ctx, bit)

    def field(self, channel: int, nbits: int, value: int | None, prev: int) -> int:
        d = self.residual(channel, None if value is None else value - prev)
        return prev + d

    def residual(self, channel: int, value: int | None) -> int:
        enc = value is not None
        prev = self.prev.get(channel, 0)
        c = _magnitude_class(prev)
        nonzero = self.bit(("z", channel, c, self.active), None if not enc else int(value != 0))
        if not nonzero:
            self.prev[channel] = 0
            self.active = 0
            return 0
        sign_ctx = 0 if prev == 0 else 1 if prev > 0 else 2
        negative = self.bit(("s", channel, sign_ctx), None if not enc else int(value < 0))
        m = abs(value) if enc else 0  # type: ignore[arg-type]
        e = m.bit_length()
        k = 1
        while k < _MAX_MAGNITUDE_BITS:
            more = self.bit(("e", channel, min(c, 2), min(k, 12)), None if not enc else int(e > k))
            if not more:
                break
            k += 1
        magnitude = 1
        for b in range(k - 2, -1, -1):
            ctx = ("m", channel, k, b) if k <= _MANTISSA_CONTEXT_BITS else None
            magnitude = (magnitude << 1) | self.bit(ctx, None if not enc else (m >> b) & 1)
        v = -magnitude if negative else magnitude
        self.prev[channel] = v
        self.active = 1
        return v


class _RangeWriter(_Adaptive):
    """LZMA's range encoder: 32-bit range, carries propagated through a cached byte."""

    def __init__(self) -> None:
        super().__init__()
        self.low = 0
        self.range = 0xFFFFFFFF
        self.cache = 0
        self.pending = 1
        self.out = bytearray()

    def code(self, bit: int | None, p0: int) -> int:
        bound = (self.range >> _PROB_BITS) * p0
        if bit:
            self.low += bound
            self.range -= bound
        else:
            self.range = bound
        while self.range < _TOP:
            self.range <<= 8
            self._shift_low()
        return int(bit)  # type: ignore[arg-type]

    def _shift_low(self) -> None:
        low = self.low
        if (low & 0xFFFFFFFF) < 0xFF000000 or low >> 32:
            carry = low >> 32
            temp = self.cache
            while self.pending:
                self.out.append((temp + carry) & 0xFF)
                temp = 0xFF
                self.pending -= 1
            self.cache = (low >> 24) & 0xFF
        self.pending += 1
        self.low = (low & 0x00FFFFFF) << 8

    def packet(self) -> bytes:
        """End a packet of a streamed bitstream: the fewest bytes that decode what was coded
        (the decoder reads zeros after them), then start the coder anew; the contexts stay.

        After renormalization the range is at least 2^24, so ``[low, low + range)`` holds a
        multiple of 2^24: coding it takes the pending bytes and at most one more, and the zero
        bytes at the end are left out."""
        self.low = (self.low + 0xFFFFFF) & ~0xFFFFFF
        self._shift_low()
        self._shift_low()
        out = self.out
        assert out[0] == 0  # the first byte is always 0: not sent
        data = bytes(out[1:]).rstrip(b"\0")
        self.low, self.range, self.cache, self.pending = 0, 0xFFFFFFFF, 0, 1
        self.out = bytearray()
        return data

    def finish(self) -> bytes:
        for _ in range(5):
            self._shift_low()
        assert self.out[0] == 0  # the first byte is always 0: not sent
        return bytes(self.out[1:])


class _RangeReader(_Adaptive):
    """The range decoder. ``pad``: a packet of a streamed bitstream, read as if zeros followed
    it (:meth:`_RangeWriter.packet`)."""

    def __init__(self, data: bytes, base: int, file: str | None, pad: bool = False) -> None:
        super().__init__()
        self.file = file
        self.pad = pad
        self.start(data, base)

    def start(self, data: bytes, base: int) -> None:
        """Start decoding ``data`` (at offset ``base`` of the bitstream); the contexts stay."""
        self.data = data
        self.pos = 0
        self.base = base
        self.range = 0xFFFFFFFF
        self.code_value = 0
        for _ in range(4):
            self.code_value = (self.code_value << 8) | self._byte()

    def offset(self) -> int:
        return self.base + self.pos

    def _byte(self) -> int:
        if self.pos >= len(self.data):
            if self.pad:
                self.pos += 1
                return 0
            raise self.error("unexpected end of the frame data")
        b = self.data[self.pos]
        self.pos += 1
        return b

    def code(self, bit: int | None, p0: int) -> int:
        bound = (self.range >> _PROB_BITS) * p0
        if self.code_value < bound:
            self.range = bound
            b = 0
        else:
            self.code_value -= bound
            self.range -= bound
            b = 1
        while self.range < _TOP:
            self.range <<= 8
            self.code_value = ((self.code_value << 8) | self._byte()) & 0xFFFFFFFF
        return b

    def finish(self) -> None:
        if self.pos != len(self.data):
            raise self.error(f"{len(self.data) - self.pos} unused bytes after the last frame")


def _errors(plan: _Plan) -> np.ndarray:
    """``(n, L) int64``: each low-level FAP's quantized prediction error (0 where not set)."""
    q = np.zeros_like(plan.index)
    low_mask = plan.mask[:, [plan.faps.index(k) for k in plan.low]]
    for j in range(len(plan.low)):
        rows = np.flatnonzero(low_mask[:, j])
        idx = plan.index[rows, j]
        q[rows, j] = np.diff(idx, prepend=0)
    return q


def _cost(v: np.ndarray) -> float:
    """Estimated bits to send the errors ``v`` (1-D): the entropy of their magnitude classes and
    signs plus the mantissa bits — what the adaptive binarization approaches."""
    if v.size == 0:
        return 0.0
    a = np.abs(v)
    cls = np.where(a <= 8, v, np.sign(v) * (8 + np.ceil(np.log2(np.maximum(a, 1)))))
    _, counts = np.unique(cls, return_counts=True)
    p = counts / v.size
    mantissa = np.where(a > 8, np.floor(np.log2(np.maximum(a, 1))), 0).sum()
    return float(-(counts * np.log2(p)).sum() + mantissa)


def _choose_predictors(plan: _Plan) -> dict[int, int]:
    """For each low-level FAP, the earlier FAP (same unit and step) whose error in the same frame
    best predicts its error, where that saves more than the header entry costs."""
    q = _errors(plan)
    low_mask = plan.mask[:, [plan.faps.index(k) for k in plan.low]]
    chosen = {}
    for j, k in enumerate(plan.low):
        rows = low_mask[:, j]
        if rows.sum() < 2:
            continue
        best, best_cost = -1, _cost(q[rows, j]) - 24.0  # a header entry costs 16 bits
        for p in range(j):
            kp = plan.low[p]
            if FAPS[kp - 1].fapu != FAPS[k - 1].fapu or plan.base_steps[p] != plan.base_steps[j]:
                continue
            v = q[:, j] - np.where(low_mask[:, p], q[:, p], 0)
            cost = _cost(v[rows])
            if cost < best_cost:
                best, best_cost = p, cost
        if best >= 0:
            chosen[k] = plan.low[best]
    return chosen


# --- encode and decode --------------------------------------------------------------------------


def encode(
    stream: FapStream,
    *,
    faps: Iterable[int | str] | str | None = None,
    rate: float | None = None,
    quantizer: float = 1.0,
    coder: str = "arithmetic",
    translation: bool = True,
    steps: Mapping[int | str, int] | None = None,
) -> bytes:
    """Code ``stream`` as a ``.fbs`` bitstream.

    Args:
        stream: the FAP stream.
        faps: the FAPs to send (numbers, names, ``"paper17"``…; see :func:`fap_set`); default
            all. FAPs no frame of the stream sets are not sent.
        rate: code at this frame rate, Hz (the stream is resampled, see
            :meth:`FapStream.resample`); default the stream's own.
        quantizer: the global factor of the quantizer steps (1 = the MPEG-4 steps of
            ``faps.tsv``); the reconstruction error of every value is at most half a step.
        coder: ``"huffman"`` (the paper's) or ``"arithmetic"`` (adaptive, fewer bits).
        translation: send the stream's head translation (:attr:`FapStream.translation`, in ES
            units, on the grid of :data:`TRANSLATION_BASE_STEP` · ``quantizer``) when it has
            one; ``False`` leaves it out. A stream without translation codes to the same bytes
            as before translation could be sent.
        steps: base steps of their own for some FAPs (numbers 3–68; FAP units) and translation
            axes (``"tx"``, ``"ty"``, ``"tz"``; ES units), whole numbers within 1–
            :data:`MAX_BASE_STEP`, instead of faps.tsv's ``quant_step`` and
            :data:`TRANSLATION_BASE_STEP` (e.g. :func:`vtts.analysis.coding_steps`, which makes
            one step of each move the face's image alike). The header carries every base step,
            so any decoder reads the stream as it reads any other.

    Returns the bitstream; ``decode`` of it equals :func:`reconstruct` with the same arguments.
    """
    if coder not in CODERS:
        raise FapError(f"unknown coder {coder!r}: expected one of {', '.join(CODERS)}")
    plan = _prepare(stream, faps, rate, quantizer, translation, steps)
    src = plan.source
    constant = bool(plan.mask.all())
    h = FbsHeader(
        coder=coder,
        fps=src.fps,
        first_frame=src.first_frame,
        n_frames=src.n_frames,
        faps=plan.faps,
        quantizer=plan.quantizer,
        base_steps=plan.base_steps,
        constant_mask=constant,
        name=src.name,
        translation_base_steps=plan.translation_steps,
    )
    if coder == "huffman":
        counter = _ErrorCounter(len(plan.low) + len(plan.translation_steps))
        _syntax(counter, h, plan)
        tables, table_of = _choose_tables(counter.errors)
        h = replace(h, huffman_tables=tables, huffman_table_of=table_of)
        writer: _HuffmanWriter | _RangeWriter = _HuffmanWriter(tables, table_of)
    else:
        h = replace(h, predictors=_choose_predictors(plan))
        writer = _RangeWriter()
    _syntax(writer, h, plan)
    payload = writer.finish()
    return _pack_header(h, len(payload)) + payload + struct.pack(">I", zlib.crc32(payload))


def decode(data: bytes, *, file: str | None = None) -> FapStream:
    """Decode a ``.fbs`` bitstream. ``file`` names it in errors.

    Raises :class:`CodingError` with the byte offset for anything that is not a complete, intact
    bitstream; never returns a stream that differs from what the encoder reconstructed.
    """
    if not isinstance(data, bytes | bytearray | memoryview):
        raise CodingError(f"expected bytes, got {type(data).__name__}", file=file)
    cur = _Cursor(bytes(data), file)
    if _parse_header(cur).stream:
        import io

        dec = StreamDecoder(io.BytesIO(bytes(data)), file=file)
        rows = list(dec.rows())
        return _assemble_rows(dec.header, rows, dec.header.first_frame, file)
    h = read_header(data, file=file)
    payload = bytes(data[h.header_size : h.header_size + h.payload_size])
    reader: _HuffmanReader | _RangeReader
    if h.coder == "huffman":
        reader = _HuffmanReader(payload, h.header_size, h.huffman_tables, h.huffman_table_of, file)
    else:
        reader = _RangeReader(payload, h.header_size, file)
    mask, index, viseme, expression, t_index = _syntax(reader, h, None)
    reader.finish()
    steps = _steps(h.base_steps, h.quantizer)
    t_steps = _steps(h.translation_base_steps, h.quantizer)
    try:
        return _assemble(
            h.fps,
            h.name,
            h.first_frame,
            h.faps,
            h.low,
            steps,
            mask,
            index,
            viseme,
            expression,
            t_steps if h.translation else None,
            t_index if h.translation else None,
        )
    except FapError as e:  # pragma: no cover - the syntax checks every field's range
        raise CodingError(
            f"decoded frames are invalid: {e}", offset=h.header_size, file=file
        ) from None


# --- streamed bitstreams ------------------------------------------------------------------------

#: The most bytes of one packet's frame data (a frame of all 68 FAPs takes well under 1,000).
MAX_PACKET_BYTES = 1 << 16
_END_MARKER = struct.Struct(">II")  # frame count, CRC-32


def _crc8_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        c = byte
        for _ in range(8):
            c = ((c << 1) ^ 0x07) & 0xFF if c & 0x80 else (c << 1) & 0xFF
        table.append(c)
    return tuple(table)


_CRC8 = _crc8_table()


def _crc8(data: bytes) -> int:
    """A packet's CRC: CRC-8 with the polynomial x^8 + x^2 + x + 1 (0x07, CRC-8/SMBUS), which
    detects every error burst of up to 8 bits (every damaged byte) in a packet; the end
    marker's CRC-32 covers the whole stream with the strength of a whole file's."""
    c = 0
    for b in data:
        c = _CRC8[c ^ b]
    return c


class _Packets:
    """The packets of a streamed bitstream after its header (in ``cur``, from ``cur.pos``; read
    from ``cur.source`` as they arrive when it has one), each checked against its CRC-8.

    Iterating yields ``(i, data, at)``: frame i's range-coded bytes and the offset of the first.
    It ends after the end marker, whose frame count and CRC-32 are checked, and after making sure
    nothing follows it; then :attr:`count` is the number of frames and :attr:`end` the offset of
    the final CRC-32. A stream that ends anywhere else is an error at the byte where it ends.
    """

    def __init__(self, cur: _Cursor, h: FbsHeader) -> None:
        self.buf = cur.data[cur.pos :]
        self.at = cur.pos  # offset of buf[0]
        self.source = cur.source
        self.file = cur.file
        self.h = h
        self.count = 0
        self.end = -1
        self.crc = 0

    def error(self, message: str, offset: int) -> CodingError:
        return CodingError(message, offset=offset, file=self.file)

    def _take(self, n: int, what: str) -> bytes:
        if len(self.buf) < n and self.source is not None:
            self.buf += _read_up_to(self.source, n - len(self.buf))
        if len(self.buf) < n:
            end = self.at + len(self.buf)
            raise self.error(
                f"unexpected end of the stream inside {what} ({n} bytes from byte {self.at}): "
                "the stream is truncated",
                end,
            )
        chunk, self.buf = self.buf[:n], self.buf[n:]
        self.at += n
        self.crc = zlib.crc32(chunk, self.crc)
        return chunk

    def _varint(self, what: str) -> tuple[int, bytes]:
        raw = b""
        while True:
            byte = self._take(1, what)
            raw += byte
            if not byte[0] & 0x80:
                break
            if len(raw) >= 3:
                raise self.error(f"{what} is not a varint of at most 3 bytes", self.at - 3)
        return sum((b & 0x7F) << (7 * i) for i, b in enumerate(raw)), raw

    def __iter__(self) -> Iterator[tuple[int, bytes, int]]:
        h = self.h
        while True:
            i = self.count
            start = self.at
            length, raw = self._varint(f"the length of packet {i}")
            if length == 0:
                break
            n = length - 1
            if n > MAX_PACKET_BYTES:
                raise self.error(
                    f"packet {i} announces {n} bytes, more than a frame takes (at most "
                    f"{MAX_PACKET_BYTES}): the stream is damaged or not a vtts stream",
                    start,
                )
            if i >= MAX_FRAMES or (i + 1) / h.fps > MAX_DURATION_S:
                raise self.error(
                    f"the stream goes on past {i} frames at {h.fps:g} Hz, beyond the limits of "
                    f"{MAX_FRAMES} frames and {MAX_DURATION_S:g} s",
                    start,
                )
            data = self._take(n, f"packet {i}")
            crc_at = self.at
            stored = self._take(1, f"the CRC of packet {i}")[0]
            computed = _crc8(raw + data)
            if stored != computed:
                raise self.error(
                    f"packet {i} CRC-8 mismatch (stored 0x{stored:02x}, computed "
                    f"0x{computed:02x}): bytes {start}–{crc_at - 1} are corrupt",
                    crc_at,
                )
            yield i, data, start + len(raw)
            self.count += 1
        marker_at = self.at - 1
        (count,) = struct.unpack(">I", self._take(4, "the end marker's frame count"))
        self.end = self.at
        computed = self.crc
        (stored,) = struct.unpack(">I", self._take(4, "the end marker's CRC"))
        if stored != computed:
            raise self.error(
                f"stream CRC-32 mismatch (stored 0x{stored:08x}, computed 0x{computed:08x}): "
                f"bytes {h.header_size}–{self.end - 1} are corrupt",
                self.end,
            )
        if count != self.count:
            raise self.error(
                f"the end marker counts {count} frames, the stream sent {self.count}", marker_at
            )
        if self.source is not None and not self.buf:
            self.buf = _read_up_to(self.source, 1)
        if self.buf:
            extra = "" if self.source is not None else f"{len(self.buf)} "
            raise self.error(f"{extra}unexpected bytes after the end marker of the stream", self.at)


def paired_predictors(
    faps: Iterable[int | str] | str, steps: Mapping[int | str, int] | None = None
) -> dict[int, int]:
    """Predictor pairs fixed in advance, for a stream that cannot choose them from its frames:
    each outer-lip FAP (``NAME_o``, 51–60) from its inner-lip FAP (4–13), else each right-side
    FAP from its left-side twin (``…_l`` / ``…_r``, ``lm`` / ``rm``), where both are in
    ``faps``, the predicting one earlier, with the same unit and base step (``steps``' where it
    gives one, as :func:`encode` takes them)."""
    own = _check_steps(steps)
    coded = set(fap_set(faps)) if isinstance(faps, str) or list(faps) else set()
    by_name = {d.name: d.number for d in FAPS}
    swap = {"l": "r", "r": "l", "lm": "rm", "rm": "lm"}
    out: dict[int, int] = {}
    for k in sorted(coded):
        if k < 3:
            continue
        d = FAPS[k - 1]
        inner = by_name.get(d.name[:-2]) if d.name.endswith("_o") else None
        mirror = by_name.get("_".join(swap.get(t, t) for t in d.name.split("_")))
        for p in (inner, mirror):
            if p is None or p not in coded or not 3 <= p < k:
                continue
            q = FAPS[p - 1]
            if q.fapu == d.fapu and own.get(p, q.quant_step) == own.get(k, d.quant_step):
                out[k] = p
                break
    return out


class StreamEncoder:
    """Codes a FAP stream frame by frame as a streamed ``.fbs`` bitstream (header flag bit 2).

    A whole ``.fbs`` needs the whole stream first (its frame count, payload length and CRC,
    Huffman tables and predictor pairs are chosen from all frames); a streamed one does not:
    :meth:`header` gives the header, :meth:`frames` the packets of frames as they come (one
    packet per frame, which a decoder can decode as soon as it arrives), :meth:`end` the end
    marker. The arithmetic coder's adaptive contexts carry on from packet to packet; each packet
    ends the range coder with the fewest bytes that decode it and starts it anew. The bytes
    ``header() + frames(s) + end()`` decode (:func:`decode`, :class:`StreamDecoder`) to
    :func:`reconstruct` of ``s`` with the same FAPs and quantizer.

    Args:
        fps: the frame rate, Hz.
        faps: the FAPs sent (see :func:`fap_set`); a frame sets some or all of them.
        translation: send the head translation (every frame must then carry one).
        quantizer: as :func:`encode`'s.
        name: the stream's name.
        first_frame: the number of the first frame.
        constant_mask: every frame sets every FAP of ``faps`` (no mask is sent per frame).
        predictors: FAP → the earlier FAP (same unit and base step) whose error in the same
            frame predicts its error, fixed in advance; default none.
        steps: base steps of their own, as :func:`encode`'s.
    """

    def __init__(
        self,
        *,
        fps: float,
        faps: Iterable[int | str] | str,
        translation: bool = False,
        quantizer: float = 1.0,
        name: str = "stream",
        first_frame: int = 0,
        constant_mask: bool = False,
        predictors: dict[int, int] | None = None,
        steps: Mapping[int | str, int] | None = None,
    ) -> None:
        fps = float(fps)
        if not (math.isfinite(fps) and MIN_FPS <= fps <= MAX_FPS):
            raise FapError(f"frame rate must be within {MIN_FPS:g}–{MAX_FPS:g} Hz, got {fps!r}")
        coded = fap_set(faps) if isinstance(faps, str) or list(faps) else ()  # () for none
        low = tuple(k for k in coded if k >= 3)
        q32 = _check_quantizer(quantizer)
        own = _check_steps(steps)
        if not 0 <= first_frame < 1 << 32:
            raise CodingError(f"first frame number {first_frame} must be within 0–2^32")
        if len(name.encode("utf-8")) > MAX_NAME_BYTES:
            raise CodingError(f"the stream's name has more than {MAX_NAME_BYTES} bytes")
        FapStream(fps=fps, name=name, values=np.zeros((0, N_FAPS)), mask=np.zeros((0, N_FAPS)))
        predictors = dict(predictors or {})
        for k, p in predictors.items():
            if k not in low or p not in low or p >= k:
                raise FapError(
                    f"predictor {k} ← {p}: both must be sent low-level FAPs, the predicting one "
                    "earlier"
                )
        self.header_info = FbsHeader(
            coder="arithmetic",
            fps=fps,
            first_frame=int(first_frame),
            n_frames=0,
            faps=coded,
            quantizer=q32,
            base_steps=tuple(own.get(k, FAPS[k - 1].quant_step) for k in low),
            constant_mask=bool(constant_mask),
            name=name,
            predictors=predictors,
            translation_base_steps=tuple(
                own.get(a, TRANSLATION_BASE_STEP) for a in TRANSLATION_AXES
            )
            if translation
            else (),
            stream=True,
        )
        self._syntax = _FrameSyntax(self.header_info)
        self._steps = _steps(self.header_info.base_steps, q32)
        self._t_steps = _steps(self.header_info.translation_base_steps, q32)
        self._writer = _RangeWriter()
        self._crc = 0
        self._state = "new"
        self.n_frames = 0

    def header(self) -> bytes:
        """The header: call first, once."""
        if self._state != "new":
            raise FapError("the stream's header was already made")
        self._state = "open"
        data = _pack_header(self.header_info, 0)
        self.header_info = replace(self.header_info, header_size=len(data))
        return data

    def frames(self, stream: FapStream) -> bytes:
        """The packets of the frames of ``stream`` (usually one frame), which must have the
        encoder's frame rate, set only FAPs it sends, every one of them in each frame with
        ``constant_mask``, and carry a head translation when it sends one."""
        h = self.header_info
        if self._state != "open":
            raise FapError("frames go between the header and the end")
        if not isinstance(stream, FapStream):
            raise FapError(f"expected a FapStream, got {type(stream).__name__}")
        if abs(stream.fps - h.fps) > 1e-9 * h.fps:
            raise FapError(f"the frames are at {stream.fps:g} Hz, the stream at {h.fps:g} Hz")
        extra = sorted(set(np.flatnonzero(stream.mask.any(axis=0)) + 1) - set(h.faps))
        if extra:
            raise FapError(f"the frames set FAPs {extra} that the stream does not send")
        if h.constant_mask and not stream.mask[:, [k - 1 for k in h.faps]].all():
            raise FapError("every frame of a stream with a constant mask sets all its FAPs")
        if h.translation and stream.translation is None:
            raise FapError("the stream sends the head translation: the frames must carry one")
        if self.n_frames + stream.n_frames > MAX_FRAMES:
            raise CodingError(f"a stream has at most {MAX_FRAMES} frames")
        if stream.n_frames == 0:
            return b""
        mask = stream.mask[:, [k - 1 for k in h.faps]]
        index = _quantize(stream, h.low, self._steps)
        t_index = None
        if h.translation:
            t_index = _quantize_translation(stream.translation, self._t_steps)  # type: ignore[arg-type]
        out = bytearray()
        for i in range(stream.n_frames):
            row = (
                mask[i].tolist(),
                index[i].tolist(),
                [0] * 4 if stream.viseme is None else stream.viseme[i].tolist(),
                [0] * 6 if stream.expression is None else stream.expression[i].tolist(),
                () if t_index is None else t_index[i].tolist(),
            )
            self._syntax.frame(self._writer, self.n_frames, row)
            data = self._writer.packet()
            raw = _varint(len(data) + 1)
            packet = raw + data + bytes([_crc8(raw + data)])
            self._crc = zlib.crc32(packet, self._crc)
            out += packet
            self.n_frames += 1
        return bytes(out)

    def end(self) -> bytes:
        """The end marker: the frame count and the CRC-32 of everything after the header."""
        if self._state != "open":
            raise FapError("the end goes after the header, once")
        self._state = "ended"
        marker = b"\0" + struct.pack(">I", self.n_frames)
        return marker + struct.pack(">I", zlib.crc32(marker, self._crc))


class StreamDecoder:
    """Decodes a ``.fbs`` bitstream from a binary file object as it arrives (a pipe).

    Creating it reads and checks the header (:attr:`header`); iterating yields each frame as
    a one-frame :class:`FapStream` (``first_frame`` its number) as soon as its packet has
    arrived and passed its CRC-8, then checks the end marker. A whole (not streamed) ``.fbs``
    is read completely (at most :data:`~vtts.limits.MAX_FBS_BYTES`), decoded, and its frames
    yielded one by one. Every problem is a :class:`CodingError` at the byte concerned; frames
    already yielded stay valid (a stream damaged later is reported when that part arrives).
    """

    def __init__(self, source: BinaryIO, *, file: str | None = None) -> None:
        self.file = file
        self._cur = _Cursor(b"", file, source)
        self.header = _parse_header(self._cur)
        self._whole: FapStream | None = None
        if not self.header.stream:
            from vtts.limits import MAX_FBS_BYTES

            rest = _read_up_to(source, MAX_FBS_BYTES + 1 - len(self._cur.data))
            data = self._cur.data + rest
            if len(data) > MAX_FBS_BYTES:
                raise CodingError(
                    f"the bitstream is larger than the limit of {MAX_FBS_BYTES} bytes",
                    offset=MAX_FBS_BYTES,
                    file=file,
                )
            self._whole = decode(data, file=file)

    def rows(self) -> Iterator[tuple]:
        """The frames as :meth:`_FrameSyntax.frame` returns them (streams only)."""
        h = self.header
        syntax = _FrameSyntax(h)
        reader: _RangeReader | None = None
        for i, data, at in _Packets(self._cur, h):
            if reader is None:
                reader = _RangeReader(data, at, self.file, pad=True)
            else:
                reader.start(data, at)
            row = syntax.frame(reader, i, None)
            if len(data) > reader.pos:
                raise reader.error(
                    f"{len(data) - reader.pos} unused bytes at the end of packet {i}"
                )
            yield row

    def __iter__(self) -> Iterator[FapStream]:
        if self._whole is not None:
            s = self._whole
            for i in range(s.n_frames):
                yield _frame_of(s, i)
            return
        h = self.header
        for i, row in enumerate(self.rows()):
            yield _assemble_rows(h, [row], h.first_frame + i, self.file)


def _frame_of(s: FapStream, i: int) -> FapStream:
    """Frame ``i`` of ``s`` as a one-frame stream."""
    return FapStream(
        fps=s.fps,
        name=s.name,
        values=s.values[i : i + 1],
        mask=s.mask[i : i + 1],
        viseme=None if s.viseme is None else s.viseme[i : i + 1],
        expression=None if s.expression is None else s.expression[i : i + 1],
        first_frame=s.first_frame + i,
        translation=None if s.translation is None else s.translation[i : i + 1],
    )


def _assemble_rows(h: FbsHeader, rows: list[tuple], first_frame: int, file: str | None):
    """The decoded stream of ``rows`` (:meth:`_FrameSyntax.frame`'s) under header ``h``."""
    n = len(rows)
    mask = np.array([r[0] for r in rows], dtype=bool).reshape(n, len(h.faps))
    index = np.array([r[1] for r in rows], dtype=np.int64).reshape(n, len(h.low))
    viseme = np.array([r[2] for r in rows], dtype=np.int64).reshape(n, 4)
    expression = np.array([r[3] for r in rows], dtype=np.int64).reshape(n, 6)
    nt = len(h.translation_base_steps)
    t_index = np.array([r[4] for r in rows], dtype=np.int64).reshape(n, nt)
    try:
        return _assemble(
            h.fps,
            h.name,
            first_frame,
            h.faps,
            h.low,
            _steps(h.base_steps, h.quantizer),
            mask,
            index,
            viseme,
            expression,
            _steps(h.translation_base_steps, h.quantizer) if h.translation else None,
            t_index if h.translation else None,
        )
    except FapError as e:  # pragma: no cover - the syntax checks every field's range
        raise CodingError(
            f"decoded frames are invalid: {e}", offset=h.header_size, file=file
        ) from None
