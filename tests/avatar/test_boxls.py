"""vtts.avatar.boxls: exact box-bounded least squares by faces, against SciPy's BVLS."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from vtts.avatar.arkit import recipes
from vtts.avatar.boxls import box_lstsq
from vtts.avatar.curves import RIDGE, _blocks


def reference(a: np.ndarray, f: np.ndarray, ridge: float) -> np.ndarray:
    c = a.shape[1]
    stacked = np.vstack([a, np.sqrt(ridge) * np.eye(c)])
    return np.stack(
        [
            lsq_linear(stacked, np.concatenate([fi, np.zeros(c)]), bounds=(0, 1), method="bvls").x
            for fi in f
        ]
    )


def cost(a, f, w, ridge):
    return np.sum((w @ a.T - f) ** 2, axis=1) + ridge * np.sum(w * w, axis=1)


@pytest.mark.parametrize("shape", [(1, 1), (1, 2), (3, 2), (6, 3), (8, 5), (2, 4)])
def test_random_problems_match_bvls(shape):
    rng = np.random.default_rng(sum(shape))
    a = rng.normal(size=shape)
    f = rng.normal(scale=2.0, size=(40, shape[0]))
    f[5] = f[3]  # a repeated frame
    w = box_lstsq(a, f, 1e-3)
    ref = reference(a, f, 1e-3)
    assert w.min() >= 0 and w.max() <= 1
    # the same minimum (where BVLS stops a hair early, it is the higher one)
    assert np.all(cost(a, f, w, 1e-3) <= cost(a, f, ref, 1e-3) + 1e-9)
    assert w == pytest.approx(ref, abs=1e-5)


def test_the_recipe_blocks_match_bvls():
    t = recipes()
    content, scale = t.fap_content(), t.fap_scale()
    rng = np.random.default_rng(7)
    for rows, cols in _blocks(content):
        a = content[np.ix_(rows, cols)] / scale[rows, None]
        f = rng.normal(scale=0.7, size=(25, len(rows)))
        w = box_lstsq(a, f, RIDGE)
        assert np.all(cost(a, f, w, RIDGE) <= cost(a, f, reference(a, f, RIDGE), RIDGE) + 1e-9)


def test_bad_arguments():
    with pytest.raises(ValueError, match="ridge"):
        box_lstsq(np.eye(2), np.zeros((1, 2)), 0.0)
    with pytest.raises(ValueError, match="unknowns"):
        box_lstsq(np.eye(9), np.zeros((1, 9)), 1e-3)
    with pytest.raises(ValueError, match="must be \\(n, 2\\)"):
        box_lstsq(np.eye(2), np.zeros((1, 3)), 1e-3)
