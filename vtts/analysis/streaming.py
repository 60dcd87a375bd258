"""Estimates written as a streamed ``.fbs`` bitstream as soon as they are made.

:class:`EstimateStream` is the ``on_estimate`` of :func:`vtts.analysis.track.track` that
``vtts analyze --stream`` passes: the first estimate writes the bitstream's header (after
``before_header``, which puts a fitted head in place so that a reader can load it when the
header arrives), each estimate one packet (:class:`vtts.fap.coding.StreamEncoder`), flushed at
once; :meth:`EstimateStream.end` writes the end marker. The frames decode to what ``vtts
analyze -o OUT.fbs`` codes for the same estimates (the estimated FAPs rounded to integers, the
head translation in ES units, the same ``quantizer``) with the same base steps — a stream's are
taken at its first estimate (``steps``), a file's at the sequence's median pose; the predictor
pairs are fixed in advance (:func:`~vtts.fap.coding.paired_predictors`), as a stream cannot
choose them from its frames.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import BinaryIO

from vtts.analysis.result import TRANSLATION, Analysis, FrameEstimate
from vtts.fap.coding import StreamEncoder, paired_predictors
from vtts.fap.fapu import Fapu
from vtts.render.camera import Camera


class EstimateStream:
    """Writes each :class:`FrameEstimate` to ``sink`` as a packet of a streamed ``.fbs``.

    sink           a binary file object (stdout's buffer); flushed after each write
    fps            the rate of the estimates, Hz
    unknowns       what is estimated (FAP numbers, ``"tx"``, ``"ty"``, ``"tz"``): the FAPs sent,
                   and the head translation when any of its axes is estimated
    name           the stream's name
    fapu           gives the tracked model's FAPUs (the translation's ES; None: the translation
                   is not sent), called once, at the first estimate (a fitted head exists by
                   then)
    before_header  called once before the header is written
    steps          given the first estimate, the coder's base steps (``encode``'s ``steps``,
                   e.g. :func:`vtts.analysis.steps.coding_steps` at that estimate's pose);
                   None: MPEG-4's

    :attr:`framing_s` adds up the seconds spent coding and writing (the latency the streaming
    adds to each estimate), :attr:`bytes_written` the bytes.
    """

    def __init__(
        self,
        sink: BinaryIO,
        *,
        fps: float,
        unknowns: Sequence[int | str],
        name: str,
        fapu: Callable[[], Fapu | None],
        before_header: Callable[[], None] | None = None,
        steps: Callable[[FrameEstimate], Mapping[int | str, int]] | None = None,
        quantizer: float = 1.0,
    ) -> None:
        self.sink = sink
        self.fps = float(fps)
        self.unknowns = tuple(unknowns)
        self.name = name
        self._fapu_of = fapu
        self._fapu: Fapu | None = None
        self._before = before_header
        self._steps_of = steps
        self.quantizer = float(quantizer)
        self.encoder: StreamEncoder | None = None
        self.framing_s = 0.0
        self.bytes_written = 0
        self.frames = 0

    def _write(self, data: bytes) -> None:
        self.sink.write(data)
        self.sink.flush()
        self.bytes_written += len(data)

    def _open(self, first: FrameEstimate) -> StreamEncoder:
        if self._before is not None:
            self._before()
        self._fapu = self._fapu_of()
        faps = sorted(u for u in self.unknowns if isinstance(u, int))
        steps = None if self._steps_of is None else self._steps_of(first)
        encoder = StreamEncoder(
            fps=self.fps,
            faps=faps,
            # without FAPUs the translation has no ES units to go in (as Analysis.stream)
            translation=self._fapu is not None and any(u in TRANSLATION for u in self.unknowns),
            name=self.name,
            # a frame held (no estimate of its own) sets no FAP (Analysis.stream): the mask may
            # change; its flag per frame costs the arithmetic coder next to nothing
            constant_mask=False,
            predictors=paired_predictors(faps, steps),
            steps=steps,
            quantizer=self.quantizer,
        )
        self._write(encoder.header())
        return encoder

    def __call__(self, estimate: FrameEstimate) -> None:
        if self.encoder is None:
            self.encoder = self._open(estimate)
        start = time.perf_counter()
        one = Analysis([estimate], self.unknowns, self.fps, Camera(1, 1, 0, 0))
        data = self.encoder.frames(one.stream(self.name, fapu=self._fapu))
        self._write(data)
        self.framing_s += time.perf_counter() - start
        self.frames += 1

    def end(self) -> None:
        """The end marker (a stream that never had an estimate gets no header, nor end)."""
        if self.encoder is not None:
            self._write(self.encoder.end())
