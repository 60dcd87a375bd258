"""Curves out: what ``vtts say`` and ``vtts play`` animate, as the curves other avatar engines read.

The input is the per-frame parameter vector that say and play render (``(n, N_PARAMS)``, the
layout of :mod:`vtts.face.miap`: low-level FAPs 3–68 in FAP units, viseme weights 0–14 from the
speech or from FAP 1, expression weights 1–6 from the bookmarks or from FAP 2) and, for say, the
timed phones. Four formats (:data:`FORMATS`), all JSON:

``arkit``
    ``{"names": [52 ARKit names], "fps": F, "frames": [[52 weights 0–1], …], "head_rotation":
    [[pitch, yaw, roll], …]}``, one row per frame (:func:`arkit_weights`, :func:`head_rotation`,
    radians). The recipe table (:mod:`vtts.avatar.arkit`) is inverted in two parts:

    - the **visemes and expressions** are weights of MIAPs that the table gives as ARKit sums, so
      they contribute ``weight × recipe`` (viseme 10 at 0.6 gives ``jawOpen`` 0.42);
    - the **low-level FAPs** are displacements: the table read backwards says which FAPs each
      ARKit shape moves (:meth:`~vtts.avatar.arkit.RecipeTable.fap_content`, ``M``), and the
      weights ``w`` are the bounded least-squares solution of ``min ‖S⁻¹(M w − f)‖² + λ‖w‖²``
      with ``0 ≤ w ≤ 1`` (:data:`RIDGE` λ), ``S`` being each FAP's amplitude in the table so
      that a FAP's error counts in its own scale. The problem splits into independent blocks
      (the upper lip's FAPs and shapes, the left eyelid's, …) of at most five shapes, each
      solved exactly for all frames at once (:func:`vtts.avatar.boxls.box_lstsq`). Negative
      FAP values find their
      shapes through the negative rows (``raise_l_cornerlip`` < 0 is ``mouthFrownLeft``); FAPs
      without a row (head rotation, ears, pupils, eyeball thrust, most of the tongue) are left
      out. Every shape's own FAP motion gives that shape back exactly.

    The two parts add up and the sum is clipped to 0–1.
``oculus``
    ``{"names": [15 Oculus visemes], "fps": F, "frames": [[15 weights 0–1], …]}``: Oculus viseme
    i is MPEG-4 viseme i; ``viseme_sil`` takes what the others leave of 1.
``azure``
    ``[{"audio_offset_ms": T, "viseme_id": ID}, …]``: an event where the viseme changes, with the
    22 SAPI ids of Azure's speech service (:mod:`vtts.avatar.sapi`).
``talkinghead``
    ``{"words": ["Hello", …], "wtimes": [ms, …], "wdurations": [ms, …], "visemes": ["sil",
    "PP", …], "vtimes": [ms, …], "vdurations": [ms, …]}``: the word and viseme tracks the
    TalkingHead browser avatar (met4citizen/TalkingHead, ``speakAudio``) plays with its audio;
    its viseme names are the Oculus ones without the ``viseme_`` prefix. The words are say's
    (as written in the text, in the audio's clock; empty when a ``--phonemes`` file gives none);
    play has no words, so its track leaves the three word keys out.

The events of ``azure`` and ``talkinghead`` come from the phones when there are some (``vtts
say``: the phones in the audio's clock, silence between them), else from the viseme track (``vtts
play``: each frame's strongest Oculus viseme, silence included); neighbours with the same viseme
are merged.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from vtts.atomic import write_text
from vtts.avatar.arkit import ARKIT_NAMES, OCULUS_VISEMES, RecipeTable, recipes
from vtts.avatar.boxls import MAX_UNKNOWNS, box_lstsq
from vtts.avatar.sapi import sapi_viseme
from vtts.errors import AvatarError
from vtts.face.miap import EXPRESSION_BASE, N_PARAMS, VISEME_BASE
from vtts.fap import AU

#: Digits kept in the weights, the event times (ms) and the head's angles (rad) of the JSON.
WEIGHT_DIGITS = 4
TIME_DIGITS = 1
HEAD_DIGITS = 5
#: Ridge weight of the least squares (in squared recipe amplitudes): picks the least motion where
#: shapes cancel or look alike (eyeLookIn against eyeLookOut: 0.3 of one rather than 0.8 of it
#: and 0.5 of the other); shrinks a weight by about 0.002 %.
RIDGE = 1e-6
#: FAP values are bounded to this many table amplitudes before the least squares.
FAR = 1e6


@dataclass(frozen=True)
class VisemeSegment:
    """A stretch of time with one MPEG-4 viseme: ``start``/``end`` in s, ``viseme`` 0–14 and
    the phone it comes from (empty when it comes from the viseme track or is silence)."""

    start: float
    end: float
    viseme: int
    phoneme: str = ""


def _params(params: np.ndarray) -> np.ndarray:
    p = np.asarray(params, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != N_PARAMS:
        raise AvatarError(f"parameter vectors must be (n, {N_PARAMS}), got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise AvatarError("parameter vectors must be finite")
    return p


def _blocks(content: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The independent parts of the FAP content ``(68, 52)``: ``(FAP rows, shape columns)`` of
    each connected group (the left eyelid's FAPs and shapes, the lips', …), solved apart."""
    moves = content != 0
    rows_left = set(np.flatnonzero(moves.any(axis=1)).tolist())
    blocks = []
    while rows_left:
        rows, cols = {rows_left.pop()}, set()
        while True:
            new_cols = set(np.flatnonzero(moves[sorted(rows)].any(axis=0)).tolist())
            new_rows = set(np.flatnonzero(moves[:, sorted(new_cols)].any(axis=1)).tolist())
            if new_cols == cols and new_rows == rows:
                break
            rows, cols = new_rows, new_cols
        rows_left -= rows
        blocks.append((np.array(sorted(rows)), np.array(sorted(cols))))
    return sorted(blocks, key=lambda b: b[0][0])


