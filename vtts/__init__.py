"""vtts: an MPEG-4 face animation runtime.

Personalized talking heads (Ostermann & Haratsch) and model-based FAP analysis and coding
(Eisert & Girod). The library is usable on its own; the ``vtts`` command is a thin layer over it:
each command is a function here taking a dataclass of options (``vtts.say(vtts.SayOptions(...))``,
:mod:`vtts.api`), imported on first use.
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


def __getattr__(name: str):
    """The commands' functions and options (:data:`vtts.api.EXPORTS`), imported on first use so
    that ``import vtts`` imports none of them."""
    import importlib

    api = importlib.import_module("vtts.api")
    if name in api.EXPORTS:
        return api.export(name)
    raise AttributeError(f"module 'vtts' has no attribute {name!r}")


__all__ = ["VttsError", "VttsWarning", "__version__", "load_model", *(
    # the names vtts.api exports, written out so that tools see them without importing it
    "AnalyzeOptions", "Analyzed", "Bundled", "Checked", "DecodeOptions", "EncodeOptions",
    "Encoded", "Info", "PlayOptions", "Played", "PoseOptions", "RenderOptions", "Said",
    "SayOptions", "Spoken", "Still", "analyze", "check", "check_file", "decode", "encode",
    "info", "models", "play", "pose", "read_stream", "render_still", "say", "speak", "voices",
)]  # fmt: skip
