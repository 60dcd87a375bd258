"""Synthetic test sequences with known FAPs, as in Eisert & Girod's first experiment.

Their Table 1 comes from a CIF sequence of 100 frames rendered from known FAPs with "a viewing
angle of about 25 degrees", analyzed every fifth frame. :func:`table1_truth` makes such FAP
curves (each FAP sweeps to its extreme and back, at its own pace), :func:`side_camera` the
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
