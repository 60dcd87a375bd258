"""A cache of parsed models: a large model loads in milliseconds from the second time on.

Parsing a bundled head (its scene and its much larger tables) is a good part of the start-up of
``vtts say`` (docs/design.md, "Model cache"). :func:`vtts.face.load_model` therefore keeps each
model whose files total at least :data:`MIN_BYTES`, once loaded without error, as an entry named
after the model and a hash of everything the result depends on: the model's path, the bytes of
its ``.wrl`` and ``.adt``, the source of the code that parses them (editing a parser or grammar
never serves an old parse), and the Python and numpy versions. The cache is invisible otherwise:
a missing, stale, corrupt or unwritable entry only means parsing again; errors are never cached,
so a bad file fails every time with its message; lenient loads (which may warn) are not cached.
Entries are written atomically, one per model name (a new one replaces the old).

An entry is data that cannot run code, whoever wrote it: one uncompressed ``.npz`` (read with
``allow_pickle=False``) holding a JSON document of the object graph and, per dtype, one flat array
that the graph's arrays are views of. The document may name only the classes in :data:`_CLASSES`,
built through their constructors (which validate) with fields of the annotated kinds; anything
else — a planted pickle, a truncated or foreign file, an entry not owned by the current user or in
a folder others can write — is a miss.

Location: ``models/`` in :func:`vtts.usercache.cache_dir` (``$VTTS_CACHE_DIR``, else
``$XDG_CACHE_HOME/vtts``, else ``~/.cache/vtts``); setting ``VTTS_CACHE_DIR`` to the empty
string turns the cache off.
"""

from __future__ import annotations

import contextlib
import dataclasses
import glob
import hashlib
import io
import json
import math
import os
import stat
import sys
import types
import typing
import zipfile
from functools import cache
from pathlib import Path, PurePath
from typing import TYPE_CHECKING, Any

import numpy as np

from vtts.limits import MAX_CACHE_ENTRY_BYTES
from vtts.usercache import cache_dir
from vtts.usercache import owned as _owned
from vtts.usercache import safe_folder as _safe_folder

if TYPE_CHECKING:
    from vtts.face.adt import AnimationTables
    from vtts.face.model import FaceModel
    from vtts.vrml.scene import Scene

#: Models whose files are smaller than this parse fast enough without a cache.
MIN_BYTES = 1 << 20

#: Bump to drop every entry written by older code whose source hash would not tell.
FORMAT = 2

SUFFIX = ".npz"
#: Entries of older formats, removed when a model's entry is rewritten.
_OLD_SUFFIXES = (".pickle",)
#: The dtypes an entry's arrays may have (numbers only: no objects, no byte swapping).
_DTYPES = frozenset({"|b1", "|u1", "|i1", "<i2", "<u2", "<i4", "<u4", "<i8", "<u8", "<f4", "<f8"})


def entry_path(files: list[Path]) -> Path | None:
    """The cache file for a model made of ``files`` (its ``.wrl`` first), or None when the model
    is too small to bother or the cache is off. Reads the files once to hash them."""
    root = cache_dir()
    if root is None:
        return None
    try:
        sizes = [f.stat().st_size for f in files]
        if sum(sizes) < MIN_BYTES:
            return None
        contents = [f.read_bytes() for f in files]
    except OSError:
        return None
    h = hashlib.blake2b(digest_size=20)
    h.update(f"{FORMAT} {sys.version} {np.__version__} {_code_hash()}".encode())
    for f, c in zip(files, contents, strict=True):
        h.update(f"\0{f.resolve()}\0{len(c)}\0".encode())
        h.update(c)
    return root / "models" / f"{files[0].stem}-{h.hexdigest()}{SUFFIX}"


def load(entry: Path) -> tuple[Scene, AnimationTables] | None:
    """The model stored at ``entry`` as its scene and tables (:func:`vtts.face.load_model` makes
    the model of them), or None (missing, unreadable, unsafe, from other code)."""
    if not _safe_folder(entry.parent):
        return None
    try:
        fd = os.open(entry, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except OSError:
        return None
    with os.fdopen(fd, "rb") as f:
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode) or not _owned(st):
                return None
            if st.st_size > MAX_CACHE_ENTRY_BYTES:
                return None
            data = f.read(MAX_CACHE_ENTRY_BYTES + 1)
        except OSError:
            return None
    try:
        return decode(data)
    except Exception:  # a corrupt or foreign entry is a miss, and is dropped
        with contextlib.suppress(OSError):
            entry.unlink()
        return None


