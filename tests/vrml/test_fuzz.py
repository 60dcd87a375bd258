"""Fuzzing the VRML97 parser: whatever the bytes, the only exceptions are VttsError subclasses.

Mutations (hypothesis-driven) of a corpus of valid files: the OpenVRML conformance files in
``tests/data/vrml97`` plus a few richer texts written here, and of random valid scenes from the
round-trip test's generator; plus random bytes and deep nesting. Scenes that parse are also
traversed, triangle-counted, written and read back, which may raise VttsError only. Failing
inputs found here are kept as explicit examples and regression tests at the end of the file.
"""

from __future__ import annotations

import itertools
import re
import warnings
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from vtts import vrml
from vtts.errors import VttsError

from ..fuzzing import examples
from .test_roundtrip_property import vrml_texts  # random valid scene texts

DATA = Path(__file__).resolve().parent.parent / "data" / "vrml97"
GOOD = sorted((DATA / "good").glob("*.wrl"))
BAD = sorted((DATA / "bad").glob("*.wrl"))
HEADER = b"#VRML V2.0 utf8\n"

RICH = [
    # A face-like shape: nested transforms, an indexed face set, material, texture, DEF/USE.
    HEADER
    + """
WorldInfo { title "tête \\"parlante\\"" info [ "a\\\\b" "漢字" ] }
DEF Head Transform {
  translation 0 1.5e-2 -3E1 rotation 0 1 0 1.5707963267948966 scale 1, 1, 1
  children [
    DEF Face Shape {
      appearance Appearance {
        material DEF Skin Material { diffuseColor 0.9 0.7 0.6 shininess .2 }
        texture ImageTexture { url [ "skin.png" "tex/skin.jpg" ] repeatS FALSE }
        textureTransform TextureTransform { scale 2 2 }
      }
      geometry IndexedFaceSet {
        coord DEF Pts Coordinate { point [ 0 0 0, 1 0 0, 1 1 0, 0 1 0, 0.5 0.5 1 ] }
        coordIndex [ 0 1 2 3 -1, 0 1 4 -1, 1 2 4 -1 2 3 4 -1 ]
        texCoord TextureCoordinate { point [ 0 0 1 0 1 1 0 1 .5 .5 ] }
        creaseAngle 0.5 solid FALSE
      }
    }
    Transform { translation -1 0 0 children USE Face }
    Group { children [ Shape { geometry IndexedFaceSet { coord USE Pts coordIndex 0 } } ] }
    Switch { whichChoice 0x1
             choice [ Group {} Shape { appearance Appearance { material USE Skin } } ] }
    Shape { appearance Appearance { texture PixelTexture { image 2 1 3 0xFF0000 0x00FF00 } } }
  ]
}
""".encode(),
    # PROTO with IS, instances, EXTERNPROTO, Script, ROUTEs.
    HEADER
    + b"""
PROTO Jaw [
  exposedField SFVec3f  pos   0 0 0
  field        SFColor  col   1 0 0
  field        MFString tex   [ "jaw.png" ]
  eventIn      SFFloat  open
  eventOut     SFTime   done
] {
  DEF T Transform {
    translation IS pos
    children Shape {
      appearance Appearance {
        material Material { diffuseColor IS col }
        texture ImageTexture { url IS tex }
      }
      geometry Box { size 1 0.2 1 }
    }
  }
  DEF S Script {
    eventIn SFFloat open IS open
    eventOut SFTime done IS done
    field SFNode t USE T
    url "javascript: function open(v) { }"
  }
}
EXTERNPROTO Eye [ exposedField SFFloat blink field MFVec3f pts ] [ "eyes.wrl#Eye" ]
EXTERNPROTO Brow [] []
DEF J Jaw { pos 0 -1 0 col 0.5 0.5 0.5 }
DEF E Eye { blink 0.25 pts [ 1 2 3, 4 5 6 ] }
Brow {}
DEF Clock TimeSensor { cycleInterval 2.5 loop TRUE }
DEF Curve ScalarInterpolator { key [ 0 .5 1 ] keyValue [ 0 1 0 ] }
DEF Mover PositionInterpolator { key [ 0 1 ] keyValue [ 0 0 0, 0 1 0 ] }
DEF Dst Transform {}
ROUTE Clock.fraction_changed TO Curve.set_fraction
ROUTE Clock.fraction_changed TO Mover.set_fraction
ROUTE Curve.value_changed TO J.open
ROUTE Mover.value_changed TO Dst.set_translation
ROUTE Dst.translation_changed TO Dst.set_translation
ROUTE Curve.value_changed TO E.set_blink
""",
    # MPEG-4 face nodes, interpolators and a viewpoint.
    HEADER
    + b"""
Viewpoint { position 0 0 5 description "front" }
NavigationInfo { type [ "EXAMINE" "ANY" ] headlight TRUE }
DEF Mesh Shape { geometry IndexedFaceSet {
  coord Coordinate { point [ 0 0 0 1 0 0 0 1 0 ] } coordIndex [ 0 1 2 ] } }
FaceDefTables {
  fapID 3 highLevelSelect 0
  faceDefMesh FaceDefMesh {
    faceSceneGraphNode USE Mesh
    intervalBorders [ -1000 0 1000 ]
    coordIndex [ 0 2 ]
    displacements [ 0 -1 0, 0 -0.5 0, 0 0 0, 0 0 0 ]
  }
  faceDefTransform [ FaceDefTransform { faceSceneGraphNode USE Mesh fieldId 2
    rotationDef 0 0 1 0.1 } ]
}
""",
]
CORPUS = [p.read_bytes() for p in GOOD + BAD] + RICH

