"""Curves out (vtts.avatar.curves, vtts.avatar.sapi): each format's structure and values."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from vtts.avatar import ARKIT_NAMES, OCULUS_VISEMES, recipes
from vtts.avatar.arkit import ARKIT_INDEX
from vtts.avatar.curves import (
    FORMATS,
    arkit_weights,
    check_format,
    curves,
    oculus_weights,
    viseme_segments,
    write_curves,
)
from vtts.avatar.sapi import FROM_MPEG4, sapi_viseme
from vtts.errors import AvatarError
from vtts.face.miap import EXPRESSION_BASE, N_PARAMS, VISEME_BASE
from vtts.speech.timings import TimedPhone, TimedWord

from ..scripts import load_script

FPS = 25.0


def frames(n: int = 1) -> np.ndarray:
    return np.zeros((n, N_PARAMS))


def weight(w: np.ndarray, name: str) -> np.ndarray:
    return w[..., ARKIT_INDEX[name]]


def test_open_jaw_gives_jaw_open():
    p = frames(3)
    p[:, 2] = [0, 500, 1000]  # open_jaw in MNS
    w = arkit_weights(p)
    assert w.shape == (3, 52)
    assert weight(w, "jawOpen") == pytest.approx([0, 0.5, 1.0], abs=1e-4)
    others = np.delete(w, ARKIT_INDEX["jawOpen"], axis=1)
    assert not others.any()


def test_signs_choose_the_shape():
    p = frames(2)
    p[0, 18] = 512  # close_t_l_eyelid half way
    p[1, 18] = -256  # wide open
    p[0, 11] = 400  # raise_l_cornerlip up
    p[1, 11] = -250  # down
    w = arkit_weights(p)
    assert weight(w, "eyeBlinkLeft") == pytest.approx([0.5, 0], abs=1e-4)
    assert weight(w, "eyeWideLeft") == pytest.approx([0, 1], abs=1e-4)
    assert weight(w, "mouthSmileLeft")[0] > 0.2 and weight(w, "mouthSmileLeft")[1] == 0
    assert weight(w, "mouthFrownLeft")[1] > 0.2 and weight(w, "mouthFrownLeft")[0] == 0
    assert weight(w, "eyeBlinkRight").max() == 0  # the other eye stays


def test_the_inverse_of_every_shape_gives_it_back():
    """Each ARKit shape's FAP motion (the table read backwards) comes back as that shape alone;
    mouthPressLeft/Right move the same FAPs, so only their sum is determined."""
    m = recipes().fap_content()
    used = [j for j in range(52) if m[:, j].any()]
    p = frames(len(used))
    for i, j in enumerate(used):
        p[i, :68] = m[:, j]
    w = arkit_weights(p)
    twins = {ARKIT_INDEX["mouthPressLeft"], ARKIT_INDEX["mouthPressRight"]}
    for i, j in enumerate(used):
        if j in twins:
            assert w[i, sorted(twins)].sum() == pytest.approx(1, abs=1e-3)
            continue
        expected = np.zeros(52)
        expected[j] = 1
        assert w[i] == pytest.approx(expected, abs=1e-3), ARKIT_NAMES[j]


def test_the_whole_upper_lip_raised_is_both_upper_up_shapes():
    p = frames()
    for k in (4, 8, 9, 51, 55, 56):
        p[0, k - 1] = -150
    w = arkit_weights(p)[0]
    assert weight(w, "mouthUpperUpLeft") == pytest.approx(0.5, abs=1e-3)
    assert weight(w, "mouthUpperUpRight") == pytest.approx(0.5, abs=1e-3)


def test_visemes_and_expressions_are_their_recipes():
    t = recipes()
    p = frames(3)
    p[0, VISEME_BASE + 1] = 1.0  # p, b, m
    p[1, VISEME_BASE + 10] = 0.5  # half an A:
    p[2, EXPRESSION_BASE + 1] = 1.0  # joy
    w = arkit_weights(p)
    assert w[0] == pytest.approx(t.viseme(1).vector())
    assert weight(w[0], "mouthClose") > 0
    assert w[1] == pytest.approx(0.5 * t.viseme(10).vector())
    assert w[2] == pytest.approx(t.expression(1).vector())


def test_weights_are_clipped_to_one():
    p = frames(2)
    p[0, 2] = 3000  # far beyond the table
    p[0, VISEME_BASE + 10] = 1.0
    p[1, [3, 7, 8, 50, 54, 55]] = -1e300  # the whole upper lip, absurdly far
    w = arkit_weights(p)
    assert weight(w, "jawOpen")[0] == 1.0
    assert weight(w, "mouthUpperUpLeft")[1] == weight(w, "mouthUpperUpRight")[1] == 1.0
    assert w.min() >= 0 and w.max() <= 1


def test_a_table_with_large_blocks_is_solved_too():
    """A table of one's own may tie more shapes to one FAP than box_lstsq visits."""
    from vtts.avatar.arkit import parse_recipes

    path = Path(__file__).resolve().parents[2] / "vtts" / "data" / "arkit_recipes.tsv"
    names = ["mouthSmileLeft", "mouthSmileRight", "mouthDimpleLeft", "mouthDimpleRight",
             "mouthLeft", "mouthRight", "mouthShrugUpper", "mouthClose", "cheekPuff"]  # fmt: skip
    row = "fap\t64\t+\t100\t" + " ".join(f"{n}=0.1" for n in names) + "\tx\n"
    table = parse_recipes(path.read_text(encoding="utf-8") + row)
    p = frames()
    p[0, 63] = 100  # bend_nose, now tied to nine shapes... and through them to the corners
    w = arkit_weights(p, table)
    assert w.min() >= 0 and w.max() <= 1 and w.sum() > 0


