"""Who is where in a photo: MediaPipe's selfie segmentation (the person against the
background), the first step of the hair, ears and neck of a fitted head.

The model (``selfie_segmentation.tflite``, Apache-2.0, shipped in ``vtts/data/landmarks/``)
takes a ``256 × 256`` RGB picture in [0, 1] and gives each pixel the probability that it shows
the person — hair, face, body and clothes alike. The photo is letterboxed (centred, black
borders) into a square so that the person keeps its proportions, and the probabilities are
sampled back onto the photo's pixels. What is hair and what is skin within the person comes
from the face's landmarks and colours (:mod:`vtts.fit.hair`).
"""

from __future__ import annotations

import threading

import numpy as np
from PIL import Image

from vtts.fit.landmarks import check_image, without_litert_banner
from vtts.resources import package_data

#: The model's input side (pixels).
INPUT = 256
#: The probability from which a pixel counts as the person.
PERSON = 0.5


class SelfieSegmenter:
    """MediaPipe's selfie segmentation on LiteRT: ``segmenter(image) -> (H, W) float32`` the
    probability (0–1) that each pixel of ``image (H, W, 3) uint8`` shows the person. Built once
    and reused; not thread-safe (make one per thread)."""

    def __init__(self, threads: int = 2) -> None:
        from ai_edge_litert.interpreter import Interpreter

        with without_litert_banner():
            self._net = Interpreter(
                model_path=str(package_data("landmarks/selfie_segmentation.tflite")),
                num_threads=threads,
            )
            self._net.allocate_tensors()
        self._in = self._net.get_input_details()[0]["index"]
        self._out = self._net.get_output_details()[0]["index"]

    def __call__(self, image: np.ndarray) -> np.ndarray:
        image = check_image(image)
        h, w = image.shape[:2]
        side = max(h, w)
        scale = INPUT / side
        inner = (max(round(w * scale), 1), max(round(h * scale), 1))
        x0, y0 = (INPUT - inner[0]) // 2, (INPUT - inner[1]) // 2
        square = Image.new("RGB", (INPUT, INPUT))
        square.paste(Image.fromarray(image).resize(inner, Image.Resampling.BILINEAR), (x0, y0))
        x = (np.asarray(square, np.float32) / 255.0)[None]
        self._net.set_tensor(self._in, x)
        self._net.invoke()
        prob = self._net.get_tensor(self._out)[0, :, :, 0]
        crop = prob[y0 : y0 + inner[1], x0 : x0 + inner[0]]
        back = Image.fromarray(crop.astype(np.float32), mode="F").resize(
            (w, h), Image.Resampling.BILINEAR
        )
        return np.clip(np.asarray(back, np.float32), 0.0, 1.0)


_default: SelfieSegmenter | None = None
_default_lock = threading.Lock()


def person_probability(image: np.ndarray) -> np.ndarray:
    """``(H, W) float32``: the probability that each pixel of ``image (H, W, 3) uint8`` shows the
    person (a shared :class:`SelfieSegmenter`, built on first use; one thread at a time uses it,
    as fitting and talking photos may run in several threads of one process)."""
    global _default
    with _default_lock:
        if _default is None:
            _default = SelfieSegmenter()
        return _default(image)
