"""MIAPs (model-independent animation parameters) and the parameter vector a model is posed with.

A MIAP is one of the 66 low-level FAPs (3–68), one of the 14 visemes, or one of the 6 expressions:
each has its own Animation Definition Table in a personalized model.

The parameter vector (``(N_PARAMS,) float64``) puts them side by side:

=====================  =========================================================
``params[k - 1]``      FAP k (3–68), in FAP units (FAPU or AU); entries 0 and 1 unused
``params[68 + v]``     weight of viseme v (0–14), 0 = none, 1 = full
``params[83 + e]``     weight of expression e (0–6), 0 = none, 1 = full
=====================  =========================================================
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from vtts.errors import FapError
from vtts.fap import EXPRESSIONS, N_FAPS, VISEMES, expression, fap, viseme

VISEME_BASE = N_FAPS
EXPRESSION_BASE = N_FAPS + 15
N_PARAMS = EXPRESSION_BASE + 7

KINDS = ("fap", "viseme", "expression")

# A FAP number as users write it; more digits than any number needs fall through to fap(), which
# refuses them (int() would fail beyond 4,300 digits)
_SIGNED = re.compile(r"[+-]?[0-9]{1,18}")


@dataclass(frozen=True, order=True)
class Miap:
    """A MIAP: ``kind`` is ``"fap"`` (number 3–68), ``"viseme"`` (1–14) or ``"expression"``
    (1–6)."""

    kind: str
    number: int

    def __post_init__(self) -> None:
        lo, hi = {"fap": (3, N_FAPS), "viseme": (1, 14), "expression": (1, 6)}[self.kind]
        if not lo <= self.number <= hi:
            raise FapError(f"{self.kind} MIAP number must be {lo}–{hi}, got {self.number}")

    @property
    def index(self) -> int:
        """Position in the parameter vector."""
        if self.kind == "fap":
            return self.number - 1
        if self.kind == "viseme":
            return VISEME_BASE + self.number
        return EXPRESSION_BASE + self.number

    @property
    def name(self) -> str:
        """``close_t_l_eyelid``, ``viseme 3 (T, D)`` style short name: the FAP name, the viseme's
        phonemes, or the expression name."""
        if self.kind == "fap":
            return fap(self.number).name
        if self.kind == "viseme":
            return VISEMES[self.number].label
        return EXPRESSIONS[self.number].name

    @property
    def key(self) -> str:
        """How ``.adt`` files write it after ``MIAP``: ``19``, ``viseme 3``, ``expression 1``."""
        return str(self.number) if self.kind == "fap" else f"{self.kind} {self.number}"

    def __str__(self) -> str:
        return f"{self.key} ({self.name})"

    @classmethod
    def parse(cls, text: str | int) -> Miap:
        """A MIAP from user text: ``19``, ``close_t_l_eyelid``, ``viseme 3``, ``viseme3``,
        ``expression joy``, ``joy``, ``smile`` (alias of joy)."""
        if isinstance(text, int):
            return cls("fap", fap(text).number) if text > 2 else cls._bad(str(text))
        t = text.strip().lower()
        # "viseme 3", "viseme_3", "viseme3", "viseme-3"; but "viseme -1" is viseme -1, not 1
        m = re.fullmatch(r"(viseme|expression)(?:[\s_]+|-(?=\w))?(-?\w+)", t)
        if m:
            # viseme() and expression() take a number as its digits (ASCII only: '²' is no number)
            kind, key = m.groups()
            if kind == "viseme":
                return cls("viseme", viseme(key).number)
            return cls("expression", expression(_alias(key)).number)
        if _SIGNED.fullmatch(t):
            n = int(t)
            return cls("fap", fap(n).number) if n > 2 else cls._bad(text)
        if _alias(t) in {e.name for e in EXPRESSIONS.values()}:
            return cls("expression", expression(_alias(t)).number)
        return cls("fap", fap(t).number) if fap(t).number > 2 else cls._bad(text)

    @staticmethod
    def _bad(text: str) -> Miap:
        raise FapError(
            f"'{text}' is not a MIAP: FAPs 1 and 2 are carried by the viseme and expression "
            "MIAPs (write 'viseme N' or an expression name)"
        )


#: Other names people use for the six expressions.
EXPRESSION_ALIASES = {
    "smile": "joy",
    "happy": "joy",
    "happiness": "joy",
    "sad": "sadness",
    "angry": "anger",
    "afraid": "fear",
    "scared": "fear",
    "disgusted": "disgust",
    "surprised": "surprise",
}


def _alias(name: str) -> str:
    return EXPRESSION_ALIASES.get(name, name)


def face_params(
    faps: Mapping[int | str, float] | None = None,
    visemes: Mapping[int | str, float] | None = None,
    expressions: Mapping[int | str, float] | None = None,
) -> np.ndarray:
    """A ``(N_PARAMS,) float64`` parameter vector from readable pieces.

    ``faps`` maps FAP numbers or names to values in FAP units; ``visemes`` and ``expressions`` map
    numbers or names to weights (0–1)::

        face_params({19: 512, "open_jaw": 300}, visemes={7: 1}, expressions={"joy": 0.8})
    """
    p = np.zeros(N_PARAMS)
    for k, v in (faps or {}).items():
        p[Miap.parse(k if isinstance(k, str) else int(k)).index] = float(v)
    for k, v in (visemes or {}).items():
        p[Miap.parse(f"viseme {k}").index] = float(v)
    for k, v in (expressions or {}).items():
        p[Miap.parse(f"expression {k}").index] = float(v)
    return p


def all_miaps() -> list[Miap]:
    """Every MIAP in parameter-vector order."""
    return (
        [Miap("fap", n) for n in range(3, N_FAPS + 1)]
        + [Miap("viseme", v) for v in range(1, 15)]
        + [Miap("expression", e) for e in range(1, 7)]
    )
