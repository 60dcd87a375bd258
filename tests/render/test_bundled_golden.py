"""Golden images of the bundled heads (352 × 288, 2× supersampled like `vtts render` stills):
neutral, each expression at its climax, each viseme, eyes closed, head turned left and pitched
down. `models/src/contact_sheet.py` lays them out in docs/heads.png."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.face import load_model
from vtts.render import FaceRenderer

MODELS = ("cybatt", "lotta")
EXPRESSIONS = ("joy", "sadness", "anger", "fear", "disgust", "surprise")

#: pose name → (FAPs, visemes, expressions)
POSES: dict[str, tuple[dict, dict, dict]] = {
    "neutral": ({}, {}, {}),
    **{e: ({}, {}, {e: 1.0}) for e in EXPRESSIONS},
    **{f"viseme{v:02d}": ({}, {v: 1.0}, {}) for v in range(1, 15)},
    "eyes-closed": ({19: 1024, 20: 1024, 21: 1024, 22: 1024}, {}, {}),
    "head-left": ({49: 30000}, {}, {}),
    "head-down": ({48: 20000}, {}, {}),
}


@pytest.fixture(scope="module")
def renderers():
    made = {}
    yield lambda name: made.setdefault(
        name, (m := load_model(name), FaceRenderer(m, size=(352, 288), supersample=2))
    )
    for _, r in made.values():
        r.close()


@pytest.mark.parametrize("pose", list(POSES))
@pytest.mark.parametrize("model_name", MODELS)
def test_golden_bundled_head(renderers, golden, model_name, pose):
    model, renderer = renderers(model_name)
    faps, visemes, expressions = POSES[pose]
    img = renderer.render(model.params(faps, visemes=visemes, expressions=expressions))
    assert img.shape == (288, 352, 3) and img.dtype == np.uint8
    golden(f"{model_name}-{pose}", img)
