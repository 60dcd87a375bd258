"""Streamed bitstreams: a frame a packet, decodable as soon as it arrives.

A whole ``.fbs`` needs the whole stream first; a streamed one (header flag bit 2, the arithmetic
coder) sends the header, then each frame as a packet — its length, its range-coded bytes and a
CRC-8 — and an end marker with the frame count and a CRC-32 of everything after the header, so
that truncation is still detected. :class:`StreamEncoder` writes one, :class:`Packets` reads
and checks the packets (:class:`~vtts.fap.coding.file.StreamDecoder` decodes them as they
arrive). A stream cannot choose its predictor pairs from its frames: :func:`paired_predictors`
fixes them in advance.
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import replace

import numpy as np

from vtts.errors import CodingError, FapError
from vtts.fap.coding.frame import FrameSyntax
from vtts.fap.coding.header import Cursor, FbsHeader, pack_header, read_up_to, varint
from vtts.fap.coding.quantizer import (
    MAX_FRAMES,
    MAX_NAME_BYTES,
    TRANSLATION_BASE_STEP,
    check_quantizer,
    check_steps,
    fap_set,
    grid_steps,
    quantize,
    quantize_translation,
)
from vtts.fap.coding.range_coder import RangeWriter
from vtts.fap.stream import TRANSLATION_AXES, FapStream
from vtts.fap.table import FAPS, N_FAPS
from vtts.limits import MAX_DURATION_S, MAX_FPS, MIN_FPS

#: The most bytes of one packet's frame data: far more than a frame of all 68 FAPs takes (see
#: ``docs/fap-coding.md``), so that only a damaged or foreign stream reaches it, and a decoder never
#: waits for or holds more.
MAX_PACKET_BYTES = 1 << 16


def _crc8_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        c = byte
        for _ in range(8):
            c = ((c << 1) ^ 0x07) & 0xFF if c & 0x80 else (c << 1) & 0xFF
        table.append(c)
    return tuple(table)


_CRC8 = _crc8_table()


def crc8(data: bytes) -> int:
    """A packet's CRC: CRC-8 with the polynomial x^8 + x^2 + x + 1 (0x07, CRC-8/SMBUS), which
    detects every error burst of up to 8 bits (every damaged byte) in a packet; the end
    marker's CRC-32 covers the whole stream with the strength of a whole file's."""
    c = 0
    for b in data:
        c = _CRC8[c ^ b]
    return c


class Packets:
    """The packets of a streamed bitstream after its header (in ``cur``, from ``cur.pos``; read
    from ``cur.source`` as they arrive when it has one), each checked against its CRC-8.

    Iterating yields ``(i, data, at)``: frame i's range-coded bytes and the offset of the first.
    It ends after the end marker, whose frame count and CRC-32 are checked, and after making sure
    nothing follows it; then :attr:`count` is the number of frames and :attr:`end` the offset of
    the final CRC-32. A stream that ends anywhere else is an error at the byte where it ends.
    """

    def __init__(self, cur: Cursor, h: FbsHeader) -> None:
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
            self.buf += read_up_to(self.source, n - len(self.buf))
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
            computed = crc8(raw + data)
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
            self.buf = read_up_to(self.source, 1)
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
    gives one, as :func:`~vtts.fap.coding.encode` takes them)."""
    own = check_steps(steps)
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
    ``header() + frames(s) + end()`` decode (:func:`~vtts.fap.coding.decode`,
    :class:`~vtts.fap.coding.StreamDecoder`) to :func:`~vtts.fap.coding.reconstruct` of ``s``
    with the same FAPs and quantizer.

    Args:
        fps: the frame rate, Hz.
        faps: the FAPs sent (see :func:`~vtts.fap.coding.fap_set`); a frame sets some or all
            of them.
        translation: send the head translation (every frame must then carry one).
        quantizer: as :func:`~vtts.fap.coding.encode`'s.
        name: the stream's name.
        first_frame: the number of the first frame.
        constant_mask: every frame sets every FAP of ``faps`` (no mask is sent per frame).
        predictors: FAP → the earlier FAP (same unit and base step) whose error in the same
            frame predicts its error, fixed in advance; default none.
        steps: base steps of their own, as :func:`~vtts.fap.coding.encode`'s.
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
        q32 = check_quantizer(quantizer)
        own = check_steps(steps)
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
        self._syntax = FrameSyntax(self.header_info)
        self._steps = grid_steps(self.header_info.base_steps, q32)
        self._t_steps = grid_steps(self.header_info.translation_base_steps, q32)
        self._writer = RangeWriter()
        self._crc = 0
        self._state = "new"
        self.n_frames = 0

    def header(self) -> bytes:
        """The header: call first, once."""
        if self._state != "new":
            raise FapError("the stream's header was already made")
        self._state = "open"
        data = pack_header(self.header_info, 0)
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
        index = quantize(stream, h.low, self._steps)
        t_index = None
        if h.translation:
            t_index = quantize_translation(stream.translation, self._t_steps)  # type: ignore[arg-type]
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
            raw = varint(len(data) + 1)
            packet = raw + data + bytes([crc8(raw + data)])
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


def frame_of(s: FapStream, i: int) -> FapStream:
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
