"""Parsing VRML97 text into a :class:`~vtts.vrml.scene.Scene`.

Three steps, as in lark's own design: the LALR parser turns text into a tree
(``grammars/vrml97.lark``), then :class:`_Builder` walks the tree in file order — DEF/USE and PROTO
scopes are order-dependent, so this is a walk, not a bottom-up transformer — and types every value
from the node tables, checking the standard's rules as it goes.

Safety: nothing is ever fetched; url fields that would leave the file's folder are rejected; the
file size and nesting depth are limited, so hostile input gives a :class:`VrmlLimitError` rather
than a RecursionError or a hang.
"""

from __future__ import annotations

import dataclasses
import os
import posixpath
import re
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

from vtts.errors import (
    VrmlLimitError,
    VrmlSemanticError,
    VrmlSyntaxError,
    VrmlUrlError,
    VttsWarning,
)
from vtts.resources import lark_parser
from vtts.vrml.fields import (
    FIELD_TYPES,
    FieldType,
    NumberError,
    SFImage,
    parse_floats,
    parse_ints,
    unescape_string,
)
from vtts.vrml.nodes import (
    ROLES,
    FieldDecl,
    NodeType,
    generic_node_type,
    interface_conflict,
    parse_default,
    standard_node_types,
)
from vtts.vrml.scene import Node, Proto, Route, Scene

#: Default limits (override per call).
MAX_BYTES = 256 * 1024 * 1024
MAX_DEPTH = 100

HEADER = "#VRML V2.0 utf8"

#: Fields whose urls are loaded from disk (and so must stay inside the file's folder).
#: Anchor.url is a hyperlink, never loaded, and is not checked.
URL_FIELDS: dict[str, tuple[str, ...]] = {
    "ImageTexture": ("url",),
    "MovieTexture": ("url",),
    "AudioClip": ("url",),
    "Inline": ("url",),
    "Script": ("url",),
    "Background": ("backUrl", "bottomUrl", "frontUrl", "leftUrl", "rightUrl", "topUrl"),
}
_SCRIPT_SCHEMES = ("javascript", "vrmlscript", "ecmascript")

#: The environment variable that names extra url roots (folders separated by os.pathsep) when a
#: call gives none.
URL_ROOT_ENV = "VTTS_URL_ROOT"
_SCHEME = re.compile(r"^([A-Za-z][A-Za-z0-9+.\-]*):")

_TERMINAL_NAMES = {
    "LBRACE": "'{'",
    "RBRACE": "'}'",
    "LSQB": "'['",
    "RSQB": "']'",
    "DOT": "'.'",
    "ID": "a name",
    "NUMBERS": "a number",
    "STRING": "a string",
    "TRUE": "TRUE",
    "FALSE": "FALSE",
    "NULL": "NULL",
    "EVENTIN": "eventIn",
    "EVENTOUT": "eventOut",
    "FIELD": "field",
    "EXPOSEDFIELD": "exposedField",
    "$END": "the end of the file",
}


@cache
def _lark() -> Lark:
    return lark_parser("vrml97", parser="lalr", lexer="contextual", maybe_placeholders=False)


def parse(
    text: str | bytes,
    *,
    file: str | None = None,
    lenient: bool = False,
    url_root: str | Path | Iterable[str | Path] | None = None,
    max_bytes: int = MAX_BYTES,
    max_depth: int = MAX_DEPTH,
) -> Scene:
    """Parse VRML97 text (``str`` or UTF-8 ``bytes``) into a :class:`Scene`.

    ``file`` names the source in error messages and is the folder url fields resolve against.
    ``lenient`` loads what other browsers accept, each with a :class:`VttsWarning` at its place
    instead of an error: unknown node types (parsed generically), unknown fields (skipped), nodes
    of the wrong role in a field (dropped), IS naming a missing member (ignored), X3D statements
    (skipped), a PROTO field default that USEs a DEF of the enclosing file (resolved, or dropped),
    urls that leave the allowed folders (kept as data, never loaded), values of the wrong type
    (skipped), a field given twice (the last kept) and members of types VRML97 lacks (left out).
    ``url_root``: folders besides the file's own that url fields may name files in (one or
    several; None reads ``$VTTS_URL_ROOT``). Raises a :class:`~vtts.errors.VrmlError` subclass for
    any invalid input.
    """
    where = file or "<text>"
    roots = url_roots(url_root)
    if isinstance(text, bytes):
        if len(text) > max_bytes:
            raise VrmlLimitError(
                f"file is {len(text)} bytes, more than the limit of {max_bytes}", file=where
            )
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as e:
            line = text.count(b"\n", 0, e.start) + 1
            col = e.start - (text.rfind(b"\n", 0, e.start) + 1) + 1
            raise VrmlSyntaxError(
                f"invalid UTF-8 byte 0x{text[e.start]:02x} (VRML97 files are UTF-8)",
                file=where,
                line=line,
                column=col,
            ) from None
    if len(text) > max_bytes:
        raise VrmlLimitError(f"text is longer than the limit of {max_bytes} bytes", file=where)
    if text.startswith("\ufeff"):
        text = text[1:]
    _check_header(text, where)
    try:
        tree = _lark().parse(text)
    except UnexpectedInput as e:
        raise _syntax_error(e, text, where) from None
    builder = _Builder(
        file=where,
        base_dir=Path(file).resolve().parent if file else None,
        roots=roots,
        lenient=lenient,
        max_depth=max_depth,
    )
    scene = builder.build(tree)
    scene.path = Path(file) if file else None
    scene.url_roots = roots
    return scene


def read(
    path: str | Path,
    *,
    lenient: bool = False,
    url_root: str | Path | Iterable[str | Path] | None = None,
    max_bytes: int = MAX_BYTES,
) -> Scene:
    """Read and parse a ``.wrl`` file (see :func:`parse`)."""
    p = Path(path)
    try:
        size = p.stat().st_size
        if size > max_bytes:
            raise VrmlLimitError(
                f"file is {size} bytes, more than the limit of {max_bytes}", file=str(p)
            )
        data = p.read_bytes()
    except OSError as e:
        raise VrmlSyntaxError(f"cannot read file: {e.strerror}", file=str(p)) from None
    return parse(data, file=str(p), lenient=lenient, url_root=url_root, max_bytes=max_bytes)


