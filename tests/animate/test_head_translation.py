"""A stream's head translation on a model: resampled with the parameters, turned into root poses
in the model's own ES."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.animate.fapstream import (
    MissingTableWarning,
    head_roots,
    model_roots,
    stream_params,
    translated_root,
)
from vtts.errors import FapError
from vtts.fap import FapStream, Fapu

FAPU = Fapu(irisd=0.001, es=0.002, ens=0.003, mns=0.004, mw=0.005)


def stream(translation: np.ndarray | None, fps: float = 25.0) -> FapStream:
    n = 3 if translation is None else len(translation)
    mask = np.zeros((n, 68), dtype=bool)
    mask[:, 2] = True
    return FapStream(
        fps=fps, name="t", values=np.zeros((n, 68)), mask=mask, translation=translation
    )


def test_translated_root_adds_the_offset_in_model_units() -> None:
    root = np.eye(4)
    root[:3, 3] = [1.0, -2.0, 0.5]  # the renderer's roots: translations
    out = translated_root(root, [100.0, -50.0, 10.0], FAPU)
    expect = root.copy()
    expect[:3, 3] += [0.2, -0.1, 0.02]
    assert np.allclose(out, expect) and out is not root
    assert np.array_equal(root[:3, 3], [1.0, -2.0, 0.5])  # not changed in place
    assert np.array_equal(translated_root(root, np.zeros(3), FAPU), root)


def test_translated_root_moves_along_the_roots_own_axes() -> None:
    root = np.eye(4)
    root[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # 90° about z
    root[:3, 3] = [5.0, 0, 0]
    out = translated_root(root, [500.0, 0, 0], FAPU)  # 1 model unit along the model's x
    assert np.allclose(out[:3, 3], [5.0, 1.0, 0.0])
    assert np.allclose(
        out, root @ np.array([[1, 0, 0, 1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    )


def test_head_roots_one_per_frame_and_bad_input() -> None:
    t = np.array([[0.0, 0, 0], [10, 0, 0], [0, 20, 0]])
    roots = head_roots(np.eye(4), t, FAPU)
    assert roots.shape == (3, 4, 4)
    assert np.allclose(roots[:, :3, 3], t * FAPU.es)
    assert np.array_equal(roots[:, :3, :3], np.repeat(np.eye(3)[None], 3, axis=0))
    with pytest.raises(FapError, match=r"root pose has shape \(4, 4\)"):
        head_roots(np.eye(3), t, FAPU)
    with pytest.raises(FapError, match=r"shape \(n, 3\)"):
        head_roots(np.eye(4), t[:, :2], FAPU)
    with pytest.raises(FapError, match="needs the model's FAPUs"):
        head_roots(np.eye(4), t, None)  # type: ignore[arg-type]


def test_stream_params_resamples_the_translation() -> None:
    t = np.cumsum(np.random.default_rng(0).normal(0, 20, size=(10, 3)), axis=0)
    sp = stream_params(stream(t), [])
    assert np.array_equal(sp.translation, t) and sp.translation is not t
    up = stream_params(stream(t), [], fps=50.0)
    assert up.translation.shape == (20, 3) == (up.n_frames, 3)
    assert np.array_equal(up.translation[::2], t)
    assert np.allclose(up.translation[1:-1:2], (t[:-1] + t[1:]) / 2)
    assert stream_params(stream(None), []).translation is None


def test_model_roots() -> None:
    t = np.array([[0.0, 0, 0], [100, 0, 0]])
    sp = stream_params(stream(t), [])
    root = np.eye(4)
    roots = model_roots(sp, root, FAPU, "m")
    assert np.allclose(roots[1, :3, 3], [0.2, 0, 0])
    assert model_roots(stream_params(stream(None), []), root, FAPU) is None
    with pytest.warns(MissingTableWarning, match="model m has no FAPUs.*translation is ignored"):
        assert model_roots(sp, root, None, "m") is None
