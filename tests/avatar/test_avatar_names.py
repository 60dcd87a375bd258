"""Morph target names as files spell them (vtts.avatar.names), and the one warning that lists the
names that match nothing."""

from __future__ import annotations

import warnings

import pytest

from vtts.avatar.arkit import ARKIT_NAMES, OCULUS_VISEMES
from vtts.avatar.importer import import_avatar
from vtts.avatar.names import canonical_name, eye_side, match_names, name_key
from vtts.errors import VttsWarning
from vtts.face import Miap

from .avatar_helpers import simple_avatar


@pytest.mark.parametrize(
    "spelled",
    ["eyeBlinkLeft", "eyeBlink_L", "EyeBlink_Left", "eyeBlinkL", "eye_blink_left", "EYEBLINKLEFT",
     "eyeblink_l", "blendShape1.eyeBlinkLeft", "blendShape1.eyeBlink_L", "Face|EyeBlink_Left",
     "head:eyeBlinkLeft", "EyeBlinkLt"],
)  # fmt: skip
def test_variants_of_eye_blink_left(spelled):
    assert canonical_name(spelled) == "eyeBlinkLeft"


@pytest.mark.parametrize("name", ARKIT_NAMES + OCULUS_VISEMES)
def test_every_canonical_name_matches_itself_and_its_variants(name):
    assert canonical_name(name) == name
    assert canonical_name(f"blendShape2.{name}") == name
    assert canonical_name(name.upper()) == name
    if name.endswith("Left"):
        assert canonical_name(name[:-4] + "_L") == name
    if name.endswith("Right"):
        assert canonical_name(name[:-5] + "_R") == name


@pytest.mark.parametrize("spelled", ["viseme_PP", "Viseme_PP", "visemePP", "V_PP", "viseme_pp"])
def test_oculus_viseme_variants(spelled):
    assert canonical_name(spelled) == "viseme_PP"


def test_left_and_right_are_not_confused():
    assert name_key("mouthSmile_L") != name_key("mouthSmile_R")
    assert canonical_name("mouthSmile_R") == "mouthSmileRight"


def test_unknown_names_and_repeats():
    matched, unknown = match_names(["jawOpen", "Jaw_Open", "wink", "EyeBlink_L", "wink"])
    assert matched == {"jawOpen": "jawOpen", "EyeBlink_L": "eyeBlinkLeft"}
    assert unknown == ["Jaw_Open", "wink"]  # a second spelling of one shape is not used


def test_unknown_targets_are_listed_in_one_warning(tmp_path):
    path = simple_avatar(tmp_path / "a.glb", ["jawOpen", "blendShape1.EyeBlink_L", "smirk",
                                               "Mouth_Stretch_R", "frown2"])  # fmt: skip
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        avatar = import_avatar(path)
    unknown = [x for x in w if "neither ARKit blendshapes nor Oculus visemes" in str(x.message)]
    assert len(unknown) == 1 and issubclass(unknown[0].category, VttsWarning)
    text = str(unknown[0].message)
    assert "2 morph targets" in text and "smirk" in text and "frown2" in text
    assert avatar.unknown == ["smirk", "frown2"]
    assert set(avatar.found) == {"jawOpen", "eyeBlinkLeft", "mouthStretchRight"}
    for fap in (3, 19, 7):  # open_jaw, close_t_l_eyelid, stretch_r_cornerlip
        assert Miap("fap", fap) in avatar.tables.adts


def test_oculus_visemes_are_used_directly(tmp_path):
    """A viseme_* target is the viseme's table as it is: weight 1 moves the vertex by the target;
    without one, the viseme comes from the recipe's ARKit shapes."""
    path = simple_avatar(tmp_path / "a.glb", ["viseme_aa", "jawOpen"])
    avatar = import_avatar(path)
    (aa,) = avatar.tables.adts[Miap("viseme", 10)].meshes
    assert aa.borders.tolist() == [0.0, 1.0] and aa.vertices.tolist() == [1]
    assert aa.displacements[0, 0, 1] == pytest.approx(-0.1)
    (th,) = avatar.tables.adts[Miap("viseme", 3)].meshes  # T, D: jawOpen 0.25 in its recipe
    assert th.vertices.tolist() == [2]
    assert th.displacements[0, 0, 1] == pytest.approx(-0.1 * 0.25)


@pytest.mark.parametrize(
    "name,side",
    [("EyeLeft", "left"), ("LeftEye", "left"), ("eye_L", "left"), ("Eye.R", "right"),
     ("L_EYEBALL", "left"), ("eyeball_right", "right"), ("EYE_R", "right"), ("Eye", None),
     ("eyelash_L", None), ("EyelidLeft", None), ("Eyebrow.L", None), ("Head", None)],
)  # fmt: skip
def test_eye_names(name, side):
    assert eye_side(name) == side
