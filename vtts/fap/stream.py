"""FAP streams and the ``.fap`` text format.

A ``.fap`` file (the text format MPEG-4 face players such as Xface read; versions 2.0 and 2.1)::

    2.1 NAME FPS NFRAMES            header; NAME has no spaces (we read it liberally)
    # comment lines and blank lines may appear anywhere
    0 0 1 1 0 … (68 mask values)    per frame: which FAPs are present
    0 10 10 …                       the frame number, then the values of the masked FAPs in order;
                                    FAP 1 (viseme) takes 4 values, FAP 2 (expression) 6

A stream may also carry the head's translation (:attr:`FapStream.translation`), which is not a FAP
and has no place in a ``.fap`` file: writing one warns that it is left out (the ``.fbs``
bitstream of :mod:`vtts.fap.coding` carries it).

We read liberally (69 mask values, the first frame numbered 0, 1 or any n ≥ 0, a wrong NFRAMES,
comments, also after the data of a line, CRLF or CR line ends, tabs, values written as floats) and
write exactly: version 2.1, 68 mask values, integral values as integers and the others as ``repr``
floats, so that writing and reading back is lossless. Every problem in a file is a
:class:`~vtts.errors.FapError` with file, line and (where one token is at fault) column, saying
what was expected.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from vtts.atomic import write_text
from vtts.errors import FapError, VttsWarning
from vtts.fap.table import N_FAPS, positive_number
from vtts.limits import (
    MAX_DURATION_S,
    MAX_FAP_VALUE,
    MAX_FPS,
    MAX_FRAMES,
    MAX_TEXT_BYTES,
    MIN_FPS,
    read_bytes_capped,
)

#: The versions of the format we read; we always write the last one.
VERSIONS = ("2.0", "2.1")
WRITE_VERSION = "2.1"

#: The parameters FAP 1 carries, in file order, with their ranges (ISO/IEC 14496-2, 6.3.11).
VISEME_FIELDS: tuple[tuple[str, int, int], ...] = (
    ("viseme_select1", 0, 14),
    ("viseme_select2", 0, 14),
    ("viseme_blend", 0, 63),
    ("viseme_def", 0, 1),
)

#: The parameters FAP 2 carries, in file order, with their ranges.
EXPRESSION_FIELDS: tuple[tuple[str, int, int], ...] = (
    ("expression_select1", 0, 6),
    ("expression_intensity1", 0, 63),
    ("expression_select2", 0, 6),
    ("expression_intensity2", 0, 63),
    ("init_face", 0, 1),
    ("expression_def", 0, 1),
)

#: The axes of :attr:`FapStream.translation`, in column order (the names ``vtts analyze`` gives
#: the head translation's unknowns).
TRANSLATION_AXES = ("tx", "ty", "tz")

#: The largest head translation a stream may carry, in ES units (a thousand eye separations).
MAX_TRANSLATION = MAX_FAP_VALUE

#: A resampled stream longer than this is a mistake (an hour at 60 fps).
MAX_RESAMPLED_FRAMES = MAX_FRAMES

_N_VISEME = len(VISEME_FIELDS)
_N_EXPRESSION = len(EXPRESSION_FIELDS)

# Whitespace between tokens. Line breaks are normalized to "\n" first; Unicode spaces (NBSP, NEL)
# are not separators, so a stray one is reported as part of a bad token rather than guessed at.
_SPACE = " \t\f\v"
_TOKEN = re.compile(r"[^ \t\f\v]+")
_INTEGER = re.compile(r"[+-]?[0-9]+", re.ASCII)
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?", re.ASCII)
_HEADER_COMMENT = re.compile(r"[ \t\f\v]#")
_CONTEXT_WIDTH = 100


class FapWarning(VttsWarning):
    """A ``.fap`` file was read but something in it looked wrong (e.g. its frame count)."""


@dataclass(eq=False, repr=False)
class FapStream:
    """A sequence of FAP frames at a fixed frame rate.

    Attributes:
        fps: frames per second, finite and > 0.
        name: the stream's name (the header's NAME field); non-empty, one line, no leading or
            trailing blanks, no word starting with ``#`` (it would read as a comment).
        values: ``(n, 68) float64``, column k = FAP k+1 in its FAPU (AU for rotations). Columns 0
            and 1 (the high-level FAPs 1 and 2) are unused and must be zero: their parameters
            are in ``viseme`` and ``expression``.
        mask: ``(n, 68) bool``, which FAPs each frame sets. Values of FAPs a frame does not set
            are not part of the stream: they are stored as 0 (and the high-level rows as 0).
        viseme: ``(n, 4) int64`` FAP 1: viseme_select1, viseme_select2 (0–14), viseme_blend
            (0–63), viseme_def (0/1). ``None`` means all zero.
        expression: ``(n, 6) int64`` FAP 2: expression_select1 (0–6), expression_intensity1
            (0–63), expression_select2, expression_intensity2, init_face (0/1),
            expression_def (0/1). ``None`` means all zero.
        first_frame: the number of the first frame in the file (0 or 1 in practice), ≥ 0;
            always 0 for an empty stream.
        version: the format version the stream was read from (``"2.0"`` or ``"2.1"``);
            files are always written as 2.1.
        translation: ``(n, 3) float64`` or ``None``: the head's translation in each frame, in ES
            units (the model's eye separation ES0 / 1024, FAPU ``es``), along the model's axes
            (x to the viewer's right, y up, z towards the viewer), from where the model stands
            at rest. A
            player moves a model's root by ``translation * fapu.es`` model units
            (:func:`vtts.animate.fapstream.translated_root`). It is not a FAP: MPEG-4 moves a
            head with the scene's Transform, so a ``.fap`` file cannot carry it (writing one
            warns), the ``.fbs`` bitstream can. ``None``: the stream carries none (which a
            player treats as no motion). Finite, ``|t| ≤`` :data:`MAX_TRANSLATION`.
    """

    fps: float
    name: str
    values: np.ndarray
    mask: np.ndarray
    viseme: np.ndarray = None  # type: ignore[assignment]
    expression: np.ndarray = None  # type: ignore[assignment]
    first_frame: int = 0
    version: str = WRITE_VERSION
    translation: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.fps = _fps(self.fps)
        self.name = _check_name(self.name)
        if not isinstance(self.version, str) or self.version not in VERSIONS:
            raise FapError(f"version must be one of {', '.join(VERSIONS)}, got {self.version!r}")
        if (
            not isinstance(self.first_frame, int | np.integer)
            or isinstance(self.first_frame, bool)
            or self.first_frame < 0
        ):
            raise FapError(f"first_frame must be an integer ≥ 0, got {self.first_frame!r}")
        self.first_frame = int(self.first_frame)

        values = _array("values", self.values, np.float64)
        if values.ndim != 2 or values.shape[1] != N_FAPS:
            raise FapError(f"values must have shape (n, {N_FAPS}), got {values.shape}")
        n = values.shape[0]
        if n / self.fps > MAX_DURATION_S:
            raise FapError(
                f"{n} frames at {self.fps:g} fps last {n / self.fps:g} s, more than the limit of "
                f"{MAX_DURATION_S:g} s (vtts.limits)"
            )
        if not np.all(np.isfinite(values)):
            raise FapError("values must be finite")
        mask = _array("mask", self.mask, None)
        if mask.shape != (n, N_FAPS):
            raise FapError(f"mask must have shape ({n}, {N_FAPS}) like values, got {mask.shape}")
        if mask.dtype != np.bool_:
            if mask.dtype.kind not in "iuf" or not np.all((mask == 0) | (mask == 1)):
                raise FapError("mask must hold booleans (or 0 and 1)")
            mask = mask != 0
        if np.any(values[:, :2] != 0):
            raise FapError(
                "values columns 0 and 1 (FAPs 1 and 2) must be zero: "
                "the high-level FAPs go in viseme and expression"
            )
        values[~mask] = 0.0
        viseme = _int_array("viseme", self.viseme, n, VISEME_FIELDS)
        expression = _int_array("expression", self.expression, n, EXPRESSION_FIELDS)
        viseme[~mask[:, 0]] = 0
        expression[~mask[:, 1]] = 0
        _check_ranges("viseme", viseme, VISEME_FIELDS)
        _check_ranges("expression", expression, EXPRESSION_FIELDS)
        self.values, self.mask, self.viseme, self.expression = values, mask, viseme, expression
        self.translation = _translation(self.translation, n)
        if n == 0:
            self.first_frame = 0  # no frame carries a number: a file cannot tell it

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.values.shape[0])

    @property
    def duration(self) -> float:
        """Length in seconds: ``n_frames / fps`` (each frame lasts 1/fps)."""
        return self.n_frames / self.fps

    @property
    def times(self) -> np.ndarray:
        """``(n,) float64``: the time of each frame in seconds, the first at 0."""
        return np.arange(self.n_frames, dtype=np.float64) / self.fps

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FapStream):
            return NotImplemented
        return (
            self.fps == other.fps
            and self.name == other.name
            and self.first_frame == other.first_frame
            and self.version == other.version
            and np.array_equal(self.values, other.values)
            and np.array_equal(self.mask, other.mask)
            and np.array_equal(self.viseme, other.viseme)
            and np.array_equal(self.expression, other.expression)
            and (self.translation is None) == (other.translation is None)
            and (self.translation is None or np.array_equal(self.translation, other.translation))
        )

    __hash__ = None  # type: ignore[assignment]  # mutable arrays

    def __repr__(self) -> str:
        return (
            f"FapStream(name={self.name!r}, fps={self.fps!r}, n_frames={self.n_frames}, "
            f"first_frame={self.first_frame}, version={self.version!r}"
            f"{', translation' if self.translation is not None else ''})"
        )

    def resample(self, fps: float) -> FapStream:
        """The stream at another frame rate (e.g. a 25 fps file played at 30 fps).

        Output frame j is at time j / ``fps``; there are ``round(n_frames * fps / self.fps)``
        of them, so the duration stays as close as the new rate allows (times past the last
        input frame hold it). Low-level values are interpolated linearly between the two
        neighbouring input frames; a FAP is masked in an output frame only if it is masked in
        both (an output frame that falls on an input frame takes that frame as it is). The
        high-level FAPs 1 and 2 are table indices and cannot be interpolated: they, and their
        mask, come from the nearest input frame. The head translation, set in every frame, is
        interpolated like a low-level FAP.
        """
        fps = _fps(fps)
        n = self.n_frames
        frames = n * fps / self.fps
        if not frames < MAX_RESAMPLED_FRAMES:
            raise FapError(
                f"resampling {n} frames from {self.fps} to {fps} fps would make more than "
                f"{MAX_RESAMPLED_FRAMES} frames"
            )
        m = math.floor(frames + 0.5) if n else 0
        # Position of each output frame in input frames; snapping absorbs rounding so that
        # frames that coincide in time (every 5th at 25 -> 30 fps) are copied exactly.
        pos = np.arange(m, dtype=np.float64) * self.fps / fps
        snapped = np.round(pos)
        pos = np.where(np.abs(pos - snapped) < 1e-9, snapped, pos)
        pos = np.minimum(pos, max(n - 1, 0))
        i0 = np.floor(pos).astype(np.int64)
        w = pos - i0
        i1 = np.where(w > 0, np.minimum(i0 + 1, n - 1), i0)
        values = (1.0 - w)[:, None] * self.values[i0] + w[:, None] * self.values[i1]
        mask = self.mask[i0] & self.mask[i1]
        nearest = np.minimum(np.floor(pos + 0.5).astype(np.int64), max(n - 1, 0))
        mask[:, :2] = self.mask[nearest, :2]
        values[:, :2] = 0.0
        translation = None
        if self.translation is not None:
            t = self.translation
            translation = (1.0 - w)[:, None] * t[i0] + w[:, None] * t[i1]
        return FapStream(
            fps=fps,
            name=self.name,
            values=values,
            mask=mask,
            viseme=self.viseme[nearest],
            expression=self.expression[nearest],
            first_frame=self.first_frame,
            version=self.version,
            translation=translation,
        )


# --- validation helpers ----------------------------------------------------------------------


def _check_name(name: object) -> str:
    if not isinstance(name, str):
        raise FapError(f"name must be a string, got {name!r}")
    # These keep the header line parseable back to the same name.
    if (
        not name
        or "\n" in name
        or "\r" in name
        or name != name.strip(_SPACE)
        or name.startswith("#")
        or _HEADER_COMMENT.search(name)
    ):
        raise FapError(
            "name must be non-empty, on one line, without leading or trailing blanks and no "
            f"word starting with '#' (a comment in the header), got {name!r}"
        )
    return name


def _array(what: str, data: Any, dtype: Any) -> np.ndarray:
    try:
        return np.array(data, dtype=dtype, copy=True)
    except (TypeError, ValueError) as e:
        raise FapError(f"{what} must be a numeric array: {e}") from None


def _translation(data: Any, n: int) -> np.ndarray | None:
    if data is None:
        return None
    t = _array("translation", data, np.float64)
    if t.shape != (n, 3):
        raise FapError(f"translation must have shape ({n}, 3) like the frames, got {t.shape}")
    bad = ~(np.abs(t) <= MAX_TRANSLATION)  # also nan
    if np.any(bad):
        i, a = (int(x) for x in np.argwhere(bad)[0])
        raise FapError(
            f"translation[{i}, {a}] ({TRANSLATION_AXES[a]}) must be finite and within "
            f"±{MAX_TRANSLATION:g} ES units, got {t[i, a]!r}"
        )
    return t


def _int_array(
    what: str, data: Any, n: int, fields: tuple[tuple[str, int, int], ...]
) -> np.ndarray:
    shape = (n, len(fields))
    if data is None:
        return np.zeros(shape, dtype=np.int64)
    arr = _array(what, data, None)
    if arr.shape != shape:
        raise FapError(f"{what} must have shape {shape}, got {arr.shape}")
    if arr.dtype.kind in "biu":
        return arr.astype(np.int64)
    if arr.dtype.kind == "f" and np.all(np.isfinite(arr)) and np.all(arr == np.round(arr)):
        if np.all(np.abs(arr) < 2**62):
            return arr.astype(np.int64)
    raise FapError(f"{what} must hold integers")


def _check_ranges(what: str, arr: np.ndarray, fields: tuple[tuple[str, int, int], ...]) -> None:
    for k, (field, lo, hi) in enumerate(fields):
        bad = (arr[:, k] < lo) | (arr[:, k] > hi)
        if np.any(bad):
            i = int(np.argmax(bad))
            raise FapError(f"{what}[{i}, {k}] ({field}) must be {lo}–{hi}, got {arr[i, k]}")


# --- reading ---------------------------------------------------------------------------------


def read_fap(path: str | os.PathLike[str]) -> FapStream:
    """Read a ``.fap`` file (UTF-8, or Latin-1 if it is not valid UTF-8). See :func:`parse_fap`."""
    file = os.fspath(path)
    try:
        data = read_bytes_capped(file, MAX_TEXT_BYTES, what="FAP file")
    except OSError as e:
        raise FapError(f"cannot read FAP file: {e.strerror or e}", file=file) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    return parse_fap(text, file=file)


class _Line:
    """One meaningful line: its number, text and tokens with their 1-based columns."""

    __slots__ = ("number", "text", "tokens", "columns")

    def __init__(self, number: int, text: str, tokens: list[str], columns: list[int]) -> None:
        self.number = number
        self.text = text
        self.tokens = tokens
        self.columns = columns


class _Parser:
    def __init__(self, text: str, file: str) -> None:
        self.file = file
        text = text.removeprefix("\ufeff").replace("\r\n", "\n").replace("\r", "\n")
        self.raw_lines = text.split("\n")

    # errors ----------------------------------------------------------------------------------

    def error(self, message: str, line: _Line | int, token: int | None = None) -> FapError:
        if isinstance(line, int):
            return FapError(message, file=self.file, line=line)
        column = line.columns[token] if token is not None else None
        return FapError(
            message,
            file=self.file,
            line=line.number,
            column=column,
            context=_context(line.text, column) if column is not None else None,
        )

    # lines -----------------------------------------------------------------------------------

    def lines(self) -> list[_Line]:
        """The header and data lines, without comment and blank lines, and without trailing
        comments: in data lines from any ``#`` (never part of a number), in the header from a
        ``#`` that starts a word (a NAME may contain one, as in ``take#2``)."""
        out = []
        for number, text in enumerate(self.raw_lines, 1):
            stripped = text.lstrip(_SPACE)
            if not stripped or stripped.startswith("#"):
                continue
            if out:
                body = text.split("#", 1)[0]
            else:
                comment = _HEADER_COMMENT.search(text)
                body = text[: comment.start()] if comment else text
            matches = list(_TOKEN.finditer(body))
            if not matches:
                continue
            out.append(
                _Line(number, text, [m.group() for m in matches], [m.start() + 1 for m in matches])
            )
        return out

    # header ----------------------------------------------------------------------------------

    def header(self, line: _Line) -> tuple[str, str, float, int]:
        tokens = line.tokens
        if len(tokens) < 4:
            raise self.error(
                f"expected a header 'VERSION NAME FPS NFRAMES', got {len(tokens)} "
                f"token{'s' if len(tokens) != 1 else ''}",
                line,
            )
        version = tokens[0]
        if version not in VERSIONS:
            raise self.error(
                f"expected FAP file version {' or '.join(VERSIONS)}, got {version!r}", line, 0
            )
        start = line.columns[0] - 1 + len(tokens[0])
        end = line.columns[-2] - 1
        name = line.text[start:end].strip(_SPACE)
        fps_token = tokens[-2]
        fps = float(fps_token) if _NUMBER.fullmatch(fps_token) else math.nan
        if not (math.isfinite(fps) and fps > 0):
            raise self.error(
                f"expected the frame rate FPS as a positive number, got {fps_token!r}",
                line,
                len(tokens) - 2,
            )
        if not MIN_FPS <= fps <= MAX_FPS:
            raise self.error(
                f"frame rate {fps_token} is outside the limits {MIN_FPS:g}–{MAX_FPS:g} fps",
                line,
                len(tokens) - 2,
            )
        nframes = _integer(tokens[-1])
        if nframes is None or nframes < 0:
            raise self.error(
                f"expected the frame count NFRAMES as an integer ≥ 0, got {tokens[-1]!r}",
                line,
                len(tokens) - 1,
            )
        return version, name, fps, nframes

    # frames ----------------------------------------------------------------------------------

    def mask(self, line: _Line) -> list[bool]:
        tokens = line.tokens
        if len(tokens) not in (N_FAPS, N_FAPS + 1):
            raise self.error(f"expected {N_FAPS} mask values (0 or 1), got {len(tokens)}", line)
        for k, t in enumerate(tokens):
            if t != "0" and t != "1":
                raise self.error(f"expected a mask value 0 or 1, got {t!r}", line, k)
        # Some writers emit a 69th mask value; it selects nothing we know of.
        return [t == "1" for t in tokens[:N_FAPS]]

    def frame_number(self, line: _Line, expected: int | None) -> int:
        token = line.tokens[0]
        number = _integer(token)
        if number is None:
            raise self.error(f"expected a frame number (an integer), got {token!r}", line, 0)
        if expected is None:
            if number < 0:
                raise self.error(f"expected a frame number ≥ 0, got {token!r}", line, 0)
        elif number != expected:
            raise self.error(
                f"expected frame number {expected} (frame numbers increase by 1), got {token!r}",
                line,
                0,
            )
        return number

    def high_level(
        self, line: _Line, k: int, fields: tuple[tuple[str, int, int], ...]
    ) -> list[int]:
        out = []
        for j, (field, lo, hi) in enumerate(fields):
            token = line.tokens[k + j]
            value = _integer(token)
            if value is None:
                raise self.error(f"expected an integer for {field}, got {token!r}", line, k + j)
            if not lo <= value <= hi:
                raise self.error(f"{field} must be {lo}–{hi}, got {token!r}", line, k + j)
            out.append(value)
        return out

    def low_level(self, line: _Line, k: int) -> float:
        token = line.tokens[k]
        if not _NUMBER.fullmatch(token):
            raise self.error(f"expected a number, got {token!r}", line, k)
        value = float(token)
        if not math.isfinite(value):
            raise self.error(f"expected a finite number, got {token!r}", line, k)
        return value

    def parse(self) -> FapStream:
        lines = self.lines()
        if not lines:
            raise self.error(
                "expected a header 'VERSION NAME FPS NFRAMES', got an empty file",
                max(len(self.raw_lines), 1),
            )
        version, name, fps, nframes = self.header(lines[0])
        data = lines[1:]
        n = (len(data) + 1) // 2
        # Rows are collected in lists, not preallocated: a huge file of junk lines fails on its
        # first bad line without first allocating arrays for all of them.
        values: list[list[float]] = []
        mask: list[list[bool]] = []
        viseme: list[list[int]] = []
        expression: list[list[int]] = []
        first_frame = 0
        for i in range(n):
            mask_line = data[2 * i]
            row = self.mask(mask_line)
            if 2 * i + 1 >= len(data):
                raise self.error(
                    f"expected the value line of frame {first_frame + i} after this mask line, "
                    "got the end of the file",
                    mask_line,
                )
            line = data[2 * i + 1]
            number = self.frame_number(line, first_frame + i if i else None)
            if i == 0:
                first_frame = number
            selected = _N_VISEME * row[0] + _N_EXPRESSION * row[1] + sum(row[2:])
            if len(line.tokens) - 1 != selected:
                raise self.error(
                    f"mask selects {selected} values but the line has {len(line.tokens) - 1}",
                    line,
                )
            k = 1
            viseme.append([0] * _N_VISEME)
            expression.append([0] * _N_EXPRESSION)
            if row[0]:
                viseme[i] = self.high_level(line, k, VISEME_FIELDS)
                k += _N_VISEME
            if row[1]:
                expression[i] = self.high_level(line, k, EXPRESSION_FIELDS)
                k += _N_EXPRESSION
            frame = [0.0] * N_FAPS
            for f in range(2, N_FAPS):
                if row[f]:
                    frame[f] = self.low_level(line, k)
                    k += 1
            values.append(frame)
            mask.append(row)
        if n / fps > MAX_DURATION_S:
            raise self.error(
                f"{n} frames at {fps:g} fps last {n / fps:g} s, more than the limit of "
                f"{MAX_DURATION_S:g} s",
                lines[0],
            )
        if nframes != n:
            warnings.warn(
                FapWarning(
                    f"the header says {nframes} frames but the file has {n}; "
                    f"using the {n} frames present",
                    file=self.file,
                    line=lines[0].number,
                ),
                stacklevel=3,
            )
        return FapStream(
            fps=fps,
            name=name,
            values=np.array(values, dtype=np.float64).reshape(n, N_FAPS),
            mask=np.array(mask, dtype=bool).reshape(n, N_FAPS),
            viseme=np.array(viseme, dtype=np.int64).reshape(n, _N_VISEME),
            expression=np.array(expression, dtype=np.int64).reshape(n, _N_EXPRESSION),
            first_frame=first_frame,
            version=version,
        )


def parse_fap(text: str, file: str = "<text>") -> FapStream:
    """Parse the text of a ``.fap`` file; ``file`` names it in errors and warnings.

    Raises :class:`FapError` (with file, line and column) for anything that is not a FAP file;
    warns with :class:`FapWarning` when the header's NFRAMES disagrees with the frames present.
    """
    return _Parser(text, file).parse()


def _integer(token: str) -> int | None:
    """The integer a token writes (``"3"``, ``"-2"``, also ``"3.0"``), else None."""
    if _INTEGER.fullmatch(token):
        if len(token) > 100:  # beyond any meaningful count; int() of huge strings is slow
            return None
        return int(token)
    if _NUMBER.fullmatch(token):
        value = float(token)
        if math.isfinite(value) and value.is_integer():
            return int(value)
    return None


def _context(text: str, column: int) -> str:
    """The line (or a window of it around ``column``) with a caret under the column."""
    text = text.expandtabs(1)
    start = max(0, column - 1 - _CONTEXT_WIDTH // 2) if len(text) > _CONTEXT_WIDTH else 0
    prefix = "…" if start else ""
    window = text[start : start + _CONTEXT_WIDTH]
    suffix = "…" if start + _CONTEXT_WIDTH < len(text) else ""
    return f"{prefix}{window}{suffix}\n{' ' * (len(prefix) + column - 1 - start)}^"


# --- writing ---------------------------------------------------------------------------------


def _format_number(value: float) -> str:
    """Integral values as integers, others as ``repr`` (the shortest exact round trip)."""
    value = float(value)
    if value.is_integer() and abs(value) < 1e16:
        return str(int(value))
    return repr(value)


def format_fap(stream: FapStream) -> str:
    """The text of ``stream`` as a version 2.1 ``.fap`` file (68 mask values per frame).

    A ``.fap`` file has no place for :attr:`FapStream.translation`: a stream that carries one
    is written without it, with a :class:`FapWarning` saying so."""
    _warn_translation(stream, None)
    return _format(stream)


def _warn_translation(stream: FapStream, file: str | None) -> None:
    if stream.translation is not None:
        warnings.warn(
            FapWarning(
                "the stream's head translation is not written: a .fap file has no place for it "
                "(a .fbs bitstream keeps it)",
                file=file,
            ),
            stacklevel=3,
        )


def _format(stream: FapStream) -> str:
    out = [f"{WRITE_VERSION} {stream.name} {_format_number(stream.fps)} {stream.n_frames}\n"]
    for i in range(stream.n_frames):
        row = stream.mask[i]
        out.append(" ".join("1" if m else "0" for m in row))
        out.append("\n")
        items = [str(stream.first_frame + i)]
        if row[0]:
            items.extend(str(int(v)) for v in stream.viseme[i])
        if row[1]:
            items.extend(str(int(v)) for v in stream.expression[i])
        items.extend(_format_number(v) for v in stream.values[i, 2:][row[2:]])
        out.append(" ".join(items))
        out.append("\n")
    return "".join(out)


def write_fap(stream: FapStream, path: str | os.PathLike[str]) -> None:
    """Write ``stream`` to ``path`` as a version 2.1 ``.fap`` file (atomically); without its
    head translation, with a :class:`FapWarning` naming ``path`` (see :func:`format_fap`)."""
    _warn_translation(stream, os.fspath(path))
    write_text(path, _format(stream))


def _fps(fps: object) -> float:
    number = positive_number("fps", fps)
    if not MIN_FPS <= number <= MAX_FPS:
        raise FapError(f"fps {number:g} is outside the limits {MIN_FPS:g}–{MAX_FPS:g}")
    return number
