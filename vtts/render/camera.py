"""The pinhole camera of Eisert & Girod (their Equation 3) and automatic framing of heads.

Equation 3 maps a point (x, y, z) in camera coordinates to pixel coordinates

    X = X0 − fx · x / z,    Y = Y0 − fy · y / z

with the camera looking along +z, y up and x to the left, X to the right and Y down the image.
That is the standard pinhole model with intrinsics (fx, fy, cx = X0, cy = Y0) measured in pixels
from the top-left corner, which is how pyrender's IntrinsicsCamera takes them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from vtts.errors import RenderError


@dataclass
class Camera:
    """Pinhole intrinsics (pixels) and the camera's pose in the world.

    ``pose`` is the ``(4, 4)`` camera-to-world matrix in the OpenGL convention (the camera looks
    along its −z axis, y up). ``znear``/``zfar`` bound the depth range (model units).
    ``placed`` is False for a camera given by its intrinsics alone (``--camera fx,fy,X0,Y0``):
    the renderer then puts it in front of the heads, far enough for them to fill its view.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    znear: float = 0.01
    zfar: float = 100.0
    placed: bool = True

    def __post_init__(self) -> None:
        for name in ("fx", "fy"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise RenderError(f"camera {name} must be a positive number of pixels, got {v}")
        self.pose = np.asarray(self.pose, dtype=np.float64).reshape(4, 4)

    @classmethod
    def eisert_girod(cls, fx: float, fy: float, x0: float, y0: float, **kw) -> Camera:
        """The camera of Eisert–Girod Equation 3 (``X0``, ``Y0`` in pixels from the top left)."""
        return cls(fx, fy, x0, y0, **kw)

    @classmethod
    def parse(cls, text: str) -> Camera:
        """``"fx,fy,X0,Y0"`` as given on the command line (``--camera 400,400,176,144``)."""
        parts = text.replace(" ", "").split(",")
        try:
            values = [float(p) for p in parts]
        except ValueError:
            values = []
        if len(values) != 4:
            raise RenderError(f"--camera takes four numbers fx,fy,X0,Y0, got {text!r}")
        return cls.eisert_girod(*values, placed=False)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates ``(n, 2)`` (X right, Y down) of world points ``(n, 3)``."""
        p = np.c_[np.asarray(points, float), np.ones(len(points))] @ np.linalg.inv(self.pose).T
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        return np.stack([self.cx + self.fx * x / -z, self.cy - self.fy * y / -z], axis=1)


def look_at(eye: np.ndarray, target: np.ndarray, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """``(4, 4)`` camera-to-world pose of a camera at ``eye`` looking at ``target``."""
    eye, target, up = (np.asarray(v, dtype=np.float64) for v in (eye, target, up))
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    right /= np.linalg.norm(right)
    true_up = np.cross(back, right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, true_up, back, eye
    return m


def frame_bounds(
    lo: np.ndarray,
    hi: np.ndarray,
    size: tuple[int, int],
    *,
    fill: float = 0.8,
    fovy_deg: float = 25,
    intrinsics: Camera | None = None,
) -> Camera:
    """A camera on +z looking at the box ``lo``–``hi`` (world units) so that it fills ``fill`` of
    the image's height or width, whichever is tighter: with a vertical field of view of
    ``fovy_deg`` and the principal point in the middle, or with the focal lengths and principal
    point of ``intrinsics``."""
    w, h = size
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    centre = (lo + hi) / 2
    extent = np.maximum(hi - lo, 1e-6)
    if intrinsics is None:
        f = (h / 2) / math.tan(math.radians(fovy_deg) / 2)
        fx, fy, cx, cy = f, f, w / 2, h / 2
    else:
        fx, fy, cx, cy = intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy
    dist_h = (extent[1] / 2) / (fill * (h / 2) / fy)
    dist_w = (extent[0] / 2) / (fill * (w / 2) / fx)
    dist = max(dist_h, dist_w) + extent[2] / 2
    eye = centre + np.array([0.0, 0.0, dist])
    return Camera(fx, fy, cx, cy, look_at(eye, centre), znear=dist / 50, zfar=dist * 10)
