"""Node types: interface declarations (the spec's ``eventIn SFBool set_bind`` lines) and the table
of the 54 standard VRML97 nodes plus the MPEG-4 face nodes.

The table is data (``standard_nodes.txt`` beside this module), written in the notation of the
standard's node reference, one block per node::

    Shape child {
      exposedField SFNode appearance NULL : appearance
      exposedField SFNode geometry   NULL : geometry
    }

A node type is also what a PROTO or EXTERNPROTO declares, and what a Script adds to its fixed
members; all of them are :class:`NodeType` objects.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from vtts.vrml.fields import FIELD_TYPES, FieldType, SFImage, parse_floats, parse_ints

ACCESS_TYPES = ("eventIn", "eventOut", "field", "exposedField")

#: The roles a node can play, i.e. which SFNode/MFNode fields may hold it.
ROLES = frozenset(
    "child geometry appearance material texture textureTransform coordinate color normal "
    "textureCoordinate fontStyle audioSource faceDefMesh faceDefTransform".split()
)


@dataclass(frozen=True)
class FieldDecl:
    """One interface member: ``access type name [default]``.

    ``default`` is a typed value (see :mod:`vtts.vrml.fields`) for fields and exposedFields, None
    for events and for EXTERNPROTO members. ``roles`` restricts the node roles an SFNode/MFNode
    member accepts (None: any node).
    """

    access: str
    type: FieldType
    name: str
    default: Any = None
    roles: frozenset[str] | None = None

    @property
    def has_value(self) -> bool:
        """Fields and exposedFields carry a value; events do not."""
        return self.access in ("field", "exposedField")

    @property
    def is_event_in(self) -> bool:
        return self.access in ("eventIn", "exposedField")

    @property
    def is_event_out(self) -> bool:
        return self.access in ("eventOut", "exposedField")


@dataclass(eq=False)
class NodeType:
    """A node type: a name, its interface and the roles its nodes can play.

    ``kind`` is ``"standard"``, ``"proto"``, ``"externproto"``, ``"script"`` or ``"generic"`` (an
    unknown type parsed in lenient mode).
    """

    name: str
    decls: dict[str, FieldDecl] = field(default_factory=dict)
    roles: frozenset[str] = frozenset({"child"})
    kind: str = "standard"

    def member(self, name: str) -> FieldDecl | None:
        """The member called ``name`` exactly, if any."""
        return self.decls.get(name)

    def field(self, name: str) -> FieldDecl | None:
        """The field or exposedField ``name`` (the only members that take a value)."""
        d = self.decls.get(name)
        return d if d is not None and d.has_value else None

    def event_in(self, name: str) -> FieldDecl | None:
        """The member an event sent to ``name`` reaches: an eventIn, an exposedField by its own
        name, an exposedField ``x`` through ``set_x``, or (as browsers allow) an eventIn
        ``set_name`` named without its prefix."""
        d = self.decls.get(name)
        if d is not None:
            return d if d.is_event_in else None
        if name.startswith("set_"):
            d = self.decls.get(name[4:])
            if d is not None and d.access == "exposedField":
                return d
        d = self.decls.get("set_" + name)
        if d is not None and d.access == "eventIn":
            return d
        return None

    def event_out(self, name: str) -> FieldDecl | None:
        """The member an event from ``name`` leaves: an eventOut, an exposedField by its own name,
        an exposedField ``x`` through ``x_changed``, or (as browsers allow) an eventOut
        ``name_changed`` named without its suffix."""
        d = self.decls.get(name)
        if d is not None:
            return d if d.is_event_out else None
        if name.endswith("_changed"):
            d = self.decls.get(name[: -len("_changed")])
            if d is not None and d.access == "exposedField":
                return d
        d = self.decls.get(name + "_changed")
        if d is not None and d.access == "eventOut":
            return d
        return None

    def any_member(self, name: str) -> FieldDecl | None:
        """``name`` as a field, an eventIn or an eventOut, in that order."""
        return self.member(name) or self.event_in(name) or self.event_out(name)

    def describe(self) -> str:
        """``Transform`` or ``PROTO Foo`` for messages."""
        if self.kind == "proto":
            return f"PROTO {self.name}"
        if self.kind == "externproto":
            return f"EXTERNPROTO {self.name}"
        return self.name


def interface_conflict(decls: dict[str, FieldDecl], new: FieldDecl) -> str | None:
    """Why ``new`` cannot join ``decls`` (a name clash, counting the implicit ``set_x`` and
    ``x_changed`` events of an exposedField), or None."""
    if new.name in decls:
        return f"'{new.name}' is declared twice"
    implicit = []
    if new.access == "exposedField":
        implicit = [f"set_{new.name}", f"{new.name}_changed"]
    for n in implicit:
        if n in decls:
            return f"exposedField '{new.name}' implies '{n}', which is already declared"
    for d in decls.values():
        if d.access == "exposedField" and new.name in (f"set_{d.name}", f"{d.name}_changed"):
            return f"'{new.name}' clashes with the implicit event of exposedField '{d.name}'"
    return None


# ---- the standard table --------------------------------------------------------------------------

_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')


def parse_default(ftype: FieldType, text: str) -> Any:
    """A typed value from a default written in VRML syntax (``0 0 1 0``, ``[ "WALK" "ANY" ]``,
    ``NULL``, ``TRUE``) — only the forms the node table uses."""
    from vtts.vrml.fields import unescape_string

    body = text.strip()
    inner = body[1:-1].strip() if body.startswith("[") and body.endswith("]") else body
    k = ftype.kind
    if k == "bool":
        return {"TRUE": True, "FALSE": False}[inner]
    if k == "string":
        items = [unescape_string(s) for s in _STRING.findall(inner)]
        return items if ftype.multi else items[0]
    if k == "node":
        return [] if ftype.multi else None
    if k == "image":
        v = parse_ints(inner, lo=0, hi=2**32 - 1)
        return SFImage(int(v[0]), int(v[1]), int(v[2]), v[3:].astype(np.uint32))
    arr = parse_ints(inner) if k == "int" else parse_floats(inner)
    if ftype.multi:
        arr = arr.astype(np.int32) if k == "int" else arr
        return arr.reshape(-1, ftype.width) if ftype.width > 1 else arr
    if ftype.width > 1:
        return arr
    return int(arr[0]) if k == "int" else float(arr[0])


_HEADER = re.compile(r"^(\w+)\s+([\w,]+)\s*\{$")
_MEMBER = re.compile(
    r"^(eventIn|eventOut|field|exposedField)\s+(\w+)\s+(\w+)\s*(.*?)\s*(?::\s*([\w,]+))?$"
)


def _load_table(path: Path) -> dict[str, NodeType]:
    types: dict[str, NodeType] = {}
    current: NodeType | None = None
    for lineno, raw in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        where = f"{path.name}:{lineno}"
        if current is None:
            m = _HEADER.match(line)
            if not m:
                raise ValueError(f"{where}: expected 'NodeName roles {{', got {line!r}")
            roles = frozenset(m.group(2).split(","))
            unknown = roles - ROLES
            if unknown:
                raise ValueError(f"{where}: unknown roles {sorted(unknown)}")
            current = NodeType(m.group(1), {}, roles, "standard")
            continue
        if line == "}":
            types[current.name] = current
            current = None
            continue
        m = _MEMBER.match(line)
        if not m:
            raise ValueError(f"{where}: cannot read member {line!r}")
        access, tname, name, default_text, roles_text = m.groups()
        ftype = FIELD_TYPES[tname]
        default = (
            parse_default(ftype, default_text) if access in ("field", "exposedField") else None
        )
        roles_set = None
        if roles_text and roles_text != "any":
            roles_set = frozenset(roles_text.split(","))
        current.decls[name] = FieldDecl(access, ftype, name, default, roles_set)
    if current is not None:
        raise ValueError(f"{path.name}: block {current.name} is not closed")
    return types


@cache
def standard_node_types() -> dict[str, NodeType]:
    """Name → :class:`NodeType` for the 54 VRML97 nodes and FaceDefTables/Mesh/Transform."""
    return _load_table(Path(__file__).with_name("standard_nodes.txt"))


def generic_node_type(name: str) -> NodeType:
    """The type given to a node of unknown type ``name`` in lenient mode: no declared members;
    fields get their types from their values."""
    return NodeType(name, {}, ROLES, "generic")
