"""IndexedFaceSet → triangles: fan triangulation, -1 separators, ccw, creaseAngle, per-vertex and
per-face attributes with their index arrays."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from vtts.errors import VrmlSemanticError, VttsError
from vtts.vrml import (
    PRIMITIVES,
    check_face_set,
    parse,
    polygon_triangle_count,
    primitive_mesh,
    read,
    triangulate,
)

H = "#VRML V2.0 utf8\n"
CUBE_POINTS = "-1 -1 1, 1 -1 1, 1 1 1, -1 1 1, -1 -1 -1, 1 -1 -1, 1 1 -1, -1 1 -1"
CUBE_FACES = "0 1 2 3 -1, 7 6 5 4 -1, 1 5 6 2 -1, 0 3 7 4 -1, 3 2 6 7 -1, 0 4 5 1"


def ifs(extra: str = "", faces: str = CUBE_FACES, points: str = CUBE_POINTS):
    scene = parse(
        H + f"DEF G IndexedFaceSet {{ coord Coordinate {{ point [ {points} ] }} "
        f"coordIndex [ {faces} ] {extra} }}"
    )
    return scene.node("G")


def outward(mesh) -> bool:
    p = mesh.positions[mesh.faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return bool((np.einsum("ij,ij->i", n, p.mean(axis=1)) > 0).all())


@pytest.mark.parametrize(
    "index, triangles",
    [
        ([0, 1, 2], 1),
        ([0, 1, 2, -1], 1),
        ([0, 1, 2, 3, 4, -1, 0, 1, 2], 4),
        ([0, 1, -1, 0, 1, 2], 1),
        ([-1, -1], 0),
        ([], 0),
    ],
)
def test_fan_triangle_counts(index, triangles):
    assert polygon_triangle_count(np.array(index)) == triangles


@pytest.mark.parametrize("crease, vertices", [(0, 24), (0.5, 24), (1.6, 8), (3.5, 8)])
def test_crease_angle_splits_or_shares_vertices(crease, vertices):
    mesh = triangulate(ifs(f"creaseAngle {crease}"))
    assert mesh.faces.shape == (12, 3)
    assert mesh.positions.shape == (vertices, 3)
    assert outward(mesh)
    assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1)
    if vertices == 24:  # flat: each normal is an axis
        assert np.allclose(np.abs(mesh.normals).max(axis=1), 1)
    else:  # smooth: normals point along the corner diagonals
        assert np.allclose(np.abs(mesh.normals), 1 / np.sqrt(3))


def test_ccw_false_flips_winding_and_normals():
    mesh = triangulate(ifs("ccw FALSE"))
    assert not outward(mesh)
    centre = mesh.positions[mesh.faces].mean(axis=1)
    face_normals = mesh.normals[mesh.faces[:, 0]]
    assert (np.einsum("ij,ij->i", face_normals, centre) < 0).all()


def test_solid_controls_double_sided():
    assert not triangulate(ifs()).double_sided
    assert triangulate(ifs("solid FALSE")).double_sided


def test_per_face_colors_split_vertices_and_map_back():
    mesh = triangulate(
        ifs(
            "colorPerVertex FALSE color Color { color [ 1 0 0, 0 1 0 ] } colorIndex [ 0 1 0 1 0 1 ]"
        )
    )
    assert mesh.colors is not None and mesh.positions.shape[0] == 24
    # the two triangles of face 1 are green
    assert np.allclose(mesh.colors[mesh.faces[mesh.face_polygon == 1]], [0, 1, 0])
    pts = np.array([[float(v) for v in p.split()] for p in CUBE_POINTS.split(",")])
    assert np.allclose(mesh.positions, pts[mesh.coord_index])


def test_texcoord_index_and_default_mapping():
    mesh = triangulate(
        ifs(
            "texCoord TextureCoordinate { point [ 0 0, 1 0, 1 1, 0 1 ] } "
            "texCoordIndex [ 0 1 2 3 -1, 0 1 2 3 -1, 0 1 2 3 -1, 0 1 2 3 -1, 0 1 2 3 -1, 0 1 2 3 ]"
            " creaseAngle 3"
        )
    )
    assert mesh.texcoords.shape == (mesh.positions.shape[0], 2)
    assert mesh.texcoords.min() == 0 and mesh.texcoords.max() == 1
    default = triangulate(ifs(points="0 0 0, 4 0 0, 4 2 0, 0 2 0", faces="0 1 2 3"))
    assert np.allclose(default.texcoords[2], [1, 0.5])  # S along x (longest), T scaled alike


def test_given_normals_per_vertex():
    mesh = triangulate(
        ifs(
            points="0 0 0, 1 0 0, 0 1 0",
            faces="0 1 2",
            extra="normal Normal { vector [ 0 0 2 ] } normalIndex [ 0 0 0 ]",
        )
    )
    assert np.allclose(mesh.normals, [[0, 0, 1]] * 3)


def test_replacement_points_keep_topology():
    node = ifs()
    mesh = triangulate(node, points=np.zeros((8, 3)) + [0, 0, 1])
    assert np.allclose(mesh.positions, [0, 0, 1])


@pytest.mark.parametrize(
    "extra, faces, fragment",
    [
        ("", "0 1 8", "coordIndex value 8 (entry 2) is out of range"),
        ("color Color { color [ 1 0 0 ] } colorIndex [ 0 1 0 ]", "0 1 2", "colorIndex value 1"),
        (
            "normal Normal { vector [ 0 0 1 ] } normalIndex [ 0 ]",
            "0 1 2",
            "normalIndex has 1 entries but coordIndex needs 3",
        ),
    ],
)
def test_bad_indices_are_named(extra, faces, fragment):
    with pytest.raises(VrmlSemanticError, match="IndexedFaceSet") as info:
        triangulate(ifs(extra, faces=faces))
    assert fragment in info.value.message


@pytest.mark.parametrize(
    "body", ["", "coordIndex []", "coord Coordinate { point [ 0 0 0 ] } coordIndex [ -1 ]"]
)
def test_no_polygons_is_an_empty_mesh(body):
    mesh = triangulate(parse(H + f"DEF G IndexedFaceSet {{ {body} }}").node("G"))
    assert mesh.faces.shape == (0, 3) and mesh.positions.shape == (0, 3)


def test_an_unknown_texture_coordinate_node_is_no_texture_coordinates():
    """A lenient load keeps an X3D TextureCoordinateGenerator as a generic node: it gives no
    coordinates, so the standard's default mapping is used."""
    with pytest.warns(UserWarning, match="TextureCoordinateGenerator"):
        scene = parse(
            H + "DEF G IndexedFaceSet { coord Coordinate { point [ 0 0 0, 1 0 0, 0 1 0 ] } "
            'coordIndex [ 0 1 2 ] texCoord TextureCoordinateGenerator { mode "SPHERE" } }',
            lenient=True,
        )
    mesh = triangulate(scene.node("G"))
    assert mesh.texcoords.shape == (3, 2) and mesh.faces.shape == (1, 3)


