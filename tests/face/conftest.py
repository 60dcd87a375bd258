"""A small personalized model built in the tests: the Candide-3 sample scene with known tables."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

SAMPLE = Path(__file__).parents[2] / "samples" / "candide3.wrl"

TABLES = """#AnimationDefinitionTables

MIAP 6 (stretch_l_cornerlip)
IndexedFaceSet: FACE_MESH
interval borders: -1000 0 1000
displacements:
vertex 50 -0.0001 0 0 0.0001 0 0
vertex 51 -0.0001 0 0 0.0001 0 0

MIAP 19 (close_t_l_eyelid)
IndexedFaceSet: FACE_MESH
interval borders: 0 512 1024
displacements:
vertex 20 0 -0.0001 0 0 -0.0003 0
vertex 21 0 -0.0002 0 0 -0.0001 0.00001

MIAP 48 (head_pitch)
Transform: HEAD
rotation neutral value: 1 0 0 (axis) 0 (angle)

MIAP viseme 1 (p, b, m)
IndexedFaceSet: FACE_MESH
interval borders: 0 1
displacements:
vertex 60 0 0.01 0
vertex 61 0 -0.01 0

MIAP expression 1 (joy)
IndexedFaceSet: FACE_MESH
interval borders: 0 0.5 1
displacements:
vertex 50 0.02 0.02 0 0.01 0.01 0
vertex 52 0.01 0 0 0.01 0 0
Transform: HEAD
translation neutral value: 0 0 0
per unit: 0 0.05 0

#TemporalDefinitionTables
expression joy: onset 0.5 offset 0.8 shape smooth climax 1 duration 2
blink: interval 4 jitter 1.5 duration 0.2 amplitude 1024

#FeaturePoints
3.5 FACE_MESH 12
"""


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
