"""Every rule of the .fap reader: a bad input, the message, the line and the column."""

from __future__ import annotations

import pytest

from vtts.errors import FapError
from vtts.fap import parse_fap


def mask_line(*faps: int, n: int = 68, bad: dict[int, str] | None = None) -> str:
    tokens = ["1" if k + 1 in faps else "0" for k in range(n)]
    for k, t in (bad or {}).items():
        tokens[k - 1] = t
    return " ".join(tokens)


M34 = mask_line(3, 4)
HEAD = "2.1 demo 25 2\n"

# fmt: off
# (id, text, message (exact), line, column)
CASES = [
    ("empty", "", "expected a header 'VERSION NAME FPS NFRAMES', got an empty file", 1, None),
    ("only-comments", "# x\n\n", "expected a header 'VERSION NAME FPS NFRAMES', got an empty file",
     3, None),
    ("short-header", "2.1 demo 25\n",
     "expected a header 'VERSION NAME FPS NFRAMES', got 3 tokens", 1, None),
    ("one-token-header", "\n\n2.1\n", "expected a header 'VERSION NAME FPS NFRAMES', got 1 token",
     3, None),
    ("version", "3.0 demo 25 0\n", "expected FAP file version 2.0 or 2.1, got '3.0'", 1, 1),
    ("version-not-number", "  fap demo 25 0\n", "expected FAP file version 2.0 or 2.1, got 'fap'",
     1, 3),
    ("fps-word", "2.1 demo abc 0\n", "expected the frame rate FPS as a positive number, got 'abc'",
     1, 10),
    ("fps-zero", "2.1 demo 0 0\n", "expected the frame rate FPS as a positive number, got '0'",
     1, 10),
    ("fps-inf", "2.1 demo 1e999 0\n",
     "expected the frame rate FPS as a positive number, got '1e999'", 1, 10),
    ("fps-nan", "2.1 demo nan 0\n", "expected the frame rate FPS as a positive number, got 'nan'",
     1, 10),
    ("nframes-negative", "2.1 demo 25 -1\n",
     "expected the frame count NFRAMES as an integer ≥ 0, got '-1'", 1, 13),
    ("nframes-fraction", "2.1 demo 25 2.5\n",
     "expected the frame count NFRAMES as an integer ≥ 0, got '2.5'", 1, 13),
    ("mask-count", HEAD + "0 0 1 1 0 0 0 0 0 0 0 0\n0 5 -3\n",
     "expected 68 mask values (0 or 1), got 12", 2, None),
    ("mask-count-70", HEAD + mask_line(3, n=70) + "\n0 5\n",
     "expected 68 mask values (0 or 1), got 70", 2, None),
    ("mask-value", HEAD + mask_line(3, bad={5: "2"}) + "\n0 5\n",
     "expected a mask value 0 or 1, got '2'", 2, 9),
    ("mask-value-float", HEAD + mask_line(3, bad={3: "1.0"}) + "\n0 5\n",
     "expected a mask value 0 or 1, got '1.0'", 2, 5),
    ("mask-69th-value", HEAD + mask_line(3, n=69, bad={69: "x"}) + "\n0 5\n",
     "expected a mask value 0 or 1, got 'x'", 2, 137),
    ("no-value-line", HEAD + M34 + "\n0 5 -3\n" + M34 + "\n# the end\n",
     "expected the value line of frame 1 after this mask line, got the end of the file", 4, None),
    ("frame-number-word", HEAD + M34 + "\nzero 5 -3\n",
     "expected a frame number (an integer), got 'zero'", 3, 1),
    ("frame-number-fraction", HEAD + M34 + "\n  0.5 5 -3\n",
     "expected a frame number (an integer), got '0.5'", 3, 3),
    ("frame-number-negative", HEAD + M34 + "\n-1 5 -3\n", "expected a frame number ≥ 0, got '-1'",
     3, 1),
    ("frame-number-gap", HEAD + M34 + "\n0 5 -3\n" + M34 + "\n2 6 -2\n",
     "expected frame number 1 (frame numbers increase by 1), got '2'", 5, 1),
    ("frame-number-repeat", HEAD + M34 + "\n1 5 -3\n\n" + M34 + "\n1 6 -2\n",
     "expected frame number 2 (frame numbers increase by 1), got '1'", 6, 1),
    ("too-few-values", HEAD + M34 + "\n0 5\n", "mask selects 2 values but the line has 1", 3, None),
    ("too-many-values", HEAD + M34 + "\n0 5 6 7\n", "mask selects 2 values but the line has 3",
     3, None),
    ("high-level-count", HEAD + mask_line(1, 2, 3) + "\n0 1 2 3 0 1 2 3 4 0 0\n",
     "mask selects 11 values but the line has 10", 3, None),
    ("value-word", HEAD + M34 + "\n0 5 abc\n", "expected a number, got 'abc'", 3, 5),
    ("value-nan", HEAD + M34 + "\n0 nan 1\n", "expected a number, got 'nan'", 3, 3),
    ("value-underscore", HEAD + M34 + "\n0 1_0 1\n", "expected a number, got '1_0'", 3, 3),
    ("value-unicode-digit", HEAD + M34 + "\n0 \u0661 1\n", "expected a number, got '\u0661'", 3, 3),
    ("value-nbsp", HEAD + M34 + "\n0 1\xa02 3\n", "expected a number, got '1\\xa02'", 3, 3),
    ("value-inf", HEAD + M34 + "\n0 1 -1e400\n", "expected a finite number, got '-1e400'", 3, 5),
    ("viseme-not-integer", HEAD + mask_line(1) + "\n0 1.5 2 3 0\n",
     "expected an integer for viseme_select1, got '1.5'", 3, 3),
    ("viseme-select-range", HEAD + mask_line(1) + "\n0 1 15 3 0\n",
     "viseme_select2 must be 0–14, got '15'", 3, 5),
    ("viseme-blend-range", HEAD + mask_line(1) + "\n0 1 2 64 0\n",
     "viseme_blend must be 0–63, got '64'", 3, 7),
    ("viseme-def-range", HEAD + mask_line(1) + "\n0 1 2 3 2\n", "viseme_def must be 0–1, got '2'",
     3, 9),
    ("expression-select-range", HEAD + mask_line(2) + "\n0 7 0 0 0 0 0\n",
     "expression_select1 must be 0–6, got '7'", 3, 3),
    ("expression-intensity-range", HEAD + mask_line(1, 2) + "\n0 0 0 0 0 1 -1 0 0 0 0\n",
     "expression_intensity1 must be 0–63, got '-1'", 3, 13),
    ("init-face-range", HEAD + mask_line(2) + "\n0 1 2 3 4 5 0\n", "init_face must be 0–1, got '5'",
     3, 11),
    ("expression-def-word", HEAD + mask_line(2) + "\n0 1 2 3 4 0 x\n",
     "expected an integer for expression_def, got 'x'", 3, 13),
]
# fmt: on


