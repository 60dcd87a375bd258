"""Talking photos (``--background photo``): a fitted head drawn into the photo it was fitted
to, and the photo around it following its motion.

The head is rendered at the photo's own camera (its ``photo`` Viewpoint) over nothing
(``background="transparent"``); where it covers the picture it is drawn, with a soft edge
(:attr:`TalkingPhotoOptions.feather`), the mouth's inside included (the model's teeth, tongue and
cavity). The parts the photo shows better than a model can — the hair, the ears, the neck, the
eyes' corners (:data:`PHOTO_SHOWN`) — are posed but not drawn: there the photo itself shows,
warped by a smooth 2-D mesh warp (:class:`~vtts.render.photo_warp.PhotoWarp`) whose handles are
the head's visible vertices (:data:`HANDLES`: the face's), projected at rest and in each frame,
fading out with the distance from the head. Only the person is warped (the photo
segmented once, by :attr:`TalkingPhotoOptions.segment`): the person is a layer over the
photo's background, which never moves and is filled in behind the person where a move reveals
it (:attr:`TalkingPhotoOptions.segment`). Far from the head the photo's pixels stay as they
are; a nod carries the hair and collar with it and stretches the picture smoothly
(the warp is continuous and kept fold-free), never tearing it. This is the "bring a portrait to
life" setting (Averbuch-Elor et al. 2017, who warp a portrait by a driving video in 2-D and add
the mouth), driven here by any FAP stream: text, voice or a video's analysis.

>>> from vtts.render.talking_photo import TalkingPhoto
>>> with TalkingPhoto(model) as tp:                   # the model's recorded photo, its size
...     frame = tp.render(model.params(visemes={10: 1.0}))   # (H, W, 3) uint8
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter

from vtts.errors import RenderError
from vtts.face import FaceModel
from vtts.render.photo_warp import PhotoWarp, WarpOptions

#: The parts the photo shows rather than the model: posed (their vertices drive the warp) but not
#: drawn. A fitted head's hair cap is skin-tight, its ears generic and its neck the bundled one;
#: its eye sockets (the generic cavity behind the eyeballs) show through the corners of the
#: lids as pink specks, even at the photo's own view, where the photo shows the eye's corners.
PHOTO_SHOWN = ("HAIR", "NECK", "L_EAR", "R_EAR", "SOCKETS")
#: The parts whose visible vertices are the warp's handles: the face (the jaw's motion stretches
#: the throat below the chin; the spline's affine part carries the face's motion on to the hair
#: and ears around it). The skull's parts are not among them: the tracked face is where a head's
#: motion is known best, and the generic skull's top, turned about the generic neck, dragged the
#: photo further than the person's hair moved (bench_reenact, docs/rendering.md). Nor is the
#: neck: a head turns and nods on it, and the shoulders stay.
HANDLES = ("FACE",)
#: The Viewpoint of a fitted head's photo (``adi fit``'s).
PHOTO_VIEWPOINT = "photo"


@dataclass(frozen=True)
class TalkingPhotoOptions:
    """How a head is drawn into its photo.

    ``warp``: how the photo around the head follows it (:class:`WarpOptions`); ``hidden``: the
    parts the photo shows instead of the model (:data:`PHOTO_SHOWN`); ``handles``: the parts
    whose motion the photo follows (:data:`HANDLES`); ``feather``: the width (pixels, a
    Gaussian's sigma) of the drawn head's soft edge (None: a 300th of the smaller side, at least
    0.75; 0: a hard edge); ``segment``: the photo's person probability, ``(H, W, 3) uint8 ->
    (H, W) float32`` in 0–1 (the commands give :func:`vtts.fit.segment.person_probability`): the
    person is warped, never the background behind it (None: the whole photo as one layer)."""

    warp: WarpOptions = field(default_factory=WarpOptions)
    hidden: tuple[str, ...] = PHOTO_SHOWN
    handles: tuple[str, ...] = HANDLES
    feather: float | None = None
    segment: Callable[[np.ndarray], np.ndarray] | None = None

    def __post_init__(self) -> None:
        if self.feather is not None and not (
            isinstance(self.feather, int | float) and 0 <= self.feather <= 50
        ):
            raise RenderError(f"the feather is a width of 0–50 pixels, got {self.feather!r}")
        if not self.handles:
            raise RenderError("the warp needs at least one part as its handles")


class TalkingPhoto:
    """``model`` (a fitted head) drawn into ``photo`` (``(H, W, 3) uint8``; None: the photo the
    model records, :func:`vtts.face.source_photo.source_photo`) at the model's ``viewpoint``.

    ``size`` (W, H): the frames' size (None: the photo's; another size must keep the photo's
    shape, and the photo is resampled to it); ``supersample`` and ``detail`` as
    :class:`~vtts.render.FaceRenderer` takes them. The renderer's interface: :meth:`render`,
    :meth:`frames`, :meth:`model_matrix`, :attr:`size`, a context manager. Frames are ``(H, W,
    3) uint8``."""

    def __init__(
        self,
        model: FaceModel,
        *,
        photo: np.ndarray | None = None,
        size: tuple[int, int] | None = None,
        viewpoint: str = PHOTO_VIEWPOINT,
        supersample: int = 1,
        detail: float | None = None,
        options: TalkingPhotoOptions | None = None,
    ) -> None:
        from vtts.render import FaceRenderer

        if isinstance(model, list | tuple):
            if len(model) != 1:
                raise RenderError(
                    f"--background photo draws one head into its photo, got {len(model)} models"
                )
            model = model[0]
        self.options = options or TalkingPhotoOptions()
        if photo is None:
            from vtts.face.source_photo import source_photo

            photo = source_photo(model)
        photo = _fit_photo(np.asarray(photo), size)
        h, w = photo.shape[:2]
        self.model = model
        self.renderer = FaceRenderer(model, size=(w, h), viewpoint=viewpoint,
                                     background="transparent", supersample=supersample,
                                     detail=detail, hidden=self.options.hidden)  # fmt: skip
        self.size = self.renderer.size
        self.photo = photo
        self.renderer.pose(model.params())
        rest, depth = self._projected(with_depth=True)
        person = None
        if self.options.segment is not None:
            person = self.options.segment(photo)
        self.warp = PhotoWarp(photo, rest, depth, self.options.warp, person)
        f = self.options.feather
        self.feather = max(0.75, min(w, h) / 300) if f is None else float(f)

    # ---- the renderer's interface -------------------------------------------------------------

    @property
    def camera(self):
        return self.renderer.camera

    def model_matrix(self, index: int = 0) -> np.ndarray:
        return self.renderer.model_matrix(index)

    def render(self, params=None, poses: list | None = None, *, roots: list | None = None):
        """The frame ``(H, W, 3) uint8`` for ``params`` (as :meth:`FaceRenderer.render` takes
        them; None: as last posed)."""
        return self.compose(self.renderer.render(params, poses, roots=roots))

    def frames(self, params: Iterable, roots: Iterable | None = None, *,
               batch: int | None = None) -> Iterator[np.ndarray]:  # fmt: skip
        """One frame per item of ``params`` (see :meth:`FaceRenderer.frames`)."""
        options = {} if batch is None else {"batch": batch}
        for rgba in self.renderer.frames(params, roots, **options):
            yield self.compose(rgba)

    def close(self) -> None:
        self.renderer.close()

    def __enter__(self) -> TalkingPhoto:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- the picture --------------------------------------------------------------------------

    def compose(self, rgba: np.ndarray) -> np.ndarray:
        """The head as last posed, rendered as ``rgba`` ``(H, W, 4) uint8`` over nothing, drawn
        into the photo warped to its pose: ``(H, W, 3) uint8``."""
        alpha = rgba[..., 3].astype(np.float32) / 255.0
        if self.feather > 0:
            alpha = np.minimum(alpha, gaussian_filter(alpha, self.feather))
        back = self.warp(self._projected(), needed=alpha < 1)
        a = alpha[..., None]
        out = rgba[..., :3].astype(np.float32) * a + back.astype(np.float32) * (1 - a)
        return np.clip(np.round(out), 0, 255).astype(np.uint8)

    def _projected(self, with_depth: bool = False):
        """The handles' vertices as last posed, projected: ``(n, 2)`` pixels (and ``(n,)``
        depth from the camera)."""
        parts = [p for p in self.options.handles if p in self.model.scene.defs]
        if not parts:
            raise RenderError(
                f"{self.model.name} has none of the parts the photo follows "
                f"({', '.join(self.options.handles)}): not a fitted head"
            )
        points = np.concatenate([self.renderer.world_points(p) for p in parts])
        cam = self.renderer.camera
        xy = cam.project(points)
        if not with_depth:
            return xy
        view = np.linalg.inv(cam.pose)
        depth = -(points @ view[2, :3] + view[2, 3])
        return xy, depth


def _fit_photo(photo: np.ndarray, size: Sequence[int] | None) -> np.ndarray:
    """The photo at ``size`` (W, H): as it is, or resampled when ``size`` has its shape (within
    a pixel); else an error."""
    if photo.ndim != 3 or photo.shape[2] < 3 or photo.dtype != np.uint8:
        raise RenderError(f"the photo must be (H, W, 3) uint8, got {photo.shape} {photo.dtype}")
    photo = np.ascontiguousarray(photo[..., :3])
    h, w = photo.shape[:2]
    if size is None or tuple(size) == (w, h):
        return photo
    sw, sh = (int(v) for v in size)
    if abs(sw * h / w - sh) > 1.0:
        raise RenderError(
            f"--size {sw}x{sh} does not have the photo's shape ({w}x{h}): give --size {w}x{h}, "
            f"or a size in the same proportion (or no --size)"
        )
    from PIL import Image

    return np.asarray(Image.fromarray(photo).resize((sw, sh), Image.Resampling.LANCZOS))
