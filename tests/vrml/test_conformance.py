"""The VRML97 conformance set: every good file parses, every bad file is rejected with a message
that names the rule it breaks, at the right line."""

from __future__ import annotations

from pathlib import Path

import pytest

from vtts.errors import VrmlSemanticError
from vtts.vrml import dumps, parse, read

DATA = Path(__file__).parents[1] / "data" / "vrml97"
GOOD = sorted((DATA / "good").glob("*.wrl"))

# file -> (line, fragments the message must contain)
BAD = {
    "exposedfield-in-script.wrl": (3, ["exposedField is not allowed in a Script"]),
    "is-outside-proto.wrl": (3, ["outside a PROTO body"]),
    "is-value-type-mismatch.wrl": (3, ["MFNode", "SFBool", "same type"]),
    "proto-eventin-conflict.wrl": (4, ["implies 'set_foo'"]),
    "proto-eventout-conflict.wrl": (4, ["foo_changed", "exposedField 'foo'"]),
    "route-from-field.wrl": (6, ["a field of PROTO FromNode", "eventOut is needed"]),
    "route-sfint32-to-sfbool.wrl": (6, ["SFInt32 eventOut", "SFBool eventIn"]),
    "route-to-field.wrl": (6, ["a field of PROTO ToNode", "eventIn is needed"]),
    "unrecognized-field.wrl": (3, ["has no field 'wrong'"]),
    "unrecognized-node.wrl": (2, ["unknown node type 'UnrecognizedNode'"]),
    "use-def-in-different-proto-default-value.wrl": (4, ["USE of undefined name 'G'"]),
    "value-for-eventin-in-proto.wrl": (3, ["'set_children' is an event of Group"]),
}


def test_conformance_set_is_complete():
    assert len(GOOD) == 13
    assert sorted(p.name for p in (DATA / "bad").glob("*.wrl")) == sorted(BAD)


@pytest.mark.parametrize("path", GOOD, ids=lambda p: p.name)
def test_good_files_parse_and_round_trip(path: Path):
    scene = read(path)
    assert parse(dumps(scene)) == scene


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_files_are_rejected_with_the_rule(name: str):
    line, fragments = BAD[name]
    with pytest.raises(VrmlSemanticError) as info:
        read(DATA / "bad" / name)
    err = info.value
    assert err.file and err.file.endswith(name)
    assert err.line == line, str(err)
    for f in fragments:
        assert f in err.message
