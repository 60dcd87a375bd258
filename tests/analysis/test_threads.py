"""The analysis runs on one BLAS thread (vtts.threads): fast beside llvmpipe, and repeatable."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_info

import vtts
from vtts.analysis import Estimator
from vtts.analysis.track import track
from vtts.threads import one_blas_thread


def _blas_threads() -> list[int]:
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_one_blas_thread_limits_every_blas_library_and_restores_them():
    import scipy.linalg  # noqa: F401  (SciPy's OpenBLAS as well as NumPy's)

    before = _blas_threads()
    assert len(before) >= 1
    with one_blas_thread():
        assert _blas_threads() == [1] * len(before)
    assert _blas_threads() == before


@pytest.fixture(scope="module")
def cybatt():
    return vtts.load_model("cybatt")


def test_the_estimator_and_the_tracker_solve_on_one_thread(cybatt, monkeypatch):
    seen: list[list[int]] = []
    solve = Estimator._solve

    def spy(self, *args, **kwargs):
        seen.append(_blas_threads())
        return solve(self, *args, **kwargs)

    monkeypatch.setattr(Estimator, "_solve", spy)
    size = (176, 144)
    est = Estimator(cybatt, size=size, unknowns=(3, 48))
    image, _ = est.render(1)
    frame = np.clip(np.round(image[..., :3]), 0, 255).astype(np.uint8)
    est.estimate(frame)
    tracked = track([frame] * 2, fps=25.0, model=cybatt, unknowns=(3, 48))
    assert len(tracked.analysis.frames) == 2
    assert seen and all(set(s) == {1} for s in seen)
    assert (tracked.analysis.psnr() > 40).all()  # the model matched to its own image
