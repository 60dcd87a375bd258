"""Hostile and mutated inputs of every kind through the real commands, in a bounded process
(issue 21): 3 GB of address space, 60 s of processor time and 60 s of wall-clock time
(``hostile.limited``; each process is forked from one that made Python's start-up and the
imports once, ``hostile.run_bounded``). Each case must end with status 0 or 1 (2 for a usage
error, as argparse reports a bad ``--seed``) and no traceback: a process beyond its memory dies
with a MemoryError traceback, one beyond its processor time by SIGXCPU, one beyond its time by
the test's timeout, so a passing case held its bounds.

The in-process fuzzers (``test_*_fuzz.py`` beside each reader) try thousands of inputs; here a
few of each kind, the hostile ones they found among them, go through argument parsing, the
readers and the commands' error reporting as a user meets them. Mutations are seeded, so every
run feeds the same bytes.
"""

from __future__ import annotations

import functools
import io
import json
import random
import shutil
import struct
import tempfile
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from .hostile import DATA, INTERESTING, OPS, mutate, mutate_bytes, run_bounded, wav
from .in_process import vtts

ROOT = DATA.parent.parent
HEAD = DATA / "models" / "head.wrl"
JOY = DATA / "fap" / "xface-joy.fap"
SAMPLE = ROOT / "samples" / "candide3.wrl"


def text_ops(seed: int, n: int = 3) -> list[tuple[str, int, int, str]]:
    """``n`` seeded edits for :func:`hostile.mutate`."""
    r = random.Random(seed)
    return [(r.choice(OPS), r.randrange(10**6), r.randrange(10**6), r.choice(INTERESTING))
            for _ in range(n)]  # fmt: skip


def byte_ops(seed: int, n: int = 4) -> list[tuple[int, str, int]]:
    """``n`` seeded edits for :func:`hostile.mutate_bytes`."""
    r = random.Random(seed)
    kinds = ["flip", "set", "insert", "delete", "truncate"]
    return [(r.randrange(10**9), r.choice(kinds[:4]), r.randrange(256)) for _ in range(n)]


def noise(seed: int, size: int = 400) -> bytes:
    return random.Random(seed).randbytes(size)


def put(path: Path, data: str | bytes, *args: str) -> list[str]:
    """Write ``data`` to ``path``; ``args`` are the command's arguments."""
    if isinstance(data, str):
        data = data.encode("utf-8", "surrogatepass")
    path.write_bytes(data)
    return list(args)


def png_size(data: bytes, w: int, h: int) -> bytes:
    """A PNG whose header declares ``w`` x ``h`` pixels (its CRC right)."""
    ihdr = struct.pack(">II", w, h) + data[24:29]
    return data[:16] + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr)) + data[33:]


@functools.cache
def small_png() -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.open(DATA / "photos" / "akiyo_frame0.png").convert("RGB").resize((176, 144)).save(
        buf, "PNG"
    )
    return buf.getvalue()


# ---- the inputs: each maker writes into the case's folder and returns the command's arguments ---

Maker = Callable[[Path], list[str]]
CASES: dict[str, Maker] = {}


def case(name: str) -> Callable[[Maker], Maker]:
    def register(make: Maker) -> Maker:
        CASES[name] = make
        return make

    return register


# .adt tables (vtts check compares them with head.wrl beside them)
def _adt(t: Path, text: str) -> list[str]:
    shutil.copy(HEAD, t / "head.wrl")
    (t / "head.adt").write_text(text, encoding="utf-8", errors="surrogatepass")
    return ["check", "head.adt"]


ADT = (DATA / "models" / "head.adt").read_text()
for _seed in (1, 2, 3):
    case(f"adt: mutated {_seed}")(lambda t, s=_seed: _adt(t, mutate(ADT, text_ops(s))))
case("adt: a Transform unit of 1e999")(lambda t: _adt(t, ADT.replace("0.05 0", "1e999 0")))
case("adt: a vertex index of 10^30")(
    lambda t: _adt(t, ADT.replace("vertex 50", "vertex " + "9" * 30))
)


# .fap files
FAP = "\n".join(JOY.read_text().split("\n")[:30]) + "\n"
for _seed in (4, 5):
    case(f"fap: mutated {_seed}")(
        lambda t, s=_seed: put(t / "x.fap", mutate(FAP, text_ops(s)), "check", "x.fap")
    )


@functools.cache
def joy_fbs() -> bytes:
    """JOY as ``vtts encode`` writes it (made once: each case damages a copy)."""
    with tempfile.TemporaryDirectory() as tmp:
        r = vtts("encode", str(JOY), "-o", "joy.fbs", "--quiet", cwd=Path(tmp))
        assert r.returncode == 0, r.stderr
        return Path(tmp, "joy.fbs").read_bytes()


