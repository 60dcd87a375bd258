"""Transform matrices of VRML97 Transform nodes and axis-angle rotations."""

from __future__ import annotations

import numpy as np


def rotation_matrix(rotation: np.ndarray) -> np.ndarray:
    """``(3, 3) float64`` matrix of an SFRotation ``(x, y, z, angle)`` (angle in radians,
    right-handed). A zero axis is the identity."""
    x, y, z, a = (float(v) for v in rotation)
    n = np.sqrt(x * x + y * y + z * z)
    if n == 0.0 or a == 0.0:
        return np.eye(3)
    x, y, z = x / n, y / n, z / n
    c, s, t = np.cos(a), np.sin(a), 1.0 - np.cos(a)
    return np.array(
        [
            [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
            [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
            [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
        ]
    )


def _homogeneous(m3: np.ndarray | None = None, t: np.ndarray | None = None) -> np.ndarray:
    m = np.eye(4)
    if m3 is not None:
        m[:3, :3] = m3
    if t is not None:
        m[:3, 3] = t
    return m


def compose_transform(
    translation: np.ndarray,
    rotation: np.ndarray,
    scale: np.ndarray,
    scale_orientation: np.ndarray,
    center: np.ndarray,
) -> np.ndarray:
    """``(4, 4)`` matrix T·C·R·SR·S·SR⁻¹·C⁻¹ of the VRML97 Transform node (ISO 14772-1 6.52).

    Factors that are exactly the identity (no translation, no center, a zero rotation, unit
    scale) are left out of the product: the same numbers (a product with the identity is exact)
    for a fraction of the work, which counts for a head's Transforms posed many times a frame
    by the estimator."""
    translation = np.asarray(translation, float)
    center = np.asarray(center, float)
    scale = np.asarray(scale, float)
    sr = rotation_matrix(scale_orientation)
    r = rotation_matrix(rotation)
    factors = []
    if translation.any():
        factors.append(_homogeneous(t=translation))
    if center.any():
        factors.append(_homogeneous(t=center))
    if not _is_identity(r):
        factors.append(_homogeneous(r))
    if not (_is_identity(sr) and (scale == 1.0).all()):
        factors += [_homogeneous(sr), _homogeneous(np.diag(scale)), _homogeneous(sr.T)]
    if center.any():
        factors.append(_homogeneous(t=-center))
    if not factors:
        return np.eye(4)
    out = factors[0]
    for f in factors[1:]:
        out = out @ f
    return out


def _is_identity(m3: np.ndarray) -> bool:
    return bool((m3 == _EYE3).all())


_EYE3 = np.eye(3)


def transform_matrix(node) -> np.ndarray:
    """The ``(4, 4) float64`` local-to-parent matrix of a Transform node."""
    return compose_transform(
        node["translation"],
        node["rotation"],
        node["scale"],
        node["scaleOrientation"],
        node["center"],
    )
