"""Writing a glTF document: binary (``.glb``) or JSON (``.gltf``), atomically."""

from __future__ import annotations

import os
import struct
from pathlib import Path

import pygltflib as gl

#: What :func:`write_document` writes, by suffix: binary glTF, or JSON with everything embedded.
GLTF_SUFFIXES = (".glb", ".gltf")


def glb_chunks(doc: gl.GLTF2) -> list[bytes]:
    """The binary glTF (GLB) of a document whose one buffer is its binary blob, as the byte
    strings to write one after the other: the 12-byte header, the JSON chunk (padded with
    spaces) and the BIN chunk (padded with zeros), each chunk 4-byte aligned."""
    blob = doc.binary_blob() or b""
    text = json_text(doc).encode("utf-8")
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    total = 12 + 8 + len(text) + (8 + len(blob) if blob else 0)
    out = [struct.pack("<4sII", b"glTF", 2, total), struct.pack("<I4s", len(text), b"JSON"), text]
    if blob:
        out += [struct.pack("<I4s", len(blob), b"BIN\0"), blob]
    return out


def json_text(doc: gl.GLTF2) -> str:
    """The document's JSON, compact (no spaces, no indentation)."""
    return doc.gltf_to_json(separators=(",", ":"), indent=None)


def write_document(doc: gl.GLTF2, path: str | os.PathLike[str]) -> Path:
    """Write ``doc`` to ``path`` by its suffix: ``.glb`` (:func:`glb_chunks`), anything else as
    JSON (the buffers then need uris), atomically: a temporary name renamed when complete, so
    that a failed write leaves no partial file. Returns the path."""
    from vtts.atomic import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:
        if path.suffix.lower() == ".glb":
            with open(tmp, "wb") as f:
                f.writelines(glb_chunks(doc))
        else:
            tmp.write_text(json_text(doc), "utf-8")
    return path