# .fbs bitstreams: header fields and frame data mutated, both CRCs recomputed
def _fbs(t: Path, seed: int, where: str) -> list[str]:
    data = joy_fbs()
    from vtts.fap.coding import read_header

    size = read_header(data).header_size
    fields, payload = data[: size - 8], data[size:-4]
    if where == "header":
        fields = mutate_bytes(fields, byte_ops(seed), start=4)
    else:
        payload = mutate_bytes(payload, byte_ops(seed))
    header = fields + struct.pack(">I", len(payload))
    header += struct.pack(">I", zlib.crc32(header))
    (t / "x.fbs").write_bytes(header + payload + struct.pack(">I", zlib.crc32(payload)))
    return ["decode", "x.fbs", "-o", "x.fap"]


for _seed, _where in ((6, "header"), (7, "header"), (8, "frames")):
    case(f"fbs: mutated {_where} {_seed}")(lambda t, s=_seed, w=_where: _fbs(t, s, w))


# say text with bookmarks (espeak-ng speaks; only the FAP stream is written)
def _say(t: Path, text: str) -> list[str]:
    (t / "text.txt").write_text(text, encoding="utf-8", errors="surrogatepass")
    return ["say", "--file", "text.txt", "--model", str(HEAD), "--fap-out", "x.fap", "--quiet"]


BOOKMARKS = (ROOT / "samples" / "texts" / "bookmarks.txt").read_text()
for _seed in (9, 10):
    case(f"say text: mutated {_seed}")(lambda t, s=_seed: _say(t, mutate(BOOKMARKS, text_ops(s))))
case("say text: a duration of 10^400 s")(lambda t: _say(t, "Hi <smile " + "9" * 400 + "s> there"))
case("say text: <fap ²=1>")(lambda t: _say(t, "Hi <fap ²=1> there"))


# say --phonemes FILE --audio WAV
def _phonemes(t: Path, name: str, data: bytes, audio: bytes | None = None) -> list[str]:
    (t / name).write_bytes(data)
    if audio is None:
        wav(t / "a.wav")
    else:
        (t / "a.wav").write_bytes(audio)
    return ["say", "Hi", "--model", str(HEAD), "--phonemes", name, "--audio", "a.wav",
            "--fap-out", "x.fap", "--quiet"]  # fmt: skip


POLLY = "\n".join(
    json.dumps({"time": ms, "type": "viseme", "value": v})
    for ms, v in ((0, "p"), (80, "E"), (190, "r"), (300, "sil"))
)
TABLE = "0 0.08 h\n0.08 0.2 @\n0.2 0.31 l\nmark 0.25 b0\n0.31 0.5 oU\n"
case("phonemes: mutated Polly marks")(
    lambda t: _phonemes(t, "m.json", mutate(POLLY, text_ops(11)).encode())
)
case("phonemes: mutated table")(
    lambda t: _phonemes(t, "m.txt", mutate(TABLE, text_ops(12)).encode())
)
case("phonemes: random bytes")(lambda t: _phonemes(t, "m.txt", noise(13)))
for _seed in (14, 15):
    case(f"audio: mutated WAV {_seed}")(
        lambda t, s=_seed: _phonemes(
            t,
            "p.txt",
            TABLE.encode(),
            mutate_bytes(wav(t / "w.wav").read_bytes()[:400], byte_ops(s)),
        )
    )


def _flac_of_ten_hours(t: Path) -> list[str]:
    import soundfile as sf

    buf = io.BytesIO()
    sf.write(buf, np.zeros(800, dtype=np.int16), 8000, format="FLAC")
    data = bytearray(buf.getvalue())
    bits = int.from_bytes(data[18:26], "big") & ~((1 << 36) - 1) | 8000 * 36_000
    data[18:26] = bits.to_bytes(8, "big")  # the STREAMINFO sample count
    args = _phonemes(t, "p.txt", TABLE.encode())
    (t / "a.flac").write_bytes(bytes(data))
    return [a if a != "a.wav" else "a.flac" for a in args]


case("audio: a FLAC claiming ten hours")(_flac_of_ten_hours)


# vtts analyze: video files and PNG folders
def _analyze(t: Path, video: str) -> list[str]:
    return ["analyze", video, "--model", str(HEAD), "-o", "x.fap", "--quiet"]


@functools.cache
def small_mp4() -> bytes:
    """Three frames from vtts's VideoWriter (made once: each case damages a copy)."""
    from PIL import Image

    from vtts.render import VideoWriter

    frame = np.asarray(Image.open(io.BytesIO(small_png())))
    with tempfile.TemporaryDirectory() as tmp:
        with VideoWriter(Path(tmp, "ok.mp4"), 10, (176, 144)) as video:
            for k in range(3):
                video.write(np.roll(frame, 4 * k, axis=1))
        return Path(tmp, "ok.mp4").read_bytes()


