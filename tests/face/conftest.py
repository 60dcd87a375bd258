"""A small personalized model built in the tests: the Candide-3 sample scene with known tables."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

SAMPLE = Path(__file__).parents[2] / "samples" / "candide3.wrl"

#: Known tables (a two-sided FAP, a two-phase FAP 19, head pitch, a viseme, joy with a Transform
#: table, temporal tables, a feature point): the test head's sidecar.
TABLES = (Path(__file__).parents[1] / "data" / "models" / "head.adt").read_text()


@pytest.fixture
def model_dir(tmp_path: Path) -> Path:
    """A folder with ``head.wrl`` (the Candide sample) and its sidecar ``head.adt``."""
    shutil.copy(SAMPLE, tmp_path / "head.wrl")
    (tmp_path / "head.adt").write_text(TABLES)
    return tmp_path


@pytest.fixture
def tables_text() -> str:
    """The text of ``head.adt``."""
    return TABLES
