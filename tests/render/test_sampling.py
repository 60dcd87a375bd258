"""Where pixels sample the image plane: supersampling and cameras given by intrinsics alone."""

from __future__ import annotations

import numpy as np

import vtts
from vtts.face import N_PARAMS
from vtts.render.camera import Camera
from vtts.render.renderer import FaceRenderer


def _block_mean(img: np.ndarray, k: int) -> np.ndarray:
    h, w = img.shape[0] // k, img.shape[1] // k
    return img.reshape(h, k, w, k, 3).astype(np.float64).mean(axis=(1, 3))


def test_a_supersampled_frame_is_the_box_average_of_the_larger_frame():
    """Pixel edges at integer coordinates: a camera scaled by 1/k and supersampled k times samples
    exactly the pixels of the full-size camera, so the result is their moving average."""
    model = vtts.load_model("cybatt")
    p = np.zeros(N_PARAMS)
    p[2], p[48] = 200, 4000
    with FaceRenderer(model, size=(352, 288)) as big:
        full = big.render(p)
        cam = big.camera
    small_cam = Camera(
        cam.fx / 4, cam.fy / 4, cam.cx / 4, cam.cy / 4, cam.pose, znear=cam.znear, zfar=cam.zfar
    )
    with FaceRenderer(model, size=(88, 72), camera=small_cam, supersample=4) as small:
        ss = small.render(p).astype(np.float64)
    assert np.abs(ss - _block_mean(full, 4)).max() <= 0.5 + 1e-9


def test_a_camera_given_by_its_intrinsics_is_placed_in_front_of_the_head():
    model = vtts.load_model("cybatt")
    cam = Camera.parse("600,600,150,130")
    assert not cam.placed
    with FaceRenderer(model, size=(352, 288), camera=cam) as r:
        img = r.render(np.zeros(N_PARAMS))
        placed = r.camera
    assert placed.placed and (placed.fx, placed.fy, placed.cx, placed.cy) == (600, 600, 150, 130)
    head = np.any(img != img[0, 0], axis=2)
    ys, xs = np.nonzero(head)
    # the head fills about 80 % of the height, centred on the principal point
    assert 0.7 * 288 < ys.max() - ys.min() < 0.9 * 288
    assert abs((xs.min() + xs.max()) / 2 - 150) < 15 and abs((ys.min() + ys.max()) / 2 - 130) < 15