VOCABULARY = [
    b"{",
    b"}",
    b"[",
    b"]",
    b"DEF",
    b"USE",
    b"PROTO",
    b"EXTERNPROTO",
    b"IS",
    b"ROUTE",
    b"TO",
    b".",
    b",",
    b'"',
    b"#",
    b"1e999",
    b"-1e999",
    b"0x",
    b"0xFFFFFFFF",
    b"0x" + b"F" * 40,
    b"-1",
    b"010",
    b"1e-999",
    b"-0",
    b".5",
    b"+",
    b"-",
    b"NULL",
    b"TRUE",
    b"FALSE",
    b"field",
    b"eventIn",
    b"eventOut",
    b"exposedField",
    b"Group",
    b"Transform",
    b"Shape",
    b"Script",
    b"IndexedFaceSet",
    b"children",
    b"url",
    b"coordIndex",
    b"point",
    b"USE A",
    b"DEF A",
    b"DEF A Group { children [ USE A ] }",
    b"ROUTE A.children TO A.children",
    b'"../up.png"',
    b'"/etc/passwd"',
    b'"C:/x.png"',
    b'"file:///x"',
    b"\\",
    b"\n",
    b"\r",
    b"\t",
    b" ",
    b"\x00",
    b"\xff",
    b"\xc3",
    b"\xed\xa0\x80",
    b"\xef\xbb\xbf",
    "é𝄞\u2028\ufeff\xa0".encode(),
    b"9" * 5000,
    b"2147483648",
    b"-2147483649",
    b"SFImage",
    b"MFNode",
    b"SFNode",
    b"#VRML V2.0 utf8\n",
    b"#VRML V1.0 ascii\n",
]
#: Words of the corpus itself: mutants built from them often stay syntactically valid.
CORPUS_WORDS = sorted({w for data in CORPUS for w in data.split()})
TOKENS = st.one_of(
    st.sampled_from(VOCABULARY),
    st.sampled_from(CORPUS_WORDS),
    st.binary(max_size=6),
    st.text(max_size=4).map(lambda s: s.encode("utf-8", "surrogatepass")),
)
BYTE_OPS = ["delete", "insert", "replace", "duplicate", "truncate", "byte", "swap"]
#: Word-level operations keep more of the structure, so that more mutants parse and reach the
#: builder's semantic checks, the writer and traversal.
WORD_OPS = ["word_delete", "word_insert", "word_replace", "word_duplicate", "word_swap"]
MUTATION = st.tuples(
    st.sampled_from(BYTE_OPS + WORD_OPS),
    st.integers(0, 10**6),
    st.integers(0, 64),
    TOKENS,
)


