"""How far an alignment's phone boundaries are from the truth of another engine's timings.

The aligned phones are espeak-ng's; the truth may come from another phone set (festival's) or
another accent, so the two sequences are first matched: each phone becomes a broad class (its
MPEG-4 viseme, every vowel one class, every pause one class), pauses are dropped, and
:class:`difflib.SequenceMatcher` finds the runs where the classes agree. A boundary is compared
where the phones on both of its sides were matched to neighbouring truth phones.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

import numpy as np

from vtts.speech.phonemes import BILABIAL, Phone

VOWELS = frozenset({10, 11, 12, 13, 14})


@dataclass
class BoundaryErrors:
    """``signed`` ``(k,)`` s: aligned − true of each matched boundary (``errors`` its absolute
    value); ``bilabials`` ``(b,)``
    bool: whether each matched p/b/m's centre falls in the same frame at ``fps`` as the truth's;
    ``matched`` and ``total``: boundaries compared and truth boundaries (speech only)."""

    signed: np.ndarray
    bilabials: np.ndarray
    matched: int
    total: int

    @property
    def errors(self) -> np.ndarray:
        return np.abs(self.signed)

    def summary(self) -> dict[str, float]:
        """median, p90 and worst error in ms, bilabial hit rate, matched fraction."""
        e = self.errors * 1000.0
        return {
            "median_ms": float(np.median(e)) if len(e) else float("nan"),
            "p90_ms": float(np.percentile(e, 90)) if len(e) else float("nan"),
            "worst_ms": float(e.max()) if len(e) else float("nan"),
            "bilabial_hit": float(self.bilabials.mean()) if len(self.bilabials) else float("nan"),
            "matched": self.matched / max(self.total, 1),
            "bias_ms": float(np.median(self.signed)) * 1000 if len(e) else float("nan"),
        }


def _token(p: Phone) -> str:
    v = p.viseme or 0
    return "V" if v in VOWELS else chr(ord("a") + v)


def boundary_errors(aligned: list[Phone], truth: list[Phone], fps: float = 30.0) -> BoundaryErrors:
    """Compare the boundaries of ``aligned`` phones with those of ``truth`` phones (both with
    visemes set, in one clock): the start of every matched phone, and the end of a matched
    phone that a pause (or the end) follows in the truth. See the module docstring."""
    a = [p for p in aligned if (p.viseme or 0) != 0]
    b = [p for p in truth if (p.viseme or 0) != 0]
    following = {id(p): k + 1 == len(b) or b[k + 1].start > p.end + 1e-6 for k, p in enumerate(b)}
    sm = difflib.SequenceMatcher(
        None, [_token(p) for p in a], [_token(p) for p in b], autojunk=False
    )
    errors, bil = [], []
    total = len(b) + sum(following.values())
    for block in sm.get_matching_blocks():
        for k in range(block.size):
            pa, pb = a[block.a + k], b[block.b + k]
            errors.append(pa.start - pb.start)
            if following[id(pb)]:
                errors.append(pa.end - pb.end)
            if pa.viseme == BILABIAL:
                ca, cb = 0.5 * (pa.start + pa.end), 0.5 * (pb.start + pb.end)
                bil.append(round(ca * fps) == round(cb * fps))
    return BoundaryErrors(np.array(errors), np.array(bil, bool), len(errors), total)