def url_roots(url_root: str | Path | Iterable[str | Path] | None = None) -> tuple[Path, ...]:
    """The extra url roots, resolved: ``url_root`` (a folder or several), or when it is None the
    folders in ``$VTTS_URL_ROOT`` (separated by ``os.pathsep``). Each must be an existing folder."""
    if url_root is None:
        env = os.environ.get(URL_ROOT_ENV, "")
        given: list[str | Path] = [d for d in env.split(os.pathsep) if d]
        origin = f"${URL_ROOT_ENV}"
    elif isinstance(url_root, (str, Path)):
        given, origin = [url_root], "url root"
    else:
        given, origin = list(url_root), "url root"
    roots = []
    for d in given:
        p = Path(d).expanduser()
        if not p.is_dir():
            raise VrmlUrlError(f"{origin} '{d}' is not a folder")
        roots.append(p.resolve())
    return tuple(roots)


def _check_header(text: str, where: str) -> None:
    first = text.split("\n", 1)[0].rstrip("\r")
    if first.startswith(HEADER) and (len(first) == len(HEADER) or first[len(HEADER)] in " \t"):
        return
    if first.startswith("#VRML V1.0"):
        raise VrmlSyntaxError(
            f"VRML 1.0 is not supported: vtts reads VRML97 files, which start with '{HEADER}'",
            file=where,
            line=1,
            column=1,
        )
    shown = first[:40] + ("…" if len(first) > 40 else "")
    raise VrmlSyntaxError(
        f"missing VRML97 header: the first line must be '{HEADER}', got {shown!r}",
        file=where,
        line=1,
        column=1,
    )


def _caret(text: str, line: int, column: int) -> str:
    lines = text.splitlines()
    src = lines[line - 1] if 0 < line <= len(lines) else ""
    start = max(0, column - 60)
    src_shown = src[start : start + 100]
    return f"    {src_shown}\n    {' ' * (column - 1 - start)}^"


def _syntax_error(e: UnexpectedInput, text: str, where: str) -> VrmlSyntaxError:
    line, col = getattr(e, "line", 0) or 0, getattr(e, "column", 0) or 0
    if isinstance(e, UnexpectedCharacters):
        ch = text[e.pos_in_stream] if e.pos_in_stream < len(text) else ""
        msg = f"unexpected character {ch!r}"
    elif isinstance(e, UnexpectedToken):
        tok = e.token
        if tok.type == "$END":
            msg = "unexpected end of file"
            line = line if line > 0 else text.count("\n") + 1
        else:
            shown = str(tok) if len(str(tok)) <= 30 else str(tok)[:30] + "…"
            msg = f"unexpected {shown!r}"
        expected = sorted({_TERMINAL_NAMES.get(t, t) for t in e.expected if not t.startswith("_")})
        if expected:
            msg += "; expected " + ", ".join(expected)
    elif isinstance(e, UnexpectedEOF):
        msg = "unexpected end of file"
        line = text.count("\n") + 1
        col = len(text.rsplit("\n", 1)[-1]) + 1
    else:  # pragma: no cover - lark has no other kinds
        msg = str(e)
    if line <= 0:
        line, col = text.count("\n") + 1, len(text.rsplit("\n", 1)[-1]) + 1
    return VrmlSyntaxError(msg, file=where, line=line, column=col, context=_caret(text, line, col))


# ---- the builder ---------------------------------------------------------------------------------


@dataclass
class _Scope:
    """A DEF namespace plus the PROTO names visible in it.

    DEF names do not cross scope boundaries (each PROTO body and each PROTO field default has its
    own); PROTO names are looked up outward.
    """

    parent: _Scope | None = None
    proto: Proto | None = None
    defs: dict[str, Node] = field(default_factory=dict)
    protos: dict[str, NodeType] = field(default_factory=dict)
    #: for the scope of a PROTO field default: ``"PROTO P field 'f'"`` (lenient mode looks
    #: outward for the DEFs its USEs name)
    default_of: str | None = None
    #: local names that X3D IMPORT statements would have made (lenient mode skips their ROUTEs)
    imports: set[str] = field(default_factory=set)

    def lookup_proto(self, name: str) -> NodeType | None:
        s: _Scope | None = self
        while s is not None:
            if name in s.protos:
                return s.protos[name]
            s = s.parent
        return None

    def in_proto(self) -> Proto | None:
        """The PROTO whose body this scope is (IS is legal only there)."""
        return self.proto


_NODE_TREES = ("node", "def_node", "use_node")

#: What :meth:`_Builder.value` gives for an SFNode whose node is dropped in lenient mode.
_DROPPED = object()


class _DropDefault(Exception):
    """Lenient mode: a USE in a PROTO field default names no DEF anywhere (the default goes)."""


class _SkipDeclaration(Exception):
    """Lenient mode: an interface declaration of a type VRML97 lacks (the warning is given)."""


class _BadValue(Exception):
    """Lenient mode: a value of the wrong type for its field (``error`` says why, and where);
    the field that holds it is skipped with a warning. Strict mode raises ``error`` itself."""

    def __init__(self, error: VrmlSemanticError) -> None:
        super().__init__(error.message)
        self.error = error


