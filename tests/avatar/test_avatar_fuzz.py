"""Hostile glTF avatars: every value of a small avatar's JSON replaced, one at a time, by junk of
another type or size. The import either succeeds or fails with a vtts error naming the file; it
never raises anything else (a Python traceback for a CLI user) and never allocates without
bound."""

from __future__ import annotations

import json
import random
import struct
import warnings

import pytest

from vtts.avatar.importer import import_avatar
from vtts.errors import VttsError

from .avatar_helpers import simple_avatar

JUNK = [None, -1, -(2**31), 2**40, 10**12, 0.5, float("nan"), "x", "", [], [1, 2], {}, {"a": 1},
        True, [None] * 3, -12, 7]  # fmt: skip


def _glb_parts(data: bytes) -> tuple[dict, bytes]:
    (json_len,) = struct.unpack_from("<I", data, 12)
    doc = json.loads(data[20 : 20 + json_len])
    return doc, data[20 + json_len :]


def _glb(doc: dict, rest: bytes) -> bytes:
    text = json.dumps(doc, allow_nan=True).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + rest
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def _paths(node, prefix=()):
    """Every (path, value) in a JSON tree."""
    yield prefix, node
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, (*prefix, i))


def _replace(doc, path, value):
    target = doc
    for k in path[:-1]:
        target = target[k]
    target[path[-1]] = value


@pytest.fixture(scope="module")
def avatar_bytes(tmp_path_factory):
    path = simple_avatar(tmp_path_factory.mktemp("fuzz") / "a.glb", ["jawOpen", "eyeBlink_L"],
                         n=3)  # fmt: skip
    return path.read_bytes()


def test_junk_values_give_clear_errors(avatar_bytes, tmp_path):
    doc, rest = _glb_parts(avatar_bytes)
    paths = [p for p, _ in _paths(doc) if p]
    rng = random.Random(18)
    cases = [(p, j) for p in paths for j in JUNK]
    rng.shuffle(cases)
    failures = []
    for k, (path, junk) in enumerate(cases[:400]):
        mutated = json.loads(json.dumps(doc))
        _replace(mutated, path, junk)
        f = tmp_path / f"m{k}.glb"
        f.write_bytes(_glb(mutated, rest))
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                import_avatar(f)
        except VttsError as e:
            if e.file != str(f):
                failures.append((path, junk, f"error without the file: {e}"))
        except Exception as e:  # noqa: BLE001 - the point of the test
            failures.append((path, junk, f"{type(e).__name__}: {e}"))
    assert not failures, "\n".join(map(str, failures))
