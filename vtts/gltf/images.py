"""The images of glTF textures: PNG and JPEG as they are, anything else Pillow reads as PNG."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from vtts.errors import ExportError
from vtts.limits import check_image_size, read_bytes_capped

#: MIME type of each image format glTF core allows.
MIME_TYPES = {"png": "image/png", "jpeg": "image/jpeg"}
#: The largest texture image file embedded in an export, bytes.
MAX_TEXTURE_FILE_BYTES = 256 << 20
#: The signature that opens a KTX2 file (Basis Universal textures).
KTX2_MAGIC = b"\xabKTX 20\xbb\r\n\x1a\n"


def png_bytes(rgba: np.ndarray) -> bytes:
    """The PNG file of an image ``(h, w, 4) uint8`` RGBA (or ``(h, w, 3)`` RGB)."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgba)).save(buf, format="PNG")
    return buf.getvalue()


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB curve (0–1) undone: linear light, as pyrender and glTF read a texture."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """Linear light (clipped to 0–1) on the sRGB curve."""
    c = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055)


def brightened(rgba: np.ndarray, gain) -> np.ndarray:
    """``rgba (h, w, 4) uint8`` with its colour channels (sRGB) ``gain (3,)`` times brighter in
    linear light, clipped at white: a VRML Material's ``diffuseColor`` above 1 (a fitted head's
    skin lit more brightly than the renderer's lights, :func:`vtts.fit.head.set_exposure`) baked
    into its texture, since glTF's ``baseColorFactor`` stops at 1."""
    lin = srgb_to_linear(rgba[..., :3] / 255.0) * np.asarray(gain, dtype=np.float64)
    srgb = linear_to_srgb(lin)
    out = np.array(rgba, copy=True)
    out[..., :3] = np.round(srgb * 255.0).astype(np.uint8)
    return out


def web_image(data: bytes, *, file: str | None, what: str) -> tuple[bytes, str]:
    """An image's bytes and format (``"png"`` or ``"jpeg"``): PNG and JPEG ``data`` as it is,
    any other format Pillow reads converted to PNG. Its size is checked
    (:func:`~vtts.limits.check_image_size`, naming ``file`` and ``what``) before its pixels are
    decoded. Raises ``OSError``, ``ValueError`` or Pillow's ``DecompressionBombError`` for data
    Pillow cannot read."""
    from PIL import Image

    with Image.open(io.BytesIO(data)) as im:
        check_image_size(*im.size, file=file, what=what)
        fmt = (im.format or "").lower()
        if fmt in MIME_TYPES:
            im.load()  # a truncated or corrupt file fails here, not in a viewer
            return data, fmt
        return png_bytes(np.asarray(im.convert("RGBA"))), "png"


def image_file(path: Path) -> tuple[bytes, str]:
    """A texture image file's bytes and MIME type for embedding (:func:`web_image`). Raises
    :class:`~vtts.errors.ExportError` for a file that cannot be read."""
    from PIL import Image

    try:
        data = read_bytes_capped(path, MAX_TEXTURE_FILE_BYTES, what="texture image")
        data, fmt = web_image(data, file=str(path), what="texture image")
    except (OSError, ValueError, Image.DecompressionBombError) as e:
        raise ExportError(f"cannot read texture image {path}: {e}") from None
    return data, MIME_TYPES[fmt]
