"""FAP stream coding (.fbs): exact decoding, error bounds, the header, and damaged input."""

from __future__ import annotations

import argparse
import dataclasses
import functools
import math
import struct
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vtts.api.coding import check_fbs, read_stream
from vtts.cli.coding import add_parser as register
from vtts.errors import CodingError, FapError, VttsError
from vtts.fap import FAPS, FapStream, FapWarning, read_fap, write_fap
from vtts.fap.coding import (
    ESCAPE,
    MAGIC,
    MAX_CODE_LENGTH,
    MAX_INDEX,
    PAPER_17,
    decode,
    encode,
    error_stats,
    fap_set,
    huffman_lengths,
    read_header,
    reconstruct,
    source_stream,
)
from vtts.fap.coding.header import pack_header

DATA = Path(__file__).resolve().parent.parent / "data" / "fap"
REAL = sorted(DATA.glob("*.fap"))
CODERS = ("huffman", "arithmetic")


def stream(values: np.ndarray, faps: list[int], **kw) -> FapStream:
    """A stream setting ``faps`` (columns of ``values``, one per FAP) in every frame."""
    n = values.shape[0]
    full = np.zeros((n, 68))
    mask = np.zeros((n, 68), dtype=bool)
    for c, k in enumerate(faps):
        full[:, k - 1] = values[:, c]
        mask[:, k - 1] = True
    return FapStream(
        fps=kw.pop("fps", 25.0), name=kw.pop("name", "t"), values=full, mask=mask, **kw
    )


def small(n: int = 6) -> FapStream:
    """A short stream with the paper's FAPs, a mask change and both high-level FAPs."""
    rng = np.random.default_rng(3)
    s = stream(np.round(rng.normal(0, 300, size=(n, 17))), list(PAPER_17), name="small")
    mask = s.mask.copy()
    mask[2, 18] = False  # FAP 19 missing in frame 2
    mask[:, 0] = mask[:, 1] = True
    viseme = np.tile([3, 10, 40, 0], (n, 1))
    viseme[3] = [1, 0, 63, 0]
    expression = np.tile([1, 30, 0, 0, 0, 0], (n, 1))
    return FapStream(
        fps=25.0,
        name="small",
        values=s.values * mask,
        mask=mask,
        viseme=viseme,
        expression=expression,
    )


def check_bound(original: FapStream, decoded: FapStream, steps: dict[int, float]) -> None:
    for k, (worst, _) in error_stats(original, decoded).items():
        assert worst <= steps[k] / 2 * (1 + 1e-9), (k, worst, steps[k])


# --- round trips --------------------------------------------------------------------------------


@pytest.mark.parametrize("coder", CODERS)
@pytest.mark.parametrize("path", REAL, ids=lambda p: p.stem)
def test_real_files_round_trip(path: Path, coder: str) -> None:
    s = read_fap(path)
    for quantizer in (1.0, 3.7):
        data = encode(s, quantizer=quantizer, coder=coder)
        decoded = decode(data)
        assert decoded == reconstruct(s, quantizer=quantizer)
        h = read_header(data)
        assert h.size == len(data) and h.coder == coder
        assert np.array_equal(decoded.mask, s.mask)
        check_bound(s, decoded, h.steps)
    # the real files are integers and most steps are 1 there: those FAPs come back exactly
    exact = [k for k in range(3, 69) if s.mask[:, k - 1].any() and FAPS[k - 1].quant_step == 1]
    d = decode(encode(s, coder=coder))
    assert np.array_equal(d.values[:, [k - 1 for k in exact]], s.values[:, [k - 1 for k in exact]])


def test_arithmetic_beats_huffman_on_real_files() -> None:
    for path in REAL:
        s = read_fap(path)
        assert len(encode(s, coder="arithmetic")) < 0.85 * len(encode(s, coder="huffman"))


@pytest.mark.parametrize("coder", CODERS)
def test_high_level_faps_and_mask_changes_are_lossless(coder: str) -> None:
    s = small(12)
    d = decode(encode(s, coder=coder))
    assert np.array_equal(d.viseme, s.viseme) and np.array_equal(d.expression, s.expression)
    assert np.array_equal(d.mask, s.mask)
    assert d.name == "small" and d.fps == 25.0


