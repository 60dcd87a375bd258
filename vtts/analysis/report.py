"""The report of an analysis: a CSV of every estimate and two plots.

:func:`write_report` writes into a folder

``frames.csv``
    one row per analyzed frame: ``frame`` (index in the video), ``time`` (s), ``psnr_db``
    (face-area PSNR, ``inf`` when the rendered model matches the frame exactly), ``face_pixels``,
    ``iterations``, ``landmark_px`` (the median distance in pixels between the frame's face
    mesh landmarks and where the estimate puts their points; ``nan`` where none were
    observed), ``held`` (1 where the frame had no estimate of its own and the last good one
    stands in, else 0), then one column per unknown in the analysis' order — ``fapK`` in the FAP's
    unit (FAPU, AU for rotations), ``tx``/``ty``/``tz`` in model units — and the photometric
    correction ``gain_r/g/b``, ``offset_r/g/b`` (camera ≈ gain · synthetic + offset, 0–255).
``psnr.png``
    the face-area PSNR over time, with its mean.
``faps.png``
    one small plot per estimated FAP over time (and the translation, when estimated), with the
    true values dashed when they are known.

and :func:`write_side_by_side` (``vtts analyze --report``) adds ``side-by-side.mp4``: each
analyzed camera frame, the decoder's view of its estimate (the model rendered from the stream
alone, :func:`vtts.analysis.quality.decoded_frames`) and their difference, amplified.

matplotlib is imported only here, and only its object-oriented API is used (no pyplot, no
global backend switch): figures render with Agg whatever backend the caller's process uses.
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from vtts.analysis.result import TRANSLATION, Analysis
from vtts.atomic import atomic_path, write_text
from vtts.errors import AnalysisError
from vtts.face import FaceModel

#: The report's file names.
CSV_NAME = "frames.csv"
PSNR_PLOT = "psnr.png"
FAPS_PLOT = "faps.png"
SIDE_BY_SIDE = "side-by-side.mp4"
#: Every file ``vtts analyze --report`` writes (checked against its inputs before any work).
REPORT_FILES = (CSV_NAME, PSNR_PLOT, FAPS_PLOT, SIDE_BY_SIDE)

#: How far above the best finite PSNR infinite values are drawn (dB), and where when no value
#: is finite.
_INF_MARGIN_DB = 5.0
_INF_ALONE_DB = 100.0

#: The least y range of a plot: a FAP that barely moves is drawn flat, not as magnified noise.
_MIN_SPAN_PSNR_DB = 1.0
_MIN_SPAN_FAP = 10.0  # FAPU (or AU)
_MIN_SPAN_TRANSLATION = 1e-3  # model units

_CHANNELS = "rgb"


def csv_columns(analysis: Analysis) -> list[str]:
    """The header of ``frames.csv``."""
    cols = ["frame", "time", "psnr_db", "face_pixels", "iterations", "landmark_px", "held"]
    cols += [f"fap{u}" if isinstance(u, int) else u for u in analysis.unknowns]
    cols += [f"gain_{c}" for c in _CHANNELS] + [f"offset_{c}" for c in _CHANNELS]
    return cols


def _number(x: float) -> str:
    """A float as the CSV writes it: shortest round-trip text, ``inf``/``-inf``/``nan``."""
    return repr(float(x))


def format_csv(analysis: Analysis) -> str:
    """The text of ``frames.csv`` (one header line, one line per estimate)."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(csv_columns(analysis))
    for fe in analysis.frames:
        row = [str(fe.index), _number(fe.time), _number(fe.psnr)]
        row += [str(int(fe.face_pixels)), str(int(fe.iterations)), _number(fe.landmark_px)]
        row.append("1" if fe.held else "0")
        for u in analysis.unknowns:
            if isinstance(u, int):
                row.append(_number(fe.params[u - 1]))
            else:
                row.append(_number(fe.translation[TRANSLATION.index(u)]))
        row += [_number(v) for v in np.asarray(fe.gain, dtype=float).reshape(3)]
        row += [_number(v) for v in np.asarray(fe.offset, dtype=float).reshape(3)]
        w.writerow(row)
    return out.getvalue()


