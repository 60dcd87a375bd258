"""The ``vtts`` command: a thin layer that parses arguments and calls the library.

Input errors are printed as ``FILE:LINE:COL: error: MESSAGE`` and exit with status 1; no Python
traceback reaches the user for bad input. Each sub-command is one function in :data:`COMMANDS`.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import math
import os
import sys
import warnings
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import NoReturn

import numpy as np

from vtts import __version__
from vtts.errors import VttsError
from vtts.messages import print_error, reported_warnings

# ---- check ---------------------------------------------------------------------------------------


def _check_wrl(path: Path, args: argparse.Namespace) -> str:
    from vtts.face import load_model
    from vtts.vrml import triangulate

    model = load_model(path, lenient=args.lenient)
    scene = model.scene
    # what render would refuse, check refuses too (an out-of-range coordIndex)
    for shape, _, _ in scene.shapes():
        geom = shape["geometry"]
        if geom is not None and geom.expand().type.name == "IndexedFaceSet":
            try:
                triangulate(geom)
            except VttsError as e:
                e.file = e.file or str(path)
                raise
    for node, urls in model.missing_textures():
        warnings.warn(model.texture_warning(node, urls), stacklevel=1)
    text = f"{_plural(scene.node_count, 'node')}, {_plural(scene.triangle_count(), 'triangle')}"
    if model.tables.adts:
        text += f", {_plural(len(model.tables.adts), 'MIAP')}"
    return text


def _check_adt(path: Path, args: argparse.Namespace) -> str:
    from vtts.errors import AdtError
    from vtts.face import check_tables, read_adt
    from vtts.vrml import read

    tables = read_adt(path)
    wrl = path.with_suffix(".wrl")
    if not wrl.is_file():
        raise AdtError(
            f"no {wrl.name} beside it: an .adt is checked against the scene it animates",
            file=str(path),
        )
    if not tables:
        raise AdtError("no tables in it (an .adt holds MIAP, temporal or feature-point tables)",
                       file=str(path))  # fmt: skip
    check_tables(tables, read(wrl, lenient=args.lenient), file=str(path))
    nodes = len(tables.mesh_nodes()) + len(tables.transform_nodes())
    return f"{_plural(len(tables.adts), 'MIAP')} on {_plural(nodes, 'node')} of {wrl.name}"


def _check_fbs(path: Path) -> str:
    from vtts.fap.cli_coding import check_fbs

    return check_fbs(path)


def _plural(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _check_fap(path: Path, args: argparse.Namespace) -> str:
    from vtts.fap import read_fap

    stream = read_fap(path)
    masked = int(stream.mask.any(axis=0).sum())
    return f"{stream.n_frames} frames at {stream.fps:g} fps, {masked} FAPs"


#: File suffix → checker returning the summary printed after ``OK FILE``.
CHECKERS: dict[str, Callable[[Path, argparse.Namespace], str]] = {
    ".wrl": _check_wrl,
    ".adt": _check_adt,
    ".fap": _check_fap,
    ".fbs": lambda path, args: _check_fbs(path),
}


def cmd_check(args: argparse.Namespace) -> int:
    """Check files; print ``OK FILE (summary)`` or ``FILE:LINE:COL: error: MESSAGE`` for each."""
    failed = 0
    for name in args.files:
        path = Path(name)
        checker = CHECKERS.get(path.suffix.lower())
        if checker is None:
            known = ", ".join(sorted(CHECKERS))
            print(
                f"{name}: error: unknown file type '{path.suffix}' (vtts checks {known})",
                file=sys.stderr,
            )
            failed += 1
            continue
        if not path.is_file():
            print(f"{name}: error: no such file", file=sys.stderr)
            failed += 1
            continue
        try:
            with reported_warnings():
                summary = checker(path, args)
        except VttsError as e:
            print_error(e, name)
            failed += 1
            continue
        print(f"OK {name} ({summary})")
    return 1 if failed else 0


# ---- info ----------------------------------------------------------------------------------------


def _describe_node(node, seen: set[int], depth: int, out: list[str]) -> None:
    from vtts.vrml.geometry import polygon_triangle_count

    pad = "  " * depth
    label = f"DEF {node.name} " if node.name else ""
    if id(node) in seen:
        out.append(f"{pad}USE {node.name or '?'} ({node.type.name})")
        return
    seen.add(id(node))
    detail = ""
    shown = node.expand()
    kind = node.type.describe() if node.type.kind in ("proto", "externproto") else node.type.name
    if shown.type.name == "IndexedFaceSet":
        coord = shown["coord"]
        n_pts = 0 if coord is None else len(coord.expand()["point"])
        ci = shown["coordIndex"]
        n_faces = int((ci == -1).sum() + (1 if len(ci) and ci[-1] != -1 else 0))
        detail = f": {n_pts} vertices, {n_faces} faces, {polygon_triangle_count(ci)} triangles"
    elif shown.type.name == "Transform":
        bits = []
        for f in ("translation", "rotation", "scale", "center"):
            if f in shown.fields:
                bits.append(f"{f} " + " ".join(f"{v:g}" for v in shown.fields[f]))
        detail = (": " + ", ".join(bits)) if bits else ""
    elif shown.type.name in ("ImageTexture",) and shown["url"]:
        detail = f": {shown['url'][0]}"
    out.append(f"{pad}{label}{kind}{detail}")
    for fname, value in node.fields.items():
        children = value if isinstance(value, list) else [value]
        nodes = [c for c in children if hasattr(c, "type")]
        if not nodes:
            continue
        if fname != "children":
            out.append(f"{pad}  .{fname}")
            for c in nodes:
                _describe_node(c, seen, depth + 2, out)
        else:
            for c in nodes:
                _describe_node(c, seen, depth + 1, out)


def scene_tree(scene) -> list[str]:
    """The scene graph as indented lines (node type, DEF name, vertex and face counts)."""
    from vtts.vrml.scene import Node, Proto

    out: list[str] = []
    seen: set[int] = set()
    for s in scene.statements:
        if isinstance(s, Node):
            _describe_node(s, seen, 0, out)
        elif isinstance(s, Proto):
            word = "PROTO" if s.kind == "proto" else "EXTERNPROTO"
            out.append(f"{word} {s.name} [{len(s.decls)} members]")
    return out


def cmd_info(args: argparse.Namespace) -> int:
    """Describe a scene or model: the scene graph, and what the model can do; or what a .fbs
    bitstream holds."""
    from vtts.face import find_model, load_model

    if Path(args.file).suffix.lower() == ".fbs":
        from vtts.fap.cli_coding import describe_fbs

        try:
            lines = describe_fbs(args.file)
        except VttsError as e:
            print_error(e, args.file)
            return 1
        print(f"{args.file}:")
        for line in lines:
            print("  " + line)
        return 0

    try:
        path = find_model(args.file)
        with reported_warnings():
            model = load_model(path, lenient=args.lenient)
    except VttsError as e:
        print_error(e, args.file)
        return 1
    scene = model.scene
    print(
        f"{path}: {_plural(scene.node_count, 'node')}, "
        f"{_plural(scene.triangle_count(), 'triangle')}"
    )
    for line in scene_tree(scene):
        print("  " + line)
    if model.tables:
        print(f"model {model.name}:")
        for line in model.describe():
            print("  " + line)
    return 0


# ---- pose ----------------------------------------------------------------------------------------


def _seed(text: str) -> int:
    """A ``--seed``: a whole number 0 to 2**63 - 1 (numpy's generators take no negative seed)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 0 <= value < 2**63:
        raise argparse.ArgumentTypeError(f"{value} must be within 0 to 2**63 - 1")
    return value


def parse_assignments(
    text: str, what: str, default: float | None = None, *, bounds: tuple[float, float] | None = None
) -> dict[str, float]:
    """``"19=512,open_jaw=300"`` → ``{"19": 512.0, "open_jaw": 300.0}``.

    Without ``=VALUE`` an item takes ``default`` (an error when None). Values must be finite and,
    with ``bounds`` (lo, hi), within them."""
    import math

    from vtts.errors import FapError

    out: dict[str, float] = {}
    for item in filter(None, (x.strip() for x in text.split(","))):
        key, eq, value = item.partition("=")
        if not eq:
            if default is None:
                raise FapError(f"{what} '{item}' needs a value: write {item}=VALUE")
            out[key.strip()] = default
            continue
        try:
            number = float(value)
        except ValueError:
            raise FapError(f"{what} '{key.strip()}': {value!r} is not a number") from None
        if not math.isfinite(number):
            raise FapError(f"{what} '{key.strip()}': {value.strip()} is not a finite number")
        if bounds is not None and not bounds[0] <= number <= bounds[1]:
            lo, hi = bounds
            raise FapError(f"{what} '{key.strip()}': {value.strip()} must be within {lo:g}–{hi:g}")
        out[key.strip()] = number
    return out


def _pose_request(args: argparse.Namespace) -> tuple[dict, dict, dict]:
    """(faps, visemes, expressions) from the --fap/--viseme/--expression flags."""
    faps: dict[str, float] = {}
    visemes: dict[str, float] = {}
    expressions: dict[str, float] = {}
    from vtts.limits import MAX_FAP_VALUE

    for text in args.fap or []:
        faps.update(parse_assignments(text, "FAP", bounds=(-MAX_FAP_VALUE, MAX_FAP_VALUE)))
    for text in args.viseme or []:
        visemes.update(parse_assignments(text, "viseme", default=1.0, bounds=(0.0, 1.0)))
    for text in args.expression or []:
        expressions.update(parse_assignments(text, "expression", default=1.0, bounds=(0.0, 1.0)))
    return faps, visemes, expressions


def _posed_params(model, request: tuple[dict, dict, dict]) -> np.ndarray:
    """The model's parameter vector for a pose request, warning once about MIAPs it lacks."""
    faps, visemes, expressions = request
    params = model.params(faps, visemes=visemes, expressions=expressions)
    unused = [
        k
        for k in [
            *faps,
            *(f"viseme {v}" for v in visemes),
            *(f"expression {e}" for e in expressions),
        ]
        if _miap_of(k) not in model.tables.adts
    ]
    if unused:
        print(
            f"warning: {model.name} has no table for {', '.join(unused)}; ignored",
            file=sys.stderr,
        )
    return params


def cmd_pose(args: argparse.Namespace) -> int:
    """Write the model posed by the given FAPs, visemes and expressions as plain VRML97."""
    from vtts.face import load_model
    from vtts.vrml import write

    request = _pose_request(args)
    model = load_model(args.model)
    pose = model.engine.deform(_posed_params(model, request))
    write(model.posed_scene(pose), args.output, comment=f"{model.name} posed by vtts pose")
    print(f"wrote {args.output}")
    return 0


def _size(text: str) -> tuple[int, int]:
    import re

    from vtts.errors import RenderError

    # ASCII digits ('²'.isdigit() is true), few enough for int() (it refuses 4,300)
    m = re.fullmatch(r"([0-9]{1,18})x([0-9]{1,18})", text.lower())
    if not m:
        raise RenderError(f"--size takes WIDTHxHEIGHT in pixels, such as 352x288; got {text!r}")
    return int(m[1]), int(m[2])


def _background(args: argparse.Namespace, video: bool):
    """The ``--background`` of a command as the renderer takes it, checked against its outputs:
    ``video`` is whether an MP4 is written (H.264 has no alpha, so no ``transparent``)."""
    from vtts.errors import RenderError
    from vtts.render.color import TRANSPARENT, parse_background

    if args.background is None:
        return None
    background = parse_background(args.background)
    if background == TRANSPARENT and video:
        raise RenderError(
            "--background transparent needs PNG output: an MP4 (H.264) has no alpha channel; "
            "write the frames with --png-dir alone"
        )
    return background


def _detail(args: argparse.Namespace) -> float | None:
    """The renderer's ``detail`` for a command: its ``--detail`` (0: every triangle),
    :data:`vtts.render.DETAIL_PX` when not given; None for commands without the option."""
    if not hasattr(args, "detail"):
        return None
    if args.detail is None:
        from vtts.render import DETAIL_PX

        return DETAIL_PX
    return args.detail


def _renderer(args: argparse.Namespace, models, supersample: int = 1, video: bool = False):
    from vtts import warm
    from vtts.errors import RenderError
    from vtts.render import Camera

    if args.camera and args.viewpoint:
        raise RenderError("--camera and --viewpoint both choose the camera: give one of them")
    camera = Camera.parse(args.camera) if args.camera else None
    background = _background(args, video)
    return warm.renderer(
        models,
        size=_size(args.size),
        camera=camera,
        viewpoint=args.viewpoint,
        layout=args.layout,
        supersample=supersample,
        detail=_detail(args),
        **({} if background is None else {"background": background}),
    )


def cmd_render(args: argparse.Namespace) -> int:
    """Render one pose of one or more models to a PNG."""
    from vtts.render import write_png
    from vtts.warm import load_model  # kept between the jobs of vtts batch

    _background(args, video=False)  # a bad color fails before the models load
    request = _pose_request(args)
    models = [load_model(m) for m in args.model]
    params = [_posed_params(m, request) for m in models]
    # a still can afford antialiasing: render at twice the size and filter down
    with _renderer(args, models, supersample=2) as renderer:
        frame = renderer.render(params)
    write_png(args.output, frame)
    print(f"wrote {args.output} ({frame.shape[1]}x{frame.shape[0]})")
    return 0


def cmd_play(args: argparse.Namespace) -> int:
    """Play a FAP stream on one or more models into an MP4 and/or a folder of PNGs; a stream's
    head translation moves each model by that many of its own ES units."""
    from vtts.errors import RenderError
    from vtts.speech.audio import read_for_mp4

    if args.stream == "-":
        return _play_live(args)
    if args.output == "-":
        raise RenderError("-o - (raw frames on stdout) plays a stream from stdin: vtts play - …")
    args.fps = DEFAULT_PLAY_FPS if args.fps is None else args.fps
    if not (args.output or args.png_dir or args.web or args.gltf or args.curves_out):
        raise RenderError(
            "nothing to write: give -o OUT.mp4 (or OUT.glb), --png-dir DIR, --web DIR and/or "
            "--curves-out FILE"
        )
    if not 0 < args.fps <= 240:
        raise RenderError(f"--fps must be within 0–240, got {args.fps:g}")
    _background(args, video=bool(args.output))
    _check_web(args)
    _check_curves(args)
    # the sound of the MP4 and the web player: any format say --audio takes, as say muxes it
    speech = read_for_mp4(args.audio) if args.audio and (args.output or args.web) else None
    with _speech_wav(speech) as wav:
        return _play(args, wav)


#: The frame rate ``vtts play`` renders a file at unless ``--fps`` says otherwise.
DEFAULT_PLAY_FPS = 30.0


def _play_live(args: argparse.Namespace) -> int:
    """``vtts play -``: render a FAP stream from stdin frame by frame as it arrives, at its own
    rate, into an MP4 (renamed into place at the end of the stream), raw rgb24 frames on stdout
    (``-o -``, flushed per frame) and/or PNGs. A streamed .fbs plays as its packets arrive; a
    whole .fbs is read completely first."""
    import itertools

    from vtts.animate.fapstream import model_roots, warn_ignored
    from vtts.animate.live import LiveParams
    from vtts.errors import RenderError
    from vtts.fap.coding import StreamDecoder
    from vtts.render import PngSequenceWriter, VideoWriter, progress
    from vtts.warm import load_model

    unsupported = [
        flag
        for flag, value in (
            ("--audio", args.audio),
            ("--web", args.web),
            ("--gltf", args.gltf),
            ("--curves-out", args.curves_out),
        )
        if value
    ]
    if unsupported:
        raise RenderError(
            f"{', '.join(unsupported)} need the whole stream: a stream from stdin (vtts play -) "
            "renders to -o OUT.mp4, -o - (raw rgb24 frames on stdout) or --png-dir"
        )
    if not (args.output or args.png_dir):
        raise RenderError(
            "nothing to write: give -o OUT.mp4, -o - (raw rgb24 frames on stdout) or --png-dir"
        )
    raw = args.output == "-"
    _background(args, video=bool(args.output))  # rgb24 frames have no alpha either
    decoder = StreamDecoder(sys.stdin.buffer, file="-")  # waits for the header
    fps = decoder.header.fps
    if args.fps is not None and abs(args.fps - fps) > 1e-9 * fps:
        raise RenderError(
            f"a stream from stdin plays at its own rate, {fps:g} Hz: give no --fps "
            f"(or --fps {fps:g}), not {args.fps:g}"
        )
    args.fps = fps
    # the models load once the header arrived: a fitted head is in place by then
    models = [load_model(m) for m in args.model]
    lives = [LiveParams(decoder.header.faps, m.tables.adts) for m in models]
    out = sys.stdout.buffer if raw else None
    n = 0
    with contextlib.ExitStack() as stack:
        renderer = stack.enter_context(_renderer(args, models, video=bool(args.output)))
        matrices = [renderer.model_matrix(j) for j in range(len(models))]
        sinks = []
        if args.output and not raw:
            sinks.append(stack.enter_context(VideoWriter(args.output, fps, renderer.size)))
        if args.png_dir:
            sinks.append(stack.enter_context(PngSequenceWriter(args.png_dir)))
        bar = stack.enter_context(progress(None, "rendering stdin", args.quiet or raw))

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
        for frame in _after_first(renderer.frames(params, roots, batch=1)):
            if out is not None:
                out.write(np.ascontiguousarray(frame[..., :3]).tobytes())
                out.flush()
            for sink in sinks:
                sink.write(frame)
            bar.advance()
            n += 1
    if not args.quiet:
        written = " and ".join(str(p) for p in (args.output if not raw else "stdout",
                                                args.png_dir) if p)  # fmt: skip
        print(f"wrote {written}: {n} frames at {fps:g} fps ({n / fps:.2f} s)", file=sys.stderr)
    return 0


@contextlib.contextmanager
def _speech_wav(speech: tuple[np.ndarray, int] | None):
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


class _SpeechTrack:
    """The speech (``(n,)`` int16 samples, rate in Hz) as a temporary WAV (:func:`_speech_wav`)
    and the MP4's AAC track encoded from it in the background (:class:`vtts.render.AacTrack`);
    :meth:`close` stops the encoding and removes both."""

    def __init__(self, speech: tuple[np.ndarray, int]) -> None:
        from vtts.render import AacTrack

        self._files = contextlib.ExitStack()
        with self._files:  # undone at once if anything fails here, kept otherwise
            self.wav = self._files.enter_context(_speech_wav(speech))
            self.aac = self._files.enter_context(AacTrack(self.wav, self.wav.parent))
            self._files = self._files.pop_all()

    def close(self) -> None:
        self._files.close()

    def __enter__(self) -> _SpeechTrack:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _play(args: argparse.Namespace, audio: Path | None) -> int:
    """The work of :func:`cmd_play` once its options are checked; ``audio`` is the speech as
    a WAV (or None)."""
    from vtts.animate.fapstream import model_roots, stream_params, warn_ignored
    from vtts.fap.cli_coding import read_stream
    from vtts.render import PngSequenceWriter, VideoWriter, progress
    from vtts.warm import load_model  # kept between the jobs of vtts batch

    stream = read_stream(args.stream)
    models = [load_model(m) for m in args.model]
    tracks, played = [], []
    for m in models:
        sp = stream_params(stream, set(m.tables.adts), fps=args.fps)
        warn_ignored(m.name, sp.ignored)
        tracks.append(sp.params)
        played.append(sp)
    n = tracks[0].shape[0]
    # where the stream's head translation moves the heads (the renderer finds them in the video)
    roots = _stream_roots(args, models, played) if args.web or args.gltf else None
    if args.web:
        _write_web(args, models, tracks, audio=audio, roots=roots)
    if args.gltf:
        _write_gltf(args, models, tracks, roots)
    if not args.output and not args.png_dir:
        _write_curves(args, stream)
        if not args.quiet:
            outputs = " and ".join(str(p) for p in (args.gltf, args.web, args.curves_out) if p)
            print(f"wrote {outputs}: {n} frames at {args.fps:g} fps ({n / args.fps:.2f} s)")
        return 0
    with contextlib.ExitStack() as stack:
        renderer = stack.enter_context(_renderer(args, models, video=bool(args.output)))
        roots = [
            model_roots(sp, renderer.model_matrix(j), m.fapu, m.name)
            for j, (sp, m) in enumerate(zip(played, models, strict=True))
        ]
        moving = None
        if any(r is not None for r in roots):
            moving = ([None if r is None else r[i] for r in roots] for i in range(n))
        sinks = []
        if args.output:
            sinks.append(
                stack.enter_context(VideoWriter(args.output, args.fps, renderer.size, audio=audio))
            )
        if args.png_dir:
            sinks.append(stack.enter_context(PngSequenceWriter(args.png_dir)))
        bar = stack.enter_context(progress(n, f"rendering {Path(args.stream).name}", args.quiet))
        for frame in _after_first(
            renderer.frames(([t[i] for t in tracks] for i in range(n)), moving)
        ):
            for sink in sinks:
                sink.write(frame)
            bar.advance()
    _write_curves(args, stream)
    written = (args.output, args.gltf, args.png_dir, args.web, args.curves_out)
    outputs = " and ".join(str(p) for p in written if p)
    if not args.quiet:
        print(f"wrote {outputs}: {n} frames at {args.fps:g} fps ({n / args.fps:.2f} s)")
    return 0


def _check_curves(args: argparse.Namespace) -> None:
    """``--curves FORMAT`` names a format and goes with ``--curves-out`` (before any work)."""
    from vtts.avatar.curves import DEFAULT_FORMAT, check_format
    from vtts.errors import AvatarError

    if args.curves is not None and not args.curves_out:
        raise AvatarError("--curves FORMAT says how to write --curves-out FILE: give that too")
    if args.curves_out:
        args.curves = check_format(args.curves or DEFAULT_FORMAT)


def _write_curves(
    args: argparse.Namespace, stream=None, params=None, phones=None, words=None
) -> None:
    """``--curves-out FILE`` of say (the first model's timeline, the phones and the words) and
    play (the stream itself, every FAP, viseme and expression it sets; no words):
    :mod:`vtts.avatar.curves`."""
    if not args.curves_out:
        return
    from vtts.animate.fapstream import stream_params
    from vtts.avatar.curves import write_curves
    from vtts.face.miap import all_miaps

    if params is None:
        params = stream_params(stream, all_miaps(), fps=args.fps).params
    write_curves(args.curves_out, args.curves, params, args.fps, phones, words)


def _write_gltf(args: argparse.Namespace, models, params, roots=None) -> None:
    """``-o OUT.glb`` (or ``.gltf``) of say and play: the animation as glTF
    (:func:`vtts.export.write_gltf`) with the camera, size and layout the video would have."""
    from vtts.export import write_gltf
    from vtts.render import Camera

    write_gltf(
        args.gltf,
        models,
        params,
        args.fps,
        roots=roots,
        camera=Camera.parse(args.camera) if args.camera else None,
        viewpoint=args.viewpoint,
        size=_size(args.size),
        layout=args.layout,
    )


def _stream_roots(args: argparse.Namespace, models, played) -> list | None:
    """Each model's root pose per frame as the stream's head translation moves it
    (:func:`vtts.animate.fapstream.model_roots`) where the export places it; None when none
    moves."""
    from vtts.animate.fapstream import model_roots
    from vtts.export import placement
    from vtts.render import Camera

    where = placement(
        models,
        camera=Camera.parse(args.camera) if args.camera else None,
        viewpoint=args.viewpoint,
        size=_size(args.size),
        layout=args.layout,
    )
    roots = [
        model_roots(sp, where.matrices[j], m.fapu, m.name)
        for j, (sp, m) in enumerate(zip(played, models, strict=True))
    ]
    return roots if any(r is not None for r in roots) else None


def _check_web(args: argparse.Namespace) -> None:
    """``--web DIR`` names a folder the web player may be written into (before any work)."""
    if args.web:
        from vtts.export.web import check_web_folder

        check_web_folder(args.web)


def _write_web(args: argparse.Namespace, models, params, *, audio=None, roots=None) -> None:
    """``--web DIR`` of say and play: the web player (:func:`vtts.export.web.write_web`) with
    the camera, size, layout and background the video would have."""
    from vtts.export.web import write_web
    from vtts.render import Camera
    from vtts.render.color import parse_background

    write_web(
        args.web,
        models,
        params,
        args.fps,
        audio=audio,
        roots=roots,
        camera=Camera.parse(args.camera) if args.camera else None,
        viewpoint=args.viewpoint,
        size=_size(args.size),
        layout=args.layout,
        background=parse_background(args.background) if args.background else None,
    )


def _speak_and_set_up(args, text: str, models: list, known: set[str]):
    """The utterance of ``text``, each model's timeline, the renderer (None without video or
    PNG output) and the speech's AAC track for the MP4 (a :class:`_SpeechTrack`, None without
    ``-o``; the caller closes it) for ``vtts say``: espeak-ng speaks (in a process of its own),
    then its sound is encoded (by ffmpeg, in another) and the timelines are built in a worker
    thread while the renderer is set up."""
    from concurrent.futures import ThreadPoolExecutor

    from vtts.animate.timeline import build_timeline
    from vtts.utterance import prepare_utterance

    def speak():
        utt = prepare_utterance(
            text,
            known=known,
            engine=args.engine,
            voice=args.voice,
            rate=args.rate,
            pitch=args.pitch,
            phonemes=args.phonemes,
            audio=args.audio,
        )
        # the MP4's sound is encoded now, on a core the renderer's set-up leaves idle
        track = _SpeechTrack((utt.audio, utt.rate)) if args.output else None
        try:
            timelines = [
                build_timeline(
                    m,
                    utt.phones,
                    utt.bookmarks,
                    utt.duration,
                    fps=args.fps,
                    seed=args.seed,
                    autonomous=not args.no_autonomous,
                )
                for m in models
            ]
        except BaseException:
            if track is not None:
                track.close()
            raise
        return utt, timelines, track

    with ThreadPoolExecutor(max_workers=1) as pool:
        speaking = pool.submit(speak)
        renderer = None
        try:
            if args.output or args.png_dir:
                renderer = _renderer(args, models, video=bool(args.output))
        except BaseException as e:
            try:
                _, _, track = speaking.result()
            except BaseException:
                if isinstance(e, VttsError):
                    raise  # a problem with the text is reported first, as it comes first
            else:
                if track is not None:
                    track.close()
            raise
        utt, timelines, track = speaking.result()
    return utt, timelines, renderer, track


def cmd_say(args: argparse.Namespace) -> int:
    """Speak bookmarked text with one or more models into an MP4 (and/or PNGs, WAV, FAP)."""

    from vtts.errors import BookmarkError, RenderError
    from vtts.limits import MAX_TEXT_BYTES, read_bytes_capped
    from vtts.warm import load_model  # kept between the jobs of vtts batch

    written = (args.output, args.gltf, args.png_dir, args.web, args.fap_out, args.wav_out)
    if not any(written) and not args.curves_out and not args.timings_out:
        raise RenderError(
            "nothing to write: give -o OUT.mp4 (or OUT.glb), --png-dir, --web, --fap-out, "
            "--wav-out, --timings-out or --curves-out"
        )
    if not 0 < args.fps <= 240:
        raise RenderError(f"--fps must be within 0–240, got {args.fps:g}")
    _background(args, video=bool(args.output))
    _check_web(args)
    _check_curves(args)
    text = args.text
    if args.text_option is not None:
        if text or args.file:
            given = "the text twice" if text else "--text and --file"
            raise RenderError(f"give the text once: got {given}")
        text = args.text_option
    if args.file:
        try:
            text = read_bytes_capped(args.file, MAX_TEXT_BYTES, what="text").decode("utf-8")
        except (OSError, UnicodeDecodeError) as e:
            reason = getattr(e, "strerror", None) or "not UTF-8 text"
            raise VttsError(f"cannot read the text: {reason}", file=args.file) from None
    if not text or not text.strip():
        raise RenderError("nothing to say: give the text, or --file FILE")
    models = [load_model(m) for m in args.model]
    known = {x.name for m in models for x in m.tables.adts if x.kind == "expression"}
    try:
        utt, timelines, renderer, track = _speak_and_set_up(args, text, models, known)
    except BookmarkError as e:
        if args.file and e.file is None:
            e.file = args.file  # the text's place is in that file
        raise
    with track if track is not None else contextlib.nullcontext():
        return _say(args, models, utt, timelines, renderer, track, written)


def _say(args, models, utt, timelines, renderer, track, written) -> int:
    """The work of :func:`cmd_say` once the speech, its timelines and the renderer are ready;
    ``track``: the speech's WAV and AAC track for the MP4 (None without ``-o``)."""
    from vtts.animate.timeline import timeline_stream
    from vtts.fap import write_fap
    from vtts.render import PngSequenceWriter, VideoWriter, progress, write_wav
    from vtts.utterance import write_utterance_timings

    for m in models:
        shown = {x.name for x in m.tables.adts if x.kind == "expression"}
        lacking = sorted({b.written for b in utt.text.check_names(shown)})
        if lacking:
            print(
                f"warning: {m.name} has no table for <{'>, <'.join(lacking)}>; not shown",
                file=sys.stderr,
            )
    n = timelines[0].n_frames
    if args.output or args.png_dir:
        with contextlib.ExitStack() as stack:
            renderer = stack.enter_context(renderer)
            sinks = []
            if args.output:
                sinks.append(
                    stack.enter_context(
                        VideoWriter(args.output, args.fps, renderer.size, audio=track.aac)
                    )
                )
            if args.png_dir:
                sinks.append(stack.enter_context(PngSequenceWriter(args.png_dir)))
            bar = stack.enter_context(progress(n, "speaking", args.quiet))
            frames = ([tl.params[i] for tl in timelines] for i in range(n))
            for frame in _after_first(renderer.frames(frames)):
                for sink in sinks:
                    sink.write(frame)
                bar.advance()
    if args.gltf:  # a glTF has no sound: --wav-out writes the speech beside it
        _write_gltf(args, models, [tl.params for tl in timelines])
    if args.web:
        with _speech_wav((utt.audio, utt.rate)) as wav:
            _write_web(args, models, [tl.params for tl in timelines], audio=wav)
    # the stream and the speech last: a say that fails on the way leaves them as they were
    if args.fap_out:
        write_fap(timeline_stream(timelines[0], models[0].name), args.fap_out)
    if args.wav_out:
        write_wav(args.wav_out, utt.audio, utt.rate)
    if args.timings_out:
        write_utterance_timings(args.timings_out, utt)
    _write_curves(args, params=timelines[0].params, phones=utt.phones, words=utt.words)
    if not args.quiet:
        written = (*written, args.timings_out, args.curves_out)
        outputs = [str(p) for p in written if p]
        print(f"wrote {', '.join(outputs)}: {utt.duration:.2f} s, {n} frames at {args.fps:g} fps")
    return 0


def cmd_analyze(args: argparse.Namespace) -> int:
    """Estimate FAPs from a video (Eisert–Girod analysis by synthesis) into a .fap/.fbs file."""
    import tempfile

    from vtts.analysis.estimator import DEFAULT_UNKNOWNS
    from vtts.analysis.report import mean_psnr, write_report, write_side_by_side
    from vtts.analysis.unknowns import parse_unknowns
    from vtts.analysis.video import read_pipe, read_video
    from vtts.atomic import atomic_path, check_outputs
    from vtts.errors import AnalysisError, VttsWarning
    from vtts.face import load_model
    from vtts.fap.stream import format_fap
    from vtts.render import Camera, progress

    # everything that can be wrong with the input fails here, before minutes of estimation
    models = args.model or ["auto"]
    if len(models) != 1:
        raise AnalysisError(f"vtts analyze fits one model, got {len(models)} --model flags")
    auto = models[0] == "auto"
    if auto and args.camera:
        raise AnalysisError("--camera is for a given --model: a fitted head brings its camera")
    if args.face is not None and args.face < 1:
        raise AnalysisError(f"--face must be 1 (the largest) or more, got {args.face}")
    if args.rate is not None and not 0 < args.rate <= 1000:
        raise AnalysisError(f"--rate must be within 0–1000 Hz, got {args.rate:g}")
    if args.step < 1:
        raise AnalysisError(f"--step must be a whole number ≥ 1, got {args.step}")
    if args.fps is not None and not 0 < args.fps <= 1000:
        raise AnalysisError(f"--fps must be within 0–1000, got {args.fps:g}")
    unknowns = parse_unknowns(args.faps) if args.faps is not None else None
    camera = Camera.parse(args.camera) if args.camera else None
    pipe = args.video == "-"
    _check_analyze_stream(args, pipe, auto)
    size = _size(args.size) if args.size is not None else None
    # with --stream there is no OUT: the bitstream goes to stdout
    out = Path(args.output) if args.output else Path(args.model_out)
    fbs = out.suffix.lower() == ".fbs"
    extra_fbs = out.with_suffix(".fbs") if args.fbs and not fbs else None
    if args.report and Path(args.report).exists() and not Path(args.report).is_dir():
        raise AnalysisError("the report folder is a file", file=args.report)
    if args.report and Path(args.report).resolve() == out.resolve():
        raise AnalysisError(
            "-o and --report name the same path: the estimate is a file, the report a folder",
            file=args.report,
        )
    if args.rate is not None and not (fbs or extra_fbs):
        raise AnalysisError("--rate sets the rate of a coded .fbs: give -o OUT.fbs or --fbs")
    if args.model_out:
        fitted = _fitted_model_paths(Path(args.model_out)) if auto else []
    else:
        fitted = _fitted_paths(out) if auto else []
    outputs = [p for p in (None if args.stream_out else out, extra_fbs, *fitted) if p]
    for path in (*outputs, args.report and Path(args.report) / "frames.csv"):
        if path:
            _check_writable(path)
    check_outputs(outputs, [] if pipe else [Path(args.video)])
    if pipe:
        video = read_pipe(sys.stdin.buffer, size, fps=args.fps, name="-")  # type: ignore[arg-type]
    else:
        video = read_video(args.video, fps=args.fps)
    model = None if auto else load_model(models[0])
    total = None if video.n_frames is None else -(-video.n_frames // args.step)
    name = _stream_name(args.video)
    say = sys.stderr if args.stream_out else sys.stdout  # with --stream, stdout is the bitstream's

    with contextlib.ExitStack() as stack:
        # the outputs' temporary files exist from the start (an unwritable -o fails now) and
        # are renamed into place only when everything succeeded
        tmp_out = None if args.stream_out else stack.enter_context(atomic_path(out))
        tmp_fbs = stack.enter_context(atomic_path(extra_fbs)) if extra_fbs else None
        # a fitted head is written into a hidden folder beside OUT and moved into place with OUT
        # (with --stream: before the stream's header, so that a reader finds it complete)
        folder = fitted[0].parent if fitted else out.parent
        staging = stack.enter_context(tempfile.TemporaryDirectory(dir=folder, prefix=".vtts-"))
        from vtts.analysis.track import track

        def place_fitted() -> None:
            # the .wrl last: a reader that waits for it finds its .adt and textures there
            for written in sorted(Path(staging).iterdir(), key=lambda p: p.suffix == ".wrl"):
                os.replace(written, fitted[0].with_name(written.name))

        sink = None
        if args.stream_out:
            from vtts.analysis.streaming import EstimateStream

            heads: list = []

            def head():
                """The tracked head, once it exists (a fitted one is in place by then)."""
                if not heads:
                    heads.append(load_model(str(fitted[0])) if auto else model)
                return heads[0]

            sent = DEFAULT_UNKNOWNS if unknowns is None else unknowns
            sink = EstimateStream(
                sys.stdout.buffer,
                fps=video.fps / args.step,
                unknowns=sent,
                name=name,
                fapu=lambda: head().fapu,
                before_header=place_fitted if auto else None,
                steps=None
                if args.steps == "mpeg4"
                else lambda first: _first_steps(head(), first, sent, video.size, camera, auto),
            )
        what = "frames from stdin" if pipe else Path(args.video).name
        tracking = pipe if args.track is None else args.track
        how = "tracking" if tracking else "analyzing"
        bar = stack.enter_context(progress(total, f"{how} {what}", args.quiet))
        options = {} if unknowns is None else {"unknowns": unknowns}
        if auto and not pipe:
            # a file can be looked ahead in: the head is made from its most typical frame
            from vtts.analysis.anchor import choose_anchor

            again = read_video(args.video, fps=args.fps)
            options["anchor"] = choose_anchor(again.frames(), again.fps, again.n_frames,
                                              step=args.step)  # fmt: skip
        tracked = track(
            video.frames(),
            fps=video.fps,
            model=model,
            model_path=Path(staging) / fitted[0].name if auto else None,
            camera=camera,
            face=args.face,
            step=args.step,
            progress=lambda _index: bar.advance(),
            on_estimate=sink,
            tracking=tracking,
            **options,
        )
        analysis = tracked.analysis
        textured = 0  # the frames the fitted head's texture is the mean of
        if auto and not pipe and sink is None and args.texture != "anchor":
            from vtts.analysis.texture import retexture

            video = read_video(args.video, fps=args.fps)  # again: the frames were not kept
            tracked.model = retexture(tracked, video.frames(), video.size)
            textured = sum(not np.isnan(fe.psnr) for fe in analysis.frames)
        stream = analysis.stream(name, fapu=tracked.model.fapu)
        steps = None
        if sink is None and (fbs or tmp_fbs is not None) and args.steps == "face":
            from vtts.analysis.steps import analysis_steps

            steps = analysis_steps(analysis, tracked.model, video.size)
        if sink is not None:
            sink.end()
        elif fbs:
            tmp_out.write_bytes(_encode_fbs(stream, args.rate, steps))
        else:
            with warnings.catch_warnings():  # the summary says where the translation went
                warnings.simplefilter("ignore", VttsWarning)
                tmp_out.write_text(format_fap(stream), encoding="utf-8")
        if tmp_fbs is not None:
            tmp_fbs.write_bytes(_encode_fbs(stream, args.rate, steps))
        if args.report:
            write_report(analysis, args.report)
            video = read_video(args.video, fps=args.fps)  # again: the frames were not kept
            write_side_by_side(args.report, video.frames(), analysis, tracked.model)
        if sink is None:
            place_fitted()
    if not args.quiet:
        written = [str(p) for p in (None if args.stream_out else out, extra_fbs) if p]
        if args.stream_out:
            per_frame = 1000 * sink.framing_s / max(sink.frames, 1)
            written.insert(
                0,
                f"the stream to stdout ({sink.bytes_written} bytes; coding and writing "
                f"{per_frame:.2f} ms a frame)",
            )
        if fitted:
            texture = f": what {textured} frames show" if textured else ""
            written.append(f"the fitted head {fitted[0]} (+ .adt, -face.png, -frame.png{texture})")
        if args.report:
            written.append(f"report in {args.report}")
        n = len(analysis.frames)
        restarts = len(tracked.restarts)
        held = f", {len(tracked.held)} held (no estimate)" if tracked.held else ""
        print(
            f"wrote {', '.join(written)}: {n} frame{'s' if n != 1 else ''} at "
            f"{analysis.fps:g} fps, {len(analysis.unknowns)} unknowns, "
            f"{'tracking' if tracking else 'accurate'} mode, "
            f"mean face PSNR {mean_psnr(analysis.psnr()):.2f} dB, "
            f"{restarts} re-initialization{'s' if restarts != 1 else ''}{held}",
            file=say,
        )
        translation = any(isinstance(u, str) for u in analysis.unknowns)
        if not args.stream_out and not fbs and not extra_fbs and translation:
            print("note: a .fap file cannot carry the head translation; -o OUT.fbs or --fbs does")
    return 0


def _check_analyze_stream(args: argparse.Namespace, pipe: bool, auto: bool) -> None:
    """The rules of ``vtts analyze -`` (raw frames on stdin) and ``--stream`` (a streamed .fbs
    on stdout)."""
    from vtts.errors import AnalysisError

    if pipe and args.size is None:
        raise AnalysisError(
            "raw frames on stdin (VIDEO -) have no size of their own: give --size WIDTHxHEIGHT"
        )
    if not pipe and args.size is not None:
        raise AnalysisError(
            "--size is the size of raw frames on stdin (VIDEO -): a video file or PNG folder "
            "states its own"
        )
    if pipe and args.report:
        raise AnalysisError(
            "--report draws side-by-side.mp4 from the video's frames again, which a pipe cannot "
            "give back: save the frames to a file and analyze that for a report"
        )
    if args.stream_out and args.output:
        raise AnalysisError(
            "--stream writes the bitstream to stdout: give no -o (save it with > OUT.fbs)"
        )
    if not args.stream_out and not args.output:
        raise AnalysisError("nothing to write: give -o OUT.fap (or OUT.fbs), or --stream")
    if args.stream_out and (args.fbs or args.rate is not None):
        raise AnalysisError("--fbs and --rate go with -o: --stream codes every estimate as made")
    if args.stream_out and auto and not args.model_out:
        raise AnalysisError(
            "--stream with --model auto needs --model-out HEAD.wrl: the fitted head a reader "
            "of the stream loads (stdout has no name to derive it from)"
        )
    if args.texture == "mean" and not auto:
        raise AnalysisError("--texture chooses the texture of the head --model auto fits")
    if args.texture == "mean" and (pipe or args.stream_out):
        raise AnalysisError(
            "--texture mean needs the whole video before the head is written: frames on stdin "
            "and --stream keep the texture of the frame the head was fitted to"
        )
    if args.model_out is not None:
        if not auto:
            raise AnalysisError("--model-out names the fitted head of --model auto")
        if Path(args.model_out).suffix.lower() != ".wrl":
            raise AnalysisError("--model-out names a .wrl file", file=args.model_out)


def _fitted_paths(out: Path) -> list[Path]:
    """The files of the head ``vtts analyze --model auto`` fits, beside ``OUT``:
    ``OUT-model.wrl``, ``OUT-model.adt``, ``OUT-model-face.png`` (the atlas) and
    ``OUT-model-frame.png`` (the first frame, the texture of what it shows)."""
    wrl = out.with_name(f"{out.stem}-model.wrl")
    return [wrl, wrl.with_suffix(".adt"), wrl.with_name(f"{wrl.stem}-face.png"),
            wrl.with_name(f"{wrl.stem}-frame.png")]  # fmt: skip


def _fitted_model_paths(wrl: Path) -> list[Path]:
    """The files of a fitted head written as ``wrl`` (``--model-out``): ``HEAD.wrl``,
    ``HEAD.adt``, ``HEAD-face.png``, ``HEAD-frame.png``."""
    return [wrl, wrl.with_suffix(".adt"), wrl.with_name(f"{wrl.stem}-face.png"),
            wrl.with_name(f"{wrl.stem}-frame.png")]  # fmt: skip


def _check_writable(path: Path) -> None:
    """Fail now, with a clear message, when ``path`` could not be created later (a file where a
    folder must be, a folder without write permission)."""
    from vtts.errors import AnalysisError

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


def _stream_name(video: str) -> str:
    """The name in the header of the estimated stream: the video's name as one word."""
    import re

    if video == "-":
        return "stdin"
    return re.sub(r"\s+", "_", Path(video).stem.strip()).lstrip("#") or "vtts_analyze"


def _first_steps(model, first, unknowns, size: tuple[int, int], camera, fitted: bool) -> dict:
    """The coder's base steps of a ``--stream`` (:func:`vtts.analysis.steps.coding_steps`),
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


def _encode_fbs(stream, rate: float | None = None, steps: dict | None = None) -> bytes:
    """``stream`` coded as ``vtts encode`` codes it by default (at ``rate`` Hz if given), with
    the base ``steps`` of :func:`vtts.analysis.steps.analysis_steps` if given."""
    from vtts.fap.coding import encode

    return encode(stream, rate=rate, steps=steps)


def cmd_voices(args: argparse.Namespace) -> int:
    """List espeak-ng's voices."""
    from vtts.speech.tts import voices

    found = voices(args.language)
    if not found:
        print(
            f"error: espeak-ng has no voice for language '{args.language}' "
            "(vtts voices lists them all)",
            file=sys.stderr,
        )
        return 1
    for v in found:
        print(f"{v.name:24s} {v.language:8s} {v.identifier}")
    return 0


def cmd_models(args: argparse.Namespace) -> int:
    """List the bundled models."""
    from vtts.face import bundled_models, load_model

    names = bundled_models()
    if not names:
        print("no bundled models")
        return 0
    for name in names:
        try:
            m = load_model(name)
        except VttsError as e:
            print(f"{name:12s} broken: {e.message}")
            continue
        print(
            f"{name:12s} {len(m.tables.adts):3d} MIAPs {m.scene.triangle_count():7d} triangles  "
            f"{m.path}"
        )
    return 0


def cmd_batch(args: argparse.Namespace) -> int:
    """Run the say/play/render jobs of a .jsonl file on Ray workers (:func:`vtts.batch.run`),
    or with --dry-run only check every line."""
    from vtts.batch import read_jobs, run
    from vtts.batch.jobs import JobError, preflight

    if args.dry_run:
        checked = read_jobs(args.jobs, args.out)
        models: dict = {}
        for job in list(checked.jobs):
            try:
                preflight(job, models)
            except JobError as e:
                e.file, e.line = args.jobs, job.line
                checked.errors.append(e)
                checked.jobs.remove(job)
        for e in sorted(checked.errors, key=lambda e: e.line or 0):
            print_error(e)
        n = len(checked.jobs)
        print(f"{args.jobs}: {n} valid job{'s' if n != 1 else ''}, {len(checked.errors)} bad")
        return 1 if checked.errors else 0
    report = run(args.jobs, args.out, args.workers, args.address, show_progress=True)
    print(f"batch: {report.summary()}")
    return 0 if report.ok else 1


def _miap_of(key: str):
    from vtts.face import Miap

    return Miap.parse(key)


# ---- argument parsing ----------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="vtts",
        description="MPEG-4 face animation: talking heads, FAP playback, analysis and coding.",
    )
    p.add_argument("--version", action="version", version=f"vtts {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    c = sub.add_parser("check", help="validate .wrl, .adt, .fap and .fbs files")
    c.add_argument("files", nargs="+", metavar="FILE")
    c.add_argument(
        "--lenient",
        action="store_true",
        help="load VRML that other browsers accept (unknown nodes and fields, misplaced nodes, "
        "X3D statements, urls out of the folder), each with a warning",
    )
    _url_root_flag(c)
    c.set_defaults(func=cmd_check)

    i = sub.add_parser(
        "info", help="describe a scene graph and what a model can do, or a .fbs bitstream"
    )
    i.add_argument("file", metavar="FILE")
    i.add_argument(
        "--lenient",
        action="store_true",
        help="load VRML that other browsers accept (unknown nodes and fields, misplaced nodes, "
        "X3D statements, urls out of the folder), each with a warning",
    )
    _url_root_flag(i)
    i.set_defaults(func=cmd_info)
    po = sub.add_parser("pose", help="write a model posed by FAPs, visemes and expressions")
    po.add_argument("--model", required=True, help="bundled model name or .wrl path")
    _url_root_flag(po)
    _pose_flags(po)
    po.add_argument("-o", "--output", required=True, help="output .wrl")
    po.set_defaults(func=cmd_pose)

    r = sub.add_parser("render", help="render one pose to a PNG")
    _models_flag(r)
    _pose_flags(r)
    _view_flags(r)
    r.add_argument("-o", "--output", required=True, help="output .png")
    r.set_defaults(func=cmd_render)

    pl = sub.add_parser("play", help="play a FAP stream on one or more models")
    pl.add_argument(
        "stream",
        help="a .fap file or a coded .fbs stream; - reads a .fbs (streamed by vtts analyze "
        "--stream) from stdin and renders each frame as it arrives",
    )
    _models_flag(pl)
    pl.add_argument(
        "--audio", help="sound to mux into the MP4 and --web (WAV, FLAC, OGG, MP3, M4A …)"
    )
    pl.add_argument(
        "--fps",
        type=float,
        help="output frame rate (default 30; a stream from stdin plays at its own)",
    )
    pl.add_argument("--png-dir", help="also (or only) write lossless PNG frames into this folder")
    pl.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    _curves_flags(pl)
    _web_flag(pl)
    _view_flags(pl)
    _detail_flag(pl)
    pl.add_argument(
        "-o",
        "--output",
        help="output .mp4, or an animated .glb/.gltf; with a stream from stdin, - writes raw "
        "rgb24 frames of --size to stdout (ffplay -f rawvideo -pixel_format rgb24 ...)",
    )
    pl.set_defaults(func=cmd_play, gltf=None)

    ms = sub.add_parser("models", help="list the bundled models")
    ms.set_defaults(func=cmd_models)

    sy = sub.add_parser("say", help="speak text with bookmarks: a talking-head video")
    sy.add_argument(
        "text",
        nargs="?",
        default="",
        help='text with bookmarks, e.g. "Hello <smile 2s> world <blink>"',
    )
    sy.add_argument(
        "--text",
        dest="text_option",
        metavar="TEXT",
        help="the text, as an option (the same as giving it first; e.g. with --audio REC)",
    )
    sy.add_argument("--file", help="read the text from a file instead")
    _models_flag(sy)
    sy.add_argument(
        "--engine",
        choices=("espeak", "festival"),
        default="espeak",
        help="speech synthesizer: espeak-ng (default) or festival's HTS voice "
        "(Debian festival, festvox-us-slt-hts)",
    )
    sy.add_argument(
        "--voice",
        help="espeak-ng voice (default en-us; see vtts voices), or with --engine festival a "
        "festival voice (default cmu_us_slt_arctic_hts)",
    )
    sy.add_argument("--rate", type=int, help="speaking rate in words per minute")
    sy.add_argument("--pitch", type=int, help="pitch 0-99")
    sy.add_argument(
        "--phonemes",
        help="timings from another engine: Polly speech marks or a "
        "'start end phoneme' table (needs --audio)",
    )
    sy.add_argument(
        "--audio",
        help="recorded speech of the text (WAV, FLAC, OGG, MP3, M4A …): the text is aligned to "
        "it, or with --phonemes, the speech they describe",
    )
    sy.add_argument("--seed", type=_seed, default=0, help="seed of the autonomous behaviour")
    sy.add_argument(
        "--no-autonomous",
        action="store_true",
        help="no autonomous blinks, nods, head motion or gaze",
    )
    sy.add_argument("--fps", type=float, default=30.0, help="frame rate (default 30)")
    sy.add_argument("--fap-out", help="also write the FAP stream (.fap)")
    sy.add_argument("--wav-out", help="also write the speech (.wav)")
    sy.add_argument(
        "--timings-out",
        help="also write the word and phone timings (.tsv: kind start end label viseme)",
    )
    _curves_flags(sy)
    sy.add_argument("--png-dir", help="also (or only) write lossless PNG frames into this folder")
    sy.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    _web_flag(sy)
    _view_flags(sy)
    _detail_flag(sy)
    sy.add_argument("-o", "--output", help="output .mp4, or an animated .glb/.gltf")
    sy.set_defaults(func=cmd_say, gltf=None)

    an = sub.add_parser(
        "analyze",
        help="estimate FAPs from a video of a face (Eisert-Girod)",
        description=(
            "Estimate FAPs and head motion from a video by analysis by synthesis: the model is "
            "rendered with the current estimate and the optical-flow constraint at every face "
            "pixel gives a linear update, over a pyramid, frame after frame."
        ),
    )
    an.add_argument(
        "video",
        metavar="VIDEO",
        help="a video file (MP4, ...), a folder of PNGs, or - for raw rgb24 frames on stdin "
        "(ffmpeg ... -f rawvideo -pix_fmt rgb24 -; with --size)",
    )
    an.add_argument(
        "--model",
        action="append",
        help="auto (default): fit a head to the video's most typical face (the first face on "
        "stdin) and write it as OUT-model.wrl; or "
        "a bundled model name or .wrl path, placed on the first face's landmarks",
    )
    _url_root_flag(an)
    an.add_argument(
        "-o", "--output", metavar="OUT.fap", help="output .fap (or coded .fbs); or --stream"
    )
    an.add_argument(
        "--stream",
        action="store_true",
        dest="stream_out",
        help="write a streamed .fbs to stdout instead of -o, each frame as soon as it is "
        "estimated (vtts play - renders it)",
    )
    an.add_argument(
        "--model-out",
        metavar="HEAD.wrl",
        help="where --model auto writes the fitted head (default OUT-model.wrl; needed with "
        "--stream), complete before the stream's header",
    )
    an.add_argument(
        "--size",
        metavar="WxH",
        help="the size of raw frames on stdin (VIDEO -), such as 176x144",
    )
    an.add_argument(
        "--face", type=int, metavar="N", help="which face to track, 1 = the largest (default)"
    )
    an.add_argument(
        "--rate",
        type=float,
        metavar="HZ",
        help="frame rate of the coded .fbs (default: the analysis rate; the paper's is 12.5)",
    )
    an.add_argument(
        "--steps",
        choices=("face", "mpeg4"),
        default="face",
        help="base steps of the coded .fbs: face (default) spends the bits where the face's "
        "image shows them (measured on the model at the median pose, a --stream's at its "
        "first estimate: about a third fewer bits for the same face); mpeg4: the standard's",
    )
    an.add_argument(
        "--faps",
        metavar="LIST",
        help="what to estimate: FAP numbers 3-68, ranges, names, tx,ty,tz (head translation) "
        "or a set (paper17, table1); default paper17",
    )
    an.add_argument(
        "--camera",
        metavar="FX,FY,X0,Y0",
        help="the video camera, Eisert-Girod Eq. 3 in pixels (default: the framing of "
        "vtts render for the video's size)",
    )
    an.add_argument("--step", type=int, default=1, metavar="N", help="analyze every N-th frame")
    mode = an.add_mutually_exclusive_group()
    mode.add_argument(
        "--track",
        action="store_true",
        default=None,
        help="the fast tracking mode: about one rendering a frame, solves on surface samples "
        "(the default for frames on stdin)",
    )
    mode.add_argument(
        "--accurate",
        dest="track",
        action="store_false",
        help="the accurate mode: each frame ends with a rendering after every solve at full "
        "size, started by solves on surface samples (the first frame: the whole pyramid); the "
        "default for a video file or folder",
    )
    an.add_argument(
        "--fps",
        type=float,
        metavar="F",
        help="frame rate of a PNG folder or of frames on stdin (default 25), or instead of a "
        "video's own",
    )
    an.add_argument(
        "--texture",
        choices=("mean", "anchor"),
        help="the fitted head's texture: mean (the default for a video file): what the tracked "
        "frames show on average; anchor: the frame it was fitted to (always for frames on "
        "stdin or --stream)",
    )
    an.add_argument(
        "--report",
        metavar="DIR",
        help="also write frames.csv, psnr.png, faps.png and side-by-side.mp4 into DIR",
    )
    an.add_argument(
        "--fbs", action="store_true", help="also write the coded bitstream beside OUT (.fbs)"
    )
    an.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    an.set_defaults(func=cmd_analyze)

    ba = sub.add_parser("batch", help="run many say/play/render jobs on Ray workers")
    ba.add_argument("jobs", metavar="JOBS.jsonl", help="one job per line (docs/batch.md)")
    ba.add_argument("--out", required=True, metavar="DIR", help="the outputs' folder")
    ba.add_argument("--workers", type=int, metavar="N", help="workers (default: one per CPU)")
    ba.add_argument("--address", help="an existing Ray cluster (default: a local one)")
    ba.add_argument("--dry-run", action="store_true", help="check every line, render nothing")
    ba.set_defaults(func=cmd_batch)

    vo = sub.add_parser("voices", help="list espeak-ng voices")
    vo.add_argument("language", nargs="?", help="only voices of this language (e.g. en)")
    vo.set_defaults(func=cmd_voices)

    from vtts.fap.cli_coding import register

    register(sub)
    return p


def _curves_flags(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--curves-out",
        metavar="FILE",
        help="also write the animation as another engine's curves (JSON, see --curves)",
    )
    p.add_argument(
        "--curves",
        metavar="FORMAT",
        help="format of --curves-out: arkit (52 blendshape weights per frame, the default), "
        "oculus (15 viseme weights per frame), azure (viseme events), talkinghead",
    )


def _models_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--model",
        action="append",
        required=True,
        help="bundled model name or .wrl path (repeat for several heads)",
    )
    _url_root_flag(p)


def _url_root_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--url-root",
        action="append",
        metavar="DIR",
        help="a folder (besides the model's own) whose files the model's urls may name, such as "
        "a shared textures/ folder (repeat for several; adds to $VTTS_URL_ROOT)",
    )


