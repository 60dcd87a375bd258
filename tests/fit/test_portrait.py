"""A portrait's head (issue 41): the person segmented, the hair a shell grown to the photo's
silhouette, the photo's expression fitted apart from the neutral face, the open mouth and the
eyes kept off the skin — and photos of every kind (no hair, a bald head, a beard, glasses, a
hat, a child, a painting, a cartoon, a face turned 45°, two faces) giving a head or a clear
error, never a traceback."""

from __future__ import annotations

import copy
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image, ImageDraw, ImageFilter

from vtts.errors import FitError
from vtts.fit import fit_photo
from vtts.fit.expression import (
    CHEEKS,
    EXPRESSION_FAPS,
    REST_WIDTH,
    ExpressionBasis,
    for_photo,
    skin_trust,
)
from vtts.fit.hair import SCALE_RANGE, fit_hair_shell
from vtts.fit.landmarks import LIPS_INNER, detect_faces
from vtts.fit.segment import person_probability

from .. import in_process

PHOTOS = Path(__file__).parents[1] / "data" / "photos"
SIDE = 160


def photo(name: str) -> np.ndarray:
    return np.asarray(Image.open(PHOTOS / name).convert("RGB"))


def small(image: np.ndarray, box: tuple[int, int, int, int], side: int = SIDE) -> np.ndarray:
    """``image`` cropped to ``box`` (x0, y0, x1, y1) and scaled to ``side`` square."""
    im = Image.fromarray(image).crop(box).resize((side, side), Image.Resampling.LANCZOS)
    return np.asarray(im)


#: Rows of background above the astronaut's hair (her photo cuts it close).
ABOVE = 64


@pytest.fixture(scope="module")
def astronaut() -> np.ndarray:
    """The astronaut's head and shoulders, 160 wide, with :data:`ABOVE` rows of background
    (the top row repeated) above: a smiling face with teeth showing."""
    head = small(photo("astronaut.png"), (96, 0, 352, 256))
    return np.pad(head, ((ABOVE, 0), (0, 0), (0, 0)), mode="edge")


@pytest.fixture(scope="module")
def fitted(astronaut):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_photo(astronaut)


# ---- segmentation, trust, expression, hair ---------------------------------------------------


def test_the_person_is_segmented(astronaut):
    p = person_probability(astronaut)
    assert p.shape == astronaut.shape[:2] and p.dtype == np.float32
    assert p[ABOVE + 60 : ABOVE + 100, 70:90].mean() > 0.9  # the face
    assert p[ABOVE : ABOVE + 20, :15].mean() < 0.2  # the flag behind her


def test_skin_takes_nothing_from_the_open_mouth_or_the_eyes(astronaut):
    face = detect_faces(astronaut)[0]
    trust = skin_trust(astronaut.shape[1::-1], face.landmarks)
    inner = face.landmarks[list(LIPS_INNER), :2].mean(axis=0)
    eye = face.landmarks[[33, 133], :2].mean(axis=0)
    cheek = face.landmarks[205, :2]
    assert trust[int(inner[1]), int(inner[0])] == 0
    assert trust[int(eye[1]), int(eye[0])] == 0
    assert trust[int(cheek[1]), int(cheek[0])] == 1


def test_a_smile_with_teeth_is_fitted_as_expression_and_the_neutral_mouth_is_shut(fitted):
    """The astronaut smiles with her mouth open: the fit opens the jaw and the lips' FAPs, and
    the neutral head (without them) has its lips closer than the photo's head has them."""
    e = fitted.expression
    assert set(e) <= set(EXPRESSION_FAPS)
    assert e.get(3, 0) > 100  # the jaw is open in the photo
    from vtts.face import FaceModel

    model = FaceModel(fitted.scene, fitted.tables)
    upper, lower = 13, 14  # landmarks: the inner lips' middles
    from vtts.fit.generic import landmark_map

    lmap = landmark_map()
    rows = {int(k): i for i, k in enumerate(lmap.landmark)}
    m = lmap.matrix(len(model.neutral_points("FACE")))
    neutral = m @ model.neutral_points("FACE")
    posed = m @ model.deform(e).points["FACE"]
    gap = [abs(p[rows[upper], 1] - p[rows[lower], 1]) for p in (neutral, posed)]
    assert gap[0] < 0.5 * gap[1]


