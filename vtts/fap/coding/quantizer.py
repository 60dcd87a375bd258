"""What the encoder sends and the decoder reconstructs: FAP selection, the quantizer and DPCM.

A low-level FAP k is coded on the grid of its step ``step_k = base_k · quantizer``: ``base_k`` is
the FAP's ``quant_step`` of ISO/IEC 14496-2 (``vtts/data/faps.tsv``: 4 for open_jaw, 170 AU for
the head rotations, …) and ``quantizer`` a global factor like MPEG-4's ``fap_quant`` (1 = the
standard's steps, 2 = twice as coarse, fewer bits). Both are stored in the bitstream, so a
decoder never depends on the table it has. A value x is sent as the index ``round(x / step)``;
the prediction is the previous *decoded* index of the same FAP (held over frames that do not set
it, 0 before the first), so the quantized prediction error is ``q = index − previous index``.
Because the prediction lies on the grid, this is exactly closed-loop DPCM: quantizing the error
``x − decoded`` gives the same q, the encoder tracks exactly what the decoder reconstructs, and
errors never accumulate. The reconstruction is ``index · step`` and ``|x − reconstruction| ≤
step / 2`` for every value, whatever the jump (no clamp anywhere). :func:`reconstruct` returns it
without coding.

The head translation (:attr:`FapStream.translation`, ES units), which MPEG-4 has no FAP for, is
quantized exactly like three more low-level FAPs on the grid of :data:`TRANSLATION_BASE_STEP`
times the quantizer.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from vtts.errors import CodingError, FapError
from vtts.fap.stream import MAX_RESAMPLED_FRAMES, MAX_TRANSLATION, TRANSLATION_AXES, FapStream
from vtts.fap.table import FAPS, N_FAPS
from vtts.fap.table import fap as fap_def

#: The 17 FAPs of Eisert & Girod's camera experiment in MPEG-4 numbering. The paper estimated six
#: global head-motion parameters (3 rotations, 3 translations), four eyebrow and seven mouth
#: parameters. MPEG-4 has FAPs for the three head rotations only (48–50): head translation is the
#: scene's Transform, not a FAP. The three translation slots are taken by the eye parameters a
#: talking head sends alongside head motion: both upper eyelids (19, 20: blinks) and the gaze
#: (23, yaw of the left eyeball; a decoder derives 24 from it by the left/right FIT rule).
#: Eyebrows: inner and outer raisers, left and right (31, 32, 35, 36). Mouth: jaw (3), the mid
#: lips (4, 5), the lip corners' stretch (6, 7) and raise (12, 13).
PAPER_17: tuple[int, ...] = (48, 49, 50, 19, 20, 23, 31, 32, 35, 36, 3, 4, 5, 6, 7, 12, 13)

#: Named FAP sets for ``--faps``.
FAP_SETS: dict[str, tuple[int, ...]] = {
    "paper17": PAPER_17,
    "all": tuple(range(1, N_FAPS + 1)),
    "low": tuple(range(3, N_FAPS + 1)),
}

#: ``|value / step|`` must stay below this (2^40): indices and errors fit any machine integer.
MAX_INDEX = 1 << 40
#: A magnitude needs at most this many bits (errors between FAPs reach 2^42).
MAX_MAGNITUDE_BITS = 43
#: Limits a decoder enforces on a header, so that no input can make it allocate without bound.
MAX_FRAMES = MAX_RESAMPLED_FRAMES
MAX_NAME_BYTES = 4096
MAX_BASE_STEP = 1 << 20
QUANTIZER_RANGE = (2.0**-6, 2.0**12)

#: The base step of the head translation's three axes, in ES units (ES0 / 1024), sent in the
#: header like the FAPs' base steps. Chosen so that one step moves the head's image about as
#: much as one step of the FAPs that move the head and mouth (the figures on a CIF head are in
#: ``docs/fap-coding.md``, "The quantizer").
TRANSLATION_BASE_STEP = 4


# --- FAP selection ------------------------------------------------------------------------------


def fap_set(text: str | Iterable[int | str]) -> tuple[int, ...]:
    """FAP numbers from a list such as ``"3,4,5"``, ``"3-13 48"``, ``"open_jaw,head_yaw"`` or a
    named set (``paper17``, ``low``: 3–68, ``all``: 1–68); sorted, without duplicates."""
    items = re.split(r"[,\s]+", text.strip()) if isinstance(text, str) else list(text)
    out: set[int] = set()
    for item in items:
        if isinstance(item, str):
            word = item.strip()
            if not word:
                continue
            if word.lower() in FAP_SETS:
                out.update(FAP_SETS[word.lower()])
                continue
            # ASCII digits, few enough for int() (it refuses 4,300)
            m = re.fullmatch(r"([0-9]{1,18})-([0-9]{1,18})", word)
            if m:
                lo, hi = int(m.group(1)), int(m.group(2))
                if not 1 <= lo <= hi <= N_FAPS:
                    raise FapError(f"FAP range {word!r} must be within 1-{N_FAPS}, low to high")
                out.update(range(lo, hi + 1))
                continue
        out.add(fap_def(item).number)
    if not out:
        raise FapError(f"no FAPs selected by {text!r}")
    return tuple(sorted(out))


# --- the grid -----------------------------------------------------------------------------------


def _float32(x: float) -> float:
    return float(np.float32(x))


def check_quantizer(quantizer: float) -> float:
    """``quantizer`` checked against :data:`QUANTIZER_RANGE` and rounded to the float32 that
    the header stores (encoder and decoder then compute the same steps)."""
    try:
        q = float(quantizer)
    except (TypeError, ValueError):
        raise FapError(f"quantizer must be a number, got {quantizer!r}") from None
    lo, hi = QUANTIZER_RANGE
    if not (math.isfinite(q) and lo <= q <= hi):
        raise FapError(f"quantizer must be within {lo:g}–{hi:g}, got {quantizer!r}")
    return _float32(q)


def check_steps(steps: Mapping[int | str, int] | None) -> dict[int | str, int]:
    """``steps`` of :func:`~vtts.fap.coding.encode`, checked: FAP numbers 3–68 and
    ``tx``/``ty``/``tz`` to whole base steps within 1–:data:`MAX_BASE_STEP`."""
    if steps is None:
        return {}
    if not isinstance(steps, Mapping):
        raise FapError(f"steps must map FAPs to base steps, got {type(steps).__name__}")
    out: dict[int | str, int] = {}
    for key, value in steps.items():
        if not (key in TRANSLATION_AXES or (isinstance(key, int) and 3 <= key <= N_FAPS)):
            raise FapError(
                f"steps: {key!r} is not a low-level FAP (3–{N_FAPS}) nor a translation axis "
                f"({', '.join(TRANSLATION_AXES)})"
            )
        if isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise FapError(f"steps: the base step of {key} must be a whole number, got {value!r}")
        if not 1 <= value <= MAX_BASE_STEP:
            raise FapError(f"steps: the base step of {key} must be within 1–{MAX_BASE_STEP}, "
                           f"got {value}")  # fmt: skip
        out[key] = int(value)
    return out


def grid_steps(base_steps: Iterable[int], quantizer: float) -> np.ndarray:
    """``(k,) float64``: step = base · quantizer, the same arithmetic in encoder and decoder."""
    return np.array([float(b) for b in base_steps], dtype=np.float64) * np.float64(quantizer)


def quantize(stream: FapStream, low: tuple[int, ...], steps: np.ndarray) -> np.ndarray:
    """``(n, L) int64``: the grid index of each low-level FAP of ``low`` (steps ``(L,)``) in
    each frame, 0 where the frame does not set it; a value too large to code is an error."""
    with np.errstate(over="ignore", invalid="ignore"):
        ratio = stream.values[:, [k - 1 for k in low]] / steps
    bad = ~(np.abs(ratio) < MAX_INDEX - 1)
    if np.any(bad):
        i, j = (int(x) for x in np.argwhere(bad)[0])
        raise CodingError(
            f"FAP {low[j]} = {stream.values[i, low[j] - 1]!r} in frame {i} is too large to code "
            f"with step {steps[j]:g}: |value / step| must stay below 2^40"
        )
    low_mask = stream.mask[:, [k - 1 for k in low]]
    return np.where(low_mask, np.rint(ratio), 0.0).astype(np.int64)


def quantize_translation(translation: np.ndarray, t_steps: np.ndarray) -> np.ndarray:
    """``(n, 3) int64``: the grid index of the head translation (``(n, 3)``, ES units) on each
    axis (steps ``(3,)``)."""
    t_index = np.rint(translation / t_steps).astype(np.int64)
    # |t| ≤ MAX_TRANSLATION keeps |t / step| far below MAX_INDEX; its grid point may lie
    # beyond the bound only within half a step of it
    beyond = ~(np.abs(t_index * t_steps) <= MAX_TRANSLATION)
    if np.any(beyond):
        i, a = (int(x) for x in np.argwhere(beyond)[0])
        value = float(translation[i, a])
        raise CodingError(
            f"head translation {TRANSLATION_AXES[a]} = {value!r} in frame "
            f"{i} is too large to code with step {t_steps[a]:g}: its reconstruction would "
            f"leave ±{MAX_TRANSLATION:g} ES units"
        )
    return t_index


def assemble(
    fps: float,
    name: str,
    first_frame: int,
    faps: tuple[int, ...],
    low: tuple[int, ...],
    steps: np.ndarray,
    mask: np.ndarray,
    index: np.ndarray,
    viseme: np.ndarray,
    expression: np.ndarray,
    translation_steps: np.ndarray | None = None,
    translation_index: np.ndarray | None = None,
) -> FapStream:
    """The decoded stream: ``index · step`` for the low-level FAPs and the head translation
    (when sent), the rest as sent. ``mask`` is ``(n, len(faps)) bool``, ``index`` ``(n,
    len(low)) int64`` with ``steps`` ``(len(low),)``, ``viseme`` ``(n, 4)``, ``expression`` ``(n,
    6)``, ``translation_index`` ``(n, 3) int64`` with ``translation_steps`` ``(3,)``."""
    n = mask.shape[0]
    full_mask = np.zeros((n, N_FAPS), dtype=bool)
    full_mask[:, [k - 1 for k in faps]] = mask
    values = np.zeros((n, N_FAPS), dtype=np.float64)
    if low:
        values[:, [k - 1 for k in low]] = index.astype(np.float64) * steps
    translation = None
    if translation_index is not None:
        translation = translation_index.astype(np.float64) * translation_steps
    return FapStream(
        fps=fps,
        name=name,
        values=values,
        mask=full_mask,
        viseme=viseme,
        expression=expression,
        first_frame=first_frame,
        translation=translation,
    )


# --- a whole stream, ready to code --------------------------------------------------------------


@dataclass(frozen=True)
class Plan:
    """A stream ready to code: the FAPs to send, their steps and quantization indices."""

    source: FapStream  # the stream after FAP selection and resampling
    faps: tuple[int, ...]  # coded FAPs, ascending (1 and 2 included when coded)
    low: tuple[int, ...]  # coded low-level FAPs
    base_steps: tuple[int, ...]
    quantizer: float  # as stored (float32)
    mask: np.ndarray  # (n, len(faps)) bool
    index: np.ndarray  # (n, len(low)) int64, 0 where not set
    reconstruction: FapStream
    translation_steps: tuple[int, ...] = ()  # base steps of tx, ty, tz; () when not sent
    translation_index: np.ndarray | None = None  # (n, 3) int64 when sent


def prepare(
    stream: FapStream,
    faps: Iterable[int | str] | str | None,
    rate: float | None,
    quantizer: float,
    translation: bool = True,
    steps: Mapping[int | str, int] | None = None,
) -> Plan:
    """``stream`` planned for coding with :func:`~vtts.fap.coding.encode`'s arguments: its FAPs
    selected, resampled to ``rate``, checked against the header's limits and quantized."""
    if not isinstance(stream, FapStream):
        raise FapError(f"expected a FapStream, got {type(stream).__name__}")
    q32 = check_quantizer(quantizer)
    own = check_steps(steps)
    wanted = set(range(1, N_FAPS + 1)) if faps is None else set(fap_set(faps))
    if rate is not None and float(rate) != stream.fps:
        stream = stream.resample(rate)
    n = stream.n_frames
    if n > MAX_FRAMES:
        raise CodingError(f"the stream has {n} frames; at most {MAX_FRAMES} can be coded")
    if stream.first_frame >= 1 << 32:
        raise CodingError(f"first frame number {stream.first_frame} must be below 2^32")
    name_bytes = len(stream.name.encode("utf-8"))
    if name_bytes > MAX_NAME_BYTES:
        raise CodingError(f"the stream's name has {name_bytes} bytes; at most {MAX_NAME_BYTES}")
    present = stream.mask.any(axis=0)
    coded = tuple(k for k in range(1, N_FAPS + 1) if present[k - 1] and k in wanted)
    low = tuple(k for k in coded if k >= 3)
    base = tuple(own.get(k, FAPS[k - 1].quant_step) for k in low)
    grid = grid_steps(base, q32)
    mask = stream.mask[:, [k - 1 for k in coded]]
    index = quantize(stream, low, grid)
    viseme = stream.viseme if 1 in coded else None
    expression = stream.expression if 2 in coded else None
    t_base: tuple[int, ...] = ()
    t_steps = t_index = None
    if translation and stream.translation is not None:
        t_base = tuple(own.get(a, TRANSLATION_BASE_STEP) for a in TRANSLATION_AXES)
        t_steps = grid_steps(t_base, q32)
        t_index = quantize_translation(stream.translation, t_steps)
    recon = assemble(
        stream.fps,
        stream.name,
        stream.first_frame,
        coded,
        low,
        grid,
        mask,
        index,
        np.zeros((n, 4), np.int64) if viseme is None else viseme,
        np.zeros((n, 6), np.int64) if expression is None else expression,
        t_steps,
        t_index,
    )
    return Plan(stream, coded, low, base, q32, mask, index, recon, t_base, t_index)


