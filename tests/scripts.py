"""The repository's scripts (``scripts/``, ``models/src/``) loaded as modules, for their tests."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]


def load_script(relative: str, name: str | None = None) -> ModuleType:
    """The script at ``relative`` (to the repository's root, e.g. ``scripts/mc_bound.py``) run
    as a module named ``name`` (default: the file's stem) and registered in ``sys.modules`` as
    an import would register it (its dataclasses look their module up there)."""
    path = ROOT / relative
    spec = importlib.util.spec_from_file_location(name or path.stem, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module
