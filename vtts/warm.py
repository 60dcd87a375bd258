"""Models and renderers kept warm between the commands one process runs (``vtts batch``'s
workers).

A command loads its heads and builds a renderer (the pyrender scene of the heads, their meshes,
materials and textures on the GL context) each time it runs; a process that runs many commands
keeps them instead. Inside ``with Warm() as warm:`` the commands' :func:`load_model` and
:func:`renderer` go through ``warm``; outside any, they load and build afresh, as a single
command does. What comes out is the same either way: a kept head is the object the first load
made (a command never changes a head), and a kept renderer is handed out again only for the same
heads and view, its heads put back where its layout placed them and posed neutral, which is how a
new one starts.
"""

from __future__ import annotations

import contextlib
import os
from collections import OrderedDict
from contextvars import ContextVar
from pathlib import Path
from typing import Any

import numpy as np

from vtts.face import FaceModel

_ACTIVE: ContextVar[Warm | None] = ContextVar("vtts_warm", default=None)

#: Renderers kept at once (each holds its scene's buffers and textures on the GL context).
MAX_RENDERERS = 4
#: Heads kept at once.
MAX_MODELS = 16


def _file_key(path: Path) -> tuple:
    """What says a file is unchanged: its resolved path, size and modification time."""
    try:
        st = path.stat()
    except OSError:
        return (str(path), None)
    return (str(path.resolve()), st.st_size, st.st_mtime_ns)


class Warm:
    """Heads and renderers kept for the commands run inside ``with warm:`` (see the module).

    ``models``: loaded heads by what names them (the name as given, ``$VTTS_URL_ROOT``, and the
    ``.wrl`` and ``.adt`` files' size and time); ``renderers``: built renderers by their heads and
    view options, the least recently used dropped beyond :data:`MAX_RENDERERS`.
    """

    def __init__(self, max_models: int = MAX_MODELS, max_renderers: int = MAX_RENDERERS) -> None:
        self.max_models = max_models
        self.max_renderers = max_renderers
        self.models: OrderedDict[tuple, FaceModel] = OrderedDict()
        self.renderers: OrderedDict[tuple, tuple[Any, list[np.ndarray]]] = OrderedDict()
        #: how many heads were loaded and renderers built (not taken from what was kept)
        self.loads = 0
        self.builds = 0
        self._token = None

    def load_model(self, name: str | Path) -> FaceModel:
        """The head ``name`` (a bundled name or a ``.wrl`` path) as
        :func:`vtts.face.load_model` loads it, kept for the next command."""
        from vtts.face import find_model
        from vtts.face import load_model as load
        from vtts.vrml.parser import URL_ROOT_ENV

        path = find_model(name)
        key = (
            str(name),
            os.getcwd(),
            os.environ.get(URL_ROOT_ENV),
            _file_key(path),
            _file_key(path.with_suffix(".adt")),
        )
        model = self.models.get(key)
        if model is None:
            model = load(name)
            self.loads += 1
            self.models[key] = model
            while len(self.models) > self.max_models:
                self.models.popitem(last=False)
        self.models.move_to_end(key)
        return model

    def renderer(self, models: list[FaceModel], **options) -> contextlib.AbstractContextManager:
        """A :class:`~vtts.render.FaceRenderer` of ``models`` with ``options`` (its keyword
        arguments), as a context manager that leaves it open for the next command."""
        from vtts.face import N_PARAMS
        from vtts.render import FaceRenderer

        key = (tuple(id(m) for m in models), repr(sorted(options.items())))
        kept = self.renderers.get(key)
        if kept is None:
            r = FaceRenderer(models, **options)
            self.builds += 1
            kept = (r, [r.model_matrix(j) for j in range(len(models))])
            self.renderers[key] = kept
            while len(self.renderers) > self.max_renderers:
                self.renderers.popitem(last=False)[1][0].close()
        else:
            r, roots = kept
            # a previous command may have moved the heads (a stream's head translation)
            r.pose([np.zeros(N_PARAMS)] * len(models), roots=roots)
        self.renderers.move_to_end(key)
        return contextlib.nullcontext(kept[0])

    def close(self) -> None:
        """Release the kept renderers and heads."""
        for r, _ in self.renderers.values():
            r.close()
        self.renderers.clear()
        self.models.clear()

    def __enter__(self) -> Warm:
        self._token = _ACTIVE.set(self)
        return self

    def __exit__(self, *exc) -> None:
        _ACTIVE.reset(self._token)
        self._token = None


def active() -> Warm | None:
    """The :class:`Warm` the current command runs inside, or None."""
    return _ACTIVE.get()


def load_model(name: str | Path) -> FaceModel:
    """A command's head: kept by the active :class:`Warm`, else :func:`vtts.face.load_model`."""
    warm = active()
    if warm is not None:
        return warm.load_model(name)
    from vtts.face import load_model as load

    return load(name)


def renderer(models: list[FaceModel], **options) -> contextlib.AbstractContextManager:
    """A command's renderer as a context manager: kept by the active :class:`Warm`, else a new
    :class:`~vtts.render.FaceRenderer` closed when the ``with`` ends."""
    warm = active()
    if warm is not None:
        return warm.renderer(models, **options)
    from vtts.render import FaceRenderer

    return FaceRenderer(models, **options)
