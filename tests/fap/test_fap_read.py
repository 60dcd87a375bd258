"""Reading .fap files: the real Xface files and the liberal rules."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from vtts.errors import FapError, VttsWarning
from vtts.fap import FapStream, FapWarning, parse_fap, read_fap

DATA = Path(__file__).resolve().parent.parent / "data" / "fap"
REAL_FILES = sorted(DATA.glob("*.fap"))
NAME = r"C:\Users\balci\Work\FACE\exml2fap\files\TempFile"


def mask_line(*faps: int, n: int = 68) -> str:
    """A mask line selecting the given FAP numbers."""
    return " ".join("1" if k + 1 in faps else "0" for k in range(n))


def test_there_are_nine_real_files() -> None:
    assert [p.name for p in REAL_FILES] == [
        "xface-anger.fap", "xface-beg.fap", "xface-disgust.fap", "xface-fear.fap",
        "xface-happy-for.fap", "xface-hate.fap", "xface-joy.fap", "xface-pride.fap",
        "xface-test.fap",
    ]  # fmt: skip


@pytest.mark.parametrize("path", REAL_FILES, ids=lambda p: p.stem)
def test_real_file_reads_with_its_header(path: Path) -> None:
    header = path.read_text().split("\n", 1)[0].split()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the headers' frame counts are right
        s = read_fap(path)
    assert isinstance(s, FapStream)
    assert s.version == header[0] == "2.1"
    assert s.name == header[1] == NAME
    assert s.fps == float(header[2]) == 25.0
    assert s.n_frames == int(header[3])
    assert s.first_frame == 0
    assert s.duration == pytest.approx(s.n_frames / 25.0)
    # Xface writes integers only, low-level FAPs only.
    assert np.array_equal(s.values, np.round(s.values))
    assert not s.mask[:, :2].any()
    assert not s.viseme.any() and not s.expression.any()


def test_real_file_values_by_hand() -> None:
    s = read_fap(DATA / "xface-anger.fap")
    assert s.n_frames == 108
    # Line 2: the mask sets FAPs 3-20, 23-26, 31-42, 48-60 and 63.
    expected = (
        set(range(3, 21)) | set(range(23, 27)) | set(range(31, 43)) | set(range(48, 61)) | {63}
    )
    assert set(np.flatnonzero(s.mask[0]) + 1) == expected
    # Line 3: "0 0 10 10 0 0 10 10 10 10 0 ..." -> FAPs 3..11
    assert list(s.values[0, 2:11]) == [0, 10, 10, 0, 0, 10, 10, 10, 10]
    # Line 5: "1 0 8 10 1 1 8 8 10 10 ..."
    assert list(s.values[1, 2:11]) == [0, 8, 10, 1, 1, 8, 8, 10, 10]
    # Last line: "107 0 10 10 0 0 10 10 10 10 0 ..."
    assert list(s.values[107, 2:11]) == [0, 10, 10, 0, 0, 10, 10, 10, 10]


def test_real_file_last_frame_by_hand() -> None:
    s = read_fap(DATA / "xface-test.fap")
    # "42 80 -90 -103 69 69 -90 -90 -103 -103 0 0 8 0 -4 -9 0 -100 -100 689 689 -946 -946 ..."
    # FAPs 3-20, then 23-26 (21, 22 are not masked).
    row = s.values[42]
    assert list(row[2:20]) == [80, -90, -103, 69, 69, -90, -90, -103, -103, 0, 0, 8, 0, -4, -9,
                               0, -100, -100]  # fmt: skip
    assert list(row[22:26]) == [689, 689, -946, -946]
    assert row[20] == row[21] == 0 and not s.mask[42, 20]


def test_test_file_is_the_start_of_anger() -> None:
    # Surprising but true of the Xface files: xface-test is the first 43 frames of xface-anger.
    anger, test = read_fap(DATA / "xface-anger.fap"), read_fap(DATA / "xface-test.fap")
    assert np.array_equal(anger.values[:43], test.values)


def test_masks_change_between_frames() -> None:
    # In xface-hate the eyelid FAPs 19 and 20 are set in a few frames only (a blink).
    s = read_fap(DATA / "xface-hate.fap")
    assert 0 < s.mask[:, 18].sum() < s.n_frames
    assert np.array_equal(s.mask[:, 18], s.mask[:, 19])


SMALL = (
    "2.1 demo 25 2\n"
    f"{mask_line(3, 4)}\n"
    "0 5 -3\n"
    f"{mask_line(3, 4)}\n"
    "1 6 -2\n"
)  # fmt: skip


def test_small_file() -> None:
    s = parse_fap(SMALL)
    assert (s.name, s.fps, s.n_frames, s.first_frame, s.version) == ("demo", 25.0, 2, 0, "2.1")
    assert s.values[:, 2:4].tolist() == [[5, -3], [6, -2]]
    assert s.mask.sum() == 4 and s.mask[:, 2:4].all()
    assert s.values.dtype == np.float64 and s.mask.dtype == np.bool_


def test_comments_and_blank_lines_anywhere() -> None:
    text = (
        "# a comment before the header\n\n"
        "2.1 demo 25 2\n"
        "  # indented comment\n\n"
        f"{mask_line(3, 4)}\n"
        "# between mask and values\n"
        "0 5 -3   # trailing comment\n"
        f"{mask_line(3, 4)}\n\n"
        "1 6 -2\n"
        "# at the end\n\n\n"
    )
    assert parse_fap(text) == parse_fap(SMALL)


@pytest.mark.parametrize("newline", ["\r\n", "\r"])
def test_other_line_ends(newline: str) -> None:
    assert parse_fap(SMALL.replace("\n", newline)) == parse_fap(SMALL)


def test_tabs_and_bom() -> None:
    assert parse_fap("\ufeff" + SMALL.replace(" ", "\t")) == parse_fap(SMALL)


def test_69_mask_values() -> None:
    text = SMALL.replace(mask_line(3, 4), mask_line(3, 4) + " 0", 1)
    text = text.replace(mask_line(3, 4) + "\n1", mask_line(3, 4) + " 1\n1")
    assert parse_fap(text) == parse_fap(SMALL)


def test_frames_starting_at_1() -> None:
    s = parse_fap(SMALL.replace("\n0 5", "\n1 5").replace("\n1 6", "\n2 6"))
    assert s.first_frame == 1
    assert np.array_equal(s.values, parse_fap(SMALL).values)


def test_name_with_spaces() -> None:
    s = parse_fap(SMALL.replace("2.1 demo 25 2", "2.1  my  demo\tfile 25 2"))
    assert s.name == "my  demo\tfile"


def test_header_comment_and_hash_in_name() -> None:
    s = parse_fap(SMALL.replace("2.1 demo 25 2", "2.1 take#2 25 2  # exported by hand"))
    assert (s.name, s.fps, s.n_frames) == ("take#2", 25.0, 2)


def test_version_2_0() -> None:
    assert parse_fap(SMALL.replace("2.1", "2.0", 1)).version == "2.0"


def test_float_values() -> None:
    text = SMALL.replace("0 5 -3", "0.0 1.5 -2e-3").replace("1 6 -2", "1 +.5 5.")
    s = parse_fap(text.replace(" 25 2", " 29.97 2"))
    assert s.fps == 29.97
    assert s.values[:, 2:4].tolist() == [[1.5, -0.002], [0.5, 5.0]]


def test_high_level_faps() -> None:
    text = (
        "2.1 hl 30 1\n"
        f"{mask_line(1, 2, 3)}\n"
        "0 1 7 40 1 3 63 0 0 1 0 -12\n"
    )  # fmt: skip
    s = parse_fap(text)
    assert s.viseme.tolist() == [[1, 7, 40, 1]]
    assert s.expression.tolist() == [[3, 63, 0, 0, 1, 0]]
    assert s.values[0, 2] == -12 and s.values[0, :2].tolist() == [0, 0]
    assert s.viseme.dtype == np.int64 and s.expression.dtype == np.int64


def test_empty_stream() -> None:
    s = parse_fap("2.1 nothing 25 0\n")
    assert s.n_frames == 0 and s.values.shape == (0, 68) and s.duration == 0.0


@pytest.mark.parametrize("nframes", [0, 1, 5])
def test_wrong_frame_count_warns(nframes: int) -> None:
    text = SMALL.replace("demo 25 2", f"demo 25 {nframes}")
    with pytest.warns(
        FapWarning,
        match=rf"^clip\.fap:1: the header says {nframes} frames but "
        r"the file has 2; using the 2 frames present$",
    ) as w:
        s = parse_fap(text, file="clip.fap")
    assert s == parse_fap(SMALL)
    assert isinstance(w[0].message, VttsWarning)
    assert (w[0].message.file, w[0].message.line) == ("clip.fap", 1)


def test_read_fap_latin1_and_path_types(tmp_path: Path) -> None:
    p = tmp_path / "x.fap"
    p.write_bytes(SMALL.replace("demo", "d\xe9mo").encode("latin-1"))
    assert read_fap(p).name == "démo"
    assert read_fap(str(p)).name == "démo"
    p.write_text(SMALL.replace("demo", "démo"), encoding="utf-8")
    assert read_fap(p).name == "démo"


def test_read_missing_file(tmp_path: Path) -> None:
    with pytest.raises(FapError, match="cannot read FAP file") as e:
        read_fap(tmp_path / "nope.fap")
    assert e.value.file == str(tmp_path / "nope.fap")
