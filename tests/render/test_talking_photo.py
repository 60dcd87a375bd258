"""Talking photos (:mod:`vtts.render.talking_photo`, ``--background photo``) on a head whose
"photo" is a rendering of itself: the bundled cybatt, given a ``photo`` Viewpoint and a photo
record (:mod:`vtts.face.source_photo`) in memory, so that no fit is needed. A fitted head's talking
photo is tested with the fit (``tests/fit/test_fit.py``)."""

from __future__ import annotations

import copy
import shutil

import numpy as np
import pytest
from PIL import Image

import vtts
from vtts.errors import RenderError
from vtts.face import FaceModel
from vtts.face.source_photo import photo_record, record_photo, source_photo
from vtts.render import FaceRenderer
from vtts.render.camera import viewpoint_fields
from vtts.render.talking_photo import PHOTO_SHOWN, TalkingPhoto, TalkingPhotoOptions
from vtts.resources import models_dir
from vtts.vrml import dumps, parse, standard_node_types

from .. import in_process

SIZE = (160, 128)


def _viewpoint(scene, camera) -> None:
    f = viewpoint_fields(camera, SIZE)
    text = (
        "#VRML V2.0 utf8\nDEF photo Viewpoint {\n"
        f"  position {' '.join(f'{v:.6f}' for v in f['position'])}\n"
        f"  orientation {' '.join(f'{v:.9f}' for v in f['orientation'])}\n"
        f"  fieldOfView {f['fieldOfView']:.9f}\n}}\n"
    )
    node = parse(text).roots[0]
    scene.statements.insert(0, node)
    scene.defs["photo"] = node


@pytest.fixture(scope="module")
def portrait(tmp_path_factory):
    """cybatt with a ``photo`` Viewpoint and its photo: itself rendered there over a gradient
    (``(H, W, 3) uint8``), recorded beside it as ``photo.png``; the model, the photo."""
    folder = tmp_path_factory.mktemp("portrait")
    bundled = vtts.load_model("cybatt")
    shutil.copy(models_dir() / "cybatt-face.png", folder / "cybatt-face.png")
    scene = copy.deepcopy(bundled.scene, {id(t): t for t in standard_node_types().values()})
    model = FaceModel(scene, bundled.tables, folder / "cybatt.wrl")
    w, h = SIZE
    gradient = np.zeros((h, w, 3), np.uint8)
    gradient[..., 0] = np.linspace(40, 220, w)[None, :]
    gradient[..., 1] = np.linspace(30, 200, h)[:, None]
    gradient[..., 2] = 90
    with FaceRenderer(model, size=SIZE, background=gradient) as r:
        _viewpoint(model.scene, r.camera)
        photo = r.render(model.params())
    Image.fromarray(photo).save(folder / "photo.png")
    record_photo(model.scene, "photo.png", w, h)
    return model, photo


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def test_the_record_names_the_photo_and_survives_writing(portrait):
    model, photo = portrait
    assert photo_record(model.scene) == ("photo.png", SIZE)
    again = parse(dumps(model.scene))
    assert photo_record(again) == ("photo.png", SIZE)
    record_photo(again, "other.png", 3, 2)  # replaced, not added
    assert photo_record(again) == ("other.png", (3, 2))
    assert sum(1 for n in again.find("WorldInfo") if n["title"] == "vtts:SourcePhoto") == 1
    assert np.array_equal(source_photo(model), photo)


def test_at_rest_the_talking_photo_is_the_photo(portrait):
    model, photo = portrait
    with TalkingPhoto(model) as tp:
        assert tp.size == SIZE
        rest = tp.render(model.params())
        drawn = tp.renderer.render()[..., 3] > 0
    assert rest.shape == (SIZE[1], SIZE[0], 3)
    # the hair, ears and neck are the photo's own, and all around them
    assert np.array_equal(rest[~drawn], photo[~drawn])
    # the face drawn again over itself (with the skin under the hair cap: cybatt's hair covers
    # its forehead)
    assert psnr(rest, photo) > 28


def test_the_hair_ears_and_neck_are_the_photos_not_drawn(portrait):
    model, photo = portrait
    with TalkingPhoto(model, photo=np.zeros_like(photo)) as tp:
        rgba = tp.renderer.render(model.params())
        hair = tp.renderer.world_points("HAIR")
    with FaceRenderer(model, size=SIZE, viewpoint="photo", background="transparent") as r:
        whole = r.render(model.params())
        assert np.allclose(r.world_points("HAIR"), hair)
    assert set(PHOTO_SHOWN) <= set(model.scene.defs)
    # the whole head covers more than the face alone
    assert (whole[..., 3] > 0).sum() > 1.2 * (rgba[..., 3] > 0).sum()


def test_a_nod_moves_the_picture_near_the_head_and_leaves_the_corners(portrait):
    model, photo = portrait
    with TalkingPhoto(model) as tp:
        nod = tp.render(model.params({48: 20000}))  # head pitch, 0.2 rad
        roll = tp.render(model.params({50: 20000}))
        jaw = tp.render(model.params({"open_jaw": 600}))
        assert tp.warp.last_scale == 1.0  # fold-free without scaling the motion down
    for frame in (nod, roll, jaw):
        assert frame.shape == photo.shape
        assert np.array_equal(frame[:6, :6], photo[:6, :6])
        assert np.array_equal(frame[:6, -6:], photo[:6, -6:])
        assert psnr(frame, photo) < 35
    # the head rolled: the hair beside the head moved, so the picture differs there
    assert np.abs(roll.astype(int) - photo.astype(int))[20:60].max() > 30


def test_frames_give_what_render_gives(portrait):
    model, _ = portrait
    params = [model.params({48: v}) for v in (0.0, 8000.0, 16000.0)]
    with TalkingPhoto(model) as tp:
        frames = list(tp.frames(params, batch=2))
        one = tp.render(params[2])
    assert len(frames) == 3
    assert np.array_equal(frames[2], one)


def test_another_size_of_the_photos_shape_resamples_it(portrait):
    model, _ = portrait
    with TalkingPhoto(model, size=(80, 64)) as tp:
        assert tp.render(model.params()).shape == (64, 80, 3)
    with pytest.raises(RenderError, match="photo's shape"):
        TalkingPhoto(model, size=(100, 100))


def test_bad_options_and_models_are_errors(portrait, tmp_path):
    model, photo = portrait
    with pytest.raises(RenderError, match="feather"):
        TalkingPhotoOptions(feather=-1)
    with pytest.raises(RenderError, match="one head"):
        TalkingPhoto([model, model])
    with pytest.raises(RenderError, match="records none"):
        TalkingPhoto(vtts.load_model("cybatt"))
    moved = FaceModel(model.scene, model.tables, tmp_path / "elsewhere.wrl")
    with pytest.raises(RenderError, match="not found beside it"):
        source_photo(moved)
    Image.fromarray(photo[:10, :10]).save(tmp_path / "photo.png")
    with pytest.raises(RenderError, match="smaller than"):
        source_photo(moved)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--model", "cybatt"], "records none"),
        (["--model", "cybatt", "--camera", "300,300,80,64"], "give no --camera"),
        (["--model", "cybatt", "--viewpoint", "front"], "--viewpoint photo"),
        (["--model", "cybatt", "--layout", "room"], "no --layout room"),
    ],
)
def test_command_errors(tmp_path, args, message):
    done = in_process.vtts("render", *args, "--background", "photo", "-o", tmp_path / "x.png")
    assert done.returncode == 1
    assert message in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "x.png").exists()
