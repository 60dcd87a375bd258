"""``adi fit``: a personalized head from one photograph.

    photo ─► landmarks (:mod:`vtts.fit.landmarks`) ─► pose, camera and shape (:mod:`.shape`)
          ─► the whole head and its tables (:mod:`.head`) ─► the skin texture (:mod:`.texture`)
          ─► OUT.wrl + OUT.adt + OUT-face.png, with ``DEF photo Viewpoint`` (the photo's camera)

>>> from vtts.fit import fit_photo
>>> head = fit_photo(image)                       # (H, W, 3) uint8 RGB
>>> head.write("me.wrl")                          # me.wrl, me.adt, me-face.png
"""

from __future__ import annotations

import contextlib
import functools
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image

from vtts.atomic import atomic_path
from vtts.errors import FitError, VttsWarning
from vtts.face import FaceModel
from vtts.face.adt import AnimationTables, format_adt
from vtts.face.atlas import EAR_TILE
from vtts.face.source_photo import record_photo
from vtts.fit.expression import (
    SHUT_LIPS,
    beyond_face,
    close_lips,
    expression_basis,
    for_photo,
    lips_gap,
    skin_trust,
)
from vtts.fit.frame import FRAME_APPEARANCES, frame_texture, project_frame
from vtts.fit.generic import GenericHead, generic_head, landmark_map
from vtts.fit.glasses import (
    GLASSES,
    add_glasses,
    glasses_part,
    glasses_score,
    rim_mask,
    without_rims,
)
from vtts.fit.glasses import TEXTURE as GLASSES_TEXTURE
from vtts.fit.hair import HairShell, fit_hair_shell
from vtts.fit.head import (
    fitted_fapu,
    fitted_geometry,
    fitted_scene,
    matte,
    set_exposure,
    set_texture_url,
    skin_parts,
    transfer_tables,
)
from vtts.fit.landmarks import (
    LEFT_EYE,
    RIGHT_EYE,
    Face,
    LandmarkDetector,
    check_image,
    choose_face,
    detect_faces,
)
from vtts.fit.neck import NECK, collar_row, cut_neck, free_neck
from vtts.fit.segment import person_probability
from vtts.fit.shape import (
    DEFAULT_FOCAL_35MM,
    MAX_FOCAL_35MM,
    MIN_FOCAL_35MM,
    ShapeFit,
    fit_shape,
    focal_length,
)
from vtts.fit.teeth import TEETH, place_teeth, skins
from vtts.fit.texture import (
    ATLAS_SIZE,
    EAR_TILES,
    EYE_TILES,
    PAINTED_PARTS,
    PHOTO_PARTS,
    PROBE_GREY,
    TILE_PARTS,
    SkinPainter,
    depth_map,
    iris_colour,
    project_skin,
    rechart_skin,
    skin_exposure,
    skin_texels,
    split_ear_tiles,
    split_eye_tiles,
    tint_eye,
    tint_tile,
    upscale,
)
from vtts.gltf.images import srgb_to_linear
from vtts.limits import MAX_PHOTO_PIXELS
from vtts.render.camera import viewpoint_fields
from vtts.resources import models_dir
from vtts.threads import one_blas_thread
from vtts.vrml import Scene, dumps, parse

#: The Viewpoint that holds the photo's camera.
PHOTO_VIEWPOINT = "photo"
#: Smallest photo side (pixels) worth fitting: the detector needs a face of about 40 pixels.
MIN_SIZE = 64
#: Painting passes: the second aims at what the first one's rendering missed.
TEXTURE_PASSES = 3
#: How far (linear light) a pass may aim beyond the photo to undo the renderer's blur.
MAX_AIM = 0.3
#: Photos with a longer side beyond this (pixels) are fitted at this size: the renderings and
#: the texture take time with the pixels, and the texture has no use for more (the written
#: Viewpoint's field of view holds at any size of the photo).
WORK_SIZE = 1024
#: The ears, painted from a video's first frame where it shows them (each ear then gets a tile of
#: its own): what lies there in the frame — an ear, or the hair that hides it — is what the next
#: frames show there too, while a portrait's head turns later and the generic ears serve better.
EARS = ("L_EAR", "R_EAR")
#: The parts a video's first frame paints (``vtts analyze --model auto``): a portrait's, and
#: the teeth and tongue, which the next frames show again as the first did.
VIDEO_PARTS = (*PHOTO_PARTS, *(n for n in TILE_PARTS if n not in PHOTO_PARTS))
#: Whether a head made for a video (:func:`with_frame`) gets a neck that follows the head's
#: rotation only near the skull (:mod:`vtts.fit.neck`), as the person's does. Off: its gain on
#: the real sequences is no larger than the difference between two runs, since the head
#: translation, which the estimator trades against the pitch, still moves the whole neck
#: (docs/analysis.md, "Camera video"; docs/fitting.md).
FREE_NECK = False
#: Whether a head made for a video ends its neck where the frame stops showing skin below the
#: chin (a collar, a bow tie: :func:`vtts.fit.neck.collar_row`), so that the clothing is not
#: painted onto a neck that turns with the head.
CUT_NECK = True
#: Larger photos are refused (a 16k photo is 270 megapixels).
MAX_SIZE = 16384


