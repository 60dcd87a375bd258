"""Fuzzing the photo reader of ``adi fit`` (issue 21): PNG and JPEG photos (with EXIF: the
orientation and the 35 mm focal length) mutated byte by byte, and any declared size. Whatever the
bytes, the only exception is FitError (or LimitError); a photo that is read is an ``(H, W, 3)
uint8`` array within the image limits, with a focal length that is None or a positive number.
"""

from __future__ import annotations

import io
import math
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from PIL import Image

from vtts.errors import FitError
from vtts.fit import load_photo
from vtts.limits import LimitError

from ..hostile import byte_mutations, mutate_bytes

DATA = Path(__file__).resolve().parents[1] / "data" / "photos"
_IMAGE = Image.open(DATA / "akiyo_frame0.png").convert("RGB").resize((48, 40))


def _photos() -> list[bytes]:
    exif = Image.Exif()
    exif[0x0112] = 6  # Orientation: turned 90°
    exif.get_ifd(0x8769)[0xA405] = 35  # FocalLengthIn35mmFilm
    out = []
    for fmt, kw in [("PNG", {}), ("JPEG", {"quality": 80}), ("JPEG", {"exif": exif}),
                    ("PNG", {"exif": exif})]:  # fmt: skip
        buf = io.BytesIO()
        _IMAGE.save(buf, fmt, **kw)
        out.append(buf.getvalue())
    return out


PHOTOS = _photos()
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("photos")


def load_or_fit_error(path: Path, data: bytes) -> np.ndarray | None:
    path.write_bytes(data)
    try:
        image, focal = load_photo(path)
    except (FitError, LimitError) as e:
        assert e.message and str(path) in str(e), str(e)
        return None
    assert image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3
    # photos are not held to vtts.limits: fit_photo takes up to 16384 on a side and scales
    # them down; what load_photo decodes is bounded by Pillow's decompression-bomb limit
    assert image.shape[0] * image.shape[1] <= 2 * Image.MAX_IMAGE_PIXELS
    assert focal is None or (math.isfinite(focal) and focal > 0)
    return image


def test_the_photos_read(folder: Path) -> None:
    shapes = [load_or_fit_error(folder / "p", data).shape for data in PHOTOS]
    assert shapes == [(40, 48, 3), (40, 48, 3), (48, 40, 3), (48, 40, 3)]
    (folder / "f.jpg").write_bytes(PHOTOS[2])
    assert load_photo(folder / "f.jpg")[1] == 35


@FUZZ
@given(st.integers(0, len(PHOTOS) - 1), byte_mutations)
def test_mutated_photos(folder: Path, which: int, ops) -> None:
    load_or_fit_error(folder / "m", mutate_bytes(PHOTOS[which], ops))


@FUZZ
@given(st.binary(max_size=300))
def test_random_bytes(folder: Path, data: bytes) -> None:
    load_or_fit_error(folder / "r", data)


@FUZZ
@given(st.integers(0, 2**31 - 1), st.integers(0, 2**31 - 1))
@example(829, 215_871)  # beyond Pillow's decompression-bomb limit
@example(89_478_479, 1)  # Pillow's PNG decoder raised MemoryError: a traceback in adi fit
def test_declared_sizes(folder: Path, w: int, h: int) -> None:
    """Any width and height in a PNG header (a small file may declare gigapixels)."""
    data = PHOTOS[0]
    ihdr = struct.pack(">II", w, h) + data[24:29]
    patched = data[:16] + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr)) + data[33:]
    load_or_fit_error(folder / "s.png", patched)
