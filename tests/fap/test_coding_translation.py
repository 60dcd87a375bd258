""".fbs with the head translation: exact decoding, the error bound, the header, version-1 files
made before translation could be sent, damaged input, and the commands."""

from __future__ import annotations

import argparse
import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vtts.api.coding import check_fbs, read_stream
from vtts.cli.coding import add_parser as register
from vtts.errors import CodingError, FapError
from vtts.fap import FapStream, FapWarning, read_fap, write_fap
from vtts.fap.coding import (
    PAPER_17,
    TRANSLATION_BASE_STEP,
    decode,
    encode,
    error_stats,
    read_header,
    reconstruct,
    source_stream,
)
from vtts.fap.coding.header import pack_header, varint
from vtts.fap.stream import MAX_TRANSLATION

V1 = Path(__file__).resolve().parent.parent / "data" / "fap" / "fbs-v1"
CODERS = ("huffman", "arithmetic")


def walk(n: int, seed: int = 0, sigma: float = 30.0) -> np.ndarray:
    """``(n, 3)``: a smooth random walk of the head, ES units, starting off-centre."""
    rng = np.random.default_rng(seed)
    velocity = np.cumsum(rng.normal(0, sigma / 4, size=(n, 3)), axis=0)
    return np.array([120.0, -40.0, 15.0]) + np.cumsum(velocity, axis=0)


def paper17(n: int = 40, seed: int = 0, fps: float = 25.0, translation: bool = True) -> FapStream:
    """The paper's 17 FAPs as random walks (FAP 19 missing in a few frames) with a head walk."""
    rng = np.random.default_rng(seed)
    values = np.zeros((n, 68))
    mask = np.zeros((n, 68), dtype=bool)
    for k in PAPER_17:
        values[:, k - 1] = np.cumsum(rng.normal(0, 40, n))
        mask[:, k - 1] = True
    mask[3:6, 18] = False
    return FapStream(
        fps=fps,
        name="walk",
        values=values * mask,
        mask=mask,
        translation=walk(n, seed) if translation else None,
    )


def check_bound(reference: FapStream, decoded: FapStream, steps: dict) -> None:
    stats = error_stats(reference, decoded)
    carried = decoded.translation is not None and decoded.n_frames > 0
    assert all(a in stats for a in ("tx", "ty", "tz")) == carried
    for k, (worst, _) in stats.items():
        assert worst <= steps[k] / 2 * (1 + 1e-9), (k, worst, steps[k])


# --- round trips --------------------------------------------------------------------------------


@pytest.mark.parametrize("coder", CODERS)
@pytest.mark.parametrize("quantizer", [1.0, 0.25, 3.3, 4.0])
def test_round_trip_is_the_reconstruction_within_half_a_step(coder: str, quantizer: float) -> None:
    s = paper17()
    data = encode(s, coder=coder, quantizer=quantizer)
    d = decode(data)
    assert d == reconstruct(s, quantizer=quantizer)
    assert d.translation is not None and d.translation.shape == (40, 3)
    h = read_header(data)
    assert h.translation and h.translation_base_steps == (TRANSLATION_BASE_STEP,) * 3
    step = TRANSLATION_BASE_STEP * np.float32(quantizer)
    assert {a: h.steps[a] for a in ("tx", "ty", "tz")} == dict.fromkeys(("tx", "ty", "tz"), step)
    check_bound(s, d, h.steps)
    assert np.array_equal(d.translation / step, np.round(d.translation / step))  # on the grid


@pytest.mark.parametrize("coder", CODERS)
def test_rate_and_fap_selection_keep_the_translation(coder: str) -> None:
    s = paper17(50)
    data = encode(s, coder=coder, rate=12.5, faps="3,48-50")
    d = decode(data)
    assert d == reconstruct(s, rate=12.5, faps="3,48-50") and d.fps == 12.5
    ref = source_stream(s, rate=12.5, faps="3,48-50")
    assert np.array_equal(ref.translation, s.resample(12.5).translation)
    check_bound(ref, d, read_header(data).steps)
    assert read_header(data).faps == (3, 48, 49, 50)


@pytest.mark.parametrize("coder", CODERS)
def test_translation_alone_and_big_jumps(coder: str) -> None:
    t = np.array([[0.0, 0, 0], [1e5, -1e5, 3], [-1e5, 7e5, -3], [2, 2, 2], [MAX_TRANSLATION] * 3])
    s = FapStream(fps=30, name="t", values=np.zeros((5, 68)), mask=np.zeros((5, 68)), translation=t)
    data = encode(s, coder=coder)
    d = decode(data)
    assert d == reconstruct(s) and read_header(data).faps == ()
    check_bound(s, d, read_header(data).steps)