@pytest.mark.parametrize(
    ("text", "message", "line", "column"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_error(text: str, message: str, line: int, column: int | None) -> None:
    with pytest.raises(FapError) as e:
        parse_fap(text, file="bad.fap")
    err = e.value
    assert err.message == message
    assert (err.file, err.line, err.column) == ("bad.fap", line, column)
    where = f"bad.fap:{line}" + (f":{column}" if column else "")
    assert str(err).startswith(f"{where}: {message}")


def test_error_context_has_a_caret() -> None:
    with pytest.raises(FapError) as e:
        parse_fap(HEAD + M34 + "\n0 5 abc\n")
    assert e.value.context == "0 5 abc\n    ^"
    assert str(e.value).endswith("\n0 5 abc\n    ^")


def test_error_context_of_a_long_line_is_a_window() -> None:
    with pytest.raises(FapError) as e:
        parse_fap(HEAD + mask_line(3, bad={40: "7"}) + "\n0 1\n")
    text, caret = e.value.context.split("\n")  # type: ignore[union-attr]
    assert text.startswith("…") and text.endswith("…") and len(text) <= 102
    assert text[len(caret) - 1] == "7"


def test_default_file_name() -> None:
    with pytest.raises(FapError) as e:
        parse_fap("")
    assert e.value.file == "<text>"
