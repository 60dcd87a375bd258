"""``vtts play``: a FAP stream played on one or more models into an MP4, PNGs, glTF, a web
player and/or another engine's curves (:func:`play`); a stream from stdin rendered frame by frame
as it arrives (``stream="-"``)."""

from __future__ import annotations

import contextlib
import itertools
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np

from vtts.api.options import (
    Curves,
    Heads,
    View,
    check_number,
    check_seed,
    check_web,
    video_or_gltf,
)
from vtts.errors import RenderError

#: The frame rate ``vtts play`` renders a file at unless ``fps`` says otherwise.
DEFAULT_PLAY_FPS = 30.0
#: The rate of a voice on stdin (``--audio -``) unless ``rate`` says otherwise, Hz.
VOICE_RATE = 16000
#: A voice on stdin is read in chunks of this long at most, s (each is recognized at once).
VOICE_CHUNK_S = 0.02


@dataclass(kw_only=True)
class PlayOptions(Heads, Curves, View):
    """What ``vtts play`` plays and writes.

    ``stream``: a ``.fap`` file or a coded ``.fbs`` (``-``: a ``.fbs`` streamed on stdin);
    ``output``: an ``.mp4`` (or ``.m4v``, ``.mov``, ``.mkv``) or an animated ``.glb``/``.gltf``
    (with ``stream="-"``, ``-``: raw rgb24 frames on stdout); ``png_dir``: a folder of PNG
    frames; ``web``: a web player's folder; ``audio``: sound muxed into the MP4 and the web
    player (WAV, FLAC, OGG, MP3, M4A …); ``fps``: the output frame rate in Hz (None: 30, and a
    stream from stdin plays at its own); ``progress``: a progress bar on stderr. The heads, the
    view and the curves: :mod:`vtts.api.options`.

    ``audio="-"`` with no ``stream`` (None): a voice on stdin instead, raw PCM, signed 16-bit
    little-endian mono at ``rate`` Hz (default :data:`VOICE_RATE`), which the face follows as it
    arrives (:func:`play_voice`), with the models' autonomous behaviour (``seed``, 0 to
    2**63 - 1; ``no_autonomous``: none).
    """

    stream: str | None = None
    output: str | None = None
    png_dir: str | None = None
    web: str | None = None
    audio: str | None = None
    fps: float | None = None
    rate: int | None = None
    seed: int = 0
    no_autonomous: bool = False
    progress: bool = False
    #: ``output`` when it is a video (or ``-``), and when it is a glTF
    video_file: str | None = field(init=False, default=None)
    gltf_file: str | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        Heads.__post_init__(self)
        if self.output != "-":
            self.video_file, self.gltf_file = video_or_gltf(self.output)
        else:
            self.video_file, self.gltf_file = "-", None
        if self.audio == "-" or self.rate is not None:
            self._check_voice()
        elif self.stream is None:
            raise RenderError(
                "give the stream to play (a .fap or .fbs file, or - for stdin), or --audio - "
                "for a voice on stdin"
            )
        elif self.stream == "-":
            self._check_live()
        else:
            self._check_file()
        self.require_model()

    def _check_voice(self) -> None:
        """The rules of a voice on stdin (``--audio -``)."""
        if self.audio != "-":
            raise RenderError("--rate is the rate of a voice on stdin: give --audio - with it")
        if self.stream is not None:
            raise RenderError(
                f"--audio - plays a voice from stdin, not a FAP stream: give no stream "
                f"({self.stream!r})"
            )
        rate = VOICE_RATE if self.rate is None else self.rate
        if isinstance(rate, bool) or not isinstance(rate, int) or not 8000 <= rate <= 192000:
            raise RenderError(
                f"--rate must be a whole number of Hz within 8000–192000, got {rate!r}"
            )
        self._check_live(voice=True)
        check_seed(self.seed)
        check_number(DEFAULT_PLAY_FPS if self.fps is None else self.fps, "--fps", 0, 240)

    def _check_file(self) -> None:
        """The rules of a stream file."""
        if self.output == "-":
            raise RenderError(
                "-o - (raw frames on stdout) plays a stream from stdin: vtts play - …"
            )
        if not (self.output or self.png_dir or self.web or self.curves_out):
            raise RenderError(
                "nothing to write: give -o OUT.mp4 (or OUT.glb), --png-dir DIR, --web DIR and/or "
                "--curves-out FILE"
            )
        check_number(DEFAULT_PLAY_FPS if self.fps is None else self.fps, "--fps", 0, 240)
        self.check_view(video=bool(self.video_file))
        check_web(self.web)
        self.check_curves()

    def _check_live(self, voice: bool = False) -> None:
        """The rules of a stream from stdin (``voice``: a voice, ``--audio -``): frames as they
        arrive, to a video, stdout or PNGs."""
        what = "a voice from stdin (vtts play --audio -)" if voice else "a stream from stdin "
        unsupported = [
            flag
            for flag, value in (
                ("--audio", self.audio if not voice else None),
                ("--web", self.web),
                ("--gltf", self.gltf_file),
                ("--curves-out", self.curves_out),
            )
            if value
        ]
        if unsupported:
            raise RenderError(
                f"{', '.join(unsupported)} need the whole stream: {what}"
                f"{'(vtts play -) ' if not voice else ' '}renders to -o OUT.mp4, -o - (raw rgb24 "
                "frames on stdout) or --png-dir"
            )
        if not (self.video_file or self.png_dir):
            raise RenderError(
                "nothing to write: give -o OUT.mp4, -o - (raw rgb24 frames on stdout) or --png-dir"
            )
        self.check_view(video=bool(self.video_file))  # rgb24 frames have no alpha either