class _Builder:
    def __init__(
        self,
        *,
        file: str,
        base_dir: Path | None,
        roots: tuple[Path, ...] = (),
        lenient: bool,
        max_depth: int,
    ):
        self.file = file
        self.base_dir = base_dir
        self.roots = roots
        self.lenient = lenient
        self.max_depth = max_depth
        self.standard = standard_node_types()
        self.node_count = 0

    # ---- errors -----------------------------------------------------------------------------

    def error(self, msg: str, tok: Token | None, cls: type = VrmlSemanticError) -> Exception:
        line = getattr(tok, "line", None)
        col = getattr(tok, "column", None)
        return cls(msg, file=self.file, line=line, column=col)

    def warn(self, msg: str, tok: Token | None, where: Any = None) -> None:
        """A lenient-mode warning at ``tok`` (or at ``where``'s ``line``/``column``)."""
        place = where if where is not None else tok
        warnings.warn(
            VttsWarning(
                msg,
                file=self.file,
                line=getattr(place, "line", None),
                column=getattr(place, "column", None),
            ),
            stacklevel=2,
        )

    def value_error(self, msg: str, tok: Token | None = None, *, line=None, column=None):
        """A value of the wrong type for its field: an error in strict mode, a :class:`_BadValue`
        (the field is skipped) in lenient mode."""
        err = VrmlSemanticError(
            msg,
            file=self.file,
            line=line if line is not None else getattr(tok, "line", None),
            column=column if column is not None else getattr(tok, "column", None),
        )
        return _BadValue(err) if self.lenient else err

    def skip_bad_value(self, bad: _BadValue, outcome: str) -> None:
        """Lenient mode: warn at the bad value's place, saying what becomes of it."""
        self.warn(f"{bad.error.message}: {outcome} (--lenient)", None, bad.error)

    # ---- statements -------------------------------------------------------------------------

    def build(self, tree: Tree) -> Scene:
        scope = _Scope()
        statements = [self.statement(t, scope, 0) for t in tree.children]
        statements = [s for s in statements if s is not None]
        return Scene(statements=statements, defs=scope.defs, node_count=self.node_count)

    def statement(self, t: Tree, scope: _Scope, depth: int) -> Any:
        kind = t.data
        if kind in _NODE_TREES:
            return self.node_stmt(t, scope, depth)
        if kind == "proto":
            return self.proto(t, scope, depth)
        if kind == "externproto":
            return self.externproto(t, scope)
        if kind == "route":
            return self.route(t, scope)
        if kind == "x3d_stmt":
            return self.x3d_statement(t, scope)
        raise AssertionError(kind)  # pragma: no cover

    def x3d_statement(self, t: Tree, scope: _Scope) -> None:
        """PROFILE, COMPONENT, META, UNIT, IMPORT, EXPORT: X3D, not VRML97 (skipped if lenient)."""
        keyword = t.children[0]
        if not self.lenient:
            raise self.error(
                f"{keyword} is an X3D statement, not VRML97: a '{HEADER}' file cannot hold it "
                "(use --lenient to skip X3D statements)",
                keyword,
                VrmlSyntaxError,
            )
        if str(keyword) == "IMPORT":
            names = [c for c in t.children[1:] if c.type == "ID"]
            scope.imports.add(str(names[-1]))  # "AS name", or the exported name itself
        self.warn(f"X3D statement {keyword} skipped (--lenient)", keyword)

    def node_stmt(self, t: Tree, scope: _Scope, depth: int) -> Node | None:
        """The node of a statement; None for a USE lenient mode dropped (an undefined name)."""
        if t.data == "use_node":
            name_tok = t.children[0]
            node = scope.defs.get(str(name_tok))
            if node is None and self.lenient and scope.default_of is not None:
                return self.outer_use(name_tok, scope)
            if node is None:
                known = ", ".join(sorted(scope.defs)) or "none"
                msg = (
                    f"USE of undefined name '{name_tok}': a USE must follow a DEF of the same "
                    f"name in the same scope (DEF names here: {known})"
                )
                if not self.lenient:
                    raise self.error(msg, name_tok)
                # browsers draw the rest of the scene: the USE stands for no node
                self.warn(f"{msg}: the USE is dropped (--lenient)", name_tok)
                return None
            return node
        if t.data == "def_node":
            name_tok, node_tree = t.children
            return self.node(node_tree, scope, depth, def_name=str(name_tok))
        return self.node(t, scope, depth)

    def outer_use(self, name_tok: Token, scope: _Scope) -> Node:
        """Lenient mode: a USE in a PROTO field default of a name DEFed outside it (browsers
        look outward; VRML97 gives each default its own DEF scope)."""
        outer = scope.parent
        while outer is not None:
            if str(name_tok) in outer.defs:
                self.warn(
                    f"USE {name_tok} in the default of {scope.default_of} names a DEF outside "
                    "the default (a PROTO field default has its own DEF scope): resolved to "
                    "a copy of that DEF (--lenient)",
                    name_tok,
                )
                # a copy, DEFed in the default's own scope: the scene written back is VRML97
                node = _copy_tree(outer.defs[str(name_tok)], {})
                scope.defs[str(name_tok)] = node
                return node
            outer = outer.parent
        self.warn(
            f"USE {name_tok} in the default of {scope.default_of} names no DEF before it: the "
            "default is dropped (--lenient)",
            name_tok,
        )
        raise _DropDefault

    def node_type(self, tok: Token, scope: _Scope) -> NodeType:
        name = str(tok)
        nt = scope.lookup_proto(name)
        if nt is not None:
            return nt
        std = self.standard.get(name)
        if std is not None:
            if name == "Script":
                # A Script adds its own interface to the fixed members: give each its own type.
                return NodeType("Script", dict(std.decls), std.roles, "script")
            return std
        if self.lenient:
            self.warn(f"unknown node type '{name}' parsed generically (--lenient)", tok)
            return generic_node_type(name)
        raise self.error(
            f"unknown node type '{name}': not a VRML97 node, an MPEG-4 face node, or a PROTO "
            "declared before this point (use --lenient to load vendor extension nodes)",
            tok,
        )

    def node(self, t: Tree, scope: _Scope, depth: int, def_name: str | None = None) -> Node:
        type_tok = t.children[0]
        if depth >= self.max_depth:
            raise self.error(
                f"nodes nest deeper than the limit of {self.max_depth} levels",
                type_tok,
                VrmlLimitError,
            )
        ntype = self.node_type(type_tok, scope)
        node = Node(ntype, name=def_name, line=type_tok.line, column=type_tok.column)
        self.node_count += 1
        if def_name is not None:
            # Registered before the body: a Script may USE itself in its own fields.
            scope.defs[def_name] = node
        for el in t.children[1:]:
            kind = el.data
            if kind == "field_value":
                if self.field_value(node, el, scope, depth):
                    node.order.append(("field", str(el.children[0])))
            elif kind == "field_is":
                if self.field_is(node, el, scope):
                    node.order.append(("is", str(el.children[0])))
            elif kind in ("route", "proto", "externproto"):
                extra = self.statement(el, scope, depth + 1)
                if extra is not None:  # None: a ROUTE lenient mode skipped
                    node.order.append(("extra", len(node.extras)))
                    node.extras.append(extra)
            elif kind in ("event_decl", "field_decl"):
                try:
                    self.script_decl(node, el, scope, depth)
                except _SkipDeclaration:
                    continue
                node.order.append(("decl", str(el.children[2])))
            else:  # pragma: no cover
                raise AssertionError(kind)
        return node

    def field_value(self, node: Node, el: Tree, scope: _Scope, depth: int) -> bool:
        """Set a field from a field_value tree; False when lenient mode skipped it."""
        name_tok, value_tree = el.children
        name = str(name_tok)
        ntype = node.type
        if ntype.kind == "generic":
            try:
                ftype, value = self.infer_value(
                    value_tree, scope, depth, f"{name}' of {ntype.describe()}"
                )
            except _BadValue as bad:
                self.skip_bad_value(bad, "the value is skipped")
                return False
            if name in node.fields:  # given twice: the last one's type
                ntype.decls[name] = FieldDecl("exposedField", ftype, name, None)
            ntype.decls.setdefault(name, FieldDecl("exposedField", ftype, name, None))
        else:
            decl = ntype.field(name)
            if decl is None or (ntype.kind == "script" and _is_script_decl(node, name)):
                problem = self.unknown_member(ntype, name_tok)
                if not self.lenient:
                    raise problem
                what = (
                    f"'{name}' is an event of {ntype.describe()}, not a field"
                    if ntype.member(name)
                    else f"{ntype.describe()} has no field '{name}'"
                )
                self.warn(f"{what}: skipped with its value (--lenient)", name_tok)
                return False
            try:
                value = self.value(value_tree, decl, scope, depth, f"{name}' of {ntype.describe()}")
            except _BadValue as bad:
                self.skip_bad_value(bad, "the value is skipped")
                return False
        if name in node.fields or name in node.is_maps:
            self.given_twice(node, name, name_tok)
        if value is _DROPPED:
            return False
        self.check_field_urls(ntype, name, value_tree, value)
        node.fields[name] = value
        return True

    def given_twice(self, node: Node, name: str, tok: Token) -> None:
        """A field (or IS binding) set a second time in one node: an error, or in lenient mode a
        warning and the earlier one forgotten (the last one counts, as in other browsers)."""
        msg = f"field '{name}' is given twice in one {node.type.describe()}"
        if not self.lenient:
            raise self.error(msg, tok)
        self.warn(f"{msg}: the last one is kept (--lenient)", tok)
        node.fields.pop(name, None)
        node.is_maps.pop(name, None)
        node.order = [o for o in node.order if not (o[0] in ("field", "is") and o[1] == name)]

    def unknown_member(self, ntype: NodeType, name_tok: Token) -> Exception:
        name = str(name_tok)
        if ntype.event_in(name) or ntype.event_out(name):
            return self.error(
                f"'{name}' is an event of {ntype.describe()}, not a field: only fields and "
                "exposedFields take a value",
                name_tok,
            )
        fields = ", ".join(d.name for d in ntype.decls.values() if d.has_value) or "none"
        return self.error(
            f"{ntype.describe()} has no field '{name}' (its fields: {fields})", name_tok
        )

    def field_is(self, node: Node, el: Tree, scope: _Scope) -> bool:
        """Bind a member with IS; False when lenient mode ignored the binding."""
        member_tok, iface_tok = el.children
        proto = scope.in_proto()
        if proto is None:
            msg = (
                f"'{member_tok} IS {iface_tok}' outside a PROTO body: IS binds a node's member "
                "to its PROTO's interface and is legal only inside a PROTO definition"
            )
            if not self.lenient:
                raise self.error(msg, member_tok)
            self.warn(f"{msg}: the binding is ignored (--lenient)", member_tok)
            return False
        ntype = node.type
        iface = proto.decls.get(str(iface_tok))
        if iface is None:
            if self.lenient:
                self.warn(
                    f"PROTO {proto.name} has no interface member '{iface_tok}': "
                    f"'{member_tok} IS {iface_tok}' ignored (--lenient)",
                    iface_tok,
                )
                return False
            raise self.error(f"PROTO {proto.name} has no interface member '{iface_tok}'", iface_tok)
        if ntype.kind == "generic":
            ntype.decls.setdefault(
                str(member_tok), FieldDecl("exposedField", iface.type, str(member_tok), None)
            )
        member = ntype.member(str(member_tok))
        access = member.access if member is not None else None
        if member is None:
            member = ntype.event_in(str(member_tok))
            access = "eventIn" if member is not None else None
        if member is None:
            member = ntype.event_out(str(member_tok))
            access = "eventOut" if member is not None else None
        if member is None:
            if self.lenient:
                self.warn(
                    f"{ntype.describe()} has no member '{member_tok}': "
                    f"'{member_tok} IS {iface_tok}' ignored (--lenient)",
                    member_tok,
                )
                return False
            raise self.unknown_member(ntype, member_tok)
        allowed = _IS_ACCESS[iface.access]
        mismatch = None
        if member.type is not iface.type:
            mismatch = (
                f"'{member_tok} IS {iface_tok}': {ntype.describe()}.{member_tok} is "
                f"{member.type.name} but PROTO {proto.name}.{iface_tok} is {iface.type.name} "
                "(rule: IS joins members of the same type)"
            )
        elif access not in allowed:
            mismatch = (
                f"'{member_tok} IS {iface_tok}': a {access} cannot be bound to the PROTO's "
                f"{iface.access} (an interface {iface.access} binds to "
                f"{' or '.join(sorted(allowed))} members)"
            )
        if mismatch is not None:
            if not self.lenient:
                raise self.error(mismatch, member_tok)
            self.warn(f"{mismatch}: the binding is ignored (--lenient)", member_tok)
            return False
        if str(member_tok) in node.fields or str(member_tok) in node.is_maps:
            self.given_twice(node, str(member_tok), member_tok)
        node.is_maps[str(member_tok)] = str(iface_tok)
        return True

    def script_decl(self, node: Node, el: Tree, scope: _Scope, depth: int) -> None:
        access_tok = el.children[0]
        if node.type.kind != "script":
            raise self.error(
                f"interface declaration '{access_tok} …' inside {node.type.describe()}: only "
                "PROTO interfaces and Script nodes declare members",
                access_tok,
            )
        as_field = False
        if str(access_tok) == "exposedField":
            msg = (
                "exposedField is not allowed in a Script (rule: a Script declares eventIn, "
                "eventOut and field members only)"
            )
            if not self.lenient:
                raise self.error(msg, access_tok)
            # X3D allows it (inputOutput); as a field the value is kept and the scene written
            # back is VRML97 again (ROUTEs to its events then warn as any bad ROUTE does)
            self.warn(f"{msg}: read as a field (--lenient)", access_tok)
            as_field = True
        decl, value, is_name = self.declaration(el, scope, depth, in_script=True)
        if as_field:
            decl = FieldDecl("field", decl.type, decl.name, None, None)
        problem = interface_conflict(node.type.decls, decl)
        if problem:
            self.member_clash(f"Script: {problem}", el.children[2])  # lenient: left out
        node.type.decls[decl.name] = decl
        node.script_decls.append(decl)
        if is_name is not None:
            fake = Tree("field_is", [el.children[2], is_name])
            if not self.field_is(node, fake, scope) and decl.has_value:
                node.fields[decl.name] = _empty_value(decl.type)  # lenient: binding ignored
        elif decl.has_value:
            node.fields[decl.name] = value

    def declaration(
        self, el: Tree, scope: _Scope, depth: int, *, in_script: bool, owner: str = "Script"
    ) -> tuple[FieldDecl, Any, Token | None]:
        """(declaration, value or None, IS target or None) of an event_decl/field_decl tree.

        ``owner`` names the PROTO in messages (``PROTO P``)."""
        access_tok, type_tok, name_tok = el.children[:3]
        ftype = self.field_type(type_tok, name_tok, owner)
        rest = el.children[3:]
        is_name: Token | None = None
        value = None
        if rest and isinstance(rest[0], Token):
            is_name = rest[0]
        elif rest:
            value_scope = (
                scope
                if in_script
                else _Scope(parent=scope, default_of=f"{owner} field '{name_tok}'")
            )
            try:
                value = self.value(
                    rest[0],
                    FieldDecl(str(access_tok), ftype, str(name_tok)),
                    value_scope,
                    depth,
                    f"{name_tok}'",
                )
            except _DropDefault:  # lenient: the warning is given
                value = [] if ftype.multi else None
            except _BadValue as bad:
                self.skip_bad_value(bad, f"{owner} field '{name_tok}' gets an empty value")
                value = _empty_value(ftype)
            if value is _DROPPED:
                value = None
        decl = FieldDecl(str(access_tok), ftype, str(name_tok), None if in_script else value, None)
        return decl, value, is_name

    def member_clash(self, msg: str, name_tok: Token) -> None:
        """An interface member that clashes with an earlier one: an error, or in lenient mode a
        warning and the later member left out (raises :class:`_SkipDeclaration`): the first one
        declared keeps the name."""
        if not self.lenient:
            raise self.error(msg, name_tok)
        self.warn(f"{msg}: the later member is left out (--lenient)", name_tok)
        raise _SkipDeclaration

    def field_type(self, type_tok: Token, name_tok: Token, owner: str) -> FieldType:
        """The type a declaration names. One VRML97 lacks (VRML 1.0's SFLong, X3D's SFDouble) is
        an error, or in lenient mode a warning and the member is left out (raises
        :class:`_SkipDeclaration`; IS bindings to it and values given for it then warn in turn)."""
        ftype = FIELD_TYPES.get(str(type_tok))
        if ftype is not None:
            return ftype
        if not self.lenient:
            raise self.error(
                f"unknown field type '{type_tok}' (VRML97 types: {', '.join(FIELD_TYPES)})",
                type_tok,
            )
        self.warn(
            f"unknown field type '{type_tok}': {owner} member '{name_tok}' left out (--lenient)",
            type_tok,
        )
        raise _SkipDeclaration

    # ---- PROTO / EXTERNPROTO / ROUTE ---------------------------------------------------------

    def proto(self, t: Tree, scope: _Scope, depth: int) -> Proto:
        name_tok = t.children[0]
        if depth >= self.max_depth:
            raise self.error(
                f"PROTOs nest deeper than the limit of {self.max_depth} levels",
                name_tok,
                VrmlLimitError,
            )
        proto = Proto(
            str(name_tok), {}, frozenset(ROLES), "proto", line=name_tok.line, column=name_tok.column
        )
        body_trees = []
        for el in t.children[1:]:
            if el.data in ("event_decl", "field_decl"):
                try:
                    decl, _value, is_name = self.declaration(
                        el, scope, depth, in_script=False, owner=f"PROTO {proto.name}"
                    )
                except _SkipDeclaration:
                    continue
                if is_name is not None:
                    raise self.error(
                        f"PROTO {proto.name}: IS is not allowed in a PROTO interface", is_name
                    )
                problem = interface_conflict(proto.decls, decl)
                if problem:
                    try:
                        self.member_clash(f"PROTO {proto.name}: {problem}", el.children[2])
                    except _SkipDeclaration:
                        continue
                proto.decls[decl.name] = decl
            else:
                body_trees.append(el)
        body_scope = _Scope(parent=scope, proto=proto)
        for bt in body_trees:
            statement = self.statement(bt, body_scope, depth + 1)
            if statement is not None:
                proto.body.append(statement)
        first = proto.first_node()
        if first is None:
            raise self.error(
                f"PROTO {proto.name} has no node in its body (rule: a PROTO body starts with "
                "its root node)",
                name_tok,
            )
        proto.roles = _roles_of(first)
        proto.url_members = _url_members(proto)
        for name in proto.url_members:
            d = proto.decls[name]
            for url in d.default or ():
                self.check_url(url, name_tok, node_name=f"PROTO {proto.name}.{name}")
        scope.protos[proto.name] = proto
        return proto

    def externproto(self, t: Tree, scope: _Scope) -> Proto:
        name_tok = t.children[0]
        proto = Proto(
            str(name_tok),
            {},
            frozenset(ROLES),
            "externproto",
            line=name_tok.line,
            column=name_tok.column,
        )
        for el in t.children[1:]:
            if el.data == "extern_decl":
                access_tok, type_tok, member_tok = el.children
                try:
                    ftype = self.field_type(type_tok, member_tok, f"EXTERNPROTO {proto.name}")
                except _SkipDeclaration:
                    continue
                decl = FieldDecl(str(access_tok), ftype, str(member_tok), None)
                problem = interface_conflict(proto.decls, decl)
                if problem:
                    try:
                        self.member_clash(f"EXTERNPROTO {proto.name}: {problem}", member_tok)
                    except _SkipDeclaration:
                        continue
                proto.decls[decl.name] = decl
            else:  # url_list
                for s in el.children:
                    url = unescape_string(str(s))
                    self.check_url(url, s)
                    proto.urls.append(url)
        scope.protos[proto.name] = proto
        return proto

    def route(self, t: Tree, scope: _Scope) -> Route | None:
        from_tok, out_tok, to_tok, in_tok = t.children
        ends = []
        for node_tok in (from_tok, to_tok):
            node = scope.defs.get(str(node_tok))
            if node is None and str(node_tok) in scope.imports:  # only lenient mode imports
                self.warn(
                    f"ROUTE names '{node_tok}', a node of a skipped X3D IMPORT: skipped "
                    "(--lenient)",
                    node_tok,
                )
                return None
            if node is None:
                return self.bad_route(
                    f"ROUTE names '{node_tok}', which is not DEFed before this point in the "
                    "same scope",
                    node_tok,
                )
            ends.append(node)
        src, dst = ends
        route = Route(
            str(from_tok), str(out_tok), str(to_tok), str(in_tok), from_tok.line, from_tok.column
        )
        if "generic" in (src.type.kind, dst.type.kind):
            return route
        out_decl = src.type.event_out(str(out_tok))
        if out_decl is None:
            return self.bad_route(
                self._route_member_problem(src, str(out_tok), "eventOut"), out_tok
            )
        in_decl = dst.type.event_in(str(in_tok))
        if in_decl is None:
            return self.bad_route(self._route_member_problem(dst, str(in_tok), "eventIn"), in_tok)
        if out_decl.type is not in_decl.type:
            return self.bad_route(
                f"ROUTE {from_tok}.{out_tok} TO {to_tok}.{in_tok} connects an "
                f"{out_decl.type.name} eventOut to an {in_decl.type.name} eventIn "
                "(rule: a ROUTE connects events of the same type)",
                from_tok,
            )
        return route

    def bad_route(self, msg: str, tok: Token) -> None:
        """A ROUTE that cannot connect: an error, or in lenient mode a warning and no ROUTE
        (browsers skip it and show the scene; only the animation it would carry is lost)."""
        if not self.lenient:
            raise self.error(msg, tok)
        self.warn(f"{msg}: the ROUTE is skipped (--lenient)", tok)

    @staticmethod
    def _route_member_problem(node: Node, name: str, wanted: str) -> str:
        d = node.type.member(name)
        label = f"{node.name}.{name}"
        if d is not None:
            return (
                f"ROUTE uses {label}, a {d.access} of {node.type.describe()}, where an {wanted} "
                "is needed (rule: a ROUTE goes from an eventOut to an eventIn)"
            )
        return f"ROUTE uses {label}, but {node.type.describe()} has no {wanted} '{name}'"

    # ---- values -------------------------------------------------------------------------------

    def value(self, t: Tree, decl: FieldDecl, scope: _Scope, depth: int, what: str) -> Any:
        """The typed value of a sf_value/mf_value tree for member ``decl``.

        ``what`` names the member in messages (``translation' of Transform``)."""
        ftype = decl.type
        bracketed = t.data == "mf_value"
        items = t.children
        first_tok = _first_token(t)
        if bracketed and not ftype.multi:
            raise self.value_error(
                f"field '{what} is {ftype.describe()}: a single value, not a '[ ]' list",
                first_tok,
            )
        kind = ftype.kind
        if kind in ("float", "int", "image"):
            toks = [i for i in items if isinstance(i, Token) and i.type == "NUMBERS"]
            if len(toks) != len(items):
                raise self.wrong_kind(what, ftype, items, first_tok)
            return self.numbers(toks, ftype, what, first_tok)
        if kind == "bool":
            if (
                len(items) != 1
                or not isinstance(items[0], Token)
                or items[0].type
                not in (
                    "TRUE",
                    "FALSE",
                )
            ):
                raise self.wrong_kind(what, ftype, items, first_tok)
            return items[0].type == "TRUE"
        if kind == "string":
            if not all(isinstance(i, Token) and i.type == "STRING" for i in items):
                raise self.wrong_kind(what, ftype, items, first_tok)
            strings = [unescape_string(str(i)) for i in items]
            if ftype.multi:
                return strings
            return strings[0]
        # nodes
        if not ftype.multi and len(items) == 1 and isinstance(items[0], Token):
            if items[0].type == "NULL":
                return None
        if not all(isinstance(i, Tree) for i in items):
            raise self.wrong_kind(what, ftype, items, first_tok)
        nodes = [self.node_stmt(i, scope, depth + 1) for i in items]
        nodes = [
            n
            for i, n in zip(items, nodes, strict=True)
            if n is not None and self.check_role(n, decl, what, _first_token(i))
        ]
        if ftype.multi:
            return nodes
        return nodes[0] if nodes else _DROPPED

    def wrong_kind(self, what: str, ftype: FieldType, items: list, tok: Token | None) -> Exception:
        got = _describe_items(items)
        return self.value_error(f"field '{what} expects {ftype.describe()}, got {got}", tok)

    def numbers(self, toks: list[Token], ftype: FieldType, what: str, first: Token) -> Any:
        parts = []
        for tok in toks:
            try:
                if ftype.kind == "float":
                    parts.append(parse_floats(str(tok)))
                elif ftype.kind == "image":
                    parts.append(parse_ints(str(tok), lo=-(2**31), hi=2**32 - 1))
                else:
                    parts.append(parse_ints(str(tok)))
            except NumberError as e:
                line, col = _offset_position(tok, e.offset)
                raise self.value_error(
                    f"field '{what} expects {ftype.describe()}: {e.word!r} is not {e.expected}",
                    line=line,
                    column=col,
                ) from None
        if not parts:
            parts = [np.zeros(0, dtype=np.float64 if ftype.kind == "float" else np.int64)]
        arr = parts[0] if len(parts) == 1 else np.concatenate(parts)
        n = arr.size
        if ftype.kind == "image":
            return self.image(arr, what, first)
        w = ftype.width
        if not ftype.multi:
            if n != w:
                raise self.value_error(
                    f"field '{what} expects {ftype.describe()}, got {n} number"
                    f"{'s' if n != 1 else ''}",
                    first,
                )
            if w > 1:
                return arr.astype(np.float64)
            return int(arr[0]) if ftype.kind == "int" else float(arr[0])
        if n % w:
            raise self.value_error(
                f"field '{what} expects {ftype.name}, a multiple of {w} numbers, got {n}", first
            )
        if ftype.kind == "int":
            return arr.astype(np.int32)
        return arr.reshape(-1, w) if w > 1 else arr

    def image(self, arr: np.ndarray, what: str, tok: Token) -> SFImage:
        if arr.size < 3:
            raise self.value_error(
                f"field '{what} expects SFImage (width height components pixels…), got "
                f"{arr.size} numbers",
                tok,
            )
        w, h, c = (int(v) for v in arr[:3])
        if w < 0 or h < 0 or not 0 <= c <= 4:
            raise self.value_error(
                f"field '{what}: SFImage size {w}x{h} with {c} components is invalid "
                "(components must be 1 to 4)",
                tok,
            )
        pixels = arr[3:]
        if pixels.size != w * h:
            raise self.value_error(
                f"field '{what}: SFImage of {w}x{h} needs {w * h} pixels, got {pixels.size}", tok
            )
        pixels = pixels.astype(np.int64) & 0xFFFFFFFF
        if c and pixels.size and pixels.max() >= 1 << (8 * c):
            raise self.value_error(
                f"field '{what}: pixel value {int(pixels.max()):#x} has more than {c} "
                f"component byte{'s' if c > 1 else ''}",
                tok,
            )
        return SFImage(w, h, c, pixels.astype(np.uint32))

    def infer_value(self, t: Tree, scope: _Scope, depth: int, what: str) -> tuple[FieldType, Any]:
        """Type and value of a field of a generic (unknown) node, from the value's form.

        ``what`` names the field in messages (``gain' of VendorNode``)."""
        items = t.children
        multi = t.data == "mf_value"
        if items and all(isinstance(i, Tree) for i in items):
            tname = "MFNode" if multi or len(items) != 1 else "SFNode"
        elif items and all(isinstance(i, Token) and i.type == "STRING" for i in items):
            tname = "MFString" if multi else "SFString"
        elif len(items) == 1 and isinstance(items[0], Token) and items[0].type in ("TRUE", "FALSE"):
            tname = "SFBool"
        elif len(items) == 1 and isinstance(items[0], Token) and items[0].type == "NULL":
            tname = "SFNode"
        elif items and all(isinstance(i, Token) and i.type == "NUMBERS" for i in items):
            tname = "MFFloat"
        elif not items:
            tname = "MFNode"
        else:
            raise self.value_error(
                f"field '{what} mixes kinds of values ({_describe_items(items)} and more); a "
                "field of an unknown node type must hold one kind",
                _first_token(t),
            )
        ftype = FIELD_TYPES[tname]
        decl = FieldDecl("exposedField", ftype, "?")
        return ftype, self.value(
            Tree("mf_value" if ftype.multi else "sf_value", items),
            decl,
            scope,
            depth,
            what,
        )

    def check_role(self, node: Node, decl: FieldDecl, what: str, tok: Token | None) -> bool:
        """True if ``node`` may stand in the field; False (lenient mode: drop it) or an error."""
        if decl.roles is None:
            return True
        roles = _roles_of(node)
        if roles & decl.roles:
            return True
        want = " or ".join(sorted(decl.roles))
        have = " or ".join(sorted(roles)) or "no known role"
        msg = f"field '{what} takes a {want} node; {node.type.describe()} is a {have} node"
        if self.lenient:
            self.warn(f"{msg}: dropped (--lenient)", tok)
            return False
        raise self.error(msg, tok)

    # ---- urls ---------------------------------------------------------------------------------

    def check_field_urls(self, ntype: NodeType, name: str, t: Tree, urls: Any) -> None:
        """Check the urls of field ``name`` if it is one whose files are loaded; each url is
        placed at its own string in the file."""
        loading = ntype.url_members if isinstance(ntype, Proto) else URL_FIELDS.get(ntype.name)
        if not loading or name not in loading:
            return
        if isinstance(urls, str):
            urls = [urls]
        for tok, url in zip(t.children, urls, strict=False):
            self.check_url(url, tok, node_name=f"{ntype.name}.{name}")

    def check_url(self, url: str, where: Any, node_name: str = "EXTERNPROTO url") -> None:
        """Refuse (lenient mode: warn about) a url that names a file outside the allowed
        folders; ``where`` (a token) places the message."""
        problem = url_problem(url, self.base_dir, self.roots)
        if not problem:
            return
        line = getattr(where, "line", None)
        col = getattr(where, "column", None)
        if self.lenient:
            warnings.warn(
                VttsWarning(
                    f"{node_name} {url!r} {problem}: not loaded (--lenient; --url-root DIR "
                    "allows files under DIR)",
                    file=self.file,
                    line=line,
                    column=col,
                ),
                stacklevel=2,
            )
            return
        raise VrmlUrlError(
            f"{node_name} {url!r} {problem}; urls may only name files inside the folder "
            "of the file that refers to them, or under a url root (--url-root DIR, "
            f"${URL_ROOT_ENV})",
            file=self.file,
            line=line,
            column=col,
        )


