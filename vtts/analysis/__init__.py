"""Estimating facial animation parameters from video (Eisert & Girod 1998).

``analyze(frames, model, fps=…)`` returns an :class:`Analysis`; :class:`Estimator` tracks one
model frame by frame. See ``docs/analysis.md``.
"""

from vtts.analysis.estimator import (
    DEFAULT_UNKNOWNS,
    PYRAMID,
    TABLE1_FAPS,
    Estimator,
    Level,
    analyze,
    face_psnr,
)
from vtts.analysis.result import Analysis, FrameEstimate

__all__ = [
    "DEFAULT_UNKNOWNS",
    "PYRAMID",
    "TABLE1_FAPS",
    "Analysis",
    "Estimator",
    "FrameEstimate",
    "Level",
    "analyze",
    "face_psnr",
]