def test_a_smile_lifts_the_cheeks_and_a_mouth_at_rest_does_not(fitted):
    """The astronaut's smile widens her mouth: her cheeks' lift is fitted (a smile's raised
    cheeks face the light where the photo is bright); a mouth at rest, no wider than
    :data:`REST_WIDTH` of the eye distance, leaves the cheeks out of the fit."""
    e = fitted.expression
    assert all(e.get(k, 0) > 20 for k in CHEEKS), e
    faps = np.array([3, 19, *CHEEKS])
    zero = np.zeros((len(faps), 468, 3))
    basis = ExpressionBasis(faps, zero, zero, np.full(len(faps), 100.0), np.zeros(len(faps), bool))
    landmarks = fitted.face.landmarks[:, :2].copy()
    assert list(for_photo(basis, landmarks).faps) == list(faps)
    eyes = np.linalg.norm(landmarks[[33, 133]].mean(axis=0) - landmarks[[263, 362]].mean(axis=0))
    middle = landmarks[[61, 291]].mean(axis=0)
    for k in (61, 291):  # the corners drawn in to a mouth at rest
        out = landmarks[k] - middle
        landmarks[k] = middle + out / np.linalg.norm(out) * 0.45 * REST_WIDTH * eyes
    rest = for_photo(basis, landmarks)
    assert list(rest.faps) == [3, 19]
    assert rest.up.shape == (2, 468, 3) and rest.sigma[1] == 100.0


def test_the_teeth_meet_the_teeth_the_photo_shows(fitted):
    """The astronaut shows her upper teeth: the model's are moved down until, at the photo's
    view, their tips meet the lower edge of hers, and widened a little beyond her mouth's
    opening; a shut
    mouth shows no teeth to place."""
    from vtts.fit.teeth import BEYOND, MIDDLE, teeth_mask

    landmarks = fitted.face.landmarks
    teeth = teeth_mask(fitted.photo, landmarks)
    assert teeth is not None
    assert fitted.teeth is not None and fitted.teeth < 0
    inner = landmarks[list(LIPS_INNER), :2]
    mid, half = (inner[:, 0].min() + inner[:, 0].max()) / 2, MIDDLE * np.ptp(inner[:, 0]) / 2
    cols = [c for c in range(int(mid - half) + 1, int(mid + half)) if teeth[:, c].any()]
    edge = np.median([np.flatnonzero(teeth[:, c]).max() + 1.0 for c in cols])
    upper = np.asarray(fitted.scene.node("UPPER_TEETH").expand()["coord"].expand()["point"])
    xy = fitted.shape.camera.project(upper)
    tips = xy[np.abs(xy[:, 0] - mid) <= half, 1].max()
    assert abs(tips - edge) < 1.0, (tips, edge)
    # and a little wider than her mouth's opening between the inner lip corners (its ends curve
    # back behind them)
    assert np.ptp(xy[:, 0]) == pytest.approx(BEYOND * np.ptp(inner[:, 0]), rel=0.03)
    # the lips drawn over the opening: no teeth
    shut = Image.fromarray(fitted.photo.copy())
    lip = tuple(int(v) for v in fitted.photo[int(landmarks[17, 1]), int(landmarks[17, 0])])
    ImageDraw.Draw(shut).polygon([tuple(p) for p in inner], fill=lip)
    assert teeth_mask(np.asarray(shut), landmarks) is None


def test_the_widened_teeth_stay_behind_the_skin(fitted):
    """Her upper row, widened towards her smile's corners, stays behind the skin at rest and
    smiling (``joy``), seen from the front and turned 30° each way: widened as far as the
    opening alone asks, its ends poked through the skin under the lips' corners when she
    smiled (18 of its points), drawn as thin lines there when turned."""
    from vtts.face import FaceModel
    from vtts.fit.teeth import in_front, skins

    model = FaceModel(fitted.scene, fitted.tables)
    (neutral, photo, joy, _), triangles = skins(model, fitted.expression)
    upper = np.asarray(fitted.scene.node("UPPER_TEETH").expand()["coord"].expand()["point"])
    for skin in (neutral, joy):
        assert not in_front(upper, skin, triangles).any()


def _panels() -> tuple[np.ndarray, np.ndarray]:
    """A skin of two upright panels at z = 0, |x| from 0.5 to 1, |y| ≤ 0.5, with an opening
    between them: ``(8, 3)`` points and ``(4, 3)`` triangles."""
    pts = np.array([[x, y, 0.0] for x in (-1.0, -0.5, 0.5, 1.0) for y in (-0.5, 0.5)])
    tri = np.array([[0, 2, 3], [0, 3, 1], [4, 6, 7], [4, 7, 5]])
    return pts, tri