@dataclass
class FittedHead:
    """A head fitted to a photo, ready to write.

    scene      the neutral VRML scene (fitted points, ``DEF photo Viewpoint``)
    tables     its Animation Definition Tables (the generic head's, carried over)
    texture    ``(S, S, 3) uint8`` the atlas
    shape      the :class:`~vtts.fit.shape.ShapeFit` (pose, camera, control points)
    face       the detected :class:`~vtts.fit.landmarks.Face` it was fitted to
    photo      ``(H, W, 3) uint8`` the photo as fitted (large photos are scaled down to
               :data:`WORK_SIZE`)
    faces      how many faces the photo showed
    seen       the fraction of skin texels the photo saw
    timings    seconds per step
    frame      ``(H_tex, W_tex, 3) uint8`` the photo as the texture of what it shows, for a
               head made for a video (see :func:`with_frame`), else None
    expression ``{FAP number: value}`` the photo's expression in the head's own FAPU units
               (:mod:`vtts.fit.expression`): ``model.params(head.expression)`` at the
               ``photo`` Viewpoint gives the photo back; empty for a head made for a video
    hair       the :class:`~vtts.fit.hair.HairShell` (None for a head made for a video)
    glasses    how plainly the photo shows glasses (:func:`~vtts.fit.glasses.glasses_score`;
               from :data:`~vtts.fit.glasses.GLASSES` on: glasses, with a warning), None for
               a head made for a video
    teeth      how far the upper teeth were moved up (model units, negative: down) to meet the
               teeth the photo's open mouth shows (:func:`~vtts.fit.teeth.place_teeth`), None
               where it shows none (or for a head made for a video)
    glasses_texture ``(h, w, 4) uint8`` the RGBA texture of the glasses' frame, a part of
               the head (:func:`~vtts.fit.glasses.glasses_part`), None where it has none
    """

    scene: Scene
    tables: AnimationTables
    texture: np.ndarray
    shape: ShapeFit
    face: Face
    photo: np.ndarray
    faces: int
    seen: float
    personality: str
    timings: dict[str, float] = field(default_factory=dict)
    frame: np.ndarray | None = None
    expression: dict[int, float] = field(default_factory=dict)
    hair: HairShell | None = None
    glasses: float | None = None
    teeth: float | None = None
    glasses_texture: np.ndarray | None = None

    def write(self, path: str | Path) -> list[Path]:
        """Write ``PATH.wrl`` (the scene), ``PATH.adt`` (its tables), ``PATH-face.png`` (its
        texture; ``PATH-glasses.png`` the glasses' where the head has them) and
        ``PATH-photo.png`` (the photo: :mod:`vtts.face.source_photo`) — for a head made for a
        video ``PATH-frame.png`` instead of the photo, which holds it — beside each other, each
        renamed into place only when all are written. Returns the paths."""
        wrl = Path(path)
        if wrl.suffix.lower() != ".wrl":
            raise FitError(f"the output must be a .wrl file, got {str(path)!r}")
        adt = wrl.with_suffix(".adt")
        images, pngs = self._images(wrl)
        text = dumps(self.scene)
        paths = [wrl, adt, *pngs]
        with contextlib.ExitStack() as stack:
            tmp = [stack.enter_context(atomic_path(p)) for p in paths]
            tmp[0].write_text(text, encoding="utf-8")
            tmp[1].write_text(format_adt(self.tables), encoding="utf-8")
            for image, target in zip(images, tmp[2:], strict=True):
                # zlib level 3: a tenth of a second, a few percent larger than the default 6
                Image.fromarray(image).save(target, format="PNG", compress_level=3)
        return paths

    def written_model(self, path: str | Path) -> FaceModel:
        """The head as :func:`~vtts.face.load_model` reads it back from ``path`` once
        :meth:`write` has written it there — the same scene and tables, since the files hold
        their numbers exactly — without reading the files again."""
        model = FaceModel(self.scene, self.tables, Path(path))
        model.scene.path = Path(path)  # its textures beside it
        return model

    def model(self, folder: Path, name: str = "fitted") -> FaceModel:
        """The head as a :class:`~vtts.face.FaceModel` whose textures are written into
        ``folder``."""
        wrl = folder / f"{name}.wrl"
        images, pngs = self._images(wrl)
        for image, png in zip(images, pngs, strict=True):
            Image.fromarray(image).save(png)
        return FaceModel(self.scene, self.tables, wrl)

    def _images(self, wrl: Path) -> tuple[list[np.ndarray], list[Path]]:
        """The images written beside ``wrl`` and their files, the scene's urls pointed at them:
        the atlas, the glasses' texture where the head has them, then the frame's texture for a
        head made for a video (which holds the photo), else the photo (recorded:
        :mod:`vtts.face.source_photo`)."""
        pngs = self._set_urls(wrl)
        images = [self.texture, self.frame] if self.frame is not None else [self.texture]
        if self.glasses_texture is not None and GLASSES_TEXTURE in self.scene.defs:
            png = wrl.with_name(glasses_texture_name(wrl))
            self.scene.node(GLASSES_TEXTURE).expand().fields["url"] = [png.name]
            pngs.insert(1, png)  # after the atlas: the last is the photo (or the frame)
            images.insert(1, self.glasses_texture)
        if self.frame is None:
            pngs.append(wrl.with_name(photo_name(wrl)))
            images.append(self.photo)
        record_photo(self.scene, pngs[-1].name, self.photo.shape[1], self.photo.shape[0])
        return images, pngs

    def _set_urls(self, wrl: Path) -> list[Path]:
        """Point the scene's textures at their files beside ``wrl``; returns the files: the
        atlas, and the frame's texture for a head made for a video."""
        png = wrl.with_name(texture_name(wrl))
        set_texture_url(self.scene, png.name)
        if self.frame is None:
            return [png]
        frame_png = wrl.with_name(frame_texture_name(wrl))
        for name in FRAME_APPEARANCES:
            self.scene.node(name).expand()["texture"].expand().fields["url"] = [frame_png.name]
        return [png, frame_png]


