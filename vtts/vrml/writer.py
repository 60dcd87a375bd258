"""Writing a :class:`~vtts.vrml.scene.Scene` back as VRML97 text.

``parse(write(scene)) == scene``: numbers are written exactly (shortest round-trip text), shared
nodes come back as DEF/USE, PROTOs, IS bindings, Script interfaces and ROUTEs are kept. Only the
fields the scene sets are written; defaults stay implicit.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from vtts.atomic import write_text
from vtts.vrml.fields import SFImage, escape_string, format_number, format_numbers
from vtts.vrml.nodes import FieldDecl, FieldType
from vtts.vrml.parser import HEADER
from vtts.vrml.scene import Node, Proto, Route, Scene

_INDENT = "  "


def dumps(scene: Scene, *, comment: str | None = None) -> str:
    """The VRML97 text of ``scene``; ``comment`` (one or more lines) goes under the header."""
    w = _Writer(_shared_nodes(scene.statements))
    w.lines.append(HEADER)
    if comment:
        w.lines.extend("# " + c for c in comment.splitlines())
    for s in scene.statements:
        w.statement(s, 0)
    return "\n".join(w.lines) + "\n"


def write(scene: Scene, path: str | os.PathLike[str], *, comment: str | None = None) -> None:
    """Write ``scene`` to ``path`` (atomically: a temporary file renamed when complete)."""
    write_text(path, dumps(scene, comment=comment))


class _Writer:
    def __init__(self, shared: set[int]) -> None:
        self.shared = shared
        self.lines: list[str] = []
        self.written: set[int] = set()
        self.names: dict[int, str] = {}
        self.generated = 0

    def statement(self, s: Any, depth: int) -> None:
        pad = _INDENT * depth
        if isinstance(s, Node):
            self.node(s, depth, pad)
        elif isinstance(s, Proto):
            self.proto(s, depth)
        elif isinstance(s, Route):
            self.lines.append(
                f"{pad}ROUTE {s.from_node}.{s.from_event} TO {s.to_node}.{s.to_event}"
            )
        else:  # pragma: no cover
            raise TypeError(f"not a VRML statement: {s!r}")

    # ---- nodes --------------------------------------------------------------------------------

    def node_ref(self, node: Node) -> str | None:
        """``USE name`` when ``node`` was written before, else None (and marks it written)."""
        if id(node) in self.written:
            name = node.name or self.names.get(id(node))
            return f"USE {name}"
        self.written.add(id(node))
        return None

    def node(self, node: Node, depth: int, first_prefix: str) -> None:
        """Write ``node`` starting on a line that begins with ``first_prefix``."""
        use = self.node_ref(node)
        if use:
            self.lines.append(first_prefix + use)
            return
        name = node.name
        if name is None and id(node) in self.shared:
            self.generated += 1
            name = f"_vtts{self.generated}"
            self.names[id(node)] = name
        head = f"DEF {name} " if name else ""
        self.lines.append(f"{first_prefix}{head}{node.type.name} {{")
        opening = len(self.lines)
        inner = depth + 1
        pad = _INDENT * inner
        decls = {d.name: d for d in node.script_decls}
        for kind, key in self.body_order(node):
            if kind == "extra":
                self.statement(node.extras[key], inner)
            elif kind == "decl":
                self.script_decl(node, decls[key], inner)
            elif kind == "field":
                decl = node.type.field(key)
                assert decl is not None, key
                self.value(f"{pad}{key} ", decl.type, node.fields[key], inner)
            else:
                self.lines.append(f"{pad}{key} IS {node.is_maps[key]}")
        if len(self.lines) == opening:  # an empty body: "Group {}"
            self.lines[-1] += "}"
        else:
            self.lines.append(_INDENT * depth + "}")

    @staticmethod
    def body_order(node: Node) -> list[tuple[str, Any]]:
        """The node's body as parsed, then whatever was added to the node since (PROTOs first,
        then Script declarations, fields, IS bindings and ROUTEs)."""
        decl_names = {d.name for d in node.script_decls}
        present = (
            {("decl", d) for d in decl_names}
            | {("field", f) for f in node.fields if f not in decl_names}
            | {("is", m) for m in node.is_maps if m not in decl_names}
            | {("extra", i) for i in range(len(node.extras))}
        )
        order = [item for item in node.order if item in present]
        seen = set(order)
        rest = (
            [("extra", i) for i, e in enumerate(node.extras) if isinstance(e, Proto)]
            + [("decl", d.name) for d in node.script_decls]
            + [("field", f) for f in node.fields if f not in decl_names]
            + [("is", m) for m in node.is_maps if m not in decl_names]
            + [("extra", i) for i, e in enumerate(node.extras) if not isinstance(e, Proto)]
        )
        return order + [item for item in rest if item not in seen]

    def script_decl(self, node: Node, decl: FieldDecl, depth: int) -> None:
        pad = _INDENT * depth
        head = f"{pad}{decl.access} {decl.type.name} {decl.name}"
        if decl.name in node.is_maps:
            self.lines.append(f"{head} IS {node.is_maps[decl.name]}")
        elif decl.has_value:
            self.value(head + " ", decl.type, node.fields[decl.name], depth)
        else:
            self.lines.append(head)

    # ---- PROTO --------------------------------------------------------------------------------

    def proto(self, proto: Proto, depth: int) -> None:
        pad = _INDENT * depth
        inner = depth + 1
        if proto.kind == "externproto":
            self.lines.append(f"{pad}EXTERNPROTO {proto.name} [")
            for d in proto.decls.values():
                self.lines.append(f"{_INDENT * inner}{d.access} {d.type.name} {d.name}")
            urls = " ".join(escape_string(u) for u in proto.urls)
            self.lines.append(f"{pad}] [ {urls} ]" if urls else f"{pad}] [ ]")
            return
        self.lines.append(f"{pad}PROTO {proto.name} [" + ("" if proto.decls else " ] {"))
        for d in proto.decls.values():
            head = f"{_INDENT * inner}{d.access} {d.type.name} {d.name}"
            if d.has_value:
                self.value(head + " ", d.type, d.default, inner)
            else:
                self.lines.append(head)
        if proto.decls:
            self.lines.append(f"{pad}] {{")
        for s in proto.body:
            self.statement(s, inner)
        self.lines.append(pad + "}")

    # ---- values -------------------------------------------------------------------------------

    def value(self, prefix: str, ftype: FieldType, value: Any, depth: int) -> None:
        """Write ``prefix`` followed by ``value`` (possibly over several lines)."""
        kind = ftype.kind
        if kind == "node":
            if not ftype.multi:
                if value is None:
                    self.lines.append(prefix + "NULL")
                else:
                    self.node(value, depth, prefix)
                return
            if not value:
                self.lines.append(prefix + "[]")
                return
            self.lines.append(prefix + "[")
            for n in value:
                self.node(n, depth + 1, _INDENT * (depth + 1))
            self.lines.append(_INDENT * depth + "]")
            return
        if kind == "bool":
            self.lines.append(prefix + ("TRUE" if value else "FALSE"))
        elif kind == "string":
            if ftype.multi:
                self.lines.append(prefix + "[ " + " ".join(escape_string(s) for s in value) + " ]")
            else:
                self.lines.append(prefix + escape_string(value))
        elif kind == "image":
            self.lines.append(prefix + _format_image(value))
        elif not ftype.multi:
            if ftype.width == 1:
                self.lines.append(prefix + format_number(value))
            else:
                self.lines.append(prefix + " ".join(format_number(v) for v in value))
        else:
            arr = np.asarray(value)
            if arr.size == 0:
                self.lines.append(prefix + "[]")
            elif arr.size <= 12:
                self.lines.append(prefix + "[ " + ", ".join(format_numbers(arr)) + " ]")
            else:
                pad = _INDENT * (depth + 1)
                self.lines.append(prefix + "[")
                if ftype.kind == "int" and arr.ndim == 1 and (arr == -1).any():
                    # coordIndex style: one polygon per line
                    text = " ".join(arr.astype(str).tolist())
                    body = text.replace(" -1 ", " -1\n" + pad)
                    self.lines.append(pad + body)
                else:
                    rows = format_numbers(arr, per_line=1 if arr.ndim > 1 else 8)
                    self.lines.append(pad + (",\n" + pad).join(rows))
                self.lines.append(_INDENT * depth + "]")


def _format_image(img: SFImage) -> str:
    head = f"{img.width} {img.height} {img.components}"
    if img.pixels.size == 0:
        return head
    digits = max(2, 2 * img.components)
    return head + " " + " ".join(f"0x{int(p):0{digits}X}" for p in img.pixels)


def _shared_nodes(statements: list[Any]) -> set[int]:
    """ids of nodes referenced more than once (they need a DEF name to be written as USE)."""
    seen: set[int] = set()
    shared: set[int] = set()
    stack: list[Any] = list(statements)
    while stack:
        s = stack.pop()
        if isinstance(s, Node):
            if id(s) in seen:
                shared.add(id(s))
                continue
            seen.add(id(s))
            for v in s.fields.values():
                stack.extend(v if isinstance(v, list) else [v])
            stack.extend(s.extras)
        elif isinstance(s, Proto):
            stack.extend(s.body)
            for d in s.decls.values():
                stack.extend(d.default if isinstance(d.default, list) else [d.default])
    return shared
