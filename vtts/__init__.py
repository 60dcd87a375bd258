"""vtts: an MPEG-4 face animation runtime.

Personalized talking heads (Ostermann & Haratsch) and model-based FAP analysis and coding
(Eisert & Girod). The library is usable on its own; the ``vtts`` command is a thin layer over it.
"""

from vtts.deferred import NUMPY_UNUSED, defer_package
from vtts.errors import VttsError, VttsWarning

for _package in NUMPY_UNUSED:  # see vtts.deferred: a faster start, nothing else changes
    defer_package(_package)

__version__ = "0.1.0"


def load_model(name_or_path, *, lenient: bool = False, url_root=None):
    """Load a personalized model by path or bundled short name (see
    :func:`vtts.face.load_model`)."""
    from vtts.face import load_model as _load

    return _load(name_or_path, lenient=lenient, url_root=url_root)


__all__ = ["VttsError", "VttsWarning", "__version__", "load_model"]