def test_in_front_of_the_skin():
    """A point is in front of the skin where the skin lies behind it and not in front of it;
    in the opening, or behind the skin, it is not; turned, the rays slant."""
    from vtts.fit.teeth import in_front

    skin, tri = _panels()
    points = np.array([[0.7, 0.0, 0.1], [0.7, 0.0, -0.1], [0.0, 0.0, 0.1], [0.48, 0.0, 0.1]])
    assert in_front(points, skin, tri, yaws=(0.0,)).tolist() == [True, False, False, False]
    # seen from 30° to the left, the point just inside the opening has the panel behind it
    assert in_front(points, skin, tri, yaws=(-30.0,)).tolist() == [True, False, False, True]


def test_the_row_spreads_only_as_far_as_it_stays_behind_the_skin():
    """Spread 1.5 times, a row in the opening between two panels would reach in front of them:
    each point goes as far as it stays behind the skin (never narrower than it was), and the
    row keeps its order across."""
    from vtts.fit.teeth import behind_skin, in_front

    skin, tri = _panels()
    x = np.linspace(-0.45, 0.45, 19)
    row = np.stack([x, np.zeros_like(x), np.full_like(x, 0.05)], axis=1)
    out = behind_skin(row, 0.0, 1.5, [skin], tri)
    assert not in_front(out, skin, tri).any()
    assert np.all(np.abs(out[:, 0]) >= np.abs(x) - 1e-12)
    assert np.all(np.diff(out[:, 0]) >= 0)
    # the middle spreads in full, the ends stop short of the panels (0.45 × 1.5 = 0.675)
    assert out[9, 0] == 0.0 and out[10, 0] == pytest.approx(1.5 * x[10])
    assert 0.45 <= out[-1, 0] < 0.5 and 0.45 <= -out[0, 0] < 0.5
    # with no skin in the way the row spreads as asked
    assert np.allclose(behind_skin(row, 0.0, 1.5, [skin + [0, 5, 0]], tri)[:, 0], 1.5 * x)


def test_the_hair_shell_grows_to_the_silhouette_and_keeps_the_seam(fitted):
    scene = copy.deepcopy(fitted.scene)
    cam = fitted.shape.camera
    face = np.asarray(scene.node("FACE").expand()["coord"].expand()["point"])
    hair0 = np.asarray(scene.node("HAIR").expand()["coord"].expand()["point"])
    # a person twice as large as the head all round: the skull grows to the bound above
    h, w = fitted.photo.shape[:2]
    big = np.ones((h, w), np.float32)
    with pytest.warns(Warning, match="hat"):  # the person reaches the frame's top
        shell = fit_hair_shell(scene, cam, big)
    hair = np.asarray(scene.node("HAIR").expand()["coord"].expand()["point"])
    assert shell.scale.max() == pytest.approx(SCALE_RANGE[1], rel=0.05)
    assert hair[:, 1].max() > hair0[:, 1].max() + 0.2  # taller
    assert hair[:, 2].min() < hair0[:, 2].min() - 0.1  # and deeper: volume when turned
    seam = np.isin(hair0.view([("", hair0.dtype)] * 3), face.view([("", face.dtype)] * 3))
    assert seam.any() and np.allclose(hair[seam.ravel()], hair0[seam.ravel()], atol=1e-5)
    # nobody there: the ears are folded away, the skull shrinks to its bound
    scene = copy.deepcopy(fitted.scene)
    shell = fit_hair_shell(scene, cam, np.zeros((h, w), np.float32))
    assert shell.ears == {"L_EAR": False, "R_EAR": False}
    ear = np.asarray(scene.node("L_EAR").expand()["coord"].expand()["point"])
    assert np.ptp(ear, axis=0).max() == 0
    assert shell.scale.min() == pytest.approx(SCALE_RANGE[0], rel=0.05)