def test_oculus_weights_and_silence():
    p = frames(2)
    p[0, VISEME_BASE + 1] = 1.0
    p[1, VISEME_BASE + 10] = 0.25
    p[1, VISEME_BASE + 11] = 0.25
    w = oculus_weights(p)
    assert w.shape == (2, 15)
    assert w[0, 1] == 1 and w[0, 0] == 0  # PP, no silence
    assert w[1, 0] == pytest.approx(0.5)  # silence takes what is left
    assert w[1, 10] == w[1, 11] == 0.25


def test_sapi_visemes_from_phones_and_visemes():
    assert [sapi_viseme(v) for v in range(15)] == list(FROM_MPEG4)
    assert sapi_viseme(1, "p") == 21
    assert sapi_viseme(8, "l") == 14 and sapi_viseme(8, "n") == 19
    assert sapi_viseme(3, "D") == 17  # espeak's D is ð
    assert sapi_viseme(4, "D") == 19  # ARPAbet's D (viseme 4) is d
    assert sapi_viseme(10, "aU") == 9 and sapi_viseme(10, "aI") == 11
    assert sapi_viseme(13, "OI") == 10 and sapi_viseme(13, "AO1") == 3
    assert sapi_viseme(5, "h") == 12
    assert sapi_viseme(11, "ə") == 1
    assert sapi_viseme(7, "zzz?") == 15  # unknown phone: the viseme's usual id
    with pytest.raises(AvatarError, match="0–14"):
        sapi_viseme(15)


def test_segments_from_phones_fill_silence():
    phones = [TimedPhone(0.1, 0.2, 1, "b"), TimedPhone(0.2, 0.35, 10, "A:")]
    segs = viseme_segments(frames(15), FPS, phones)  # 0.6 s
    assert [(s.viseme, round(s.start, 3), round(s.end, 3)) for s in segs] == [
        (0, 0.0, 0.1), (1, 0.1, 0.2), (10, 0.2, 0.35), (0, 0.35, 0.6)
    ]  # fmt: skip


def test_event_formats_from_phones():
    phones = [
        TimedPhone(0.1, 0.2, 1, "b"),
        TimedPhone(0.2, 0.3, 1, "m"),  # same viseme: merged
        TimedPhone(0.3, 0.5, 10, "A:"),
    ]
    az = curves("azure", frames(15), FPS, phones)
    assert az == [
        {"audio_offset_ms": 0.0, "viseme_id": 0},
        {"audio_offset_ms": 100.0, "viseme_id": 21},
        {"audio_offset_ms": 300.0, "viseme_id": 2},
        {"audio_offset_ms": 500.0, "viseme_id": 0},
    ]
    th = curves("talkinghead", frames(15), FPS, phones)
    assert th == {
        "visemes": ["sil", "PP", "aa", "sil"],
        "vtimes": [0.0, 100.0, 300.0, 500.0],
        "vdurations": [100.0, 200.0, 200.0, 100.0],
    }


