"""The scene API: DEF lookup, traversal with accumulated transforms, PROTO expansion, writing."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.vrml import compose_transform, dumps, parse, rotation_matrix, write

H = "#VRML V2.0 utf8\n"

SCENE = (
    H
    + """
DEF ROOT Transform {
  translation 0 0 -5
  children [
    DEF YAW Transform {
      rotation 0 1 0 1.5707963267948966
      children [
        DEF FACE Shape { geometry IndexedFaceSet {
          coord Coordinate { point [ 0 0 0, 1 0 0, 0 1 0 ] } coordIndex [ 0 1 2 ] } }
      ]
    }
    Transform { translation 2 0 0 scale 2 2 2 children [ USE FACE ] }
    Switch { whichChoice 1 choice [ Shape {} DEF CHOSEN Shape {} ] }
    Switch { choice [ Shape {} ] }
  ]
}
"""
)


def test_defs_and_find():
    scene = parse(SCENE)
    assert scene.node("YAW")["rotation"][1] == 1
    assert len(scene.find("Shape")) == 4  # distinct nodes, USE counted once
    with pytest.raises(KeyError, match="no node is DEFed as 'NOPE'"):
        scene.node("NOPE")


def test_traverse_accumulates_transforms():
    scene = parse(SCENE)
    shapes = list(scene.shapes())
    # FACE twice (DEF + USE), CHOSEN once; the unselected Switch choices not at all
    assert [s.name for s, _, _ in shapes] == ["FACE", "FACE", "CHOSEN"]
    m_face = shapes[0][1]
    p = m_face @ np.array([1.0, 0, 0, 1])  # x axis turned by 90° about y, then moved back
    assert np.allclose(p[:3], [0, 0, -6])
    p2 = shapes[1][1] @ np.array([1.0, 0, 0, 1])
    assert np.allclose(p2[:3], [4, 0, -5])
    assert [n.name for n in shapes[0][2]] == ["ROOT", "YAW"]
    assert scene.triangle_count() == 2


def test_transform_matrix_matches_the_spec_order():
    t, r, s = np.array([1.0, 2, 3]), np.array([0, 0, 1, np.pi / 2]), np.array([2.0, 1, 1])
    so, c = np.array([0, 0, 1, 0.0]), np.array([1.0, 0, 0])
    m = compose_transform(t, r, s, so, c)
    # a point at the center only moves by the translation
    assert np.allclose((m @ np.r_[c, 1])[:3], c + t)
    assert np.allclose(rotation_matrix([0, 0, 0, 1]), np.eye(3))
    assert np.allclose(rotation_matrix([0, 0, 2, np.pi / 2]) @ [1, 0, 0], [0, 1, 0])


def test_identity_factors_left_out_of_a_transform_change_no_number():
    """Every factor of T·C·R·SR·S·SR⁻¹·C⁻¹ multiplied out, identities included, gives the
    same numbers as the product without the identity factors, for fields with and without
    each factor."""
    from itertools import product

    from vtts.vrml.transform import _homogeneous

    def spelled_out(t, r, s, so, c):
        sr = rotation_matrix(so)
        return (
            _homogeneous(t=t)
            @ _homogeneous(t=c)
            @ _homogeneous(rotation_matrix(r))
            @ _homogeneous(sr)
            @ _homogeneous(np.diag(s))
            @ _homogeneous(sr.T)
            @ _homogeneous(t=-c)
        )

    rng = np.random.default_rng(7)
    for given in product([False, True], repeat=5):
        t, c, s = (
            rng.normal(size=3) if g else z
            for g, z in zip(given[:3], (np.zeros(3), np.zeros(3), np.ones(3)), strict=True)
        )
        r = np.r_[rng.normal(size=3), rng.normal()] if given[3] else np.array([0, 0, 1, 0.0])
        so = np.r_[rng.normal(size=3), rng.normal()] if given[4] else np.array([0, 0, 1, 0.0])
        expected = spelled_out(t, r, s, so, c)
        assert np.array_equal(compose_transform(t, r, s, so, c), expected), given
    assert np.array_equal(
        compose_transform(np.zeros(3), [0, 0, 1, 0], np.ones(3), [0, 0, 1, 0], np.zeros(3)),
        np.eye(4),
    )


def test_proto_instances_expand_for_traversal():
    scene = parse(
        H
        + """
PROTO Head [ field SFVec3f where 0 0 0  field MFNode parts [] ] {
  Transform { translation IS where children IS parts }
}
Head { where 1 0 0 parts [ Shape {} ] }
Head { where 0 1 0 }
"""
    )
    shapes = list(scene.shapes())
    assert len(shapes) == 1 and np.allclose(shapes[0][1][:3, 3], [1, 0, 0])
    inst = scene.roots[1]
    assert inst.expand().type.name == "Transform"
    assert inst.expand() is inst.expand()  # cached


def test_nested_proto_expansion():
    scene = parse(
        H
        + """
PROTO Inner [ field SFFloat r 1 ] { Shape { geometry Sphere { radius IS r } } }
PROTO Outer [ field SFFloat r 2 ] { Inner { r IS r } }
Outer { r 3 }
"""
    )
    shape = scene.roots[0].expand()
    assert shape.type.name == "Shape" and shape["geometry"]["radius"] == 3.0


def test_write_is_atomic_and_exact(tmp_path):
    scene = parse(SCENE)
    out = tmp_path / "sub" / "out.wrl"
    write(scene, out, comment="written by a test")
    assert out.read_text().startswith("#VRML V2.0 utf8\n# written by a test\n")
    assert parse(out.read_text()) == scene
    assert not [p for p in out.parent.iterdir() if p.name != "out.wrl"]


def test_scene_equality_sees_differences():
    a = parse(SCENE)
    assert parse(SCENE.replace("0 0 -5", "0 0 -5.000001")) != a
    assert parse(SCENE.replace("USE FACE", "DEF FACE2 Shape {}")) != a
    assert parse(dumps(a)) == a


def test_a_long_proto_chain_is_a_limit_not_recursion():
    """P99's first node is a P98, whose first node is a P97, …: no PROTO expands into itself,
    the chain is just deeper than the limit (and one within the limit expands)."""
    from vtts.errors import VrmlLimitError, VrmlSemanticError
    from vtts.vrml.scene import MAX_PROTO_CHAIN, Node

    def chain(n: int) -> str:
        protos = "".join(f"PROTO P{i} [] {{ P{i - 1} {{}} }}\n" for i in range(1, n))
        return H + "PROTO P0 [] { Shape { geometry Box {} } }\n" + protos + f"P{n - 1} {{}}\n"

    with pytest.raises(VrmlLimitError, match=f"chain of more than {MAX_PROTO_CHAIN} PROTOs") as e:
        list(parse(chain(100)).traverse())
    assert "into itself" not in str(e.value) and "P99 -> P98" in str(e.value)
    shapes = list(parse(chain(MAX_PROTO_CHAIN)).shapes())
    assert [s.type.name for s, _, _ in shapes] == ["Shape"]
    # true recursion (not writable in VRML97 text, where a PROTO body cannot name its own PROTO)
    scene = parse(H + "PROTO P [] { Group {} }\nP {}\n")
    scene.protos[0].body[0] = Node(scene.protos[0])
    with pytest.raises(VrmlSemanticError, match=r"PROTO P expands into itself \(P -> P\)"):
        scene.roots[0].expand()
