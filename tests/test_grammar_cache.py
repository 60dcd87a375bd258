"""lark keeps the grammars' parser tables as pickles: vtts gives it files in the user's own cache
folder only (never the shared temporary folder, where anyone can plant one), reads none that
others could have written, and works the same with the cache off."""

from __future__ import annotations

import os
import pickle
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from vtts.usercache import trusted_file

#: Builds the three cached parsers and parses a line with each, in a fresh process (the parsers
#: are made once per process).
SCRIPT = """
import vtts.face.adt as A, vtts.vrml.parser as P, vtts.speech.bookmarks as B
P.parse('#VRML V2.0 utf8\\nTransform { children [] }')
A.parse_adt('#AnimationDefinitionTables\\n')
assert [b.name for b in B.parse_bookmarks('Hi <smile 2s> there.').bookmarks] == ['joy']
print("parsed")
"""


class _Planted:
    """Unpickling it creates the folder ``marker``."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.mkdir, (str(self.marker),))


def _run(cache: Path | str, tmp: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "VTTS_CACHE_DIR": str(cache), "TMPDIR": str(tmp)}
    return subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=120, env=env
    )


@pytest.fixture
def folders(tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    return tmp_path / "cache", tmp, tmp_path / "pwned"


def _plant(path: Path, marker: Path) -> None:
    # lark's file: the grammar's hash on the first line, then pickles (the first is loaded)
    path.write_bytes(b"planted\n" + pickle.dumps(_Planted(marker)))


def test_the_tables_are_kept_in_the_users_cache_not_the_temporary_folder(folders):
    cache, tmp, _ = folders
    r = _run(cache, tmp)
    assert r.returncode == 0 and "parsed" in r.stdout, r.stderr
    kept = sorted((cache / "grammars").iterdir())
    assert [p.name.split("-")[0] for p in kept] == ["adt", "bookmarks", "vrml97"]
    assert all(trusted_file(p) for p in kept)
    assert stat.S_IMODE(os.stat(cache / "grammars").st_mode) == 0o700
    assert list(tmp.iterdir()) == []  # lark's own cache=True would write /tmp/.lark_cache_*
    r = _run(cache, tmp)  # read back
    assert r.returncode == 0 and "parsed" in r.stdout, r.stderr


def test_a_file_others_could_have_written_is_not_loaded(folders):
    """A planted pickle, made writable by others, is removed unread: nothing runs, the parsers
    are built afresh and kept again."""
    cache, tmp, marker = folders
    assert _run(cache, tmp).returncode == 0
    for path in (cache / "grammars").iterdir():
        _plant(path, marker)
        path.chmod(0o666)
        assert not trusted_file(path)
    r = _run(cache, tmp)
    assert r.returncode == 0 and "parsed" in r.stdout, r.stderr
    assert not marker.exists()
    assert all(trusted_file(p) for p in (cache / "grammars").iterdir())


def test_a_folder_others_can_write_is_not_used(folders):
    """In a cache folder that others can write, even a file of the user's own is not loaded
    (another user could have replaced it), and nothing is written there."""
    cache, tmp, marker = folders
    assert _run(cache, tmp).returncode == 0
    grammars = cache / "grammars"
    for path in grammars.iterdir():
        _plant(path, marker)
    grammars.chmod(0o777)
    before = sorted(p.name for p in grammars.iterdir())
    r = _run(cache, tmp)
    assert r.returncode == 0 and "parsed" in r.stdout, r.stderr
    assert not marker.exists()
    assert sorted(p.name for p in grammars.iterdir()) == before
    assert list(tmp.iterdir()) == []


def test_the_cache_turned_off_writes_nothing(folders):
    _, tmp, _ = folders
    r = _run("", tmp)
    assert r.returncode == 0 and "parsed" in r.stdout, r.stderr
    assert list(tmp.iterdir()) == []
