"""The MPEG-4 tables: the 68 FAPs, the 15 visemes and the 6 primary expressions.

Loaded once from the package data (``vtts/data/faps.tsv``, ``visemes.tsv``, ``expressions.tsv``,
ISO/IEC 14496-2; see ``vtts/data/README.md`` for the sources). Each table row is a small frozen
dataclass; lookups accept a number or a name and raise :class:`~vtts.errors.FapError` naming the
value and the valid range otherwise.
"""

from __future__ import annotations

import csv
import math
import numbers
import re
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from vtts.errors import FapError
from vtts.resources import package_data

#: Number of FAPs (2 high-level + 66 low-level).
N_FAPS = 68

#: FAPUs used by the low-level FAPs; ``AU`` is the angle unit (1e-5 rad).
FAPU_NAMES = ("IRISD", "ES", "ENS", "MNS", "MW", "AU")


@dataclass(frozen=True)
class FapDef:
    """One row of the FAP table (ISO/IEC 14496-2, Table C-1).

    ``fapu`` is one of :data:`FAPU_NAMES`, or ``None`` for the high-level FAPs 1 (viseme) and
    2 (expression), which carry table indices rather than displacements. ``bidirectional`` tells
    whether negative values are meaningful; ``positive_motion`` is the direction a positive value
    moves the feature point (``"down"``, ``"left"``, …); ``fdp_group``/``fdp_index`` name the
    feature point it moves (``2.1`` = chin); ``quant_step`` is the default quantization step of the
    FAP coder.
    """

    number: int
    name: str
    fapu: str | None
    bidirectional: bool
    positive_motion: str
    fdp_group: int
    fdp_index: int
    quant_step: int

    @property
    def feature_point(self) -> str:
        """The feature point as MPEG-4 writes it, e.g. ``"2.1"``."""
        return f"{self.fdp_group}.{self.fdp_index}"

    @property
    def high_level(self) -> bool:
        """True for FAPs 1 (viseme) and 2 (expression)."""
        return self.fapu is None


@dataclass(frozen=True)
class Viseme:
    """A viseme (ISO/IEC 14496-2, Table C-3): the mouth shape shared by some phonemes.

    ``label`` is the table's phoneme text (``"p, b, m"``, ``"none"`` for viseme 0),
    ``phonemes`` the phonemes in it (empty for viseme 0) and ``example`` the example words.
    """

    number: int
    label: str
    phonemes: tuple[str, ...]
    example: str


@dataclass(frozen=True)
class Expression:
    """A primary expression (ISO/IEC 14496-2, Table C-4), e.g. 1 = ``"joy"``."""

    number: int
    name: str


def _rows(name: str) -> list[dict[str, str]]:
    with package_data(name).open(encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f, delimiter="\t"))


def _load_faps() -> tuple[FapDef, ...]:
    faps = []
    for row in _rows("faps.tsv"):
        fapu = row["fapu"]
        faps.append(
            FapDef(
                number=int(row["fap"]),
                name=row["name"],
                fapu=None if fapu == "-" else fapu,
                bidirectional=row["direction_kind"] == "bidirectional",
                positive_motion=row["positive_motion"],
                fdp_group=int(row["fdp_group"]),
                fdp_index=int(row["fdp_index"]),
                quant_step=int(row["quant_step"]),
            )
        )
    # The rest of the package indexes FAPS by number - 1: a damaged data file must fail here.
    if [f.number for f in faps] != list(range(1, N_FAPS + 1)):
        raise FapError("vtts/data/faps.tsv must list FAPs 1 to 68 in order")
    return tuple(faps)


def _load_visemes() -> Mapping[int, Viseme]:
    visemes = {}
    for row in _rows("visemes.tsv"):
        number = int(row["viseme"])
        label = row["phonemes"]
        phonemes = () if label == "none" else tuple(p.strip() for p in label.split(","))
        visemes[number] = Viseme(number, label, phonemes, row["example"])
    return MappingProxyType(visemes)