def with_frame(head: FittedHead, neck: bool | None = None) -> FittedHead:
    """``head`` (fitted to a video's frame) made for that video, changed in place and returned:
    the parts the frame shows take the frame itself as their texture, unlit
    (:mod:`vtts.fit.frame`), so that the head rendered at the frame's view gives the frame
    back. First, with :data:`CUT_NECK`, the neck ends where the frame stops showing skin under
    the chin (:func:`vtts.fit.neck.collar_row`, :func:`vtts.fit.neck.cut_neck`); with ``neck``
    (default :data:`FREE_NECK`) the neck follows the head's rotation only near the skull
    (:func:`vtts.fit.neck.free_neck`)."""
    h, w = head.photo.shape[:2]
    if CUT_NECK and NECK in head.scene.defs:
        _cut_at_collar(head.scene, head.tables, head.shape, head.photo)
    project_frame(head.scene, head.shape.camera, (w, h))
    if FREE_NECK if neck is None else neck:
        free_neck(head.scene, head.tables)
    head.frame = frame_texture(head.photo)
    return head


def _cut_at_collar(scene: Scene, tables, shape: ShapeFit, photo: np.ndarray,
                   expression: dict[int, float] | None = None) -> None:  # fmt: skip
    """End the neck of ``scene`` where ``photo`` stops showing skin under the chin
    (:func:`vtts.fit.neck.collar_row`), the head posed in ``expression`` as in the photo."""
    drawn = _drawn(scene, tables, photo.shape[:2], (NECK, "FACE"), expression)
    row = collar_row(photo, drawn[NECK], drawn["FACE"])
    if row is not None:
        cut_neck(scene, shape.camera, row)


def _drawn(scene: Scene, tables, size: tuple[int, int], names: tuple[str, ...],
           expression: dict[int, float] | None = None) -> dict[str, np.ndarray]:  # fmt: skip
    """``{name: (H, W) bool}``: where each IndexedFaceSet of ``names`` shows in the head of
    ``scene`` drawn at its photo's view, ``size`` (H, W), in ``expression`` (the renderer's
    triangle numbers)."""
    from vtts.render import FaceRenderer

    h, w = size
    nodes = {n: scene.node(n).expand() for n in names}
    with tempfile.TemporaryDirectory(prefix="vtts-fit-") as tmp:
        folder = Path(tmp)
        Image.new("RGB", (4, 4), (128, 128, 128)).save(folder / "grey.png")
        model = FaceModel(scene, tables, folder / "probe.wrl")
        textures = scene.find("ImageTexture")
        urls = [node.fields.get("url") for node in textures]
        set_texture_url(model.scene, "grey.png")
        try:
            with FaceRenderer(model, size=(w, h), viewpoint=PHOTO_VIEWPOINT) as r:
                _, numbers = r.render(model.params(expression), triangles=True)
                sets = r.triangle_sets
        finally:
            for node, url in zip(textures, urls, strict=True):
                if url is None:
                    node.fields.pop("url", None)
                else:
                    node.fields["url"] = url
    out = {}
    for name, node in nodes.items():
        mask = np.zeros(numbers.shape, bool)
        for drawn, first, count in sets:
            if drawn is node:
                mask |= (numbers >= first) & (numbers < first + count)
        out[name] = mask
    return out


def texture_name(wrl: Path) -> str:
    return f"{wrl.stem}-face.png"