def _lsq_linear(a: np.ndarray, f: np.ndarray) -> np.ndarray:
    """:func:`box_lstsq` for large blocks: SciPy's BVLS, one frame at a time."""
    from scipy.optimize import lsq_linear

    c = a.shape[1]
    stacked = np.vstack([a, np.sqrt(RIDGE) * np.eye(c)])
    rhs = np.hstack([f, np.zeros((f.shape[0], c))])
    return np.stack([lsq_linear(stacked, b, bounds=(0.0, 1.0), method="bvls").x for b in rhs])


def arkit_weights(params: np.ndarray, table: RecipeTable | None = None) -> np.ndarray:
    """``(n, 52) float64`` ARKit weights 0–1 (:data:`ARKIT_NAMES` order) of ``(n, N_PARAMS)``
    parameter vectors; the inversion is in the module documentation."""
    p = _params(params)
    table = recipes() if table is None else table
    content = table.fap_content()
    scale = table.fap_scale()
    out = np.zeros((p.shape[0], len(ARKIT_NAMES)))
    for rows, cols in _blocks(content):
        a = content[np.ix_(rows, cols)] / scale[rows, None]
        # far beyond the table every weight is at 1 or 0 anyway; the bound keeps squares finite
        f = np.clip(p[:, rows] / scale[rows], -FAR, FAR)
        moving = np.any(f != 0, axis=1)
        if not moving.any():
            continue
        if len(cols) <= MAX_UNKNOWNS:
            out[np.ix_(moving, cols)] = box_lstsq(a, f[moving], RIDGE)
        else:  # a table of one's own may tie more shapes together than the faces can visit
            out[np.ix_(moving, cols)] = _lsq_linear(a, f[moving])
    out += p[:, VISEME_BASE : VISEME_BASE + 15] @ table.viseme_matrix()
    out += p[:, EXPRESSION_BASE : EXPRESSION_BASE + 7] @ table.expression_matrix()
    return np.clip(out, 0.0, 1.0)


def oculus_weights(params: np.ndarray) -> np.ndarray:
    """``(n, 15) float64`` Oculus viseme weights 0–1: visemes 1–14 as the parameter vectors give
    them (clipped to 0–1), ``viseme_sil`` what they leave of 1."""
    p = _params(params)
    w = np.clip(p[:, VISEME_BASE : VISEME_BASE + 15], 0.0, 1.0)
    w[:, 0] = np.clip(1.0 - w[:, 1:].sum(axis=1), 0.0, 1.0)
    return w


def viseme_segments(
    params: np.ndarray, fps: float, phones: Sequence | None = None
) -> list[VisemeSegment]:
    """The viseme track as segments covering ``0 … n / fps`` s: from ``phones`` (objects with
    ``start``, ``end`` in s, ``viseme`` and ``phoneme``, such as
    :class:`~vtts.speech.timings.TimedPhone`) when given, else from each frame's strongest
    Oculus viseme. Gaps between phones are silence (viseme 0)."""
    p = _params(params)
    duration = p.shape[0] / fps
    segments: list[VisemeSegment] = []
    if phones:
        t = 0.0
        for ph in sorted(phones, key=lambda ph: ph.start):
            start, end = max(float(ph.start), t), float(ph.end)
            if end <= start:
                continue
            if start > t:
                segments.append(VisemeSegment(t, start, 0))
            segments.append(VisemeSegment(start, end, int(ph.viseme), str(ph.phoneme or "")))
            t = end
        if duration > t:
            segments.append(VisemeSegment(t, duration, 0))
        return segments
    strongest = np.argmax(oculus_weights(p), axis=1)
    start = 0
    for i in range(1, p.shape[0] + 1):
        if i == p.shape[0] or strongest[i] != strongest[start]:
            segments.append(VisemeSegment(start / fps, i / fps, int(strongest[start])))
            start = i
    return segments


def _events(segments: Sequence[VisemeSegment], key: Callable[[VisemeSegment], object]) -> list:
    """``(key, start s, end s)`` with neighbours of the same key merged."""
    merged: list[list] = []
    for s in segments:
        k = key(s)
        if merged and merged[-1][0] == k and abs(merged[-1][2] - s.start) < 1e-9:
            merged[-1][2] = s.end
        else:
            merged.append([k, s.start, s.end])
    return merged


