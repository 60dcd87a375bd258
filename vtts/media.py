"""The external media tool every layer shares: the ffmpeg binary.

Low level on purpose: reading sound files (:mod:`vtts.speech.audio`), writing video
(:mod:`vtts.render.output`) and the web player's audio (:mod:`vtts.export.web`) all run the same
ffmpeg, and none of them should import another's package to find it.
"""

from __future__ import annotations

from vtts.errors import RenderError


def ffmpeg_exe() -> str:
    """Path of the ffmpeg binary shipped in the ``imageio-ffmpeg`` wheel.

    ``imageio_ffmpeg`` honours the ``IMAGEIO_FFMPEG_EXE`` environment variable, so a system
    ffmpeg can be substituted without code changes.
    """
    import imageio_ffmpeg

    try:
        return imageio_ffmpeg.get_ffmpeg_exe()
    except RuntimeError as exc:  # no binary for this platform and none on PATH
        raise RenderError(f"no ffmpeg binary found: {exc}") from exc