@dataclass(frozen=True)
class Played:
    """What :func:`play` wrote: ``written``, the outputs in the order the command names them
    (``"stdout"`` for raw frames); ``n_frames`` at ``fps`` Hz."""

    written: list[str]
    n_frames: int
    fps: float

    @property
    def seconds(self) -> float:
        return self.n_frames / self.fps


def play(
    options: PlayOptions,
    *,
    stdin: BinaryIO | None = None,
    stdout: BinaryIO | None = None,
    on_first_frame: Callable[[], None] | None = None,
) -> Played:
    """Play ``options.stream`` (see :class:`PlayOptions`); a stream's head translation moves
    each model by that many of its own ES units. ``stdin`` and ``stdout``: where a stream from
    stdin and raw frames go (None: the process's); ``on_first_frame``: called once the first
    frame is rendered."""
    from vtts.api.options import check_io, url_roots_set
    from vtts.threads import PipeReader

    check_io(options)
    with url_roots_set(options.url_root):
        if options.audio == "-":
            stdin = PipeReader(sys.stdin.buffer) if stdin is None else stdin
            stdout = sys.stdout.buffer if stdout is None else stdout
            return play_voice(options, stdin, stdout, on_first_frame)
        if options.stream == "-":
            # the process's stdin is read so that a signal ends the wait for a packet
            stdin = PipeReader(sys.stdin.buffer) if stdin is None else stdin
            stdout = sys.stdout.buffer if stdout is None else stdout
            return play_live(options, stdin, stdout, on_first_frame)
        from vtts.api.outputs import speech_wav
        from vtts.speech.audio import read_for_mp4

        # the sound of the MP4 and the web player: any format say --audio takes, as say muxes it
        speech = (
            read_for_mp4(options.audio)
            if options.audio and (options.video_file or options.web)
            else None
        )
        with speech_wav(speech) as wav:
            return play_file(options, wav, on_first_frame)


