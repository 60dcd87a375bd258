"""``EXT_meshopt_compression`` (and ``KHR_meshopt_compression``): bufferViews compressed by
zeux's meshoptimizer, decoded with the ``meshoptimizer`` package, filters undone."""

from __future__ import annotations

import numpy as np

MODES = ("ATTRIBUTES", "TRIANGLES", "INDICES")
#: The byteStrides a filter works on (None: any multiple of 4).
FILTER_STRIDES: dict[str, tuple[int, ...] | None] = {
    "OCTAHEDRAL": (4, 8),
    "QUATERNION": (8,),
    "EXPONENTIAL": None,
}


class MeshoptError(ValueError):
    """A compressed bufferView breaks a rule of the extension, or does not decode."""


def decode_view(source: bytes, count: int, stride: int, mode, filt) -> bytes:
    """The ``count × stride`` bytes of a compressed bufferView: ``source`` decoded as
    ``mode`` (``ATTRIBUTES``, ``TRIANGLES`` or ``INDICES``) and its ``filt`` (``NONE``,
    ``OCTAHEDRAL``, ``QUATERNION``, ``EXPONENTIAL``) undone. Raises :class:`MeshoptError`."""
    try:
        import meshoptimizer
    except ImportError:  # pragma: no cover - a dependency of vtts
        raise MeshoptError("the meshoptimizer package is not installed") from None
    if mode == "ATTRIBUTES":
        if not (stride % 4 == 0 and 4 <= stride <= 256):
            raise MeshoptError(f"ATTRIBUTES need a byteStride of 4–256 in steps of 4, got {stride}")
        _check_filter(filt, stride)
    elif mode in ("TRIANGLES", "INDICES"):
        if stride not in (2, 4):
            raise MeshoptError(f"{mode} need a byteStride of 2 or 4, got {stride}")
    else:
        raise MeshoptError(f"mode must be ATTRIBUTES, TRIANGLES or INDICES, got {mode!r}")
    try:
        if mode == "ATTRIBUTES":
            # the package's default (float32) mode holds count·stride bytes; its dtype= mode
            # allocates count elements only and overflows for strides above the itemsize
            out = meshoptimizer.decode_vertex_buffer(count, stride, source)
            raw = np.ascontiguousarray(out).view(np.uint8).reshape(-1)[: count * stride]
            if filt not in (None, "NONE"):
                funcs = {"OCTAHEDRAL": meshoptimizer.decode_filter_oct,
                         "QUATERNION": meshoptimizer.decode_filter_quat,
                         "EXPONENTIAL": meshoptimizer.decode_filter_exp}  # fmt: skip
                raw = np.asarray(funcs[filt](raw.copy(), count, stride), dtype=np.uint8)
        else:
            decode = (meshoptimizer.decode_index_buffer if mode == "TRIANGLES"
                      else meshoptimizer.decode_index_sequence)  # fmt: skip
            out = decode(count, stride, source)
            raw = np.ascontiguousarray(out).view(np.uint8).reshape(-1)[: count * stride]
    except (RuntimeError, ValueError) as e:
        raise MeshoptError(f"cannot decode: {e}") from None
    return raw.tobytes()


def _check_filter(filt, stride: int) -> None:
    if filt in (None, "NONE"):
        return
    if filt not in FILTER_STRIDES:
        raise MeshoptError(f"unknown filter {filt!r}")
    need = FILTER_STRIDES[filt]
    if need is not None and stride not in need:
        raise MeshoptError(
            f"the {filt} filter needs a byteStride of {' or '.join(map(str, need))}, got {stride}"
        )
    if need is None and stride % 4:
        raise MeshoptError(f"the {filt} filter needs a byteStride in steps of 4")
