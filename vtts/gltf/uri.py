"""glTF uris: base64 data uris (read and written) and files beside the glTF file."""

from __future__ import annotations

import base64
from pathlib import Path
from urllib.parse import unquote

from vtts.vrml.parser import local_path


def data_uri(data: bytes, mime: str) -> str:
    """``data`` as a base64 data uri of MIME type ``mime``."""
    return f"data:{mime};base64," + base64.b64encode(data).decode("ascii")


def is_data_uri(uri: str) -> bool:
    return uri.startswith("data:")


def data_uri_bytes(uri: str, limit: int) -> bytes:
    """The bytes of a base64 data uri of at most ``limit`` bytes. Raises ``ValueError`` naming
    the rule the uri breaks."""
    head, _, payload = uri.partition(",")
    if not head.endswith(";base64"):
        raise ValueError("only base64 data uris are read")
    # four base64 characters carry three bytes: check before decoding
    if len(payload) > limit * 4 // 3 + 4:
        raise ValueError(f"a data uri larger than {limit >> 20} MiB")
    try:
        return base64.b64decode(payload, validate=False)
    except ValueError as e:
        raise ValueError(f"bad base64 data: {e}") from None


def local_file(uri: str, folder: Path) -> Path | None:
    """The existing file a relative (percent-encoded) ``uri`` names inside ``folder``, or None:
    network uris are never fetched, and a path that leads out of ``folder`` (``..``, an absolute
    path, a symbolic link) is not followed."""
    path = local_path(unquote(uri))
    if path is None:
        return None
    base = folder.resolve()
    found = (base / path).resolve()
    if found.is_file() and base in found.parents:
        return found
    return None
