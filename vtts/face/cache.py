"""A cache of parsed models: a large model loads in milliseconds from the second time on.

Parsing a bundled head (a 0.6 MB scene and 4.5 MB of tables) takes a quarter of a second, a sixth
of the start-up of ``vtts say``. :func:`vtts.face.load_model` therefore keeps each model whose
files total at least :data:`MIN_BYTES`, once loaded without error, as a pickle named after the
model and a hash of everything the result depends on: the model's path, the bytes of its ``.wrl``
and ``.adt``, the source of the code that parses them (editing a parser or grammar never serves an
old parse), and the Python and numpy versions. The cache is invisible otherwise: a missing, stale,
corrupt or unwritable entry only means parsing again; errors are never cached, so a bad file fails
every time with its message; lenient loads (which may warn) are not cached. Entries are written
atomically, one per model name (a new one replaces the old).

Location: ``$VTTS_CACHE_DIR``, else ``$XDG_CACHE_HOME/vtts``, else ``~/.cache/vtts``; setting
``VTTS_CACHE_DIR`` to the empty string turns the cache off.
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import io
import os
import pickle
import sys
from functools import cache
from pathlib import Path

import numpy as np

#: Models whose files are smaller than this parse fast enough without a cache.
MIN_BYTES = 1 << 20

#: Bump to drop every entry written by older code whose source hash would not tell.
FORMAT = 1


def cache_dir() -> Path | None:
    """Where the cache lives, or None when it is turned off."""
    env = os.environ.get("VTTS_CACHE_DIR")
    if env is not None:
        return Path(env) if env else None
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "vtts"


def entry_path(files: list[Path]) -> Path | None:
    """The cache file for a model made of ``files`` (its ``.wrl`` first), or None when the model
    is too small to bother or the cache is off. Reads the files once to hash them."""
    root = cache_dir()
    if root is None:
        return None
    try:
        contents = [f.read_bytes() for f in files]
    except OSError:
        return None
    if sum(len(c) for c in contents) < MIN_BYTES:
        return None
    h = hashlib.blake2b(digest_size=20)
    h.update(f"{FORMAT} {sys.version} {np.__version__} {_code_hash()}".encode())
    for f, c in zip(files, contents, strict=True):
        h.update(f"\0{f.resolve()}\0{len(c)}\0".encode())
        h.update(c)
    return root / "models" / f"{files[0].stem}-{h.hexdigest()}.pickle"


def load(entry: Path):
    """The model stored at ``entry``, or None (missing, unreadable, from other code)."""
    try:
        data = entry.read_bytes()
    except OSError:
        return None
    try:
        return _Unpickler(io.BytesIO(data)).load()
    except Exception:  # a corrupt or foreign entry is a miss, and is dropped
        with contextlib.suppress(OSError):
            entry.unlink()
        return None


def store(entry: Path, model) -> None:
    """Keep ``model`` at ``entry``, in place of older entries of a model of the same name (so the
    cache holds one entry per model name); failing to write (read-only home, full disk) is not
    an error."""
    from vtts.atomic import atomic_path

    buffer = io.BytesIO()
    _Pickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump(model)
    stem = entry.name.rsplit("-", 1)[0]
    with contextlib.suppress(OSError):
        entry.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        for old in entry.parent.glob(f"{glob.escape(stem)}-*.pickle"):
            if old.name.rsplit("-", 1)[0] == stem:
                old.unlink(missing_ok=True)
        with atomic_path(entry) as tmp:
            tmp.write_bytes(buffer.getvalue())


@cache
def _code_hash() -> str:
    """A hash of the source that turns model files into models: the VRML and face packages and
    the grammars."""
    from vtts.resources import grammar_path

    package = Path(__file__).resolve().parents[1]
    sources = sorted((package / "vrml").glob("*.*")) + sorted((package / "face").glob("*.py"))
    sources += sorted(grammar_path("adt").parent.glob("*.lark"))
    h = hashlib.blake2b(digest_size=20)
    for p in sources:
        h.update(p.name.encode() + b"\0" + p.read_bytes())
    return h.hexdigest()


class _Pickler(pickle.Pickler):
    """Pickles the standard node types by name, so that a cached scene shares them with a parsed
    one (code compares node types by identity)."""

    def persistent_id(self, obj):
        from vtts.vrml import NodeType, standard_node_types

        if isinstance(obj, NodeType) and standard_node_types().get(obj.name) is obj:
            return ("standard node type", obj.name)
        return None


class _Unpickler(pickle.Unpickler):
    def persistent_load(self, pid):
        from vtts.vrml import standard_node_types

        kind, name = pid
        if kind != "standard node type":
            raise pickle.UnpicklingError(f"unknown persistent id {pid!r}")
        return standard_node_types()[name]
