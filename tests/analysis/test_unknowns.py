"""The ``--faps`` list of ``vtts analyze``: FAP numbers, names, ranges, tx/ty/tz and sets."""

from __future__ import annotations

import pytest

from vtts.analysis.unknowns import (
    DEFAULT_UNKNOWNS,
    TABLE1_FAPS,
    UNKNOWN_SETS,
    describe_unknown,
    parse_unknowns,
)
from vtts.errors import AnalysisError, VttsError


def test_the_papers_17_unknowns():
    assert len(DEFAULT_UNKNOWNS) == 17
    assert len(set(DEFAULT_UNKNOWNS)) == 17
    head = {48, 49, 50, "tx", "ty", "tz"}
    brows = {31, 32, 35, 36}
    mouth = {3, 4, 5, 6, 7, 12, 13}
    assert set(DEFAULT_UNKNOWNS) == head | brows | mouth
    assert set(TABLE1_FAPS) == {3, 12, 13, 19, 20, 35, 36, 48, 49, 50}


@pytest.mark.parametrize(
    "text, expected",
    [
        ("3", (3,)),
        ("3,12,13", (3, 12, 13)),
        ("13, 3 12", (13, 3, 12)),  # order kept; commas and blanks separate
        ("tx,ty,tz", ("tx", "ty", "tz")),
        ("TX,48", ("tx", 48)),
        ("open_jaw,head_yaw", (3, 49)),
        ("3-6", (3, 4, 5, 6)),
        ("68", (68,)),
        ("paper17", DEFAULT_UNKNOWNS),
        ("table1", TABLE1_FAPS),
        ("table1,tx", (*TABLE1_FAPS, "tx")),
        ("paper17,19,20", (*DEFAULT_UNKNOWNS, 19, 20)),
        (",3,,4,", (3, 4)),
    ],
)
def test_valid_lists(text, expected):
    assert parse_unknowns(text) == expected


def test_faps_are_ints_and_translation_strings():
    out = parse_unknowns("3,tz")
    assert type(out[0]) is int and out[1] == "tz"


@pytest.mark.parametrize(
    "text, fragments",
    [
        ("1", ["'1'", "FAP 1", "high-level", "3–68"]),
        ("2,3", ["'2'", "FAP 2", "high-level"]),
        ("1-5", ["'1-5'", "FAP 1"]),
        ("69", ["'69'", "out of range"]),
        ("0", ["'0'", "out of range"]),
        ("3,foo", ["'foo'", "not a FAP", "paper17", "tx"]),
        ("tw", ["'tw'", "not a FAP"]),
        ("3.5", ["'3.5'", "not a FAP"]),
        ("6-3", ["'6-3'", "low to high"]),
        ("3,3", ["'3'", "FAP 3 is already listed"]),
        ("tx,12,TX", ["'TX'", "tx is already listed by 'tx'"]),
        ("3,paper17", ["'paper17'", "FAP 3", "already listed by '3'"]),
        ("3-5,4", ["'4'", "FAP 4", "by '3-5'"]),
        ("open_jaw,3", ["'3'", "FAP 3", "by 'open_jaw'"]),
        ("paper17,table1", ["'table1'", "already listed by 'paper17'"]),
        ("", ["selects nothing"]),
        (" , ", ["selects nothing"]),
    ],
)
def test_invalid_lists_name_the_item(text, fragments):
    with pytest.raises(AnalysisError) as info:
        parse_unknowns(text)
    for fragment in fragments:
        assert fragment in str(info.value)


def test_errors_are_vtts_errors():
    assert issubclass(AnalysisError, VttsError)


@pytest.mark.parametrize("name", sorted(UNKNOWN_SETS))
def test_named_sets_are_valid_unknown_lists(name):
    assert parse_unknowns(name) == UNKNOWN_SETS[name]
    assert parse_unknowns(",".join(map(str, UNKNOWN_SETS[name]))) == UNKNOWN_SETS[name]


def test_describe_unknown():
    assert describe_unknown(3) == "FAP 3 open_jaw"
    assert describe_unknown("tx") == "tx"