def _ms(seconds: float) -> float:
    return round(1000.0 * seconds, TIME_DIGITS)


def azure_events(segments: Sequence[VisemeSegment]) -> list[dict]:
    """Azure-style viseme events ``{"audio_offset_ms", "viseme_id"}`` (SAPI ids 0–21), one where
    the id changes."""
    events = _events(segments, lambda s: sapi_viseme(s.viseme, s.phoneme))
    return [{"audio_offset_ms": _ms(start), "viseme_id": k} for k, start, _ in events]


def _duration_ms(start: float, end: float) -> float:
    # the difference of the rounded times, so that time + duration is the next event's time
    return round(_ms(end) - _ms(start), TIME_DIGITS)


def talkinghead_track(segments: Sequence[VisemeSegment], words: Sequence | None = None) -> dict:
    """TalkingHead's ``{"words", "wtimes", "wdurations", "visemes", "vtimes", "vdurations"}``
    (viseme names without ``viseme_``, times in ms). ``words``: objects with ``start``, ``end``
    (s) and ``label``, such as :class:`~vtts.speech.timings.TimedWord`, in time order in the
    track; None leaves the three word keys out (TalkingHead then shows no subtitles)."""
    events = _events(segments, lambda s: OCULUS_VISEMES[s.viseme].removeprefix("viseme_"))
    track: dict[str, list] = {}
    if words is not None:
        ordered = sorted(words, key=lambda w: w.start)
        track["words"] = [str(w.label) for w in ordered]
        track["wtimes"] = [_ms(w.start) for w in ordered]
        track["wdurations"] = [_duration_ms(w.start, w.end) for w in ordered]
    track["visemes"] = [k for k, _, _ in events]
    track["vtimes"] = [_ms(start) for _, start, _ in events]
    track["vdurations"] = [_duration_ms(start, end) for _, start, end in events]
    return track


def _frames(names: Sequence[str], fps: float, weights: np.ndarray) -> dict:
    return {
        "names": list(names),
        "fps": fps,
        "frames": np.round(weights, WEIGHT_DIGITS).tolist(),
    }


def head_rotation(params: np.ndarray) -> np.ndarray:
    """``(n, 3) float64`` the head's pitch, yaw and roll in radians (FAPs 48–50, AU · 10⁻⁵):
    pitch > 0 nods down, yaw > 0 turns to the face's left, roll > 0 tilts to its right, as
    MPEG-4 defines them. ARKit gives the head as the face anchor's transform, not as
    blendshapes, so the ``arkit`` curves carry it beside the weights."""
    p = _params(params)
    return p[:, 47:50] * AU


def _arkit(params, fps, phones, words) -> dict:
    out = _frames(ARKIT_NAMES, fps, arkit_weights(params))
    out["head_rotation"] = np.round(head_rotation(params), HEAD_DIGITS).tolist()
    return out


def _oculus(params, fps, phones, words) -> dict:
    return _frames(OCULUS_VISEMES, fps, oculus_weights(params))


def _azure(params, fps, phones, words) -> list:
    return azure_events(viseme_segments(params, fps, phones))


def _talkinghead(params, fps, phones, words) -> dict:
    return talkinghead_track(viseme_segments(params, fps, phones), words)


#: The curves formats and what makes each (params, fps, phones, words) → JSON value.
FORMATS: dict[str, Callable] = {
    "arkit": _arkit,
    "oculus": _oculus,
    "azure": _azure,
    "talkinghead": _talkinghead,
}

#: The format ``--curves`` defaults to.
DEFAULT_FORMAT = "arkit"


def check_format(name: str) -> str:
    """``name`` as a curves format (case-insensitive), or an :class:`~vtts.errors.AvatarError`
    listing the formats."""
    key = name.strip().lower() if isinstance(name, str) else ""
    if key not in FORMATS:
        raise AvatarError(f"unknown curves format {name!r}: expected one of {', '.join(FORMATS)}")
    return key


def curves(
    fmt: str,
    params: np.ndarray,
    fps: float,
    phones: Sequence | None = None,
    words: Sequence | None = None,
) -> dict | list:
    """The curves of ``params`` (``(n, N_PARAMS)`` at ``fps`` frames/s) in format ``fmt`` as a
    JSON value; ``phones`` (say's timed phones) time the event formats, ``words`` (say's
    :class:`~vtts.speech.timings.TimedWord` list, possibly empty) give ``talkinghead`` its word
    track (left out when None)."""
    maker = FORMATS[check_format(fmt)]
    if not (isinstance(fps, int | float) and np.isfinite(fps) and fps > 0):
        raise AvatarError(f"the frame rate must be finite and > 0, got {fps!r}")
    return maker(params, float(fps), phones, words)


def write_curves(
    path: str | os.PathLike[str],
    fmt: str,
    params: np.ndarray,
    fps: float,
    phones: Sequence | None = None,
    words: Sequence | None = None,
) -> None:
    """Write :func:`curves` to ``path`` as JSON, atomically."""
    value = curves(fmt, params, fps, phones, words)
    write_text(path, json.dumps(value, separators=(",", ":")) + "\n")