@pytest.mark.parametrize("coder", CODERS)
def test_big_jumps_escape_without_clamping(coder: str) -> None:
    v = np.array([[0.0, 0], [1e9, -3], [-1e9, 70], [5.0, -70], [5, 64], [5, -64], [5, 63]])
    s = stream(v, [49, 3])
    data = encode(s, coder=coder)
    d = decode(data)
    assert d == reconstruct(s)
    check_bound(s, d, read_header(data).steps)


def test_prediction_holds_over_frames_without_the_fap() -> None:
    # FAP 3 is sent in frames 0 and 3 only: frame 3 is predicted from frame 0's decoded value
    s = stream(np.array([[400.0], [0], [0], [404]]), [3])
    mask = s.mask.copy()
    mask[1:3, 2] = False
    s = FapStream(fps=25, name="h", values=s.values * mask, mask=mask)
    for coder in CODERS:
        assert decode(encode(s, coder=coder)) == reconstruct(s)


def test_empty_and_fapless_streams() -> None:
    empty = FapStream(fps=30, name="e", values=np.zeros((0, 68)), mask=np.zeros((0, 68)))
    nothing = FapStream(fps=30, name="n", values=np.zeros((5, 68)), mask=np.zeros((5, 68)))
    for s in (empty, nothing):
        for coder in CODERS:
            d = decode(encode(s, coder=coder))
            assert d == reconstruct(s) and d.n_frames == s.n_frames and not d.mask.any()


def test_value_too_large_for_the_quantizer() -> None:
    s = stream(np.array([[0.0], [4.0 * MAX_INDEX]]), [3])
    with pytest.raises(CodingError, match="too large to code") as e:
        encode(s)
    assert e.value.offset is None


# --- the property: the decoder reproduces the encoder's reconstruction --------------------------

FAP_NUMBERS = st.lists(st.integers(1, 68), min_size=0, max_size=8, unique=True)
VALUE = st.one_of(
    st.integers(-300, 300).map(float),
    st.floats(-1e5, 1e5, allow_nan=False),
    st.sampled_from([0.0, 1e9, -1e9, 0.5, -0.5, 2.0, 1e-300]),
)

ANY_FPS = st.sampled_from([25.0, 30.0, 12.5, 29.97, 0.01, 1000.0])


def high_level(draw: st.DrawFn, fields: tuple, n: int) -> np.ndarray:
    """``(n, len(fields)) int64``: a high-level FAP's parameters in each frame (drawn only for
    a FAP the stream sets: the stream stores 0 where it does not)."""
    rows = [draw(st.tuples(*(st.integers(lo, hi) for _, lo, hi in fields))) for _ in range(n)]
    return np.array(rows, dtype=np.int64).reshape(n, len(fields))


@st.composite
def streams(draw, fps: st.SearchStrategy[float] = ANY_FPS) -> FapStream:
    n = draw(st.integers(0, 25))
    faps = draw(FAP_NUMBERS)
    values = np.zeros((n, 68))
    mask = np.zeros((n, 68), dtype=bool)
    varying = draw(st.booleans())
    for k in faps:
        if k >= 3:
            values[:, k - 1] = draw(st.lists(VALUE, min_size=n, max_size=n))
        if varying:
            mask[:, k - 1] = draw(st.lists(st.booleans(), min_size=n, max_size=n))
        else:
            mask[:, k - 1] = True
    viseme = high_level(draw, VIS, n) if 1 in faps else None
    expression = high_level(draw, EXP, n) if 2 in faps else None
    return FapStream(
        fps=draw(fps),
        name=draw(st.sampled_from(["s", "speaker 1", "C:\\tmp\\x", "é"])),
        values=values * mask,
        mask=mask,
        viseme=viseme,
        expression=expression,
        first_frame=draw(st.integers(0, 5)),
    )


from vtts.fap.stream import EXPRESSION_FIELDS as EXP  # noqa: E402
from vtts.fap.stream import VISEME_FIELDS as VIS  # noqa: E402

PROPERTY = settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@PROPERTY
@given(
    streams(),
    st.sampled_from(CODERS),
    st.sampled_from([1.0, 0.25, 3.3, 64.0]),
    st.one_of(st.none(), FAP_NUMBERS.filter(bool)),
)
def test_decoder_reproduces_the_encoders_reconstruction(
    s: FapStream, coder: str, quantizer: float, faps: list[int] | None
) -> None:
    data = encode(s, coder=coder, quantizer=quantizer, faps=faps)
    decoded = decode(data)
    assert decoded == reconstruct(s, quantizer=quantizer, faps=faps)
    h = read_header(data)
    assert h.size == len(data) and h.n_frames == s.n_frames
    check_bound(source_stream(s, faps=faps), decoded, h.steps)


