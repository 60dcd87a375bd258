"""Finding the files that ship with vtts (grammars, bundled models, data tables).

In a wheel, ``grammars/`` and ``models/`` are installed inside the package as ``vtts/_data/``; in a
source checkout (editable install) they sit at the top of the repository. Code asks this module,
never the current working directory.
"""

from __future__ import annotations

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


def models_dir() -> Path:
    """The folder of bundled models."""
    return _data_root("models")


def package_data(name: str) -> Path:
    """Path of a data file inside the package (``vtts/data/NAME``)."""
    return _PACKAGE / "data" / name
