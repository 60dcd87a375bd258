"""Synthetic test sequences with known FAPs, as in Eisert & Girod's first experiment.

Their Table 1 comes from a CIF sequence of 100 frames rendered from known FAPs with "a viewing
angle of about 25 degrees", analyzed every fifth frame. :func:`table1_truth` makes such FAP
curves (each FAP sweeps to its extreme and back, at its own pace), :func:`random_truth` seeded
curves through the same FAPs' ranges that start anywhere in them, :func:`side_camera` the
camera 25° to the side of the default framing, and :func:`render_sequence` the frames, with
optional camera noise and a change of light for the harder cases. :func:`relative_errors` is the
table's measure: the mean absolute error of each FAP relative to its extreme value.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from vtts.face import N_PARAMS, FaceModel
from vtts.render.camera import Camera
from vtts.render.renderer import FaceRenderer
from vtts.vrml import rotation_matrix

#: Extreme value of each Table 1 FAP in the synthetic sequence (FAPU; AU = 1e-5 rad for 48–50).
TABLE1_EXTREMES: dict[int, float] = {
    3: 600.0,  # open_jaw
    12: 250.0,  # raise_l_cornerlip
    13: -250.0,  # raise_r_cornerlip
    19: 700.0,  # close_t_l_eyelid
    20: 700.0,  # close_t_r_eyelid
    35: 300.0,  # raise_l_o_eyebrow
    36: -300.0,  # raise_r_o_eyebrow
    48: 12000.0,  # head_pitch, 0.12 rad
    49: -20000.0,  # head_yaw, 0.2 rad
    50: 10000.0,  # head_roll, 0.1 rad
}


def table1_truth(n_frames: int = 100, extremes: dict[int, float] | None = None) -> np.ndarray:
    """``(n_frames, N_PARAMS)`` parameter vectors: every FAP of ``extremes`` starts at 0 and
    follows ``extreme · sin²(π · c · t)`` (t from 0 to 1 over the sequence) with its own number of
    cycles c between 1 and 2, so each reaches its extreme at least once and the FAPs do not move
    in lockstep. Values are integers, as in a FAP stream."""
    extremes = TABLE1_EXTREMES if extremes is None else extremes
    t = np.linspace(0.0, 1.0, n_frames)
    out = np.zeros((n_frames, N_PARAMS))
    for i, (fap, peak) in enumerate(sorted(extremes.items())):
        cycles = 1.0 + (i * 0.37) % 1.0
        out[:, fap - 1] = np.round(peak * np.sin(np.pi * cycles * t) ** 2)
    return out


#: FAPs whose range in :func:`random_truth` is one-sided, from neutral to the extreme: the jaw
#: opens only (FAP 3 is unidirectional), and the eyelids go from open to as far closed as Table 1
#: closes them.
ONE_SIDED: frozenset[int] = frozenset({3, 19, 20, 21, 22})


def table1_range(fap: int, extreme: float) -> tuple[float, float]:
    """The range ``(lo, hi)`` a FAP of :func:`random_truth` moves in: ``[0, extreme]`` (or
    ``[extreme, 0]``) for :data:`ONE_SIDED` FAPs, ``±|extreme|`` for the others."""
    if fap in ONE_SIDED:
        return min(0.0, extreme), max(0.0, extreme)
    return -abs(extreme), abs(extreme)


def random_truth(
    seed: int, n_frames: int = 100, extremes: dict[int, float] | None = None
) -> np.ndarray:
    """``(n_frames, N_PARAMS)`` parameter vectors of the FAPs of ``extremes`` (default
    :data:`TABLE1_EXTREMES`) on seeded random trajectories that start away from neutral.

    Each FAP follows ``lo + (hi − lo) · sin²(π · c · t + φ)`` (t from 0 to 1) over its range
    :func:`table1_range`: its value at frame 0 is uniform in the range (φ from a uniform
    fraction of the range, rising or falling at random), and c is chosen so that its fastest
    motion is that of a :func:`table1_truth` curve (1 to 2 cycles of ``extreme · sin²``): a
    two-sided range sweeps twice the span at half the cycles. Values are integers."""
    extremes = TABLE1_EXTREMES if extremes is None else extremes
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n_frames)
    out = np.zeros((n_frames, N_PARAMS))
    for fap, peak in sorted(extremes.items()):
        lo, hi = table1_range(fap, peak)
        start, falling, pace = rng.uniform(), rng.uniform() < 0.5, rng.uniform(1.0, 2.0)
        phase = np.arcsin(np.sqrt(start))  # sin²(phase) = start
        if falling:
            phase = np.pi - phase
        cycles = pace * abs(peak) / (hi - lo)
        out[:, fap - 1] = np.round(lo + (hi - lo) * np.sin(np.pi * cycles * t + phase) ** 2)
    return out + 0.0  # no negative zeros


def side_camera(model: FaceModel, size: tuple[int, int], angle_deg: float = 25.0) -> Camera:
    """The default framing camera of ``model`` at ``size`` turned ``angle_deg`` about the
    vertical axis through the head's centre (positive: the camera moves to the model's left)."""
    default = FaceRenderer(model, size=size).camera
    turn = np.eye(4)
    turn[:3, :3] = rotation_matrix([0.0, 1.0, 0.0, np.radians(angle_deg)])
    return Camera(
        default.fx,
        default.fy,
        default.cx,
        default.cy,
        turn @ default.pose,
        znear=default.znear,
        zfar=default.zfar,
    )


def render_sequence(
    model: FaceModel,
    params: np.ndarray,
    *,
    size: tuple[int, int] = (352, 288),
    camera: Camera | None = None,
    noise: float = 0.0,
    light: Sequence[float] | None = None,
    seed: int = 0,
) -> list[np.ndarray]:
    """Render ``params`` ``(n, N_PARAMS)`` into ``n`` frames ``(H, W, 3) uint8``.

    ``noise``: standard deviation (gray levels) of Gaussian camera noise added to each frame;
    ``light``: ``(n,)`` brightness factor per frame (1 = as rendered), applied to the rendered
    frame before the noise — a change of illumination the model does not know about."""
    rng = np.random.default_rng(seed)
    out = []
    with FaceRenderer(model, size=size, camera=camera) as r:
        for i, frame in enumerate(r.frames(list(params))):
            img = frame.astype(np.float64)
            if light is not None:
                img = img * float(light[i])
            if noise > 0:
                img = img + rng.normal(0.0, noise, img.shape)
            out.append(np.clip(np.round(img), 0, 255).astype(np.uint8))
    return out


def relative_errors(estimated: np.ndarray, truth: np.ndarray, extremes: np.ndarray) -> np.ndarray:
    """Table 1's measure: ``mean |estimated − truth| / |extreme|`` per column, in percent.
    ``estimated`` and ``truth`` are ``(n, K)``, ``extremes`` ``(K,)``."""
    err = np.abs(np.asarray(estimated, float) - np.asarray(truth, float))
    return 100.0 * err.mean(axis=0) / np.abs(np.asarray(extremes, float))
