"""Mesh geometry every layer shares: which triangles touch a vertex, vertex normals, and where a
pixel's ray meets its triangle.

The lowest layer of vtts's own geometry (it imports nothing of vtts but, for types, the camera):
the renderer, the glTF export, the analysis and the photo fit import it downward.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

if TYPE_CHECKING:
    from vtts.render.camera import Camera


def incidence(faces: np.ndarray, n_vertices: int) -> sp.csr_matrix:
    """``(V, m)``: which of the ``faces (m, 3)`` touch each of the ``n_vertices`` vertices (1 where
    a triangle uses a vertex)."""
    m = faces.shape[0]
    return sp.csr_matrix(
        (np.ones(3 * m), (faces.reshape(-1), np.repeat(np.arange(m), 3))), shape=(n_vertices, m)
    )


def vertex_normals(
    positions: np.ndarray, faces: np.ndarray, incidence: sp.csr_matrix
) -> np.ndarray:
    """Area-weighted unit vertex normals ``(n, 3)`` from ``positions (n, 3)`` and
    ``faces (m, 3)``, summing over each vertex's triangles through ``incidence (n, m)``; for
    ``positions (T, n, 3)``, the normals of each of the T shapes ``(T, n, 3)``, the same
    numbers as one by one (one sparse product for all)."""
    single = positions.ndim == 2
    p = positions[None] if single else positions
    # np.cross on gathered (m, 3, 3) corners, computed per coordinate on contiguous columns:
    # the same arithmetic (so the same bits), without the strided gathers
    x, y, z = (np.ascontiguousarray(p[..., k]) for k in range(3))  # (T, n)
    i0, i1, i2 = faces[:, 0], faces[:, 1], faces[:, 2]
    ax, ay, az = x[:, i0], y[:, i0], z[:, i0]
    ux, uy, uz = x[:, i1] - ax, y[:, i1] - ay, z[:, i1] - az
    vx, vy, vz = x[:, i2] - ax, y[:, i2] - ay, z[:, i2] - az
    t = p.shape[0]
    fn = np.empty((faces.shape[0], t, 3))  # triangle-major: one product sums them all
    fn[:, :, 0] = (uy * vz - uz * vy).T
    fn[:, :, 1] = (uz * vx - ux * vz).T
    fn[:, :, 2] = (ux * vy - uy * vx).T
    vn = (incidence @ fn.reshape(faces.shape[0], 3 * t)).reshape(-1, t, 3).transpose(1, 0, 2)
    norm = np.linalg.norm(vn, axis=2, keepdims=True)
    out = np.divide(vn, norm, out=np.zeros_like(vn), where=norm > 0)
    return out[0] if single else out


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