@settings(max_examples=40, deadline=None)
@given(streams(fps=st.sampled_from([25.0, 30.0, 29.97])), st.sampled_from([12.5, 7.0, 30.0]))
def test_rate_resamples_before_coding(s: FapStream, rate: float) -> None:
    d = decode(encode(s, rate=rate, coder="huffman"))
    assert d.fps == rate
    assert d == reconstruct(s, rate=rate)
    assert d.n_frames == (math.floor(s.n_frames * rate / s.fps + 0.5) if s.n_frames else 0)


# --- header -------------------------------------------------------------------------------------


@pytest.mark.parametrize("coder", CODERS)
def test_header_fields(coder: str) -> None:
    s = small(8)
    data = encode(s, faps=PAPER_17 + (1,), quantizer=2.5, coder=coder, rate=12.5)
    h = read_header(data)
    assert data[:4] == MAGIC and data[4] == 1 and data[5] == (0 if coder == "huffman" else 1)
    assert struct.unpack(">d", data[7:15])[0] == 12.5 == h.fps
    assert struct.unpack(">II", data[15:23]) == (s.first_frame, h.n_frames) == (0, 4)
    assert h.faps == tuple(sorted((1, *PAPER_17)))
    assert int.from_bytes(data[23:32], "big") >> 4 == sum(1 << (68 - k) for k in h.faps)
    assert h.quantizer == 2.5 and struct.unpack(">f", data[32:36])[0] == 2.5
    assert h.steps == {k: FAPS[k - 1].quant_step * 2.5 for k in PAPER_17}
    assert h.name == "small" and not h.constant_mask
    assert struct.unpack(">I", data[h.header_size - 4 : h.header_size])[0] == zlib.crc32(
        data[: h.header_size - 4]
    )
    assert struct.unpack(">I", data[-4:])[0] == zlib.crc32(data[h.header_size : -4])
    if coder == "huffman":
        assert 1 <= len(h.huffman_tables) <= 4 and len(h.huffman_table_of) == 17
    else:
        assert not h.huffman_tables


def test_steps_are_stored_not_looked_up(monkeypatch: pytest.MonkeyPatch) -> None:
    s = stream(np.array([[0.0], [10], [21]]), [3])  # open_jaw, step 4
    data = encode(s)
    from vtts.fap import coding

    changed = tuple(dataclasses.replace(f, quant_step=99) for f in FAPS)
    for module in vars(coding).values():  # wherever the package looks the table up
        if getattr(module, "FAPS", None) is FAPS:
            monkeypatch.setattr(module, "FAPS", changed)
    assert decode(data).values[:, 2].tolist() == [0.0, 8.0, 20.0]


def test_constant_mask_flag_and_table_bytes() -> None:
    s = stream(np.array([[0.0, 1], [4, 1], [8, 2]]), [3, 4])
    h = read_header(encode(s, coder="huffman"))
    assert h.constant_mask and h.faps == (3, 4) and h.base_steps == (4, 2)


def test_fap_set() -> None:
    assert fap_set("3,4, 5") == (3, 4, 5)
    assert fap_set("paper17") == tuple(sorted(PAPER_17)) and len(PAPER_17) == 17
    assert fap_set("3-5 open_jaw head_yaw") == (3, 4, 5, 49)
    assert fap_set([50, "48"]) == (48, 50)
    assert fap_set("all") == tuple(range(1, 69))
    for bad in ("", "69", "5-3", "0-4", "nose"):
        with pytest.raises(FapError):
            fap_set(bad)


def test_faps_selects_and_drops_absent_ones() -> None:
    s = read_fap(DATA / "xface-joy.fap")
    d = decode(encode(s, faps="paper17", coder="huffman"))
    sent = set(np.flatnonzero(d.mask.any(axis=0)) + 1)
    assert sent == set(PAPER_17) & set(np.flatnonzero(s.mask.any(axis=0)) + 1)


def test_bad_arguments() -> None:
    s = small()
    with pytest.raises(FapError, match="coder"):
        encode(s, coder="lzw")
    for q in (0, -1, math.nan, 1e9):
        with pytest.raises(FapError, match="quantizer"):
            encode(s, quantizer=q)
    with pytest.raises(FapError):
        encode(s, rate=0)
    with pytest.raises(FapError):
        encode("not a stream")  # type: ignore[arg-type]


