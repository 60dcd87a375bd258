"""Where vtts keeps what it can make again (parsed models, parser tables), and whether a file
there can be trusted.

Location: ``$VTTS_CACHE_DIR``, else ``$XDG_CACHE_HOME/vtts``, else ``~/.cache/vtts``; setting
``VTTS_CACHE_DIR`` to the empty string turns every cache off. A file there is read only when
it is a regular file owned by the current user and writable by nobody else, in a folder of the
same kind: what anyone else could have planted is never loaded.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path


def cache_dir() -> Path | None:
    """Where the caches live, or None when they are turned off."""
    env = os.environ.get("VTTS_CACHE_DIR")
    if env is not None:
        return Path(env) if env else None
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "vtts"


def owned(st: os.stat_result) -> bool:
    """Owned by the current user and writable by nobody else."""
    mine = not hasattr(os, "getuid") or st.st_uid == os.getuid()
    return mine and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def safe_folder(folder: Path) -> bool:
    """Whether files in ``folder`` can only have been written by the current user."""
    try:
        st = os.lstat(folder)
    except OSError:
        return False
    return stat.S_ISDIR(st.st_mode) and owned(st)


def private_folder(name: str) -> Path | None:
    """The cache's sub-folder ``name``, made (mode 0700) if missing, or None when the cache is
    off or the folder is not the user's own (see :func:`safe_folder`)."""
    root = cache_dir()
    if root is None:
        return None
    folder = root / name
    try:
        folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    except OSError:
        return None
    return folder if safe_folder(folder) else None


def trusted_file(path: Path) -> bool:
    """Whether ``path`` may be read as data only the current user wrote: a regular file (not a
    link) owned by the user, writable by nobody else, in a folder of the same kind."""
    if not safe_folder(path.parent):
        return False
    try:
        st = os.lstat(path)
    except OSError:
        return False
    return stat.S_ISREG(st.st_mode) and owned(st)
