"""The 20 VRML97 field types: their Python/numpy values, parsing from tokens and writing back.

Values by type (one row of :data:`FIELD_TYPES` each):

============  ===================================================================
SFBool        ``bool``
SFInt32       ``int``
SFFloat       ``float``
SFTime        ``float`` (seconds)
SFString      ``str``
SFColor       ``(3,) float64``
SFVec2f       ``(2,) float64``
SFVec3f       ``(3,) float64``
SFRotation    ``(4,) float64`` (axis x, y, z, angle in radians)
SFImage       :class:`SFImage` (width, height, components, ``(w*h,) uint32`` pixels)
SFNode        :class:`~vtts.vrml.scene.Node` or ``None``
MFInt32       ``(n,) int32``
MFFloat       ``(n,) float64``
MFTime        ``(n,) float64``
MFColor       ``(n, 3) float64``
MFVec2f       ``(n, 2) float64``
MFVec3f       ``(n, 3) float64``
MFRotation    ``(n, 4) float64``
MFString      ``list[str]``
MFNode        ``list[Node]``
============  ===================================================================

Numeric arrays are made from the text in one numpy call, never a Python object per number.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class FieldType:
    """One VRML97 field type.

    ``width`` is the number of numbers per element of a numeric type (3 for SFVec3f/MFVec3f),
    ``kind`` one of ``"float" "int" "bool" "string" "node" "image"``.
    """

    name: str
    kind: str
    width: int = 1

    @property
    def multi(self) -> bool:
        """True for MF types."""
        return self.name.startswith("MF")

    @property
    def numeric(self) -> bool:
        return self.kind in ("float", "int")

    def describe(self) -> str:
        """A phrase for error messages: ``SFVec3f (3 numbers)``."""
        if self.kind in ("float", "int") and not self.multi:
            noun = "integer" if self.kind == "int" else "number"
            return f"{self.name} ({self.width} {noun}{'s' if self.width > 1 else ''})"
        return self.name


FIELD_TYPES: dict[str, FieldType] = {
    t.name: t
    for t in [
        FieldType("SFBool", "bool"),
        FieldType("SFInt32", "int"),
        FieldType("SFFloat", "float"),
        FieldType("SFTime", "float"),
        FieldType("SFString", "string"),
        FieldType("SFColor", "float", 3),
        FieldType("SFVec2f", "float", 2),
        FieldType("SFVec3f", "float", 3),
        FieldType("SFRotation", "float", 4),
        FieldType("SFImage", "image"),
        FieldType("SFNode", "node"),
        FieldType("MFInt32", "int"),
        FieldType("MFFloat", "float"),
        FieldType("MFTime", "float"),
        FieldType("MFColor", "float", 3),
        FieldType("MFVec2f", "float", 2),
        FieldType("MFVec3f", "float", 3),
        FieldType("MFRotation", "float", 4),
        FieldType("MFString", "string"),
        FieldType("MFNode", "node"),
    ]
}

INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1


@dataclass(frozen=True, eq=False)
class SFImage:
    """An uncompressed image value: ``pixels`` is ``(width*height,) uint32``, each pixel packing
    ``components`` bytes (1 grey, 2 grey+alpha, 3 RGB, 4 RGBA), bottom row first."""

    width: int
    height: int
    components: int
    pixels: np.ndarray

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, SFImage)
            and (self.width, self.height, self.components)
            == (other.width, other.height, other.components)
            and np.array_equal(self.pixels, other.pixels)
        )

    def __hash__(self) -> int:
        return hash((self.width, self.height, self.components, self.pixels.tobytes()))

    def to_rgba(self) -> np.ndarray:
        """``(height, width, 4) uint8`` with the top row first (image convention)."""
        p = self.pixels.astype(np.uint32).reshape(self.height, self.width)[::-1]
        c = self.components
        shifts = [8 * (c - 1 - k) for k in range(c)]
        chans = [((p >> s) & 0xFF).astype(np.uint8) for s in shifts]
        if c == 1:
            chans = [chans[0], chans[0], chans[0], np.full_like(chans[0], 255)]
        elif c == 2:
            chans = [chans[0], chans[0], chans[0], chans[1]]
        elif c == 3:
            chans = chans + [np.full_like(chans[0], 255)]
        return np.stack(chans, axis=-1)


class NumberError(ValueError):
    """A word in a run of numbers is not a number of the required kind; ``offset`` is the word's
    position in the run's text."""

    def __init__(self, word: str, offset: int, expected: str) -> None:
        super().__init__(f"{word!r} is not {expected}")
        self.word = word
        self.offset = offset
        self.expected = expected


_WORD = re.compile(r"[^\s,]+")


def _words(text: str) -> list[str]:
    # str.split() is three times faster than a regex split on large runs
    return text.replace(",", " ").split() or [""]


_FLOAT_WORD = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\Z")
_INT_WORD = re.compile(r"[+-]?(?:0[xX][0-9a-fA-F]+|[0-9]+)\Z")


