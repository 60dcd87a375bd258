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


@dataclass
class WordErrors:
    """``signed`` ``(k,)`` s: aligned − true of each compared word boundary (the start of every
    word found in both, and its end where a pause or the end of the speech follows it in the
    truth); ``lost``: the words of the transcript the alignment gave no time; ``unmatched``:
    the truth's words that no aligned word was matched with (``lost`` among them)."""

    signed: np.ndarray
    lost: list[str]
    unmatched: list[str]
    words: int

    @property
    def errors(self) -> np.ndarray:
        return np.abs(self.signed)


def _key(text: str) -> str:
    return "".join(c for c in text.lower() if c.isalnum())


def transcript_words(text: str) -> list[str]:
    """The words of a plain transcript as ``vtts say`` counts them: its whitespace-separated
    tokens that hold a letter or digit, punctuation around them stripped."""
    return [w for w in (_key(t) for t in text.split()) if w]


def word_errors(aligned, truth, text: str) -> WordErrors:
    """Compare the word times of ``aligned`` (objects with ``start``, ``end``, ``text``: the
    aligner's words) with ``truth``'s (another engine's words of the same ``text``, in one
    clock). Words are matched by their letters, in order (:class:`difflib.SequenceMatcher`)."""
    said = transcript_words(text)
    a = [w for w in aligned if _key(w.text)]
    b = [w for w in truth if _key(w.text)]
    kept = difflib.SequenceMatcher(None, said, [_key(w.text) for w in a], autojunk=False)
    lost_at = set(range(len(said)))
    for block in kept.get_matching_blocks():
        lost_at -= set(range(block.a, block.a + block.size))
    sm = difflib.SequenceMatcher(
        None, [_key(w.text) for w in a], [_key(w.text) for w in b], autojunk=False
    )
    signed, matched = [], set()
    for block in sm.get_matching_blocks():
        for k in range(block.size):
            wa, wb = a[block.a + k], b[block.b + k]
            matched.add(block.b + k)
            signed.append(wa.start - wb.start)
            j = block.b + k + 1
            if j == len(b) or b[j].start > wb.end + 1e-6:
                signed.append(wa.end - wb.end)
    return WordErrors(
        np.array(signed),
        [said[k] for k in sorted(lost_at)],
        [b[k].text for k in range(len(b)) if k not in matched],
        len(said),
    )
