"""Option pieces the commands share, each checked once: the heads (:class:`Heads`), a pose of
FAPs, visemes and expressions (:class:`PoseRequest`), the view of a rendering (:class:`View`),
another engine's curves (:class:`Curves`); the readers of option strings (:func:`parse_size`,
:func:`parse_assignments`); and which options name what a command writes and reads
(:func:`check_io`).

An options class is a dataclass whose ``__post_init__`` checks it: a bad value raises the
:class:`~vtts.errors.VttsError` subclass the command reports, naming the value and the rule.
Field names are the command line's option names (``png_dir`` is ``--png-dir``).
"""

from __future__ import annotations

import contextlib
import math
import os
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from vtts.errors import FapError, RenderError, VttsError

#: What ``-o`` of ``say`` and ``play`` may be: video containers ffmpeg writes with H.264 and AAC,
#: or an animated glTF (binary or JSON: :data:`vtts.export.GLTF_SUFFIXES`).
VIDEO_SUFFIXES = (".mp4", ".m4v", ".mov", ".mkv")
GLTF_SUFFIXES = (".glb", ".gltf")
#: Options that name files a command writes, which may replace no input nor each other
#: (:func:`check_io`; ``vtts batch`` keeps them inside its folder).
OUTPUT_OPTIONS = ("output", "fap_out", "wav_out", "timings_out", "curves_out")
#: Options that name folders a command writes (``out``: ``vtts batch``'s), and another file
#: (``analyze``'s fitted head).
OUTPUT_FOLDERS = ("png_dir", "web", "report", "out")
MORE_OUTPUTS = ("model_out",)
#: Options that name files or folders a command reads.
INPUT_OPTIONS = ("stream", "video", "audio", "file", "phonemes", "input")
#: The layouts of several heads: side by side, or side by side in a simple room.
LAYOUTS = ("row", "room")
#: The frame size (WIDTHxHEIGHT, pixels) when none is given.
DEFAULT_SIZE = "352x288"
#: The highest ``seed`` (numpy's generators take no negative seed).
MAX_SEED = 2**63 - 1


def parse_size(text: str) -> tuple[int, int]:
    """``"352x288"`` → ``(352, 288)``: a frame size in pixels, (width, height)."""
    # ASCII digits ('²'.isdigit() is true), few enough for int() (it refuses 4,300)
    m = re.fullmatch(r"([0-9]{1,18})x([0-9]{1,18})", text.lower())
    if not m:
        raise RenderError(f"--size takes WIDTHxHEIGHT in pixels, such as 352x288; got {text!r}")
    return int(m[1]), int(m[2])


def parse_assignments(
    text: str, what: str, default: float | None = None, *, bounds: tuple[float, float] | None = None
) -> dict[str, float]:
    """``"19=512,open_jaw=300"`` → ``{"19": 512.0, "open_jaw": 300.0}``.

    Without ``=VALUE`` an item takes ``default`` (an error when None). Values must be finite and,
    with ``bounds`` (lo, hi), within them."""
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


def check_seed(seed: int) -> int:
    """A seed of the autonomous behaviour: a whole number 0 to 2**63 - 1."""
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise RenderError(f"--seed must be a whole number, got {seed!r}")
    if not 0 <= seed <= MAX_SEED:
        raise RenderError(f"--seed {seed} must be within 0 to 2**63 - 1")
    return seed


def check_number(
    value: float | None, name: str, lo: float, hi: float, error: type[VttsError] = RenderError
) -> None:
    """``value`` (None: not given) is a number within ``lo`` < value ≤ ``hi``; else ``error``
    naming the option ``name``."""
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise error(f"{name} must be a number, got {value!r}")
    if not lo < value <= hi:  # NaN too
        raise error(f"{name} must be within {lo:g}–{hi:g}, got {value:g}")


def check_choice(
    value: str, name: str, choices: Sequence[str], error: type[VttsError] = RenderError
) -> None:
    """``value`` is one of ``choices``; else ``error`` naming the option ``name``."""
    if value not in choices:
        raise error(f"{name} must be one of {', '.join(choices)}, got {value!r}")


def as_list(value: str | Sequence[str] | None) -> list[str]:
    """An option that may be repeated, as a list: one string is a list of one."""
    if value is None:
        return []
    if isinstance(value, str | os.PathLike):
        return [os.fspath(value)]
    return [os.fspath(v) for v in value]


