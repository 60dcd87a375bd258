"""Fuzzing the photo reader of ``adi fit`` (issue 21): PNG and JPEG photos (with EXIF: the
orientation and the 35 mm focal length) mutated byte by byte, and any declared size. Whatever the
bytes, the only exception is FitError (or LimitError); a photo that is read is an ``(H, W, 3)
uint8`` array within the image limits, with a focal length that is None or a positive number.
"""

from __future__ import annotations

import io
import math
import struct
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from PIL import Image

from vtts.errors import FitError, VttsWarning
from vtts.fit import load_photo
from vtts.limits import MAX_PHOTO_PIXELS, LimitError

from ..fuzzing import examples
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
FUZZ = settings(
    max_examples=examples(150), deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


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
    # fit_photo takes photos up to 16384 on a side and MAX_PHOTO_PIXELS and scales them down
    assert image.shape[0] * image.shape[1] <= MAX_PHOTO_PIXELS
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


# ---- EXIF tags, deep and wide images, sizes (issue 45) -------------------------------------------


def _exif_jpeg(focal_type: int = 3, focal_value: int = 35, count: int = 1) -> bytes:
    """PHOTOS[2] (Orientation 6, FocalLengthIn35mmFilm 35) with the focal length's entry
    rewritten: its type, count and value field."""
    data = bytearray(PHOTOS[2])
    i = data.find(b"\xa4\x05")
    struct.pack_into(">HHII", data, i, 0xA405, focal_type, count, focal_value)
    return bytes(data)


def test_a_malformed_exif_tag_is_ignored_with_a_warning(folder: Path) -> None:
    """A LONG8 focal length made Pillow's exif_transpose fail writing the block back: a
    struct.error traceback. The tag is ignored; the photo is still turned upright."""
    path = folder / "bad-tag.jpg"
    path.write_bytes(_exif_jpeg(focal_type=16))
    with pytest.warns(VttsWarning, match="EXIF") as caught:
        image, focal = load_photo(path)
    assert image.shape == (48, 40, 3) and focal is None
    assert str(path) in str(caught[0].message)


@pytest.mark.parametrize(
    "focal_type, value, shown",
    [
        (3, 65535 << 16, "65535"),  # SHORT: the largest
        (8, 0xFFCE0000, "-50"),  # SSHORT −50
        (3, 5 << 16, "5"),  # below a fisheye
    ],
)
def test_an_implausible_exif_focal_length_is_ignored_naming_the_file(
    folder: Path, focal_type: int, value: int, shown: str
) -> None:
    """65535, 0/0 or −50 reached the fit as "camera fx … got nan", naming neither the file nor
    EXIF."""
    path = folder / "focal.jpg"
    path.write_bytes(_exif_jpeg(focal_type, value))
    with pytest.warns(VttsWarning, match=f"focal length {shown} mm is outside 8–2000") as w:
        assert load_photo(path)[1] is None
    assert w[0].message.file == str(path)


def test_a_zero_by_zero_exif_focal_length_is_ignored(folder: Path) -> None:
    data = bytearray(_exif_jpeg(5, 8))  # RATIONAL at offset 8: make it 0/0
    tiff = data.find(b"Exif\0\0") + 6
    struct.pack_into(">II", data, tiff + 8, 0, 0)
    path = folder / "nan.jpg"
    path.write_bytes(bytes(data))
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        image, focal = load_photo(path)
    assert focal is None or 8 <= focal <= 2000


@FUZZ
@given(byte_mutations)
def test_mutated_exif_blocks(folder: Path, ops) -> None:
    """Damage inside the EXIF block only (the fuzz above mostly breaks the pixels)."""
    data = PHOTOS[2]
    start = data.find(b"Exif")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        load_or_fit_error(folder / "e.jpg", mutate_bytes(data[: start + 80], ops, start=start)
                          + data[start + 80 :])  # fmt: skip


def _grey() -> np.ndarray:
    return np.asarray(_IMAGE.convert("L"))


DEEP = {
    "I;16": lambda g: Image.fromarray(g.astype(np.uint16) * 257),  # 16-bit grey
    "I": lambda g: Image.fromarray(g.astype(np.int32) * 257),  # 16-bit samples widened
    "F 0-1": lambda g: Image.fromarray((g / 255).astype(np.float32)),  # float in 0–1
    "F 0-255": lambda g: Image.fromarray(g.astype(np.float32)),  # float in 0–255
}


@pytest.mark.parametrize(
    "kind, fmt",
    # PNG holds no floats, and Pillow writes no 32-bit PNG
    [("I;16", "png"), *((k, "tiff") for k in DEEP)],
)
def test_deep_images_are_scaled_not_clipped(folder: Path, kind: str, fmt: str) -> None:
    """A 16-bit grey PNG or a float TIFF of a clear face gave "no face found": Pillow's
    conversion clipped it white."""
    image = DEEP[kind](_grey())
    path = folder / f"deep.{fmt}"
    image.save(path)
    rgb, _ = load_photo(path)
    assert rgb.shape == (40, 48, 3)
    assert np.abs(rgb[..., 0].astype(int) - _grey()).max() <= 1


def test_a_photo_declaring_too_many_pixels_is_refused_before_decoding(folder: Path) -> None:
    """A 68 KB JPEG declaring 13000x13000 took adi fit to 3 GB (the only cap was Pillow's)."""
    data = bytearray(PHOTOS[1])
    sof = data.find(b"\xff\xc0")
    struct.pack_into(">HH", data, sof + 5, 13000, 13000)
    path = folder / "huge.jpg"
    path.write_bytes(bytes(data))
    with pytest.raises(FitError, match=f"13000x13000 pixels, more than the limit of 16384 on a "
                       f"side and {MAX_PHOTO_PIXELS} in all") as e:  # fmt: skip
        load_photo(path)
    assert str(path) in str(e.value)


def test_a_large_jpeg_is_decoded_at_the_working_size(folder: Path) -> None:
    path = folder / "large.jpg"
    _IMAGE.resize((4800, 4000)).save(path, quality=60)
    rgb, _ = load_photo(path)
    assert rgb.shape == (2000, 2400, 3)  # by 1/2: the least that keeps 1024 pixels