@pytest.mark.parametrize("coder", CODERS)
def test_empty_stream_with_translation(coder: str) -> None:
    s = FapStream(
        fps=30,
        name="e",
        values=np.zeros((0, 68)),
        mask=np.zeros((0, 68)),
        translation=np.zeros((0, 3)),
    )
    d = decode(encode(s, coder=coder))
    assert d == reconstruct(s) and d.translation.shape == (0, 3)
    assert error_stats(s, d) == {}


@pytest.mark.parametrize("coder", CODERS)
def test_translation_false_leaves_it_out(coder: str) -> None:
    s = paper17()
    without = encode(s, coder=coder, translation=False)
    assert without == encode(dataclasses.replace(s, translation=None), coder=coder)
    d = decode(without)
    assert d.translation is None and d == reconstruct(s, translation=False)
    assert not read_header(without).translation and "tx" not in read_header(without).steps
    assert source_stream(s, translation=False).translation is None
    assert len(encode(s, coder=coder)) > len(without)  # the translation costs bits


FAPS = st.lists(st.sampled_from([3, 4, 19, 48, 50, 60]), max_size=4, unique=True)
AXIS = st.one_of(
    st.floats(-1e4, 1e4, allow_nan=False),
    st.integers(-300, 300).map(float),
    st.sampled_from([0.0, 2.0, -2.0, 1e6, -1e6, 5e-324]),
)


@st.composite
def streams(draw) -> FapStream:
    n = draw(st.integers(0, 20))
    values = np.zeros((n, 68))
    mask = np.zeros((n, 68), dtype=bool)
    for k in draw(FAPS):
        values[:, k - 1] = draw(st.lists(st.floats(-1e5, 1e5), min_size=n, max_size=n))
        mask[:, k - 1] = draw(st.lists(st.booleans(), min_size=n, max_size=n))
    t = np.array(draw(st.lists(st.tuples(AXIS, AXIS, AXIS), min_size=n, max_size=n)))
    return FapStream(
        fps=draw(st.sampled_from([25.0, 12.5, 30.0])),
        name="p",
        values=values * mask,
        mask=mask,
        translation=t.reshape(n, 3),
    )


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(streams(), st.sampled_from(CODERS), st.sampled_from([1.0, 0.25, 4.0, 64.0]))
def test_decoder_reproduces_the_encoders_reconstruction(
    s: FapStream, coder: str, quantizer: float
) -> None:
    try:
        data = encode(s, coder=coder, quantizer=quantizer)
    except CodingError as e:  # only a value within half a step of the bound can be refused
        assert "would leave ±1e+06 ES units" in e.message
        assert np.abs(s.translation).max() > MAX_TRANSLATION - 32 * quantizer
        return
    d = decode(data)
    assert d == reconstruct(s, quantizer=quantizer)
    check_bound(s, d, read_header(data).steps)


def test_reconstruction_beyond_the_bound_is_refused() -> None:
    t = np.array([[MAX_TRANSLATION, 0.0, 0.0]])
    s = FapStream(
        fps=25, name="far", values=np.zeros((1, 68)), mask=np.zeros((1, 68)), translation=t
    )
    with pytest.raises(CodingError, match=r"head translation tx = 1000000.0 in frame 0") as e:
        encode(s, quantizer=3.3)  # the grid point nearest 1e6 is 1000005.6
    assert e.value.offset is None
    assert decode(encode(s, quantizer=4.0)) == reconstruct(s, quantizer=4.0)


def test_error_stats_needs_a_reference_translation() -> None:
    s = paper17(5)
    d = decode(encode(s))
    with pytest.raises(FapError, match="carries a head translation, the reference none"):
        error_stats(dataclasses.replace(s, translation=None), d)
    stats = error_stats(s, d)
    assert set(stats) == {*PAPER_17, "tx", "ty", "tz"}


# --- the header and version-1 bitstreams --------------------------------------------------------


@pytest.mark.parametrize("coder", CODERS)
def test_header_layout(coder: str) -> None:
    s = paper17(8)
    data = encode(s, coder=coder, quantizer=2.0)
    h = read_header(data)
    assert data[4] == 1  # still version 1: the flag tells
    assert data[6] == 0x02  # translation, and the mask is not constant (FAP 19)
    # the base steps, varints: the 17 FAPs', then tx's, ty's, tz's; then the name
    steps = b"".join(varint(b) for b in h.base_steps) + b"\x04\x04\x04"
    end = 36 + len(steps)
    assert data[36:end] == steps and data[end : end + 5] == b"\x04walk"
    if coder == "huffman":
        assert len(h.huffman_table_of) == 17 + 3
    constant = encode(dataclasses.replace(s, mask=s.mask | np.isin(np.arange(68), [18])))
    assert constant[6] == 0x03


