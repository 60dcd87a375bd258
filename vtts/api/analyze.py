"""``vtts analyze``: FAPs and head motion estimated from a video of a face by analysis by
synthesis (Eisert & Girod) into a ``.fap`` file or a coded ``.fbs`` (:func:`analyze`); with
``model="auto"`` the head is fitted to the video first, and its texture made from what the
tracked frames show.

Everything that can be wrong with the options fails when they are made, before minutes of
estimation; the outputs are written to temporary names and renamed into place only when
everything succeeded, the fitted head's files from a hidden folder beside them.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from vtts.errors import AnalysisError

#: The texture of a fitted head: what most tracked frames show (``mean``: a robust average), or
#: its anchor frame.
TEXTURES = ("mean", "anchor")
#: The base steps of a coded ``.fbs``: measured on the face, or MPEG-4's.
STEPS = ("face", "mpeg4")
#: The coder's quantizer of ``vtts analyze``'s coded output (the steps are the base steps times
#: this): the paper's rate at 12.5 Hz (docs/analysis.md, "Measuring on people").
QUANTIZER = 4.0


def fitted_paths(out: Path) -> list[Path]:
    """The files of the head ``model="auto"`` fits, beside ``OUT``: ``OUT-model.wrl``,
    ``OUT-model.adt``, ``OUT-model-face.png`` (the atlas) and ``OUT-model-frame.png`` (the
    first frame, the texture of what it shows)."""
    return fitted_model_paths(out.with_name(f"{out.stem}-model.wrl"))


def fitted_model_paths(wrl: Path) -> list[Path]:
    """The files of a fitted head written as ``wrl`` (``model_out``): ``HEAD.wrl``,
    ``HEAD.adt``, ``HEAD-face.png``, ``HEAD-frame.png``."""
    return [wrl, wrl.with_suffix(".adt"), wrl.with_name(f"{wrl.stem}-face.png"),
            wrl.with_name(f"{wrl.stem}-frame.png")]  # fmt: skip


def check_writable(path: Path) -> None:
    """Fail now, with a clear message, when ``path`` could not be created later (a file where a
    folder must be, a folder without write permission)."""
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise AnalysisError(f"cannot write here: {folder} is a file, not a folder", file=str(path))
    if not os.access(folder, os.W_OK | os.X_OK):
        raise AnalysisError(
            f"cannot write here: no permission to write in {folder}", file=str(path)
        )
    if path.is_dir():
        raise AnalysisError("cannot write here: it is a folder", file=str(path))


def check_frames_folder(video: Path, outputs: list[Path]) -> None:
    """Refuse a PNG output written straight into ``video`` when it is a folder of frames: every
    PNG there is read as a frame, so the next analysis of the folder would meet a texture or a
    plot of another size among its frames. Other outputs (the ``.fap``, the head's ``.wrl``, a
    report in a subfolder) leave the frames as they are and may go there."""
    if not video.is_dir():
        return
    from vtts.analysis.video import PNG_SUFFIX

    folder = video.resolve()
    for out in outputs:
        if out.suffix.lower() == PNG_SUFFIX and out.parent.resolve() == folder:
            raise AnalysisError(
                f"this PNG would be written among the frames of {video}, where every PNG is "
                "read as a frame: the next analysis of the folder would fail on it; write the "
                "outputs outside it (-o, --model-out, --report)",
                file=str(out),
            )


def stream_name(video: str) -> str:
    """The name in the header of the estimated stream: the video's name as one word."""
    if video == "-":
        return "stdin"
    return re.sub(r"\s+", "_", Path(video).stem.strip()).lstrip("#") or "vtts_analyze"


