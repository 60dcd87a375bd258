"""Background colors and the transparent background: parsing, exact alpha, RGBA outputs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vtts.errors import RenderError
from vtts.face import load_model
from vtts.render import (
    FaceRenderer,
    PngSequenceWriter,
    VideoWriter,
    parse_background,
    parse_color,
    write_png,
)

HEAD = Path(__file__).parents[1] / "data" / "models" / "head.wrl"


@pytest.fixture(scope="module")
def head():
    return load_model(HEAD)


@pytest.mark.parametrize(
    "text, rgb",
    [
        ("black", (0, 0, 0)),
        ("White", (1, 1, 1)),
        ("grey", (0.5, 0.5, 0.5)),
        ("gray", (0.5, 0.5, 0.5)),
        ("green", (0, 1, 0)),
        ("blue", (0, 0, 1)),
        ("red", (1, 0, 0)),
        ("#00FF80", (0, 1, 128 / 255)),
        ("0.2,0.5, 1", (0.2, 0.5, 1)),
    ],
)
def test_colors_parse(text, rgb):
    assert parse_color(text) == pytest.approx(rgb)
    assert parse_background(text) == pytest.approx(rgb)


@pytest.mark.parametrize("text", ["purplish", "#12345", "#gg0000", "1,0", "0.5,2,0", "nan,0,0"])
def test_bad_colors_name_the_value_and_the_forms(text):
    with pytest.raises(RenderError, match=rf"not a color: '{text}'.*#rrggbb.*r,g,b"):
        parse_color(text)
    with pytest.raises(RenderError, match=r"not a background.*or transparent"):
        parse_background(text)


def test_a_named_background_colors_the_image(head):
    with FaceRenderer(head, size=(64, 48), background="green") as r:
        img = r.render(head.params({}))
    assert img[0, 0].tolist() == [0, 255, 0]


def _render(head, background, supersample=1) -> np.ndarray:
    with FaceRenderer(head, background=background, supersample=supersample) as r:
        return r.render(head.params({19: 1024}, expressions={"joy": 1}))


def test_transparent_alpha_is_exactly_the_heads_coverage(head):
    gray = _render(head, (0.32, 0.36, 0.42))
    white = _render(head, "white")
    rgba = _render(head, "transparent")
    assert rgba.shape == (288, 352, 4) and rgba.dtype == np.uint8
    background = np.any(gray != white, axis=2)
    assert 0.2 < background.mean() < 0.9
    assert np.array_equal(rgba[..., 3], np.where(background, 0, 255))
    # the heads' pixels are those of an opaque render; nothing shows around them
    assert np.array_equal(rgba[~background][:, :3], gray[~background])
    assert not rgba[background][:, :3].any()


def test_supersampled_transparent_stills_keep_straight_colors(head):
    opaque = _render(head, "white", supersample=2)
    rgba = _render(head, "transparent", supersample=2)
    alpha = rgba[..., 3]
    edge = (alpha > 0) & (alpha < 255)
    assert edge.any() and set(np.unique(alpha)) <= {0, 64, 128, 191, 255}
    full = alpha == 255
    assert np.array_equal(rgba[full][:, :3], opaque[full])
    # a partly covered pixel is the head's color (no white mixed in): no brighter than its
    # opaque render on white
    assert np.all(rgba[edge][:, :3] <= opaque[edge])


def test_transparent_frames_carry_triangle_numbers(head):
    with FaceRenderer(head, background="transparent") as r:
        rgba, numbers = r.render(head.params({}), triangles=True)
    assert rgba.shape[2] == 4
    assert np.array_equal(rgba[..., 3] > 0, numbers >= 0)


def test_pngs_keep_alpha_and_video_refuses_it(tmp_path):
    from PIL import Image

    rgba = np.zeros((24, 32, 4), np.uint8)
    rgba[4:10, 5:20] = [10, 200, 30, 255]
    write_png(tmp_path / "still.png", rgba)
    with Image.open(tmp_path / "still.png") as im:
        assert im.mode == "RGBA"
        assert np.array_equal(np.asarray(im), rgba)
    with PngSequenceWriter(tmp_path / "seq") as seq:
        seq.write(rgba)
        seq.write(rgba)
        with pytest.raises(RenderError, match=r"\(24, 32, 4\) uint8 array"):
            seq.write(rgba[..., :3])
    with Image.open(tmp_path / "seq" / "frame_000001.png") as im:
        assert im.mode == "RGBA"
    with (
        pytest.raises(RenderError, match="video has no alpha"),
        VideoWriter(tmp_path / "x.mp4", 30, (32, 24)) as video,
    ):
        video.write(rgba)
    assert not (tmp_path / "x.mp4").exists()
