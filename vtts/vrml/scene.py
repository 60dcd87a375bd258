"""The parsed scene: nodes, PROTOs, ROUTEs, and what one asks of a scene graph.

A :class:`Scene` holds the file's top-level statements in order. Nodes keep only the fields the
file set (``node.fields``); ``node[name]`` falls back to the type's default. A USE is the same
:class:`Node` object referenced again, so sharing is preserved, and the writer emits DEF/USE back.

PROTO instances are nodes whose type is a :class:`Proto`; :meth:`Node.expand` builds the
instance's implementation (a copy of the PROTO body with its IS fields bound), which is what
traversal and rendering see.
"""

from __future__ import annotations

import copy
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vtts.errors import VrmlLimitError, VrmlSemanticError
from vtts.vrml.fields import equal_values
from vtts.vrml.nodes import FieldDecl, NodeType

#: Most node instances a traversal visits (USE shared inside shared nodes can make a small file
#: describe an exponentially large graph).
MAX_INSTANCES = 200_000

#: Most PROTO instances one node expands through (P1's first node a P2 instance, whose first node
#: is a P3 instance, …) before :meth:`Node.expand` gives up with a :class:`VrmlLimitError`.
MAX_PROTO_CHAIN = 64


@dataclass(eq=False)
class Route:
    """``ROUTE from_node.from_event TO to_node.to_event`` (names as written in the file)."""

    from_node: str
    from_event: str
    to_node: str
    to_event: str
    line: int = 0
    column: int = 0


@dataclass(eq=False)
class Proto(NodeType):
    """A PROTO (``kind="proto"``, with a body) or EXTERNPROTO (``kind="externproto"``, with urls).

    ``body`` holds the implementation's statements (nodes, protos, routes) in order; the first
    node decides the roles of the instances.
    """

    body: list[Any] = field(default_factory=list)
    urls: list[str] = field(default_factory=list)
    #: interface members whose values reach a url field that loads a file (checked like one)
    url_members: set[str] = field(default_factory=set)
    line: int = 0
    column: int = 0

    def first_node(self) -> Node | None:
        for s in self.body:
            if isinstance(s, Node):
                return s
        return None


@dataclass(eq=False)
class Node:
    """One node: its type, the fields set in the file, an optional DEF name.

    ``is_maps`` (inside PROTO bodies) maps a member of this node to the PROTO interface member it
    is bound to by ``IS``. ``script_decls`` lists a Script's own interface declarations in order.
    ``extras`` holds ROUTE and PROTO statements written inside the node's body. ``order`` records
    the body as written — ``("field", name)``, ``("is", member)``, ``("decl", name)`` and
    ``("extra", index into extras)`` — so the writer keeps PROTO and ROUTE statements where they
    were (a PROTO defined in a body after a USE of an outer PROTO of the same name must stay
    after it).
    """

    type: NodeType
    fields: dict[str, Any] = field(default_factory=dict)
    name: str | None = None
    is_maps: dict[str, str] = field(default_factory=dict)
    script_decls: list[FieldDecl] = field(default_factory=list)
    extras: list[Any] = field(default_factory=list)
    order: list[tuple[str, Any]] = field(default_factory=list, repr=False)
    line: int = 0
    column: int = 0
    _expansion: Node | None = field(default=None, repr=False)

    @property
    def type_name(self) -> str:
        return self.type.name

    def __getitem__(self, name: str) -> Any:
        """The value of field ``name``: as set in the file, else the type's default."""
        if name in self.fields:
            return self.fields[name]
        decl = self.type.field(name)
        if decl is None:
            raise KeyError(f"{self.type.describe()} has no field '{name}'")
        return copy.copy(decl.default) if isinstance(decl.default, list) else decl.default

    def get(self, name: str, default: Any = None) -> Any:
        try:
            return self[name]
        except KeyError:
            return default

    def __repr__(self) -> str:
        label = f"DEF {self.name} " if self.name else ""
        return f"<Node {label}{self.type.name} at line {self.line}>"

    # ---- PROTO expansion -------------------------------------------------------------------------

    def expand(self) -> Node:
        """The node this one stands for: itself for built-in types, the first node of the
        instantiated body for a PROTO instance (recursively). EXTERNPROTO instances have no
        implementation here (vtts loads nothing from the network) and expand to themselves."""
        node = self
        chain: list[str] = []
        seen: set[int] = set()
        while node.type.kind == "proto":
            if id(node.type) in seen:
                raise VrmlSemanticError(
                    f"PROTO {node.type.name} expands into itself "
                    f"({' -> '.join([*chain, node.type.name])})",
                    line=self.line,
                )
            if len(chain) == MAX_PROTO_CHAIN:
                raise VrmlLimitError(
                    f"PROTO {self.type.name} starts a chain of more than {MAX_PROTO_CHAIN} PROTOs "
                    f"(each one's first node an instance of the next: {chain[0]} -> {chain[1]} "
                    f"-> … -> {chain[-1]} -> {node.type.name}), deeper than the limit of "
                    f"{MAX_PROTO_CHAIN}",
                    line=self.line,
                )
            seen.add(id(node.type))
            chain.append(node.type.name)
            if node._expansion is None:
                node._expansion = _instantiate(node)
            node = node._expansion
        return node

    def children_nodes(self) -> Iterator[Node]:
        """Every node directly held in this node's SFNode/MFNode fields (file order)."""
        for v in self.fields.values():
            if isinstance(v, Node):
                yield v
            elif isinstance(v, list):
                for item in v:
                    if isinstance(item, Node):
                        yield item