def test_the_fit_at_the_photo_view_gives_the_photo_back(fitted, tmp_path):
    """Everything the model draws at the photo's view, in the photo's expression."""
    import vtts
    from vtts.fit.report import figures

    fitted.write(tmp_path / "a.wrl")
    figs = figures(vtts.load_model(tmp_path / "a.wrl"), fitted, fitted.photo)
    assert figs["psnr_db"]["skin"] > 25
    assert figs["psnr_db"]["head"] > 19
    assert figs["photo_expression_faps"]
    assert figs["teeth_moved"] == fitted.teeth < 0  # her teeth, placed (vtts.fit.teeth)
    # the written head keeps the photo's expression
    from vtts.fit.photo import photo_expression

    assert photo_expression(vtts.load_model(tmp_path / "a.wrl").scene) == fitted.expression


# ---- photos of every kind ---------------------------------------------------------------------


def _landmarks(image: np.ndarray) -> np.ndarray:
    return detect_faces(image)[0].landmarks[:, :2]


def bald(image: np.ndarray) -> np.ndarray:
    """The hair above the brows painted over in the forehead's skin colour."""
    lm = _landmarks(image)
    out = image.copy()
    top = int(lm[10, 1]) + 2
    skin = image[int(lm[151, 1]), int(lm[151, 0])]
    x0, x1 = int(lm[:, 0].min()) - 8, int(lm[:, 0].max()) + 8
    im = Image.fromarray(out)
    ImageDraw.Draw(im).ellipse([x0, top - (x1 - x0) // 2, x1, top + 10], fill=tuple(skin))
    return np.asarray(im)


def no_hair(image: np.ndarray) -> np.ndarray:
    """The hair above the forehead replaced by the background's grey."""
    lm = _landmarks(image)
    out = image.copy()
    out[: int(lm[10, 1]), :] = 200
    return out


def beard(image: np.ndarray) -> np.ndarray:
    lm = _landmarks(image)
    im = Image.fromarray(image.copy())
    chin = [tuple(lm[i]) for i in (132, 58, 172, 136, 150, 149, 176, 148, 152, 377, 400, 378,
                                   379, 365, 397, 288, 361)]  # fmt: skip
    mouth = [tuple(lm[i]) for i in (61, 91, 84, 314, 321, 291)]
    ImageDraw.Draw(im).polygon(chin + mouth[::-1], fill=(60, 40, 25))
    return np.asarray(im)


def glasses(image: np.ndarray) -> np.ndarray:
    lm = _landmarks(image)
    im = Image.fromarray(image.copy())
    d = ImageDraw.Draw(im)
    for a, b in ((33, 133), (362, 263)):
        c = (lm[a] + lm[b]) / 2
        r = np.linalg.norm(lm[a] - lm[b]) * 0.75
        d.ellipse([c[0] - r, c[1] - r * 0.7, c[0] + r, c[1] + r * 0.7], outline=(20, 20, 20),
                  width=2)  # fmt: skip
    d.line([tuple(lm[133]), tuple(lm[362])], fill=(20, 20, 20), width=2)
    return np.asarray(im)


def hat(image: np.ndarray) -> np.ndarray:
    lm = _landmarks(image)
    im = Image.fromarray(image.copy())
    x0, x1 = lm[:, 0].min() - 12, lm[:, 0].max() + 12
    top = lm[10, 1]
    ImageDraw.Draw(im).rectangle([x0 + 10, 0, x1 - 10, top - 4], fill=(30, 30, 90))
    ImageDraw.Draw(im).rectangle([x0 - 10, top - 14, x1 + 10, top - 4], fill=(30, 30, 90))
    return np.asarray(im)


def child(image: np.ndarray) -> np.ndarray:
    """A child's proportions: the face below the eyes squeezed to three quarters."""
    lm = _landmarks(image)
    eyes = int(lm[[33, 263], 1].mean())
    h, w = image.shape[:2]
    lower = Image.fromarray(image[eyes:]).resize((w, round((h - eyes) * 0.75)))
    out = np.full_like(image, 210)
    out[:eyes] = image[:eyes]
    out[eyes : eyes + lower.height] = np.asarray(lower)
    return out


def painting(image: np.ndarray) -> np.ndarray:
    im = Image.fromarray(image).filter(ImageFilter.ModeFilter(5)).quantize(24).convert("RGB")
    return np.asarray(im.filter(ImageFilter.EDGE_ENHANCE_MORE))


def cartoon(_image: np.ndarray) -> np.ndarray:
    """The cartoon portrait among the photos (a rendered figure with big eyes)."""
    return small(photo("lp_s7.jpg"), (0, 0, 852, 852))


def drawing(_image: np.ndarray) -> np.ndarray:
    """A face drawn with circles: no face a detector knows."""
    im = Image.new("RGB", (SIDE, SIDE), (250, 250, 240))
    d = ImageDraw.Draw(im)
    d.ellipse([40, 30, 120, 130], outline=(0, 0, 0), width=3)
    d.ellipse([58, 60, 70, 72], fill=(0, 0, 0))
    d.ellipse([90, 60, 102, 72], fill=(0, 0, 0))
    d.arc([60, 85, 100, 110], 20, 160, fill=(0, 0, 0), width=3)
    return np.asarray(im)


def turned(_image: np.ndarray) -> np.ndarray:
    """The bundled head seen from 45° to its side."""
    import vtts
    from vtts.render import FaceRenderer

    model = vtts.load_model("cybatt")
    au = math.radians(45) / 1e-5
    with FaceRenderer(model, size=(SIDE, SIDE), background=(0.8, 0.8, 0.8)) as r:
        return r.render(model.params({49: au}))[..., :3]


def two_faces(image: np.ndarray) -> np.ndarray:
    half = np.asarray(Image.fromarray(image).resize((SIDE // 2, SIDE // 2)))
    out = np.full_like(image, 128)
    out[40 : 40 + SIDE // 2, : SIDE // 2] = half
    out[40 : 40 + SIDE // 2, SIDE // 2 :] = half
    return out


CASES = {"no hair": no_hair, "bald": bald, "beard": beard, "glasses": glasses, "hat": hat,
         "child": child, "painting": painting, "cartoon": cartoon, "drawing": drawing,
         "turned 45°": turned, "two faces": two_faces}  # fmt: skip


#: Cases run through the ``adi fit`` command (the others through the library, which the
#: command wraps: the same outcome without writing 7 MB of model).
CLI_CASES = ("drawing", "two faces", "turned 45°")
#: Cases that show a face plainly: they must give a head.
MUST_FIT = ("beard", "glasses", "child", "bald", "no hair")


@pytest.mark.parametrize("case", list(CASES))
def test_every_kind_of_photo_gives_a_head_or_a_clear_error(case, astronaut, tmp_path):
    image = CASES[case](astronaut)
    if case not in CLI_CASES:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                head = fit_photo(image)
        except FitError as e:
            assert case not in MUST_FIT, e
            assert str(e)
            return
        assert np.isfinite(head.shape.residual).all() and head.texture.dtype == np.uint8
        assert head.hair is not None
        return
    path = tmp_path / "photo.png"
    Image.fromarray(image).save(path)
    done = in_process.adi("fit", str(path), "-o", str(tmp_path / "me.wrl"))
    assert "Traceback" not in done.stderr, done.stderr
    if done.returncode == 0:
        assert (tmp_path / "me.wrl").is_file() and (tmp_path / "me-face.png").is_file()
    else:
        assert done.returncode == 1 and "error:" in done.stderr, done.stderr
        assert "photo.png" in done.stderr
        assert not (tmp_path / "me.wrl").exists()


def test_a_tall_hat_is_left_out_with_a_warning(fitted):
    """Something on the head far taller than hair (a top hat: the person's silhouette reaches
    twice the skull's height above it): the shell stops at its bound, and says so. (The
    segmentation model takes a drawn hat for background, so the silhouette is given here.)"""
    scene = copy.deepcopy(fitted.scene)
    h, w = fitted.photo.shape[:2]
    c = fitted.shape.camera.project(np.array([[0.0, 0.2, -0.9]]))[0]
    person = np.zeros((h, w), np.float32)
    yy, xx = np.mgrid[0:h, 0:w]
    person[np.hypot(xx - c[0], yy - c[1]) < 0.45 * w] = 1  # the head and hair
    person[:, int(c[0] - 0.2 * w) : int(c[0] + 0.2 * w)][: int(c[1])] = 1  # the hat, to the top
    with pytest.warns(Warning, match="hat"):
        shell = fit_hair_shell(scene, fitted.shape.camera, person)
    assert shell.capped
    plain = fit_hair_shell(copy.deepcopy(fitted.scene), fitted.shape.camera, fitted_person(fitted))
    assert not plain.capped


def fitted_person(head) -> np.ndarray:
    return person_probability(head.photo)


# ---- glasses ----------------------------------------------------------------------------------


def _frame(clip: str, side: int = SIDE) -> np.ndarray:
    """The first frame of a development clip, cropped square around its face and scaled to
    ``side``."""
    from vtts.analysis.video import read_video

    frame = next(iter(read_video(Path(__file__).parents[1] / "data" / "video" / clip).frames()))
    lm = _landmarks(frame)
    c, r = lm.mean(axis=0), 1.3 * np.ptp(lm[:, 1])
    return small(frame, tuple(int(v) for v in (c[0] - r, c[1] - r, c[0] + r, c[1] + r)), side)


def test_glasses_are_told_from_bare_skin():
    """lp_d13 wears thin metal glasses, lp_d3 none (both 160² crops of development frames)."""
    from vtts.fit.glasses import GLASSES, glasses_score, wears_glasses

    for clip, wears in (("lp_d13.mp4", True), ("lp_d3.mp4", False)):
        image = _frame(clip)
        score = glasses_score(image, _landmarks(image))
        assert wears_glasses(image, _landmarks(image)) == wears, (clip, score)
        assert (score >= 2 * GLASSES) if wears else (score < GLASSES / 2), (clip, score)


def test_the_frame_is_found_and_filled_from_the_skin_around_it(astronaut):
    """Glasses drawn on the astronaut (dark rims two pixels wide): the rims' mask covers the
    frame's pixels and little beyond them, and filling them gives back the skin the frame
    hides, nearly as the photo without glasses shows it."""
    from scipy import ndimage

    from vtts.fit.glasses import rim_mask, without_rims

    image = glasses(astronaut)
    frame = np.abs(image.astype(int) - astronaut.astype(int)).sum(axis=2) > 60
    rims = rim_mask(image, detect_faces(image)[0].landmarks)
    assert (rims & frame).sum() >= 0.9 * frame.sum()
    assert (rims & ~ndimage.binary_dilation(frame, iterations=3)).sum() <= 0.05 * rims.sum()
    filled = without_rims(image, rims)
    assert (filled[~rims] == image[~rims]).all()
    off = np.abs(filled.astype(int) - astronaut.astype(int))[frame].mean()
    assert off < 0.25 * np.abs(image.astype(int) - astronaut.astype(int))[frame].mean()


def test_a_photo_with_glasses_is_fitted_with_its_frame_as_a_part(astronaut, fitted, tmp_path):
    """Glasses drawn on the astronaut: the head is fitted, with a warning that the lenses are
    not modelled, and the report says so. The frame is a part of its own, written with its
    RGBA texture and read back: at the photo's view the head draws the frame where the photo
    shows it, and without that part the skin there (the texture has no frame); every point
    of it lies in front of the skin. The photo without glasses gives no warning and no
    part."""
    from scipy.interpolate import LinearNDInterpolator

    from vtts.face import load_model
    from vtts.fit.glasses import GLASSES, PART
    from vtts.fit.report import photo_view
    from vtts.render import FaceRenderer

    image = glasses(astronaut)
    with pytest.warns(Warning, match="glasses") as caught:
        head = fit_photo(image)
    assert head.glasses >= GLASSES
    assert sum("glasses" in str(w.message) for w in caught) == 1
    assert fitted.glasses < GLASSES
    assert PART not in fitted.scene.defs and fitted.glasses_texture is None
    files = head.write(tmp_path / "g.wrl")
    assert tmp_path / "g-glasses.png" in files
    alpha = np.asarray(Image.open(tmp_path / "g-glasses.png"))[..., 3]
    assert alpha.min() == 0 and alpha.max() == 255
    model = load_model(tmp_path / "g.wrl")
    assert PART in model.scene.defs
    frame = np.abs(image.astype(int) - astronaut.astype(int)).sum(axis=2) > 60
    drawn, masks = photo_view(model, image, head.expression)
    shown = frame & masks["face"]
    assert shown.sum() > 0.8 * frame.sum()
    to_skin = np.abs(drawn.astype(int) - astronaut.astype(int))[shown].mean()
    to_frame = np.abs(drawn.astype(int) - image.astype(int))[shown].mean()
    assert to_frame < 0.3 * to_skin, (to_skin, to_frame)
    h, w = image.shape[:2]
    with FaceRenderer(model, size=(w, h), viewpoint="photo", hidden=(PART,)) as r:
        bare, numbers = r.render(model.params(head.expression), triangles=True)
    skin = frame & (numbers >= 0)
    to_skin = np.abs(bare[..., :3].astype(int) - astronaut.astype(int))[skin].mean()
    to_frame = np.abs(bare[..., :3].astype(int) - image.astype(int))[skin].mean()
    assert to_skin < 0.3 * to_frame, (to_skin, to_frame)
    # in front of the skin: never on the cheeks when the head turns
    face, part = model.neutral_points("FACE"), model.neutral_points(PART)
    under = LinearNDInterpolator(face[:, :2], face[:, 2])(part[:, :2])
    assert np.isfinite(under).mean() > 0.9
    assert (part[:, 2] > under)[np.isfinite(under)].all()
    # the photo's view holds whatever depth the part takes: each point moves along its pixel's
    # ray, and stays in front of what that view shows (here a wall through the frame)
    from vtts.fit.glasses import glasses_part, rim_mask

    camera, lm = head.shape.camera, head.face.landmarks
    rims = rim_mask(image, lm)
    free = glasses_part(image, rims, camera, face, lm)
    origin = camera.pose[:3, 3]
    dist = np.linalg.norm(free.points - origin, axis=1)
    wall = np.full(image.shape[:2], float(np.median(dist)))
    held = glasses_part(image, rims, camera, face, lm, wall)
    near = np.linalg.norm(held.points - origin, axis=1)
    assert (near < np.median(dist)).all() and (near <= dist + 1e-9).all()
    assert np.allclose(camera.project(held.points), camera.project(free.points), atol=1e-6)


# ---- the skin's exposure ------------------------------------------------------------------------


def brighter(image: np.ndarray, gain: float) -> np.ndarray:
    """``image`` ``gain`` times brighter in linear light (about 2.2 gamma), clipped at white."""
    lin = (image / 255.0) ** 2.2 * gain
    return (np.clip(lin, 0, 1) ** (1 / 2.2) * 255 + 0.5).astype(np.uint8)


def test_a_brightly_lit_photo_is_drawn_back_unclipped(astronaut, monkeypatch, tmp_path):
    """A photo lit more brightly than the renderer lights the head: the skin's Material is lit
    brighter (diffuseColor above 1, brightest in red, up to MAX_EXPOSURE), the texture divided
    by it, and the face at the photo's view comes back closer than with the renderer's light,
    where the texture clipped at white."""
    import vtts
    from vtts.fit import photo as fit_module
    from vtts.fit.report import figures
    from vtts.fit.texture import MAX_EXPOSURE

    image = brighter(astronaut, 1.6)

    def fit_and_measure(name: str) -> tuple[np.ndarray, dict]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            head = fit_photo(image)
        head.write(tmp_path / f"{name}.wrl")
        model = vtts.load_model(tmp_path / f"{name}.wrl")
        diffuse = model.scene.node("SKIN").expand()["material"].expand()["diffuseColor"]
        return np.asarray(diffuse), figures(model, head, head.photo)["psnr_db"]

    lit, lit_psnr = fit_and_measure("lit")
    assert 1.1 < lit[0] <= MAX_EXPOSURE and lit[0] >= lit[2] >= 1.0, lit
    monkeypatch.setattr(fit_module, "skin_exposure", lambda proj, target: np.ones(3))
    plain, plain_psnr = fit_and_measure("plain")
    assert (plain == 1.0).all()
    assert lit_psnr["face"] > plain_psnr["face"] + 0.3, (lit_psnr, plain_psnr)


def test_the_skin_is_lit_as_brightly_as_the_photo_asks_per_channel():
    """The skin's exposure is 1 where the photo is darker than the renderer's shading, the
    asked-for quantile of what the texels need (per channel) where it is brighter, at most the
    limit; texels the photo is not trusted for ask for nothing."""
    from vtts.fit.texture import Projection, SkinTexels, skin_exposure

    n = 1000
    texels = SkinTexels(rows=np.zeros(n), cols=np.zeros(n), points=np.zeros((n, 3)),
                        normals=np.zeros((n, 3)), photo=np.ones(n, bool), skin=np.ones(n, bool),
                        rim=np.zeros(n, bool), face=np.zeros(n, bool))  # fmt: skip
    target = np.full((1, n, 3), 0.25, np.float32)
    target[0, :, 0] = np.linspace(0.0, 0.9, n)  # red: up to 1.8 times the shading's 0.5
    xy = np.c_[np.arange(n) + 0.5, np.full(n, 0.5)]
    gain = np.full((n, 3), 0.5)
    proj = Projection(texels, np.arange(n), xy, np.ones(n), gain, np.zeros((n, 3)))
    k = skin_exposure(proj, target, quantile=0.9, limit=2.0)
    assert k[0] == pytest.approx(0.9 * 1.8, rel=0.01) and (k[1:] == 1.0).all()
    assert skin_exposure(proj, target, quantile=0.99, limit=1.5)[0] == 1.5
    assert (skin_exposure(proj, target * 0.5, quantile=0.9, limit=2.0) == 1.0).all()
    proj.weight[:] = 0.1  # untrusted texels ask for nothing
    assert (skin_exposure(proj, target, quantile=0.9, limit=2.0) == 1.0).all()


def _oval_landmarks(centre=(50.0, 50.0), radius=30.0, eyes=40.0) -> np.ndarray:
    """``(468, 2)`` landmarks: the face outline a circle, the eyes ``eyes`` pixels apart."""
    from vtts.fit.landmarks import FACE_OVAL

    pts = np.zeros((468, 2))
    angles = np.linspace(0, 2 * np.pi, len(FACE_OVAL), endpoint=False)
    pts[list(FACE_OVAL)] = np.c_[np.sin(angles), -np.cos(angles)] * radius + centre
    pts[[33, 133]] = (centre[0] - eyes / 2, centre[1])
    pts[[362, 263]] = (centre[0] + eyes / 2, centre[1])
    return pts


def test_beyond_the_face_is_the_outside_of_its_outline_and_a_band_within():
    from vtts.fit.expression import OUTLINE_BAND, beyond_face

    b = beyond_face((100, 100), _oval_landmarks())
    assert b.shape == (100, 100) and b.dtype == np.float32
    assert b[50, 50] == 0 and b[2, 2] == 1 and b[50, 95] == 1
    band = OUTLINE_BAND * 40  # 8 pixels
    inner = b[50, 21 : 21 + round(band) + 2]  # from the outline (x = 20) inwards
    assert 0 < inner[1] < 1 and inner[-1] == 0 and np.all(np.diff(inner) <= 0)
    assert b[50, 20] > 0.5 and b[50, 79] > 0.5  # the band on both sides
    # with the photo: within the band only where it is darker than the face (a sideburn)
    image = np.full((100, 100, 3), 200, np.uint8)
    image[:, :25] = 40  # a dark strip over the left edge
    b = beyond_face((100, 100), _oval_landmarks(), image)
    assert b[50, 20] > 0.5 and b[50, 79] == 0  # just inside the outline: dark, lit
    assert b[50, 95] == 1 and b[50, 50] == 0  # outside whatever its colour; the middle


def test_a_grazing_face_texel_beyond_the_face_outline_takes_the_photo():
    """At a grazing view (cosine 0.1) a face texel inside the photo's face outline is left to
    the mirror (weight 0), one beyond it takes the photo's pixel, as the hair shell's does."""
    from vtts.fit.texture import RIM_GRAZING, SkinTexels, grazing_weight, project_skin
    from vtts.render.camera import Camera, look_at

    cam = Camera(100.0, 100.0, 50.0, 50.0, look_at(np.array([0.0, 0, 10]), np.zeros(3)))
    points = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])  # left and right of the centre
    normals = []
    for p in points:
        ray = (cam.pose[:3, 3] - p) / np.linalg.norm(cam.pose[:3, 3] - p)
        side = np.cross(ray, [0.0, 1.0, 0.0])
        side /= np.linalg.norm(side)
        normals.append(0.1 * ray + np.sqrt(1 - 0.01) * side)  # cosine 0.1 with the view
    n = 2
    texels = SkinTexels(rows=np.zeros(n), cols=np.arange(n), points=points,
                        normals=np.array(normals), photo=np.ones(n, bool),
                        skin=np.ones(n, bool), rim=np.zeros(n, bool),
                        face=np.ones(n, bool))  # fmt: skip
    depth = np.full((100, 100), np.inf)
    gain, offset = np.full((100, 100, 3), 0.5), np.zeros((100, 100, 3))
    beyond = np.zeros((100, 100), np.float32)
    beyond[:, 50:] = 1.0  # the right half shows no face
    assert project_skin(texels, cam, (100, 100), depth, gain, offset).index.size == 0
    proj = project_skin(texels, cam, (100, 100), depth, gain, offset, beyond=beyond)
    assert list(proj.index) == [1]
    assert proj.weight[0] == pytest.approx(float(grazing_weight(np.array(0.1), RIM_GRAZING)))
