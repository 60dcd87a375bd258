"""The coder's base steps measured on the model: one step of each FAP changes the face's image
about alike, where MPEG-4's steps differ by orders of magnitude."""

from __future__ import annotations

import numpy as np
import pytest

import vtts
from vtts.analysis import TABLE1_FAPS
from vtts.analysis.steps import analysis_steps, coding_steps
from vtts.errors import AnalysisError
from vtts.face import N_PARAMS
from vtts.fap.coding import MAX_BASE_STEP, decode, encode, read_header, reconstruct
from vtts.fap.stream import FapStream
from vtts.fap.table import FAPS
from vtts.render.camera import Camera
from vtts.render.renderer import FaceRenderer

SIZE = (352, 288)
LUMA = np.array([0.299, 0.587, 0.114])


@pytest.fixture(scope="module")
def cybatt():
    return vtts.load_model("cybatt")


def _changes(renderer: FaceRenderer, steps: dict) -> np.ndarray:
    """The summed squared luminance change of the rendered frame from neutral when each FAP
    of ``steps`` alone moves by its step."""
    base = renderer.render(np.zeros(N_PARAMS)) @ LUMA
    out = []
    for k, step in steps.items():
        p = np.zeros(N_PARAMS)
        p[k - 1] = step
        out.append(float(((renderer.render(p) @ LUMA - base) ** 2).sum()))
    return np.array(out)


def test_one_step_of_each_fap_changes_the_face_about_alike(cybatt):
    with FaceRenderer(cybatt, size=SIZE) as r:
        steps = coding_steps(cybatt, r.camera, SIZE, TABLE1_FAPS)
        assert sorted(steps) == sorted(TABLE1_FAPS)
        assert all(isinstance(s, int) and 1 <= s <= MAX_BASE_STEP for s in steps.values())
        mpeg4 = _changes(r, {k: FAPS[k - 1].quant_step for k in TABLE1_FAPS})
        face = _changes(r, steps)
    # MPEG-4's steps: an eyelid's step changes the face by a few gray levels squared, the
    # head's pitch by 2·10^5 (a spread of 30,000); measured on the model, the spread is about
    # 30 (the linear model the steps come from misses what the jaw and lids uncover)
    spread = face.max() / face.min()
    assert mpeg4.max() / mpeg4.min() > 300 * spread, (mpeg4, face)
    assert spread < 50, face
    # the lips' and eyebrows' steps grow, the head's rotation keeps about its own
    for k in (12, 13, 35, 36):
        assert steps[k] >= 4 * FAPS[k - 1].quant_step, steps
    for k in (48, 49, 50):
        assert 0.25 <= steps[k] / FAPS[k - 1].quant_step <= 2, steps


def test_translation_steps_are_in_es_units_and_a_stream_carries_the_steps(cybatt):
    with FaceRenderer(cybatt, size=SIZE) as r:
        camera = r.camera
    unknowns = (48, 49, 50, "tx", "ty", "tz", 3, 12)
    steps = coding_steps(cybatt, camera, SIZE, unknowns)
    assert set(steps) == set(unknowns)
    # the head moving sideways moves every pixel; towards the camera, few of them much
    assert steps["tz"] > steps["tx"] and steps["tz"] > steps["ty"]
    n = 20
    values, mask = np.zeros((n, 68)), np.zeros((n, 68), bool)
    for k in (3, 12, 48, 49, 50):
        values[:, k - 1] = np.linspace(0, 40 * steps[k], n).round()
        mask[:, k - 1] = True
    translation = np.linspace([0, 0, 0], [30.0, -12.0, 50.0], n)
    stream = FapStream(25.0, "t", values, mask, translation=translation)
    data = encode(stream, steps=steps)
    h = read_header(data)
    assert h.base_steps == tuple(steps[k] for k in h.low)
    assert h.translation_base_steps == tuple(steps[a] for a in ("tx", "ty", "tz"))
    again = decode(data)
    expected = reconstruct(stream, steps=steps)
    assert np.array_equal(again.values, expected.values)
    assert np.array_equal(again.translation, expected.translation)
    # within half a step of each value, on each FAP's own grid
    for k in (3, 12, 48):
        assert np.abs(again.values[:, k - 1] - values[:, k - 1]).max() <= steps[k] / 2
    assert len(data) < len(encode(stream))  # the lips' finer MPEG-4 steps cost more here


@pytest.mark.parametrize(
    "steps, fragment",
    [
        ({2: 4}, "2 is not a low-level FAP"),
        ({"tq": 4}, "'tq' is not a low-level FAP"),
        ({3: 0}, "within 1–"),
        ({3: 1 << 21}, "within 1–"),
        ({3: 1.5}, "must be a whole number"),
        ({3: True}, "must be a whole number"),
        ([(3, 4)], "steps must map FAPs"),
    ],
)
def test_bad_steps_are_a_clear_error(steps, fragment):
    values, mask = np.zeros((2, 68)), np.zeros((2, 68), bool)
    mask[:, 2] = True
    stream = FapStream(25.0, "t", values, mask)
    with pytest.raises(vtts.errors.FapError, match=fragment.replace("(", r"\(")):
        encode(stream, steps=steps)


def test_a_model_out_of_view_is_a_clear_error(cybatt):
    away = Camera(400.0, 400.0, 176.0, 144.0, pose=np.diag([1.0, 1.0, 1.0, 1.0]))
    away.pose[:3, 3] = [0.0, 0.0, -1e4]  # far behind the head, looking away from it
    with pytest.raises(AnalysisError, match="covers no pixel"):
        coding_steps(cybatt, away, SIZE, TABLE1_FAPS)


def test_an_analysis_without_frames_has_no_pose(cybatt):
    from vtts.analysis import Analysis

    empty = Analysis([], TABLE1_FAPS, 25.0, Camera(1, 1, 0, 0))
    with pytest.raises(AnalysisError, match="without frames"):
        analysis_steps(empty, cybatt, SIZE)
