"""Coding a whole ``.fbs``, and reading any ``.fbs`` — whole or streamed — from bytes or a pipe.

:func:`encode` chooses what a whole bitstream's header fixes from all frames (the constant mask,
the Huffman tables in a first pass, or the arithmetic mode's predictor pairs), then codes the
frames. :func:`read_header`, :func:`decode` and :class:`StreamDecoder` take either form: a whole
bitstream's frame data are checked against its length and CRC-32 before they are decoded, a
streamed one's packets (:mod:`~vtts.fap.coding.packets`) each against its CRC-8 as it arrives.
"""

from __future__ import annotations

import io
import struct
import zlib
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import replace
from typing import BinaryIO

import numpy as np

from vtts.errors import CodingError, FapError
from vtts.fap.coding.frame import FrameSyntax, code_frames
from vtts.fap.coding.header import (
    CODERS,
    Cursor,
    FbsHeader,
    check_whole,
    pack_header,
    parse_header,
    read_up_to,
)
from vtts.fap.coding.huffman import ErrorCounter, HuffmanReader, HuffmanWriter, choose_tables
from vtts.fap.coding.packets import Packets, frame_of
from vtts.fap.coding.quantizer import assemble, grid_steps, prepare
from vtts.fap.coding.range_coder import RangeReader, RangeWriter, choose_predictors
from vtts.fap.stream import FapStream
from vtts.limits import MAX_FBS_BYTES


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
        faps: the FAPs to send (numbers, names, ``"paper17"``…; see
            :func:`~vtts.fap.coding.fap_set`); default all. FAPs no frame of the stream sets
            are not sent.
        rate: code at this frame rate, Hz (the stream is resampled, see
            :meth:`FapStream.resample`); default the stream's own.
        quantizer: the global factor of the quantizer steps (1 = the MPEG-4 steps of
            ``faps.tsv``); the reconstruction error of every value is at most half a step.
        coder: ``"huffman"`` (the paper's) or ``"arithmetic"`` (adaptive, fewer bits).
        translation: send the stream's head translation (:attr:`FapStream.translation`, in ES
            units, on the grid of :data:`~vtts.fap.coding.TRANSLATION_BASE_STEP` ·
            ``quantizer``) when it has one; ``False`` leaves it out. A stream without
            translation codes to the same bytes as before translation could be sent.
        steps: base steps of their own for some FAPs (numbers 3–68; FAP units) and translation
            axes (``"tx"``, ``"ty"``, ``"tz"``; ES units), whole numbers within 1–
            :data:`~vtts.fap.coding.MAX_BASE_STEP`, instead of faps.tsv's ``quant_step`` and
            :data:`~vtts.fap.coding.TRANSLATION_BASE_STEP` (e.g.
            :func:`vtts.analysis.coding_steps`, which makes one step of each move the face's
            image alike). The header carries every base step, so any decoder reads the stream
            as it reads any other.

    Returns the bitstream; ``decode`` of it equals :func:`~vtts.fap.coding.reconstruct` with the
    same arguments.
    """
    if coder not in CODERS:
        raise FapError(f"unknown coder {coder!r}: expected one of {', '.join(CODERS)}")
    plan = prepare(stream, faps, rate, quantizer, translation, steps)
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
        counter = ErrorCounter(len(plan.low) + len(plan.translation_steps))
        code_frames(counter, h, plan)
        tables, table_of = choose_tables(counter.errors)
        h = replace(h, huffman_tables=tables, huffman_table_of=table_of)
        writer: HuffmanWriter | RangeWriter = HuffmanWriter(tables, table_of)
    else:
        h = replace(h, predictors=choose_predictors(plan))
        writer = RangeWriter()
    code_frames(writer, h, plan)
    payload = writer.finish()
    return pack_header(h, len(payload)) + payload + struct.pack(">I", zlib.crc32(payload))


def decode(data: bytes, *, file: str | None = None) -> FapStream:
    """Decode a ``.fbs`` bitstream. ``file`` names it in errors.

    Raises :class:`CodingError` with the byte offset for anything that is not a complete, intact
    bitstream; never returns a stream that differs from what the encoder reconstructed.
    """
    if not isinstance(data, bytes | bytearray | memoryview):
        raise CodingError(f"expected bytes, got {type(data).__name__}", file=file)
    cur = Cursor(bytes(data), file)
    if parse_header(cur).stream:
        dec = StreamDecoder(io.BytesIO(bytes(data)), file=file)
        rows = list(dec.rows())
        return _assemble_rows(dec.header, rows, dec.header.first_frame, file)
    h = read_header(data, file=file)
    payload = bytes(data[h.header_size : h.header_size + h.payload_size])
    reader: HuffmanReader | RangeReader
    if h.coder == "huffman":
        reader = HuffmanReader(payload, h.header_size, h.huffman_tables, h.huffman_table_of, file)
    else:
        reader = RangeReader(payload, h.header_size, file)
    mask, index, viseme, expression, t_index = code_frames(reader, h, None)
    reader.finish()
    steps = grid_steps(h.base_steps, h.quantizer)
    t_steps = grid_steps(h.translation_base_steps, h.quantizer)
    try:
        return assemble(
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
    cur = Cursor(data, file)
    h = parse_header(cur)
    if h.stream:
        packets = Packets(cur, h)
        for _ in packets:
            pass
        return replace(h, n_frames=packets.count, payload_size=packets.end - h.header_size)
    return check_whole(cur, h)


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
        self._cur = Cursor(b"", file, source)
        self.header = parse_header(self._cur)
        self._whole: FapStream | None = None
        if not self.header.stream:
            rest = read_up_to(source, MAX_FBS_BYTES + 1 - len(self._cur.data))
            data = self._cur.data + rest
            if len(data) > MAX_FBS_BYTES:
                raise CodingError(
                    f"the bitstream is larger than the limit of {MAX_FBS_BYTES} bytes",
                    offset=MAX_FBS_BYTES,
                    file=file,
                )
            self._whole = decode(data, file=file)

    def rows(self) -> Iterator[tuple]:
        """The frames as :meth:`~vtts.fap.coding.frame.FrameSyntax.frame` returns them
        (streams only)."""
        h = self.header
        syntax = FrameSyntax(h)
        reader: RangeReader | None = None
        for i, data, at in Packets(self._cur, h):
            if reader is None:
                reader = RangeReader(data, at, self.file, pad=True)
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
                yield frame_of(s, i)
            return
        h = self.header
        for i, row in enumerate(self.rows()):
            yield _assemble_rows(h, [row], h.first_frame + i, self.file)


def _assemble_rows(
    h: FbsHeader, rows: list[tuple], first_frame: int, file: str | None
) -> FapStream:
    """The decoded stream of ``rows`` (:meth:`~vtts.fap.coding.frame.FrameSyntax.frame`'s)
    under header ``h``."""
    n = len(rows)
    mask = np.array([r[0] for r in rows], dtype=bool).reshape(n, len(h.faps))
    index = np.array([r[1] for r in rows], dtype=np.int64).reshape(n, len(h.low))
    viseme = np.array([r[2] for r in rows], dtype=np.int64).reshape(n, 4)
    expression = np.array([r[3] for r in rows], dtype=np.int64).reshape(n, 6)
    nt = len(h.translation_base_steps)
    t_index = np.array([r[4] for r in rows], dtype=np.int64).reshape(n, nt)
    try:
        return assemble(
            h.fps,
            h.name,
            first_frame,
            h.faps,
            h.low,
            grid_steps(h.base_steps, h.quantizer),
            mask,
            index,
            viseme,
            expression,
            grid_steps(h.translation_base_steps, h.quantizer) if h.translation else None,
            t_index if h.translation else None,
        )
    except FapError as e:  # pragma: no cover - the syntax checks every field's range
        raise CodingError(
            f"decoded frames are invalid: {e}", offset=h.header_size, file=file
        ) from None