#: Which node-member accesses an interface member of each access may be bound to with IS
#: (ISO 14772-1 4.8.3, table 4.4).
_IS_ACCESS = {
    "exposedField": {"exposedField"},
    "field": {"field", "exposedField"},
    "eventIn": {"eventIn", "exposedField"},
    "eventOut": {"eventOut", "exposedField"},
}


def url_problem(url: str, base_dir: Path | None = None, roots: Iterable[Path] = ()) -> str | None:
    """Why a url must not be loaded from disk, or None if it may be.

    Network and script urls are kept as data (vtts never fetches anything: None here, and
    :func:`resolve_url` skips them). A local path must lie inside ``base_dir`` (the folder of the
    file holding the url, which relative paths resolve against) or one of ``roots``; without
    ``base_dir`` it must be relative and not climb out with ``..``. The check is on the text;
    :func:`resolve_url` checks again after following symbolic links.
    """
    path = local_path(url)
    if path is None:
        m = _SCHEME.match(url)
        if m and len(m.group(1)) == 1:
            return "is an absolute path (a drive letter)"
        if url.lower().startswith("file:"):
            return "is a file: url of another host"
        return None  # http, urn, javascript…: data only, never fetched
    allowed = [d for d in (base_dir, *roots) if d is not None]
    if path.startswith("/"):
        if _inside(posixpath.normpath(path), allowed):
            return None
        return "is an absolute path outside the allowed folders"
    norm = posixpath.normpath(path) if path else path
    if norm == ".." or norm.startswith("../"):
        if base_dir is not None and _inside(posixpath.join(base_dir.as_posix(), norm), allowed):
            return None
        return "leaves the file's folder"
    return None