def play_live(o: PlayOptions, stdin: BinaryIO, stdout: BinaryIO, on_first_frame=None) -> Played:
    """Render a FAP stream from ``stdin`` frame by frame as it arrives, at its own rate, into an
    MP4 (renamed into place at the end of the stream), raw rgb24 frames on ``stdout`` (``-o -``,
    flushed per frame) and/or PNGs. A streamed .fbs plays as its packets arrive; a whole .fbs is
    read completely first."""
    from vtts.animate.fapstream import model_roots, warn_ignored
    from vtts.animate.live import LiveParams
    from vtts.api.outputs import after_first
    from vtts.fap.coding import StreamDecoder
    from vtts.render import PngSequenceWriter, VideoWriter, progress
    from vtts.warm import load_model

    raw = o.video_file == "-"
    decoder = StreamDecoder(stdin, file="-")  # waits for the header
    fps = decoder.header.fps
    if o.fps is not None and abs(o.fps - fps) > 1e-9 * fps:
        raise RenderError(
            f"a stream from stdin plays at its own rate, {fps:g} Hz: give no --fps "
            f"(or --fps {fps:g}), not {o.fps:g}"
        )
    # the models load once the header arrived: a fitted head is in place by then
    models = [load_model(m) for m in o.model]
    lives = [LiveParams(decoder.header.faps, m.tables.adts) for m in models]
    out = stdout if raw else None
    n = 0
    with contextlib.ExitStack() as stack:
        renderer = stack.enter_context(o.renderer(models, video=bool(o.video_file)))
        matrices = [renderer.model_matrix(j) for j in range(len(models))]
        sinks = []
        if o.video_file and not raw:
            sinks.append(stack.enter_context(VideoWriter(o.video_file, fps, renderer.size)))
        if o.png_dir:
            sinks.append(stack.enter_context(PngSequenceWriter(o.png_dir)))
        bar = stack.enter_context(progress(None, "rendering stdin", not o.progress or raw))

        moves = decoder.header.translation

        def items():
            for i, frame in enumerate(decoder):
                played = [live(frame) for live in lives]
                roots = []
                for j, (sp, m) in enumerate(zip(played, models, strict=True)):
                    if i == 0:
                        warn_ignored(m.name, sp.ignored)
                    # model_roots warns (once: at the first frame) about a model without FAPUs
                    r = model_roots(sp, matrices[j], m.fapu, m.name) if i == 0 or m.fapu else None
                    roots.append(None if r is None else r[0])
                yield [sp.params[0] for sp in played], roots

        a, b = itertools.tee(items())
        params = (p for p, _ in a)
        roots = (r for _, r in b) if moves else None
        n += _deliver(after_first(renderer.frames(params, roots, batch=1), on_first_frame),
                      out, sinks, bar)  # fmt: skip
    written = [str(p) for p in (o.video_file if not raw else "stdout", o.png_dir) if p]
    return Played(written, n, fps)


def _deliver(frames, out: BinaryIO | None, sinks: list, bar) -> int:
    """Each of ``frames`` (``(H, W, 4) uint8``) as soon as it is rendered: its RGB bytes to
    ``out`` (flushed), then to each of ``sinks``; the progress ``bar`` advanced. Returns how
    many there were."""
    n = 0
    for frame in frames:
        if out is not None:
            out.write(np.ascontiguousarray(frame[..., :3]).tobytes())
            out.flush()
        for sink in sinks:
            sink.write(frame)
        bar.advance()
        n += 1
    return n


def play_voice(o: PlayOptions, stdin: BinaryIO, stdout: BinaryIO, on_first_frame=None) -> Played:
    """Render a face that follows a voice on ``stdin`` (raw PCM, s16le mono at ``o.rate`` Hz)
    as it arrives: each chunk is recognized (:class:`~vtts.speech.recognize.LiveRecognizer`),
    the visemes become frames (:class:`~vtts.animate.voice.VoiceTrack`) rendered at once into
    an MP4 (renamed into place at the end), raw rgb24 frames on ``stdout`` (``-o -``, flushed
    per frame) and/or PNGs. The stream may end anywhere: a last odd byte (half a sample) is
    ignored with a warning."""
    import warnings

    from vtts.animate.voice import LiveHabits, VoiceTrack
    from vtts.api.outputs import after_first
    from vtts.errors import SpeechError, VttsWarning
    from vtts.render import PngSequenceWriter, VideoWriter, progress
    from vtts.speech.recognize import LiveRecognizer
    from vtts.warm import load_model

    rate = VOICE_RATE if o.rate is None else o.rate
    fps = DEFAULT_PLAY_FPS if o.fps is None else o.fps
    raw = o.video_file == "-"
    models = [load_model(m) for m in o.model]
    live = LiveRecognizer(rate)
    track = VoiceTrack(fps)
    chunk = max(int(rate * VOICE_CHUNK_S), 1) * 2

    habits = [LiveHabits(m, fps, seed=o.seed) for m in models] if not o.no_autonomous else []

    def voice_frames():
        """The voice track's frames as the voice arrives."""
        carry = b""
        total = 0
        while True:
            data = stdin.read(chunk)
            if not data:
                break
            total += len(data)
            data = carry + data
            whole = len(data) // 2 * 2
            carry = data[whole:]
            yield from track.add(live.feed(np.frombuffer(data[:whole], dtype="<i2")))
        if total < 2:
            raise SpeechError(
                "no voice came on stdin: not one sample (raw PCM, s16le mono, was expected)",
                file="-",
            )
        if carry:
            warnings.warn(
                VttsWarning(
                    "the voice on stdin ended inside a sample (an odd number of bytes): "
                    "its last byte is ignored",
                    file="-",
                ),
                stacklevel=2,
            )
        yield from track.add(live.finish())
        yield from track.finish()

    def params():
        for i, p in enumerate(voice_frames()):
            yield [p + h(i) for h in habits] if habits else [p] * len(models)

    out = stdout if raw else None
    n = 0
    with contextlib.ExitStack() as stack:
        renderer = stack.enter_context(o.renderer(models, video=bool(o.video_file)))
        sinks = []
        if o.video_file and not raw:
            sinks.append(stack.enter_context(VideoWriter(o.video_file, fps, renderer.size)))
        if o.png_dir:
            sinks.append(stack.enter_context(PngSequenceWriter(o.png_dir)))
        bar = stack.enter_context(progress(None, "following the voice on stdin",
                                           not o.progress or raw))  # fmt: skip
        n += _deliver(after_first(renderer.frames(params(), batch=1), on_first_frame), out, sinks,
                      bar)  # fmt: skip
    written = [str(p) for p in (o.video_file if not raw else "stdout", o.png_dir) if p]
    return Played(written, n, fps)