@dataclass(kw_only=True)
class AnalyzeOptions:
    """What ``vtts analyze`` estimates and writes.

    ``video``: a video file, a folder of PNGs, or ``-`` for raw rgb24 frames on stdin (of
    ``size``, ``"WxH"``); ``model``: ``auto`` (or None: fit a head to the video's most typical
    face) or a bundled model name or ``.wrl`` path placed on the first face's landmarks;
    ``output``: the ``.fap`` (or coded ``.fbs``) written; ``stream_out``: write a streamed
    ``.fbs`` to stdout instead, each frame as estimated; ``model_out``: where ``auto`` writes
    the fitted head (default ``OUT-model.wrl``; needed with ``stream_out``; refused with a
    given model: nothing is fitted); ``face``: which face to track, 1 = the largest; ``rate``:
    the coded ``.fbs``'s frame rate in Hz (0–1000; None: the analysis rate); ``steps``:
    ``face`` or ``mpeg4`` base steps; ``quantizer``: the coder's global factor of the steps
    (:data:`QUANTIZER`); ``faps``: what to estimate
    (:func:`vtts.analysis.unknowns.parse_unknowns`; None: paper17); ``camera``:
    ``"FX,FY,X0,Y0"`` in pixels (with a given model); ``step``: analyze every N-th frame;
    ``at_rate``: analyze the frames the coded stream at ``rate`` shows instead (the frame nearest
    each 1 / ``rate`` s, :mod:`vtts.analysis.frame_times`);
    ``track``: the fast tracking mode (False: accurate; None: tracking for stdin only);
    ``fps``: frame rate of a PNG folder or stdin (0–1000; None: 25, or the video's own);
    ``texture``: ``mean`` or ``anchor``; ``report``: a folder for frames.csv, psnr.png,
    faps.png and side-by-side.mp4; ``fbs``: also write the coded bitstream beside ``output``;
    ``url_root``: more folders the model's urls may name; ``progress``: a progress bar on
    stderr.
    """

    video: str
    model: list[str] | None = None
    output: str | None = None
    stream_out: bool = False
    model_out: str | None = None
    size: str | None = None
    face: int | None = None
    rate: float | None = None
    steps: str = "face"
    quantizer: float = QUANTIZER
    faps: str | None = None
    camera: str | None = None
    step: int = 1
    at_rate: bool = False
    track: bool | None = None
    fps: float | None = None
    texture: str | None = None
    report: str | None = None
    fbs: bool = False
    url_root: list[str] | None = None
    progress: bool = False
    # what the options come to, worked out once when they are checked
    auto: bool = field(init=False, default=True, repr=False)
    pipe: bool = field(init=False, default=False, repr=False)
    unknowns: Any = field(init=False, default=None, repr=False)
    pinhole: Any = field(init=False, default=None, repr=False)
    frame_size: tuple[int, int] | None = field(init=False, default=None, repr=False)
    out: Path = field(init=False, default=Path(), repr=False)
    extra_fbs: Path | None = field(init=False, default=None, repr=False)
    fitted: list[Path] = field(init=False, default_factory=list, repr=False)

    def __post_init__(self) -> None:
        from vtts.analysis.unknowns import parse_unknowns
        from vtts.api.options import as_list, check_choice, parse_size
        from vtts.render import Camera

        self.model = as_list(self.model) or None
        self.url_root = as_list(self.url_root) or None
        models = self.model or ["auto"]
        if len(models) != 1:
            raise AnalysisError(f"vtts analyze fits one model, got {len(models)} --model flags")
        self.auto = models[0] == "auto"
        if self.auto and self.camera:
            raise AnalysisError("--camera is for a given --model: a fitted head brings its camera")
        if self.face is not None and self.face < 1:
            raise AnalysisError(f"--face must be 1 (the largest) or more, got {self.face}")
        if self.rate is not None and not 0 < self.rate <= 1000:
            raise AnalysisError(f"--rate must be within 0–1000 Hz, got {self.rate:g}")
        if self.step < 1:
            raise AnalysisError(f"--step must be a whole number ≥ 1, got {self.step}")
        if self.at_rate and (self.rate is None or self.step != 1):
            raise AnalysisError("--at-rate analyzes the frames of --rate: give --rate, "
                                "and no --step")  # fmt: skip
        if self.fps is not None and not 0 < self.fps <= 1000:
            raise AnalysisError(f"--fps must be within 0–1000, got {self.fps:g}")
        check_choice(self.steps, "--steps", STEPS, AnalysisError)
        if not (isinstance(self.quantizer, int | float) and 0 < self.quantizer <= 1000):
            raise AnalysisError(f"--quantizer must be a number within 0–1000, got "
                                f"{self.quantizer!r}")  # fmt: skip
        if self.texture is not None:
            check_choice(self.texture, "--texture", TEXTURES, AnalysisError)
        self.unknowns = parse_unknowns(self.faps) if self.faps is not None else None
        self.pinhole = Camera.parse(self.camera) if self.camera else None
        self.pipe = self.video == "-"
        self.check_stream()
        self.frame_size = parse_size(self.size) if self.size is not None else None
        # with stream_out there is no OUT: the bitstream goes to stdout, the fitted head's
        # staging folder is beside model_out (a given model needs none)
        self.out = out = Path(self.output or self.model_out or "stdout")
        fbs = out.suffix.lower() == ".fbs"
        self.extra_fbs = out.with_suffix(".fbs") if self.fbs and not fbs else None
        if self.report and Path(self.report).exists() and not Path(self.report).is_dir():
            raise AnalysisError("the report folder is a file", file=self.report)
        if self.report and Path(self.report).resolve() == out.resolve():
            raise AnalysisError(
                "-o and --report name the same path: the estimate is a file, the report a folder",
                file=self.report,
            )
        if self.rate is not None and not (fbs or self.extra_fbs):
            raise AnalysisError("--rate sets the rate of a coded .fbs: give -o OUT.fbs or --fbs")
        if self.model_out:
            self.fitted = fitted_model_paths(Path(self.model_out)) if self.auto else []
        else:
            self.fitted = fitted_paths(out) if self.auto else []

    def check_stream(self) -> None:
        """The rules of ``video="-"`` (raw frames on stdin) and ``stream_out`` (a streamed
        .fbs on stdout)."""
        from vtts.api.options import check_not_stdout

        check_not_stdout(self)
        pipe, auto = self.pipe, self.auto
        if pipe and self.size is None:
            raise AnalysisError(
                "raw frames on stdin (VIDEO -) have no size of their own: give --size WIDTHxHEIGHT"
            )
        if not pipe and self.size is not None:
            raise AnalysisError(
                "--size is the size of raw frames on stdin (VIDEO -): a video file or PNG folder "
                "states its own"
            )
        if pipe and self.report:
            raise AnalysisError(
                "--report draws side-by-side.mp4 from the video's frames again, which a pipe "
                "cannot give back: save the frames to a file and analyze that for a report"
            )
        if self.stream_out and self.output:
            raise AnalysisError(
                "--stream writes the bitstream to stdout: give no -o (save it with > OUT.fbs)"
            )
        if not self.stream_out and not self.output:
            raise AnalysisError("nothing to write: give -o OUT.fap (or OUT.fbs), or --stream")
        if self.stream_out and (self.fbs or self.rate is not None):
            raise AnalysisError(
                "--fbs and --rate go with -o: --stream codes every estimate as made"
            )
        if self.stream_out and auto and not self.model_out:
            raise AnalysisError(
                "--stream with --model auto needs --model-out HEAD.wrl: the fitted head a reader "
                "of the stream loads (stdout has no name to derive it from)"
            )
        if self.texture == "mean" and not auto:
            raise AnalysisError("--texture chooses the texture of the head --model auto fits")
        if self.texture == "mean" and (pipe or self.stream_out):
            raise AnalysisError(
                "--texture mean needs the whole video before the head is written: frames on "
                "stdin and --stream keep the texture of the frame the head was fitted to"
            )
        if self.model_out is not None:
            if not auto:
                raise AnalysisError(
                    f"--model-out is where --model auto writes the head it fits: with --model "
                    f"{self.model[0]} nothing is fitted and nothing would be written there "
                    "(the estimate plays on that model): leave --model-out out",
                    file=self.model_out,
                )
            if Path(self.model_out).suffix.lower() != ".wrl":
                raise AnalysisError("--model-out names a .wrl file", file=self.model_out)

    @property
    def tracking(self) -> bool:
        """Whether the fast tracking mode runs (the default for frames on stdin)."""
        return self.pipe if self.track is None else self.track

    @property
    def coded(self) -> bool:
        """Whether ``output`` is a coded ``.fbs``."""
        return self.out.suffix.lower() == ".fbs"