def reconstruct(
    stream: FapStream,
    *,
    faps: Iterable[int | str] | str | None = None,
    rate: float | None = None,
    quantizer: float = 1.0,
    translation: bool = True,
    steps: Mapping[int | str, int] | None = None,
) -> FapStream:
    """The stream a decoder reconstructs from ``encode(stream, …)`` with the same arguments
    (either coder): the selected FAPs at ``rate``, low-level values on their quantizer grid, the
    head translation (when the stream has one and ``translation``) on its grid.

    ``decode(encode(s, **kw)) == reconstruct(s, **kw)`` holds exactly (same arrays, name, rate,
    first frame; version 2.1).
    """
    return prepare(stream, faps, rate, quantizer, translation, steps).reconstruction


def source_stream(
    stream: FapStream,
    *,
    faps: Iterable[int | str] | str | None = None,
    rate: float | None = None,
    translation: bool = True,
) -> FapStream:
    """What the encoder codes before quantization: ``stream`` resampled to ``rate`` with only the
    selected FAPs (those masked in some frame) kept, and its head translation if it is sent.
    Compare a decoded stream with this one."""
    plan = prepare(stream, faps, rate, 1.0, translation)
    s = plan.source
    keep = np.zeros(N_FAPS, dtype=bool)
    keep[[k - 1 for k in plan.faps]] = True
    mask = s.mask & keep
    return FapStream(
        fps=s.fps,
        name=s.name,
        values=np.where(mask, s.values, 0.0),
        mask=mask,
        viseme=s.viseme if keep[0] else None,
        expression=s.expression if keep[1] else None,
        first_frame=s.first_frame,
        translation=s.translation if plan.translation_steps else None,
    )