@contextlib.contextmanager
def _url_roots(args: argparse.Namespace):
    """``--url-root`` as ``$VTTS_URL_ROOT`` while the command runs: every model load sees it."""
    from vtts.vrml.parser import URL_ROOT_ENV, url_roots

    given = getattr(args, "url_root", None)
    if not given:
        yield
        return
    before = os.environ.get(URL_ROOT_ENV)
    roots = [str(r) for r in url_roots(given)] + ([before] if before else [])
    os.environ[URL_ROOT_ENV] = os.pathsep.join(roots)
    try:
        yield
    finally:
        if before is None:
            del os.environ[URL_ROOT_ENV]
        else:
            os.environ[URL_ROOT_ENV] = before


def _pose_flags(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--fap",
        action="append",
        metavar="N=V,...",
        help="FAP values in FAP units, by number or name (19=512,open_jaw=300)",
    )
    p.add_argument(
        "--viseme",
        action="append",
        metavar="V[=W]",
        help="viseme number or phoneme with an optional weight 0-1 (7 or 7=0.5)",
    )
    p.add_argument(
        "--expression",
        action="append",
        metavar="NAME[=W]",
        help="expression with an optional weight 0-1 (joy=0.8)",
    )


def _web_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--web",
        metavar="DIR",
        help="also (or only) write a web player into this folder: index.html, the animation as "
        ".glb, the audio and three.js; serve it with python -m http.server -d DIR",
    )


