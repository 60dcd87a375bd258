"""scripts/appearance_oracle.py: a texture that changes with the frame, as oracles of Equation 18
(docs/analysis.md, "Appearance that changes with the frame")."""

from __future__ import annotations

import numpy as np

from ..scripts import load_script

oracle = load_script("scripts/appearance_oracle.py")


def test_a_frames_residual_is_what_the_camera_shows_beyond_the_texture():
    rng = np.random.default_rng(0)
    n = 12
    texture = rng.uniform(0, 255, (n, 3))
    at = rng.integers(0, 6, (4, 40))  # only texels 0..5 are seen
    weights = rng.uniform(0.1, 1, (4, 40))
    weights /= weights.sum(0)
    drawn = np.einsum("kn,knc->nc", weights, texture[at])
    res = oracle.frame_residuals([(7, at, weights, drawn + [10.0, -5.0, 0.0])], texture, n)
    residual, weight = res[7]
    assert np.allclose(residual[:6], [10.0, -5.0, 0.0], atol=1e-4)
    assert np.all(residual[6:] == 0) and np.all(weight[6:] == 0)
    assert np.isclose(weight.sum(), 40.0)


def test_the_regression_finds_a_linear_appearance_and_leaves_unseen_texels_at_zero():
    rng = np.random.default_rng(1)
    n, t = 5, 30
    features = rng.normal(size=(t, 2))
    coef = rng.normal(size=(n, 3, 3)) * 10
    phi = np.hstack([np.ones((t, 1)), features])
    residuals = [np.einsum("nkc,k->nc", coef, row).astype(np.float32) for row in phi]
    weights = [np.r_[np.ones(n - 1), 0.0].astype(np.float32) for _ in range(t)]
    found = oracle.regress(residuals, weights, features, ridge=1e-6)
    assert np.allclose(found[: n - 1], coef[: n - 1], atol=1e-3)
    assert np.allclose(found[n - 1], 0.0)
    # the ridge pulls the coefficients, not the constant
    held = oracle.regress(residuals, weights, features, ridge=1e3)
    assert np.abs(held[: n - 1, 1:]).max() < 0.1 * np.abs(coef[: n - 1, 1:]).max()


def test_principal_components_keep_what_k_numbers_per_frame_can_say():
    rng = np.random.default_rng(2)
    n, t = 8, 10
    a, b = rng.normal(size=(2, n, 3))
    coefs = rng.normal(size=(t, 2))
    residuals = [(c0 * a + c1 * b).astype(np.float32) for c0, c1 in coefs]
    weights = [np.ones(n, np.float32)] * t
    two = oracle.principal(residuals, weights, 2)
    assert np.allclose(two, np.stack(residuals), atol=1e-4)
    one = oracle.principal(residuals, weights, 1)
    assert np.abs(one - np.stack(residuals)).max() > 0.1


def test_a_video_that_cannot_be_read_is_said_without_a_traceback(tmp_path, capsys):
    bad = tmp_path / "clip.mp4"
    bad.write_bytes(b"not a video")
    assert oracle.main([str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("appearance_oracle: ") and "clip.mp4" in err
    assert "Traceback" not in err
