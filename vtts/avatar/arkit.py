"""ARKit blendshapes, Oculus visemes and the recipe table that ties them to MPEG-4.

Names
-----
:data:`ARKIT_NAMES` are Apple's 52 blendshape locations (``ARFaceAnchor.BlendShapeLocation``)
spelled and ordered as Apple's documentation lists them: left eye, right eye, mouth and jaw,
eyebrows, cheeks, nose, tongue. *Left* and *right* are the face's own sides (Apple: a closed right
eye is reported as ``eyeBlinkRight``), as in MPEG-4's ``_l_``/``_r_`` FAPs.

:data:`OCULUS_VISEMES` are the 15 morph targets of Oculus (Meta) LipSync avatars, ``viseme_sil``
to ``viseme_U``. Their order is MPEG-4's viseme order (ISO/IEC 14496-2 Table C-3): Oculus viseme
``i`` is MPEG-4 viseme ``i`` (:func:`oculus_viseme`, :func:`mpeg4_viseme`).

The recipe table
----------------
``vtts/data/arkit_recipes.tsv`` (:func:`recipes`) describes every MIAP that ARKit can show as a
weighted sum of ARKit shapes: a row ``fap 3 + 1000 jawOpen=1`` says that open_jaw at +1000 MNS
looks like ``jawOpen`` at 1.0. Bidirectional FAPs have a row per direction (``fap 12 +``:
mouthSmileLeft, ``fap 12 -``: mouthFrownLeft); visemes 0–14 and expressions 1–6 have one row each
at weight 1. Where several FAPs together make one ARKit motion (the whole upper lip raised is
FAPs 4, 8, 9, 51, 55 and 56 together), each row carries its share of the shape, so that all of
them at their amplitudes add up to a weight of 1.

Read forwards (:meth:`Recipe.per_unit`) the table turns ARKit targets into Animation Definition
Tables; read backwards (:meth:`RecipeTable.fap_content`) it gives the FAPs each ARKit shape moves,
which the curves export inverts by least squares.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cache
from types import MappingProxyType

import numpy as np

from vtts.errors import AvatarError
from vtts.fap import N_FAPS, fap
from vtts.resources import package_data

#: Apple's 52 ARKit blendshape names, in the order of Apple's documentation.
ARKIT_NAMES: tuple[str, ...] = (
    # left eye
    "eyeBlinkLeft", "eyeLookDownLeft", "eyeLookInLeft", "eyeLookOutLeft", "eyeLookUpLeft",
    "eyeSquintLeft", "eyeWideLeft",
    # right eye
    "eyeBlinkRight", "eyeLookDownRight", "eyeLookInRight", "eyeLookOutRight", "eyeLookUpRight",
    "eyeSquintRight", "eyeWideRight",
    # mouth and jaw
    "jawForward", "jawLeft", "jawRight", "jawOpen", "mouthClose", "mouthFunnel", "mouthPucker",
    "mouthLeft", "mouthRight", "mouthSmileLeft", "mouthSmileRight", "mouthFrownLeft",
    "mouthFrownRight", "mouthDimpleLeft", "mouthDimpleRight", "mouthStretchLeft",
    "mouthStretchRight", "mouthRollLower", "mouthRollUpper", "mouthShrugLower", "mouthShrugUpper",
    "mouthPressLeft", "mouthPressRight", "mouthLowerDownLeft", "mouthLowerDownRight",
    "mouthUpperUpLeft", "mouthUpperUpRight",
    # eyebrows
    "browDownLeft", "browDownRight", "browInnerUp", "browOuterUpLeft", "browOuterUpRight",
    # cheeks
    "cheekPuff", "cheekSquintLeft", "cheekSquintRight",
    # nose
    "noseSneerLeft", "noseSneerRight",
    # tongue
    "tongueOut",
)  # fmt: skip

#: Index of each ARKit name in :data:`ARKIT_NAMES`.
ARKIT_INDEX: Mapping[str, int] = MappingProxyType({n: i for i, n in enumerate(ARKIT_NAMES)})

#: The 15 Oculus (Meta) LipSync viseme targets; position i is MPEG-4 viseme i.
OCULUS_VISEMES: tuple[str, ...] = tuple(
    f"viseme_{v}"
    for v in ("sil", "PP", "FF", "TH", "DD", "kk", "CH", "SS", "nn", "RR", "aa", "E", "I", "O", "U")
)

_OCULUS_BY_KEY = {name.lower(): i for i, name in enumerate(OCULUS_VISEMES)} | {
    name.removeprefix("viseme_").lower(): i for i, name in enumerate(OCULUS_VISEMES)
}

KINDS = ("fap", "viseme", "expression")
_SIGNS = {"+": 1, "-": -1}
_COLUMNS = ("kind", "number", "sign", "amplitude", "shapes", "note")


def oculus_viseme(viseme: int) -> str:
    """The Oculus viseme target of MPEG-4 viseme ``viseme`` (0–14): 1 → ``"viseme_PP"``."""
    if isinstance(viseme, bool) or not isinstance(viseme, int) or not 0 <= viseme <= 14:
        raise AvatarError(f"MPEG-4 visemes are 0–14, got {viseme!r}")
    return OCULUS_VISEMES[viseme]


def mpeg4_viseme(name: str) -> int:
    """The MPEG-4 viseme (0–14) of an Oculus viseme, with or without its prefix and in any case:
    ``"viseme_PP"``, ``"PP"``, ``"pp"`` → 1."""
    key = name.strip().lower() if isinstance(name, str) else None
    if key not in _OCULUS_BY_KEY:
        names = ", ".join(OCULUS_VISEMES)
        raise AvatarError(f"unknown Oculus viseme {name!r}: expected one of {names}")
    return _OCULUS_BY_KEY[key]


@dataclass(frozen=True)
class Recipe:
    """One row of the recipe table: a MIAP in one direction as ARKit shapes.

    ``kind``/``number``: ``"fap"`` 3–68, ``"viseme"`` 0–14 or ``"expression"`` 1–6; ``sign``: +1 or
    −1, the direction of the FAP value the row describes (+1 for visemes and expressions);
    ``amplitude``: the value (> 0, FAP units of that FAP, or a weight of 1 for visemes and
    expressions) at which the MIAP looks like ``shapes`` (ARKit name → weight, 0 < weight ≤ 1);
    ``note``: the table's comment.
    """

    kind: str
    number: int
    sign: int
    amplitude: float
    shapes: Mapping[str, float]
    note: str = ""

    @property
    def value(self) -> float:
        """The signed MIAP value the row describes: ``sign · amplitude``."""
        return self.sign * self.amplitude

    def per_unit(self) -> dict[str, float]:
        """ARKit weight per unit of the MIAP value in the row's direction (``shapes /
        amplitude``): what one FAP unit (or a viseme/expression weight of 1) adds."""
        return {name: w / self.amplitude for name, w in self.shapes.items()}

    def vector(self) -> np.ndarray:
        """``(52,) float64`` the row's ARKit weights in :data:`ARKIT_NAMES` order."""
        out = np.zeros(len(ARKIT_NAMES))
        for name, w in self.shapes.items():
            out[ARKIT_INDEX[name]] = w
        return out