def photo_name(wrl: Path) -> str:
    """The file of the photo a head was fitted to, beside it (``adi fit``; a head made for a
    video keeps its frame in :func:`frame_texture_name`)."""
    return f"{wrl.stem}-photo.png"


def glasses_texture_name(wrl: Path) -> str:
    """The file of the glasses' RGBA texture (:mod:`vtts.fit.glasses`), beside the head."""
    return f"{wrl.stem}-glasses.png"


def frame_texture_name(wrl: Path) -> str:
    """The file of a video head's frame texture (see :func:`with_frame`)."""
    return f"{wrl.stem}-frame.png"


def load_photo(path: str | Path) -> tuple[np.ndarray, float | None]:
    """The photo as ``(H, W, 3) uint8`` RGB (EXIF orientation applied) and its 35 mm-equivalent
    focal length from EXIF, or None.

    The size is checked before the pixels are decoded (:data:`~vtts.limits.MAX_PHOTO_PIXELS`);
    a JPEG larger than the fit works at is decoded at a fraction of its size (the fit scales it
    down to :data:`WORK_SIZE` anyway). 16-bit and floating-point images are scaled to 8 bits,
    not clipped. A malformed EXIF block, or a focal length no lens has, is ignored with a
    warning."""
    p = Path(path)
    try:
        with Image.open(p) as im:
            w, h = im.size
            # before decoding: a 100-byte PNG may declare 89 million x 1, a 68 KB JPEG 13000²
            if max(w, h) > MAX_SIZE or w * h > MAX_PHOTO_PIXELS:
                raise FitError(
                    f"{p}: the photo is {w}x{h} pixels, more than the limit of {MAX_SIZE} on a "
                    f"side and {MAX_PHOTO_PIXELS} in all (vtts.limits); scale it down"
                )
            if im.format == "JPEG":
                im.draft("RGB", (WORK_SIZE, WORK_SIZE))  # at least this size, by 1/2, 1/4, 1/8
            im.load()
            exif = _exif(im, p)
            # turned here rather than by ImageOps.exif_transpose, which writes the EXIF block
            # back and fails on any tag it cannot write (struct.error): a bad tag loses only
            # itself
            orientation = exif.get(0x0112) if exif is not None else None
            turn = ORIENTATIONS.get(orientation) if isinstance(orientation, int) else None
            rgb = _rgb(im if turn is None else im.transpose(turn))
    except FileNotFoundError:
        raise FitError(f"{p}: no such file") from None
    except IsADirectoryError:
        raise FitError(f"{p}: is a folder, not a photo") from None
    except (OSError, SyntaxError, ValueError, Image.DecompressionBombError) as e:
        raise FitError(f"{p}: not a readable image ({e})") from None
    return rgb, _exif_focal(exif, p)


#: EXIF Orientation → the turn that shows the photo upright.
ORIENTATIONS = {
    2: Image.Transpose.FLIP_LEFT_RIGHT,
    3: Image.Transpose.ROTATE_180,
    4: Image.Transpose.FLIP_TOP_BOTTOM,
    5: Image.Transpose.TRANSPOSE,
    6: Image.Transpose.ROTATE_270,
    7: Image.Transpose.TRANSVERSE,
    8: Image.Transpose.ROTATE_90,
}


def _rgb(im: Image.Image) -> np.ndarray:
    """``(H, W, 3) uint8`` of a decoded image: 16-bit and 32-bit integer images scaled from
    their range, floating-point ones from 0–1, 0–255 or 0–65535 (the least that holds them);
    Pillow's ``convert`` clips them to 255 (a white picture)."""
    if im.mode not in ("I", "F") and not im.mode.startswith("I;16"):
        return np.asarray(im.convert("RGB"))
    a = np.asarray(im, dtype=np.float64)
    a = np.where(np.isfinite(a), a, 0.0)
    if im.mode == "F":
        # the range the samples were written for: 0–1, 8 or 16 bits, else their own maximum
        most = float(a.max(initial=0.0))
        top = next((t for t in (1.0, 255.0, 65535.0) if most <= t), most)
        a = np.clip(a, 0.0, None) / top * 255.0
    else:  # 16-bit samples, whether Pillow keeps them as I;16 or widens them to I
        a = np.clip(a, 0.0, 65535.0) / 257.0
    grey = (a + 0.5).astype(np.uint8)
    return np.repeat(grey[..., None], 3, axis=2)


def _exif(im: Image.Image, path: Path) -> Image.Exif | None:
    """The image's EXIF block, or None (with a warning when it is malformed)."""
    try:
        exif = im.getexif()
        list(exif.items())  # the tags are read lazily; a malformed one fails here
    except Exception as e:  # noqa: BLE001 - struct.error and the like, from the tag's bytes
        _warn_exif(path, f"the block is malformed ({type(e).__name__}: {e})")
        return None
    return exif


