"""FAP stream coding: the ``.fbs`` bitstream (Eisert & Girod's FAP coder).

The scheme of the paper ("Camera sequences"): every FAP is predicted from the previous *decoded*
frame, the prediction error is quantized with a per-FAP step, and the quantized error is entropy
coded — Huffman, as in the paper, or adaptive binary arithmetic coding. The paper's six
head-motion parameters include a translation, which MPEG-4 has no FAP for: when a stream carries
one (:attr:`FapStream.translation`, ES units) it is coded like three more low-level FAPs (a
header flag says so; a stream without it codes to the bytes it always did). High-level FAPs 1
(viseme) and 2 (expression) are lossless. The byte-by-byte layout is in ``docs/fap-coding.md``.

One module per concept, each importing only those listed before it:

- :mod:`~vtts.fap.coding.quantizer`: FAP selection, the quantizer's grid and closed-loop DPCM
  (:func:`reconstruct`, :func:`source_stream`, :func:`error_stats`);
- :mod:`~vtts.fap.coding.elements`: the syntax elements' interface each coder implements;
- :mod:`~vtts.fap.coding.huffman`: the paper's Huffman mode;
- :mod:`~vtts.fap.coding.range_coder`: the adaptive binary range coder and its contexts;
- :mod:`~vtts.fap.coding.header`: :class:`FbsHeader`, written and parsed;
- :mod:`~vtts.fap.coding.frame`: the frame syntax, shared by encoder and decoder;
- :mod:`~vtts.fap.coding.packets`: streamed bitstreams' packets (:class:`StreamEncoder`);
- :mod:`~vtts.fap.coding.file`: :func:`encode`, :func:`decode`, :func:`read_header` and
  :class:`StreamDecoder`, which take whole and streamed bitstreams alike.

Every problem in a bitstream is a :class:`~vtts.errors.CodingError` carrying the byte offset where
it was found. Two CRC-32s (header, frame data) make sure corruption is reported, never decoded
into a silently different stream; truncation is reported at the byte where the data ends.
"""

from __future__ import annotations

from vtts.fap.coding.file import StreamDecoder, decode, encode, read_header
from vtts.fap.coding.header import CODERS, MAGIC, VERSION, FbsHeader
from vtts.fap.coding.huffman import ESCAPE, MAX_CODE_LENGTH, SYMBOL_MAX, huffman_lengths
from vtts.fap.coding.packets import MAX_PACKET_BYTES, StreamEncoder, frame_of, paired_predictors
from vtts.fap.coding.quantizer import (
    FAP_SETS,
    MAX_BASE_STEP,
    MAX_FRAMES,
    MAX_INDEX,
    MAX_NAME_BYTES,
    PAPER_17,
    QUANTIZER_RANGE,
    TRANSLATION_BASE_STEP,
    error_stats,
    fap_set,
    reconstruct,
    source_stream,
)

__all__ = [
    "CODERS",
    "ESCAPE",
    "FAP_SETS",
    "MAGIC",
    "MAX_BASE_STEP",
    "MAX_CODE_LENGTH",
    "MAX_FRAMES",
    "MAX_INDEX",
    "MAX_NAME_BYTES",
    "MAX_PACKET_BYTES",
    "PAPER_17",
    "QUANTIZER_RANGE",
    "SYMBOL_MAX",
    "TRANSLATION_BASE_STEP",
    "VERSION",
    "FbsHeader",
    "StreamDecoder",
    "StreamEncoder",
    "decode",
    "encode",
    "error_stats",
    "fap_set",
    "frame_of",
    "huffman_lengths",
    "paired_predictors",
    "read_header",
    "reconstruct",
    "source_stream",
]
