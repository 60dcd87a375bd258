"""vtts.warm: heads and renderers kept between the commands of one process, handed out again as
a new one would start."""

from __future__ import annotations

import os

import numpy as np
import pytest

from vtts import warm
from vtts.errors import RenderError
from vtts.face import N_PARAMS, FaceModel
from vtts.render import FaceRenderer

os.environ.setdefault("LP_NUM_THREADS", "1")


def test_a_kept_renderer_comes_back_as_a_new_one_starts():
    with warm.Warm() as w:
        assert warm.active() is w
        head = w.load_model("cybatt")
        assert w.load_model("cybatt") is head and w.loads == 1
        with w.renderer([head], size=(96, 64)) as r:
            first = r.render(np.zeros(N_PARAMS)).copy()
            home = r.model_matrix(0)
            moved = home.copy()
            moved[0, 3] += 0.05  # a stream's head translation moved the head
            r.pose(np.zeros(N_PARAMS), roots=[moved])
            assert not np.array_equal(r.render(), first)
        with w.renderer([head], size=(96, 64)) as again:
            assert again is r  # the same scene, not closed by the first command's with
            assert np.array_equal(again.model_matrix(0), home)
            assert np.array_equal(again.render(), first)
        with w.renderer([head], size=(64, 48)):
            pass
        assert w.builds == 2  # another size is another renderer
    assert warm.active() is None


def test_outside_a_warm_commands_load_and_build_afresh():
    head = warm.load_model("cybatt")
    assert isinstance(head, FaceModel) and warm.load_model("cybatt") is not head
    with warm.renderer([head], size=(64, 48)) as r:
        assert isinstance(r, FaceRenderer)
    with pytest.raises(RenderError, match="closed"):  # closed by its with, as before
        r.render()