def _instantiate(instance: Node) -> Node:
    """A copy of the PROTO body with IS-bound fields replaced by the instance's values."""
    proto = instance.type
    assert isinstance(proto, Proto)
    first = proto.first_node()
    if first is None:  # pragma: no cover - the parser requires a body node
        raise VrmlSemanticError(f"PROTO {proto.name} has no body node", line=proto.line)
    memo: dict[int, Any] = {}

    def bound(name: str) -> Any:
        if name in instance.fields:
            return instance.fields[name]
        d = proto.decls.get(name)
        return d.default if d is not None else None

    def clone(node: Node) -> Node:
        if id(node) in memo:
            return memo[id(node)]
        new = Node(
            node.type, {}, node.name, {}, list(node.script_decls), [], node.line, node.column
        )
        memo[id(node)] = new
        for k, v in node.fields.items():
            new.fields[k] = clone_value(v)
        for member, iface in node.is_maps.items():
            decl = node.type.field(member)
            if decl is not None and proto.decls.get(iface) and proto.decls[iface].has_value:
                # Nodes from the instance are shared, not copied: an instance value is one
                # object in the scene, as if USEd.
                new.fields[member] = bound(iface)
        return new

    def clone_value(v: Any) -> Any:
        if isinstance(v, Node):
            return clone(v)
        if isinstance(v, list):
            return [clone(x) if isinstance(x, Node) else x for x in v]
        return v

    return clone(first)


#: The grouping nodes whose children are drawn (see :func:`drawn_children`).
GROUPING = ("Transform", "Group", "Anchor", "Billboard", "Collision", "Switch", "LOD")


def drawn_children(node: Node) -> list:
    """The children of a grouping node that a browser draws: all of a Transform's, Group's,
    Anchor's, Billboard's or Collision's, a Switch's ``whichChoice`` (none when out of range),
    an LOD's first level (vtts draws the most detailed one); [] for any other node."""
    t = node.type.name
    if t in ("Transform", "Group", "Anchor", "Billboard", "Collision"):
        return list(node["children"])
    if t == "Switch":
        k = node["whichChoice"]
        return [node["choice"][k]] if 0 <= k < len(node["choice"]) else []
    if t == "LOD":
        return list(node["level"][:1])
    return []


@dataclass(eq=False)
class Scene:
    """A parsed VRML97 file.

    ``statements``: the top level in file order (:class:`Node`, :class:`Proto`, :class:`Route`).
    ``defs``: DEF name → node for the top-level namespace (the last DEF of a name wins, as USE
    sees it at the end of the file). ``path``: the file it came from (None for text).
    ``url_roots``: folders besides the file's own that its urls may load files from.
    """

    statements: list[Any] = field(default_factory=list)
    defs: dict[str, Node] = field(default_factory=dict)
    path: Path | None = None
    node_count: int = 0
    url_roots: tuple[Path, ...] = ()

    @property
    def roots(self) -> list[Node]:
        """The top-level nodes."""
        return [s for s in self.statements if isinstance(s, Node)]

    @property
    def protos(self) -> list[Proto]:
        return [s for s in self.statements if isinstance(s, Proto)]

    @property
    def routes(self) -> list[Route]:
        return [s for s in self.statements if isinstance(s, Route)]

    def node(self, name: str) -> Node:
        """The node DEFed as ``name`` at the top level (or inside a top-level node)."""
        try:
            return self.defs[name]
        except KeyError:
            raise KeyError(f"no node is DEFed as '{name}'") from None

    def find(self, type_name: str) -> list[Node]:
        """Every distinct node of a type, in depth-first file order (PROTO instances expanded)."""
        out: list[Node] = []
        seen: set[int] = set()

        def visit(n: Node, depth: int) -> None:
            n = n.expand()
            if id(n) in seen:
                return
            if depth > 256:
                raise VrmlLimitError("scene graph nests deeper than 256 levels", line=n.line)
            seen.add(id(n))
            if len(seen) > MAX_INSTANCES:
                raise VrmlLimitError(
                    f"the scene graph expands to more than {MAX_INSTANCES} nodes (PROTOs that "
                    "instance PROTOs multiply)",
                    line=n.line,
                )
            if n.type.name == type_name:
                out.append(n)
            for c in n.children_nodes():
                visit(c, depth + 1)

        for r in self.roots:
            visit(r, 0)
        return out

    def traverse(self) -> Iterator[tuple[Node, np.ndarray, tuple[Node, ...]]]:
        """Depth-first walk of the rendered graph with accumulated transforms.

        Yields ``(node, matrix, path)`` for every node reached through grouping nodes, where
        ``matrix`` is the ``(4, 4) float64`` local-to-world transform of the node's coordinate
        system and ``path`` the chain of grouping nodes above it. PROTO instances are expanded,
        Switch follows ``whichChoice``, LOD its first level. A node USEd twice is yielded twice.
        """
        from vtts.vrml.transform import transform_matrix

        visits = [0]

        def walk(n: Node, m: np.ndarray, path: tuple[Node, ...]) -> Iterator:
            n = n.expand()
            visits[0] += 1
            if visits[0] > MAX_INSTANCES:
                raise VrmlLimitError(
                    f"the scene graph expands to more than {MAX_INSTANCES} node instances "
                    "(nodes USEd inside nodes USEd again multiply)",
                    line=n.line,
                )
            yield n, m, path
            if n.type.name not in GROUPING:
                return
            kids = drawn_children(n)
            m2 = m @ transform_matrix(n) if n.type.name == "Transform" else m
            if len(path) > 256:
                raise VrmlLimitError("scene graph nests deeper than 256 levels", line=n.line)
            for c in kids:
                yield from walk(c, m2, (*path, n))

        for r in self.roots:
            yield from walk(r, np.eye(4), ())

    def shapes(self) -> Iterator[tuple[Node, np.ndarray, tuple[Node, ...]]]:
        """``(Shape node, world matrix (4, 4), path)`` for every Shape instance."""
        for n, m, path in self.traverse():
            if n.type.name == "Shape":
                yield n, m, path

    def triangle_count(self) -> int:
        """Triangles of every IndexedFaceSet instance in the rendered graph."""
        from vtts.vrml.geometry import polygon_triangle_count

        total = 0
        for shape, _, _ in self.shapes():
            g = shape["geometry"]
            if g is not None:
                g = g.expand()
                if g.type.name == "IndexedFaceSet":
                    total += polygon_triangle_count(g["coordIndex"])
        return total

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Scene) and same_statements(self.statements, other.statements)

    __hash__ = None  # type: ignore[assignment]