def mean_psnr(psnr: np.ndarray) -> float:
    """The mean of the finite PSNRs (dB); ``inf`` when every frame is identical to its
    synthetic image, ``nan`` when there is no value at all."""
    p = np.asarray(psnr, dtype=np.float64)
    finite = p[np.isfinite(p)]
    if finite.size:
        return float(finite.mean())
    return math.inf if np.any(np.isposinf(p)) else math.nan


def write_report(
    analysis: Analysis,
    directory: str | os.PathLike[str],
    *,
    truth: np.ndarray | None = None,
) -> list[Path]:
    """Write ``frames.csv``, ``psnr.png`` and ``faps.png`` into ``directory`` (created if
    needed; each file appears complete or not at all). Returns the paths written.

    ``truth`` is the ``(n_frames, len(analysis.faps))`` array of true FAP values (FAPU), in the
    order of :attr:`Analysis.faps`, for synthetic test sequences; it is drawn dashed.
    """
    d = Path(directory)
    if truth is not None:
        truth = np.asarray(truth, dtype=np.float64)
        want = (len(analysis.frames), len(analysis.faps))
        if truth.shape != want:
            raise AnalysisError(
                f"truth must be (n_frames, n_faps) = {want}, one column per estimated FAP, "
                f"got {truth.shape}"
            )
    if d.exists() and not d.is_dir():
        raise AnalysisError("the report folder is a file", file=str(d))
    d.mkdir(parents=True, exist_ok=True)
    written = [d / CSV_NAME, d / PSNR_PLOT, d / FAPS_PLOT]
    write_text(written[0], format_csv(analysis))
    _save(psnr_figure(analysis), written[1])
    _save(faps_figure(analysis, truth), written[2])
    return written


def write_side_by_side(
    directory: str | os.PathLike[str],
    frames: Iterable[np.ndarray],
    analysis: Analysis,
    model: FaceModel,
) -> Path:
    """Write ``side-by-side.mp4`` into ``directory`` at the analysis's rate: for each analyzed
    frame (``frames`` is the whole video, ``(H, W, 3) uint8`` each; those the analysis skipped
    are passed over) the camera frame, the decoder's view of the estimate (the FAPs as the
    stream carries them and the head translation, through the analysis's camera, without the
    light correction, which a stream does not carry) and their difference ×4
    (:func:`vtts.analysis.quality.side_by_side`). Returns the path."""
    from vtts.analysis.quality import decoded_frames, side_by_side
    from vtts.render import VideoWriter

    path = Path(directory) / SIDE_BY_SIDE
    stream = analysis.stream(fapu=model.fapu)
    wanted = iter(fe.index for fe in analysis.frames)
    next_index = next(wanted, None)
    views = None
    writer = None
    with contextlib.ExitStack() as stack:
        for i, frame in enumerate(frames):
            if next_index is None:
                break
            if i != next_index:
                continue
            if views is None:
                h, w = frame.shape[:2]
                views = decoded_frames(stream, model, (w, h), camera=analysis.camera)
                writer = stack.enter_context(VideoWriter(path, analysis.fps, (3 * w, h)))
            writer.write(side_by_side(frame, next(views)))
            next_index = next(wanted, None)
    return path


def _save(fig, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)


def _times(analysis: Analysis) -> np.ndarray:
    return np.array([fe.time for fe in analysis.frames], dtype=np.float64)


def psnr_figure(analysis: Analysis):
    """The ``psnr.png`` figure: face-area PSNR (dB) over time (s).

    Infinite values (identical images) are drawn as triangles at a ceiling above the best finite
    value and labelled as such."""
    from matplotlib.figure import Figure

    t, p = _times(analysis), analysis.psnr()
    fig = Figure(figsize=(8, 3.2), layout="constrained")
    ax = fig.add_subplot()
    inf = np.isposinf(p)
    finite = np.isfinite(p)
    ceiling = (p[finite].max() + _INF_MARGIN_DB) if finite.any() else _INF_ALONE_DB
    shown = np.where(inf, ceiling, p)
    ax.plot(t, shown, "-", color="C0", lw=1, marker="." if len(t) < 200 else None, ms=3)
    if inf.any():
        ax.plot(
            t[inf],
            shown[inf],
            "^",
            color="C3",
            ms=5,
            label=f"identical (∞), drawn at {ceiling:.1f} dB",
        )
        ax.annotate(
            f"{int(inf.sum())} frame{'s' if inf.sum() != 1 else ''} with infinite PSNR",
            xy=(0.01, 0.97),
            xycoords="axes fraction",
            va="top",
            fontsize=8,
            color="C3",
        )
    mean = mean_psnr(p)
    if math.isfinite(mean):
        ax.axhline(mean, color="0.4", ls="--", lw=0.8, label=f"mean {mean:.2f} dB")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best", fontsize=8)
    _min_span(ax, shown, _MIN_SPAN_PSNR_DB)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("face-area PSNR (dB)")
    ax.set_title(f"PSNR of the synthetic frames — {_title(analysis)}", fontsize=10)
    ax.grid(True, alpha=0.3)
    return fig