@dataclass(frozen=True)
class RecipeTable:
    """The recipe table: :class:`Recipe` rows, looked up by MIAP (see the module documentation)."""

    rows: tuple[Recipe, ...]
    _index: Mapping[tuple[str, int, int], Recipe] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "_index", MappingProxyType({(r.kind, r.number, r.sign): r for r in self.rows})
        )

    def fap(self, number: int, sign: int = 1) -> Recipe | None:
        """The row of FAP ``number`` (3–68) in direction ``sign`` (+1 or −1; a FAP value's sign),
        or None where ARKit has no shape for that motion (head rotation, ears, pupils, …)."""
        if not 3 <= number <= N_FAPS:
            raise AvatarError(f"low-level FAPs are 3–{N_FAPS}, got {number!r}")
        if sign not in (1, -1):
            raise AvatarError(f"the sign of a FAP value is +1 or -1, got {sign!r}")
        return self._index.get(("fap", number, sign))

    def viseme(self, number: int) -> Recipe:
        """The row of MPEG-4 viseme ``number`` (0–14; viseme 0 has no shapes)."""
        row = self._index.get(("viseme", number, 1))
        if row is None:
            raise AvatarError(f"visemes are 0–14, got {number!r}")
        return row

    def expression(self, number: int) -> Recipe:
        """The row of expression ``number`` (1–6, joy to surprise)."""
        row = self._index.get(("expression", number, 1))
        if row is None:
            raise AvatarError(f"expressions are 1–6, got {number!r}")
        return row

    def fap_rows(self) -> tuple[Recipe, ...]:
        """The FAP rows, in table order."""
        return tuple(r for r in self.rows if r.kind == "fap")

    def shapes_used(self) -> frozenset[str]:
        """The ARKit names some row uses."""
        return frozenset(n for r in self.rows for n in r.shapes)

    def viseme_matrix(self) -> np.ndarray:
        """``(15, 52) float64``: row v is viseme v's ARKit weights."""
        return np.stack([self.viseme(v).vector() for v in range(15)])

    def expression_matrix(self) -> np.ndarray:
        """``(7, 52) float64``: row e is expression e's ARKit weights (row 0 zero: neutral)."""
        out = np.zeros((7, len(ARKIT_NAMES)))
        for e in range(1, 7):
            out[e] = self.expression(e).vector()
        return out

    def fap_content(self) -> np.ndarray:
        """``(68, 52) float64``: the table read backwards, the FAPs each ARKit shape moves.

        ``M[k - 1, j]`` is how far FAP k (FAP units, signed) moves when shape j goes from 0 to 1:
        for each FAP row that contains the shape, the row's signed amplitude times the shape's
        part of the row's weights. So every shape at 1 moves all the FAPs whose rows share it
        to their amplitudes (``mouthUpperUpLeft`` and ``mouthUpperUpRight`` at 1 raise FAPs 4,
        8, 9, 51, 55 and 56 to −300 MNS), and a FAP row with one shape gives the row itself
        back. Rows 1 and 2 (the high-level FAPs) are zero.
        """
        m = np.zeros((N_FAPS, len(ARKIT_NAMES)))
        for r in self.fap_rows():
            total = sum(r.shapes.values())
            for name, w in r.shapes.items():
                m[r.number - 1, ARKIT_INDEX[name]] += r.value * w / total
        return m

    def fap_scale(self) -> np.ndarray:
        """``(68,) float64``: each FAP's larger amplitude in the table (1 where it has no row): the
        FAP unit that the curves' least squares measure a FAP's error in."""
        s = np.zeros(N_FAPS)
        for r in self.fap_rows():
            s[r.number - 1] = max(s[r.number - 1], r.amplitude)
        return np.where(s > 0, s, 1.0)


