"""A head made for a video (:func:`vtts.fit.with_frame`): the first frame as the texture of what
it shows, unlit, gives the frame back; each ear has a tile of its own."""

from __future__ import annotations

import copy
import itertools
from pathlib import Path

import numpy as np
import pytest

from vtts.analysis.quality import coverage, face_psnr_rgb
from vtts.analysis.video import read_video
from vtts.cli import main
from vtts.face import N_PARAMS, load_model
from vtts.fit import fit_photo, with_frame
from vtts.fit.frame import FRAME_APPEARANCES, FRAME_PARTS, frame_texture, texture_size
from vtts.fit.photo import VIDEO_PARTS
from vtts.fit.texture import EAR_TILES
from vtts.render import FaceRenderer

AKIYO = Path(__file__).parents[1] / "data" / "video" / "akiyo_cif.mp4"


@pytest.fixture(scope="module")
def akiyo():
    """Akiyo's first frame and a head fitted to it as for a video (not yet made for it)."""
    frame = next(itertools.islice(read_video(AKIYO).frames(), 0, None))
    return frame, fit_photo(frame, photo_parts=VIDEO_PARTS, portrait=False)


def _render(paths, frame) -> np.ndarray:
    """The head written to ``paths`` rendered at ``frame``'s view (the photo Viewpoint)."""
    return _render_model(load_model(str(paths[0])), frame)


def _render_model(model, frame) -> np.ndarray:
    h, w = frame.shape[:2]
    with FaceRenderer(model, size=(w, h), viewpoint="photo", background="transparent") as r:
        return r.render(np.zeros(N_PARAMS))


def test_texture_size_is_the_powers_of_two_that_hold_the_frame():
    assert texture_size(352, 288) == (512, 512)
    assert texture_size(176, 144) == (256, 256)
    assert texture_size(256, 255) == (256, 256)
    assert texture_size(1920, 1080) == (2048, 2048)
    image = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3)
    tex = frame_texture(image)
    assert tex.shape == (2, 4, 3)
    assert np.array_equal(tex[:, :3], image) and np.array_equal(tex[:, 3], image[:, 2])


def test_the_head_made_for_the_video_gives_its_frame_back(akiyo, tmp_path):
    frame, head = akiyo
    head = copy.deepcopy(head)
    atlas = _render_model(head.model(tmp_path, "atlas"), frame)  # the painted atlas: not written
    mask = coverage(atlas)
    before = face_psnr_rgb(frame, atlas, mask)
    paths = with_frame(head).write(tmp_path / "video.wrl")
    assert [p.name for p in paths] == ["video.wrl", "video.adt", "video-face.png",
                                       "video-frame.png"]  # fmt: skip
    rendered = _render(paths, frame)
    mask = coverage(rendered)
    after = face_psnr_rgb(frame, rendered, mask)
    # the painted atlas, resampled twice and lit, gives about 28 dB; the frame itself, unlit,
    # gives it back but for the few pixels of the eye sockets and teeth that show
    assert before < 32.0, before
    assert after > 40.0, (before, after)
    text = paths[0].read_text()
    # the frame's Appearances, and the record of the photo (vtts.face.source_photo: the frame is it)
    assert text.count('"video-frame.png"') == len(FRAME_APPEARANCES) + 1
    assert '"video-face.png"' in text  # the mouth's inside keeps the atlas
    model = load_model(str(paths[0]))
    for name in FRAME_APPEARANCES:
        assert model.scene.node(name).expand()["material"] is None  # unlit
    for name in FRAME_PARTS:
        uv = np.asarray(model.scene.node(name).expand()["texCoord"].expand()["point"])
        assert uv.shape[0] == len(model.scene.node(name).expand()["coord"].expand()["point"])
    assert main(["check", str(paths[0])]) == 0


