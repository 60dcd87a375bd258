"""Streamed .fbs bitstreams: frame-by-frame coding, decoding as packets arrive, damage."""

from __future__ import annotations

import io
import os
import struct
import threading
from pathlib import Path

import numpy as np
import pytest

from vtts.api.coding import check_fbs, read_stream
from vtts.errors import CodingError, FapError
from vtts.fap import FapStream, read_fap
from vtts.fap.coding import (
    PAPER_17,
    StreamDecoder,
    StreamEncoder,
    decode,
    encode,
    frame_of,
    paired_predictors,
    read_header,
    reconstruct,
)

from ..in_process import vtts

DATA = Path(__file__).resolve().parent.parent / "data" / "fap"


def small(n: int = 6) -> FapStream:
    """The paper's FAPs with a mask change, both high-level FAPs and a head translation."""
    rng = np.random.default_rng(3)
    values = np.zeros((n, 68))
    mask = np.zeros((n, 68), dtype=bool)
    for k in PAPER_17:
        values[:, k - 1] = np.round(rng.normal(0, 300, size=n))
        mask[:, k - 1] = True
    mask[min(2, n - 1), 18] = False  # FAP 19 missing in frame 2
    mask[:, 0] = mask[:, 1] = True
    viseme = np.tile([3, 10, 40, 0], (n, 1))
    viseme[min(3, n - 1)] = [1, 0, 63, 0]
    expression = np.tile([1, 30, 0, 0, 0, 0], (n, 1))
    return FapStream(
        fps=25.0,
        name="small",
        values=values * mask,
        mask=mask,
        viseme=viseme,
        expression=expression,
        translation=np.cumsum(rng.normal(0, 20, size=(n, 3)), axis=0),
    )


def streamed(s: FapStream, **kw) -> tuple[bytes, list[bytes]]:
    """``s`` coded frame by frame: the whole bytes and the header, packets and end apart."""
    faps = sorted(set(np.flatnonzero(s.mask.any(axis=0)) + 1))
    enc = StreamEncoder(
        fps=s.fps, faps=faps, name=s.name, translation=s.translation is not None, **kw
    )
    parts = [enc.header(), *(enc.frames(frame_of(s, i)) for i in range(s.n_frames)), enc.end()]
    return b"".join(parts), parts


def same(a: FapStream, b: FapStream) -> None:
    assert a.n_frames == b.n_frames and a.fps == b.fps and a.name == b.name
    assert np.array_equal(a.mask, b.mask) and np.array_equal(a.values, b.values)
    for x, y in (
        (a.viseme, b.viseme),
        (a.expression, b.expression),
        (a.translation, b.translation),
    ):
        assert (x is None) == (y is None) and (x is None or np.array_equal(x, y))


@pytest.mark.parametrize("quantizer", [1.0, 4.0])
def test_streamed_decodes_to_the_reconstruction(quantizer):
    s = small()
    data, _ = streamed(s, quantizer=quantizer, predictors=paired_predictors(PAPER_17))
    same(decode(data), reconstruct(s, quantizer=quantizer))
    h = read_header(data)
    assert h.stream and h.n_frames == s.n_frames and h.size == len(data)
    frames = list(StreamDecoder(io.BytesIO(data)))
    assert [f.first_frame for f in frames] == list(range(s.n_frames))
    whole = reconstruct(s, quantizer=quantizer)
    for i, f in enumerate(frames):
        same(f, frame_of(whole, i))


@pytest.mark.parametrize("path", sorted(DATA.glob("*.fap"))[:3], ids=lambda p: p.name)
def test_real_files_stream_exactly(path):
    s = read_fap(path)
    faps = sorted(set(np.flatnonzero(s.mask.any(axis=0)) + 1))
    data, _ = streamed(s, predictors=paired_predictors(faps))
    same(decode(data), reconstruct(s))


def test_files_made_before_streams_are_whole_bitstreams():
    for coder in ("huffman", "arithmetic"):
        kept = (DATA / "fbs-v1" / f"{coder}.fbs").read_bytes()
        assert not read_header(kept).stream
        assert decode(kept).n_frames == read_fap(DATA / "fbs-v1" / "decoded.fap").n_frames


def test_each_frame_is_decoded_as_soon_as_its_packet_arrives():
    """A pipe whose writer waits after each packet: the decoder yields the frame before the
    next packet is written (no read-ahead past a packet)."""
    s = small(4)
    _, parts = streamed(s)
    r, w = os.pipe()
    got: list[int] = []
    sent = threading.Event()
    received = threading.Semaphore(0)

    def write():
        with os.fdopen(w, "wb", buffering=0) as f:
            f.write(parts[0])
            for p in parts[1:-1]:
                f.write(p)
                received.acquire(timeout=10)  # the reader has the frame before the next packet
            sent.set()
            f.write(parts[-1])

    t = threading.Thread(target=write)
    t.start()
    with os.fdopen(r, "rb") as f:
        for frame in StreamDecoder(f):
            got.append(frame.first_frame)
            assert not sent.is_set()
            received.release()
    t.join()
    assert got == list(range(4))


