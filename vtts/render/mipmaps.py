"""Mipmaps of a texture, made on the CPU.

pyrender has OpenGL make a texture's mipmaps (``glGenerateMipmap``). Mesa's software rasterizer
does that by drawing each level with a blit shader that it compiles on the first call, a large
part of every process's time to its first frame, for levels that NumPy computes in a fraction
of that (docs/rendering.md, "Start-up", has the timings). vtts therefore uploads the levels
itself (:func:`mip_levels`; :func:`vtts.render.pyrender_adapter.pyrender_texture`), the same
texels as llvmpipe's own.
"""

from __future__ import annotations

import numpy as np


def mip_levels(image: np.ndarray) -> list[np.ndarray]:
    """The mipmap chain of an ``(h, w, c) uint8`` image, rows in the order GL stores them:
    ``[image, (h/2, w/2, c), …, (1, 1, c)]``, each level ``max(1, ⌊size/2⌋)`` of the one before
    along each side.

    A texel is the mean of the 2×2 texels under it as Mesa's llvmpipe filters it for
    ``glGenerateMipmap`` (bilinear filtering halfway between them in 8-bit arithmetic): each
    row's pair averaged, rounding halves up, then the two rows' averages averaged the same way
    (``tests/render`` checks the texels against llvmpipe's). A side that is already 1 is not
    averaged. Sides that are powers of two only: see :func:`power_of_two`."""
    image = np.asarray(image)
    if image.ndim != 3 or image.dtype != np.uint8 or not power_of_two(image.shape[:2]):
        raise ValueError(f"an (h, w, c) uint8 image with sides 2^k is needed, got {image.shape}")
    levels = [image]
    level = image
    while level.shape[0] > 1 or level.shape[1] > 1:
        h, w = level.shape[:2]
        s = level.astype(np.uint16)
        if w > 1:  # sides of 2^k: every level's sides are even or 1
            s = (s[:, 0::2] + s[:, 1::2] + 1) >> 1
        if h > 1:
            s = (s[0::2] + s[1::2] + 1) >> 1
        level = s.astype(np.uint8)
        levels.append(level)
    return levels


def power_of_two(size: tuple[int, ...]) -> bool:
    """Whether every side in ``size`` is a power of two (1, 2, 4, …). Mesa filters the levels
    of other sizes at fractions of texels, which :func:`mip_levels` does not copy: such
    textures keep ``glGenerateMipmap``."""
    return all(n > 0 and n & (n - 1) == 0 for n in size)
