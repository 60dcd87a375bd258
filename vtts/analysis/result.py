"""What an analysis produces: one estimate per analyzed frame, and the stream they make."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vtts.fap.fapu import Fapu
from vtts.fap.stream import FapStream
from vtts.fap.table import N_FAPS
from vtts.render.camera import Camera

#: Names of the unknowns that are not FAPs: the head's translation (model units, world axes).
TRANSLATION = ("tx", "ty", "tz")


@dataclass
class FrameEstimate:
    """The estimate for one video frame.

    index        frame number in the video (0-based)
    time         seconds from the video's start
    params       ``(N_PARAMS,)`` parameter vector; FAP k (FAPU, AU for rotations) at ``k - 1``
    translation  ``(3,)`` head translation in model units (world x right, y up, z to the camera)
    gain, offset ``(3,)`` per RGB channel: the camera frame ≈ gain · synthetic + offset (0–255)
    psnr         luminance PSNR (dB) over the face area between the frame and the model rendered
                 with the estimate; ``inf`` when identical
    face_pixels  how many pixels the face area has (model pixels at full resolution)
    iterations   linear solves made for this frame, over all pyramid levels
    landmark_px  median distance (pixels) between the face mesh's landmarks of the frame and
                 where the estimate puts their points; NaN when none were observed
    held         no estimate of its own: the landmarks lost the face or the estimate failed, and
                 the last good estimate stands in (its coded frame sets no FAP: a decoder holds
                 the last values)
    """

    index: int
    time: float
    params: np.ndarray
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gain: np.ndarray = field(default_factory=lambda: np.ones(3))
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    psnr: float = float("nan")
    face_pixels: int = 0
    iterations: int = 0
    landmark_px: float = float("nan")
    held: bool = False


@dataclass
class Analysis:
    """The estimates of a video, in frame order.

    ``unknowns`` names what was estimated: FAP numbers (ints) and ``"tx"``, ``"ty"``, ``"tz"``.
    ``fps`` is the rate of the estimates (the video's rate divided by the frame step).
    """

    frames: list[FrameEstimate]
    unknowns: tuple[int | str, ...]
    fps: float
    camera: Camera
    model: str = ""

    @property
    def faps(self) -> tuple[int, ...]:
        """The estimated FAP numbers, in order."""
        return tuple(u for u in self.unknowns if isinstance(u, int))

    def fap_values(self) -> np.ndarray:
        """``(n_frames, len(faps))`` estimated FAP values (FAPU)."""
        idx = [f - 1 for f in self.faps]
        return np.array([fe.params[idx] for fe in self.frames]).reshape(len(self.frames), -1)

    def psnr(self) -> np.ndarray:
        """``(n_frames,)`` face-area PSNR of each estimate (dB)."""
        return np.array([fe.psnr for fe in self.frames], dtype=np.float64)

    def stream(self, name: str = "vtts analyze", fapu: Fapu | None = None) -> FapStream:
        """The estimates as a FAP stream at :attr:`fps`: the estimated FAPs rounded to integers,
        every frame setting each of them except the frames :attr:`~FrameEstimate.held`, which
        set none (MPEG-4's hold: a decoder keeps the last values, and the stream says that the
        frame was not estimated). With the model's ``fapu``, the estimated head translation
        rides along (:attr:`FapStream.translation`, in ES units; axes not estimated stay 0);
        without it, or when none was estimated, the stream has none."""
        n = len(self.frames)
        values = np.zeros((n, N_FAPS))
        mask = np.zeros((n, N_FAPS), dtype=bool)
        for i, fe in enumerate(self.frames):
            if fe.held:
                continue
            for f in self.faps:
                values[i, f - 1] = np.round(fe.params[f - 1])
                mask[i, f - 1] = True
        translation = None
        if fapu is not None and any(u in TRANSLATION for u in self.unknowns):
            translation = np.array([fe.translation for fe in self.frames]).reshape(n, 3) / fapu.es
        return FapStream(self.fps, name, values, mask, translation=translation)
