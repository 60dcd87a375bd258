"""The renderer: golden images, the camera model, textures, several heads, per-frame updates."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vtts.errors import RenderError
from vtts.face import load_model
from vtts.render import Camera, FaceRenderer, frame_bounds

BG = (0.32, 0.36, 0.42)


@pytest.fixture(scope="module")
def head():
    return load_model(Path(__file__).parents[1] / "data" / "models" / "head.wrl")


@pytest.fixture(scope="module")
def renderer(head):
    with FaceRenderer(head) as r:
        yield r


def foreground(img: np.ndarray) -> np.ndarray:
    bg = np.round(np.array(BG) * 255)
    return np.abs(img.astype(float) - bg).sum(axis=2) > 12


@pytest.mark.parametrize(
    "name, faps, visemes, expressions",
    [
        ("head-neutral", {}, {}, {}),
        ("head-joy-pitch", {48: 25000}, {}, {"joy": 1.0}),
        ("head-eyelid-lips", {19: 1024, 6: 900}, {1: 1.0}, {}),
    ],
)
def test_golden_poses(renderer, head, golden, name, faps, visemes, expressions):
    img = renderer.render(head.params(faps, visemes=visemes, expressions=expressions))
    assert img.shape == (288, 352, 3) and img.dtype == np.uint8
    golden(name, img)


def test_golden_two_heads_in_a_room(head, golden):
    with FaceRenderer([head, head], layout="room", size=(352, 288)) as r:
        img = r.render([head.params({}), head.params({48: -20000}, expressions={"joy": 1})])
    golden("two-heads-room", img)


def test_frames_depend_only_on_their_parameters(renderer, head):
    a = renderer.render(head.params({}))
    b = renderer.render(head.params({48: 30000}, expressions={"joy": 1}))
    again = renderer.render(head.params({}))
    assert np.array_equal(a, again)
    assert not np.array_equal(a, b)


def test_camera_projection_matches_the_pixels(head):
    model_pts = head.neutral_points("FACE_MESH")
    with FaceRenderer(head) as r:
        img = r.render(head.params({}))
        offset = r.scene.get_pose(r.instances[0].root)
        world = model_pts @ offset[:3, :3].T + offset[:3, 3]
        xy = r.camera.project(world)
    fg = foreground(img)
    rows, cols = np.nonzero(fg)
    # the silhouette's box is the projected vertices' box (within the shading of the edge)
    assert abs(cols.min() - xy[:, 0].min()) < 3 and abs(cols.max() - xy[:, 0].max()) < 3
    assert abs(rows.min() - xy[:, 1].min()) < 3 and abs(rows.max() - xy[:, 1].max()) < 3


def test_eisert_girod_camera_zooms_and_shifts(head):
    with FaceRenderer(head) as r:
        auto = r.camera
    zoom = Camera.eisert_girod(
        auto.fx * 2,
        auto.fy * 2,
        auto.cx + 40,
        auto.cy,
        pose=auto.pose,
        znear=auto.znear,
        zfar=auto.zfar,
    )
    with FaceRenderer(head, camera=zoom) as r:
        img = r.render(head.params({}))
    cols = np.nonzero(foreground(img))[1]
    with FaceRenderer(head) as r:
        base_cols = np.nonzero(foreground(r.render(head.params({}))))[1]
    assert (cols.max() - cols.min()) > 1.8 * (base_cols.max() - base_cols.min())
    assert Camera.parse("400,410,176,144").fy == 410
    with pytest.raises(RenderError, match="four numbers"):
        Camera.parse("400,400")


QUAD = """#VRML V2.0 utf8
Shape {
  appearance Appearance { texture PixelTexture { image 2 2 3 0xFF0000 0x00FF00 0x0000FF 0xFFFFFF } }
  geometry IndexedFaceSet {
    coord Coordinate { point [ -1 -1 0, 1 -1 0, 1 1 0, -1 1 0 ] }
    coordIndex [ 0 1 2 3 ] texCoord TextureCoordinate { point [ 0 0, 1 0, 1 1, 0 1 ] }
  }
}
"""


def test_texture_orientation_follows_vrml(tmp_path):
    """SFImage rows run bottom to top: red bottom left, green bottom right, blue top left."""
    (tmp_path / "quad.wrl").write_text(QUAD)
    model = load_model(tmp_path / "quad.wrl")
    with FaceRenderer(model, size=(64, 64)) as r:
        img = r.render(model.params({})).astype(int)

    def dominant(y, x):
        return int(np.argmax(img[y, x]))

    assert dominant(48, 16) == 0  # bottom left: red
    assert dominant(48, 48) == 1  # bottom right: green
    assert dominant(16, 16) == 2  # top left: blue
    assert img[16, 48].min() > 150  # top right: white


def test_background_image(head):
    bg = np.zeros((72, 88, 3), dtype=np.uint8)
    bg[:, :44] = [255, 0, 0]
    with FaceRenderer(head, size=(88, 72), background=bg) as r:
        img = r.render(head.params({}))
    assert img[2, 2].tolist() == [255, 0, 0] and img[2, 85].tolist() == [0, 0, 0]
    assert foreground(img).any()


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        ({"size": (8, 8)}, "image size must be within"),
        ({"layout": "circle"}, "layout must be"),
        ({"background": np.zeros((10, 10, 3), np.uint8)}, "background image is 10x10"),
    ],
)
def test_bad_setup_is_a_clear_error(head, kwargs, fragment):
    with pytest.raises(RenderError, match=fragment):
        FaceRenderer(head, **kwargs)


def test_parameter_shape_is_checked(renderer, head):
    with pytest.raises(RenderError, match="parameter vector has shape"):
        renderer.render(np.zeros(5))
    with pytest.raises(RenderError, match="1 models but 2 parameter vectors"):
        renderer.render([head.params({}), head.params({})])


def test_frame_bounds_fits_the_box():
    cam = frame_bounds(np.array([-1, -2, -1.0]), np.array([1, 2, 1.0]), (100, 200), fill=0.5)
    top, bottom = cam.project(np.array([[0, 2, 0.0], [0, -2, 0.0]]))
    assert bottom[1] > top[1]
    assert 0.45 * 200 < bottom[1] - top[1] < 0.6 * 200


def test_supersampled_stills_are_the_same_picture_smoother(head, image_psnr):
    with FaceRenderer(head) as r:
        plain = r.render(head.params({}))
    with FaceRenderer(head, supersample=2) as r:
        smooth = r.render(head.params({}))
    assert smooth.shape == plain.shape
    assert not np.array_equal(smooth, plain)
    assert image_psnr(smooth, plain) > 25
    with pytest.raises(RenderError, match="supersample must be 1 to 4"):
        FaceRenderer(head, supersample=8)


def test_views_of_one_renderer_are_windows_and_scaled_copies(head):
    """``set_view``: a shifted principal point renders a window of the image pixel for pixel, a
    scaled camera with supersampling renders what a renderer of that size renders, and going
    back restores the first view."""
    p = head.params({3: 300, 48: 4000})
    with FaceRenderer(head) as r:
        first = r.camera
        full = r.render(p)
        c = first
        r.set_view(Camera(c.fx, c.fy, c.cx - 96, c.cy - 64, c.pose, znear=c.znear, zfar=c.zfar),
                   (48, 32), 1)  # fmt: skip
        window = r.render(p)
        assert window.shape == (32, 48, 3)
        assert np.array_equal(window, full[64:96, 96:144])
        half = Camera(c.fx / 2, c.fy / 2, c.cx / 2, c.cy / 2, c.pose, znear=c.znear, zfar=c.zfar)
        r.set_view(half, (176, 144), 2)
        small = r.render(p)
        with FaceRenderer(head, size=(176, 144), camera=half, supersample=2) as other:
            assert np.array_equal(small, other.render(p))
        r.set_view(first, (352, 288), 1)
        assert np.array_equal(r.render(p), full)


def test_bad_views_are_clear_errors(head):
    with FaceRenderer(head) as r:
        c = r.camera
        with pytest.raises(RenderError, match="placed camera"):
            r.set_view(Camera(c.fx, c.fy, c.cx, c.cy, placed=False))
        with pytest.raises(RenderError, match="16–4096"):
            r.set_view(c, (8, 8))
        with pytest.raises(RenderError, match="supersample"):
            r.set_view(c, supersample=5)
    bg = np.zeros((288, 352, 3), np.uint8)
    with FaceRenderer(head, background=bg) as r, pytest.raises(RenderError, match="keeps its"):
        r.set_view(r.camera, (176, 144))


def test_a_pose_computed_by_the_caller_renders_the_same(head):
    p = head.params({3: 300, 19: 700})
    with FaceRenderer(head) as r:
        expected = r.render(p)
        r.render(head.params({}))
        assert np.array_equal(r.render(p, poses=[head.engine.deform(p)]), expected)
        with pytest.raises(RenderError, match="1 models but 2 poses"):
            r.render(p, poses=[head.engine.deform(p)] * 2)


def test_triangle_numbers_come_from_the_same_rasterization(head):
    """Every pixel the head covers, and only those, names a triangle of one of the drawn
    IndexedFaceSets; the image is the plain render's. (That the triangle contains the pixel's
    centre is checked through the estimator's geometry in tests/analysis.)"""
    from vtts.vrml import triangulate

    p = head.params({3: 300, 48: 20000, 19: 700})
    with FaceRenderer(head) as r:
        image, numbers = r.render(p, triangles=True)
        assert np.array_equal(image, r.render(p))
        assert numbers.shape == image.shape[:2] and numbers.dtype == np.int64
        assert np.array_equal(numbers >= 0, foreground(image))
        total = sum(count for _, _, count in r.triangle_sets)
        assert numbers.min() == -1 and numbers.max() < total
        firsts = [first for _, first, _ in r.triangle_sets]
        assert firsts == sorted(firsts) and firsts[0] == 0
        for node, _, count in r.triangle_sets:
            assert len(triangulate(node).faces) == count
        rows, cols = np.nonzero(numbers >= 0)
        assert len(np.unique(numbers[rows, cols])) > total // 2  # the front of the head


def test_triangle_numbers_need_a_plain_renderer(head):
    with FaceRenderer(head, supersample=2) as r, pytest.raises(RenderError, match="triangle"):
        r.render(head.params({}), triangles=True)
    bg = np.zeros((288, 352, 3), np.uint8)
    with FaceRenderer(head, background=bg) as r, pytest.raises(RenderError, match="triangle"):
        r.render(head.params({}), triangles=True)


def test_a_texture_file_written_anew_is_read_anew(tmp_path):
    """Decoded texture images are kept by the file's bytes: the same file again gives the kept
    image (read-only), the file rewritten in place at once (the same name, size and, often, the
    same time stamp) gives its new pixels."""
    from PIL import Image

    from vtts.render.scene import load_image

    png = tmp_path / "t.bmp"
    Image.new("RGB", (8, 8), (10, 20, 30)).save(png)
    first = load_image(png)
    assert load_image(png) is first and not first.flags.writeable
    Image.new("RGB", (8, 8), (40, 50, 60)).save(png)
    assert load_image(png)[0, 0].tolist() == [40, 50, 60, 255]