def local_path(url: str) -> str | None:
    """The file path a url names (``file:`` removed, ``/`` separators, fragment dropped), or
    None for a network or script url, a drive letter or a ``file:`` url of another host."""
    path = url.split("#", 1)[0]
    m = _SCHEME.match(path)
    if m:
        if len(m.group(1)) == 1 or m.group(1).lower() != "file":
            return None
        path = path[len("file:") :]
        if path.startswith("//"):
            path = path[2:]
            if path.lower().startswith("localhost/"):
                path = path[len("localhost") :]
            elif not path.startswith("/"):
                return None
    return path.replace("\\", "/")


def _inside(path: str, folders: Iterable[Path]) -> bool:
    """Whether the normalized absolute ``path`` is inside (or is) one of ``folders``."""
    p = Path(posixpath.normpath(path))
    return any(p == d or d in p.parents for d in folders)


def resolve_url(urls: list[str], base_dir: Path | None, roots: Iterable[Path] = ()) -> Path | None:
    """The first url of ``urls`` that names an existing local file inside ``base_dir`` or one
    of ``roots`` (relative urls resolve against ``base_dir``).

    Network urls are skipped (never fetched). Symbolic links are followed and the result is
    checked again, so a link cannot lead outside the allowed folders either.
    """
    if base_dir is None:
        return None
    base = base_dir.resolve()
    allowed = [base, *(Path(r).resolve() for r in roots)]
    for url in urls:
        path = local_path(url)
        if path is None or url_problem(url, base, allowed[1:]) is not None:
            continue
        p = (base / path).resolve()
        if p.is_file() and any(p == d or d in p.parents for d in allowed):
            return p
    return None


