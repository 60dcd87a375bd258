"""scripts/fitting_figure.py, the contact sheet of docs/fitting.md: every photo's cell square."""

from __future__ import annotations

import numpy as np
import pytest

from ..scripts import load_script

fitting_figure = load_script("scripts/fitting_figure.py")


@pytest.mark.parametrize(
    ("size", "box"),
    [
        ((480, 640), (200, 300, 300, 400)),  # a face in the middle: the full margin
        ((480, 640), (0, 0, 150, 160)),  # at the top-left corner: moved inside
        ((500, 375), (250, 20, 370, 160)),  # at the right edge, near the top
        ((300, 300), (0, 0, 300, 300)),  # a face that fills the photo: shrunk to it
    ],
)
def test_the_crop_around_a_face_is_square_and_inside_the_photo(size, box):
    h, w = size
    image = np.arange(h * w).reshape(h, w)
    crop = fitting_figure.crop_to_face(image, box)
    assert crop.shape[0] == crop.shape[1] > 0
    # a window of the photo itself, holding the face box's centre
    top, left = divmod(int(crop[0, 0]), w)
    cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
    assert left <= cx <= left + crop.shape[1] and top <= cy <= top + crop.shape[0]
    assert crop.shape[0] <= min(h, w)
