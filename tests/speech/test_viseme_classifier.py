"""The viseme classifier's pieces: the smoothing with minimum durations, the features, the
weights file (``vtts/data/viseme_classifier.npz``) and its bad copies."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from vtts.errors import SpeechError
from vtts.resources import package_data
from vtts.speech.viseme_classifier import (
    HOP,
    N_MELS,
    OFFSETS,
    RATE,
    WEIGHTS,
    frame_features,
    load_classifier,
    smooth,
)


def _best(scores: np.ndarray, min_frames: np.ndarray, switch: float) -> float:
    """The best total by trying every sequence (the first and last runs may be short)."""
    n, k = scores.shape
    best = -np.inf
    for seq in itertools.product(range(k), repeat=n):
        s = np.array(seq)
        edges = np.flatnonzero(np.diff(s)) + 1
        starts, ends = np.concatenate([[0], edges]), np.concatenate([edges, [n]])
        inner = zip(starts[1:-1], ends[1:-1], strict=True)
        if all(b - a >= min_frames[s[a]] for a, b in inner):
            best = max(best, scores[np.arange(n), s].sum() - switch * edges.size)
    return best


def test_smoothing_finds_the_best_sequence_with_minimum_durations() -> None:
    rng = np.random.default_rng(3)
    m = np.array([1, 2, 3])
    for _ in range(15):
        scores = rng.normal(0, 2, (6, 3))
        got = smooth(scores, m, 1.0).astype(int)
        total = scores[np.arange(6), got].sum() - np.count_nonzero(np.diff(got))
        assert total == pytest.approx(_best(scores, m, 1.0))
    # a flicker shorter than its minimum is smoothed away
    scores = np.zeros((10, 3))
    scores[:, 0] = 1.0
    scores[4, 2] = 2.5  # alone it wins a frame; three frames of viseme 2 cost more
    assert smooth(scores, m, 0.5).tolist() == [0] * 10
    assert smooth(np.zeros((0, 15)), np.ones(15), 1.0).size == 0


def test_features_are_independent_of_the_level() -> None:
    t = np.arange(RATE) / RATE
    x = (0.3 * np.sin(2 * np.pi * 220 * t) * (t > 0.3)).astype(np.float32)
    x += np.random.default_rng(0).normal(0, 1e-4, x.size).astype(np.float32)
    f = frame_features(x)
    assert f.shape == (RATE // HOP, N_MELS + 1) and np.isfinite(f).all()
    g = frame_features(x * np.float32(0.05))
    assert np.allclose(f[40:], g[40:], atol=0.05)  # where the tone sounds


def test_the_weights_file_is_small_and_whole() -> None:
    path = package_data(WEIGHTS)
    assert path.stat().st_size < 5_000_000
    c = load_classifier()
    assert c.weights[0].shape[0] == len(OFFSETS) * (N_MELS + 1) == c.mean.size
    assert c.weights[-1].shape[1] == 15 and c.min_frames.shape == (15,)


def test_a_bad_weights_file_is_a_clear_error(tmp_path: Path) -> None:
    bad = tmp_path / "w.npz"
    np.savez(bad, layers=np.int64(1), mean=np.zeros(3))
    with pytest.raises(SpeechError, match=f"{bad}: not a viseme classifier's weights"):
        load_classifier(bad)
    with pytest.raises(SpeechError, match="not a viseme classifier's weights"):
        load_classifier(tmp_path / "missing.npz")