@dataclass(frozen=True)
class Analyzed:
    """What :func:`analyze` wrote and found.

    ``output`` and ``extra_fbs``: the estimate's files (None: not written; ``output`` is None
    with ``stream_out``); ``fitted``: the fitted head's files (``.wrl``, ``.adt``, ``-face.png``,
    ``-frame.png``; empty for a given model); ``textured``: the frames its texture is the mean
    of (0: its anchor frame's); ``report``: the report's folder; ``stream_bytes`` and
    ``stream_ms_per_frame``: what ``stream_out`` wrote, and the time coding and writing took a
    frame (None without it); ``analysis``: the estimates
    (:class:`vtts.analysis.estimator.Analysis`); ``tracked``: the tracking's result (the head
    it tracked as ``.model``, ``.restarts``, ``.held``); ``stream``: the estimate as a
    :class:`~vtts.fap.stream.FapStream`.
    """

    output: Path | None
    extra_fbs: Path | None
    fitted: list[Path]
    textured: int
    report: str | None
    stream_bytes: int | None
    stream_ms_per_frame: float | None
    analysis: Any
    tracked: Any
    stream: Any


def first_steps(model, first, unknowns, size: tuple[int, int], camera, fitted: bool) -> dict:
    """The coder's base steps of a ``stream_out`` (:func:`vtts.analysis.steps.coding_steps`),
    measured at the pose of its ``first`` estimate, through a fitted head's own camera (its
    ``photo`` Viewpoint) or the ``camera`` given with a model (None: the default framing)."""
    from vtts.analysis.steps import coding_steps
    from vtts.render import Camera, find_viewpoint

    pose = {"params": first.params, "translation": first.translation}
    if fitted:
        node, matrix = find_viewpoint(model.scene, "photo")
        own = Camera.from_viewpoint(node, size, matrix)
        return coding_steps(model, None, size, unknowns, model_camera=own, **pose)
    return coding_steps(model, camera, size, unknowns, **pose)