def test_a_video_head_with_the_neck_weighed_down_passes_check(akiyo, tmp_path):
    frame, head = akiyo
    paths = with_frame(copy.deepcopy(head), neck=True).write(tmp_path / "neck.wrl")
    model = load_model(str(paths[0]))
    # the neck follows the head's rotation near the skull only (vtts.fit.neck): its own tables
    with_neck = {
        m.number for m in model.miaps if "NECK" in [t.node for t in model.tables.adts[m].meshes]
    }
    assert with_neck == {48, 49, 50}
    assert main(["check", str(paths[0])]) == 0
    # it does not change the first frame: the head Transforms are the identity there
    rendered = _render(paths, frame)
    assert face_psnr_rgb(frame, rendered, coverage(rendered)) > 40.0


def test_the_ears_of_a_video_head_have_tiles_of_their_own(akiyo):
    """(A photo's head keeps the ears' shared generic tile: test_fit.py's
    test_a_photo_head_keeps_the_shared_generic_ear, on the head it fits anyway.)"""
    _, head = akiyo
    for name, (u0, v0, u1, v1) in EAR_TILES.items():
        uv = np.asarray(head.scene.node(name).expand()["texCoord"].expand()["point"])
        assert (uv[:, 0] >= u0 - 1e-9).all() and (uv[:, 0] <= u1 + 1e-9).all(), name
        assert (uv[:, 1] >= v0 - 1e-9).all() and (uv[:, 1] <= v1 + 1e-9).all(), name


CARPHONE = Path(__file__).parents[1] / "data" / "video" / "carphone_qcif.mp4"


def _neck_points(head) -> np.ndarray:
    return np.array(head.scene.node("NECK").expand()["coord"].expand()["point"], np.float64)


@pytest.fixture(scope="module")
def carphone(fits):
    """Carphone's first frame and a head fitted to it as for a video (not yet made for it), as
    the tracking fits it: one fit with the tracking tests that ran in this process before
    (conftest.py's ``SharedFits``)."""
    import vtts.fit

    frame = next(iter(read_video(CARPHONE).frames()))
    with fits.sharing():
        head = vtts.fit.fit_photo(
            frame, face=1, detector=None, photo_parts=VIDEO_PARTS, portrait=False
        )
    return frame, head


def test_a_video_head_ends_its_neck_at_the_collar(carphone, tmp_path):
    # Carphone's first frame: a bow tie and a white collar under the neck (vtts.fit.neck)
    frame, head = carphone
    head = copy.deepcopy(head)
    before = _neck_points(head)
    urls = [list(n["url"]) for n in head.scene.find("ImageTexture")]
    with_frame(head)
    # the probe rendering that found the collar left the scene's textures as they were
    assert [list(n["url"]) for n in head.scene.find("ImageTexture")] == urls
    paths = head.write(tmp_path / "carphone.wrl")
    after = _neck_points(head)
    assert after[:, 1].min() > before[:, 1].min() + 0.2  # the lowest rings rose to the collar
    assert np.array_equal(after[-32:], before[-32:])  # the top ring stays where it was
    assert len(np.unique(after.round(6), axis=0)) < len(before)  # lower rings on one another
    # the head still gives the frame back and is a valid model
    rendered = _render(paths, frame)
    assert face_psnr_rgb(frame, rendered, coverage(rendered)) > 40.0
    assert main(["check", str(paths[0])]) == 0
    # drawn again, its neck shows skin to its bottom: nothing more to cut
    from vtts.fit.neck import collar_row
    from vtts.fit.photo import _drawn

    drawn = _drawn(head.scene, head.tables, frame.shape[:2], ("NECK", "FACE"))
    assert drawn["NECK"].any()
    assert collar_row(frame, drawn["NECK"], drawn["FACE"]) is None


def test_a_neck_that_shows_skin_to_the_frame_bottom_stays_whole(akiyo, carphone, monkeypatch):
    # Akiyo's neck shows skin from her chin to the opening of her blouse: not cut
    _, head = akiyo
    head = copy.deepcopy(head)
    before = _neck_points(head)
    with_frame(head)
    assert np.array_equal(_neck_points(head), before)
    # and with the cut turned off nothing is cut anywhere
    import vtts.fit.photo as photo

    monkeypatch.setattr(photo, "CUT_NECK", False)
    head = copy.deepcopy(carphone[1])  # fitted as ever: the cut is with_frame's
    before = _neck_points(head)
    with_frame(head)
    assert np.array_equal(_neck_points(head), before)