def _exif_focal(exif: Image.Exif | None, path: Path) -> float | None:
    """The 35 mm-equivalent focal length EXIF gives (FocalLengthIn35mmFilm), None where it
    gives none (0 means unknown) or one no lens has (with a warning)."""
    if exif is None:
        return None
    try:
        f35 = exif.get_ifd(0x8769).get(0xA405)  # the Exif IFD's FocalLengthIn35mmFilm
        focal = None if f35 is None else float(f35)
    except Exception as e:  # noqa: BLE001 - a malformed tag only loses the hint
        _warn_exif(path, f"its focal length cannot be read ({type(e).__name__})")
        return None
    if focal is None or focal == 0:
        return None
    if not MIN_FOCAL_35MM <= focal <= MAX_FOCAL_35MM:  # NaN (0/0) too
        _warn_exif(path, f"its 35 mm-equivalent focal length {focal:g} mm is outside "
                         f"{MIN_FOCAL_35MM:g}–{MAX_FOCAL_35MM:g}: ignored, the fit takes "
                         f"{DEFAULT_FOCAL_35MM:g} mm (give --focal)")  # fmt: skip
        return None
    return focal


def _warn_exif(path: Path, what: str) -> None:
    import warnings

    warnings.warn(VttsWarning(f"EXIF: {what}", file=str(path)), stacklevel=3)


@one_blas_thread()  # small dense solves: BLAS threads only spin against the renderer's
def fit_photo(
    image: np.ndarray,
    *,
    personality: str = "cybatt",
    face: int | None = None,
    focal_35mm: float | None = None,
    name: str = "fitted",
    detector: LandmarkDetector | None = None,
    photo_parts: tuple[str, ...] = PHOTO_PARTS,
    portrait: bool = True,
) -> FittedHead:
    """Fit the generic head of ``personality`` to the face in ``image (H, W, 3) uint8`` RGB.

    ``face`` chooses among several faces (1 = the largest; default: the largest, with a
    warning); ``focal_35mm`` is the lens as a 35 mm-equivalent focal length (mm; default
    :data:`~vtts.fit.shape.DEFAULT_FOCAL_35MM`); ``photo_parts`` the parts the photo paints
    where it sees them (:data:`~vtts.fit.texture.PHOTO_PARTS`; ``vtts analyze`` adds the neck,
    :data:`VIDEO_PARTS`, since the video shows what the photo showed there). A ``portrait``
    head (the default) is neutral whatever the photo's expression (:mod:`vtts.fit.expression`),
    its hair a shell grown to the photo's silhouette (:mod:`vtts.fit.hair`), its neck ended at
    the collar, and nothing of the photo's background painted on it; ``portrait=False`` fits
    the shape alone, as ``vtts analyze --model auto`` does for a video's first frame. Raises
    :class:`~vtts.errors.FitError` when no face is found."""
    t0 = time.perf_counter()
    timings: dict[str, float] = {}
    image = check_image(image)
    h, w = image.shape[:2]
    if min(h, w) < MIN_SIZE:
        raise FitError(f"the photo is {w}x{h} pixels: too small to fit (at least {MIN_SIZE})")
    if max(h, w) > MAX_SIZE or w * h > MAX_PHOTO_PIXELS:
        raise FitError(
            f"the photo is {w}x{h} pixels, more than the limit of {MAX_SIZE} on a side and "
            f"{MAX_PHOTO_PIXELS} in all (vtts.limits); scale it down"
        )
    if max(h, w) > WORK_SIZE:
        scale = WORK_SIZE / max(h, w)
        size = (max(round(w * scale), 1), max(round(h * scale), 1))
        image = np.asarray(Image.fromarray(image).resize(size, Image.Resampling.LANCZOS))
        h, w = image.shape[:2]
    faces = detect_faces(image, detector)
    timings["landmarks"] = time.perf_counter() - t0
    if not faces:
        raise FitError("no face found in the photo")
    chosen = choose_face(faces, face, "the photo", "fitting")
    g = generic_head(personality)
    t = time.perf_counter()
    focal = focal_length((w, h), focal_35mm)
    lmap = landmark_map()
    basis = for_photo(_expression_basis(personality), chosen.landmarks) if portrait else None
    shape = fit_shape(g, lmap, chosen.landmarks, (w, h), focal, expression=basis)
    timings["shape"] = time.perf_counter() - t
    t = time.perf_counter()
    geometry = fitted_geometry(g, shape.control)
    fapu = fitted_fapu(g.model.tables, geometry.points)
    tables = transfer_tables(g.model.tables, g.model.fapu, fapu)
    title = f"{name}: fitted to a photo (adi fit, personality {personality})"
    scene = fitted_scene(g.model, geometry, f"{name}-face.png", title)
    add_viewpoint(scene, shape)
    expression = fitted_expression(shape.expression, g.model.fapu, fapu)
    shut = portrait and lips_gap(chosen.landmarks) < SHUT_LIPS
    if shut:
        expression = close_lips(FaceModel(scene, tables, Path("fitted.wrl")), shape.camera,
                                expression)  # fmt: skip
    set_photo_expression(scene, expression)
    timings["head"] = time.perf_counter() - t
    hair, trust, skin, glasses, teeth, rims = None, None, None, None, None, None
    painted = image  # what the texture is painted from
    if portrait:
        t = time.perf_counter()
        glasses = glasses_score(image, chosen.landmarks)
        if glasses >= GLASSES:
            warnings.warn(
                VttsWarning(
                    "the photo shows glasses: their frame is a part of the head where it is "
                    "found (a thin shape in front of the eyes, textured with the photo's frame, "
                    "kept off the skin), but the lenses are not modelled: their tint and "
                    "reflections stay painted around the eyes; a photo without glasses gives "
                    "a better head"
                ),
                stacklevel=2,
            )
            # the texture is painted from the photo without the frame (vtts.fit.glasses)
            rims = rim_mask(image, chosen.landmarks)
            painted = without_rims(image, rims)
        matte(scene)
        trust = person_probability(image)
        hair = fit_hair_shell(scene, shape.camera, trust)
        if CUT_NECK and NECK in scene.defs and NECK in photo_parts:
            _cut_at_collar(scene, tables, shape, image, expression)
        skin = skin_trust((w, h), chosen.landmarks, mouth=not shut)
        teeth = None
        if not shut:
            # widened only as far as the row stays behind the skin, here and turned
            around = skins(FaceModel(scene, tables, Path("fitted.wrl")), expression)
            teeth = place_teeth(scene, shape.camera, image, chosen.landmarks, *around)
        if teeth is not None:
            # the photo paints the teeth where they show, placed where it shows them
            photo_parts = (*photo_parts, *(n for n in TEETH if n not in photo_parts))
        timings["hair"] = time.perf_counter() - t
    t = time.perf_counter()
    atlas, seen, depth = _texture(g, scene, tables, shape, painted, chosen, photo_parts, expression,
                           trust, skin, photo_lit=portrait)  # fmt: skip
    timings["texture"] = time.perf_counter() - t
    glasses_texture = None
    if rims is not None:
        t = time.perf_counter()
        # the frame as a part of its own, added once the texture is painted (the probes must
        # see the skin behind it)
        part = glasses_part(image, rims, shape.camera, geometry.points["FACE"], chosen.landmarks,
                            depth)  # fmt: skip
        if part is not None:
            add_glasses(scene, part, glasses_texture_name(Path(f"{name}.wrl")))
            glasses_texture = part.texture
        timings["glasses"] = time.perf_counter() - t
    timings["total"] = time.perf_counter() - t0
    return FittedHead(scene, tables, atlas, shape, chosen, image, len(faces), seen, personality,
                      timings, expression=expression, hair=hair, glasses=glasses,
                      teeth=teeth, glasses_texture=glasses_texture)  # fmt: skip


