"""vtts say with the bundled personalities: closures in the mesh, personal timing."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.animate.timeline import build_timeline
from vtts.face import load_model
from vtts.face.miap import EXPRESSION_BASE, N_PARAMS
from vtts.utterance import prepare_utterance

TEXT = "<surprise 3s> My mom bought a big map, maybe a bamboo boat, by the pub."


@pytest.fixture(scope="module")
def models():
    return load_model("cybatt"), load_model("lotta")


@pytest.fixture(scope="module")
def utterance():
    return prepare_utterance(TEXT)


def lip_gap(model, params) -> float:
    """Vertical distance between the inner lip midpoints (feature points 2.2 and 2.3)."""
    fp = model.tables.feature_points
    pose = model.engine.deform(params)
    (nu, vu), (nl, vl) = fp["2.2"], fp["2.3"]
    up = pose.points.get(nu, model.neutral_points(nu))[vu]
    lo = pose.points.get(nl, model.neutral_points(nl))[vl]
    return float(up[1] - lo[1])


@pytest.mark.parametrize("index", [0, 1])
def test_lips_close_at_every_bilabial_centre_under_surprise(models, utterance, index):
    model = models[index]
    neutral = lip_gap(model, np.zeros(N_PARAMS))
    surprised = np.zeros(N_PARAMS)
    surprised[EXPRESSION_BASE + 6] = 1.0
    assert lip_gap(model, surprised) > neutral + 0.01  # surprise alone opens the mouth
    tl = build_timeline(
        model, utterance.phones, utterance.bookmarks, utterance.duration, autonomous=False
    )
    assert len(tl.bilabial_centres) >= 10
    for c in tl.bilabial_centres:
        frame = tl.params[int(round(c * tl.fps))]
        assert frame[EXPRESSION_BASE + 6] == 0.0 or c < 0.2
        assert lip_gap(model, frame) <= neutral + 0.002, f"lips open at {c:.3f} s"
    # and surprise is there in between
    assert tl.params[:, EXPRESSION_BASE + 6].max() > 0.9


def test_two_models_blink_at_different_times_and_smile_differently(models, utterance):
    a, b = (build_timeline(m, utterance.phones, [], 20.0, seed=0) for m in models)
    blinks_a = [s for s, _ in a.events["blink"]]
    blinks_b = [s for s, _ in b.events["blink"]]
    assert blinks_a != blinks_b
    assert len(blinks_b) > len(blinks_a)  # lotta blinks more often
    from vtts.speech.bookmarks import Bookmark

    smile = [Bookmark("expression", "joy", duration=1.0, time=0.5)]
    ea, eb = (
        build_timeline(m, [], smile, 4.0, autonomous=False).params[:, EXPRESSION_BASE + 1]
        for m in models
    )
    assert not np.allclose(ea, eb)
    assert np.argmax(eb > 0.5) < np.argmax(ea > 0.5)  # lotta's smile comes faster
