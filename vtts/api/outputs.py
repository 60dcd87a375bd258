"""What ``say`` and ``play`` write besides the frames: the speech as a temporary WAV and its AAC
track (:class:`SpeechTrack`), the animation as glTF (:func:`write_gltf_file`), the web player
(:func:`write_web_folder`) and another engine's curves (:func:`write_curves_file`), each with the
camera, size and layout the video would have."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import numpy as np

from vtts.api.options import View


@contextlib.contextmanager
def speech_wav(speech: tuple[np.ndarray, int] | None) -> Iterator[Path | None]:
    """``speech`` (``(n,)`` int16 samples, rate in Hz) as a temporary WAV, what the MP4 muxer
    and the web player encode as AAC; None for no speech."""
    if speech is None:
        yield None
        return
    import tempfile

    from vtts.render import write_wav

    with tempfile.TemporaryDirectory(prefix="vtts-speech-") as tmp:
        wav = Path(tmp) / "speech.wav"
        write_wav(wav, *speech)
        yield wav


class SpeechTrack:
    """The speech (``(n,)`` int16 samples, rate in Hz) as a temporary WAV (:func:`speech_wav`)
    and the MP4's AAC track encoded from it in the background (:class:`vtts.render.AacTrack`);
    :meth:`close` stops the encoding and removes both."""

    def __init__(self, speech: tuple[np.ndarray, int]) -> None:
        from vtts.render import AacTrack

        self._files = contextlib.ExitStack()
        with self._files:  # undone at once if anything fails here, kept otherwise
            self.wav = self._files.enter_context(speech_wav(speech))
            self.aac = self._files.enter_context(AacTrack(self.wav, self.wav.parent))
            self._files = self._files.pop_all()

    def close(self) -> None:
        self._files.close()

    def __enter__(self) -> SpeechTrack:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def after_first(frames: Iterable, on_first: Callable[[], None] | None) -> Iterator:
    """``frames``, calling ``on_first`` once the first one is out (it compiled the shaders and
    uploaded the meshes: the end of a command's start-up)."""
    first = on_first is not None
    for frame in frames:
        yield frame
        if first:
            first = False
            on_first()


def write_curves_file(
    path: str, curves: str, fps: float, stream=None, params=None, phones=None, words=None
) -> None:
    """Another engine's curves (:mod:`vtts.avatar.curves`) of say (``params``: the first
    model's timeline, ``(n_frames, N_PARAMS)``; the phones and the words) or play (``stream``
    itself, every FAP, viseme and expression it sets; no words)."""
    from vtts.animate.fapstream import stream_params
    from vtts.avatar.curves import write_curves
    from vtts.face.miap import all_miaps

    if params is None:
        params = stream_params(stream, all_miaps(), fps=fps).params
    write_curves(path, curves, params, fps, phones, words)


def write_gltf_file(path: str, view: View, models, params, fps: float, roots=None) -> None:
    """The animation as glTF (:func:`vtts.export.write_gltf`): ``params``, one
    ``(n_frames, N_PARAMS)`` array per model, at ``fps`` Hz."""
    from vtts.export import write_gltf

    write_gltf(
        path,
        models,
        params,
        fps,
        roots=roots,
        camera=view.pinhole(),
        viewpoint=view.viewpoint,
        size=view.frame_size(),
        layout=view.layout,
    )


def write_web_folder(
    folder: str, view: View, models, params, fps: float, *, audio=None, roots=None
) -> None:
    """The web player (:func:`vtts.export.web.write_web`) with the view's background too."""
    from vtts.export.web import write_web
    from vtts.render.color import parse_background

    write_web(
        folder,
        models,
        params,
        fps,
        audio=audio,
        roots=roots,
        camera=view.pinhole(),
        viewpoint=view.viewpoint,
        size=view.frame_size(),
        layout=view.layout,
        # a talking photo is drawn in the video; the web player draws the head in 3-D
        background=(
            parse_background(view.background)
            if view.background and not view.talking_photo()
            else None
        ),
    )