@pytest.mark.parametrize("coder", CODERS)
def test_version_1_files_still_decode(coder: str) -> None:
    data = (V1 / f"{coder}.fbs").read_bytes()
    h = read_header(data)
    assert h.version == 1 and not h.translation and h.translation_base_steps == ()
    assert "tx" not in h.steps
    d = decode(data)
    assert d == read_fap(V1 / "decoded.fap") and d.translation is None
    assert d.n_frames == 12 and d.fps == 12.5 and d.first_frame == 1
    # without translation, today's encoder writes the same bytes
    assert encode(read_fap(V1 / "source.fap"), quantizer=2.0, rate=12.5, coder=coder) == data


# --- damaged input ------------------------------------------------------------------------------


def tiny(coder: str) -> bytes:
    return encode(paper17(5), coder=coder, quantizer=3.0, faps="3,19,48")


@pytest.mark.parametrize("coder", CODERS)
def test_every_truncation_is_reported_where_the_data_ends(coder: str) -> None:
    data = tiny(coder)
    for n in range(len(data)):
        with pytest.raises(CodingError) as e:
            decode(data[:n], file="t.fbs")
        assert e.value.offset == n, (n, e.value.message)


@pytest.mark.parametrize("coder", CODERS)
def test_every_byte_flip_is_detected(coder: str) -> None:
    data = tiny(coder)
    h = read_header(data)
    for i in range(len(data)):
        for flip in (0x01, 0x02, 0x80, 0xFF):
            bad = bytearray(data)
            bad[i] ^= flip
            with pytest.raises(CodingError) as e:
                decode(bytes(bad))
            off = e.value.offset
            assert off is not None and 0 <= off <= len(data)
            if i >= h.header_size:
                assert off == len(data) - 4 and "CRC" in e.value.message


def crafted(data: bytes, **changes) -> bytes:
    """``data`` with header fields changed and both CRCs right."""
    h = read_header(data)
    return pack_header(dataclasses.replace(h, **changes), h.payload_size) + data[h.header_size :]


@pytest.mark.parametrize("coder", CODERS)
def test_crafted_translation_headers(coder: str) -> None:
    data = tiny(coder)
    h = read_header(data)
    with pytest.raises(CodingError, match="base step must be ≥ 1") as e:
        decode(crafted(data, translation_base_steps=(4, 0, 4)))
    assert e.value.offset == 36 + 4 + 1  # FAPs 3, 19, 48 (2 bytes), tx, then ty
    with pytest.raises(CodingError, match=r"base step of the head translation's ty must be at"):
        decode(crafted(data, translation_base_steps=(4, 2**21, 4)))
    # the flag cleared (or a translation announced where none was coded): the frames disagree
    plain = encode(paper17(5, translation=False), coder=coder, quantizer=3.0, faps="3,19,48")
    for bad in (
        crafted(data, translation_base_steps=()),
        crafted(plain, translation_base_steps=(4, 4, 4)),
    ):
        with pytest.raises(CodingError) as e:
            decode(bad)
        assert e.value.offset >= read_header(bad).header_size
    with pytest.raises(CodingError, match="unknown flags 0x0a") as e:
        bad = bytearray(data)
        bad[6] |= 0x08  # bit 2 marks a streamed bitstream
        decode(bytes(bad))
    assert e.value.offset == 6
    if coder == "huffman":
        tables = (h.huffman_tables[0],) * 2
        with pytest.raises(CodingError, match="head translation tz uses Huffman table 3 of 2"):
            decode(crafted(data, huffman_tables=tables, huffman_table_of=(0, 0, 0, 0, 0, 3)))


@pytest.mark.parametrize("coder", CODERS)
def test_a_translation_beyond_the_bound_is_refused_at_its_byte(coder: str) -> None:
    """A bitstream that passes its CRCs but decodes to a translation beyond ±1e6 ES units: its
    steps scaled up by a crafted header make the decoded value too large."""
    t = np.array([[0.0, 0, 0], [9e5, 0, 0]])
    s = FapStream(fps=25, name="t", values=np.zeros((2, 68)), mask=np.zeros((2, 68)), translation=t)
    data = encode(s, coder=coder)
    h = read_header(data)
    with pytest.raises(CodingError, match=r"translation's tx leaves ±1e\+06 ES units in frame 1"):
        decode(crafted(data, translation_base_steps=(8, 4, 4)))
    assert h.translation


