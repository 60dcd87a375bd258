"""Packages whose ``__init__`` runs when one of their names is first used.

vtts's commands start in a fraction of a second, and some packages that the libraries it uses
import are never used by them: pyrender imports trimesh in every module but uses it only to
convert trimesh meshes (vtts: VRML's Box, Sphere, Cylinder and Cone, and the room), and trimesh's
own import (scipy.spatial, networkx graphs) is half of pyrender's import time; SciPy's array-API
layer copies NumPy's namespace, which imports ``numpy.f2py``, ``numpy.testing`` and ``numpy.ma``
(70 ms of the 0.29 s of imports of ``vtts say`` on the 2-core machine). :func:`defer_package`
puts such a package in ``sys.modules`` unexecuted: importing it works as usual, and its body
runs at the first attribute anyone reads from it — or, unless told otherwise, when one of its
submodules is imported (which reads its ``__path__``), so that the package's own order of
imports holds.
"""

from __future__ import annotations

import importlib.util
import sys
import types

#: NumPy's subpackages that SciPy's import touches but vtts does not use (deferred when vtts is
#: imported: ``vtts/__init__.py``).
NUMPY_UNUSED = ("numpy.f2py", "numpy.testing", "numpy.ma")


def defer_package(name: str, *, lone_submodules: bool = False) -> None:
    """Run package ``name``'s ``__init__`` only when one of its names is first used, or one of
    its submodules is imported. With ``lone_submodules``, its submodules import meanwhile
    without it (for packages whose submodules need nothing of it: pyrender imports
    ``trimesh.transformations``). Nothing happens when it is imported already or is not a
    package. For a subpackage (``numpy.testing``) the parent is imported and given it as its
    attribute, as an import would."""
    if name in sys.modules:
        return
    parent, _, child = name.rpartition(".")
    if parent:
        importlib.import_module(parent)
        if name in sys.modules:  # the parent imported it
            return
    spec = importlib.util.find_spec(name)
    if spec is None or spec.loader is None or spec.submodule_search_locations is None:
        return
    module = importlib.util.module_from_spec(spec)
    if not lone_submodules:
        del module.__path__  # read by the import of a submodule: see _DeferredPackage
    module.__class__ = _DeferredPackage
    sys.modules[name] = module
    if parent:
        setattr(sys.modules[parent], child, module)


class _DeferredPackage(types.ModuleType):
    """A package whose ``__init__`` has not run yet (see :func:`defer_package`)."""

    def __getattr__(self, attr: str):
        # only called for names the module does not have yet (its __path__ too, when withheld):
        # run the package body once, as a plain module (a name missing while it runs is then a
        # plain AttributeError)
        self.__class__ = types.ModuleType
        self.__path__ = self.__spec__.submodule_search_locations
        self.__spec__.loader.exec_module(self)
        return getattr(self, attr)
