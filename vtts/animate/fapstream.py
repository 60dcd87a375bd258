"""A FAP stream as per-frame parameter vectors for one personalized model.

:func:`stream_params` turns a :class:`~vtts.fap.FapStream` into ``(n, N_PARAMS)`` parameter
vectors (the layout of :mod:`vtts.face.miap`) at the output frame rate, in four steps:

1. **Hold.** MPEG-4 transmits in each frame only the FAPs its mask sets; a FAP a frame leaves out
   keeps the value it last had (so a stream can send an eyelid only while it blinks). Every FAP,
   the high-level FAPs 1 and 2 included, is therefore carried forward from the last frame that
   set it; before the first frame that sets it, it is 0 (neutral). This happens before
   resampling, so a FAP masked only in some frames never drops to 0 between them.
2. **High-level FAPs.** FAP 1 (viseme_select1, viseme_select2, viseme_blend, viseme_def) becomes
   viseme weights: viseme_select1 gets ``blend / 63``, viseme_select2 gets ``1 − blend / 63``
   (ISO/IEC 14496-2: the blended viseme is ``v1·b/63 + v2·(1 − b/63)``); FAP 2 becomes expression
   weights ``intensity / 63`` for each of its two selects. Select 0 (neutral) adds nothing, and
   two selects naming the same viseme or expression add up. viseme_def, expression_def and
   init_face (a stream redefining the decoder's visemes and expressions) are not interpreted: a
   personalized model brings its own.
3. **Interpolation of FAPs the model cannot show** (below).
4. **Resampling** to the output rate, linear in time (see :func:`resample_params`). The weights
   are interpolated like the low-level FAPs: a viseme switch between two input frames becomes a
   short cross-fade rather than a jump at the nearest frame.

A stream's head translation (:attr:`~vtts.fap.FapStream.translation`, ES units) is resampled the
same way into :attr:`StreamParams.translation`; it is not a parameter of the face but moves the
model as a whole: :func:`translated_root` (one frame) and :func:`head_roots` (every frame) give
the model's root pose, ``translation × ES`` model units from where it stands, in its own ES, so
one stream moves heads of any size alike.

The low-level FAPs 3–68 are placed at ``params[k - 1]`` whether or not the model has tables for
them (a model ignores entries it has no table for).

FAP interpolation
-----------------
MPEG-4 lets a decoder derive FAPs that are not transmitted from ones that are: the FAP
Interpolation Table (FIT, in a model's FaceDefTables) is a graph whose nodes are sets of FAPs and
whose links say how a child node is computed from a parent; a child with several parents is
computed from the first parent whose FAPs are all available, else from the second, and so on.
The MPEG-4 reference software's FIT demonstration (``video/snhc/FIT``, ``test1.fit``) uses the two
canonical relations, which are the rules here, with the identity as the link function:

- **left ↔ right symmetry**: every FAP whose name carries a side token (``l``/``r`` or
  ``lm``/``rm``) and its mirror (19 ↔ 20, 23 ↔ 24, 53 ↔ 54, 55 ↔ 56, …; :data:`MIRROR`);
- **inner ↔ outer lip**: FAPs 4–13 and their outer-lip versions 51–60 (``NAME`` ↔ ``NAME_o``;
  :data:`LIP_LAYER`).

Here the rules serve a model rather than a bitstream: a FAP the stream uses (masked in at least
one frame) but the model has no table for is *moved* onto a counterpart that the model has and
the stream does not set, so that its motion is still seen. Candidates, best first, each rank
tried for all such FAPs before the next (in FAP order within a rank):

1. the same place on the other lip contour (inner ↔ outer), for lip FAPs: the outer lip follows
   the inner one closely, whereas the other side may do something else (a lopsided smile);
2. the mirror FAP on the other side;
3. the other side's other lip contour (a lip FAP's mirror's inner/outer counterpart).

A FAP the model has a table for is never overwritten: a counterpart the stream sets itself, or
that another FAP already filled, is not a candidate. A FAP with no candidate left is *ignored*
(listed in :attr:`StreamParams.ignored`; :func:`warn_ignored` emits one warning naming them all).

Signs: the value is copied unchanged. The FAP table (``positive_motion`` in faps.tsv; ISO/IEC
14496-2 Table C-1) defines every left/right pair so that equal values give the natural paired
motion: vertical, forward and growing motions are the same on both sides, and horizontal ones
are mirror images (stretch_l_cornerlip moves left, stretch_r_cornerlip right; squeeze_l_eyebrow
moves right, squeeze_r_eyebrow left — both towards the nose), so equal values are symmetric. The
one exception to mirroring is gaze: yaw_l_eyeball and yaw_r_eyeball are both positive to the left,
so equal values turn both eyes the same way, which is what a copied gaze must do. Xface's
engine (``XEngine/DeformableGeometry.cpp``, its table of FAP directions) uses the same
conventions. A test checks these properties of the pairs against the FAP table.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Collection, Iterable
from dataclasses import dataclass, field

import numpy as np

from vtts.errors import FapError, VttsWarning
from vtts.face.miap import EXPRESSION_BASE, N_PARAMS, VISEME_BASE, Miap
from vtts.fap import FAPS, N_FAPS, FapStream, Fapu, fap
from vtts.fap.stream import MAX_RESAMPLED_FRAMES
from vtts.fap.table import positive_number

#: The range of FAP 1's viseme_blend and FAP 2's intensities: weight = value / 63.
HIGH_LEVEL_SCALE = 63.0

_SIDE_SWAP = {"l": "r", "r": "l", "lm": "rm", "rm": "lm"}


class MissingTableWarning(VttsWarning):
    """A stream uses FAPs (or visemes, expressions) the model has no table for and that cannot be
    filled from a counterpart: they are ignored."""


def _mirror_pairs() -> dict[int, int]:
    by_name = {d.name: d.number for d in FAPS}
    out = {}
    for d in FAPS:
        tokens = d.name.split("_")
        swapped = [_SIDE_SWAP.get(t, t) for t in tokens]
        if swapped != tokens:
            # A KeyError here means faps.tsv lost one side of a pair.
            out[d.number] = by_name["_".join(swapped)]
    return out


def _lip_layer_pairs() -> dict[int, int]:
    by_name = {d.name: d.number for d in FAPS}
    out = {}
    for d in FAPS:
        outer = by_name.get(d.name + "_o")
        if outer is not None:
            out[d.number] = outer
            out[outer] = d.number
    return out


#: FAP number → the FAP on the other side of the face (23 pairs, both directions).
MIRROR: dict[int, int] = _mirror_pairs()

#: FAP number → the same lip point on the other contour: 4–13 (inner) ↔ 51–60 (outer).
LIP_LAYER: dict[int, int] = _lip_layer_pairs()

if len(MIRROR) != 46 or sorted(LIP_LAYER) != [*range(4, 14), *range(51, 61)]:
    raise FapError("vtts/data/faps.tsv: the left/right or inner/outer lip FAP names are damaged")


def _ranked_candidates(number: int) -> tuple[int | None, int | None, int | None]:
    """FAP ``number``'s other lip contour, other side, and other side's other lip contour."""
    layer = LIP_LAYER.get(number)
    mirror = MIRROR.get(number)
    diagonal = LIP_LAYER[mirror] if layer is not None and mirror is not None else None
    return layer, mirror, diagonal


def fill_candidates(number: int) -> list[int]:
    """FAPs that may stand in for FAP ``number`` on a model without its table, best first:
    the other lip contour, the other side, the other side's other lip contour (see the module
    documentation). Empty for FAPs without counterparts (open_jaw, head rotations, …)."""
    return [k for k in _ranked_candidates(number) if k is not None]


@dataclass(eq=False)
class StreamParams:
    """A FAP stream as per-frame parameter vectors for one model.

    Attributes:
        params: ``(n, N_PARAMS) float64``: frame i's parameter vector (:mod:`vtts.face.miap`:
            ``params[i, k - 1]`` FAP k in FAP units, ``params[i, 68 + v]`` viseme v's weight,
            ``params[i, 83 + e]`` expression e's weight, weights 0–1).
        fps: frames per second of ``params``.
        times: ``(n,) float64`` seconds, frame i at ``i / fps``.
        filled: FAP number → the stream FAP whose values it carries because the model has no
            table for the latter (e.g. ``{19: 20}``: the model's close_t_l_eyelid shows the
            stream's close_t_r_eyelid).
        ignored: FAP numbers (3–68) the stream uses that the model can neither show nor fill,
            ascending.
        missing_visemes: visemes (1–14) the stream gives a weight > 0 but the model has no table
            for, ascending.
        missing_expressions: expressions (1–6) likewise.
        translation: ``(n, 3) float64``: the stream's head translation in each frame, ES units
            (see :attr:`vtts.fap.FapStream.translation`), or None when the stream has none.
    """

    params: np.ndarray
    fps: float
    times: np.ndarray
    filled: dict[int, int] = field(default_factory=dict)
    ignored: list[int] = field(default_factory=list)
    missing_visemes: list[int] = field(default_factory=list)
    missing_expressions: list[int] = field(default_factory=list)
    translation: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.params.shape[0])

    @property
    def duration(self) -> float:
        """Length in seconds: ``n_frames / fps``."""
        return self.n_frames / self.fps


# --- the steps -------------------------------------------------------------------------------


def _last_set(mask: np.ndarray) -> np.ndarray:
    """``(n, c) int64``: for each frame and column, the last frame ≤ it whose mask is set, or -1."""
    n = mask.shape[0]
    idx = np.where(mask, np.arange(n)[:, None], -1)
    return np.maximum.accumulate(idx, axis=0) if n else idx


def hold(stream: FapStream) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The stream with every FAP held from the last frame that set it (MPEG-4 semantics).

    Returns ``values (n, 68) float64`` (0 before a FAP is first set), ``viseme (n, 4) int64``,
    ``expression (n, 6) int64`` (all zero before FAP 1 or 2 is first set) and ``set (n, 68) bool``,
    whether each FAP has been set in or before each frame.
    """
    last = _last_set(stream.mask)
    is_set = last >= 0
    safe = np.maximum(last, 0)
    cols = np.arange(N_FAPS)[None, :]
    values = np.where(is_set, stream.values[safe, cols], 0.0)
    viseme = np.where(is_set[:, :1], stream.viseme[safe[:, 0]], 0)
    expression = np.where(is_set[:, 1:2], stream.expression[safe[:, 1]], 0)
    return values, viseme, expression, is_set


def viseme_weights(viseme: np.ndarray) -> np.ndarray:
    """``(n, 15) float64`` viseme weights (column v = viseme v, column 0 neutral and left 0) from
    ``(n, 4)`` FAP 1 rows: viseme_select1 gets ``blend / 63``, viseme_select2 ``1 − blend / 63``."""
    viseme = np.asarray(viseme)
    n = viseme.shape[0]
    out = np.zeros((n, 15))
    rows = np.arange(n)
    blend = viseme[:, 2] / HIGH_LEVEL_SCALE
    np.add.at(out, (rows, viseme[:, 0]), blend)
    np.add.at(out, (rows, viseme[:, 1]), 1.0 - blend)
    out[:, 0] = 0.0
    return out


def expression_weights(expression: np.ndarray) -> np.ndarray:
    """``(n, 7) float64`` expression weights (column e = expression e, column 0 left 0) from
    ``(n, 6)`` FAP 2 rows: each select gets its ``intensity / 63``."""
    expression = np.asarray(expression)
    n = expression.shape[0]
    out = np.zeros((n, 7))
    rows = np.arange(n)
    np.add.at(out, (rows, expression[:, 0]), expression[:, 1] / HIGH_LEVEL_SCALE)
    np.add.at(out, (rows, expression[:, 2]), expression[:, 3] / HIGH_LEVEL_SCALE)
    out[:, 0] = 0.0
    return out


def plan_fills(used: Iterable[int], shown: Iterable[int]) -> tuple[dict[int, int], list[int]]:
    """Which FAPs stand in for which, by the interpolation rules of this module.

    ``used``: low-level FAP numbers the stream sets (in at least one frame); ``shown``: those the
    model has tables for. Returns ``filled`` (target FAP → source FAP) and ``ignored`` (used FAPs
    neither shown nor filled, ascending). A target is always shown and never used.
    """
    used = set(used)
    shown = set(shown)
    pending = sorted(used - shown)
    filled: dict[int, int] = {}
    for rank in range(3):
        still = []
        for source in pending:
            target = _ranked_candidates(source)[rank]
            free = target in shown and target not in used and target not in filled
            if target is not None and free:
                filled[target] = source
            else:
                still.append(source)
        pending = still
    return filled, pending


def resample_params(params: np.ndarray, fps_in: float, fps_out: float) -> np.ndarray:
    """``(m, p)`` rows at ``fps_out`` from ``(n, p)`` rows at ``fps_in``, linear in time.

    Output frame j is at ``j / fps_out`` s; there are ``round(n · fps_out / fps_in)`` of them, so
    the duration is kept as closely as the new rate allows (times past the last input frame hold
    it). Output frames that coincide in time with an input frame (every 6th at 25 → 30 fps) copy
    it exactly. The same timing as :meth:`vtts.fap.FapStream.resample`.
    """
    fps_in, fps_out = _fps(fps_in), _fps(fps_out)
    params = np.asarray(params, dtype=np.float64)
    n = params.shape[0]
    frames = n * fps_out / fps_in
    if not frames < MAX_RESAMPLED_FRAMES:
        raise FapError(
            f"resampling {n} frames from {fps_in} to {fps_out} fps would make more than "
            f"{MAX_RESAMPLED_FRAMES} frames"
        )
    m = math.floor(frames + 0.5) if n else 0
    pos = np.arange(m, dtype=np.float64) * fps_in / fps_out
    snapped = np.round(pos)
    pos = np.where(np.abs(pos - snapped) < 1e-9, snapped, pos)
    pos = np.minimum(pos, max(n - 1, 0))
    i0 = np.floor(pos).astype(np.int64)
    w = (pos - i0)[:, None]
    i1 = np.minimum(i0 + 1, max(n - 1, 0))
    # (1 - w)·a + w·b with w = 0 must give a exactly, also when b is far from a.
    return np.where(w > 0, (1.0 - w) * params[i0] + w * params[i1], params[i0])


def _miaps(available: Collection[Miap]) -> set[Miap]:
    out = set()
    for m in available:
        if not isinstance(m, Miap):
            raise FapError(f"available must hold Miap objects, got {m!r}")
        out.add(m)
    return out


def stream_params(
    stream: FapStream, available: Collection[Miap], fps: float | None = None
) -> StreamParams:
    """The stream as parameter vectors for a model with tables for the MIAPs ``available``.

    ``available`` is any collection of :class:`~vtts.face.miap.Miap` (``model.tables.adts``
    works as it is). ``fps``: the output frame rate; ``None`` keeps the stream's. Steps (module
    documentation): hold each FAP's last value, FAPs 1 and 2 to viseme and expression weights,
    fill FAPs the model lacks from their counterparts, resample. Raises
    :class:`~vtts.errors.FapError` for a bad ``fps`` or ``available``.
    """
    shown_miaps = _miaps(available)
    fps_out = stream.fps if fps is None else _fps(fps)
    values, viseme, expression, _ = hold(stream)
    n = stream.n_frames

    params = np.zeros((n, N_PARAMS))
    params[:, 2:N_FAPS] = values[:, 2:]
    vw = viseme_weights(viseme)
    ew = expression_weights(expression)
    params[:, VISEME_BASE : VISEME_BASE + 15] = vw
    params[:, EXPRESSION_BASE : EXPRESSION_BASE + 7] = ew

    used = [k for k in range(3, N_FAPS + 1) if stream.mask[:, k - 1].any()]
    shown = {m.number for m in shown_miaps if m.kind == "fap"}
    filled, ignored = plan_fills(used, shown)
    for target, source in filled.items():
        params[:, target - 1] = params[:, source - 1]

    shown_visemes = {m.number for m in shown_miaps if m.kind == "viseme"}
    shown_expressions = {m.number for m in shown_miaps if m.kind == "expression"}
    missing_visemes = [v for v in range(1, 15) if v not in shown_visemes and np.any(vw[:, v] > 0)]
    missing_expressions = [
        e for e in range(1, 7) if e not in shown_expressions and np.any(ew[:, e] > 0)
    ]

    translation = stream.translation
    if fps_out != stream.fps:
        params = resample_params(params, stream.fps, fps_out)
        if translation is not None:
            translation = resample_params(translation, stream.fps, fps_out)
    times = np.arange(params.shape[0], dtype=np.float64) / fps_out
    return StreamParams(
        params=params,
        fps=fps_out,
        times=times,
        filled=dict(sorted(filled.items())),
        ignored=ignored,
        missing_visemes=missing_visemes,
        missing_expressions=missing_expressions,
        translation=None if translation is None else translation.copy(),
    )


# --- the head translation --------------------------------------------------------------------


def translated_root(root_pose: np.ndarray, translation_es: np.ndarray, fapu: Fapu) -> np.ndarray:
    """The ``(4, 4)`` pose of a model's root moved by a head translation.

    ``root_pose``: ``(4, 4)``, the root's pose at rest (for a :class:`~vtts.render.FaceRenderer`,
    ``renderer.model_matrix(i)`` before any frame); ``translation_es``: ``(3,)`` in ES units
    (:attr:`vtts.fap.FapStream.translation`: x to the viewer's right, y up, z towards the
    viewer, along the model's axes); ``fapu``: the model's FAPUs (``model.fapu``). The root
    moves by ``translation_es · fapu.es`` model units along its own axes: ``root_pose @
    T(translation_es · fapu.es)``, which for the renderer's roots (translations only) adds the
    offset to the root's position, as the analysis does. The inverse, a root offset ``d`` in
    model units as ES units, is ``R⁻¹ d / fapu.es`` (``d / fapu.es`` for those roots).
    """
    return head_roots(root_pose, np.asarray(translation_es, dtype=np.float64)[None], fapu)[0]


def head_roots(root_pose: np.ndarray, translation_es: np.ndarray, fapu: Fapu) -> np.ndarray:
    """``(n, 4, 4)``: :func:`translated_root` for each row of ``translation_es`` ``(n, 3)``."""
    root = np.asarray(root_pose, dtype=np.float64)
    t = np.asarray(translation_es, dtype=np.float64)
    if root.shape != (4, 4):
        raise FapError(f"a root pose has shape (4, 4), got {root.shape}")
    if t.ndim != 2 or t.shape[1] != 3:
        raise FapError(f"a head translation has shape (n, 3), got {t.shape}")
    if not isinstance(fapu, Fapu):
        raise FapError(f"the head translation needs the model's FAPUs, got {fapu!r}")
    out = np.repeat(root[None], t.shape[0], axis=0)
    out[:, :3, 3] += (t * fapu.es) @ root[:3, :3].T
    return out


def model_roots(
    params: StreamParams, root_pose: np.ndarray, fapu: Fapu | None, model_name: str | None = None
) -> np.ndarray | None:
    """The model's root pose in each frame of ``params`` ``(n, 4, 4)``, moved by the stream's
    head translation (:func:`head_roots`); None when the stream carries none, or when the model
    has no FAPUs (its tables give no feature points to measure ES on): then a
    :class:`MissingTableWarning` says the translation is ignored."""
    if params.translation is None:
        return None
    if fapu is None:
        who = f"model {model_name}" if model_name else "the model"
        warnings.warn(
            MissingTableWarning(
                f"{who} has no FAPUs (no feature points to measure its eye separation on): the "
                "stream's head translation is ignored"
            ),
            stacklevel=2,
        )
        return None
    return head_roots(root_pose, params.translation, fapu)


# --- the warning -----------------------------------------------------------------------------


def missing_fap_warning(
    ignored: Iterable[int],
    model_name: str | None = None,
    *,
    visemes: Iterable[int] = (),
    expressions: Iterable[int] = (),
) -> str:
    """One message naming what a model cannot show, e.g. ``"model cybatt has no tables for
    FAPs 27 thrust_l_eyeball, 28 thrust_r_eyeball; they are ignored"``.

    ``ignored``: FAP numbers; ``visemes``, ``expressions``: numbers of those the model lacks.
    Empty string when all three are empty.
    """
    faps = sorted(set(ignored))
    vis = sorted(set(visemes))
    exps = sorted(set(expressions))
    groups = []
    if faps:
        word = "FAPs" if len(faps) > 1 else "FAP"
        groups.append(word + " " + ", ".join(f"{k} {fap(k).name}" for k in faps))
    for kind, numbers in (("viseme", vis), ("expression", exps)):
        if numbers:
            word = kind + ("s" if len(numbers) > 1 else "")
            groups.append(word + " " + ", ".join(f"{k} ({Miap(kind, k).name})" for k in numbers))
    if not groups:
        return ""
    count = len(faps) + len(vis) + len(exps)
    what = groups[0] if len(groups) == 1 else ", ".join(groups[:-1]) + " and " + groups[-1]
    who = f"model {model_name}" if model_name else "the model"
    if count == 1:
        return f"{who} has no table for {what}; it is ignored"
    return f"{who} has no tables for {what}; they are ignored"


def warn_ignored(
    model_name: str | None,
    ignored: Iterable[int] | StreamParams,
    *,
    visemes: Iterable[int] = (),
    expressions: Iterable[int] = (),
) -> str | None:
    """Emit one :class:`MissingTableWarning` naming what the model cannot show, if anything.

    ``ignored`` is a list of FAP numbers or a :class:`StreamParams` (whose ignored FAPs, missing
    visemes and missing expressions are all named). Returns the message, or None when nothing is
    ignored (and nothing is emitted).
    """
    if isinstance(ignored, StreamParams):
        visemes = [*visemes, *ignored.missing_visemes]
        expressions = [*expressions, *ignored.missing_expressions]
        ignored = ignored.ignored
    message = missing_fap_warning(ignored, model_name, visemes=visemes, expressions=expressions)
    if not message:
        return None
    warnings.warn(MissingTableWarning(message), stacklevel=2)
    return message


def _fps(fps: object) -> float:
    return positive_number("fps", fps)