@dataclass(kw_only=True)
class Heads:
    """The heads a command animates.

    ``model``: bundled model names or ``.wrl`` paths (one string for one head);
    ``url_root``: folders, besides each model's own, whose files the models' urls may name
    (added to ``$VTTS_URL_ROOT`` while the command runs).
    """

    model: list[str] = field(default_factory=list)
    url_root: list[str] | None = None

    def __post_init__(self) -> None:
        self.model = as_list(self.model)
        self.url_root = as_list(self.url_root) or None

    def require_model(self) -> None:
        """At least one model is given (checked after the values, as a parser would)."""
        if not self.model:
            raise VttsError("no model: give one or more (bundled model names or .wrl paths)")


@dataclass(kw_only=True)
class PoseRequest:
    """A pose: ``fap`` (``"19=512,open_jaw=300"``, in FAP units), ``viseme`` (``"7"`` or
    ``"7=0.5"``, weights 0–1) and ``expression`` (``"joy=0.8"``), each a string or a list of
    them as the repeated options give them."""

    fap: list[str] | None = None
    viseme: list[str] | None = None
    expression: list[str] | None = None

    def __post_init__(self) -> None:
        self.fap = as_list(self.fap) or None
        self.viseme = as_list(self.viseme) or None
        self.expression = as_list(self.expression) or None

    def pose_values(self) -> tuple[dict[str, float], dict[str, float], dict[str, float]]:
        """(faps, visemes, expressions) by name or number: raises :class:`FapError` for a bad
        item."""
        from vtts.limits import MAX_FAP_VALUE

        faps: dict[str, float] = {}
        visemes: dict[str, float] = {}
        expressions: dict[str, float] = {}
        for text in self.fap or []:
            faps.update(parse_assignments(text, "FAP", bounds=(-MAX_FAP_VALUE, MAX_FAP_VALUE)))
        for text in self.viseme or []:
            visemes.update(parse_assignments(text, "viseme", default=1.0, bounds=(0.0, 1.0)))
        for text in self.expression or []:
            expressions.update(
                parse_assignments(text, "expression", default=1.0, bounds=(0.0, 1.0))
            )
        return faps, visemes, expressions


