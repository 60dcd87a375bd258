"""Fuzzing the ``.adt`` reader (issue 21): whatever the text, the only exception is AdtError with
a place in the file, and whatever is accepted writes and reads back unchanged.

Mutations of the test head's tables (``tests/data/models/head.adt``), of what ``format_adt``
writes for them, of a bundled head's temporal tables, plus random text and token soup. Tables that
parse are also checked against the test head's scene and deformed, which may raise AdtError only.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from vtts.errors import AdtError
from vtts.face import FaceModel
from vtts.face.adt import AnimationTables, check_tables, format_adt, parse_adt
from vtts.vrml import read

from ..fuzzing import examples
from ..hostile import mutate, mutations

ROOT = Path(__file__).resolve().parents[2]
HEAD = ROOT / "tests" / "data" / "models"
REAL = (HEAD / "head.adt").read_text()
WRITTEN = format_adt(parse_adt(REAL))
# cybatt's temporal tables: every expression and habit setting a bundled head uses
_CYBATT = (ROOT / "models" / "cybatt.adt").read_text()
TEMPORAL = _CYBATT[_CYBATT.index("#TemporalDefinitionTables") :]
CORPUS = [REAL, WRITTEN, TEMPORAL]
SCENE = read(HEAD / "head.wrl")

FUZZ = settings(
    max_examples=examples(150), deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


def parse_or_adt_error(text: str) -> AnimationTables | None:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)  # an overflow in a conversion
            tables = parse_adt(text, file="fuzz.adt")
    except AdtError as e:
        assert e.file == "fuzz.adt" and e.line is not None and e.line >= 1, str(e)
        assert e.message and str(e)
        return None
    # whatever was accepted writes and reads back unchanged
    again = parse_adt(format_adt(tables), file="again.adt")
    assert again == tables, format_adt(tables)
    # and fits the scene or says why; a model of tables that fit can be posed
    try:
        check_tables(tables, SCENE, file="fuzz.adt")
    except AdtError as e:
        assert e.message
        return tables
    model = FaceModel(SCENE, tables)
    params = model.params()
    params[[m.index for m in tables.adts]] = 0.5
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pose = model.engine.deform(params)
    for points in pose.points.values():
        assert np.isfinite(points).all()
    return tables


def test_the_corpus_parses_and_round_trips() -> None:
    for text in CORPUS:
        assert parse_or_adt_error(text)


@FUZZ
@given(st.binary(max_size=1000))
def test_random_bytes(data: bytes) -> None:
    parse_or_adt_error(data.decode("latin-1"))


@FUZZ
@given(st.text(max_size=300))
def test_random_text_after_a_header(text: str) -> None:
    parse_or_adt_error(text)
    parse_or_adt_error("#AnimationDefinitionTables\n" + text)
    parse_or_adt_error("#TemporalDefinitionTables\n" + text)


@FUZZ
@given(st.sampled_from(CORPUS), mutations)
# non-finite numbers were accepted, then failed to write (OverflowError) or read back
@example(REAL, [("replace", REAL.index("0.05 0"), 0, "1e999")])
@example(REAL, [("replace", REAL.index("0 (angle)"), 0, "1e999")])
@example(REAL, [("replace", REAL.index("1024\n"), 3, "1e999")])
# a vertex index of 10^30 wrapped around in int64 and was reported as negative
@example(REAL, [("insert", REAL.index("vertex 50") + 7, 0, "9" * 30)])
def test_mutated_tables(text: str, ops: list[tuple[str, int, int, str]]) -> None:
    parse_or_adt_error(mutate(text, ops))


WORDS = [
    "MIAP", "19", "6", "48", "viseme", "expression", "joy", "(label)", "IndexedFaceSet", ":",
    "FACE_MESH", "HEAD", "interval", "borders", "displacements", "vertex", "0", "1", "-1", "512",
    "0.5", "1e308", "1e999", "Transform", "rotation", "translation", "scale", "neutral", "value",
    "(axis)", "per", "unit", "\n", "\n", "\n", "#", "#TemporalDefinitionTables", "blink", "onset",
    "shape", "smooth", "amplitude", "#FeaturePoints", "3.5", "12",
]  # fmt: skip


@FUZZ
@given(st.lists(st.sampled_from(WORDS), max_size=60))
def test_token_soup(words: list[str]) -> None:
    parse_or_adt_error("#AnimationDefinitionTables\n" + " ".join(words) + "\n")


@FUZZ
@given(
    borders=st.lists(st.sampled_from(["-1000", "0", "0.5", "1", "1024", "1e308"]), max_size=5),
    rows=st.lists(
        st.lists(st.sampled_from(["0", "1", "2", "-3", "0.5", "1e308", "-1e308", "x"]), max_size=8),
        max_size=4,
    ),
)
def test_mesh_table_soup(borders: list[str], rows: list[list[str]]) -> None:
    """Well-formed MIAP blocks with random borders and vertex rows: the shape and value checks."""
    lines = ["#AnimationDefinitionTables", "MIAP 19", "IndexedFaceSet: FACE_MESH"]
    lines += ["interval borders: " + " ".join(borders), "displacements:"]
    lines += ["vertex " + " ".join(r) for r in rows]
    parse_or_adt_error("\n".join(lines) + "\n")
