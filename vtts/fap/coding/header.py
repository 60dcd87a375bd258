"""The ``.fbs`` header: what it says (:class:`FbsHeader`), written and parsed byte by byte.

A fixed part (magic, version, coder, flags, frame rate, first frame, frame count, the mask of the
coded FAPs, the quantizer), then the base steps, the stream's name, the coder's tables (Huffman
code lengths, or the arithmetic mode's predictor pairs), the length of the frame data and a
CRC-32 of the header. The byte-by-byte layout is in ``docs/fap-coding.md``. A decoder checks every
field before it trusts it (:func:`parse_header`), and the framing of a whole bitstream after it
(:func:`check_whole`; a streamed one's packets are :mod:`~vtts.fap.coding.packets`').
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import BinaryIO

import numpy as np

from vtts.errors import CodingError, FapError
from vtts.fap.coding.huffman import ESCAPE, MAX_CODE_LENGTH, SYMBOL_MAX, pack_table, unzigzag
from vtts.fap.coding.quantizer import (
    MAX_BASE_STEP,
    MAX_FRAMES,
    MAX_NAME_BYTES,
    QUANTIZER_RANGE,
    grid_steps,
)
from vtts.fap.stream import TRANSLATION_AXES, FapStream
from vtts.fap.table import N_FAPS
from vtts.limits import MAX_DURATION_S, MAX_FPS, MIN_FPS

MAGIC = b"VFBS"
VERSION = 1
#: Coder names and their ids in the header.
CODERS: dict[str, int] = {"huffman": 0, "arithmetic": 1}
_CODER_NAMES = {v: k for k, v in CODERS.items()}

_FIXED = struct.Struct(">4sBBBdII9sf")  # magic … quantizer: 36 bytes
_FLAG_CONSTANT_MASK = 0x01
_FLAG_TRANSLATION = 0x02
_FLAG_STREAM = 0x04
_FLAGS = _FLAG_CONSTANT_MASK | _FLAG_TRANSLATION | _FLAG_STREAM


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
            units; :data:`~vtts.fap.coding.quantizer.TRANSLATION_BASE_STEP`), or ``()`` when
            the stream carries none.
        predictors: arithmetic mode: FAP → the earlier FAP whose error in the same frame
            predicts its error.
        header_size, payload_size: bytes of the header (with its CRC) and of the frame data
            (without its CRC); the file has ``header_size + payload_size + 4`` bytes. For a
            stream (``stream``), the frame data are the packets and the end marker before its
            CRC, and both are known only once the whole stream was read (0 before).
        stream: a streamed bitstream (header flag bit 2): the frames follow as packets, each
            decodable as soon as it arrives, and an end marker
            (:class:`~vtts.fap.coding.packets.StreamEncoder`); ``n_frames`` is then the count of
            the end marker (0 when only the header was read).
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
        out.update(zip(self.low, grid_steps(self.base_steps, self.quantizer).tolist(), strict=True))
        t = grid_steps(self.translation_base_steps, self.quantizer).tolist()
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


def varint(value: int) -> bytes:
    """``value`` (≥ 0) as an unsigned LEB128 varint: 7 bits a byte, low first, high bit = more."""
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


def pack_header(h: FbsHeader, payload_size: int) -> bytes:
    """The bytes of header ``h`` announcing ``payload_size`` bytes of frame data, its CRC-32
    last; ``h``'s own ``header_size``, ``payload_size`` and (for a stream) ``n_frames`` are
    not used."""
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
        out += varint(b)
    name = h.name.encode("utf-8")
    out += varint(len(name)) + name
    if h.coder == "huffman":
        out.append(len(h.huffman_tables))
        if len(h.huffman_tables) > 1:
            bits = 0
            for t in h.huffman_table_of:
                bits = (bits << 2) | t
            nbytes = (2 * len(h.huffman_table_of) + 7) // 8
            out += (bits << (8 * nbytes - 2 * len(h.huffman_table_of))).to_bytes(nbytes, "big")
        for table in h.huffman_tables:
            out += pack_table(table)
    else:
        out.append(len(h.predictors))
        for k in sorted(h.predictors):
            out += bytes([k, h.predictors[k]])
    out += struct.pack(">I", payload_size)
    out += struct.pack(">I", zlib.crc32(out))
    return bytes(out)


class Cursor:
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
            self.data += read_up_to(self.source, self.pos + n - len(self.data))
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


def read_up_to(source: BinaryIO, n: int) -> bytes:
    """Up to ``n`` bytes of ``source``: fewer only at its end (a pipe's reads may be short)."""
    out = b""
    while len(out) < n:
        chunk = source.read(n - len(out))
        if not chunk:
            break
        out += chunk
    return out


def parse_header(cur: Cursor) -> FbsHeader:
    """The header at the start of ``cur``, checked up to its CRC and its fields' values."""
    if cur.source is not None:
        cur.data += read_up_to(cur.source, 4)
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
            lengths = {ESCAPE: nibbles[0]} | {unzigzag(z): x for z, x in enumerate(nibbles[1:])}
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


def check_whole(cur: Cursor, h: FbsHeader) -> FbsHeader:
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
