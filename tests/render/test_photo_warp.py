"""The talking photo's warp (:mod:`vtts.render.photo_warp`): pixels far from the head stay,
pixels near it move with it, and a nod neither tears nor folds the picture."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.errors import RenderError
from vtts.render.photo_warp import PhotoWarp, WarpOptions, bilinear, fold_free

W, H = 320, 256
#: The head: an ellipse of points around (160, 110), 45 × 60 pixels in radius; the neck's pivot
#: below it.
CENTRE = np.array([160.0, 110.0])
PIVOT = np.array([160.0, 200.0])


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(7)
    photo = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    t = rng.random(4000) * 2 * np.pi
    r = np.sqrt(rng.random(4000))
    rest = CENTRE + np.c_[45 * r * np.cos(t), 60 * r * np.sin(t)]
    depth = rng.random(4000)
    return photo, rest, PhotoWarp(photo, rest, depth, WarpOptions(reach=1.0, motion=3.0))


def nod(points: np.ndarray, degrees: float) -> np.ndarray:
    """``points`` turned about the neck's pivot in the picture's plane, and foreshortened
    vertically as a head pitched by that angle is."""
    a = np.radians(degrees)
    p = points - PIVOT
    turned = p @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    turned[:, 1] *= np.cos(a)
    return turned + PIVOT


def test_nothing_moves_at_rest(scene):
    photo, rest, warp = scene
    assert np.array_equal(warp(rest), photo)


def test_pixels_far_from_the_head_stay(scene):
    photo, rest, _ = scene
    warp = PhotoWarp(photo, rest, options=WarpOptions(reach=0.5))
    out = warp(nod(rest, 4))
    reach = warp.last_reach
    assert reach >= 0.5 * warp.head_size
    ys, xs = np.mgrid[0:H, 0:W]
    # beyond the fade's reach from every point of the head, and a grid cell for the bilinear
    # cells that straddle it
    far = np.hypot(xs - CENTRE[0], ys - CENTRE[1]) > 60 + reach + 2 * warp.step
    assert far.sum() > 0.1 * far.size
    assert np.array_equal(out[far], photo[far])
    assert not np.array_equal(out, photo)


def test_pixels_near_the_head_move_with_it(scene):
    photo, rest, warp = scene
    shift = np.array([6.0, -4.0])
    out = warp(rest + shift)
    # inside the head the picture moves by the head's shift (whole pixels: sampled exactly)
    for x, y in [(160, 110), (140, 90), (175, 140)]:
        assert np.array_equal(out[y - 4, x + 6], photo[y, x]), (x, y)
    # and so does it just outside the head's outline, then the motion fades out
    field = warp.field(rest + shift)
    distance = warp.distance
    band = (distance > 0) & (distance <= warp.step)  # the nodes next to the outline
    assert band.sum() > 10
    assert np.abs(field[band] - shift).max() < 0.5
    assert np.abs(field[warp.head] - shift).max() < 0.05
    mid = (distance > 0.4 * warp.head_size) & (distance < 0.6 * warp.head_size)
    assert (np.linalg.norm(field[mid], axis=-1) < 0.8 * np.linalg.norm(shift)).all()
    assert np.abs(field[distance > warp.last_reach]).max() == 0


def test_the_hair_above_follows_farther_than_the_shoulders_below(scene):
    photo, rest, _ = scene
    warp = PhotoWarp(photo, rest, options=WarpOptions(reach=0.25, above=2.0, motion=0.0))
    shift = np.array([6.0, 0.0])
    field = warp.field(rest + shift)
    column = int(np.argmin(np.abs(warp.gx - CENTRE[0])))
    top, chin = rest[:, 1].min(), rest[:, 1].max()
    gap = 0.35 * warp.head_size  # beyond the reach below the chin, within it above the top
    above = int(np.argmin(np.abs(warp.gy - (top - gap))))
    below = int(np.argmin(np.abs(warp.gy - (chin + gap))))
    assert np.linalg.norm(field[above, column]) > 0.5
    assert np.linalg.norm(field[below, column]) == 0
    # one reach all round: the same distance above and below fades alike
    even = PhotoWarp(photo, rest, options=WarpOptions(reach=0.25, above=1.0, motion=0.0))
    field = even.field(rest + shift)
    assert np.linalg.norm(field[above, column]) == np.linalg.norm(field[below, column]) == 0


@pytest.mark.parametrize("default", [True, False], ids=["default", "wide"])
@pytest.mark.parametrize("degrees", [-25.0, 10.0, 25.0])
def test_a_nod_neither_tears_nor_folds(scene, degrees, default):
    photo, rest, warp = scene
    if default:  # the fade's defaults: steeper, so the fold rule has more to do
        warp = PhotoWarp(photo, rest)
    moved = nod(rest, degrees)
    field = warp.field(moved)
    # fold-free: the forward map's Jacobian determinant is positive everywhere
    assert fold_free(field, warp.step) > 0.2
    # no tear: neighbouring output pixels take neighbouring places of the photo
    src, (r0, r1, c0, c1) = warp.source(moved)
    steps = np.concatenate(
        [np.diff(src, axis=0).reshape(-1, 2), np.diff(src, axis=1).reshape(-1, 2)]
    )
    assert np.linalg.norm(steps, axis=1).max() < 2.5 * warp.step
    out = warp(moved)
    assert out.shape == photo.shape and out.dtype == np.uint8


def test_a_large_jerk_is_kept_fold_free_by_widening_or_scaling(scene):
    photo, rest, warp = scene
    # the top of the head thrown far one way, the chin the other: a field no head makes
    moved = rest + np.c_[(110 - rest[:, 1]) * 0.9, np.zeros(len(rest))]
    field = warp.field(moved)
    outside = ~warp.head
    assert fold_free(field, warp.step, outside) >= 0.25 - 1e-9


@pytest.fixture(scope="module")
def person():
    """A photo of a person — a red head (the handles' ellipse) on a red body below it — before
    a background of blue and white vertical stripes, and the person's probability (1 on the
    person, 0 elsewhere)."""
    rng = np.random.default_rng(11)
    ys, xs = np.mgrid[0:H, 0:W]
    head = ((xs + 0.5 - CENTRE[0]) / 50) ** 2 + ((ys + 0.5 - CENTRE[1]) / 66) ** 2 <= 1
    body = (ys >= 165) & (np.abs(xs + 0.5 - CENTRE[0]) < 90)
    shown = head | body
    photo = np.zeros((H, W, 3), np.uint8)
    photo[...] = np.where(((xs // 8) % 2 == 0)[..., None], [40, 60, 220], [235, 235, 235])
    photo[shown] = np.c_[rng.integers(180, 256, shown.sum()), rng.integers(0, 60, shown.sum()),
                         rng.integers(0, 60, shown.sum())]  # fmt: skip
    return photo, shown.astype(np.float32)


def test_only_the_person_moves_never_the_background(scene, person):
    _, rest, _ = scene
    photo, probability = person
    options = WarpOptions(reach=1.0, motion=3.0)  # a wide fade: it reaches the background
    layered = PhotoWarp(photo, rest, options=options, person=probability)
    single = PhotoWarp(photo, rest, options=options)
    assert layered.coverage is not None
    # at rest the picture is the photo, exactly
    assert np.array_equal(layered(rest), photo)
    shift = np.array([10.0, 0.0])
    out, dragged = layered(rest + shift), single(rest + shift)
    ys, xs = np.mgrid[0:H, 0:W]
    # the background where the person (moved by at most the shift) does not come
    background = layered.coverage == 0
    for dx in range(1, 12):
        background[:, dx:] &= layered.coverage[:, :-dx] == 0
    # one layer drags the stripes near the head; with the person layered over them they stay
    assert not np.array_equal(dragged[background], photo[background])
    assert np.array_equal(out[background], photo[background])
    # the head moved with its handles
    for x, y in [(160, 110), (140, 90), (175, 140)]:
        assert np.array_equal(out[y, x + 10], photo[y, x]), (x, y)
    # where the head was and is no more, the background shows (filled in from around it: blue
    # and white, not the person's red)
    left = ((xs + 0.5 - CENTRE[0]) / 50) ** 2 + ((ys + 0.5 - CENTRE[1]) / 66) ** 2 <= 1
    left &= xs + 0.5 < CENTRE[0] + 10 - 1.15 * 50  # left of the moved head's edge
    left &= np.abs(ys + 0.5 - CENTRE[1]) < 20
    assert left.sum() > 20
    revealed = out[left].astype(int)
    assert (revealed[:, 2] > revealed[:, 0]).mean() > 0.9  # blue above red: the background's


def test_a_segmentation_that_misses_the_face_is_not_used(scene, person):
    _, rest, _ = scene
    photo, probability = person
    elsewhere = np.zeros_like(probability)
    elsewhere[:40, :40] = 1.0  # a "person" in the corner, not where the face is
    warp = PhotoWarp(photo, rest, person=elsewhere)
    assert warp.coverage is None
    moved = nod(rest, 10)
    assert np.array_equal(warp(moved), PhotoWarp(photo, rest)(moved))
    with pytest.raises(RenderError, match="probability"):
        PhotoWarp(photo, rest, person=probability[:-1])


def test_bilinear_samples_between_pixels():
    image = np.zeros((2, 2, 1), np.uint8)
    image[0, 1] = 200
    at = np.array([[0.5, 0.5], [1.5, 0.5], [1.0, 0.5], [1.0, 1.0], [-3.0, 9.0]])
    assert bilinear(image, at)[:, 0].tolist() == [0, 200, 100, 50, 0]


def test_bad_handles_and_options_are_errors():
    photo = np.zeros((32, 32, 3), np.uint8)
    with pytest.raises(RenderError, match="outside the photo"):
        PhotoWarp(photo, np.array([[-5.0, -5.0], [-6.0, -5.0], [-5.0, -7.0]]))
    with pytest.raises(RenderError, match=r"\(n, 2\)"):
        PhotoWarp(photo, np.zeros((4, 3)))
    with pytest.raises(RenderError, match="uint8"):
        PhotoWarp(photo.astype(float), np.zeros((4, 2)))
    with pytest.raises(RenderError, match="reach"):
        WarpOptions(reach=float("nan"))
    with pytest.raises(RenderError, match="above"):
        WarpOptions(above=0.5)
    warp = PhotoWarp(photo, np.array([[10.0, 10.0], [20.0, 10.0], [15.0, 20.0]]))
    with pytest.raises(RenderError, match="not finite"):
        warp.field(np.array([[np.nan, 10.0], [20.0, 10.0], [15.0, 20.0]]))