def _url_members(proto: Proto) -> set[str]:
    """Interface members of ``proto`` whose value ends up in a url field that loads a file
    (through IS, directly or through PROTO instances in the body), so that instance values and
    defaults are checked like the url fields themselves."""
    out: set[str] = set()
    seen: set[int] = set()
    stack = list(proto.body)
    while stack:
        n = stack.pop()
        if not isinstance(n, Node) or id(n) in seen:
            continue
        seen.add(id(n))
        inner = (
            n.type.url_members
            if isinstance(n.type, Proto)
            else set(URL_FIELDS.get(n.type.name, ()))
        )
        for member, iface in n.is_maps.items():
            if member in inner:
                out.add(iface)
        for v in n.fields.values():
            stack.extend(v if isinstance(v, list) else [v])
    return out


def _copy_tree(node: Node, memo: dict[int, Node]) -> Node:
    """A copy of ``node`` and the nodes in its fields (sharing inside it kept; types shared)."""
    if id(node) in memo:
        return memo[id(node)]
    new = dataclasses.replace(
        node,
        fields={},
        is_maps=dict(node.is_maps),
        script_decls=list(node.script_decls),
        extras=list(node.extras),
        order=list(node.order),
        _expansion=None,
    )
    memo[id(node)] = new
    for k, v in node.fields.items():
        if isinstance(v, Node):
            v = _copy_tree(v, memo)
        elif isinstance(v, list):
            v = [_copy_tree(x, memo) if isinstance(x, Node) else x for x in v]
        elif isinstance(v, np.ndarray):
            v = v.copy()
        new.fields[k] = v
    return new


