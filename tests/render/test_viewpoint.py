"""VRML97 Viewpoints as cameras: the exact mapping, the inverse writer, and clear errors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from vtts.errors import RenderError
from vtts.face import load_model
from vtts.render import Camera, FaceRenderer, find_viewpoint, viewpoint_fields
from vtts.vrml import parse

HEAD = Path(__file__).parents[1] / "data" / "models" / "head.wrl"

RIG = """#VRML V2.0 utf8
DEF RIG Transform {
  translation 0.3 -0.2 0.5
  rotation 0 1 0 0.4
  scale 2 2 2
  children [
    DEF CAM Viewpoint { position 0.1 0.05 3 orientation 1 0 0 -0.1 fieldOfView 0.6 }
  ]
}
"""


def _vec(values) -> str:
    return " ".join(repr(float(v)) for v in values)


def _unproject(camera: Camera, pixels: np.ndarray, depth: float) -> np.ndarray:
    """World points ``(n, 3)`` that ``camera`` shows at ``pixels (n, 2)``, ``depth`` in front."""
    x = (pixels[:, 0] - camera.cx) / camera.fx * depth
    y = -(pixels[:, 1] - camera.cy) / camera.fy * depth
    cam = np.c_[x, y, np.full(len(pixels), -depth), np.ones(len(pixels))]
    return (cam @ camera.pose.T)[:, :3]


def _inside(pixels: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which ``pixels (n, 2)`` lie inside triangle ``tri (3, 2)``, and their distance to its
    nearest edge (pixels)."""
    signs, dists = [], []
    for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
        e = b - a
        cross = e[0] * (pixels[:, 1] - a[1]) - e[1] * (pixels[:, 0] - a[0])
        signs.append(cross)
        dists.append(np.abs(cross) / np.linalg.norm(e))
    s = np.stack(signs)
    inside = np.all(s > 0, axis=0) | np.all(s < 0, axis=0)
    return inside, np.min(np.stack(dists), axis=0)


@pytest.mark.parametrize("size", [(200, 120), (120, 200)])
def test_viewpoint_maps_points_where_the_pixels_show_them(tmp_path, size):
    """A triangle put at known pixels of a Viewpoint (under a rotated, scaled Transform) covers
    exactly the pixels whose centres Camera.project puts inside it; fieldOfView spans the
    smaller side of the image."""
    w, h = size
    node, world = find_viewpoint(parse(RIG), "CAM")
    camera = Camera.from_viewpoint(node, size, world)
    assert camera.fx == camera.fy == pytest.approx((min(w, h) / 2) / math.tan(0.3))
    assert (camera.cx, camera.cy) == (w / 2, h / 2)
    # the Transform's scale moves the position (×2) but does not scale the camera
    assert np.allclose(camera.pose[:3, :3] @ camera.pose[:3, :3].T, np.eye(3))
    assert np.allclose(camera.pose[:3, 3], world[:3, :3] @ [0.1, 0.05, 3] + world[:3, 3])

    corners = np.array([[0.2 * w, 0.15 * h], [0.85 * w, 0.3 * h], [0.4 * w, 0.9 * h]])
    points = _unproject(camera, corners, depth=5.0)
    shape = (
        "Shape { appearance Appearance { material Material { emissiveColor 1 1 1 } }\n"
        "  geometry IndexedFaceSet { solid FALSE coordIndex [ 0 1 2 -1 ]\n"
        f"    coord Coordinate {{ point [ {', '.join(_vec(p) for p in points)} ] }} }} }}\n"
    )
    (tmp_path / "rig.wrl").write_text(RIG + shape)
    model = load_model(tmp_path / "rig.wrl")
    with FaceRenderer(model, size=size, viewpoint="CAM", background="transparent") as r:
        covered = r.render(model.params({}))[..., 3] > 0
        # the renderer moves the model; the camera moves with it
        m = r.model_matrix(0)
        shown = r.camera.project(points @ m[:3, :3].T + m[:3, 3])
    assert np.allclose(shown, corners, rtol=0, atol=1e-9)
    assert np.allclose(camera.project(points), corners, rtol=0, atol=1e-9)

    ys, xs = np.mgrid[0:h, 0:w]
    centres = np.c_[xs.ravel() + 0.5, ys.ravel() + 0.5]
    inside, edge = _inside(centres, corners)
    wrong = inside != covered.ravel()
    assert inside.sum() > 1000
    # pixel centres on an edge go either way (the rasterizer's tie rule and float rounding)
    assert np.all(edge[wrong] < 0.01), edge[wrong]


