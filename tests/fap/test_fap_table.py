"""The FAP, viseme and expression tables and their lookups."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.errors import FapError, VttsError
from vtts.fap import EXPRESSIONS, FAPS, VISEMES, FapDef, expression, fap, viseme


def test_68_faps_in_order() -> None:
    assert len(FAPS) == 68
    assert [f.number for f in FAPS] == list(range(1, 69))
    assert FAPS[0].name == "viseme" and FAPS[1].name == "expression"


@pytest.mark.parametrize(
    ("number", "name", "fapu", "bidirectional", "motion", "point", "step"),
    [
        (3, "open_jaw", "MNS", False, "down", "2.1", 4),
        (19, "close_t_l_eyelid", "IRISD", True, "down", "3.1", 1),
        (23, "yaw_l_eyeball", "AU", True, "left", "3.5", 128),
        (48, "head_pitch", "AU", True, "down", "7.1", 170),
        (53, "stretch_l_cornerlip_o", "MW", True, "left", "8.3", 2),
        (68, "pull_r_ear", "ENS", True, "right", "10.4", 1),
    ],
)
def test_rows(
    number: int, name: str, fapu: str, bidirectional: bool, motion: str, point: str, step: int
) -> None:
    d = fap(number)
    assert d == FAPS[number - 1]
    assert (d.name, d.fapu, d.bidirectional, d.positive_motion) == (
        name,
        fapu,
        bidirectional,
        motion,
    )
    assert (d.feature_point, d.quant_step, d.high_level) == (point, step, False)


def test_high_level_faps_have_no_fapu() -> None:
    assert fap(1).fapu is None and fap(1).high_level
    assert fap("expression").fapu is None and fap(2).high_level
    assert {f.fapu for f in FAPS[2:]} == {"IRISD", "ES", "ENS", "MNS", "MW", "AU"}


def test_fapdef_is_frozen() -> None:
    with pytest.raises(AttributeError):
        fap(3).name = "x"  # type: ignore[misc]
    assert isinstance(fap(3), FapDef)


@pytest.mark.parametrize(
    "key", [3, "open_jaw", "OPEN_JAW", " Open_Jaw ", "3", np.int64(3), np.uint8(3)]
)
def test_fap_lookup(key: object) -> None:
    assert fap(key).number == 3  # type: ignore[arg-type]


@pytest.mark.parametrize("key", [0, 69, -1, "69", "jaw", "", True, 3.0, None])
def test_fap_lookup_errors(key: object) -> None:
    with pytest.raises(FapError) as e:
        fap(key)  # type: ignore[arg-type]
    assert repr(key) in str(e.value) and "1–68" in str(e.value)
    assert isinstance(e.value, VttsError)


def test_visemes() -> None:
    assert sorted(VISEMES) == list(range(15))
    assert VISEMES[0].phonemes == () and VISEMES[0].label == "none"
    assert VISEMES[6].phonemes == ("tS", "dZ", "S")
    assert VISEMES[1].example == "put, bed, mill"


@pytest.mark.parametrize(
    ("key", "number"),
    [(0, 0), (14, 14), ("7", 7), ("p", 1), ("m", 1), ("T", 3), ("t", 4), ("S", 6), ("s", 7),
     ("A:", 10), ("p, b, m", 1), ("none", 0)],
)  # fmt: skip
def test_viseme_lookup(key: int | str, number: int) -> None:
    assert viseme(key).number == number


@pytest.mark.parametrize("key", [-1, 15, "x", "P", "", True])
def test_viseme_lookup_errors(key: object) -> None:
    with pytest.raises(FapError, match="expected a viseme number 0–14"):
        viseme(key)  # type: ignore[arg-type]


def test_expressions() -> None:
    assert {k: e.name for k, e in EXPRESSIONS.items()} == {
        1: "joy",
        2: "sadness",
        3: "anger",
        4: "fear",
        5: "disgust",
        6: "surprise",
    }


@pytest.mark.parametrize(("key", "number"), [(1, 1), ("joy", 1), ("Surprise", 6), ("3", 3)])
def test_expression_lookup(key: int | str, number: int) -> None:
    assert expression(key).number == number


@pytest.mark.parametrize("key", [0, 7, "smile", "neutral", None])
def test_expression_lookup_errors(key: object) -> None:
    with pytest.raises(FapError, match=r"expected an expression number 1–6 or one of joy, "):
        expression(key)  # type: ignore[arg-type]


def test_tables_are_read_only() -> None:
    with pytest.raises(TypeError):
        VISEMES[0] = VISEMES[1]  # type: ignore[index]
    with pytest.raises(TypeError):
        EXPRESSIONS[1] = EXPRESSIONS[2]  # type: ignore[index]
