"""What an analysis estimates: FAP numbers and the head translation ``tx``, ``ty``, ``tz``.

Eisert & Girod estimate 17 parameters per frame from a head-and-shoulders video: six for the
global head motion (three rotations, three translations), four for the eyebrows and seven for the
mouth. In MPEG-4 terms the rotations are FAPs 48–50 (head pitch, yaw, roll) and the translation is
not a FAP at all (it is the scene's Transform), so the translation is named ``tx``, ``ty``, ``tz``.

:func:`parse_unknowns` reads the ``--faps`` option of ``vtts analyze``.
"""

from __future__ import annotations

import re

from vtts.analysis.result import TRANSLATION
from vtts.errors import AnalysisError, FapError
from vtts.fap.table import N_FAPS
from vtts.fap.table import fap as fap_def

#: The paper's 17 unknowns: head rotation (48–50) and translation, the inner and outer eyebrow
#: raisers (31, 32, 35, 36), and the mouth: jaw (3), mid lips (4, 5), lip-corner stretch (6, 7)
#: and raise (12, 13).
DEFAULT_UNKNOWNS: tuple[int | str, ...] = (
    48, 49, 50, "tx", "ty", "tz", 31, 32, 35, 36, 3, 4, 5, 6, 7, 12, 13,
)  # fmt: skip

#: The head's rigid motion: rotation (FAPs 48–50) and translation. A head has inertia, so its
#: motion is what an estimator carries on from the last two frames (:class:`vtts.analysis.
#: Estimator`'s ``predict``); the face's own FAPs change too abruptly with speech for that.
HEAD_MOTION: tuple[int | str, ...] = (48, 49, 50, "tx", "ty", "tz")
#: The head's rotation: pitch, yaw, roll (AU).
HEAD_ROTATION: tuple[int, ...] = (48, 49, 50)

#: The FAPs of the paper's Table 1 (estimation accuracy on synthetic sequences): jaw, lip corners
#: raised, eyelids, outer eyebrows and the three head rotations.
TABLE1_FAPS: tuple[int, ...] = (3, 12, 13, 19, 20, 35, 36, 48, 49, 50)

#: The eyelids (top and bottom, left and right): thin edges a few pixels tall that move by less
#: than a pixel for tens of FAP units, so that the rendered image changes in whole pixels where
#: the optical-flow model expects a smooth change. An estimator refines them on the rendered
#: image itself (:class:`vtts.analysis.Estimator`'s ``refine``).
EYELIDS: tuple[int, ...] = (19, 20, 21, 22)

#: The jaw and the lip-corner raisers. Where the jaw opens, the lips uncover the teeth and the
#: optical-flow model's smooth change fails at that occlusion: on a lit synthetic face the jaw
#: and the corners can stall together two or three units off (the solves' steps tiny, the face
#: at 42 dB). The tracking mode refines them on the rendered image on a lit face
#: (:class:`vtts.analysis.tracker.Tracker`'s ``lit_refine``).
JAW_AND_CORNERS: tuple[int, ...] = (3, 12, 13)

#: Named sets for ``--faps``.
UNKNOWN_SETS: dict[str, tuple[int | str, ...]] = {
    "paper17": DEFAULT_UNKNOWNS,
    "table1": TABLE1_FAPS,
}

#: FAP numbers an analysis can estimate: the low-level FAPs (1 and 2 are visemes and
#: expressions, table indices without a motion of their own).
ESTIMABLE = range(3, N_FAPS + 1)

# ASCII digits, few enough for int() (it refuses 4,300); longer numbers are no FAP's anyway
_RANGE = re.compile(r"([0-9]{1,18})-([0-9]{1,18})")
_NUMBER = re.compile(r"[0-9]{1,18}")


def _items(word: str) -> tuple[int | str, ...]:
    """The unknowns one item of the list stands for (a set or a range stands for several)."""
    key = word.lower()
    if key in UNKNOWN_SETS:
        return UNKNOWN_SETS[key]
    if key in TRANSLATION:
        return (key,)
    m = _RANGE.fullmatch(key)
    if m:
        lo, hi = int(m[1]), int(m[2])
        if not lo <= hi:
            raise AnalysisError(f"--faps item {word!r}: a range goes from low to high")
        numbers = range(lo, hi + 1)
    elif _NUMBER.fullmatch(key):
        numbers = range(int(key), int(key) + 1)
    else:
        try:
            number = fap_def(word).number
            numbers = range(number, number + 1)
        except FapError:
            raise AnalysisError(
                f"--faps item {word!r} is not a FAP: expected a FAP number "
                f"{ESTIMABLE.start}–{ESTIMABLE.stop - 1}, a range such as 3-13, a FAP name such "
                f"as open_jaw, {', '.join(TRANSLATION)} (head translation) or a set "
                f"({', '.join(UNKNOWN_SETS)})"
            ) from None
    for k in numbers:
        if k not in ESTIMABLE:
            what = "out of range" if k > N_FAPS or k < 1 else "high-level (a viseme or expression)"
            raise AnalysisError(
                f"--faps item {word!r}: FAP {k} is {what} and cannot be estimated; "
                f"low-level FAPs are {ESTIMABLE.start}–{ESTIMABLE.stop - 1}"
            )
    return tuple(numbers)


def parse_unknowns(text: str) -> tuple[int | str, ...]:
    """The unknowns of a ``--faps`` list, in the order given.

    ``text`` is a comma (or blank) separated list of FAP numbers (3–68), ranges (``3-13``), FAP
    names (``open_jaw``), ``tx``/``ty``/``tz`` and named sets (``paper17``, ``table1``). FAPs are
    returned as ints, the translation as the strings ``"tx"``, ``"ty"``, ``"tz"``. Anything else,
    FAPs 1 and 2, and an unknown listed twice (also through a set) are an
    :class:`~vtts.errors.AnalysisError` naming the item.
    """
    out: list[int | str] = []
    source: dict[int | str, str] = {}
    for word in filter(None, re.split(r"[,\s]+", text.strip())):
        for u in _items(word):
            if u in source:
                name = f"FAP {u}" if isinstance(u, int) else u
                by = "" if source[u] == word else f" by {source[u]!r}"
                raise AnalysisError(
                    f"--faps item {word!r}: {name} is already listed{by}; "
                    "each unknown is estimated once"
                )
            source[u] = word
            out.append(u)
    if not out:
        raise AnalysisError(f"--faps selects nothing: got {text!r}")
    return tuple(out)


def describe_unknown(u: int | str) -> str:
    """A short label: ``"FAP 3 open_jaw"`` or ``"tx"``."""
    return f"FAP {u} {fap_def(u).name}" if isinstance(u, int) else u