def _fail(message: str, file: str, line: int, column: int | None = None) -> AvatarError:
    return AvatarError(message, file=file, line=line, column=column)


def _parse_shapes(text: str, file: str, line: int) -> dict[str, float]:
    shapes: dict[str, float] = {}
    for item in text.split():
        name, eq, weight = item.partition("=")
        if not eq:
            raise _fail(f"a shape is written NAME=WEIGHT, got {item!r}", file, line)
        if name not in ARKIT_INDEX:
            raise _fail(f"{name!r} is not one of the 52 ARKit blendshape names", file, line)
        if name in shapes:
            raise _fail(f"{name!r} is given twice in one row", file, line)
        try:
            w = float(weight)
        except ValueError:
            raise _fail(
                f"the weight of {name} must be a number, got {weight!r}", file, line
            ) from None
        if not (math.isfinite(w) and 0 < w <= 1):
            raise _fail(f"the weight of {name} must be within (0, 1], got {weight!r}", file, line)
        shapes[name] = w
    return shapes


def parse_recipes(text: str, file: str = "<recipes>") -> RecipeTable:
    """A :class:`RecipeTable` from the text of a recipe table (``#`` comment lines, a header
    line, then tab-separated rows; see ``vtts/data/arkit_recipes.tsv``). Raises
    :class:`~vtts.errors.AvatarError` naming the file, line and rule broken."""
    rows: list[Recipe] = []
    seen: set[tuple[str, int, int]] = set()
    header = False
    for i, raw in enumerate(text.splitlines(), start=1):
        if not raw.strip() or raw.startswith("#"):
            continue
        cells = raw.split("\t")
        if not header:
            if tuple(c.strip() for c in cells) != _COLUMNS:
                raise _fail(f"the header must be {' '.join(_COLUMNS)} (tab-separated)", file, i)
            header = True
            continue
        if len(cells) != len(_COLUMNS):
            raise _fail(f"a row has {len(_COLUMNS)} tab-separated cells, got {len(cells)}", file, i)
        kind, number_text, sign_text, amp_text, shapes_text, note = (c.strip() for c in cells)
        if kind not in KINDS:
            raise _fail(f"the kind must be one of {', '.join(KINDS)}, got {kind!r}", file, i)
        try:
            number = int(number_text)
        except ValueError:
            raise _fail(f"the number must be an integer, got {number_text!r}", file, i) from None
        lo, hi = {"fap": (3, N_FAPS), "viseme": (0, 14), "expression": (1, 6)}[kind]
        if not lo <= number <= hi:
            raise _fail(f"{kind} numbers are {lo}–{hi}, got {number}", file, i)
        if sign_text not in _SIGNS or (kind != "fap" and sign_text != "+"):
            allowed = "+ or -" if kind == "fap" else "+"
            raise _fail(f"the sign of a {kind} row must be {allowed}, got {sign_text!r}", file, i)
        sign = _SIGNS[sign_text]
        if kind == "fap" and sign < 0 and not fap(number).bidirectional:
            raise _fail(f"FAP {number} is unidirectional: it has no '-' direction", file, i)
        try:
            amplitude = float(amp_text)
        except ValueError:
            raise _fail(f"the amplitude must be a number, got {amp_text!r}", file, i) from None
        if not (math.isfinite(amplitude) and amplitude > 0):
            raise _fail(f"the amplitude must be finite and > 0, got {amp_text!r}", file, i)
        if kind != "fap" and amplitude != 1:
            raise _fail(f"a {kind} row stands for a weight of 1, got {amp_text!r}", file, i)
        shapes = _parse_shapes(shapes_text, file, i)
        if not shapes and not (kind == "viseme" and number == 0):
            raise _fail(f"{kind} {number} {sign_text} has no shapes", file, i)
        key = (kind, number, sign)
        if key in seen:
            raise _fail(f"{kind} {number} {sign_text} has a row already", file, i)
        seen.add(key)
        rows.append(Recipe(kind, number, sign, amplitude, MappingProxyType(shapes), note))
    if not header:
        raise AvatarError("the recipe table has no header line", file=file)
    for kind, numbers in (("viseme", range(15)), ("expression", range(1, 7))):
        missing = [n for n in numbers if (kind, n, 1) not in seen]
        if missing:
            raise AvatarError(
                f"the recipe table lacks {kind}s {', '.join(map(str, missing))}", file=file
            )
    return RecipeTable(tuple(rows))


@cache
def recipes() -> RecipeTable:
    """The recipe table shipped with vtts (``vtts/data/arkit_recipes.tsv``)."""
    path = package_data("arkit_recipes.tsv")
    return parse_recipes(path.read_text(encoding="utf-8"), file=str(path))