def _view_flags(p: argparse.ArgumentParser) -> None:
    p.add_argument("--size", default="352x288", help="WIDTHxHEIGHT in pixels (default 352x288)")
    p.add_argument(
        "--camera",
        metavar="FX,FY,X0,Y0",
        help="pinhole camera of Eisert-Girod Eq. 3 in pixels (default: frame the heads)",
    )
    p.add_argument(
        "--viewpoint",
        metavar="NAME",
        help="look through the Viewpoint DEFed as NAME in the (first) model's scene",
    )
    p.add_argument(
        "--background",
        metavar="COLOR",
        help="a color name (black, white, gray, green, blue, ...), #rrggbb or r,g,b in 0-1; "
        "or transparent: RGBA PNGs whose alpha is the heads' coverage",
    )
    p.add_argument(
        "--layout",
        choices=("row", "room"),
        default="row",
        help="several heads side by side, or side by side in a simple room",
    )


def _detail_px(text: str) -> float:
    """``--detail``'s value: a distance in pixels from 0 to 100."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0 <= value <= 100:  # NaN too
        raise argparse.ArgumentTypeError(f"a distance in pixels from 0 to 100, got {text!r}")
    return value


def _detail_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--detail",
        type=_detail_px,
        metavar="PX",
        help="draw fewer triangles where the heads' surface moves by less than PX pixels of "
        "the video (default half a pixel, vtts.render.DETAIL_PX; 0: every triangle)",
    )


#: Options (argparse ``dest`` names) that name files a command writes, which may replace no
#: input nor each other (:func:`_check_io`; ``vtts batch`` keeps them inside its folder).
OUTPUT_OPTIONS = ("output", "fap_out", "wav_out", "timings_out", "curves_out")
#: Options that name files or folders a command reads.
INPUT_OPTIONS = ("stream", "video", "audio", "file", "phonemes", "input")


def _model_files(name: str) -> list[Path]:
    """A model's ``.wrl``, its sidecar ``.adt`` and the images its urls name beside it (what an
    output must not overwrite); empty when the model is not found (loading reports that)."""
    import re

    from vtts.face import find_model

    try:
        wrl = find_model(name)
    except VttsError:
        return []
    files = [wrl, wrl.with_suffix(".adt")]
    with contextlib.suppress(OSError):
        text = wrl.read_bytes()[: 64 << 20].decode("utf-8", "replace")
        for url in set(re.findall(r'"([^"\n]{1,400}\.(?:png|jpe?g|gif|bmp))"', text, re.I)):
            files.append(wrl.parent / url)
    return files


def _check_io(args: argparse.Namespace) -> None:
    """Outputs that would replace an input, each other, a link or a device are refused before
    the command starts (:func:`vtts.atomic.check_outputs`)."""
    from vtts.atomic import check_outputs

    # "-" is stdin or stdout, not a file
    outputs = [v for k in OUTPUT_OPTIONS if (v := getattr(args, k, None)) and v != "-"]
    if not outputs:
        return
    inputs = [v for k in INPUT_OPTIONS if (v := getattr(args, k, None)) and v != "-"]
    models = getattr(args, "model", None) or []
    for m in [models] if isinstance(models, str) else models:
        inputs += _model_files(m)
    check_outputs(outputs, inputs)


#: What ``-o`` of ``say`` and ``play`` may be: video containers ffmpeg writes with H.264 and AAC,
#: or an animated glTF (binary or JSON: :data:`vtts.export.GLTF_SUFFIXES`).
VIDEO_SUFFIXES = (".mp4", ".m4v", ".mov", ".mkv")
GLTF_SUFFIXES = (".glb", ".gltf")


def _video_output(args: argparse.Namespace) -> None:
    """``say``/``play -o`` must name a video (``say -o x.png`` wrote an MP4 named .png) or a
    glTF file: then ``args.gltf`` takes it and ``args.output``, the video, is None."""
    from vtts.errors import RenderError

    out = getattr(args, "output", None)
    if not out or args.func not in (cmd_say, cmd_play):
        return
    if out == "-" and args.func is cmd_play:
        return  # raw frames on stdout (vtts play -)
    suffix = Path(out).suffix.lower()
    if suffix in GLTF_SUFFIXES:
        args.gltf, args.output = out, None
    elif suffix not in VIDEO_SUFFIXES:
        given = Path(out).suffix or "a name without a suffix"
        kinds = ", ".join(VIDEO_SUFFIXES)
        raise RenderError(
            f"-o writes a video ({kinds}) or an animated glTF (.glb, .gltf), not {given}: for "
            "frames give --png-dir DIR, for a still use vtts render",
            file=str(out),
        )


def _terminate_as_interrupt(signum, frame) -> None:
    """SIGTERM and SIGHUP end a command as Ctrl-C does: temporary files are removed and no
    output is left half-written."""
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, _terminate_as_interrupt)
    return execute(args)


def execute(args: argparse.Namespace) -> int:
    """Run the command ``args`` (from :func:`build_parser`) as ``vtts`` does: its exit status,
    with bad input printed on stderr as one clear message (``vtts batch`` runs its jobs so)."""
    if getattr(args, "command", None) not in ("say", "play"):
        _startup_done()
    try:
        with reported_warnings(), _url_roots(args):
            _check_io(args)
            _video_output(args)
            return args.func(args)
    except VttsError as e:
        print_error(e)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (``vtts check … | head``): not an error worth a traceback
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except OSError as e:
        # an output that cannot be written (permissions, a full disk, a missing folder)
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        print(f"{where}error: {e.strerror or e}", file=sys.stderr)
        return 1


#: Whether :func:`run` paused Python's cyclic garbage collector for the command's start-up.
_GC_PAUSED = False


def _startup_done() -> None:
    """The command's start-up is over: the objects it made (modules, the model, OpenGL's and
    pyrender's) are frozen out of every later collection and the collector runs again. The
    little garbage start-up leaves in cycles (about 3,000 objects in a ``vtts say``) is frozen
    with them: it stays until the command ends."""
    global _GC_PAUSED
    if _GC_PAUSED:
        _GC_PAUSED = False
        gc.freeze()
        gc.enable()


def _after_first(frames: Iterable) -> Iterator:
    """``frames``, with :func:`_startup_done` once the first one is out (it compiles the
    shaders and uploads the meshes: start-up too)."""
    first = True
    for frame in frames:
        yield frame
        if first:
            first = False
            _startup_done()


def run() -> NoReturn:
    """The ``vtts`` command: :func:`main`, then leave without the interpreter's teardown.

    Every output is complete and closed when :func:`main` returns (writers rename their files
    only when done, and wait for their encoders), so what is left at exit is the interpreter's
    own cleanup: several garbage collections over the ~90,000 objects of OpenGL, pyrender and
    the model, about a quarter of a second of ``vtts say "Hi."``. Library users calling
    :func:`main` keep the normal exit.

    The cyclic garbage collector is paused while a command starts: importing NumPy, SciPy,
    PyOpenGL and pyrender and setting up a scene makes hundreds of thousands of objects and
    almost no garbage cycles, and the collector would walk them all again and again (tens of
    milliseconds of a short ``vtts say``). ``vtts say`` and ``vtts play`` resume it after their
    first frame, every other command before it starts (:func:`_startup_done`); the frames make no
    cyclic garbage (319 frames of a say, none)."""
    global _GC_PAUSED
    gc.disable()
    _GC_PAUSED = True
    code = main()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):
            stream.flush()
    os._exit(code)


if __name__ == "__main__":  # pragma: no cover
    run()
