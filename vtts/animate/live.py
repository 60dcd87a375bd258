"""A FAP stream played as its frames arrive (``vtts play -``).

:func:`~vtts.animate.fapstream.stream_params` needs the whole stream: it holds each FAP from
the last frame that set it and plans the fills of FAPs a model lacks from the FAPs the stream
uses. :class:`LiveParams` does the same one frame at a time: it carries the held values from
frame to frame and plans the fills from the FAPs the stream's header lists, so that each frame
gets the parameter vector (and head translation) that ``stream_params`` gives it in the whole
stream — for the streams ``vtts analyze`` sends, whose every frame sets every FAP listed,
exactly the same.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable

import numpy as np

from vtts.animate.fapstream import StreamParams, stream_params
from vtts.errors import FapError
from vtts.face.miap import Miap
from vtts.fap.stream import FapStream
from vtts.fap.table import N_FAPS


class LiveParams:
    """Parameter vectors for one model from a stream's frames, one at a time.

    ``faps``: the FAPs the stream sends (its header's list); ``available``: the model's MIAPs
    (``model.tables.adts``). Calling it with each frame in order (a one-frame
    :class:`~vtts.fap.FapStream`) returns that frame's one-frame :class:`StreamParams`; a FAP the
    frame does not set keeps its last value (0 before it is first set), as MPEG-4 holds it.
    """

    def __init__(self, faps: Iterable[int], available: Collection[Miap]) -> None:
        self.faps = sorted({int(k) for k in faps})
        self.available = available
        self.values = np.zeros(N_FAPS)
        self.viseme = np.zeros(4, dtype=np.int64)
        self.expression = np.zeros(6, dtype=np.int64)
        self.translation: np.ndarray | None = None
        self.mask = np.zeros(N_FAPS, dtype=bool)
        self.mask[[k - 1 for k in self.faps]] = True

    def __call__(self, frame: FapStream) -> StreamParams:
        if frame.n_frames != 1:
            raise FapError(f"a live stream goes one frame at a time, got {frame.n_frames}")
        m = frame.mask[0]
        if np.any(m & ~self.mask):
            extra = [int(k) + 1 for k in np.flatnonzero(m & ~self.mask)]
            raise FapError(f"the frame sets FAPs {extra} that the stream's header does not list")
        self.values = np.where(m, frame.values[0], self.values)
        if m[0] and frame.viseme is not None:
            self.viseme = frame.viseme[0].copy()
        if m[1] and frame.expression is not None:
            self.expression = frame.expression[0].copy()
        if frame.translation is not None:
            self.translation = frame.translation[0].copy()
        held = FapStream(
            fps=frame.fps,
            name=frame.name,
            values=self.values[None],
            mask=self.mask[None],
            viseme=self.viseme[None],
            expression=self.expression[None],
            translation=None if self.translation is None else self.translation[None],
        )
        return stream_params(held, self.available)
