"""Which frame of a video file to make the head from: the one whose face looks most like the
face in the others.

A head made for a video takes the frame it is fitted to as its texture
(:func:`vtts.fit.with_frame`), so every later frame is matched against that frame's eyes, mouth
and light. The first frame is often not typical: Akiyo looks up at the camera at first and down
at her notes for most of the sequence, and a head made from her first frame shows open eyes the
decoder draws in every frame. :func:`anchor_frame` samples the video, aligns each sample's face
to the mean of their landmarks (a similarity transform), compares the aligned faces' gray levels
(each normalized to zero mean and unit deviation) and returns the sample whose face is nearest
to all the others on average (the medoid). The tracker then fits the head there and tracks the
video from there backwards to its start and forwards to its end
(:func:`vtts.analysis.track.track`'s ``anchor``; :func:`choose_anchor` looks at the first
:data:`ANCHOR_SECONDS` of a file).

A stream has no later frames to look at: it keeps the first frame with a face.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable

import numpy as np
from scipy.ndimage import map_coordinates

from vtts.analysis.frame_times import analyzed

#: Frames sampled, spread evenly over the part of the video looked at.
SAMPLES = 30
#: The head is made from a frame of the video's first this many seconds: the frames before the
#: chosen one are kept in memory until it is reached, then tracked backwards from it.
ANCHOR_SECONDS = 20.0
#: The aligned face is compared on a GRID × GRID raster over the landmarks' bounding box.
GRID = 48


def choose_anchor(frames: Iterable[np.ndarray], fps: float, n_frames: int | None = None, *,
                  step: int = 1, detector=None,
                  rate: float | None = None) -> int | None:  # fmt: skip
    """The index of the frame of a video file to make the head from (for
    :func:`vtts.analysis.track.track`'s ``anchor``): :func:`anchor_frame` over the frames
    analyzed (every ``step``-th, or those of ``rate`` Hz: :mod:`vtts.analysis.frame_times`) of
    the first :data:`ANCHOR_SECONDS` of ``frames`` (``(H, W, 3) uint8``, ``n_frames`` of them
    when known, at ``fps``); None where none shows a face."""
    span = max(1, int(ANCHOR_SECONDS * fps))
    count = span if n_frames is None else min(int(n_frames), span)
    indices = [i for i in range(count) if analyzed(i, fps, step, rate)]
    chosen = (f for i, f in enumerate(itertools.islice(frames, count))
              if analyzed(i, fps, step, rate))  # fmt: skip
    found = anchor_frame(chosen, len(indices), detector=detector)
    return None if found is None else indices[found[0]]


def anchor_frame(
    frames: Iterable[np.ndarray],
    n_frames: int,
    *,
    detector=None,
    samples: int = SAMPLES,
) -> tuple[int, np.ndarray] | None:
    """``(index, frame)`` of the frame among ``frames`` (each ``(H, W, 3) uint8``, ``n_frames``
    of them) whose face looks most like the faces of the others, or None where no sampled
    frame shows a face. Every ``max(1, n_frames // samples)``-th frame is looked at (the
    largest face of each)."""
    from vtts.fit.landmarks import detect_faces

    every = max(1, int(n_frames) // max(1, samples))
    seen: list[tuple[int, np.ndarray, np.ndarray]] = []
    for index, frame in enumerate(frames):
        if index % every:
            continue
        faces = detect_faces(frame, detector)
        if faces:
            seen.append((index, frame, np.asarray(faces[0].landmarks, np.float64)[:, :2]))
    if not seen:
        return None
    if len(seen) <= 2:
        return seen[0][0], seen[0][1]
    mean = np.mean([points for _, _, points in seen], axis=0)
    lo, hi = mean.min(axis=0), mean.max(axis=0)
    rows, cols = np.mgrid[0:GRID, 0:GRID]
    grid = np.c_[lo[0] + (cols.ravel() + 0.5) / GRID * (hi[0] - lo[0]),
                 lo[1] + (rows.ravel() + 0.5) / GRID * (hi[1] - lo[1])]  # fmt: skip
    faces = np.array([_aligned(frame, points, mean, grid) for _, frame, points in seen])
    distance = np.sqrt(((faces[:, None] - faces[None]) ** 2).mean(axis=-1))
    best = int(np.argmin(distance.sum(axis=1)))
    return seen[best][0], seen[best][1]


def _aligned(frame: np.ndarray, points: np.ndarray, mean: np.ndarray,
             grid: np.ndarray) -> np.ndarray:  # fmt: skip
    """The gray levels of ``frame`` at the ``grid (G², 2)`` points of the mean face, carried
    onto the frame's face by the similarity that maps ``mean`` onto its landmarks ``points``
    (least squares), normalized to zero mean and unit deviation: ``(G²,)``."""
    src, dst = points - points.mean(axis=0), mean - mean.mean(axis=0)
    u, s, vt = np.linalg.svd(dst.T @ src)
    if np.linalg.det(u @ vt) < 0:  # a rotation, not a mirror
        u[:, -1] *= -1
        s[-1] *= -1
    rotation = u @ vt
    scale = s.sum() / max(float((dst**2).sum()), 1e-12)
    at = (grid - mean.mean(axis=0)) @ (scale * rotation) + points.mean(axis=0)
    gray = np.asarray(frame, np.float64).mean(axis=-1)
    values = map_coordinates(gray, [at[:, 1] - 0.5, at[:, 0] - 0.5], order=1, mode="nearest")
    return (values - values.mean()) / (values.std() + 1e-6)