#: How the first WorldInfo's info line that holds the photo's expression begins.
PHOTO_EXPRESSION = "photo expression (FAP values at the photo Viewpoint):"


def set_photo_expression(scene: Scene, expression: dict[int, float]) -> None:
    """Record ``expression`` ``{FAP: value}`` (the photo's, in the head's FAPU units) in the
    first WorldInfo's info of ``scene``, as ``photo expression (…): 3 284 12 40`` (FAP and value
    pairs; none for a neutral photo), so that a written head keeps how to give its photo back
    (:func:`photo_expression`)."""
    infos = scene.find("WorldInfo")
    if not infos:
        return
    info = [line for line in infos[0].fields.get("info", []) or []
            if not str(line).startswith(PHOTO_EXPRESSION)]  # fmt: skip
    pairs = " ".join(f"{k} {v:g}" for k, v in sorted(expression.items()))
    infos[0].fields["info"] = [*info, f"{PHOTO_EXPRESSION} {pairs}".rstrip()]


def photo_expression(scene: Scene) -> dict[int, float]:
    """``{FAP: value}`` the photo's expression recorded in ``scene`` by
    :func:`set_photo_expression` (empty where none is): ``model.params(photo_expression(
    model.scene))`` at the ``photo`` Viewpoint draws the photo's face."""
    for node in scene.find("WorldInfo")[:1]:
        for line in node.fields.get("info", []) or []:
            line = str(line)
            if line.startswith(PHOTO_EXPRESSION):
                words = line[len(PHOTO_EXPRESSION) :].split()
                try:
                    pairs = [(int(a), float(b)) for a, b in zip(words[::2], words[1::2],
                                                                 strict=True)]  # fmt: skip
                except ValueError:
                    return {}
                return {k: v for k, v in pairs if 1 <= k <= 68}
    return {}