def analyze(
    options: AnalyzeOptions, *, stdin: BinaryIO | None = None, stdout: BinaryIO | None = None
) -> Analyzed:
    """Estimate FAPs from ``options.video`` (see :class:`AnalyzeOptions`). ``stdin`` and
    ``stdout``: where raw frames come from and a streamed ``.fbs`` goes (None: the
    process's)."""
    from vtts.analysis.report import REPORT_FILES
    from vtts.api.options import model_files, url_roots_set
    from vtts.atomic import check_outputs
    from vtts.threads import PipeReader

    o = options
    outputs = [p for p in (None if o.stream_out else o.out, o.extra_fbs, *o.fitted) if p]
    report = [Path(o.report) / name for name in REPORT_FILES] if o.report else []
    for path in (*outputs, *report[:1]):
        check_writable(path)
    inputs = [] if o.pipe else [Path(o.video)]
    if not o.auto:
        inputs += model_files(o.model[0])
    # every file the report folder would receive too: --report rep on rep/side-by-side.mp4
    # must not replace its video
    check_outputs([*outputs, *report], inputs)
    if not o.pipe:
        check_frames_folder(Path(o.video), [*outputs, *report])
    with url_roots_set(o.url_root):
        # the process's stdin is read so that a signal ends the wait for a frame
        if stdin is None:
            stdin = PipeReader(sys.stdin.buffer) if o.pipe else sys.stdin.buffer
        stdout = sys.stdout.buffer if stdout is None else stdout
        return estimate(o, stdin, stdout)