def test_a_whole_bitstream_reads_through_the_stream_decoder():
    s = small()
    data = encode(s)
    frames = list(StreamDecoder(io.BytesIO(data)))
    whole = decode(data)
    assert len(frames) == s.n_frames
    for i, f in enumerate(frames):
        same(f, frame_of(whole, i))


def test_every_truncation_and_byte_change_is_an_error():
    data, _ = streamed(small(3))
    for n in range(len(data)):
        with pytest.raises(CodingError):
            decode(data[:n])
        with pytest.raises(CodingError):
            list(StreamDecoder(io.BytesIO(data[:n])))
    for i in range(len(data)):
        bad = bytearray(data)
        bad[i] ^= 0x5A
        with pytest.raises(CodingError):
            decode(bytes(bad))
    with pytest.raises(CodingError, match="after the end marker"):
        decode(data + b"\0")


def test_truncation_is_reported_where_the_stream_ends():
    data, parts = streamed(small(3))
    cut = len(parts[0]) + len(parts[1]) + 2
    with pytest.raises(CodingError, match=f"byte {cut}: unexpected end of the stream inside"):
        list(StreamDecoder(io.BytesIO(data[:cut])))
    # the frames before the cut came out first
    got = []
    with pytest.raises(CodingError):
        for f in StreamDecoder(io.BytesIO(data[: len(data) - 3])):
            got.append(f)
    assert len(got) == 3


def test_garbage_and_empty_input():
    with pytest.raises(CodingError, match="byte 0: not a vtts FAP bitstream"):
        StreamDecoder(io.BytesIO(b"\x00\x00\x00\x00garbage" * 10))
    with pytest.raises(CodingError, match="truncated"):
        StreamDecoder(io.BytesIO(b""))


def test_header_rules():
    data, _ = streamed(small(2))
    bad = bytearray(data)
    bad[5] = 0  # Huffman coder with the stream flag
    with pytest.raises(CodingError, match="byte 5: .*arithmetic coder"):
        decode(bytes(bad))
    bad = bytearray(data)
    bad[19:23] = struct.pack(">I", 2)
    with pytest.raises(CodingError, match="byte 19: .*counts no frames"):
        decode(bytes(bad))


def test_encoder_refuses_what_it_cannot_send():
    enc = StreamEncoder(fps=25, faps=[3, 4], constant_mask=True)
    with pytest.raises(FapError, match="between the header"):
        enc.frames(small(1))
    enc.header()
    with pytest.raises(FapError, match="do.? not send|does not send"):
        enc.frames(small(1))
    one = FapStream(25.0, "x", np.zeros((1, 68)), np.zeros((1, 68), bool))
    one.mask[0, 2] = True
    with pytest.raises(FapError, match="constant mask"):
        enc.frames(one)
    with pytest.raises(FapError, match="Hz"):
        enc.frames(FapStream(30.0, "x", one.values, one.mask))
    with pytest.raises(FapError, match="predictor"):
        StreamEncoder(fps=25, faps=[3, 4], predictors={3: 4})


def test_saved_stream_checks_and_plays_from_a_file(tmp_path):
    data, _ = streamed(small())
    path = tmp_path / "s.fbs"
    path.write_bytes(data)
    assert check_fbs(path).startswith("6 frames at 25 Hz")
    same(read_stream(path), decode(data))


def test_packet_crc_is_crc8_smbus():
    from vtts.fap.coding.packets import crc8

    assert crc8(b"123456789") == 0xF4  # the catalogue's check value of CRC-8/SMBUS


def test_a_stream_of_the_head_translation_alone():
    n = 4
    t = np.cumsum(np.ones((n, 3)) * 7.0, axis=0)
    s = FapStream(25.0, "t", np.zeros((n, 68)), np.zeros((n, 68), bool), translation=t)
    enc = StreamEncoder(
        fps=25, faps=[], translation=True, name="t", predictors=paired_predictors([])
    )
    data = enc.header() + enc.frames(s) + enc.end()
    same(decode(data), reconstruct(s))


def test_vtts_info_and_decode_of_a_saved_stream(tmp_path):

    data, _ = streamed(small())
    path = tmp_path / "s.fbs"
    path.write_bytes(data)
    r = vtts("info", str(path))
    assert r.returncode == 0 and "streamed (packets and an end marker)" in r.stdout, r.stderr
    assert "6 frames at 25 Hz" in r.stdout
    out = tmp_path / "s.fap"
    r = vtts("decode", str(path), "-o", str(out))
    assert r.returncode == 0 and read_fap(out).n_frames == 6, r.stderr