def store(entry: Path, model: FaceModel) -> None:
    """Keep ``model`` at ``entry``, in place of older entries of a model of the same name (so the
    cache holds one entry per model name); failing to write (read-only home, full disk, a folder
    that is not the user's own) is not an error."""
    from vtts.atomic import atomic_path

    try:
        data = encode(model)
    except (TypeError, ValueError, RecursionError):  # a model the format cannot hold is not kept
        return
    stem = entry.name.rsplit("-", 1)[0]
    with contextlib.suppress(OSError):
        entry.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        if not _safe_folder(entry.parent):
            return
        for suffix in (SUFFIX, *_OLD_SUFFIXES):
            for old in entry.parent.glob(f"{glob.escape(stem)}-*{suffix}"):
                if old.name.rsplit("-", 1)[0] == stem:
                    old.unlink(missing_ok=True)
        with atomic_path(entry) as tmp:
            tmp.write_bytes(data)


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


# ---- the entry format ----------------------------------------------------------------------------
#
# The document is JSON where every value that is not a JSON scalar is a one-key object:
#   {"L": [...]} list   {"T": [...]} tuple   {"S": [...]} set   {"F": [...]} frozenset
#   {"D": [[k, v], ...]} dict (any keys, in order)   {"P": "..."} path
#   {"A": [dtype, offset, shape]} an array: a view of the flat array of its dtype
#   {"O": [class, {field: value}]} an instance of one of _CLASSES
#   {"N": name} a standard VRML node type   {"V": name} a VRML field type
#   {"R": k} the k-th list, set, dict, array or instance built so far (shared objects stay shared)


@cache
def _classes() -> dict[str, type]:
    """The classes an entry may hold, by name."""
    from vtts.face.adt import Adt, AnimationTables, MeshTable, TransformTable
    from vtts.face.miap import Miap
    from vtts.face.temporal import ExpressionTiming, Habit, TemporalTables
    from vtts.vrml.fields import SFImage
    from vtts.vrml.nodes import FieldDecl, NodeType
    from vtts.vrml.scene import Node, Proto, Route, Scene

    return {
        c.__name__: c
        for c in (
            Scene, Node, Route, Proto, NodeType, FieldDecl, SFImage,
            AnimationTables, Adt, MeshTable, TransformTable, Miap,
            TemporalTables, ExpressionTiming, Habit,
        )
    }  # fmt: skip


def encode(model: FaceModel) -> bytes:
    """The entry for ``model``: ``.npz`` bytes. Raises TypeError or ValueError for a value the
    format cannot hold (the model is then not cached)."""
    enc = _Encoder()
    doc = {"format": FORMAT, "scene": enc.value(model.scene), "tables": enc.value(model.tables)}
    extra = set(vars(model)) - {"scene", "tables", "path", "engine", "fapu"}
    if extra:
        raise TypeError(f"a model with attributes {sorted(extra)} cannot be cached")
    arrays = {
        f"a{i}": np.concatenate(parts) if parts else np.zeros(0, dt)
        for i, (dt, parts) in enumerate(enc.arrays.items())
    }
    doc["dtypes"] = list(enc.arrays)
    text = json.dumps(doc, separators=(",", ":"), ensure_ascii=True)
    buffer = io.BytesIO()
    np.savez(buffer, doc=np.frombuffer(text.encode("ascii"), np.uint8), **arrays)
    return buffer.getvalue()


def decode(data: bytes) -> tuple[Scene, AnimationTables]:
    """The model's scene and tables in an entry's bytes. Raises (anything) for an entry that is
    not one."""
    from vtts.face.adt import AnimationTables, check_tables
    from vtts.vrml.scene import Scene

    with zipfile.ZipFile(io.BytesIO(data)) as z:  # no member may inflate beyond the entry
        if any(i.compress_type != zipfile.ZIP_STORED for i in z.infolist()):
            raise ValueError("compressed members")
    with np.load(io.BytesIO(data), allow_pickle=False) as npz:
        doc = json.loads(npz["doc"].tobytes().decode("ascii"))
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise ValueError("another format")
        dtypes = doc["dtypes"]
        if not isinstance(dtypes, list) or len(dtypes) != len(npz.files) - 1:
            raise ValueError("arrays do not match the document")
        flats = {}
        for i, dt in enumerate(dtypes):
            flat = npz[f"a{i}"]
            if dt not in _DTYPES or flat.dtype.str != dt or flat.ndim != 1:
                raise ValueError(f"array {i}: {flat.dtype.str} {flat.shape}")
            flats[dt] = flat
    dec = _Decoder(flats)
    scene, tables = dec.value(doc["scene"]), dec.value(doc["tables"])
    if not (isinstance(scene, Scene) and isinstance(tables, AnimationTables)):
        raise TypeError("not a model")
    check_tables(tables, scene)
    return scene, tables


