"""``vtts render``: one pose of one or more models as an image (:func:`render`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vtts.api.options import Heads, PoseRequest, View


@dataclass(kw_only=True)
class RenderOptions(Heads, PoseRequest, View):
    """What ``vtts render`` draws: the heads (:class:`~vtts.api.options.Heads`) in a pose
    (:class:`~vtts.api.options.PoseRequest`) seen so (:class:`~vtts.api.options.View`);
    ``output``: the PNG written (None: the frame is only returned). ``detail`` None draws every
    triangle."""

    output: str | None = None

    def __post_init__(self) -> None:
        Heads.__post_init__(self)
        PoseRequest.__post_init__(self)
        self.background_color(video=False)  # a bad color fails before the models load
        self.check_view(video=False)
        self.require_model()

    def detail_px(self) -> float | None:
        """A still draws every triangle unless ``detail`` says otherwise: it is looked at, not
        played."""
        return self.detail


@dataclass(frozen=True)
class Still:
    """A rendered pose: ``frame``, ``(height, width, 3)`` uint8 RGB (4 channels with a
    transparent background), and the PNG it was written to (or None)."""

    frame: np.ndarray
    output: Path | None


def render(options: RenderOptions) -> Still:
    """Render the pose (antialiased: drawn at twice the size and filtered down)."""
    from vtts.api.options import check_io, url_roots_set
    from vtts.api.pose import posed_params
    from vtts.render import write_png
    from vtts.warm import load_model  # kept between the jobs of vtts batch

    check_io(options)
    request = options.pose_values()
    with url_roots_set(options.url_root):
        models = [load_model(m) for m in options.model]
        params = [posed_params(m, request) for m in models]
        with options.renderer(models, supersample=2) as renderer:
            frame = renderer.render(params)
    if options.output is not None:
        write_png(options.output, frame)
    return Still(frame, None if options.output is None else Path(options.output))