@pytest.mark.parametrize(
    "node, lo, hi",
    [
        ("Box { size 2 4 6 }", [-1, -2, -3], [1, 2, 3]),
        ("Sphere { radius 0.5 }", [-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]),
        ("Cylinder { radius 1 height 3 }", [-1, -1.5, -1], [1, 1.5, 1]),  # VRML's axis is y
        ("Cone { bottomRadius 2 height 1 }", [-2, -0.5, -2], [2, 0.5, 2]),
    ],
)
def test_primitive_meshes_fill_the_vrml_bounds(node, lo, hi):
    geom = parse(H + f"DEF G {node}").node("G")
    mesh = primitive_mesh(geom)
    assert mesh.is_watertight and mesh.volume > 0  # closed, and wound outward
    assert np.allclose(mesh.bounds, [lo, hi], atol=1e-9)


def test_primitive_mesh_is_none_for_other_geometry():
    assert primitive_mesh(ifs()) is None
    assert PRIMITIVES == ("Box", "Sphere", "Cylinder", "Cone")


# ---- check_face_set: what vtts check runs instead of triangulate --------------------------------

#: (extra fields, coordIndex) of IndexedFaceSets on the cube's 8 points, valid and not: every
#: index rule triangulate enforces, per vertex and per face, with and without own index arrays.
FACE_SET_CASES = [
    ("", CUBE_FACES),
    ("", "0 1 8"),
    ("", "0 1 -2"),
    ("", "0 1 2 -1 -1 3 4 -1 5"),
    ("", "0 1 -1 2"),
    ("", "-1"),
    ("", ""),
    ("color Color { color [ 1 0 0 ] } colorIndex [ 0 1 0 ]", "0 1 2"),
    ("color Color { color [ 1 0 0 ] } colorIndex [ 0 0 0 ]", "0 1 2"),
    ("color Color { color [ 1 0 0 ] } colorPerVertex FALSE", "0 1 2 -1 0 2 3"),
    ("color Color { color [ 1 0 0 0 1 0 ] } colorPerVertex FALSE", "0 1 2 -1 0 2 3"),
    ("color Color { color [ 1 0 0 ] } colorPerVertex FALSE colorIndex [ 0 ]", "0 1 2 -1 0 2 3"),
    ("color Color { color [ 1 0 0 ] } colorPerVertex FALSE colorIndex [ 0 3 ]", "0 1 2 -1 2 3 4"),
    ("color Color { color [ 1 0 0 ] }", "0 1 2"),
    ("normal Normal { vector [ 0 0 1 ] } normalIndex [ 0 ]", "0 1 2"),
    ("normal Normal { vector [ 0 0 1 ] } normalIndex [ 0 0 0 ]", "0 1 2"),
    ("normal Normal { vector [ 0 0 1 ] } normalIndex [ 0 0 -1 0 ]", "0 1 2 -1 0 2 3"),
    ("normal Normal { vector [ 0 0 1 ] } normalPerVertex FALSE normalIndex [ 1 ]", "0 1 2"),
    ("normal Normal { vector [ 0 0 1, 0 1 0 ] } normalPerVertex FALSE", "0 1 2 -1 0 2 3"),
    ("normal Normal { vector [ 0 0 1 ] } normalPerVertex FALSE", "0 1 2 -1 0 2 3"),
    ("texCoord TextureCoordinate { point [ 0 0, 1 0, 1 1 ] }", "0 1 2"),
    ("texCoord TextureCoordinate { point [ 0 0, 1 0, 1 1 ] }", "0 1 3"),
    ("texCoord TextureCoordinate { point [ 0 0, 1 0 ] } texCoordIndex [ 0 1 1 ]", "0 1 3"),
    ("texCoord TextureCoordinate { point [ 0 0, 1 0 ] } texCoordIndex [ 0 1 2 ]", "0 1 3"),
    ("texCoord TextureCoordinate { point [ 0 0 ] } texCoordIndex [ 0 0 ]", "0 1 3"),
    # two broken rules: the first triangulate meets is the one named
    (
        "normal Normal { vector [ 0 0 1 ] } color Color { color [ 1 0 0 ] } colorIndex [ 5 ]",
        "0 1 9",
    ),
    (
        "normal Normal { vector [ 0 0 1 ] } color Color { color [ 1 0 0 ] } colorIndex [ 5 ]",
        "0 1 2",
    ),
]


