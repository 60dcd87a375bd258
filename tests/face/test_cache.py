"""The cache of parsed models is invisible: the same model, never a stale one, never an error
hidden, and nothing when turned off."""

from __future__ import annotations

import io
import json
import os
import pickle
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from vtts import vrml
from vtts.errors import VttsError
from vtts.face import N_PARAMS, cache, find_model, load_model

HEAD = Path(__file__).parents[1] / "data" / "models" / "head.wrl"


@pytest.fixture
def cybatt_model(tmp_path, monkeypatch):
    """A copy of cybatt (large enough to be cached) and an empty cache folder."""
    monkeypatch.setenv("VTTS_CACHE_DIR", str(tmp_path / "cache"))
    src = find_model("cybatt")
    for suffix in (".wrl", ".adt"):
        shutil.copy(src.with_suffix(suffix), tmp_path / f"head{suffix}")
    shutil.copy(src.with_name("cybatt-face.png"), tmp_path / "cybatt-face.png")
    return tmp_path / "head.wrl"


@pytest.fixture
def big_model(tmp_path, monkeypatch):
    """The test head (``HEAD``, its tables beside it) with comments enough to make it just
    large enough to be cached, and an empty cache folder: a fifth of cybatt's parse, for the
    tests of what the cache does with its entries (cybatt, whose parse the cache is for, is
    ``cybatt_model``)."""
    monkeypatch.setenv("VTTS_CACHE_DIR", str(tmp_path / "cache"))
    shutil.copy(HEAD.with_suffix(".adt"), tmp_path / "head.adt")
    text = HEAD.read_text()
    line = "# a comment that makes the model large enough to be cached\n"
    lines = cache.MIN_BYTES - len(text.encode()) - HEAD.with_suffix(".adt").stat().st_size
    (tmp_path / "head.wrl").write_text(text + line * (lines // len(line) + 1))
    return tmp_path / "head.wrl"


def _entries(model_path):
    return sorted((model_path.parent / "cache" / "models").glob("*.npz"))


def _same(a, b, tmp_path) -> bool:
    p = a.params({3: 300, 48: 2000}, visemes={10: 1.0}, expressions={"joy": 0.6})
    vrml.write(a.posed_scene(a.engine.deform(p)), tmp_path / "a.wrl")
    vrml.write(b.posed_scene(b.engine.deform(p)), tmp_path / "b.wrl")
    return (tmp_path / "a.wrl").read_text() == (tmp_path / "b.wrl").read_text() and (
        a.describe() == b.describe()
    )


def test_a_cached_model_is_the_parsed_one(cybatt_model, tmp_path):
    parsed = load_model(cybatt_model)
    assert len(_entries(cybatt_model)) == 1
    cached = load_model(cybatt_model)
    assert cached is not parsed and cached.path == cybatt_model
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
    _, tables = cache.load(entry)
    assert tables.adts.keys() == changed.tables.adts.keys()


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


def test_an_unwritable_cache_is_no_error(cybatt_model, monkeypatch):
    blocker = cybatt_model.parent / "file"
    blocker.write_text("")
    monkeypatch.setenv("VTTS_CACHE_DIR", str(blocker))  # a file where the folder should be
    assert np.isfinite(
        load_model(cybatt_model).engine.deform(np.zeros(N_PARAMS)).points["FACE"]
    ).all()


# ---- hostile entries: the cache holds data, never code ------------------------------------------


class _Planted:
    """Unpickling this creates ``marker``: what a planted pickle could do instead."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (Path.touch, (self.marker,))


def _entry_for(model_path: Path) -> Path:
    return cache.entry_path([model_path, model_path.with_suffix(".adt")])


def test_a_planted_pickle_runs_nothing(big_model, tmp_path):
    parsed = load_model(big_model)
    entry = _entry_for(big_model)
    marker = tmp_path / "pwned"
    payload = pickle.dumps(_Planted(marker))
    entry.write_bytes(payload)
    entry.with_suffix(".pickle").write_bytes(payload)  # where older versions looked
    again = load_model(big_model)
    assert not marker.exists()
    assert _same(parsed, again, tmp_path)
    assert not entry.with_suffix(".pickle").exists()  # the new entry replaced the old kind


def _rewrite(entry: Path, change) -> None:
    """Rewrite the entry's JSON document with ``change(doc)``, keeping its arrays."""
    with np.load(entry) as npz:
        arrays = {k: npz[k] for k in npz.files}
    doc = json.loads(arrays.pop("doc").tobytes())
    change(doc)
    text = json.dumps(doc).encode()
    buffer = io.BytesIO()
    np.savez(buffer, doc=np.frombuffer(text, np.uint8), **arrays)
    entry.write_bytes(buffer.getvalue())


def _first(doc, cls):
    """The fields of the first instance of ``cls`` in the document."""
    stack = [doc]
    while stack:
        j = stack.pop()
        if isinstance(j, dict):
            if "O" in j and j["O"][0] == cls:
                return j["O"][1]
            stack.extend(j.values())
        elif isinstance(j, list):
            stack.extend(reversed(j))
    raise AssertionError(cls)


def _set(doc, cls, name, value):
    _first(doc, cls)[name] = value


def _truncate(entry):
    entry.write_bytes(entry.read_bytes()[: entry.stat().st_size // 2])


def _compress(entry):
    with np.load(entry) as npz:
        arrays = {k: npz[k] for k in npz.files}
    np.savez_compressed(entry.with_suffix(""), **arrays)
    entry.with_suffix("").with_suffix(".npz").replace(entry)


BAD_ENTRIES = {
    "garbage": lambda e: e.write_bytes(os.urandom(5000)),
    "empty": lambda e: e.write_bytes(b""),
    "truncated": _truncate,
    "a zip of something else": lambda e: zipfile.ZipFile(e, "w").writestr("doc.npy", b"x"),
    "compressed": _compress,
    "another format": lambda e: _rewrite(e, lambda d: d.update(format=1)),
    "not a model": lambda e: _rewrite(e, lambda d: d.update(scene={"L": []})),
    "an unknown class": lambda e: _rewrite(
        e, lambda d: _first(d, "Node").update(type={"O": ["Popen", {}]})
    ),
    "a missing field": lambda e: _rewrite(e, lambda d: _first(d, "Node").pop("name")),
    "a field of the wrong type": lambda e: _rewrite(e, lambda d: _set(d, "Node", "fields", 7)),
    "a wrong-shape table": lambda e: _rewrite(
        e, lambda d: _first(d, "MeshTable")["displacements"]["A"].__setitem__(2, [1, 1, 3])
    ),
    "an array beyond its data": lambda e: _rewrite(
        e, lambda d: _first(d, "MeshTable")["vertices"]["A"].__setitem__(1, 10**12)
    ),
    "a dangling reference": lambda e: _rewrite(e, lambda d: _set(d, "Scene", "defs", {"R": 10**6})),
}


@pytest.mark.parametrize("kind", BAD_ENTRIES)
def test_a_bad_entry_is_a_miss(big_model, tmp_path, kind):
    parsed = load_model(big_model)
    (entry,) = _entries(big_model)
    BAD_ENTRIES[kind](entry)
    assert cache.load(entry) is None
    again = load_model(big_model)
    assert _same(parsed, again, tmp_path)
    assert cache.load(entry) is not None  # rewritten, good again


def _chmod_and_load(big_model, tmp_path, target):
    parsed = load_model(big_model)
    (entry,) = _entries(big_model)
    path = entry if target == "entry" else entry.parent
    path.chmod(path.stat().st_mode | 0o022)
    assert cache.load(entry) is None
    assert _same(parsed, load_model(big_model), tmp_path)


@pytest.mark.parametrize("target", ["entry", "folder"])
def test_an_entry_others_could_write_is_a_miss(big_model, tmp_path, target):
    _chmod_and_load(big_model, tmp_path, target)


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0, reason="needs chown")
def test_an_entry_of_another_user_is_a_miss(big_model, tmp_path):
    parsed = load_model(big_model)
    (entry,) = _entries(big_model)
    os.chown(entry, 12345, 12345)
    assert cache.load(entry) is None
    assert _same(parsed, load_model(big_model), tmp_path)
    # a folder of another user: read nothing, write nothing
    os.chown(entry.parent, 12345, 12345)
    os.chown(entry, 12345, 12345)
    assert cache.load(entry) is None
    load_model(big_model)
    assert entry.stat().st_uid == 12345


def test_the_entry_of_a_symlink_is_a_miss(big_model, tmp_path):
    parsed = load_model(big_model)
    (entry,) = _entries(big_model)
    elsewhere = tmp_path / "elsewhere.npz"
    entry.replace(elsewhere)
    entry.symlink_to(elsewhere)
    assert cache.load(entry) is None
    assert _same(parsed, load_model(big_model), tmp_path)


def _vtts(*args: str, cache_dir: Path, cwd: Path) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).with_name("vtts")
    env = {**os.environ, "VTTS_CACHE_DIR": str(cache_dir)}
    return subprocess.run(
        [str(exe), *args], capture_output=True, text=True, timeout=120, env=env, cwd=cwd
    )


def test_commands_work_with_a_poisoned_cache(tmp_path, monkeypatch):
    """Every bundled model's entry is a pickle that would create a file: ``vtts models`` and
    ``vtts render`` work and nothing is created."""
    monkeypatch.setenv("VTTS_CACHE_DIR", str(tmp_path / "cache"))
    marker = tmp_path / "pwned"
    for name in ("cybatt", "lotta"):
        wrl = find_model(name)
        entry = cache.entry_path([wrl, wrl.with_suffix(".adt")])
        entry.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        entry.write_bytes(pickle.dumps(_Planted(marker)))
    r = _vtts("models", cache_dir=tmp_path / "cache", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "cybatt" in r.stdout and "Traceback" not in r.stderr
    r = _vtts(
        "render", "--model", "cybatt", "-o", "x.png", cache_dir=tmp_path / "cache", cwd=tmp_path
    )
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "x.png").stat().st_size > 0
    assert not marker.exists()
