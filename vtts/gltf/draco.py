"""``KHR_draco_mesh_compression``: a primitive's attributes and triangles compressed by Google's
Draco library, decoded with DracoPy."""

from __future__ import annotations

import numpy as np


class DracoError(ValueError):
    """Draco data that does not decode to a triangle mesh."""


def decode_draco(data: bytes) -> tuple[dict[int, np.ndarray], np.ndarray]:
    """The attributes and triangles of a Draco-compressed mesh: ``{unique id: (v, k) array}``
    (the integer or float values as decoded) and ``(m, 3) int64`` vertex indices. Raises
    :class:`DracoError`."""
    try:
        import DracoPy
    except ImportError:  # pragma: no cover - a dependency of vtts
        raise DracoError("the DracoPy package is not installed") from None
    try:
        mesh = DracoPy.decode(bytes(data))
    except Exception as e:  # DracoPy raises its own exception types and ValueError
        raise DracoError(f"cannot decode the Draco data: {short_reason(e)}") from None
    faces = getattr(mesh, "faces", None)
    if faces is None or not len(faces):
        raise DracoError("the Draco data is a point cloud, not triangles")
    attributes = {}
    for att in mesh.attributes:
        a = np.asarray(att["data"])
        attributes[int(att["unique_id"])] = a.reshape(len(a), -1)
    return attributes, np.asarray(faces, dtype=np.int64)


def short_reason(e: BaseException) -> str:
    """The first line of an exception's message (its type when it has none), at most 200
    characters: a library's error quoted in ours."""
    text = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    return text[:200]