# --- commands ------------------------------------------------------------------------------------


def run(*argv: str) -> int:
    p = argparse.ArgumentParser(prog="vtts")
    register(p.add_subparsers(dest="command"))
    args = p.parse_args(list(argv))
    return args.func(args)


def test_check_says_it_carries_the_translation(tmp_path: Path) -> None:
    a, b = tmp_path / "a.fbs", tmp_path / "b.fbs"
    a.write_bytes(encode(paper17(25), coder="huffman"))
    b.write_bytes(encode(paper17(25), translation=False))
    h = read_header(a.read_bytes())
    assert check_fbs(a) == (
        f"25 frames at 25 Hz, 17 FAPs and the head translation, huffman, "
        f"{h.bits_per_frame:.1f} bits/frame, {h.kbit_per_s:.3f} kbit/s"
    )
    assert h.bits_per_frame == 8 * a.stat().st_size / 25  # the translation's bits counted
    assert "translation" not in check_fbs(b) and "17 FAPs, arithmetic" in check_fbs(b)


def test_info_names_the_base_steps_of_its_own(tmp_path: Path) -> None:
    """``vtts info`` of a .fbs lists the base steps that are not MPEG-4's (vtts analyze's steps
    measured on the face), and nothing of the kind for the standard's."""
    from vtts.api.coding import describe_fbs

    a, b = tmp_path / "a.fbs", tmp_path / "b.fbs"
    a.write_bytes(encode(paper17(25), steps={12: 40, 3: 4, "tz": 9}))
    b.write_bytes(encode(paper17(25)))
    lines = describe_fbs(a)
    assert "base steps of its own (MPEG-4's for the rest): 12 40, tz 9" in lines, lines
    assert not any("base steps" in line for line in describe_fbs(b))


def test_cli_encode_keeps_or_drops_and_decode_warns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src, again, dropped, fap = (tmp_path / x for x in ("s.fbs", "a.fbs", "d.fbs", "o.fap"))
    s = paper17(20)
    src.write_bytes(encode(s, quantizer=2.0))
    assert run("encode", str(src), "-o", str(again), "--quantizer", "2") == 0
    said = capsys.readouterr().out
    assert "17 FAPs and the head translation" in said and "max error" in said
    assert decode(again.read_bytes()) == decode(src.read_bytes())  # the grid is kept
    assert run("encode", str(src), "-o", str(dropped), "--no-translation", "--quiet") == 0
    assert read_stream(dropped).translation is None
    with pytest.warns(FapWarning, match="head translation is not written") as w:
        assert run("decode", str(src), "-o", str(fap), "--quiet") == 0
    assert w[0].message.file == str(fap)
    assert read_fap(fap) == dataclasses.replace(decode(src.read_bytes()), translation=None)


def test_cli_max_error_names_the_translation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # FAP values on their grid (no error), the translation off it: the worst is the translation
    s = paper17(10)
    s = dataclasses.replace(s, values=np.round(s.values / 170) * 170 * 4)
    src, out = tmp_path / "s.fbs", tmp_path / "o.fbs"
    src.write_bytes(encode(s, quantizer=0.25))
    assert run("encode", str(src), "-o", str(out)) == 0
    said = capsys.readouterr().out
    assert "ES units on the head translation's t" in said


def test_encode_of_a_fap_file_is_unchanged(tmp_path: Path) -> None:
    fap, fbs = tmp_path / "s.fap", tmp_path / "s.fbs"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_fap(paper17(10, translation=False), fap)
        assert run("encode", str(fap), "-o", str(fbs), "--quiet") == 0
    assert not read_header(fbs.read_bytes()).translation
    assert fbs.read_bytes() == encode(read_fap(fap))


def test_steps_are_stored_not_looked_up(monkeypatch: pytest.MonkeyPatch) -> None:
    from vtts.fap import coding

    data = encode(paper17(4), quantizer=1.0)
    expect = reconstruct(paper17(4), quantizer=1.0)
    for module in (coding, *vars(coding).values()):  # wherever the package has the base step
        if getattr(module, "TRANSLATION_BASE_STEP", None) == TRANSLATION_BASE_STEP:
            monkeypatch.setattr(module, "TRANSLATION_BASE_STEP", 99)
    assert decode(data) == expect
    assert read_header(data).steps["tx"] == 4.0