@dataclass(kw_only=True)
class View:
    """How the heads are seen.

    ``size``: ``"WIDTHxHEIGHT"`` in pixels (None: :data:`DEFAULT_SIZE`, or with ``background``
    ``photo`` the photo's); ``camera``: a pinhole camera ``"FX,FY,X0,Y0"`` of Eisert–Girod Eq. 3
    in pixels (None: frame the heads); ``viewpoint``: the Viewpoint DEFed so in the first
    model's scene; ``background``: a color name, ``#rrggbb``, ``r,g,b`` in 0–1,
    ``transparent``, or ``photo`` — a fitted head drawn into the photo it was fitted to, seen
    through its ``photo`` Viewpoint (:mod:`vtts.render.talking_photo`; ``photo`` below) — (None:
    the renderer's); ``layout``: ``row`` or ``room``; ``detail``: draw fewer triangles where the
    surface moves by less than this many pixels (0: every triangle; None:
    :data:`vtts.render.DETAIL_PX`).
    """

    size: str | None = None
    camera: str | None = None
    viewpoint: str | None = None
    background: str | None = None
    layout: str = "row"
    detail: float | None = None

    def check_view(self, video: bool) -> None:
        """The view's values; ``video``: whether an MP4 is written (H.264 has no alpha, so no
        ``transparent``)."""
        self.background_color(video)
        self.frame_size()  # here, not at the first frame: a batch's dry run checks it too
        check_choice(self.layout, "--layout", LAYOUTS)
        if self.detail is not None and not 0 <= self.detail <= 100:  # NaN too
            raise RenderError(f"--detail is a distance in pixels from 0 to 100, got {self.detail}")
        if self.talking_photo():
            self._check_photo_view()

    def talking_photo(self) -> bool:
        """Whether the heads are drawn into their photo (``background`` ``photo``)."""
        from vtts.render.color import is_photo

        return is_photo(self.background)

    def _check_photo_view(self) -> None:
        """A photo is seen from its own camera, with one head in it."""
        from vtts.render.talking_photo import PHOTO_VIEWPOINT

        if self.camera:
            raise RenderError(
                "--background photo sees the head through its photo's camera: give no --camera "
                f"(--viewpoint {PHOTO_VIEWPOINT} is the photo's)"
            )
        if self.viewpoint not in (None, PHOTO_VIEWPOINT):
            raise RenderError(
                f"--background photo draws the head into its photo, seen from where the photo "
                f"was taken: --viewpoint {PHOTO_VIEWPOINT} (or none), not {self.viewpoint!r}"
            )
        if self.layout != "row":
            raise RenderError("--background photo draws one head into its photo: no --layout room")

    def background_color(self, video: bool = False):
        """The background as the renderer takes it (None: not given; ``"photo"`` for a talking
        photo)."""
        from vtts.render.color import PHOTO, TRANSPARENT, parse_background

        if self.background is None:
            return None
        if self.talking_photo():
            return PHOTO
        background = parse_background(self.background)
        if background == TRANSPARENT and video:
            raise RenderError(
                "--background transparent needs PNG output: an MP4 (H.264) has no alpha channel; "
                "write the frames with --png-dir alone"
            )
        return background

    def frame_size(self) -> tuple[int, int]:
        """(width, height) in pixels, within what a renderer can draw (:data:`DEFAULT_SIZE`
        when not given)."""
        from vtts.render.renderer import check_size

        return check_size(parse_size(self.size or DEFAULT_SIZE))

    def pinhole(self):
        """The :class:`vtts.render.Camera` of ``camera``, or None."""
        from vtts.render import Camera

        return Camera.parse(self.camera) if self.camera else None

    def detail_px(self) -> float:
        """The renderer's ``detail`` in pixels."""
        if self.detail is None:
            from vtts.render import DETAIL_PX

            return DETAIL_PX
        return self.detail

    def renderer(self, models, supersample: int = 1, video: bool = False):
        """A :class:`vtts.render.FaceRenderer` of ``models`` seen so, as a context manager
        (kept between the jobs of ``vtts batch``: :func:`vtts.warm.renderer`); a
        :class:`~vtts.render.talking_photo.TalkingPhoto` for ``background`` ``photo``."""
        from vtts import warm

        if self.camera and self.viewpoint:
            raise RenderError("--camera and --viewpoint both choose the camera: give one of them")
        if self.talking_photo():
            from vtts.fit.segment import person_probability
            from vtts.render.talking_photo import PHOTO_VIEWPOINT, TalkingPhoto, TalkingPhotoOptions

            self._check_photo_view()
            return TalkingPhoto(
                models,
                options=TalkingPhotoOptions(segment=person_probability),
                size=self.frame_size() if self.size else None,
                viewpoint=self.viewpoint or PHOTO_VIEWPOINT,
                supersample=supersample,
                detail=self.detail_px(),
            )
        camera = self.pinhole()
        background = self.background_color(video)
        return warm.renderer(
            models,
            size=self.frame_size(),
            camera=camera,
            viewpoint=self.viewpoint,
            layout=self.layout,
            supersample=supersample,
            detail=self.detail_px(),
            **({} if background is None else {"background": background}),
        )


@dataclass(kw_only=True)
class Curves:
    """``curves_out``: also write the animation as another engine's curves (JSON) in the
    ``curves`` format (``arkit``, the default, ``oculus``, ``azure``, ``talkinghead``:
    :mod:`vtts.avatar.curves`)."""

    curves_out: str | None = None
    curves: str | None = None

    def check_curves(self) -> None:
        """``curves`` names a format and goes with ``curves_out``."""
        from vtts.avatar.curves import DEFAULT_FORMAT, check_format
        from vtts.errors import AvatarError

        if self.curves is not None and not self.curves_out:
            raise AvatarError("--curves FORMAT says how to write --curves-out FILE: give that too")
        if self.curves_out:
            self.curves = check_format(self.curves or DEFAULT_FORMAT)


def video_or_gltf(output: str | None) -> tuple[str | None, str | None]:
    """``-o`` of ``say`` and ``play`` as (video, glTF): a video (``say -o x.png`` wrote an MP4
    named .png) or an animated glTF file; (None, None) when not given."""
    if not output:
        return None, None
    suffix = Path(output).suffix.lower()
    if suffix in GLTF_SUFFIXES:
        return None, output
    if suffix not in VIDEO_SUFFIXES:
        given = Path(output).suffix or "a name without a suffix"
        kinds = ", ".join(VIDEO_SUFFIXES)
        raise RenderError(
            f"-o writes a video ({kinds}) or an animated glTF (.glb, .gltf), not {given}: for "
            "frames give --png-dir DIR, for a still use vtts render",
            file=str(output),
        )
    return output, None


