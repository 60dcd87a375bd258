"""vtts: an MPEG-4 face animation runtime.

Personalized talking heads (Ostermann & Haratsch) and model-based FAP analysis and coding
(Eisert & Girod). The library is usable on its own; the ``vtts`` command is a thin layer over it.
"""

from vtts.errors import VttsError, VttsWarning

__version__ = "0.1.0"

__all__ = ["VttsError", "VttsWarning", "__version__"]
