"""What the eyes observe of a head (vtts.analysis.eyes): the pupils and the lid points, on the
bundled heads and on a head fitted to a photo, against the iris model's view of that photo."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import vtts
import vtts.fit.photo
from vtts.analysis import Estimator
from vtts.analysis.eyes import (
    GAZE_FAPS,
    LID_FAPS,
    LID_LANDMARKS,
    eye_points,
    lid_points,
    pupil_vertices,
)
from vtts.face import N_PARAMS
from vtts.fit.iris import IrisModel

SIZE = (352, 288)
UNKNOWNS = (19, 20, 21, 22, 23, 24, 25, 26, 48, 49, 50, "tx", "ty", "tz")
PHOTO = Path(__file__).parents[1] / "data" / "photos" / "akiyo_frame0.png"


@pytest.fixture(scope="module", params=["cybatt", "lotta"])
def bundled(request) -> Estimator:
    return Estimator(vtts.load_model(request.param), size=SIZE, unknowns=UNKNOWNS)


@pytest.fixture(scope="module")
def fitted(fits, tmp_path_factory) -> tuple[Estimator, np.ndarray, np.ndarray]:
    """A head fitted to Akiyo's first frame, its estimator on the photo's camera, the photo and
    its face mesh."""
    image = np.asarray(Image.open(PHOTO).convert("RGB"))
    with fits.sharing():
        head = vtts.fit.photo.fit_photo(image)
    model = head.model(tmp_path_factory.mktemp("fitted"))
    estimator = Estimator(model, size=SIZE, model_camera=head.shape.camera, unknowns=UNKNOWNS)
    return estimator, image, head.face.landmarks


def _column(estimator: Estimator, unknown) -> int:
    return estimator.unknowns.index(unknown)


def test_the_pupils_are_the_eyeballs_front_poles(bundled):
    points = eye_points(bundled)
    assert points.pupils.names == ("pupil right", "pupil left")
    world = bundled.geometry.positions(bundled.params, bundled.translation)
    camera = bundled.camera.pose[:3, 3]
    for name, vertex in zip(points.pupils.names, points.pupils.vertices[:, 0], strict=True):
        eyeball = {"right": "R_EYEBALL", "left": "L_EYEBALL"}[name.split()[1]]
        shape = next(s for s in bundled.geometry.shapes if s.node.name == eyeball)
        ball = world[shape.first_vertex : shape.first_vertex + len(shape.mesh.positions)]
        # the point of the eyeball nearest the camera that looks at the face
        nearest = ball[np.argmin(np.linalg.norm(ball - camera, axis=1))]
        np.testing.assert_allclose(world[vertex], nearest, atol=1e-6)


def test_each_pupil_turns_with_its_own_eye(bundled):
    xy, jac = eye_points(bundled).pupils.project(bundled)
    assert xy.shape == (2, 2) and jac.shape == (4, len(UNKNOWNS))
    for row, eye in enumerate(("right", "left")):
        yaw, pitch = (_column(bundled, f) for f in GAZE_FAPS[eye])
        others = [_column(bundled, f) for e, fs in GAZE_FAPS.items() if e != eye for f in fs]
        x, y = jac[2 * row], jac[2 * row + 1]
        # a hundredth of a radian (1000 units) moves the pupil about a tenth of a pixel, across
        # for the yaw and down (positive) for the pitch; the other eye's FAPs not at all
        assert 0.05 < x[yaw] * 1000 < 0.3 and abs(y[yaw]) < 0.2 * x[yaw]
        assert 0.05 < y[pitch] * 1000 < 0.3 and abs(x[pitch]) < 0.2 * y[pitch]
        assert np.abs(jac[2 * row : 2 * row + 2, others]).max() == 0.0


def test_the_lid_points_move_with_their_lid(bundled):
    rows = lid_points(bundled.model)
    assert len(rows.fap) == sum(len(v) for v in LID_LANDMARKS.values()) == 12
    np.testing.assert_allclose(rows.weights.sum(axis=1), 1.0, atol=1e-5)
    engine = bundled.model.engine
    neutral = engine.points(np.zeros(N_PARAMS))["FACE"]
    for (eye, lid), fap in LID_FAPS.items():
        params = np.zeros(N_PARAMS)
        params[fap - 1] = 1.0
        most = np.abs(engine.points(params)["FACE"] - neutral)[:, 1].max()
        mine = (rows.eye == eye) & (rows.lid == lid)
        assert set(rows.fap[mine]) == {fap}
        down = -rows.motion[mine, 1] if lid == "upper" else rows.motion[mine, 1]
        # every point moves the lid's way by at least half the FAP's largest motion, the
        # middle one (MPEG-4's eyelid point) by nearly all of it
        assert (down > 0.5 * most).all()
        assert down[1] > 0.9 * most


def test_a_head_not_built_on_candide_has_pupils_but_no_lid_points(data_dir):
    model = vtts.load_model(data_dir / "models" / "head.wrl")
    assert lid_points(model) is None
    estimator = Estimator(model, size=SIZE, unknowns=(19, 48))
    points = eye_points(estimator)
    assert len(points.lids) == 0 and points.lid_rows is None
    assert points.lids.project(estimator)[1].shape == (0, 2)
    # it defines the left pupil only
    assert set(pupil_vertices(estimator.geometry, model.tables.feature_points)) <= {"left"}


def test_a_fitted_head_is_where_the_iris_model_sees_the_eyes(fitted):
    estimator, image, landmarks = fitted
    points = eye_points(estimator)
    assert len(points.pupils) == 2 and len(points.lids) == 12
    eyes = IrisModel().eyes(image, landmarks)
    pupils, lids = points.targets(eyes)
    normals = points.lid_normals(eyes)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    assert (normals[:, 1] > 0.95).all()  # an upright face: across the eye is down the image
    xy, jac = points.pupils.project(estimator)
    assert np.linalg.norm(xy - pupils, axis=1).max() < 2.0
    xy, jac = points.lids.project(estimator)
    gap = np.linalg.norm(xy - lids, axis=1)
    assert np.median(gap) < 1.0 and gap.max() < 2.0
    assert np.abs(((xy - lids) * normals).sum(axis=1)).max() < 1.5
    # closing a lid by 100 units moves its points half a pixel or more, that way, in the image
    rows = points.lid_rows
    for (eye, lid), fap in LID_FAPS.items():
        mine = np.flatnonzero((rows.eye == eye) & (rows.lid == lid))
        dy = jac[2 * mine + 1, _column(estimator, fap)] * 100
        assert (dy > 0.3).all() if lid == "upper" else (dy < -0.3).all()