# ---- structural equality -----------------------------------------------------------------------


def same_statements(a: list[Any], b: list[Any], memo: dict[int, int] | None = None) -> bool:
    """True when two statement lists are the same scene: same node types, DEF names, field values
    (exactly), IS bindings, PROTO interfaces and bodies, ROUTEs, and the same sharing (USE)."""
    memo = {} if memo is None else memo
    if len(a) != len(b):
        return False
    return all(_same_statement(x, y, memo) for x, y in zip(a, b, strict=True))


def _same_statement(x: Any, y: Any, memo: dict[int, int]) -> bool:
    if type(x) is not type(y):
        return False
    if isinstance(x, Node):
        return same_node(x, y, memo)
    if isinstance(x, Route):
        return (x.from_node, x.from_event, x.to_node, x.to_event) == (
            y.from_node,
            y.from_event,
            y.to_node,
            y.to_event,
        )
    if isinstance(x, Proto):
        return _same_proto(x, y, memo)
    return False


def _same_decls(a: list[FieldDecl], b: list[FieldDecl], memo: dict[int, int]) -> bool:
    if len(a) != len(b):
        return False
    for d, e in zip(a, b, strict=True):
        if (d.access, d.type.name, d.name) != (e.access, e.type.name, e.name):
            return False
        if not _same_value(d.default, e.default, memo):
            return False
    return True


def _same_proto(x: Proto, y: Proto, memo: dict[int, int]) -> bool:
    if id(x) in memo:
        return memo[id(x)] == id(y)
    memo[id(x)] = id(y)
    return (
        x.name == y.name
        and x.kind == y.kind
        and x.urls == y.urls
        and _same_decls(list(x.decls.values()), list(y.decls.values()), memo)
        and same_statements(x.body, y.body, memo)
    )


def same_node(x: Node, y: Node, memo: dict[int, int] | None = None) -> bool:
    """Structural equality of two nodes (see :func:`same_statements`)."""
    memo = {} if memo is None else memo
    if id(x) in memo:
        return memo[id(x)] == id(y)
    memo[id(x)] = id(y)
    if x.type.name != y.type.name or x.name != y.name or x.is_maps != y.is_maps:
        return False
    if x.type.kind in ("proto", "externproto") and not _same_proto(x.type, y.type, memo):
        return False
    if not _same_decls(x.script_decls, y.script_decls, memo):
        return False
    if x.fields.keys() != y.fields.keys():
        return False
    if not all(_same_value(x.fields[k], y.fields[k], memo) for k in x.fields):
        return False
    return same_statements(x.extras, y.extras, memo)


def _same_value(a: Any, b: Any, memo: dict[int, int]) -> bool:
    if isinstance(a, Node) or isinstance(b, Node):
        return isinstance(a, Node) and isinstance(b, Node) and same_node(a, b, memo)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same_value(p, q, memo) for p, q in zip(a, b, strict=True))
    return equal_values(a, b)