def error_stats(reference: FapStream, decoded: FapStream) -> dict[int | str, tuple[float, float]]:
    """Per low-level FAP set in ``decoded``: ``(max, rms)`` of ``|decoded − reference|`` in FAP
    units over the frames that set it; and when ``decoded`` carries a head translation, the same
    for each of its axes (keys ``"tx"``, ``"ty"``, ``"tz"``, ES units, every frame). The streams
    must have the same frames (and both a translation, or ``decoded`` none)."""
    if reference.n_frames != decoded.n_frames:
        raise FapError(
            f"the streams have {reference.n_frames} and {decoded.n_frames} frames: "
            "compare a decoded stream with source_stream() of the original"
        )
    if decoded.translation is not None and reference.translation is None:
        raise FapError(
            "the decoded stream carries a head translation, the reference none: "
            "compare a decoded stream with source_stream() of the original"
        )
    out: dict[int | str, tuple[float, float]] = {}
    for k in range(3, N_FAPS + 1):
        m = decoded.mask[:, k - 1]
        if m.any():
            d = np.abs(decoded.values[m, k - 1] - reference.values[m, k - 1])
            out[k] = (float(d.max()), float(np.sqrt(np.mean(d * d))))
    if decoded.translation is not None and decoded.n_frames:
        for a, axis in enumerate(TRANSLATION_AXES):
            d = np.abs(decoded.translation[:, a] - reference.translation[:, a])  # type: ignore[index]
            out[axis] = (float(d.max()), float(np.sqrt(np.mean(d * d))))
    return out