def _int_value(word: str) -> int:
    """The value of a decimal or hexadecimal integer word (``int(w, 0)`` refuses ``010``)."""
    sign = -1 if word.startswith("-") else 1
    digits = word.lstrip("+-")
    if len(digits) > 64:  # far beyond any VRML integer; Python refuses >4300 digits anyway
        raise OverflowError(word)
    if digits[:2] in ("0x", "0X"):
        return sign * int(digits[2:], 16)
    return sign * int(digits, 10)


def parse_floats(text: str) -> np.ndarray:
    """All numbers of a run (``"0 0 1, 1 0 0"``) as a ``(n,) float64`` array.

    Hexadecimal integers are accepted (VRML allows them wherever an integer is, and an integer is
    a valid float). Raises :class:`NumberError` at the first word that is not a number.
    """
    words = _words(text)
    if words == [""]:
        return np.zeros(0)
    try:
        arr = np.array(words, dtype=np.float64)
    except ValueError:
        arr = None
    if arr is None or not np.isfinite(arr).all():
        # numpy refused a word (or accepted 'inf'/'nan', which the lexer never produces but a
        # caller might pass): find the culprit, allowing hexadecimal integers.
        out = []
        for m in _WORD.finditer(text):
            w = m.group()
            if _FLOAT_WORD.match(w):
                out.append(float(w))
            elif _INT_WORD.match(w):
                try:
                    out.append(float(_int_value(w)))
                except (OverflowError, ValueError):
                    raise NumberError(w, m.start(), "a finite number") from None
            else:
                raise NumberError(w, m.start(), "a number")
        arr = np.array(out, dtype=np.float64)
        if not np.isfinite(arr).all():
            bad = int(np.argmin(np.isfinite(arr)))
            m = list(_WORD.finditer(text))[bad]
            raise NumberError(m.group(), m.start(), "a finite number")
    return arr


#: Bytes a run of plain decimal integers holds: digits, signs, and the separators of _words.
_INT_BYTES = np.zeros(256, dtype=bool)
_INT_BYTES[list(b"0123456789+- \t\n\r,")] = True
_SEPARATOR_BYTES = np.zeros(256, dtype=bool)
_SEPARATOR_BYTES[list(b" \t\n\r,")] = True
_DIGIT_BYTES = np.zeros(256, dtype=bool)
_DIGIT_BYTES[list(b"0123456789")] = True
#: Below this many characters the word list is as fast, and simpler.
_FAST_INTS_MIN = 4096


def _plain_decimal_ints(text: str) -> np.ndarray | None:
    """The integers of a long run that is nothing but decimal integers (digits, each optionally
    after one leading sign) and separators, read by numpy's C parser without a Python string per
    word (a large coordIndex is most of a mesh file's words); None for anything else (a short or
    empty run, hexadecimal, a stray word), which the word-by-word path reads or names.

    Values beyond int64 come back clamped, so the caller's range check still finds them."""
    if len(text) < _FAST_INTS_MIN or not text.isascii():
        return None
    b = np.frombuffer(text.encode("ascii"), dtype=np.uint8)
    if not _INT_BYTES[b].all():
        return None
    sep = _SEPARATOR_BYTES[b]
    digit = _DIGIT_BYTES[b]
    sign = ~sep & ~digit
    if sign.any():
        # a sign starts its word and is followed by a digit ("5-3", "+-1", "-" are not integers)
        at = np.flatnonzero(sign)
        before_ok = (at == 0) | sep[np.maximum(at - 1, 0)]
        after_ok = (at + 1 < b.size) & digit[np.minimum(at + 1, b.size - 1)]
        if not (before_ok & after_ok).all():
            return None
    starts = int(np.count_nonzero(~sep[1:] & sep[:-1])) + (0 if sep[0] else 1)
    if starts == 0:
        return None
    try:
        with warnings.catch_warnings():
            # numpy before 2.3 warns and stops at unmatched text instead of raising
            warnings.simplefilter("error", DeprecationWarning)
            arr = np.fromstring(text.replace(",", " "), dtype=np.int64, sep=" ")
    except (ValueError, DeprecationWarning):
        return None
    # one number per word: numpy would also read "12" "34" out of a word it splits itself
    return arr if arr.size == starts else None


def parse_ints(text: str, *, lo: int = INT32_MIN, hi: int = INT32_MAX) -> np.ndarray:
    """All integers of a run as a ``(n,) int64`` array, each in ``[lo, hi]``.

    Decimal and hexadecimal (``0xFF``) integers; raises :class:`NumberError` at the first word that
    is not an integer or is out of range.
    """
    arr = _plain_decimal_ints(text)
    if arr is None:
        arr = _ints_by_word(text, lo, hi)
    if arr.size and (arr.min() < lo or arr.max() > hi):
        bad = int(np.argmax((arr < lo) | (arr > hi)))
        m = list(_WORD.finditer(text))[bad]
        raise NumberError(m.group(), m.start(), f"an integer in [{lo}, {hi}]")
    return arr