def _mp4(t: Path, seed: int) -> list[str]:
    """:func:`small_mp4` damaged in its second half (the frame data)."""
    data = small_mp4()
    (t / "x.mp4").write_bytes(mutate_bytes(data, byte_ops(seed), start=len(data) // 2))
    return _analyze(t, "x.mp4")


def _frames(t: Path, data: bytes) -> list[str]:
    (t / "frames").mkdir()
    (t / "frames" / "0001.png").write_bytes(small_png())
    (t / "frames" / "0002.png").write_bytes(data)
    return _analyze(t, "frames")


for _seed in (16, 17):
    case(f"video: a mutated MP4 {_seed}")(lambda t, s=_seed: _mp4(t, s))
case("video: random bytes")(lambda t: put(t / "x.mp4", noise(18)) + _analyze(t, "x.mp4"))
case("video: a mutated PNG frame")(lambda t: _frames(t, mutate_bytes(small_png(), byte_ops(19))))
case("video: a PNG frame declaring 829x215871")(
    lambda t: _frames(t, png_size(small_png(), 829, 215_871))
)


# adi fit: photos
def _fit(t: Path, data: bytes) -> list[str]:
    (t / "photo.png").write_bytes(data)
    (t / "out").mkdir()
    return ["fit", "photo.png", "-o", "out/me.wrl"]


case("photo: mutated")(lambda t: _fit(t, mutate_bytes(small_png(), byte_ops(20))))
case("photo: random bytes")(lambda t: _fit(t, noise(21)))
case("photo: declaring 89478479x1")(lambda t: _fit(t, png_size(small_png(), 89_478_479, 1)))


# adi build: deformed exports
def _build(t: Path, name: str, data: bytes) -> list[str]:
    (t / name).write_bytes(data)
    return ["build", str(SAMPLE), name, "-o", "x.adt"]


def _gltf(t: Path, change: Callable[[dict], None]) -> list[str]:
    from vtts.face import load_model

    from .adi.adi_helpers import face_points, face_triangles, write_gltf

    shutil.copy(SAMPLE, t / "head.wrl")
    model = load_model(t / "head.wrl")
    base = face_points(model)
    path = write_gltf(
        t / "g.gltf", [("FACE_MESH", base, face_triangles(model), {"joy@1": base * 0})]
    )
    doc = json.loads(path.read_text())
    change(doc)
    return _build(t, "joy@1.gltf", json.dumps(doc).encode())


OBJ = "".join(f"v {x} {y} 0\n" for x, y in np.random.default_rng(0).random((113, 2)).round(3))
case("obj: mutated")(lambda t: _build(t, "joy@1.obj", mutate(OBJ, text_ops(22)).encode()))
case("ply: random bytes after the header")(
    lambda t: _build(t, "joy@1.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex "
                     b"4000000000\nproperty float x\nproperty float y\nproperty float z\n"
                     b"end_header\n" + noise(23))
)  # fmt: skip
case("gltf: count false")(lambda t: _gltf(t, lambda d: d["accessors"][0].update(count=False)))
case("gltf: buffer -1")(lambda t: _gltf(t, lambda d: d["bufferViews"][0].update(buffer=-1)))
case("gltf: a morph target shorter than its base")(
    lambda t: _gltf(t, lambda d: d["accessors"][-1].update(count=50))
)

# VRML scenes
VRML = (ROOT / "samples" / "candide3.wrl").read_text()[:3000]
case("vrml: mutated")(lambda t: put(t / "x.wrl", mutate(VRML, text_ops(24)), "check", "x.wrl"))

# option strings
for _args in (
    ["render", "--model", str(HEAD), "--size", "²x288", "-o", "x.png"],
    ["render", "--model", str(HEAD), "--fap", "9" * 5000 + "=1", "-o", "x.png"],
    ["pose", "--model", str(HEAD), "--viseme", "²", "-o", "x.wrl"],
    ["render", "--model", str(HEAD), "--camera", "nan,1e308,-0,inf", "-o", "x.png"],
    ["render", "--model", str(HEAD), "--background", "1,1,1e999", "-o", "x.png"],
    ["encode", str(JOY), "--faps", "3-" + "9" * 5000, "-o", "x.fbs"],
    ["analyze", "x.mp4", "--model", str(HEAD), "--faps", "+-5", "-o", "x.fap"],
    ["say", "Hi", "--model", str(HEAD), "--seed", "9" * 5000, "--fap-out", "x.fap"],
):
    _shown = " ".join(a if a != str(HEAD) else "head.wrl" for a in _args)
    case(f"option: {_shown[:60]}")(lambda t, a=_args: a)

ADI = ("fit", "build")


@pytest.mark.parametrize("name", CASES)
def test_a_hostile_input_is_a_clear_error_within_bounds(tmp_path: Path, name: str) -> None:
    args = CASES[name](tmp_path)
    tool = "adi" if args[0] in ADI else "vtts"
    r = run_bounded(tool, *args, cwd=tmp_path)
    assert r.returncode in (0, 1) or (r.returncode == 2 and "usage:" in r.stderr), (
        r.returncode,
        r.stderr[-2000:],
    )
    assert "Traceback" not in r.stderr, r.stderr[-3000:]
    if r.returncode:
        assert "error" in r.stderr
