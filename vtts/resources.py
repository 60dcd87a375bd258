"""Finding the files that ship with vtts (grammars, bundled models, data tables), and the
parsers of its grammars.

In a wheel, ``grammars/`` and ``models/`` are installed inside the package as ``vtts/_data/``; in a
source checkout (editable install) they sit at the top of the repository. Code asks this module,
never the current working directory.
"""

from __future__ import annotations

import hashlib
import sys
from functools import cache
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def _data_root(name: str) -> Path:
    installed = _PACKAGE / "_data" / name
    if installed.is_dir():
        return installed
    checkout = _PACKAGE.parent / name
    if checkout.is_dir():
        return checkout
    raise FileNotFoundError(f"vtts installation is incomplete: no {name}/ folder found")


def grammar_path(name: str) -> Path:
    """Path of ``grammars/NAME.lark``."""
    return _data_root("grammars") / f"{name}.lark"


@cache
def grammar_text(name: str) -> str:
    """The text of ``grammars/NAME.lark``."""
    return grammar_path(name).read_text(encoding="utf-8")


def lark_parser(name: str, **options):
    """A lark parser (``lark.Lark``) of ``grammars/NAME.lark`` with ``options`` (an LALR
    parser's, e.g. ``parser="lalr", lexer="contextual"``), its tables kept between processes.

    Building the VRML97 grammar's tables takes about 80 ms and the ``.adt`` one's 40; lark keeps
    them in a file it reads back with ``pickle``, which runs whatever code the file names. Its
    own place for that file (``cache=True``) is the shared temporary folder under a name anyone
    can predict, so another user could plant one there for vtts to run. vtts gives lark a file in
    the user's own cache folder instead (``grammars/`` in :func:`vtts.usercache.cache_dir`,
    named by a hash of the grammar, the options and the lark and Python versions), and only when
    that folder and any file already there are the user's own and writable by nobody else
    (:func:`vtts.usercache.trusted_file`; an untrusted file is removed first); otherwise, or
    with ``VTTS_CACHE_DIR=""``, the tables are built afresh."""
    import lark

    from vtts.usercache import private_folder, trusted_file

    text = grammar_text(name)
    cache_file: str | bool = False
    folder = private_folder("grammars")
    if folder is not None:
        key = f"{text}\0{sorted(options.items())!r}\0{lark.__version__}\0{sys.version}"
        path = folder / f"{name}-{hashlib.sha256(key.encode()).hexdigest()[:20]}.lark"
        if path.exists() or path.is_symlink():
            if not trusted_file(path):
                try:
                    path.unlink()
                except OSError:
                    path = None
        if path is not None:
            cache_file = str(path)
    return lark.Lark(text, cache=cache_file, **options)


def models_dir() -> Path:
    """The folder of bundled models."""
    return _data_root("models")


def package_data(name: str) -> Path:
    """Path of a data file inside the package (``vtts/data/NAME``)."""
    return _PACKAGE / "data" / name
