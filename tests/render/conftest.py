"""Fixtures for rendering tests: the test head and golden-image comparison."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parents[1] / "data"
GOLDEN = Path(__file__).parents[1] / "golden"
#: Golden images match when the PSNR is at least this (rasterizer noise stays far above it).
GOLDEN_PSNR_DB = 40.0


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB of two uint8 images (inf when identical)."""
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


@pytest.fixture
def image_psnr():
    """:func:`psnr` for tests in any folder below this one, as a fixture."""
    return psnr


@pytest.fixture
def head_path() -> Path:
    return DATA / "models" / "head.wrl"


@pytest.fixture
def golden():
    """``golden(name, image)``: compare with ``tests/golden/NAME.png`` by PSNR, or write it when
    ``VTTS_REGENERATE_GOLDEN=1`` (``make golden``) — never silently."""
    from PIL import Image

    def check(name: str, image: np.ndarray) -> None:
        path = GOLDEN / f"{name}.png"
        if os.environ.get("VTTS_REGENERATE_GOLDEN") == "1":
            path.parent.mkdir(parents=True, exist_ok=True)
            Image.fromarray(image).save(path)
            return
        if not path.is_file():
            pytest.fail(
                f"no golden image {path}: run `make golden` and look at it before committing"
            )
        want = np.asarray(Image.open(path).convert("RGB"))
        assert want.shape == image.shape, f"{name}: size {image.shape} != golden {want.shape}"
        value = psnr(want, image)
        if value < GOLDEN_PSNR_DB:
            Image.fromarray(image).save(path.with_name(f"{name}.actual.png"))
        assert value >= GOLDEN_PSNR_DB, f"{name}: PSNR {value:.1f} dB < {GOLDEN_PSNR_DB} dB"

    return check