def test_huffman_lengths_are_limited_and_complete() -> None:
    fib = [1, 1]
    while len(fib) < 40:
        fib.append(fib[-1] + fib[-2])
    lengths = huffman_lengths(dict(enumerate(fib)))
    assert max(lengths.values()) <= MAX_CODE_LENGTH
    assert sum(2.0**-x for x in lengths.values()) == 1.0
    assert huffman_lengths({5: 10}) == {5: 1} and huffman_lengths({}) == {}


def test_huffman_symbol_range() -> None:
    assert ESCAPE == -64


# --- damaged input ------------------------------------------------------------------------------


@functools.cache
def tiny(coder: str) -> bytes:
    """A short valid bitstream (made once per coder: the property tests damage it many
    times)."""
    return encode(small(5), coder=coder, quantizer=3.0)


@pytest.mark.parametrize("coder", CODERS)
def test_every_truncation_is_reported_where_the_data_ends(coder: str) -> None:
    data = tiny(coder)
    for n in range(len(data)):
        with pytest.raises(CodingError) as e:
            decode(data[:n], file="t.fbs")
        assert e.value.offset == n, (n, e.value.message)
        assert e.value.file == "t.fbs" and e.value.message.startswith(f"byte {n}: ")


@pytest.mark.parametrize("coder", CODERS)
def test_every_byte_flip_is_detected(coder: str) -> None:
    data = tiny(coder)
    h = read_header(data)
    for i in range(len(data)):
        for flip in (0x01, 0x80, 0xFF):
            bad = bytearray(data)
            bad[i] ^= flip
            with pytest.raises(CodingError) as e:
                decode(bytes(bad))
            off = e.value.offset
            assert off is not None and 0 <= off <= len(data)
            if i >= h.header_size:  # in the frame data or its CRC: the frame data CRC
                assert off == len(data) - 4 and "CRC" in e.value.message


def test_trailing_bytes() -> None:
    data = tiny("huffman")
    with pytest.raises(CodingError, match="unexpected bytes after the end") as e:
        decode(data + b"\0")
    assert e.value.offset == len(data)


@pytest.mark.parametrize(
    ("offset", "value", "message"),
    [
        (0, b"XFBS", "not a vtts FAP bitstream"),
        (4, b"\x02", "unsupported bitstream version 2"),
        (5, b"\x07", "unknown coder 7"),
        (6, b"\x80", "unknown flags"),
        (7, struct.pack(">d", math.nan), "frame rate"),
        (7, struct.pack(">d", -25.0), "frame rate"),
        (19, struct.pack(">I", 2**31), "frames exceed the decoder's limit"),
        (31, b"\x0f", "FAP mask sets bits past FAP 68"),
        (32, struct.pack(">f", 0.0), "quantizer"),
    ],
)
def test_header_field_errors_name_their_byte(offset: int, value: bytes, message: str) -> None:
    data = bytearray(tiny("arithmetic"))
    data[offset : offset + len(value)] = value
    with pytest.raises(CodingError, match=message) as e:
        decode(bytes(data))
    assert e.value.offset == offset


def crafted(data: bytes, **changes) -> bytes:
    """``data`` with header fields changed and both CRCs right: damage only a decoder's checks
    beyond the CRCs can find."""
    h = read_header(data)
    payload = data[h.header_size : -4]
    return pack_header(dataclasses.replace(h, **changes), len(payload)) + data[h.header_size :]


def test_crafted_headers_that_pass_the_crc() -> None:
    data = tiny("arithmetic")
    with pytest.raises(CodingError, match="predictor entry 3 ← 50") as e:
        decode(crafted(data, predictors={3: 50}))
    assert 36 < e.value.offset < read_header(data).header_size
    with pytest.raises(CodingError, match="invalid stream name") as e:
        decode(crafted(data, name="#comment"))
    assert 36 < e.value.offset < read_header(data).header_size
    with pytest.raises(CodingError, match="base step must be ≥ 1") as e:
        decode(crafted(data, base_steps=(0,) * 17))
    assert e.value.offset == 36


def test_crafted_huffman_tables() -> None:
    data = tiny("huffman")
    h = read_header(data)
    incomplete = tuple({**t, 0: 15} for t in h.huffman_tables)
    with pytest.raises(CodingError, match="complete prefix code"):
        decode(crafted(data, huffman_tables=incomplete))
    with pytest.raises(CodingError, match="uses Huffman table 3 of"):
        decode(crafted(data, huffman_tables=h.huffman_tables[:1] * 2, huffman_table_of=(3,) * 17))


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_random_bytes(data: bytes) -> None:
    for candidate in (data, MAGIC + data, tiny("huffman")[:40] + data):
        with pytest.raises(CodingError) as e:
            decode(candidate)
        assert 0 <= e.value.offset <= len(candidate)