def _is_script_decl(node: Node, name: str) -> bool:
    return any(d.name == name for d in node.script_decls)


def _roles_of(node: Node) -> frozenset[str]:
    return node.type.roles


def _empty_value(ftype: FieldType) -> Any:
    """The empty value of a type: 0, FALSE, "", NULL, a zero vector, an empty list or image."""
    if ftype.multi:
        text = "[]"
    else:
        text = {"bool": "FALSE", "string": '""', "node": "NULL", "image": "0 0 0"}.get(
            ftype.kind, " ".join(["0"] * ftype.width)
        )
    return parse_default(ftype, text)


def _first_token(t: Any) -> Token | None:
    if isinstance(t, Token):
        return t
    for c in t.children:
        tok = _first_token(c)
        if tok is not None:
            return tok
    return None


def _describe_items(items: list) -> str:
    if not items:
        return "an empty list"
    i = items[0]
    if isinstance(i, Tree):
        return "a node"
    return {
        "NUMBERS": "a number",
        "STRING": "a string",
        "TRUE": "TRUE",
        "FALSE": "FALSE",
        "NULL": "NULL",
    }.get(i.type, repr(str(i)))


def _offset_position(tok: Token, offset: int) -> tuple[int, int]:
    text = str(tok)[:offset]
    nl = text.count("\n")
    if nl == 0:
        return tok.line, tok.column + offset
    return tok.line + nl, offset - text.rfind("\n")