def stream_roots(o: PlayOptions, models, played) -> list | None:
    """Each model's root pose per frame as the stream's head translation moves it
    (:func:`vtts.animate.fapstream.model_roots`) where the export places it; None when none
    moves."""
    from vtts.animate.fapstream import model_roots
    from vtts.export import placement

    where = placement(
        models,
        camera=o.pinhole(),
        viewpoint=o.viewpoint,
        size=o.frame_size(),
        layout=o.layout,
    )
    roots = [
        model_roots(sp, where.matrices[j], m.fapu, m.name)
        for j, (sp, m) in enumerate(zip(played, models, strict=True))
    ]
    return roots if any(r is not None for r in roots) else None


def play_file(o: PlayOptions, audio: Path | None, on_first_frame=None) -> Played:
    """Play a stream file once the options are checked; ``audio`` is the speech as a WAV (or
    None)."""
    from vtts.animate.fapstream import model_roots, stream_params, warn_ignored
    from vtts.api.coding import read_stream
    from vtts.api.outputs import after_first, write_curves_file, write_gltf_file, write_web_folder
    from vtts.render import PngSequenceWriter, VideoWriter, progress
    from vtts.warm import load_model  # kept between the jobs of vtts batch

    fps = DEFAULT_PLAY_FPS if o.fps is None else o.fps
    stream = read_stream(o.stream)
    models = [load_model(m) for m in o.model]
    tracks, played = [], []
    for m in models:
        sp = stream_params(stream, set(m.tables.adts), fps=fps)
        warn_ignored(m.name, sp.ignored)
        tracks.append(sp.params)
        played.append(sp)
    n = tracks[0].shape[0]
    # where the stream's head translation moves the heads (the renderer finds them in the video)
    roots = stream_roots(o, models, played) if o.web or o.gltf_file else None
    if o.web:
        write_web_folder(o.web, o, models, tracks, fps, audio=audio, roots=roots)
    if o.gltf_file:
        write_gltf_file(o.gltf_file, o, models, tracks, fps, roots)
    if not o.video_file and not o.png_dir:
        if o.curves_out:
            write_curves_file(o.curves_out, o.curves, fps, stream)
        return Played([str(p) for p in (o.gltf_file, o.web, o.curves_out) if p], n, fps)
    with contextlib.ExitStack() as stack:
        renderer = stack.enter_context(o.renderer(models, video=bool(o.video_file)))
        roots = [
            model_roots(sp, renderer.model_matrix(j), m.fapu, m.name)
            for j, (sp, m) in enumerate(zip(played, models, strict=True))
        ]
        moving = None
        if any(r is not None for r in roots):
            moving = ([None if r is None else r[i] for r in roots] for i in range(n))
        sinks = []
        if o.video_file:
            video = VideoWriter(o.video_file, fps, renderer.size, audio=audio)
            sinks.append(stack.enter_context(video))
        if o.png_dir:
            sinks.append(stack.enter_context(PngSequenceWriter(o.png_dir)))
        bar = stack.enter_context(progress(n, f"rendering {Path(o.stream).name}", not o.progress))
        frames = renderer.frames(([t[i] for t in tracks] for i in range(n)), moving)
        for frame in after_first(frames, on_first_frame):
            for sink in sinks:
                sink.write(frame)
            bar.advance()
    if o.curves_out:
        write_curves_file(o.curves_out, o.curves, fps, stream)
    written = (o.video_file, o.gltf_file, o.png_dir, o.web, o.curves_out)
    return Played([str(p) for p in written if p], n, fps)