@settings(max_examples=200, deadline=None)
@given(st.binary(min_size=0, max_size=200), st.sampled_from(CODERS))
def test_random_frame_data_behind_a_valid_header(payload: bytes, coder: str) -> None:
    """Frame data that passes its CRC but was not made by the encoder: a CodingError or a valid
    stream, nothing else."""
    data = tiny(coder)
    h = read_header(data)
    header = data[: h.header_size - 8] + struct.pack(">I", len(payload))
    header += struct.pack(">I", zlib.crc32(header))
    crafted = header + payload + struct.pack(">I", zlib.crc32(payload))
    try:
        s = decode(crafted)
    except CodingError as e:
        assert e.offset is not None and h.header_size <= e.offset <= len(crafted)
    else:
        assert s.n_frames == h.n_frames


def test_not_bytes() -> None:
    with pytest.raises(CodingError):
        decode("VFBS")  # type: ignore[arg-type]


# --- CLI ----------------------------------------------------------------------------------------


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="vtts")
    register(p.add_subparsers(dest="command"))
    return p


def run(*argv: str) -> int:
    args = parser().parse_args(list(argv))
    return args.func(args)


def test_cli_encode_decode(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fbs = tmp_path / "joy.fbs"
    out = tmp_path / "joy.fap"
    src = str(DATA / "xface-joy.fap")
    argv = ["encode", src, "-o", str(fbs), "--faps", "paper17", "--rate", "12.5"]
    argv += ["--quantizer", "4", "--coder", "huffman"]
    with pytest.warns(FapWarning, match="FAPs 31, 32, 35, 36 of --faps not in the stream"):
        assert run(*argv) == 0
    said = capsys.readouterr().out
    assert said.startswith(f"wrote {fbs}: 54 frames at 12.5 Hz") and "huffman" in said
    assert run("decode", str(fbs), "-o", str(out)) == 0
    s = read_fap(DATA / "xface-joy.fap")
    expect = reconstruct(s, faps="paper17", rate=12.5, quantizer=4)
    assert read_fap(out) == expect
    assert read_stream(fbs) == expect and read_stream(out) == expect
    summary = check_fbs(fbs)
    assert summary.startswith("54 frames at 12.5 Hz, ") and "kbit/s" in summary


def test_cli_warns_about_absent_faps(tmp_path: Path) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run(
            "encode",
            str(DATA / "xface-joy.fap"),
            "-o",
            str(tmp_path / "x.fbs"),
            "--faps",
            "3,43,44",
            "--quiet",
        )
    assert any("FAPs 43, 44 of --faps" in str(w.message) for w in caught)


def test_cli_errors_name_file_and_byte(tmp_path: Path) -> None:
    fbs = tmp_path / "a.fbs"
    run("encode", str(DATA / "xface-test.fap"), "-o", str(fbs), "--quiet")
    damaged = tmp_path / "damaged.fbs"
    damaged.write_bytes(fbs.read_bytes()[:-10])
    out = tmp_path / "never.fap"
    with pytest.raises(CodingError) as e:
        run("decode", str(damaged), "-o", str(out))
    assert e.value.file == str(damaged) and e.value.message.startswith("byte ")
    assert sorted(tmp_path.iterdir()) == sorted([fbs, damaged])  # nothing half-written
    with pytest.raises(VttsError):
        check_fbs(damaged)
    with pytest.raises(FapError, match="cannot read"):
        check_fbs(tmp_path / "missing.fbs")
    with pytest.raises(SystemExit):
        parser().parse_args(["encode", "x.fap", "-o", "y.fbs", "--rate", "-2"])


def test_cli_reencodes_a_bitstream(tmp_path: Path) -> None:
    a, b = tmp_path / "a.fbs", tmp_path / "b.fbs"
    src = tmp_path / "s.fap"
    write_fap(small(7), src)
    run("encode", str(src), "-o", str(a), "--quiet", "--coder", "huffman")
    run("encode", str(a), "-o", str(b), "--quiet")
    assert decode(b.read_bytes()) == decode(a.read_bytes())  # the grid is kept