def same_outcome(node) -> int:
    """check_face_set raises exactly what triangulate raises (class, message, line, column), or
    counts exactly its triangles; the count."""
    try:
        mesh = triangulate(node)
    except VrmlSemanticError as e:
        with pytest.raises(VrmlSemanticError) as info:
            check_face_set(node)
        assert (info.value.message, info.value.line, info.value.column) == (
            e.message,
            e.line,
            e.column,
        )
        return -1
    assert check_face_set(node) == len(mesh.faces)
    return len(mesh.faces)


@pytest.mark.parametrize("extra, faces", FACE_SET_CASES)
def test_check_face_set_agrees_with_triangulate(extra, faces):
    same_outcome(ifs(extra, faces=faces))


def test_check_face_set_without_coord_or_index():
    for body in ("", "coordIndex [ 0 1 2 ]", "coord Coordinate { point [ 0 0 0 ] }"):
        same_outcome(parse(H + f"DEF G IndexedFaceSet {{ {body} }}").node("G"))


def test_check_face_set_agrees_on_every_file_in_the_repository():
    """Every IndexedFaceSet of the conformance files, the wild files and the bundled models."""
    root = Path(__file__).resolve().parents[2]
    files = [
        *sorted((root / "tests" / "data").rglob("*.wrl")),
        *sorted((root / "models").rglob("*.wrl")),
    ]
    seen = 0
    for path in files:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                scene = read(path, lenient=True)
        except VttsError:
            continue  # the conformance set's bad files: they never reach a check of faces
        for node in scene.find("IndexedFaceSet"):
            same_outcome(node)
            seen += 1
    assert seen > 10