def check_web(web: str | None) -> None:
    """``web`` names a folder the web player may be written into."""
    if web:
        from vtts.export.web import check_web_folder

        check_web_folder(web)


@contextlib.contextmanager
def url_roots_set(url_root: Sequence[str] | None) -> Iterator[None]:
    """``url_root`` added to ``$VTTS_URL_ROOT`` while the command runs: every model load sees
    it."""
    from vtts.vrml.parser import URL_ROOT_ENV, url_roots

    if not url_root:
        yield
        return
    before = os.environ.get(URL_ROOT_ENV)
    roots = [str(r) for r in url_roots(url_root)] + ([before] if before else [])
    os.environ[URL_ROOT_ENV] = os.pathsep.join(roots)
    try:
        yield
    finally:
        if before is None:
            del os.environ[URL_ROOT_ENV]
        else:
            os.environ[URL_ROOT_ENV] = before


def model_files(name: str) -> list[Path]:
    """A model's ``.wrl``, its sidecar ``.adt`` and the images its urls name beside it (what an
    output must not overwrite); empty when the model is not found (loading reports that)."""
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


def check_not_stdout(options) -> None:
    """``-`` given to an option that writes a file or a folder is refused: it would make one
    named ``-`` where the user meant stdout. stdout is written by ``vtts play - -o -`` (raw
    frames of a stream from stdin; :class:`~vtts.api.play.PlayOptions` checks the rest), ``vtts
    play --audio - -o -`` (of a voice from stdin) and ``vtts analyze --stream``, nowhere else."""
    for key in (*OUTPUT_OPTIONS, *MORE_OUTPUTS, *OUTPUT_FOLDERS):
        if getattr(options, key, None) != "-":
            continue
        live = getattr(options, "stream", None) == "-" or getattr(options, "audio", None) == "-"
        if key == "output" and live and hasattr(options, "stream"):
            continue
        flag = "-o" if key == "output" else "--" + key.replace("_", "-")
        what = "a folder" if key in OUTPUT_FOLDERS else "a file"
        raise VttsError(
            f"{flag} -: this option writes {what}, and '-' would be one named '-' (stdout is "
            "for vtts play - -o -, vtts play --audio - -o - and vtts analyze --stream): give a "
            "name, ./- for one named '-'"
        )


def check_io(options) -> None:
    """Outputs of ``options`` (an options object or the command line's namespace: the
    attributes of :data:`OUTPUT_OPTIONS`) that would replace an input, each other, a link or a
    device are refused before the command starts (:func:`vtts.atomic.check_outputs`), and so
    is ``-`` where it cannot mean stdout (:func:`check_not_stdout`)."""
    from vtts.atomic import check_outputs

    check_not_stdout(options)
    # "-" is stdin or stdout, not a file
    outputs = [v for k in OUTPUT_OPTIONS if (v := getattr(options, k, None)) and v != "-"]
    folders = [v for k in ("web", "png_dir") if (v := getattr(options, k, None)) and v != "-"]
    if not outputs and not folders:
        return
    inputs = [v for k in INPUT_OPTIONS if (v := getattr(options, k, None)) and v != "-"]
    models = getattr(options, "model", None) or []
    for m in [models] if isinstance(models, str) else models:
        inputs += model_files(m)
    check_outputs(outputs, inputs)
    check_folders(folders, outputs, inputs)


def check_folders(folders: list[str], outputs: list[str], inputs: list[str | Path]) -> None:
    """The folders a command fills (``web``, ``png_dir``) hold none of its inputs (the web
    folder's files are replaced: ``--audio w/speech.m4a --web w`` would lose its audio) and none
    of its other outputs (``--web w -o w/x.mp4`` would fail after the whole render, finding
    the folder not the player's); raises :class:`VttsError` naming the path."""
    for folder in folders:
        root = Path(folder).resolve()
        for path, what in [*((p, "input") for p in inputs), *((p, "output") for p in outputs)]:
            if root in Path(path).resolve().parents:
                raise VttsError(
                    f"this {what} lies inside {folder}, the folder the command fills: give "
                    "another place for one of them",
                    file=str(path),
                )
    resolved = [Path(f).resolve() for f in folders]
    for i, a in enumerate(resolved):
        for j, b in enumerate(resolved):
            if i != j and a == b:
                raise VttsError(f"two outputs name the same folder ({folders[i]})", file=str(b))
            if i != j and a in b.parents:
                raise VttsError(
                    f"the output folders {folders[i]} and {folders[j]} overlap: give each its own",
                    file=str(folders[j]),
                )
