"""The geometry glTF stores its own way: quaternions, triangle strips and fans, texture
transforms."""

from __future__ import annotations

import math

import numpy as np

from vtts.gltf.spec import TRIANGLE_FAN, TRIANGLES


def quat_matrix(q: np.ndarray) -> np.ndarray:
    """The rotation matrix ``(3, 3)`` of a glTF quaternion ``(x, y, z, w)`` (normalized here;
    a zero quaternion is the identity)."""
    n = float(np.linalg.norm(q))
    if not n > 0 or not math.isfinite(n):
        return np.eye(3)
    x, y, z, w = np.asarray(q, dtype=np.float64) / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def triangles(idx: np.ndarray, mode: int) -> np.ndarray:
    """``(m, 3)`` triangles of an index list ``(n,)`` drawn as TRIANGLES, TRIANGLE_STRIP or
    TRIANGLE_FAN."""
    n = idx.size
    if mode == TRIANGLES:
        return idx[: n - n % 3].reshape(-1, 3)
    if n < 3:
        return np.zeros((0, 3), dtype=np.int64)
    k = np.arange(n - 2)
    if mode == TRIANGLE_FAN:
        return np.c_[np.full(n - 2, idx[0]), idx[k + 1], idx[k + 2]]
    even = k % 2 == 0  # a strip's odd triangles are wound the other way round
    a = np.where(even, idx[k], idx[k + 1])
    b = np.where(even, idx[k + 1], idx[k])
    return np.c_[a, b, idx[k + 2]]


def uv_transform(ext: dict) -> np.ndarray:
    """``(3, 3)`` the KHR_texture_transform matrix (translation · rotation · scale) on
    ``(u, v, 1)``; bad values are left at their defaults."""
    offset = floats(ext.get("offset"), [0.0, 0.0], 2)
    scale = floats(ext.get("scale"), [1.0, 1.0], 2)
    (rotation,) = floats([ext.get("rotation")], [0.0], 1)
    c, s = math.cos(rotation), math.sin(rotation)
    t = np.array([[1, 0, offset[0]], [0, 1, offset[1]], [0, 0, 1]])
    # the extension's GLSL: mat3(cos, sin, 0, -sin, cos, 0, 0, 0, 1), filled column by column
    r = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return t @ r @ np.diag([scale[0], scale[1], 1.0])


def floats(values, default: list, n: int) -> list[float]:
    """``values`` as ``n`` finite floats, else ``default`` (a glTF property of the wrong kind is
    left at its default)."""
    if values is None or (len(values) == 1 and values[0] is None):
        return [float(v) for v in default]
    try:
        out = [float(v) for v in values]
    except (TypeError, ValueError):
        return [float(v) for v in default]
    if len(out) != n or not all(math.isfinite(v) for v in out):
        return [float(v) for v in default]
    return out
