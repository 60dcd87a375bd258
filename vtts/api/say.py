"""``vtts say``: bookmarked text spoken by one or more models into an MP4, PNGs, glTF, a web
player, the FAP stream, the speech, its timings and/or another engine's curves (:func:`say`)."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from vtts.api.options import (
    Curves,
    Heads,
    View,
    check_choice,
    check_number,
    check_seed,
    check_web,
    video_or_gltf,
)
from vtts.errors import RenderError, VttsError
from vtts.messages import echo
from vtts.speech.engine import DEFAULT_ENGINE
from vtts.speech.engine import ENGINES as SPEECH_ENGINES

if TYPE_CHECKING:
    from concurrent.futures import Future

#: The speech synthesizers (:mod:`vtts.speech.engine`): espeak-ng, festival's HTS voice, Piper.
ENGINES = tuple(SPEECH_ENGINES)


def merged_text(text: str, text_option: str | None, file: str | None) -> str:
    """The text given as ``vtts say TEXT`` or as ``--text TEXT`` (once: not with the other,
    nor with ``--file``)."""
    if text_option is None:
        return text
    if text or file:
        given = "the text twice" if text else "--text and --file"
        raise RenderError(f"give the text once: got {given}")
    return text_option


@dataclass(kw_only=True)
class SayOptions(Heads, Curves, View):
    """What ``vtts say`` speaks and writes.

    ``text``: text with bookmarks (``"Hello <smile 2s> world <blink>"``); ``file``: read the
    text from this UTF-8 file instead; ``engine``: ``espeak``, ``festival`` or ``piper`` (the
    extra ``vtts[piper]``); ``voice``: its voice (None: the engine's default, ``vtts voices``);
    ``rate``: words per minute; ``pitch``: 0–99; ``phonemes``: timings from another engine
    (Polly speech marks or a ``start end phoneme`` table; with ``audio``); ``audio``: recorded
    speech of the text, which it is aligned to (without a text, its phones are recognized from
    the sound: :mod:`vtts.speech.recognize`); ``words``: then, where words are recognized too
    (``auto``: where the phones are uncertain, ``always``, ``never``;
    :data:`~vtts.speech.recognize.WORD_MODES`); ``seed``: of the autonomous behaviour (blinks,
    nods, head motion, gaze), 0 to 2**63 - 1; ``no_autonomous``: none of it; ``fps``: frame
    rate in Hz, within 0–240.

    Outputs: ``output`` (an ``.mp4``, ``.m4v``, ``.mov``, ``.mkv`` or an animated
    ``.glb``/``.gltf``), ``png_dir`` (PNG frames), ``web`` (a web player's folder), ``fap_out``
    (the first model's FAP stream, ``.fap``), ``wav_out`` (the speech), ``timings_out`` (word
    and phone timings, ``.tsv``), ``curves_out`` (:class:`~vtts.api.options.Curves`); at least
    one. ``progress``: a progress bar on stderr. The heads and the view:
    :mod:`vtts.api.options`.
    """

    text: str = ""
    file: str | None = None
    engine: str = DEFAULT_ENGINE
    voice: str | None = None
    rate: int | None = None
    pitch: int | None = None
    phonemes: str | None = None
    audio: str | None = None
    words: str = "auto"
    seed: int = 0
    no_autonomous: bool = False
    fps: float = 30.0
    output: str | None = None
    png_dir: str | None = None
    web: str | None = None
    fap_out: str | None = None
    wav_out: str | None = None
    timings_out: str | None = None
    progress: bool = False
    #: ``output`` when it is a video, and when it is a glTF
    video_file: str | None = field(init=False, default=None)
    gltf_file: str | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        Heads.__post_init__(self)
        self.video_file, self.gltf_file = video_or_gltf(self.output)
        written = (self.output, self.png_dir, self.web, self.fap_out, self.wav_out)
        if not any(written) and not self.curves_out and not self.timings_out:
            raise RenderError(
                "nothing to write: give -o OUT.mp4 (or OUT.glb), --png-dir, --web, --fap-out, "
                "--wav-out, --timings-out or --curves-out"
            )
        check_number(self.fps, "--fps", 0, 240)
        self.check_view(video=bool(self.video_file))
        check_web(self.web)
        self.check_curves()
        check_choice(self.engine, "--engine", ENGINES)
        if self.words != "auto":  # the default needs no look at the recognizer
            from vtts.speech.recognize import WORD_MODES

            check_choice(self.words, "--words", WORD_MODES)
        check_seed(self.seed)
        for name, value in (("--rate", self.rate), ("--pitch", self.pitch)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, int)):
                raise RenderError(f"{name} must be a whole number, got {value!r}")
        self.require_model()


@dataclass(frozen=True)
class Said:
    """What :func:`say` wrote: ``written``, the outputs in the order the command names them;
    the speech's ``duration`` in seconds, ``n_frames`` at ``fps`` Hz; ``audio``, the speech,
    ``(n,)`` int16 samples at ``rate`` Hz."""

    written: list[str]
    duration: float
    n_frames: int
    fps: float
    audio: np.ndarray
    rate: int


def say(options: SayOptions, *, on_first_frame: Callable[[], None] | None = None) -> Said:
    """Speak ``options.text`` (see :class:`SayOptions`). ``on_first_frame``: called once the
    first frame is rendered. Raises a :class:`~vtts.errors.BookmarkError` locating a bad
    bookmark in the text (in ``file`` when the text came from it)."""
    from vtts.api.options import check_io, url_roots_set
    from vtts.errors import BookmarkError
    from vtts.limits import MAX_TEXT_BYTES, read_bytes_capped
    from vtts.warm import load_model  # kept between the jobs of vtts batch

    o = options
    check_io(o)
    text = o.text
    if o.file:
        try:
            text = read_bytes_capped(o.file, MAX_TEXT_BYTES, what="text").decode("utf-8")
        except (OSError, UnicodeDecodeError) as e:
            reason = getattr(e, "strerror", None) or "not UTF-8 text"
            raise VttsError(f"cannot read the text: {reason}", file=o.file) from None
    if (not text or not text.strip()) and (o.audio is None or o.phonemes is not None):
        # (a recording alone is enough: its phones are recognized from the sound)
        raise RenderError("nothing to say: give the text, or --file FILE (or --audio REC)")
    with url_roots_set(o.url_root):
        models = [load_model(m) for m in o.model]
        known = {x.name for m in models for x in m.tables.adts if x.kind == "expression"}
        try:
            utt, timelines, renderer, track = speak_and_set_up(o, text, models, known)
        except BookmarkError as e:
            if o.file and e.file is None:
                e.file = o.file  # the text's place is in that file
            raise
        with track if track is not None else contextlib.nullcontext():
            return write_said(o, models, utt, timelines, renderer, track, on_first_frame)


def speak_and_set_up(o: SayOptions, text: str, models: list, known: set[str]):
    """The utterance of ``text``, each model's timeline, the renderer (None without video or
    PNG output) and the speech's AAC track for the MP4 (a
    :class:`~vtts.api.outputs.SpeechTrack`, None without a video; the caller closes it):
    espeak-ng speaks (in a process of its own), then its sound is encoded (by ffmpeg, in
    another) and the timelines are built in a worker thread while the renderer is set up."""
    from concurrent.futures import ThreadPoolExecutor

    from vtts.animate.timeline import build_timeline, speech_bilabials, speech_lead
    from vtts.api.outputs import SpeechTrack
    from vtts.threads import result
    from vtts.utterance import prepare_utterance

    def speak():
        with recognition_bar(o.progress) as tick:
            utt = prepare_utterance(
                text,
                known=known,
                engine=o.engine,
                voice=o.voice,
                rate=o.rate,
                pitch=o.pitch,
                phonemes=o.phonemes,
                audio=o.audio,
                words=o.words,
                progress=tick,
            )
        # the MP4's sound is encoded now, on a core the renderer's set-up leaves idle
        track = SpeechTrack((utt.audio, utt.rate)) if o.video_file else None
        try:
            timelines = [
                build_timeline(
                    m,
                    utt.phones,
                    utt.bookmarks,
                    utt.duration,
                    fps=o.fps,
                    seed=o.seed,
                    autonomous=not o.no_autonomous,
                    lead=speech_lead(o.engine),
                    bilabials=speech_bilabials(o.engine),
                )
                for m in models
            ]
        except BaseException:
            if track is not None:
                track.close()
            raise
        return utt, timelines, track

    pool = ThreadPoolExecutor(max_workers=1)
    speaking = pool.submit(speak)
    try:
        renderer = None
        try:
            if o.video_file or o.png_dir:
                renderer = o.renderer(models, video=bool(o.video_file))
        except Exception as e:
            try:
                _, _, track = result(speaking)
            except Exception:
                if isinstance(e, VttsError):
                    raise  # a problem with the text is reported first, as it comes first
            else:
                if track is not None:
                    track.close()
            raise
        utt, timelines, track = result(speaking)
    except BaseException:
        # interrupted (Ctrl-C, SIGTERM) or failed: the speech is not waited for, as it may never
        # come (--audio a named pipe nobody writes); a track it makes later is closed then
        speaking.add_done_callback(_close_track)
        raise
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
    return utt, timelines, renderer, track


@contextlib.contextmanager
def recognition_bar(show: bool):
    """A callback ``tick(done_s, total_s)`` that draws a progress bar of the seconds of audio
    recognized (:func:`vtts.utterance.recognized`), made at its first call; none unless
    ``show``."""
    import math

    from vtts.render import progress

    with contextlib.ExitStack() as stack:
        bars = []

        def tick(done: float, total: float) -> None:
            if not bars:
                seconds = max(int(math.ceil(total)), 1)
                bars.append(stack.enter_context(progress(seconds, "recognizing speech", not show)))
            bar = bars[0]
            bar.advance(max(int(done) - bar.completed, 0))

        yield tick


def _close_track(speaking: Future) -> None:
    """Close the AAC track of a speech nobody waits for any more (see
    :func:`speak_and_set_up`)."""
    if not speaking.cancelled() and speaking.exception() is None:
        track = speaking.result()[2]
        if track is not None:
            track.close()


def write_said(o: SayOptions, models, utt, timelines, renderer, track, on_first_frame) -> Said:
    """The work of :func:`say` once the speech, its timelines and the renderer are ready;
    ``track``: the speech's WAV and AAC track for the MP4 (None without a video)."""
    from vtts.animate.timeline import timeline_stream
    from vtts.api.outputs import (
        after_first,
        speech_wav,
        write_curves_file,
        write_gltf_file,
        write_web_folder,
    )
    from vtts.fap import write_fap
    from vtts.render import PngSequenceWriter, VideoWriter, progress, write_wav
    from vtts.utterance import write_utterance_timings

    for m in models:
        shown = {x.name for x in m.tables.adts if x.kind == "expression"}
        lacking = sorted({b.written for b in utt.text.check_names(shown)})
        if lacking:
            echo(
                f"warning: {m.name} has no table for <{'>, <'.join(lacking)}>; not shown",
                file=sys.stderr,
            )
    n = timelines[0].n_frames
    if o.video_file or o.png_dir:
        with contextlib.ExitStack() as stack:
            renderer = stack.enter_context(renderer)
            sinks = []
            if o.video_file:
                video = VideoWriter(o.video_file, o.fps, renderer.size, audio=track.aac)
                sinks.append(stack.enter_context(video))
            if o.png_dir:
                sinks.append(stack.enter_context(PngSequenceWriter(o.png_dir)))
            bar = stack.enter_context(progress(n, "speaking", not o.progress))
            frames = ([tl.params[i] for tl in timelines] for i in range(n))
            for frame in after_first(renderer.frames(frames), on_first_frame):
                for sink in sinks:
                    sink.write(frame)
                bar.advance()
    params = [tl.params for tl in timelines]
    if o.gltf_file:  # a glTF has no sound: wav_out writes the speech beside it
        write_gltf_file(o.gltf_file, o, models, params, o.fps)
    if o.web:
        with speech_wav((utt.audio, utt.rate)) as wav:
            write_web_folder(o.web, o, models, params, o.fps, audio=wav)
    # the stream and the speech last: a say that fails on the way leaves them as they were
    if o.fap_out:
        write_fap(timeline_stream(timelines[0], models[0].name), o.fap_out)
    if o.wav_out:
        write_wav(o.wav_out, utt.audio, utt.rate)
    if o.timings_out:
        write_utterance_timings(o.timings_out, utt)
    if o.curves_out:
        write_curves_file(o.curves_out, o.curves, o.fps, params=timelines[0].params,
                          phones=utt.phones, words=utt.words)  # fmt: skip
    written = (o.video_file, o.gltf_file, o.png_dir, o.web, o.fap_out, o.wav_out, o.timings_out,
               o.curves_out)  # fmt: skip
    return Said([str(p) for p in written if p], utt.duration, n, o.fps, utt.audio, utt.rate)