class _Encoder:
    def __init__(self) -> None:
        from vtts.vrml.fields import FIELD_TYPES
        from vtts.vrml.nodes import standard_node_types

        self.memo: dict[int, int] = {}
        self.keep: list[Any] = []  # keeps memoized objects alive so that ids stay unique
        self.busy: set[int] = set()
        self.arrays: dict[str, list[np.ndarray]] = {}
        self.sizes: dict[str, int] = {}
        self.field_types = FIELD_TYPES
        self.node_types = standard_node_types()

    def value(self, v: Any) -> Any:
        from vtts.vrml.fields import FieldType
        from vtts.vrml.nodes import NodeType

        if v is None or isinstance(v, (bool, str)):
            return v
        if isinstance(v, (int, float)) and type(v) in (int, float, np.float64):
            return float(v) if isinstance(v, float) else v
        if isinstance(v, tuple) and type(v) is tuple:
            return {"T": [self.value(x) for x in v]}
        if isinstance(v, PurePath):
            return {"P": str(v)}
        if isinstance(v, FieldType):
            if self.field_types.get(v.name) is not v:
                raise TypeError(f"field type {v.name} is not a standard one")
            return {"V": v.name}
        if isinstance(v, NodeType) and self.node_types.get(v.name) is v:
            return {"N": v.name}
        if id(v) in self.memo:
            return {"R": self.memo[id(v)]}
        if id(v) in self.busy:
            raise ValueError("a cycle in the model's object graph")
        self.busy.add(id(v))
        out = self._compound(v)
        self.busy.discard(id(v))
        self.memo[id(v)] = len(self.memo)
        self.keep.append(v)
        return out

    def _compound(self, v: Any) -> Any:
        if type(v) is list:
            return {"L": [self.value(x) for x in v]}
        if type(v) in (set, frozenset):
            items = sorted(v, key=repr)  # a stable entry for the same model
            return {"S" if type(v) is set else "F": [self.value(x) for x in items]}
        if type(v) is dict:
            return {"D": [[self.value(k), self.value(x)] for k, x in v.items()]}
        if type(v) is np.ndarray:
            a = np.ascontiguousarray(v)
            dt = a.dtype.newbyteorder("<").str if a.dtype.byteorder != "|" else a.dtype.str
            if dt not in _DTYPES:
                raise TypeError(f"an array of dtype {a.dtype} cannot be cached")
            flat = a.astype(dt, copy=False).reshape(-1)
            offset = self.sizes.get(dt, 0)
            self.arrays.setdefault(dt, []).append(flat)
            self.sizes[dt] = offset + flat.size
            return {"A": [dt, offset, list(a.shape)]}
        name = type(v).__name__
        if _classes().get(name) is not type(v):
            raise TypeError(f"a {type(v).__qualname__} cannot be cached")
        names = [f.name for f in dataclasses.fields(v)]
        if set(vars(v)) - set(names):
            raise TypeError(f"a {name} with attributes beyond its fields cannot be cached")
        return {"O": [name, {n: self.value(getattr(v, n)) for n in names}]}


