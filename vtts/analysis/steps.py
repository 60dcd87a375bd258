"""Base steps of the FAP coder that spend its bits where the face's image shows them.

The coder (:mod:`vtts.fap.coding`) puts each FAP on a grid of ``base step · quantizer``; MPEG-4's
base steps (``quant_step`` in ``faps.tsv``, and :data:`~vtts.fap.coding.TRANSLATION_BASE_STEP`
for the head translation) were set FAP by FAP, each moving its feature point by about a tenth of
a pixel on a CIF head. But one step of a lip corner moves a few hundred pixels of the face, one
step of the head's rotation every one of them: for the squared error of the decoded face (the
face PSNR) the steps of the lips are too fine and cost bits the image does not show.

For uniform quantizers at a high rate the squared error a FAP adds is ``step² / 12`` times
``w``, the summed squared change of the face's luminance per unit of that FAP, and the bits it
costs fall by one for every doubling of its step; the error for a given number of bits is then
least when every FAP adds the same, ``step_k² · w_k`` alike (the classic allocation for
independent Gaussian sources at high rate). :func:`coding_steps` renders the model once at a
pose, takes each pixel's image motion per unit of each unknown (Equations 9, 14 and 15, as the
estimator does) through the rendered luminance's gradient, sums ``w_k`` over the pixels the model
covers, and returns ``c / √w_k`` with ``c`` chosen so that one step of every unknown together
costs the face what MPEG-4's steps cost: at the same quantizer the face is reproduced about as
closely, for fewer bits (on Akiyo and Carphone, a third fewer at quantizer 1; see
``docs/analysis.md``). The steps go in the bitstream's header, so every decoder reads the stream
as it reads any other.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from vtts.analysis.estimator import LUMA, PYRAMID, Estimator
from vtts.analysis.result import TRANSLATION, Analysis
from vtts.analysis.solve import smooth
from vtts.errors import AnalysisError
from vtts.face import N_PARAMS, FaceModel
from vtts.fap.coding import MAX_BASE_STEP, TRANSLATION_BASE_STEP
from vtts.fap.table import FAPS
from vtts.render.camera import Camera


def coding_steps(
    model: FaceModel,
    camera: Camera | None,
    size: tuple[int, int],
    unknowns: Sequence[int | str],
    *,
    params: np.ndarray | None = None,
    translation: np.ndarray | None = None,
    model_camera: Camera | None = None,
) -> dict[int | str, int]:
    """Base steps for :func:`vtts.fap.coding.encode` (its ``steps``) of the FAPs and
    translation axes among ``unknowns``, for ``model`` seen through ``camera`` (the renderer's
    world, as :attr:`~vtts.analysis.Analysis.camera`; or ``model_camera`` in the model's own
    coordinates, as a fitted head's ``photo`` Viewpoint gives it; neither: the framing ``vtts
    render`` uses, as the estimator's default) at ``size`` (W, H) pixels, posed at
    ``params`` ``(N_PARAMS,)`` (FAP units; default neutral) and ``translation`` ``(3,)`` (model
    units; default none) — typically the sequence's median pose.

    Returns FAP number → base step (FAP units) and ``"tx"``/``"ty"``/``"tz"`` → base step (ES
    units; none for a model without FAPUs, whose streams carry no translation), whole numbers
    within 1–:data:`~vtts.fap.coding.MAX_BASE_STEP`; an unknown that moves no pixel of the model
    at that pose keeps MPEG-4's step. AnalysisError if the model covers no pixel."""
    fapu = model.fapu
    if fapu is None:  # no ES units: a stream of this model carries no translation
        unknowns = [u for u in unknowns if u not in TRANSLATION]
    if not unknowns:
        return {}
    # the full-size image only (a small video has no room for the coarser levels)
    est = Estimator(model, size=size, camera=camera, model_camera=model_camera,
                    unknowns=unknowns, illumination=False, pyramid=PYRAMID[-1:])  # fmt: skip
    if params is not None:
        est.params[:] = np.asarray(params, dtype=np.float64).reshape(N_PARAMS)
    if translation is not None:
        est.translation[:] = np.asarray(translation, dtype=np.float64).reshape(3)
    image, ids, (top, left) = est._render_window(1, whole=True)
    rows, cols = np.nonzero(ids >= 0)
    if rows.size == 0:
        raise AnalysisError("the model covers no pixel through this camera: no steps to measure")
    pix = np.stack([cols + (left + 0.5), rows + (top + 0.5)], axis=1)
    _, _, du, dv = est._image_motion(pix, ids[rows, cols], est._levels[1][0])
    luma = smooth(image, est.sigma) @ LUMA
    gy, gx = np.gradient(luma)
    change = gx[rows, cols, None] * du + gy[rows, cols, None] * dv  # (N, K) per unit
    weight = (change.astype(np.float64) ** 2).sum(axis=0)  # (K,)
    default, scale = [], []
    for u in est.unknowns:
        if isinstance(u, str):
            default.append(TRANSLATION_BASE_STEP)
            scale.append(fapu.es**2)  # per ES unit instead of per model unit
        else:
            default.append(FAPS[u - 1].quant_step)
            scale.append(1.0)
    weight = weight * np.array(scale)
    default_steps = np.array(default, dtype=np.float64)
    seen = weight > 0
    if not seen.any():
        return {u: int(d) for u, d in zip(est.unknowns, default, strict=True)}
    c = np.sqrt(np.mean(default_steps[seen] ** 2 * weight[seen]))
    steps = np.where(seen, c / np.sqrt(np.where(seen, weight, 1.0)), default_steps)
    steps = np.clip(np.rint(steps), 1, MAX_BASE_STEP).astype(int)
    return {u: int(s) for u, s in zip(est.unknowns, steps, strict=True)}


def analysis_steps(analysis: Analysis, model: FaceModel, size: tuple[int, int]) -> dict:
    """:func:`coding_steps` for ``analysis``'s unknowns on ``model`` (the head it was estimated
    with) through its camera at ``size`` (W, H), at the sequence's median pose (over the frames
    that were estimated, not held)."""
    shown = [fe for fe in analysis.frames if not np.isnan(fe.psnr)] or analysis.frames
    if not shown:
        raise AnalysisError("an analysis without frames has no pose to measure the steps at")
    params = np.median([fe.params for fe in shown], axis=0)
    translation = np.median([fe.translation for fe in shown], axis=0)
    return coding_steps(model, analysis.camera, size, analysis.unknowns, params=params,
                        translation=translation)  # fmt: skip
