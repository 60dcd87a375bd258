"""``vtts models``: the bundled models, each loaded to show what it holds (:func:`models`)."""

from __future__ import annotations

from dataclasses import dataclass

from vtts.errors import VttsError


@dataclass(frozen=True)
class Bundled:
    """A bundled model: its ``name`` and the loaded ``model`` (a
    :class:`~vtts.face.FaceModel`), or the ``error`` that stopped it loading."""

    name: str
    model: object | None = None
    error: VttsError | None = None


def models() -> list[Bundled]:
    """Every bundled model, loaded (a broken one with its error instead)."""
    from vtts.face import bundled_models, load_model

    out = []
    for name in bundled_models():
        try:
            out.append(Bundled(name, load_model(name)))
        except VttsError as e:
            out.append(Bundled(name, error=e))
    return out