def test_check_face_set_is_not_for_other_nodes():
    with pytest.raises(TypeError, match="not an IndexedFaceSet"):
        check_face_set(parse(H + "DEF B Box { }").node("B"))


def test_a_kept_mesh_is_given_again_read_only_and_a_changed_node_gets_its_own(monkeypatch):
    """triangulate keeps meshes by their node's geometry: the same geometry (another node, the
    same fields) gives the kept mesh, read-only; any field it reads, changed, gives a new one.
    (A cube is small enough to be made anew each time: here it is kept too.)"""
    import vtts.vrml.geometry

    assert triangulate(ifs()) is not triangulate(ifs())
    monkeypatch.setattr(vtts.vrml.geometry, "KEEP_FROM", 0)
    a = triangulate(ifs())
    assert triangulate(ifs()) is a
    assert not a.positions.flags.writeable and not a.normals.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        a.positions[0] = 0
    changed = [
        ifs(points=CUBE_POINTS.replace("-1 -1 1,", "-1 -1 2,", 1)),
        ifs(faces=CUBE_FACES.replace("0 1 2 3", "0 2 3 1", 1)),
        ifs("ccw FALSE"),
        ifs("solid FALSE"),
        ifs("creaseAngle 1"),
        ifs("texCoord TextureCoordinate { point [ 0 0, 1 0, 1 1, 0 1 ] } "
            "texCoordIndex [ 0 1 2 3 -1, 0 1 2 3 -1, 0 1 2 3 -1, 0 1 2 3 -1, 0 1 2 3 -1, "
            "0 1 2 3 ]"),
    ]  # fmt: skip
    meshes = [triangulate(n) for n in changed]
    assert all(m is not a for m in meshes) and len({id(m) for m in meshes}) == len(meshes)
    # a node changed after its mesh was kept gives the changed mesh: a field set anew, or its
    # array changed in place
    node = ifs()
    coord = node["coord"].expand()
    coord.fields["point"] = coord["point"] * 2
    assert np.array_equal(triangulate(node).positions, 2 * a.positions)
    coord.fields["point"] *= 1.5
    assert np.array_equal(triangulate(node).positions, 3 * a.positions)
    # replacement points (an animated pose) are never kept
    moved = triangulate(ifs(), points=a.positions[:8] * 0 + 1)
    assert moved is not triangulate(ifs(), points=a.positions[:8] * 0 + 1)
