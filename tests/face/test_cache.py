"""The cache of parsed models is invisible: the same model, never a stale one, never an error
hidden, and nothing when turned off."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from vtts import vrml
from vtts.errors import VttsError
from vtts.face import N_PARAMS, cache, find_model, load_model

HEAD = Path(__file__).parents[1] / "data" / "models" / "head.wrl"


@pytest.fixture
def big_model(tmp_path, monkeypatch):
    """A copy of cybatt (large enough to be cached) and an empty cache folder."""
    monkeypatch.setenv("VTTS_CACHE_DIR", str(tmp_path / "cache"))
    src = find_model("cybatt")
    for suffix in (".wrl", ".adt"):
        shutil.copy(src.with_suffix(suffix), tmp_path / f"head{suffix}")
    shutil.copy(src.with_name("cybatt-face.png"), tmp_path / "cybatt-face.png")
    return tmp_path / "head.wrl"


def _entries(model_path):
    return sorted((model_path.parent / "cache" / "models").glob("*.pickle"))


def _same(a, b, tmp_path) -> bool:
    p = a.params({3: 300, 48: 2000}, visemes={10: 1.0}, expressions={"joy": 0.6})
    vrml.write(a.posed_scene(a.engine.deform(p)), tmp_path / "a.wrl")
    vrml.write(b.posed_scene(b.engine.deform(p)), tmp_path / "b.wrl")
    return (tmp_path / "a.wrl").read_text() == (tmp_path / "b.wrl").read_text() and (
        a.describe() == b.describe()
    )


def test_a_cached_model_is_the_parsed_one(big_model, tmp_path):
    parsed = load_model(big_model)
    assert len(_entries(big_model)) == 1
    cached = load_model(big_model)
    assert cached is not parsed and cached.path == big_model
    assert _same(parsed, cached, tmp_path)
    # standard node types stay shared with the parser's (code compares them by identity)
    assert cached.scene.roots[0].type is parsed.scene.roots[0].type


def test_a_changed_file_is_parsed_again(big_model, tmp_path):
    load_model(big_model)
    (first,) = _entries(big_model)
    adt = big_model.with_suffix(".adt")
    text = adt.read_text()
    adt.write_text(text.replace("vertex", "vertex", 1) + "\n")  # one more byte
    changed = load_model(big_model)
    (entry,) = _entries(big_model)  # the new entry replaced the old one
    assert entry != first
    assert cache.load(entry).tables.adts.keys() == changed.tables.adts.keys()


def test_a_corrupt_entry_is_a_miss(big_model, tmp_path):
    parsed = load_model(big_model)
    (entry,) = _entries(big_model)
    entry.write_bytes(b"not a pickle")
    again = load_model(big_model)
    assert _same(parsed, again, tmp_path)
    assert entry.read_bytes() != b"not a pickle"  # rewritten


def test_errors_are_never_cached(big_model):
    adt = big_model.with_suffix(".adt")
    adt.write_text(adt.read_text().replace("vertex", "vortex", 1))
    for _ in range(2):
        with pytest.raises(VttsError):
            load_model(big_model)
    assert _entries(big_model) == []


def test_the_cache_can_be_turned_off(big_model, monkeypatch):
    monkeypatch.setenv("VTTS_CACHE_DIR", "")
    assert cache.cache_dir() is None
    load_model(big_model)
    assert not (big_model.parent / "cache").exists()


def test_small_and_lenient_models_are_not_cached(big_model):
    load_model(HEAD)
    load_model(big_model, lenient=True)
    assert _entries(big_model) == []


def test_an_unwritable_cache_is_no_error(big_model, monkeypatch):
    blocker = big_model.parent / "file"
    blocker.write_text("")
    monkeypatch.setenv("VTTS_CACHE_DIR", str(blocker))  # a file where the folder should be
    assert np.isfinite(load_model(big_model).engine.deform(np.zeros(N_PARAMS)).points["FACE"]).all()
