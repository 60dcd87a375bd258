"""Rendering: models to pixels with pyrender on Mesa's EGL, and the writers for PNG, MP4 and WAV.

- :class:`FaceRenderer` — one or more personalized models in one scene, posed per frame;
- :class:`Camera` — the pinhole camera of Eisert–Girod Equation 3, a VRML ``Viewpoint``
  (:func:`find_viewpoint`, :func:`viewpoint_fields`), or automatic framing;
- :func:`parse_color`, :func:`parse_background` — background colors as the commands write them;
- :class:`VideoWriter`, :class:`PngSequenceWriter`, :func:`write_png`, :func:`write_wav` — outputs
  written to a temporary name and renamed when complete; :class:`AacTrack` — a video's sound
  encoded in the background beforehand;
- :func:`probe_media` — frame count and durations of an MP4; :func:`progress` — a progress bar;
- :func:`warm_up` — the process's OpenGL context and drawing pass made before the first frame.
"""

from vtts.render.camera import (
    Camera,
    find_viewpoint,
    frame_bounds,
    look_at,
    viewpoint_fields,
    viewpoints,
)
from vtts.render.color import parse_background, parse_color
from vtts.render.output import (
    AacTrack,
    MediaInfo,
    PngSequenceWriter,
    VideoWriter,
    probe_media,
    progress,
    write_png,
    write_wav,
)
from vtts.render.renderer import DETAIL_PX, FaceRenderer, warm_up

__all__ = [
    "AacTrack",
    "Camera",
    "DETAIL_PX",
    "FaceRenderer",
    "MediaInfo",
    "PngSequenceWriter",
    "VideoWriter",
    "find_viewpoint",
    "frame_bounds",
    "look_at",
    "parse_background",
    "parse_color",
    "probe_media",
    "progress",
    "viewpoint_fields",
    "viewpoints",
    "warm_up",
    "write_png",
    "write_wav",
]