def test_talkinghead_words():
    """say's words become TalkingHead's words/wtimes/wdurations (ms, in time order); none is
    an empty track, and no words at all (play) leaves the keys out."""
    phones = [TimedPhone(0.1, 0.2, 1, "b"), TimedPhone(0.2, 0.3, 10, "A:")]
    words = [TimedWord(0.4, 0.55, "up"), TimedWord(0.1, 0.3, "Bob")]
    th = curves("talkinghead", frames(15), FPS, phones, words)
    assert th["words"] == ["Bob", "up"]
    assert th["wtimes"] == [100.0, 400.0] and th["wdurations"] == [200.0, 150.0]
    assert th["visemes"] == ["sil", "PP", "aa", "sil"]
    empty = curves("talkinghead", frames(15), FPS, phones, [])
    assert empty["words"] == empty["wtimes"] == empty["wdurations"] == []
    assert "words" not in curves("talkinghead", frames(15), FPS, phones)
    assert "words" not in curves("azure", frames(15), FPS, phones, words)[0]


def test_event_formats_from_the_viseme_track():
    """play has no phones: each frame's strongest viseme, silence included."""
    p = frames(10)
    p[3:6, VISEME_BASE + 1] = 1.0
    p[6:8, VISEME_BASE + 14] = 0.8
    th = curves("talkinghead", p, FPS)
    assert th["visemes"] == ["sil", "PP", "U", "sil"]
    assert th["vtimes"] == [0.0, 120.0, 240.0, 320.0]
    assert th["vdurations"] == [120.0, 120.0, 80.0, 80.0]
    az = curves("azure", p, FPS)
    assert [e["viseme_id"] for e in az] == [0, 21, 4, 0]


def test_frame_formats_and_writing(tmp_path):
    p = frames(4)
    p[:, 2] = 500
    out = tmp_path / "c.json"
    write_curves(out, "arkit", p, FPS)
    data = json.loads(out.read_text())
    assert data["names"] == list(ARKIT_NAMES) and data["fps"] == FPS
    assert len(data["frames"]) == 4 and all(len(f) == 52 for f in data["frames"])
    assert data["frames"][0][ARKIT_INDEX["jawOpen"]] == 0.5
    assert data["head_rotation"] == [[0.0, 0.0, 0.0]] * 4
    p[1, 47:50] = [10000, -5000, 2000]  # head_pitch, head_yaw, head_roll in AU
    assert curves("arkit", p, FPS)["head_rotation"][1] == [0.1, -0.05, 0.02]
    ocu = curves("oculus", p, FPS)
    assert ocu["names"] == list(OCULUS_VISEMES) and ocu["frames"][0][0] == 1.0
    assert [p.name for p in tmp_path.iterdir()] == ["c.json"]  # no temporary left


def test_formats_and_errors():
    assert set(FORMATS) == {"arkit", "oculus", "azure", "talkinghead"}
    assert check_format(" ARKit ") == "arkit"
    with pytest.raises(AvatarError, match="expected one of arkit, oculus, azure, talkinghead"):
        check_format("bvh")
    with pytest.raises(AvatarError, match="must be \\(n, 90\\)"):
        curves("arkit", np.zeros((3, 68)), FPS)
    with pytest.raises(AvatarError, match="finite"):
        curves("arkit", np.full((1, N_PARAMS), np.nan), FPS)
    with pytest.raises(AvatarError, match="frame rate"):
        curves("oculus", frames(), 0)


def _personalities():
    """The bundled heads' recipes (models/src/personalities.py): visemes and expressions as FAP
    values, what the modeler dialled in."""
    return load_script("models/src/personalities.py", "_vtts_personalities")


@pytest.mark.parametrize("head", ["cybatt", "lotta"])
def test_the_table_agrees_with_itself_on_the_bundled_heads(head):
    """A bundled head's viseme or expression, given as its FAP values, comes out of the FAP rows
    close to the table's own row for it (cosine of the 52 weights): the FAP amplitudes and the
    viseme/expression rows tell one story."""
    heads = _personalities()
    visemes = getattr(heads, f"{head}_visemes")()
    expressions = getattr(heads, f"{head}_expressions")()
    t = recipes()
    names = ["joy", "sadness", "anger", "fear", "disgust", "surprise"]
    cases = [(t.viseme(v), visemes[v], 0.85) for v in range(1, 15)]
    cases += [(t.expression(e), expressions[n], 0.75) for e, n in enumerate(names, start=1)]
    for row, recipe, least in cases:
        p = frames()
        for k, value in recipe.faps.items():
            p[0, k - 1] = value
        got, want = arkit_weights(p)[0], row.vector()
        cosine = got @ want / np.linalg.norm(got) / np.linalg.norm(want)
        assert cosine >= least, (row.kind, row.number, round(cosine, 2))
