"""The ARKit names, the Oculus visemes and the recipe table (vtts.avatar.arkit)."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.avatar import ARKIT_NAMES, OCULUS_VISEMES, mpeg4_viseme, oculus_viseme, recipes
from vtts.avatar.arkit import ARKIT_INDEX, parse_recipes
from vtts.errors import AvatarError
from vtts.fap import fap

HEADER = "kind\tnumber\tsign\tamplitude\tshapes\tnote\n"


def test_arkit_names_are_apples_52():
    assert len(ARKIT_NAMES) == 52 == len(set(ARKIT_NAMES))
    assert ARKIT_NAMES[:2] == ("eyeBlinkLeft", "eyeLookDownLeft")
    assert ARKIT_NAMES[-1] == "tongueOut"
    # every sided name has its mirror
    for name in ARKIT_NAMES:
        if name.endswith("Left"):
            assert name.removesuffix("Left") + "Right" in ARKIT_INDEX


def test_oculus_visemes_follow_mpeg4_order():
    assert len(OCULUS_VISEMES) == 15
    assert oculus_viseme(0) == "viseme_sil"
    assert oculus_viseme(1) == "viseme_PP"
    assert oculus_viseme(10) == "viseme_aa"
    for v in range(15):
        assert mpeg4_viseme(oculus_viseme(v)) == v
    assert mpeg4_viseme("kk") == 5 == mpeg4_viseme("KK")
    with pytest.raises(AvatarError, match="unknown Oculus viseme 'xx'"):
        mpeg4_viseme("xx")
    with pytest.raises(AvatarError, match="0–14"):
        oculus_viseme(15)


def test_table_rows_named_in_the_issue():
    t = recipes()
    assert dict(t.fap(3).shapes) == {"jawOpen": 1.0}
    assert t.fap(3).amplitude == 1000
    assert "eyeBlinkLeft" in t.fap(19).shapes
    assert "eyeWideLeft" in t.fap(19, -1).shapes
    assert "mouthStretchLeft" in t.fap(6).shapes
    assert {"mouthClose", "mouthPressLeft", "mouthPressRight"} <= set(t.viseme(1).shapes)
    assert t.viseme(0).shapes == {}
    assert "mouthSmileLeft" in t.expression(1).shapes
    # head rotations have no blendshape
    assert t.fap(48) is None and t.fap(48, -1) is None
    # per unit: one FAP unit of open_jaw is a thousandth of jawOpen
    assert t.fap(3).per_unit() == pytest.approx({"jawOpen": 1e-3})


def test_table_directions_agree_with_the_fap_table():
    for r in recipes().fap_rows():
        if r.sign < 0:
            assert fap(r.number).bidirectional
        assert all(0 < w <= 1 for w in r.shapes.values())


def test_shares_of_a_shape_add_up_to_one():
    """Every ARKit shape the FAP rows use reaches 1 when all its rows are at their amplitudes."""
    totals: dict[str, float] = {}
    for r in recipes().fap_rows():
        for name, w in r.shapes.items():
            totals[name] = totals.get(name, 0.0) + w
    assert totals
    for name, total in totals.items():
        assert total == pytest.approx(1.0, abs=2e-3), name


def test_fap_content_reads_the_rows_backwards():
    t = recipes()
    m = t.fap_content()
    assert m.shape == (68, 52)
    assert m[2, ARKIT_INDEX["jawOpen"]] == 1000
    # the upper lip's left half: its share of the mid FAPs, all of the left ones
    up = m[:, ARKIT_INDEX["mouthUpperUpLeft"]]
    assert up[4 - 1] == pytest.approx(-150)
    assert up[8 - 1] == pytest.approx(-300)
    assert up[9 - 1] == 0
    both = up + m[:, ARKIT_INDEX["mouthUpperUpRight"]]
    for k in (4, 8, 9, 51, 55, 56):
        assert both[k - 1] == pytest.approx(-300)
    assert not m[:2].any()
    scale = t.fap_scale()
    assert scale[2] == 1000 and scale[47] == 1  # open_jaw; head_pitch has no row
    assert t.viseme_matrix().shape == (15, 52)
    assert not t.expression_matrix()[0].any()
    assert np.all(t.viseme_matrix()[1:].sum(axis=1) > 0)


@pytest.mark.parametrize(
    ("row", "message"),
    [
        ("fap\t3\t+\t1000\tjawOpn=1\tx", "'jawOpn' is not one of the 52 ARKit"),
        ("fap\t3\t+\t1000\tjawOpen=2\tx", "within \\(0, 1\\]"),
        ("fap\t3\t+\t1000\tjawOpen\tx", "NAME=WEIGHT"),
        ("fap\t3\t-\t1000\tjawOpen=1\tx", "FAP 3 is unidirectional"),
        ("fap\t2\t+\t1000\tjawOpen=1\tx", "fap numbers are 3–68"),
        ("fap\t3\t+\t0\tjawOpen=1\tx", "finite and > 0"),
        ("viseme\t1\t-\t1\tjawOpen=1\tx", "must be \\+"),
        ("viseme\t1\t+\t2\tjawOpen=1\tx", "weight of 1"),
        ("mouth\t1\t+\t1\tjawOpen=1\tx", "kind must be one of"),
        ("fap\t3\t+\t1000\t\tx", "has no shapes"),
        ("fap\t3\t+\t1000\tjawOpen=1", "6 tab-separated cells"),
    ],
)
def test_bad_rows_name_the_line_and_rule(row, message):
    with pytest.raises(AvatarError, match=message) as e:
        parse_recipes("# comment\n" + HEADER + row + "\n", file="r.tsv")
    assert e.value.file == "r.tsv" and e.value.line == 3


def test_a_table_needs_every_viseme_and_expression():
    with pytest.raises(AvatarError, match="lacks visemes 0, 1"):
        parse_recipes(HEADER + "fap\t3\t+\t1000\tjawOpen=1\tx\n")
    with pytest.raises(AvatarError, match="header"):
        parse_recipes("fap\t3\t+\t1000\tjawOpen=1\tx\n")
    text = HEADER + "fap\t3\t+\t1000\tjawOpen=1\tx\n" * 2
    with pytest.raises(AvatarError, match="has a row already"):
        parse_recipes(text)
