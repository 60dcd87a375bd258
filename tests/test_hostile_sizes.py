"""Inputs whose size is hostile fail at once with a clear error naming the limit: each case runs
the CLI in a process limited to 3 GB of address space and 60 s (``hostile.run_bounded``), and
must exit 1 with the message and no traceback (before the limits of vtts.limits, these took 6 to
24 GB or ran for minutes)."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from vtts import limits

from .hostile import DATA, run_bounded, wav
from .in_process import vtts

HEAD = str(DATA / "models" / "head.wrl")
JOY = str(DATA / "fap" / "xface-joy.fap")


def _slow_fap(tmp: Path) -> Path:
    mask = " ".join(["0", "0", "1"] + ["0"] * 65)
    frames = "".join(f"{mask}\n{i} 100\n" for i in range(5))
    (tmp / "slow.fap").write_text(f"2.1 slow 0.0001 5\n{frames}")
    return tmp / "slow.fap"


def _long_fbs(tmp: Path) -> Path:
    """A valid bitstream whose header claims 200,000 frames at 0.05 Hz (46 days)."""
    fbs = tmp / "joy.fbs"
    r = vtts("encode", JOY, "-o", str(fbs), "--quiet", cwd=tmp)
    assert r.returncode == 0, r.stderr
    data = bytearray(fbs.read_bytes())
    struct.pack_into(">d", data, 7, 0.05)
    struct.pack_into(">I", data, 19, 200_000)
    fbs.write_bytes(bytes(data))
    return fbs


def _long_string_wrl(tmp: Path) -> Path:
    p = tmp / "long.wrl"
    with open(p, "w") as f:
        f.write('#VRML V2.0 utf8\nWorldInfo { info ["')
        f.write("a" * 50_000_000)
        f.write('"] }\n')
    return p


def _blank_adt(tmp: Path) -> Path:
    (tmp / "blank.wrl").write_bytes(Path(HEAD).read_bytes())
    with open(tmp / "blank.adt", "w") as f:
        f.write("#AnimationDefinitionTables\n")
        f.write("\n" * 30_000_000)
    return tmp / "blank.adt"


def _big_frames(tmp: Path) -> Path:
    from PIL import Image

    folder = tmp / "frames"
    folder.mkdir()
    Image.new("L", (8192, 8192)).save(folder / "0001.png")
    return folder


def _phonemes(tmp: Path) -> Path:
    (tmp / "ph.txt").write_text("0 0.1 h\n0.1 1000000 a\n")
    return tmp / "ph.txt"


CASES = {
    "a phoneme table ending at 10^6 s": (
        lambda t: ["say", "Hi", "--model", HEAD, "--phonemes", str(_phonemes(t)), "--audio",
                   str(wav(t / "a.wav")), "--wav-out", "x.wav"],
        "the phonemes last until 1e+06 s, more than the limit of 3600 s",
    ),
    "a .fap at 0.0001 fps": (
        lambda t: ["play", str(_slow_fap(t)), "--model", HEAD, "-o", "x.mp4"],
        "frame rate 0.0001 is outside the limits 0.01–1000 fps",
    ),
    "encode --rate 230000": (
        lambda t: ["encode", JOY, "--rate", "230000", "-o", "x.fbs"],
        "fps 230000 is outside the limits 0.01–1000",
    ),
    "an .fbs header of 200,000 frames at 0.05 Hz": (
        lambda t: ["check", str(_long_fbs(t))],
        "200000 frames at 0.05 Hz last 4e+06 s, more than the limit of 3600 s",
    ),
    "render --size 8192x8192": (
        lambda t: ["render", "--model", HEAD, "--size", "8192x8192", "-o", "x.png"],
        "image size must be within 16–4096 pixels, got 8192x8192",
    ),
    "render --size 4096x4096": (
        lambda t: ["render", "--model", HEAD, "--size", "4096x4096", "-o", "x.png"],
        "image size 4096x4096 has 16777216 pixels, more than the limit of 8294400",
    ),
    "an 8192x8192 PNG frame": (
        lambda t: ["analyze", str(_big_frames(t)), "--model", HEAD, "-o", "x.fap"],
        "the frame is 8192x8192 pixels, more than the limit of 4096 pixels on a side",
    ),
    "/dev/zero as --file": (
        lambda t: ["say", "--file", "/dev/zero", "--model", HEAD, "--wav-out", "x.wav"],
        "/dev/zero: error: text is larger than the limit of 64 MiB",
    ),
    "/dev/zero as --phonemes": (
        lambda t: ["say", "Hi", "--model", HEAD, "--phonemes", "/dev/zero", "--audio",
                   str(wav(t / "a.wav")), "--wav-out", "x.wav"],
        "/dev/zero: error: phoneme file is larger than the limit of 64 MiB",
    ),
    "/dev/zero to encode": (
        lambda t: ["encode", "/dev/zero", "-o", "x.fbs"],
        "/dev/zero: error: FAP file is larger than the limit of 64 MiB",
    ),
    "/dev/zero to decode": (
        lambda t: ["decode", "/dev/zero", "-o", "x.fap"],
        "/dev/zero: error: FAP bitstream is larger than the limit of 64 MiB",
    ),
}  # fmt: skip


def _transcript(tmp: Path, words: int = 100_000, word: str = "word") -> Path:
    (tmp / "long.txt").write_text(" ".join([word] * words))
    return tmp / "long.txt"


CASES["a 100,000-word transcript for 0.5 s of --audio"] = (
    lambda t: ["say", "--file", str(_transcript(t)), "--model", HEAD, "--audio",
               str(wav(t / "a.wav")), "--wav-out", "x.wav"],
    "the transcript has 100000 words for a recording of 0.5 s: more than the 15",
)  # fmt: skip
CASES["a 100,000-letter word for 0.5 s of --audio"] = (
    lambda t: ["say", "--file", str(_transcript(t, 1, "a" * 100_000)), "--model", HEAD,
               "--audio", str(wav(t / "a.wav")), "--wav-out", "x.wav"],
    "the transcript has 100000 characters for a recording of 0.5 s",
)  # fmt: skip


def _polly(tmp: Path, time: str, value: str = '"p"') -> Path:
    (tmp / "marks.json").write_text(f'{{"time": {time}, "type": "viseme", "value": {value}}}\n')
    return tmp / "marks.json"


POLLY = {
    "nested 10,000 deep": (("0", "[" * 10_000 + "]" * 10_000), "nested too deeply"),
    "an integer of 5,000 digits": (("9" * 5000,), "Exceeds the limit (4300 digits)"),
    "1e400 ms": (("1e400",), "time must be milliseconds >= 0, got 'inf'"),
    "1e300 ms": (("1e300",), "the phonemes last until 1e+297 s, more than the limit of 3600 s"),
}
for _name, (_polly_args, _message) in POLLY.items():
    CASES[f"Polly speech marks: {_name}"] = (
        lambda t, a=_polly_args: ["say", "Hi", "--model", HEAD, "--phonemes",
                                  str(_polly(t, *a)), "--audio", str(wav(t / "a.wav")),
                                  "--wav-out", "x.wav"],
        _message,
    )  # fmt: skip


@pytest.mark.parametrize("case", CASES)
def test_a_hostile_size_is_a_clear_error(tmp_path, case):
    make_args, message = CASES[case]
    r = run_bounded("vtts", *make_args(tmp_path), cwd=tmp_path)
    assert r.returncode == 1, (r.returncode, r.stderr[-2000:])
    assert message in r.stderr
    assert "Traceback" not in r.stderr


# Inputs that used to blow up inside a regular expression: they now load (or fail on their
# content) within the same bounds.
LOADS = {
    "a VRML string of 50 MB": (_long_string_wrl, 0, "OK"),
    "an .adt of 30 MB of blank lines": (_blank_adt, 1, "no tables in it"),
}


@pytest.mark.parametrize("case", LOADS)
def test_a_large_input_stays_within_bounds(tmp_path, case):
    make, code, fragment = LOADS[case]
    r = run_bounded("vtts", "check", str(make(tmp_path)), cwd=tmp_path)
    assert r.returncode == code, r.stderr[-2000:]
    assert fragment in r.stdout + r.stderr


def test_the_limits_are_documented():
    doc = (Path(__file__).parents[1] / "docs" / "limits.md").read_text(encoding="utf-8")
    names = [n for n in vars(limits) if n.isupper()]
    assert names
    missing = [n for n in names if n not in doc]
    assert not missing, f"docs/limits.md does not explain {missing}"
