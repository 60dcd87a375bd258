"""Fuzzing the ``.fbs`` decoder beyond its CRCs (issue 21).

``test_coding.py`` throws random bytes and byte flips at the decoder, which its two CRCs catch
first. Here the header fields and the frame data of real coded streams are mutated and both CRCs
recomputed, so that every later check is reached: whatever the bytes, the only exception is
CodingError with a byte offset in the data; a stream that decodes writes as a ``.fap`` file and
reads back unchanged, and codes again.
"""

from __future__ import annotations

import struct
import warnings
import zlib
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vtts.errors import CodingError, FapError
from vtts.fap import FapStream, format_fap, parse_fap
from vtts.fap.coding import decode, encode, read_header

from ..fuzzing import examples
from ..hostile import byte_mutations, mutate_bytes

DATA = Path(__file__).resolve().parent.parent / "data" / "fap"


def _short(path: Path, frames: int = 8) -> FapStream:
    lines = path.read_text().split("\n")
    head = lines[0].split()
    head[3] = str(frames)
    body = [ln for ln in lines[1:] if ln.strip() and not ln.startswith("#")][: 2 * frames]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return parse_fap("\n".join([" ".join(head), *body]) + "\n")


STREAMS = [_short(DATA / "xface-joy.fap"), _short(DATA / "xface-hate.fap", 5)]
CODED = [
    encode(s, coder=coder, quantizer=q, faps=faps)
    for s in STREAMS
    for coder, q, faps in [("huffman", 1.0, None), ("arithmetic", 4.0, None),
                           ("huffman", 2.0, "paper17"), ("arithmetic", 1.0, "3-13")]
]  # fmt: skip

FUZZ = settings(
    max_examples=examples(200), deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


def split(data: bytes) -> tuple[bytes, bytes]:
    """(header fields, frame data) of a valid bitstream: without the payload length and CRCs."""
    h = read_header(data)
    return data[: h.header_size - 8], data[h.header_size : -4]


def framed(fields: bytes, payload: bytes) -> bytes:
    """A bitstream of ``fields`` and ``payload`` whose length and CRCs are right."""
    header = fields + struct.pack(">I", len(payload))
    header += struct.pack(">I", zlib.crc32(header))
    return header + payload + struct.pack(">I", zlib.crc32(payload))


def decode_or_coding_error(data: bytes) -> FapStream | None:
    try:
        stream = decode(data, file="fuzz.fbs")
    except CodingError as e:
        assert e.file == "fuzz.fbs" and e.offset is not None and 0 <= e.offset <= len(data)
        assert e.message.startswith(f"byte {e.offset}: ")
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert parse_fap(format_fap(stream)) == stream
    try:
        encode(stream, coder="huffman")
    except FapError as e:  # a value too large for the quantizer: a clear error too
        assert e.message
    return stream


def test_the_coded_streams_decode() -> None:
    for data in CODED:
        assert decode_or_coding_error(data) is not None
        assert framed(*split(data)) == data


@FUZZ
@given(st.sampled_from(CODED), byte_mutations)
def test_mutated_header_fields(data: bytes, ops: list[tuple[int, str, int]]) -> None:
    fields, payload = split(data)
    # the magic stays, so that the damage reaches the fields behind it
    decode_or_coding_error(framed(mutate_bytes(fields, ops, start=4), payload))


@FUZZ
@given(st.sampled_from(CODED), byte_mutations)
def test_mutated_frame_data(data: bytes, ops: list[tuple[int, str, int]]) -> None:
    fields, payload = split(data)
    decode_or_coding_error(framed(fields, mutate_bytes(payload, ops)))


@FUZZ
@given(st.sampled_from(CODED), byte_mutations, byte_mutations)
def test_mutated_fields_and_data(
    data: bytes, ops: list[tuple[int, str, int]], more: list[tuple[int, str, int]]
) -> None:
    fields, payload = split(data)
    decode_or_coding_error(framed(mutate_bytes(fields, ops, start=4), mutate_bytes(payload, more)))


@FUZZ
@given(st.sampled_from(CODED), st.binary(max_size=64))
def test_random_fields_behind_the_fixed_header(data: bytes, tail: bytes) -> None:
    """The variable fields (steps, name, Huffman tables, predictors) replaced by random bytes."""
    fields, payload = split(data)
    decode_or_coding_error(framed(fields[:36] + tail, payload))