@functools.lru_cache(maxsize=4)
def _expression_basis(personality: str):
    """The expression basis of a bundled head (:func:`vtts.fit.expression.expression_basis`)."""
    g = generic_head(personality)
    return expression_basis(g.model, landmark_map().matrix(len(g.face)))


def fitted_expression(expression: dict[int, float], fapu0, fapu) -> dict[int, float]:
    """The photo's expression ``{FAP: value}`` in the generic head's FAPU units (``fapu0``)
    turned into the fitted head's (``fapu``): the same displacement, since the tables scale by
    the ratio of the two (:func:`vtts.fit.head.transfer_tables`). Values are rounded to whole
    units and zeros dropped."""
    from vtts.fap import fap

    out = {}
    for number, value in expression.items():
        unit = fap(number).fapu
        ratio = (
            1.0
            if unit in (None, "AU")
            else getattr(fapu, unit.lower()) / getattr(fapu0, unit.lower())
        )
        v = round(value / ratio)
        if v:
            out[number] = float(v)
    return out


def add_viewpoint(scene: Scene, shape: ShapeFit) -> None:
    """Put ``DEF photo Viewpoint`` (the photo's camera) into ``scene`` after its WorldInfos, so
    that VRML browsers open at the photo's view."""
    f = viewpoint_fields(shape.camera, shape.size)
    pos = " ".join(f"{v:.6f}" for v in f["position"])
    ori = " ".join(f"{v:.9f}" for v in f["orientation"])
    w, h = shape.size
    text = (
        f"#VRML V2.0 utf8\nDEF {PHOTO_VIEWPOINT} Viewpoint {{\n  position {pos}\n"
        f"  orientation {ori}\n  fieldOfView {f['fieldOfView']:.9f}\n"
        f'  description "the photo ({w}x{h}): vtts render --viewpoint {PHOTO_VIEWPOINT} '
        f'--size {w}x{h}"\n}}\n'
    )
    node = parse(text).roots[0]
    at = 0
    while at < len(scene.statements) and getattr(scene.statements[at], "type_name", "") == (
        "WorldInfo"
    ):
        at += 1
    scene.statements.insert(at, node)
    scene.defs[PHOTO_VIEWPOINT] = node


