"""Fixtures of the ADI tests (helpers live in ``adi_helpers.py``)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from vtts.face import FaceModel, load_model

from .adi_helpers import PHASES, SAMPLE, TABLES, export_pose, params_for, with_worldinfo


@pytest.fixture(scope="session")
def model_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with ``head.wrl`` (the Candide sample) and its sidecar ``head.adt``."""
    d = tmp_path_factory.mktemp("model")
    shutil.copy(SAMPLE, d / "head.wrl")
    (d / "head.adt").write_text(TABLES)
    return d


@pytest.fixture(scope="session")
def model(model_dir: Path) -> FaceModel:
    return load_model(model_dir / "head.wrl")


@pytest.fixture(scope="session")
def neutral_wrl(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The neutral scene alone (no sidecar beside it)."""
    d = tmp_path_factory.mktemp("neutral")
    shutil.copy(SAMPLE, d / "neutral.wrl")
    return d / "neutral.wrl"


@pytest.fixture(scope="session")
def phase_files(model: FaceModel, tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Every phase of :data:`PHASES` exported as ``NAME@AMP.wrl``, except the joy climax, which
    names its MIAP in a WorldInfo string instead (``joy_climax.wrl``)."""
    d = tmp_path_factory.mktemp("phases")
    files = []
    for key, amps in PHASES.items():
        for a in amps:
            if key == "joy" and a == 1:
                scene = model.posed_scene(model.deform(params_for(model, key, a)))
                text = with_worldinfo(scene, "miap joy 1")
                (d / "joy_climax.wrl").write_text(text)
                files.append(d / "joy_climax.wrl")
                continue
            files.append(export_pose(model, key, a, d / f"{key}@{a:g}.wrl"))
    return files
