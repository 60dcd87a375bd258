"""Where a pixel's ray meets the triangle the pixel shows.

The renderer numbers the triangle each pixel shows in the same rasterization that draws the
colors (:meth:`vtts.render.renderer.FaceRenderer.render` with ``triangles``); the barycentric
coordinates and depth of the pixel's 3D point then follow exactly from the pixel's ray.
"""

from __future__ import annotations

import numpy as np

from vtts.render.camera import Camera


def ray_barycentrics(
    pixels: np.ndarray, camera: Camera, triangles: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where the rays of ``pixels`` meet their triangles.

    ``pixels`` ``(N, 2)`` are (X, Y) image coordinates (pixel centres at ``col + 0.5``,
    ``row + 0.5``); ``triangles`` ``(N, 3, 3)`` the world positions of each pixel's triangle.
    Returns the barycentric coordinates ``(N, 3)`` (perspective-correct: the 3D point is
    ``Σ λ_m v_m``) and the camera-space points ``(N, 3)`` (OpenGL camera: looking along −z).
    """
    inv = np.linalg.inv(camera.pose)
    v = triangles @ inv[:3, :3].T + inv[:3, 3]  # camera space (N, 3, 3)
    d = np.stack(
        [
            (pixels[:, 0] - camera.cx) / camera.fx,
            -(pixels[:, 1] - camera.cy) / camera.fy,
            -np.ones(len(pixels)),
        ],
        axis=1,
    )
    # Möller–Trumbore with the ray from the camera centre (the origin)
    e1 = v[:, 1] - v[:, 0]
    e2 = v[:, 2] - v[:, 0]
    pv = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    det = np.where(np.abs(det) < 1e-300, 1e-300, det)
    tv = -v[:, 0]
    b1 = np.einsum("ij,ij->i", tv, pv) / det
    qv = np.cross(tv, e1)
    b2 = np.einsum("ij,ij->i", d, qv) / det
    t = np.einsum("ij,ij->i", e2, qv) / det
    lam = np.stack([1 - b1 - b2, b1, b2], axis=1)
    return lam, d * t[:, None]