class _Decoder:
    def __init__(self, flats: dict[str, np.ndarray]) -> None:
        from vtts.vrml.fields import FIELD_TYPES
        from vtts.vrml.nodes import standard_node_types

        self.flats = flats
        self.built: list[Any] = []
        self.field_types = FIELD_TYPES
        self.node_types = standard_node_types()

    def value(self, j: Any) -> Any:
        if j is None or isinstance(j, (bool, int, float, str)):
            return j
        if not (isinstance(j, dict) and len(j) == 1):
            raise ValueError(f"not a value: {str(j)[:40]}")
        ((tag, body),) = j.items()
        if tag == "T":
            return tuple(self.value(x) for x in _list(body))
        if tag == "P":
            return Path(_str(body))
        if tag == "V":
            return self.field_types[_str(body)]
        if tag == "N":
            return self.node_types[_str(body)]
        if tag == "R":
            if type(body) is not int or not 0 <= body < len(self.built):
                raise ValueError(f"reference {body!r}")
            return self.built[body]
        if tag == "L":
            v = [self.value(x) for x in _list(body)]
        elif tag in ("S", "F"):
            items = [self.value(x) for x in _list(body)]
            v = set(items) if tag == "S" else frozenset(items)
        elif tag == "D":
            v = {}
            for pair in _list(body):
                k, x = _list(pair, 2)
                key = self.value(k)  # before the value: references count in document order
                v[key] = self.value(x)
        elif tag == "A":
            dt, offset, shape = _list(body, 3)
            flat = self.flats[dt]
            shape = tuple(_list(shape))
            if not all(type(n) is int and n >= 0 for n in (offset, *shape)):
                raise ValueError(f"array {body!r}")
            size = math.prod(shape)
            if offset + size > flat.size:
                raise ValueError(f"array {body!r} beyond its data")
            v = flat[offset : offset + size].reshape(shape)
        elif tag == "O":
            name, fields = _list(body, 2)
            v = _build(_classes()[_str(name)], {k: self.value(x) for k, x in fields.items()})
        else:
            raise ValueError(f"unknown tag {tag!r}")
        self.built.append(v)
        return v


def _list(j: Any, n: int | None = None) -> list:
    if type(j) is not list or (n is not None and len(j) != n):
        raise ValueError(f"expected a list{f' of {n}' if n else ''}, got {str(j)[:40]}")
    return j


def _str(j: Any) -> str:
    if type(j) is not str:
        raise ValueError(f"expected a string, got {str(j)[:40]}")
    return j


def _build(cls: type, values: dict[str, Any]) -> Any:
    """An instance of ``cls`` through its constructor, after checking that ``values`` are exactly
    its fields, each of its annotated kind (outer type only: list, dict, ndarray, a class)."""
    hints = _hints(cls)
    if set(values) != set(hints):
        raise ValueError(f"{cls.__name__}: fields {sorted(values)}, expected {sorted(hints)}")
    for name, allowed in hints.items():
        if allowed and not isinstance(values[name], allowed):
            raise TypeError(f"{cls.__name__}.{name}: a {type(values[name]).__name__}")
    check = _CHECKS.get(cls.__name__)
    if check is not None:  # a cheap check in place of a costly constructor
        check(values)
        obj = object.__new__(cls)
        for k, v in values.items():
            object.__setattr__(obj, k, v)
        return obj
    init = _init_fields(cls)
    obj = cls(**{k: v for k, v in values.items() if k in init})
    for k in values.keys() - init:
        object.__setattr__(obj, k, values[k])
    return obj


def _check_mesh_table(v: dict[str, Any]) -> None:
    # The values were checked when the model was parsed (increasing borders with 0 among them,
    # distinct vertices: np.unique over every table would take a third of the load); what an
    # entry could still get wrong is the arrays' kinds and shapes.
    b, vertices, d = v["borders"], v["vertices"], v["displacements"]
    if not (isinstance(v["node"], str) and b.dtype == np.float64 and vertices.dtype == np.int64):
        raise TypeError("MeshTable: array kinds")
    if b.ndim != 1 or b.size < 2 or vertices.ndim != 1:
        raise ValueError("MeshTable: array shapes")
    if d.dtype != np.float64 or d.shape != (b.size - 1, vertices.size, 3):
        raise ValueError(f"MeshTable: displacements of shape {d.shape}")
    if vertices.size and vertices.min() < 0:
        raise ValueError("MeshTable: a negative vertex")


_CHECKS = {"MeshTable": _check_mesh_table}


@cache
def _init_fields(cls: type) -> frozenset[str]:
    return frozenset(f.name for f in dataclasses.fields(cls) if f.init)


@cache
def _hints(cls: type) -> dict[str, tuple[type, ...]]:
    """Field name → the types its value may have (empty: any)."""
    hints = typing.get_type_hints(cls)
    return {f.name: _outer(hints[f.name]) for f in dataclasses.fields(cls)}


def _outer(hint: Any) -> tuple[type, ...]:
    if hint is Any:
        return ()
    if isinstance(hint, types.UnionType) or typing.get_origin(hint) is typing.Union:
        parts = [_outer(h) for h in typing.get_args(hint)]
        return () if any(p == () for p in parts) else tuple(t for p in parts for t in p)
    origin = typing.get_origin(hint) or hint
    if origin is float:
        return (float, int)
    if origin is type(None):
        return (type(None),)
    if isinstance(origin, type):
        return (origin,)
    return ()
