"""Rendering: models to pixels with pyrender on Mesa's EGL, and the writers for PNG, MP4 and WAV.

- :class:`FaceRenderer` — one or more personalized models in one scene, posed per frame;
- :class:`Camera` — the pinhole camera of Eisert–Girod Equation 3, or automatic framing;
- :class:`VideoWriter`, :class:`PngSequenceWriter`, :func:`write_png`, :func:`write_wav` — outputs
  written to a temporary name and renamed when complete;
- :func:`probe_media` — frame count and durations of an MP4; :func:`progress` — a progress bar.
"""

from vtts.render.camera import Camera, frame_bounds, look_at
from vtts.render.output import (
    MediaInfo,
    PngSequenceWriter,
    VideoWriter,
    probe_media,
    progress,
    write_png,
    write_wav,
)
from vtts.render.renderer import FaceRenderer, vertex_normals

__all__ = [
    "Camera",
    "FaceRenderer",
    "MediaInfo",
    "PngSequenceWriter",
    "VideoWriter",
    "frame_bounds",
    "look_at",
    "probe_media",
    "progress",
    "vertex_normals",
    "write_png",
    "write_wav",
]