def mutate_words(data: bytes, op: str, pos: int, length: int, tok: bytes) -> bytes:
    parts = re.split(rb"(\s+)", data)  # words at even indices, whitespace at odd ones
    words = parts[::2]
    i = pos % len(words)
    k = (pos // 7 + length) % len(words)
    if op == "word_delete":
        words[i] = b""
    elif op == "word_insert":
        words[i] = tok + b" " + words[i]
    elif op == "word_replace":
        words[i] = tok
    elif op == "word_duplicate":
        words[i] = b" ".join([words[i]] * (2 + length % 3))
    elif op == "word_swap":
        words[i], words[k] = words[k], words[i]
    parts[::2] = words
    return b"".join(parts)


def mutate(data: bytes, ops: list[tuple[str, int, int, bytes]]) -> bytes:
    b = bytearray(data)
    for op, pos, length, tok in ops:
        if op.startswith("word_"):
            b = bytearray(mutate_words(bytes(b), op, pos, length, tok))
            continue
        i = pos % (len(b) + 1)
        j = min(len(b), i + length)
        if op == "delete":
            del b[i:j]
        elif op == "insert":
            b[i:i] = tok
        elif op == "replace":
            b[i:j] = tok
        elif op == "duplicate":
            b[j:j] = b[i:j] * (1 + length % 3)
        elif op == "truncate":
            del b[i:]
        elif op == "byte" and i < len(b):
            b[i] = (b[i] + 1 + length) % 256
        elif op == "swap":
            k = (pos // 7) % (len(b) + 1)
            if k >= j:
                b[i:k] = b[j:k] + b[i:j]
    return bytes(b)


def check(data: bytes) -> vrml.Scene | None:
    """Parse ``data`` strictly and leniently; anything but a VttsError fails the test."""
    scene = None
    for lenient in (False, True):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                s = vrml.parse(data, lenient=lenient)
            except VttsError as e:
                assert str(e)
                continue
            use(s, lenient)
        scene = scene or s
    return scene


def use(scene: vrml.Scene, lenient: bool) -> None:
    """What callers do with a parsed scene; each step may raise VttsError only."""
    for step in (scene.triangle_count, lambda: list(scene.traverse())):
        try:
            step()
        except VttsError:
            pass
    try:
        vrml.parse(vrml.dumps(scene), lenient=lenient)
    except VttsError:
        pass


def test_corpus_is_valid() -> None:
    for data in [p.read_bytes() for p in GOOD] + RICH:
        vrml.parse(data)
        assert check(data) is not None


FUZZ = settings(
    max_examples=examples(1200),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

# Bugs found by fuzzing (see the regression tests below), kept as explicit examples.
LEADING_ZERO_WITH_HEX = HEADER + b"Shape { geometry IndexedFaceSet { coordIndex [ 010 0x1 ] } }\n"
HUGE_HEX_FLOAT = HEADER + b"Transform { translation 0x" + b"F" * 300 + b" 0 0 }\n"
HUGE_DECIMAL_INT = HEADER + b"Switch { whichChoice " + b"9" * 5000 + b" }\n"


@FUZZ
@given(st.sampled_from(CORPUS), st.lists(MUTATION, min_size=1, max_size=6))
@example(LEADING_ZERO_WITH_HEX, [])
@example(HUGE_HEX_FLOAT, [])
@example(HUGE_DECIMAL_INT, [])
def test_mutated_corpus(data: bytes, ops: list[tuple[str, int, int, bytes]]) -> None:
    check(mutate(data, ops))


@settings(max_examples=examples(300), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(vrml_texts(), st.lists(MUTATION, min_size=1, max_size=3))
def test_mutated_generated_scenes(text: str, ops: list[tuple[str, int, int, bytes]]) -> None:
    check(mutate(text.encode("utf-8"), ops))


@settings(max_examples=examples(300), deadline=None)
@given(st.binary(max_size=400))
def test_random_bytes_after_the_header(data: bytes) -> None:
    check(HEADER + data)


@settings(max_examples=examples(300), deadline=None)
@given(st.text(max_size=200))
def test_random_unicode_after_the_header(text: str) -> None:
    check(HEADER + text.encode("utf-8", "surrogatepass"))


#: (opening, closing) pairs that nest.
NESTERS = [
    (b"Group { children [ ", b"] } "),
    (b"Transform { children ", b"} "),
    (b"Shape { appearance Appearance { material ", b"} } "),
    (b"PROTO P [] { ", b"} P {} "),
    (b"PROTO P [ field SFNode f ", b"] { Group {} } "),
    (b"Script { field SFNode f ", b"} "),
    (b"Group { PROTO Q [] { Group { children [ ", b"] } } } "),
    (b"DEF A Group { children [ USE A ", b"] } "),
    (b"[ ", b"] "),
    (b"{ ", b"} "),
]


#: The deepest nesting tried. Without the parser's depth limit (100 levels) its builder
#: overflows Python's stack from 100 to 500 levels of these patterns: 2000 is well past both.
DEEPEST = 2000


@settings(max_examples=examples(40), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(st.sampled_from(NESTERS), min_size=1, max_size=3),
    st.integers(1, DEEPEST),
    st.integers(0, DEEPEST),
    st.lists(MUTATION, max_size=2),
)
@example([NESTERS[0]], DEEPEST, DEEPEST, [])
@example([NESTERS[3]], DEEPEST, DEEPEST, [])
def test_deep_nesting(pattern, n: int, closed: int, ops) -> None:
    opener = b"".join(o for o, _ in pattern)
    closer = b"".join(c for _, c in reversed(pattern))
    data = HEADER + opener * n + b"Group {} " + closer * min(n, closed)
    check(mutate(data, ops))


# ---- regression tests for the bugs fuzzing found ------------------------------------------------


@pytest.mark.parametrize(
    "data",
    [
        pytest.param(LEADING_ZERO_WITH_HEX, id="int-run-leading-zero-and-hex-ValueError"),
        pytest.param(
            HEADER + b"PixelTexture { image 01 1 1 0xFF }\n", id="image-leading-zero-ValueError"
        ),
        pytest.param(HUGE_HEX_FLOAT, id="float-huge-hex-OverflowError"),
        pytest.param(HUGE_DECIMAL_INT, id="int-over-4300-digits-ValueError"),
        pytest.param(
            HEADER
            + b"Shape { geometry IndexedFaceSet { coordIndex [ 0x1 "
            + b"9" * 5000
            + b" ] } }",
            id="int-run-over-4300-digits-with-hex-ValueError",
        ),
    ],
)
def test_only_vtts_errors_regressions(data: bytes) -> None:
    check(data)


def test_shared_subgraphs_do_not_explode() -> None:
    """A 1.5 kB file of nested DEF/USE pairs is a DAG with 2**40 paths: traversal must stop with a
    VttsError (a limit) instead of yielding nodes for hours."""
    text = "#VRML V2.0 utf8\nDEF A0 Group {}\n" + "".join(
        f"DEF A{i} Group {{ children [ USE A{i - 1} USE A{i - 1} ] }}\n" for i in range(1, 41)
    )
    scene = vrml.parse(text)
    limit = 500_000
    try:
        n = sum(1 for _ in itertools.islice(scene.traverse(), limit))
    except VttsError:
        return
    assert n < limit, f"traverse() yielded {limit} nodes from {len(text)} bytes with no limit"


def test_proto_expansion_is_limited(monkeypatch: pytest.MonkeyPatch) -> None:
    """A chain of PROTOs, each instancing the previous one twice, expands to 2**n nodes (2**40 in
    2 kB): traverse(), triangle_count() and find() must all stop at the instance limit with a
    VttsError. (The limit is lowered here so that the test is fast.)"""
    monkeypatch.setattr("vtts.vrml.scene.MAX_INSTANCES", 1000)
    n = 12  # 4096 Shapes
    text = (
        "#VRML V2.0 utf8\n"
        "PROTO P0 [] { Shape { geometry IndexedFaceSet { coordIndex [ 0 1 2 ] } } }\n"
        + "".join(
            f"PROTO P{i} [] {{ Group {{ children [ P{i - 1} {{}} P{i - 1} {{}} ] }} }}\n"
            for i in range(1, n + 1)
        )
        + f"P{n} {{}}\n"
    )
    for what in ("traverse", "triangle_count", "find"):
        scene = vrml.parse(text)  # fresh: expansions are cached on the nodes
        call = {
            "traverse": lambda s=scene: list(s.traverse()),
            "triangle_count": scene.triangle_count,
            "find": lambda s=scene: s.find("Shape"),
        }[what]
        try:
            call()
        except VttsError:
            continue
        pytest.fail(f"{what}() expanded 4096 PROTO instances, past the limit of 1000, unchecked")