def _texture(g: GenericHead, scene: Scene, tables, shape: ShapeFit, image: np.ndarray,
             face: Face, photo_parts: tuple[str, ...] = PHOTO_PARTS,
             expression: dict[int, float] | None = None, trust: np.ndarray | None = None,
             skin: np.ndarray | None = None, photo_lit: bool = False):  # fmt: skip
    """The atlas: the generic tiles (upscaled; one eye tile per eye, in the photo's eye
    colours; the ear in its skin colour), painted from the photo where it sees the head —
    the head posed in the photo's ``expression``; ``trust`` and ``skin`` ``(H, W)`` weigh
    the photo's pixels for every part and for the skin (:func:`~vtts.fit.texture.project_skin`).
    Also returns the texels' share the photo saw and ``(H, W)`` the distance of what each pixel
    shows at the photo's view (:func:`~vtts.fit.texture.depth_map`). With ``photo_lit`` the
    skin is lit as brightly as the photo needs (:func:`~vtts.fit.texture.skin_exposure`,
    :func:`~vtts.fit.head.set_exposure`), else as the renderer lights it."""
    from vtts.render import FaceRenderer

    with Image.open(models_dir() / f"{g.model.name}-face.png") as im:
        size = atlas_size(image)
        generic_atlas = upscale(im, size)
    split_eye_tiles(generic_atlas, scene)
    ears = [n for n in EARS if n in photo_parts]
    if ears:
        split_ear_tiles(generic_atlas, scene)
    rechart_skin(scene)
    h, w = image.shape[:2]
    photo = ((image / 255.0) ** 2.2).astype(np.float32)
    probes = {}
    with tempfile.TemporaryDirectory(prefix="vtts-fit-") as tmp:
        folder = Path(tmp)
        model = FaceModel(scene, tables, folder / "probe.wrl")
        if expression:
            # painted as the photo shows the face; the texture coordinates are the neutral's
            model = FaceModel(model.posed_scene(model.deform(expression)), tables,
                              folder / "probe.wrl")  # fmt: skip
        for label, value in (("grey", PROBE_GREY), ("black", 0.0)):
            png = folder / f"{label}.png"
            Image.new("RGB", (16, 16), (round(value * 255),) * 3).save(png)
            set_texture_url(model.scene, png.name)
            with FaceRenderer(model, size=(w, h), viewpoint=PHOTO_VIEWPOINT) as r:
                if label == "grey":
                    frame, numbers = r.render(model.params(), triangles=True)
                    depth = depth_map(numbers, r.triangle_sets, r.camera, r.model_matrix(0))
                    on_skin = _drawn_parts(numbers, r.triangle_sets, skin_parts(model.scene))
                else:
                    frame = r.render(model.params())
            probes[label] = ((frame[..., :3] / 255.0) ** 2.2).astype(np.float32)
        offset = probes["black"]
        gain = (probes["grey"] - offset) / srgb_to_linear(PROBE_GREY)
        irises = [
            iris_colour(photo, gain, offset, face.landmarks[list(contour), :2])
            for contour in (RIGHT_EYE, LEFT_EYE)
        ]
        irises = [c for c in irises if c is not None]
        if irises:
            for tile in EYE_TILES.values():
                tint_eye(generic_atlas, np.mean(irises, axis=0), tile)
        names = [*PAINTED_PARTS, *(n for n in photo_parts if n not in PAINTED_PARTS)]
        parts = {n: model.scene.node(n).expand() for n in names if n in model.scene.defs}
        texels = skin_texels(parts, size, photo_parts)
        beyond = beyond_face((w, h), face.landmarks, image)
        proj = project_skin(texels, shape.camera, (w, h), depth, gain, offset, trust, skin,
                            beyond)  # fmt: skip
        if photo_lit:
            # the skin lit as brightly as the photo needs (the shading scales with it: the
            # Material's diffuseColor multiplies the texture), the texture divided by it
            exposure = skin_exposure(proj, photo)
            if np.any(exposure > 1.0):
                for lit in (scene, model.scene):
                    set_exposure(lit, exposure)
                scale = np.where(on_skin[..., None], np.broadcast_to(exposure, 3), 1.0)
                proj.gain = proj.gain * proj.taps(scale)
        painter = SkinPainter(proj, size)
        target = photo
        for k in range(TEXTURE_PASSES):
            if k == 0 and ears:
                # what the picture does not show of a painted ear keeps the generic ear, in the
                # skin's colour (the painted skin chart's): tinted before the passes paint over it
                skin, _ = painter.paint(generic_atlas.copy(), target, tiles=False)
                for name in ears:
                    tint_tile(generic_atlas, EAR_TILES[name], _skin_ratio(skin, generic_atlas))
                # the first pass's skin chart is that one (the same target): its tiles alone
                skin[painter.r1 :] = generic_atlas[painter.r1 :]
                atlas, seen = painter.paint(skin, target, skin=False)
            else:
                atlas, seen = painter.paint(generic_atlas.copy(), target)
            if k == TEXTURE_PASSES - 1:
                break
            # render what the texture gives and aim the next pass at what it missed: the
            # renderer's texture filtering blurs, the correction sharpens it back
            png = folder / f"pass{k}.bmp"  # read back at once: no time for compression
            Image.fromarray((np.clip(atlas, 0, 1) * 255 + 0.5).astype(np.uint8)).save(png)
            set_texture_url(model.scene, png.name)
            with FaceRenderer(model, size=(w, h), viewpoint=PHOTO_VIEWPOINT) as r:
                rendered = ((r.render(model.params())[..., :3] / 255.0) ** 2.2).astype(np.float32)
            covered = np.isfinite(depth)[..., None]
            # bounded: where no texture can give the photo (the model's silhouette over
            # background, a mouth it draws shut) the aim would run away into specks
            aim = np.clip(target + photo - rendered, photo - MAX_AIM, photo + MAX_AIM)
            target = np.where(covered, np.clip(aim, 0.0, 1.0), target)
    if not ears:
        # the ears keep the generic tile, in the photo's skin colour
        tint_tile(atlas, EAR_TILE, _skin_ratio(atlas, generic_atlas))
    return (np.clip(atlas, 0, 1) * 255 + 0.5).astype(np.uint8), seen, depth


def _drawn_parts(numbers: np.ndarray, sets, names: list[str]) -> np.ndarray:
    """``(H, W)`` bool: where the renderer's triangle ``numbers`` show an IndexedFaceSet
    DEFed with one of ``names`` (``sets``: its ``triangle_sets``)."""
    out = np.zeros(numbers.shape, bool)
    for node, first, count in sets:
        if node.name in names:
            out |= (numbers >= first) & (numbers < first + count)
    return out


#: Photos up to this size (pixels, the longer side) get an atlas of half :data:`ATLAS_SIZE`:
#: their face covers fewer pixels than that atlas has texels for it, and the texture's time
#: goes with its texels.
SMALL_PHOTO = 256


def atlas_size(image: np.ndarray) -> int:
    """Texels (square) of the atlas for a photo ``image (H, W, 3)``."""
    return ATLAS_SIZE // 2 if max(image.shape[:2]) <= SMALL_PHOTO else ATLAS_SIZE


def _skin_ratio(atlas: np.ndarray, generic_atlas: np.ndarray) -> np.ndarray:
    """``(3,)``: the painted skin chart's mean colour over the generic one's, per channel."""
    rows = slice(0, int(atlas.shape[0] * 0.75))
    return atlas[rows].reshape(-1, 3).mean(axis=0) / np.maximum(
        generic_atlas[rows].reshape(-1, 3).mean(axis=0), 1e-6
    )
