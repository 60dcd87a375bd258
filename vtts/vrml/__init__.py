"""VRML97 (ISO/IEC 14772-1) for vtts: parse, inspect, triangulate and write scenes.

>>> from vtts import vrml
>>> scene = vrml.parse('#VRML V2.0 utf8\\nDEF T Transform { translation 0 1 0 }')
>>> scene.node("T")["translation"]
array([0., 1., 0.])
"""

from vtts.vrml.fields import FIELD_TYPES, FieldType, SFImage
from vtts.vrml.geometry import (
    PRIMITIVES,
    TriangleMesh,
    check_face_set,
    polygon_triangle_count,
    primitive_mesh,
    triangulate,
)
from vtts.vrml.nodes import FieldDecl, NodeType, standard_node_types
from vtts.vrml.parser import parse, read, resolve_url, url_problem, url_roots
from vtts.vrml.scene import Node, Proto, Route, Scene, drawn_children, same_node
from vtts.vrml.transform import compose_transform, rotation_matrix, transform_matrix
from vtts.vrml.writer import dumps, write

__all__ = [
    "FIELD_TYPES",
    "PRIMITIVES",
    "FieldDecl",
    "FieldType",
    "Node",
    "NodeType",
    "Proto",
    "Route",
    "SFImage",
    "Scene",
    "TriangleMesh",
    "check_face_set",
    "compose_transform",
    "drawn_children",
    "dumps",
    "parse",
    "polygon_triangle_count",
    "primitive_mesh",
    "read",
    "resolve_url",
    "rotation_matrix",
    "same_node",
    "standard_node_types",
    "transform_matrix",
    "triangulate",
    "url_problem",
    "url_roots",
    "write",
]
