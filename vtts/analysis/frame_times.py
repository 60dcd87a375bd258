"""Which frames of a video are analyzed: every ``step``-th, or the frames a coded stream shows.

A stream coded at ``rate`` Hz from a video at ``fps`` shows at its frame ``j`` (time ``j /
rate``) the estimates around that time. Estimated every ``step``-th frame, a video whose rate is
not ``step · rate`` (a 30 fps clip every second frame: 15 Hz, coded at 12.5 Hz) has its
estimates resampled (:meth:`~vtts.fap.stream.FapStream.resample`): two of every five coded
frames then lie midway between two estimates and show their mean, which a head moving jerkily
(Carphone's, a hand-held phone in a car) never took (docs/analysis.md, "Carphone's accurate
geometry"). Analyzed **at the rate**, the frame nearest each time ``j / rate`` is estimated and
the stream carries exactly those estimates: every coded frame is a frame analyzed. On a 25 fps
video at 12.5 Hz that is every second frame; on a 30 fps one frames 0, 2, 5, 7, 10, 12, … (12.5
frames a second analyzed instead of 15).
"""

from __future__ import annotations

import math

from vtts.errors import AnalysisError


def check_rate(fps: float, step: int = 1, rate: float | None = None) -> None:
    """Refuse a ``rate`` (Hz) that is not a positive number at most the video's ``fps``, or
    given with a ``step`` other than 1."""
    if rate is None:
        return
    if not (math.isfinite(rate) and 0 < rate <= fps):
        raise AnalysisError(f"the frames analyzed at {rate:g} Hz: the rate must lie within "
                            f"0–{fps:g} Hz, the video's")  # fmt: skip
    if step != 1:
        raise AnalysisError("analyze every step-th frame or the frames of a rate, not both")


def nearest_frame(j: int, fps: float, rate: float) -> int:
    """The video frame (at ``fps``) nearest time ``j / rate``: ``⌊j · fps / rate + ½⌋``."""
    return math.floor(j * fps / rate + 0.5)


def analyzed(index: int, fps: float, step: int = 1, rate: float | None = None) -> bool:
    """Whether frame ``index`` of a video at ``fps`` is analyzed: every ``step``-th frame, or
    with ``rate`` (Hz) the frame nearest each time ``j / rate`` (:func:`nearest_frame`)."""
    if rate is None:
        return index % step == 0
    j = math.floor(index * rate / fps + 0.5)
    return any(nearest_frame(n, fps, rate) == index for n in (j - 1, j, j + 1))


def analysis_fps(fps: float, step: int = 1, rate: float | None = None) -> float:
    """The rate (Hz) of the estimates of a video at ``fps``: ``rate``, else ``fps / step``."""
    return float(rate) if rate is not None else fps / step