def faps_figure(analysis: Analysis, truth: np.ndarray | None = None):
    """The ``faps.png`` figure: one small plot per estimated FAP (its unit on the y axis),
    one more for the head translation when it was estimated; ``truth`` dashed."""
    from matplotlib.figure import Figure

    from vtts.fap.table import fap as fap_def

    t = _times(analysis)
    faps = analysis.faps
    values = analysis.fap_values()
    moves = [u for u in analysis.unknowns if isinstance(u, str)]
    n = len(faps) + (1 if moves else 0)
    cols = max(1, min(4, n))
    rows = max(1, math.ceil(n / cols))
    fig = Figure(figsize=(3.2 * cols, 2.2 * rows + 0.6), layout="constrained")
    axes = fig.subplots(rows, cols, sharex=True, squeeze=False).ravel()
    for j, k in enumerate(faps):
        ax = axes[j]
        d = fap_def(k)
        ax.plot(t, values[:, j], color="C0", lw=1, label="estimate")
        if truth is not None:
            ax.plot(t, truth[:, j], color="C1", lw=1, ls="--", label="truth")
        ax.set_title(f"FAP {k} {d.name}", fontsize=8)
        ax.set_ylabel(d.fapu or "", fontsize=8)
    if moves:
        ax = axes[len(faps)]
        tr = np.array([fe.translation for fe in analysis.frames], dtype=np.float64).reshape(-1, 3)
        for u in moves:
            ax.plot(t, tr[:, TRANSLATION.index(u)], lw=1, label=u)
        ax.set_title("head translation", fontsize=8)
        ax.set_ylabel("model units", fontsize=8)
        ax.legend(fontsize=7, loc="best")
    for j, ax in enumerate(axes[:n]):
        span = _MIN_SPAN_FAP if j < len(faps) else _MIN_SPAN_TRANSLATION
        _min_span(ax, np.concatenate([line.get_ydata() for line in ax.get_lines()]), span)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
    for ax in axes[n:]:
        ax.set_visible(False)
    for ax in axes[max(0, n - cols) : n]:  # the lowest plot of each column, also above a gap
        ax.set_xlabel("time (s)", fontsize=8)
        ax.xaxis.set_tick_params(labelbottom=True)
    if n == 0:
        axes[0].set_visible(True)
        axes[0].text(0.5, 0.5, "no FAPs estimated", ha="center", va="center")
        axes[0].set_axis_off()
    if truth is not None and faps:
        fig.legend(*axes[0].get_legend_handles_labels(), loc="outside upper right", fontsize=8)
    fig.suptitle(f"Estimated FAPs — {_title(analysis)}", fontsize=10)
    return fig


def _min_span(ax, values: np.ndarray, span: float) -> None:
    """Show at least ``span`` on the y axis and plain tick labels: a nearly constant curve reads
    as constant, not as noise magnified under an offset label such as ``+3.07e1``."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size and v.max() - v.min() < span:
        mid = (v.max() + v.min()) / 2
        ax.set_ylim(mid - span / 2, mid + span / 2)
    ax.ticklabel_format(axis="y", useOffset=False)


def _title(analysis: Analysis) -> str:
    n = len(analysis.frames)
    who = f"{analysis.model}, " if analysis.model else ""
    return f"{who}{n} frame{'s' if n != 1 else ''} at {analysis.fps:g} fps"