def test_a_viewpoint_like_the_automatic_framing_renders_the_same_image(tmp_path):
    head = load_model(HEAD)
    with FaceRenderer(head) as r:
        auto = r.render(head.params({}))
        eye = np.linalg.inv(r.model_matrix(0)) @ r.camera.pose[:, 3]
        fields = viewpoint_fields(r.camera, r.size)
    assert np.allclose(fields["orientation"][3], 0)
    text = HEAD.read_text() + (
        f"DEF AUTO Viewpoint {{ position {_vec(eye[:3])} fieldOfView {fields['fieldOfView']!r} }}\n"
    )
    (tmp_path / "head.wrl").write_text(text)
    (tmp_path / "head.adt").write_bytes(HEAD.with_suffix(".adt").read_bytes())
    model = load_model(tmp_path / "head.wrl")
    with FaceRenderer(model, viewpoint="AUTO") as r:
        seen = r.render(model.params({}))
    assert np.array_equal(seen, auto)


def _random_camera(rng: np.random.Generator) -> tuple[Camera, tuple[int, int]]:
    from scipy.spatial.transform import Rotation

    w, h = (int(v) for v in rng.integers(16, 2000, size=2))
    f = (min(w, h) / 2) / math.tan(rng.uniform(0.05, 3.0) / 2)
    pose = np.eye(4)
    pose[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    pose[:3, 3] = rng.normal(scale=5, size=3)
    return Camera(f, f, w / 2, h / 2, pose), (w, h)


def test_viewpoint_fields_round_trip_through_from_viewpoint():
    rng = np.random.default_rng(7)
    for _ in range(50):
        camera, size = _random_camera(rng)
        fields = viewpoint_fields(camera, size)
        assert fields["position"].shape == (3,) and fields["orientation"].shape == (4,)
        text = (
            "#VRML V2.0 utf8\n"
            f"DEF V Viewpoint {{ position {_vec(fields['position'])} "
            f"orientation {_vec(fields['orientation'])} fieldOfView {fields['fieldOfView']!r} }}"
        )
        node, world = find_viewpoint(parse(text), "V")
        back = Camera.from_viewpoint(node, size, world)
        # points in front of the camera, projected by both
        local = np.c_[rng.uniform(-1, 1, (20, 2)), -rng.uniform(0.5, 20, 20), np.ones(20)]
        points = (local @ camera.pose.T)[:, :3]
        want, got = camera.project(points), back.project(points)
        assert np.all(np.abs(got - want) <= 1e-9 * np.maximum(np.abs(want), 1.0))


@pytest.mark.parametrize(
    "camera, fragment",
    [
        (Camera(500, 501, 50, 40), "fx 500 and fy 501 differ"),
        (Camera(500, 500, 51, 40), r"principal point \(51, 40\) is not \(50.0, 40.0\)"),
    ],
)
def test_viewpoint_fields_need_a_viewpoint_camera(camera, fragment):
    with pytest.raises(RenderError, match=fragment):
        viewpoint_fields(camera, (100, 80))


def test_unknown_viewpoints_are_named():
    scene = parse(RIG + "DEF SIDE Viewpoint { position 5 0 0 }\n")
    with pytest.raises(RenderError, match="no Viewpoint named 'TOP'.*Viewpoints are CAM, SIDE"):
        find_viewpoint(scene, "TOP")
    with pytest.raises(RenderError, match="'CAM' in the scene: it has no Viewpoint"):
        find_viewpoint(parse("#VRML V2.0 utf8\nGroup {}\n"), "CAM")
    bad = parse("#VRML V2.0 utf8\nDEF WIDE Viewpoint { fieldOfView 3.5 }\n")
    with pytest.raises(RenderError, match="WIDE fieldOfView must lie between 0 and π.*3.5"):
        Camera.from_viewpoint(*find_viewpoint(bad, "WIDE")[:1], (64, 64))


def test_a_renderer_takes_a_camera_or_a_viewpoint():
    head = load_model(HEAD)
    with pytest.raises(RenderError, match="camera or a viewpoint"):
        FaceRenderer(head, camera=Camera(400, 400, 176, 144), viewpoint="CAM")
    with pytest.raises(RenderError, match=r"no Viewpoint named 'CAM' in the scene of head\.wrl"):
        FaceRenderer(head, viewpoint="CAM")