def _load_expressions() -> Mapping[int, Expression]:
    return MappingProxyType(
        {
            int(r["expression"]): Expression(int(r["expression"]), r["name"])
            for r in _rows("expressions.tsv")
        }
    )


#: The 68 FAPs; ``FAPS[k]`` is FAP ``k + 1``.
FAPS: tuple[FapDef, ...] = _load_faps()

#: Visemes by number, 0 (neutral / silence) to 14.
VISEMES: Mapping[int, Viseme] = _load_visemes()

#: Primary expressions by number, 1 (joy) to 6 (surprise).
EXPRESSIONS: Mapping[int, Expression] = _load_expressions()

_FAP_BY_NAME = {f.name.lower(): f for f in FAPS}
_VISEME_BY_TEXT = {v.label: v for v in VISEMES.values()} | {
    p: v for v in VISEMES.values() for p in v.phonemes
}
_EXPRESSION_BY_NAME = {e.name.lower(): e for e in EXPRESSIONS.values()}


def positive_number(what: str, value: object) -> float:
    """``value`` as a finite float > 0, or a :class:`FapError` naming ``what`` and the value."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise FapError(f"{what} must be a number, got {value!r}") from None
    if not (math.isfinite(number) and number > 0):
        raise FapError(f"{what} must be finite and > 0, got {value!r}")
    return number


def _as_number(key: object) -> int | None:
    """``key`` as an int if it is an integer (not a bool) or a string of at most 18 ASCII
    digits, else None (no table number has more, and int() refuses over 4,300 digits)."""
    if isinstance(key, numbers.Integral) and not isinstance(key, bool):
        return int(key)
    if isinstance(key, str) and re.fullmatch(r"[0-9]{1,18}", key.strip()):
        return int(key.strip())
    return None


def fap(key: int | str) -> FapDef:
    """The FAP with number ``key`` (1–68) or name ``key`` (case-insensitive, ``"open_jaw"``)."""
    number = _as_number(key)
    if number is not None:
        if 1 <= number <= N_FAPS:
            return FAPS[number - 1]
    elif isinstance(key, str) and key.strip().lower() in _FAP_BY_NAME:
        return _FAP_BY_NAME[key.strip().lower()]
    raise FapError(
        f"unknown FAP {key!r}: expected a FAP number 1–{N_FAPS} or a FAP name such as 'open_jaw'"
    )


def viseme(key: int | str) -> Viseme:
    """The viseme with number ``key`` (0–14), or the viseme of a phoneme of the table.

    A string is a phoneme of the table (``"p"``, ``"tS"``, ``"A:"``: case matters, ``"T"`` and
    ``"t"`` are different visemes) or a whole label (``"p, b, m"``, ``"none"``).
    """
    number = _as_number(key)
    if number is not None:
        if number in VISEMES:
            return VISEMES[number]
    elif isinstance(key, str) and key.strip() in _VISEME_BY_TEXT:
        return _VISEME_BY_TEXT[key.strip()]
    raise FapError(
        f"unknown viseme {key!r}: expected a viseme number 0–{max(VISEMES)} "
        "or a phoneme of the viseme table such as 'p'"
    )


def expression(key: int | str) -> Expression:
    """The primary expression with number ``key`` (1–6) or name ``key`` (case-insensitive)."""
    number = _as_number(key)
    if number is not None:
        if number in EXPRESSIONS:
            return EXPRESSIONS[number]
    elif isinstance(key, str) and key.strip().lower() in _EXPRESSION_BY_NAME:
        return _EXPRESSION_BY_NAME[key.strip().lower()]
    names = ", ".join(e.name for e in EXPRESSIONS.values())
    raise FapError(
        f"unknown expression {key!r}: expected an expression number "
        f"{min(EXPRESSIONS)}–{max(EXPRESSIONS)} or one of {names}"
    )