def estimate(o: AnalyzeOptions, stdin: BinaryIO, stdout: BinaryIO) -> Analyzed:
    """The work of :func:`analyze` once its outputs are known to be writable."""
    from vtts.analysis.estimator import DEFAULT_UNKNOWNS
    from vtts.analysis.frame_times import analysis_fps, analyzed
    from vtts.analysis.report import write_report, write_side_by_side
    from vtts.analysis.video import read_pipe, read_video
    from vtts.atomic import atomic_path
    from vtts.errors import VttsWarning
    from vtts.face import load_model
    from vtts.fap.coding import encode
    from vtts.fap.stream import format_fap
    from vtts.render import progress

    auto, pipe, fitted, camera, unknowns = o.auto, o.pipe, o.fitted, o.pinhole, o.unknowns
    if pipe:
        video = read_pipe(stdin, o.frame_size, fps=o.fps, name="-")
    else:
        video = read_video(o.video, fps=o.fps)
    model = None if auto else load_model(o.model[0])
    rate = o.rate if o.at_rate else None  # the frames of the coded rate analyzed
    total = None
    if video.n_frames is not None:
        total = sum(analyzed(i, video.fps, o.step, rate) for i in range(video.n_frames))
    name = stream_name(o.video)

    with contextlib.ExitStack() as stack:
        # the outputs' temporary files exist from the start (an unwritable output fails now)
        # and are renamed into place only when everything succeeded
        tmp_out = None if o.stream_out else stack.enter_context(atomic_path(o.out))
        tmp_fbs = stack.enter_context(atomic_path(o.extra_fbs)) if o.extra_fbs else None
        # a fitted head is written into a hidden folder beside it and moved into place with OUT
        # (with stream_out: before the stream's header, so that a reader finds it complete); a
        # given model writes nothing, and needs no folder
        staging = Path()
        if auto:
            folder = fitted[0].parent
            staging = Path(
                stack.enter_context(tempfile.TemporaryDirectory(dir=folder, prefix=".vtts-"))
            )
        from vtts.analysis.track import track

        def place_fitted() -> None:
            # the .wrl last: a reader that waits for it finds its .adt and textures there
            for written in sorted(staging.iterdir(), key=lambda p: p.suffix == ".wrl"):
                os.replace(written, fitted[0].with_name(written.name))

        sink = None
        if o.stream_out:
            from vtts.analysis.streaming import EstimateStream

            heads: list = []

            def head():
                """The tracked head, once it exists (a fitted one is in place by then)."""
                if not heads:
                    heads.append(load_model(str(fitted[0])) if auto else model)
                return heads[0]

            sent = DEFAULT_UNKNOWNS if unknowns is None else unknowns
            sink = EstimateStream(
                stdout,
                fps=analysis_fps(video.fps, o.step, rate),
                unknowns=sent,
                name=name,
                fapu=lambda: head().fapu,
                quantizer=o.quantizer,
                before_header=place_fitted if auto else None,
                steps=None
                if o.steps == "mpeg4"
                else lambda first: first_steps(head(), first, sent, video.size, camera, auto),
            )
        what = "frames from stdin" if pipe else Path(o.video).name
        how = "tracking" if o.tracking else "analyzing"
        bar = stack.enter_context(progress(total, f"{how} {what}", not o.progress))
        options = {} if unknowns is None else {"unknowns": unknowns}
        if auto and not pipe:
            # a file can be looked ahead in: the head is made from its most typical frame
            from vtts.analysis.anchor import choose_anchor

            again = read_video(o.video, fps=o.fps)
            options["anchor"] = choose_anchor(again.frames(), again.fps, again.n_frames,
                                              step=o.step, rate=rate)  # fmt: skip
        tracked = track(
            video.frames(),
            fps=video.fps,
            model=model,
            model_path=staging / fitted[0].name if auto else None,
            camera=camera,
            face=o.face,
            step=o.step,
            rate=rate,
            progress=lambda _index: bar.advance(),
            on_estimate=sink,
            tracking=o.tracking,
            **options,
        )
        analysis = tracked.analysis
        textured = 0  # the frames the fitted head's texture is the mean of
        if auto and not pipe and sink is None and o.texture != "anchor":
            from vtts.analysis.texture import retexture

            video = read_video(o.video, fps=o.fps)  # again: the frames were not kept
            tracked.model = retexture(tracked, video.frames, video.size)
            textured = sum(not np.isnan(fe.psnr) for fe in analysis.frames)
        stream = analysis.stream(name, fapu=tracked.model.fapu)
        steps = None
        if sink is None and (o.coded or tmp_fbs is not None) and o.steps == "face":
            from vtts.analysis.steps import analysis_steps

            steps = analysis_steps(analysis, tracked.model, video.size)
        if sink is not None:
            sink.end()
        elif o.coded:
            tmp_out.write_bytes(encode(stream, rate=o.rate, steps=steps, quantizer=o.quantizer))
        else:
            with warnings.catch_warnings():  # the summary says where the translation went
                warnings.simplefilter("ignore", VttsWarning)
                tmp_out.write_text(format_fap(stream), encoding="utf-8")
        if tmp_fbs is not None:
            tmp_fbs.write_bytes(encode(stream, rate=o.rate, steps=steps, quantizer=o.quantizer))
        if o.report:
            write_report(analysis, o.report)
            video = read_video(o.video, fps=o.fps)  # again: the frames were not kept
            write_side_by_side(o.report, video.frames(), analysis, tracked.model)
        if sink is None and auto:
            place_fitted()
    return Analyzed(
        output=None if o.stream_out else o.out,
        extra_fbs=o.extra_fbs,
        fitted=fitted,
        textured=textured,
        report=o.report,
        stream_bytes=None if sink is None else sink.bytes_written,
        stream_ms_per_frame=None if sink is None else 1000 * sink.framing_s / max(sink.frames, 1),
        analysis=analysis,
        tracked=tracked,
        stream=stream,
    )