def _ints_by_word(text: str, lo: int, hi: int) -> np.ndarray:
    """:func:`parse_ints` for any run: numpy from the word list, else word by word (hexadecimal,
    or naming the first word that is not an integer)."""
    words = _words(text)
    if words == [""]:
        return np.zeros(0, dtype=np.int64)
    try:
        arr = np.array(words, dtype=np.int64)
    except (ValueError, OverflowError):
        out = []
        for m in _WORD.finditer(text):
            w = m.group()
            if not _INT_WORD.match(w):
                raise NumberError(w, m.start(), "an integer") from None
            try:
                v = _int_value(w)
            except (OverflowError, ValueError):
                raise NumberError(w, m.start(), f"an integer in [{lo}, {hi}]") from None
            if not lo <= v <= hi:
                raise NumberError(w, m.start(), f"an integer in [{lo}, {hi}]") from None
            out.append(v)
        arr = np.array(out, dtype=np.int64)
    return arr


_UNESCAPE = re.compile(r"\\(.)", re.S)


def unescape_string(token: str) -> str:
    """The value of a quoted VRML string token: drop the quotes, ``\\"`` → ``"``, ``\\\\`` → ``\\``.

    Any other backslash pair stands for the character after the backslash (as the spec says)."""
    return _UNESCAPE.sub(r"\1", token[1:-1])


def escape_string(value: str) -> str:
    """A quoted VRML string token for ``value``."""
    return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'


# ---- writing ------------------------------------------------------------------------------------


def format_number(x: float) -> str:
    """Shortest text that reads back to exactly ``x`` (``1`` for 1.0)."""
    if x == 0 and math.copysign(1.0, x) < 0:
        return "-0"
    if x == int(x) and abs(x) < 1e15:
        return str(int(x))
    return repr(float(x))


#: A float's text ending in ".0" (before an exponent, a space or the end), trimmed to the integer.
_POINT_ZERO = re.compile(r"\.0(?=e|\s|$)")


def _seven_digits(a: np.ndarray) -> bool:
    """Whether every number of the float64 array ``a`` is one of at most 7 significant digits
    (the double nearest to ``m * 10**-d``, ``m`` an integer below 10**7, ``d`` 0 … 22, so that
    the division that makes it here is exact and correctly rounded) and below 10**6 in size, or
    zero. For those ``"%.7g" % x`` is exactly the text ``repr(x)`` gives with a trailing
    ``.0`` trimmed: the 7-digit rounding of ``x`` is ``m * 10**-d`` (``x`` lies within half
    an ulp of it), no shorter decimal lies within half an ulp, and both write an exponent from
    10**-5 down and none above."""
    mag = np.abs(a)
    nonzero = mag != 0
    if not np.all(mag[nonzero] < 1e6) or not np.all(mag[nonzero] >= 1e-16):
        return False  # also False for NaN and infinity
    digits = 6 - np.floor(np.log10(mag[nonzero]))
    scale = 10.0**digits
    return bool(np.array_equal(np.round(a[nonzero] * scale) / scale, a[nonzero]))


def format_numbers(arr: np.ndarray, per_line: int = 1) -> list[str]:
    """One line of text per row of ``arr`` (``(n, k)`` or ``(n,)``), numbers exact.

    ``per_line`` groups scalar arrays (MFInt32 faces, MFFloat) several to a line.
    """
    a = np.asarray(arr)
    if a.ndim == 1:
        a = a.reshape(-1, per_line) if a.size % per_line == 0 else a.reshape(-1, 1)
    if a.dtype.kind in "iu":
        text = a.astype(str)
    elif a.dtype == np.float64:
        # Python's repr is the same shortest round-trip text as numpy's str, at half the time;
        # one %-format per row and one trim over all rows take a third less than a join and a
        # trim per row
        if not a.shape[0]:
            return []
        if _seven_digits(a):
            # "%.7g" is repr's own text for such numbers (see _seven_digits), at a third of its
            # time: a fitted head's tables are rounded to 7 digits
            row_format = " ".join(["%.7g"] * a.shape[1])
            return [row_format % tuple(row) for row in a.tolist()]
        row_format = " ".join(["%r"] * a.shape[1])
        text = "\n".join([row_format % tuple(row) for row in a.tolist()])
        return _POINT_ZERO.sub("", text).split("\n")
    else:
        # numpy's str of a float is its type's shortest round-trip text; trim "1.0" to "1".
        text = a.astype(str)
        text = np.char.replace(text, ".0e", "e")
        ends = np.char.endswith(text, ".0")
        if ends.any():
            text[ends] = np.char.rstrip(np.char.rstrip(text[ends], "0"), ".")
    return [" ".join(row) for row in text.tolist()]


def equal_values(a: Any, b: Any) -> bool:
    """Exact equality of two field values of the same type (numpy arrays compared elementwise).

    Node values are compared by :func:`vtts.vrml.scene.same_node`, not here."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a_arr, b_arr = np.asarray(a), np.asarray(b)
        return a_arr.shape == b_arr.shape and bool(np.array_equal(a_arr, b_arr))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b
