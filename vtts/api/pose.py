"""``vtts pose``: a model posed by FAPs, visemes and expressions, written as plain VRML97
(:func:`pose`); the parameter vector of a pose (:func:`posed_params`), shared with ``render``."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vtts.api.options import PoseRequest, as_list
from vtts.errors import VttsError
from vtts.messages import echo


def posed_params(model, request: tuple[dict, dict, dict]) -> np.ndarray:
    """The model's ``(N_PARAMS,)`` parameter vector for a pose request (faps, visemes,
    expressions: :meth:`PoseRequest.pose_values`), warning on stderr once about MIAPs it
    lacks."""
    from vtts.face import Miap

    faps, visemes, expressions = request
    params = model.params(faps, visemes=visemes, expressions=expressions)
    unused = [
        k
        for k in [
            *faps,
            *(f"viseme {v}" for v in visemes),
            *(f"expression {e}" for e in expressions),
        ]
        if Miap.parse(k) not in model.tables.adts
    ]
    if unused:
        echo(
            f"warning: {model.name} has no table for {', '.join(unused)}; ignored",
            file=sys.stderr,
        )
    return params


@dataclass(kw_only=True)
class PoseOptions(PoseRequest):
    """What ``vtts pose`` writes: ``model`` (a bundled name or ``.wrl`` path) posed by the
    request's FAPs, visemes and expressions, into ``output`` (a ``.wrl``); ``url_root``: more
    folders the model's urls may name."""

    model: str
    output: str
    url_root: list[str] | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        self.url_root = as_list(self.url_root) or None
        if not self.model or not self.output:
            raise VttsError("vtts pose needs a model and an output .wrl")


def pose(options: PoseOptions) -> Path:
    """Write the posed model (see :class:`PoseOptions`); the path written."""
    from vtts.api.options import check_io, url_roots_set
    from vtts.face import load_model
    from vtts.vrml import write

    check_io(options)
    request = options.pose_values()
    with url_roots_set(options.url_root):
        model = load_model(options.model)
        pose = model.engine.deform(posed_params(model, request))
        write(model.posed_scene(pose), options.output, comment=f"{model.name} posed by vtts pose")
    return Path(options.output)
