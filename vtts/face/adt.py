"""Animation Definition Tables (ADTs): how each MIAP deforms a personalized model.

One :class:`Adt` per MIAP holds

- :class:`MeshTable` s — for an IndexedFaceSet (by DEF name): interval borders I0 < … < In with 0
  among them, the affected vertices, and for each interval a displacement per unit of the MIAP.
  The displacement at value f is the integral from 0 to f of that piecewise-constant slope
  (MPEG-4 FaceDefMesh semantics); outside the borders the outer intervals extend.
- :class:`TransformTable` s — for a Transform (by DEF name): which field moves (rotation,
  translation or scale), its neutral value and its change per unit. A rotation keeps its axis; its
  angle is the neutral angle plus f times the unit (AU = 1e-5 rad for angle FAPs).

:class:`AnimationTables` bundles the ADTs with the model's temporal tables and feature points; it
reads and writes the ``.adt`` text format (``grammars/adt.lark``, ``docs/adt-format.md``) and
converts to and from MPEG-4 FaceDefTables nodes embedded in the ``.wrl``.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedInput

from vtts.atomic import write_text
from vtts.errors import AdtError, FapError, VttsError
from vtts.face.miap import Miap
from vtts.face.temporal import TemporalTables
from vtts.fap import AU
from vtts.limits import MAX_ADT_BYTES, read_bytes_capped
from vtts.resources import lark_parser
from vtts.vrml.fields import NumberError, format_number, format_numbers, parse_floats

TRANSFORM_FIELDS = ("rotation", "translation", "scale")
#: MPEG-4 FaceDefTransform.fieldId for each Transform field.
FIELD_IDS = {"rotation": 1, "scale": 2, "translation": 3}
#: The largest vertex index a table may name (VRML's SFInt32).
MAX_VERTEX_INDEX = 2**31 - 1


# ---- tables --------------------------------------------------------------------------------------


def interval_weights(borders: np.ndarray, f: np.ndarray | float) -> np.ndarray:
    """How much of each interval lies between 0 and ``f``, signed.

    ``borders``: ``(n+1,)`` increasing, containing 0. Returns ``(..., n)``: for f ≥ 0 the length
    of [0, f] inside each interval, for f < 0 minus the length of [f, 0]; the first and last
    intervals extend to −∞ and +∞. The displacement at f is ``weights @ slopes``.
    """
    b = np.asarray(borders, dtype=np.float64)
    lo = b[:-1].copy()
    hi = b[1:].copy()
    lo[0], hi[-1] = -np.inf, np.inf
    f = np.asarray(f, dtype=np.float64)[..., None]
    return np.clip(f, lo, hi) - np.clip(0.0, lo, hi)


@dataclass(eq=False)
class MeshTable:
    """The part of a MIAP's ADT that moves vertices of one IndexedFaceSet.

    node           DEF name of the IndexedFaceSet
    borders        ``(n+1,) float64`` interval borders, increasing, including 0
    vertices       ``(v,) int64`` indices into the IndexedFaceSet's Coordinate points
    displacements  ``(n, v, 3) float64`` model units per unit of the MIAP, per interval
    """

    node: str
    borders: np.ndarray
    vertices: np.ndarray
    displacements: np.ndarray

    def __post_init__(self) -> None:
        self.borders = np.asarray(self.borders, dtype=np.float64).reshape(-1)
        self.vertices = np.asarray(self.vertices, dtype=np.int64).reshape(-1)
        n = self.borders.size - 1
        self.displacements = np.asarray(self.displacements, dtype=np.float64).reshape(
            n if n > 0 else 0, self.vertices.size, 3
        )
        problem = border_problem(self.borders)
        if problem:
            raise AdtError(f"IndexedFaceSet {self.node}: {problem}")
        if self.vertices.size and self.vertices.min() < 0:
            raise AdtError(f"IndexedFaceSet {self.node}: vertex index {self.vertices.min()} < 0")
        # sorted neighbours rather than np.unique, which imports numpy.ma (see vtts.deferred)
        ordered = np.sort(self.vertices)
        if np.any(ordered[1:] == ordered[:-1]):
            raise AdtError(f"IndexedFaceSet {self.node}: a vertex is listed twice")

    def displacement(self, f: float) -> np.ndarray:
        """``(v, 3)`` displacement of the table's vertices at MIAP value ``f``."""
        return np.tensordot(interval_weights(self.borders, f), self.displacements, axes=1)

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, MeshTable)
            and self.node == other.node
            and np.array_equal(self.borders, other.borders)
            and np.array_equal(self.vertices, other.vertices)
            and np.array_equal(self.displacements, other.displacements)
        )


def border_problem(borders: np.ndarray) -> str | None:
    """Why interval borders are invalid, or None: they must increase and include 0."""
    if borders.size < 2:
        return f"interval borders need at least two values, got {borders.tolist()}"
    if not np.isfinite(borders).all():
        return f"interval borders must be finite, got {borders.tolist()}"
    if (np.diff(borders) <= 0).any():
        return f"interval borders must increase, got {_fmt_list(borders)}"
    if 0.0 not in borders:
        return f"interval borders must include 0, got {_fmt_list(borders)}"
    return None


def _fmt_list(a: np.ndarray) -> str:
    return "[" + " ".join(format_number(v) for v in a) + "]"


@dataclass(eq=False)
class TransformTable:
    """The part of a MIAP's ADT that moves one Transform field.

    node     DEF name of the Transform
    field    ``"rotation"``, ``"translation"`` or ``"scale"``
    neutral  ``(4,)`` axis + angle (rotation) or ``(3,)`` vector: the value at MIAP value 0
    unit     rotation: radians per unit of the MIAP (a scalar, along the neutral axis);
             translation and scale: ``(3,)`` change per unit
    """

    node: str
    field: str
    neutral: np.ndarray
    unit: np.ndarray

    def __post_init__(self) -> None:
        if self.field not in TRANSFORM_FIELDS:
            raise AdtError(f"Transform {self.node}: field must be one of {TRANSFORM_FIELDS}")
        self.neutral = np.asarray(self.neutral, dtype=np.float64).reshape(-1)
        self.unit = np.asarray(self.unit, dtype=np.float64).reshape(-1)
        want = (4, 1) if self.field == "rotation" else (3, 3)
        if (self.neutral.size, self.unit.size) != want:
            raise AdtError(
                f"Transform {self.node}: a {self.field} table needs a neutral value of "
                f"{want[0]} numbers and a unit of {want[1]}, got {self.neutral.size} and "
                f"{self.unit.size}"
            )
        if self.field == "rotation" and not np.linalg.norm(self.neutral[:3]) > 0:
            raise AdtError(f"Transform {self.node}: rotation axis must not be 0 0 0")

    def value(self, f: float) -> np.ndarray:
        """The field's value at MIAP value ``f`` (axis+angle for rotations)."""
        if self.field == "rotation":
            return np.r_[self.neutral[:3], self.neutral[3] + f * self.unit[0]]
        return self.neutral + f * self.unit

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, TransformTable)
            and (self.node, self.field) == (other.node, other.field)
            and np.array_equal(self.neutral, other.neutral)
            and np.array_equal(self.unit, other.unit)
        )


@dataclass(eq=False)
class Adt:
    """One MIAP's Animation Definition Table: its mesh and Transform tables."""

    miap: Miap
    meshes: list[MeshTable] = field(default_factory=list)
    transforms: list[TransformTable] = field(default_factory=list)

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, Adt)
            and self.miap == other.miap
            and self.meshes == other.meshes
            and self.transforms == other.transforms
        )


@dataclass(eq=False)
class AnimationTables:
    """Everything a personalized model adds to its neutral scene.

    adts            MIAP → :class:`Adt`, in file order
    temporal        :class:`TemporalTables`
    feature_points  MPEG-4 feature point (``"3.5"``) → (IndexedFaceSet DEF name, vertex index)
    """

    adts: dict[Miap, Adt] = field(default_factory=dict)
    temporal: TemporalTables = field(default_factory=TemporalTables)
    feature_points: dict[str, tuple[str, int]] = field(default_factory=dict)

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, AnimationTables)
            and list(self.adts.items()) == list(other.adts.items())
            and self.temporal == other.temporal
            and self.feature_points == other.feature_points
        )

    def __bool__(self) -> bool:
        return bool(self.adts or self.temporal or self.feature_points)

    def add(self, adt: Adt) -> None:
        if adt.miap in self.adts:
            raise AdtError(f"MIAP {adt.miap} is defined twice")
        self.adts[adt.miap] = adt

    def mesh_nodes(self) -> list[str]:
        """DEF names of every IndexedFaceSet the tables animate, in first-use order."""
        return list(dict.fromkeys(m.node for a in self.adts.values() for m in a.meshes))

    def transform_nodes(self) -> list[str]:
        return list(dict.fromkeys(t.node for a in self.adts.values() for t in a.transforms))


# ---- the .adt text format ------------------------------------------------------------------------


@cache
def _lark() -> Lark:
    return lark_parser("adt", parser="lalr", lexer="contextual", maybe_placeholders=False)


def read_adt(path: str | os.PathLike[str]) -> AnimationTables:
    """Read a ``.adt`` file."""
    p = Path(path)
    try:
        text = read_bytes_capped(p, MAX_ADT_BYTES, what=".adt file").decode("utf-8")
    except UnicodeDecodeError as e:
        raise AdtError(f"not UTF-8 text (byte {e.start})", file=str(p)) from None
    except OSError as e:
        raise AdtError(f"cannot read file: {e.strerror}", file=str(p)) from None
    return parse_adt(text, file=str(p))


def parse_adt(text: str, *, file: str = "<text>") -> AnimationTables:
    """Parse ``.adt`` text into :class:`AnimationTables`; errors are :class:`AdtError` with the
    file, line and column."""
    if not text.endswith("\n"):
        text += "\n"
    try:
        tree = _lark().parse(text)
    except UnexpectedInput as e:
        line, col = getattr(e, "line", 0), getattr(e, "column", 0)
        token = getattr(e, "token", None)
        if token is not None and token.type == "$END":
            msg = "unexpected end of file"
        elif token is not None:
            msg = f"unexpected {str(token).strip()[:30]!r}"
        else:
            ch = text[e.pos_in_stream] if e.pos_in_stream < len(text) else ""
            msg = f"unexpected character {ch!r}"
        expected = sorted(getattr(e, "expected", None) or getattr(e, "allowed", None) or [])
        names = [_EXPECTED.get(x, x) for x in expected if not x.startswith("_") or x == "_NL"]
        if names:
            msg += "; expected " + ", ".join(sorted(set(names)))
        if line is None or line <= 0:
            line = text.count("\n")
        raise AdtError(msg, file=file, line=line, column=col or 1) from None
    return _AdtBuilder(file).build(tree)


_EXPECTED = {
    "_NL": "end of line",
    "INT": "an integer",
    "NUMBER": "a number",
    "WORD": "a name",
    "LABEL": "'(…)'",
    "VERTEX_BLOCK": "'vertex' lines",
    "MIAP": "'MIAP'",
    "COLON": "':'",
    "$END": "end of file",
    "TEMPORAL_HEADER": "#TemporalDefinitionTables",
    "FEATURES_HEADER": "#FeaturePoints",
    "INDEXEDFACESET": "'IndexedFaceSet'",
    "TRANSFORM": "'Transform'",
    "INTERVAL": "'interval borders:'",
    "DISPLACEMENTS": "'displacements:'",
    "NEUTRAL": "'neutral value:'",
    "PER": "'per unit:'",
    "ROTATION": "'rotation'",
    "TRANSLATION": "'translation'",
    "SCALE": "'scale'",
    "VISEME": "'viseme'",
    "EXPRESSION": "'expression'",
    "SETTING": "a setting",
}


#: A vertex line's start: the grammar's VERTEX_BLOCK begins each line of numbers so.
_VERTEX_WORD = re.compile(r"^[ \t]*vertex", re.MULTILINE)


def _vertex_lines(block: str) -> list[int]:
    """The lines (from 0) of a vertex block that hold a vertex (not blank, not a comment)."""
    return [
        k
        for k, raw in enumerate(block.split("\n"))
        if raw.strip() and not raw.strip().startswith("#")
    ]


class _AdtBuilder:
    def __init__(self, file: str) -> None:
        self.file = file

    def error(self, msg: str, tok: Any) -> AdtError:
        return AdtError(
            msg,
            file=self.file,
            line=getattr(tok, "line", None),
            column=getattr(tok, "column", None),
        )

    def build(self, tree: Tree) -> AnimationTables:
        tables = AnimationTables()
        for section in tree.children:
            if section.data == "animation":
                for m in section.children[1:]:
                    adt = self.miap(m)
                    if adt.miap in tables.adts:
                        raise self.error(
                            f"MIAP {adt.miap} is defined twice", m.children[0].children[0]
                        )
                    tables.adts[adt.miap] = adt
            elif section.data == "temporal":
                for t in section.children[1:]:
                    self.timing(t, tables.temporal)
            elif section.data == "features":
                for f in section.children[1:]:
                    point, node, vertex = f.children
                    if str(point) in tables.feature_points:
                        raise self.error(f"feature point {point} is given twice", point)
                    tables.feature_points[str(point)] = (str(node), int(vertex))
        return tables

    def miap(self, t: Tree) -> Adt:
        id_tree = t.children[0]
        tok = id_tree.children[0]
        try:
            if id_tree.data == "fap_id":
                miap = Miap.parse(int(tok))
            elif id_tree.data == "viseme_id":
                miap = Miap("viseme", int(tok))
            else:
                miap = Miap.parse(f"expression {tok}")
        except (FapError, ValueError) as e:
            raise self.error(getattr(e, "message", str(e)), tok) from None
        adt = Adt(miap)
        for target in t.children[1:]:
            if isinstance(target, Token):  # the (label)
                continue
            try:
                if target.data == "mesh_table":
                    adt.meshes.append(self.mesh(target))
                else:
                    adt.transforms.extend(self.transform(target))
            except AdtError as e:
                if e.line is None:
                    first = target.children[0]
                    raise self.error(f"MIAP {miap}: {e.message}", first) from None
                raise
        return adt

    def number(self, tok: Token) -> float:
        # 1e999 reads as inf, which no table can use and no .adt can write
        value = float(tok)
        if not np.isfinite(value):
            raise self.error(f"{str(tok)!r} is not a finite number", tok)
        return value

    def numbers(self, toks: list[Token]) -> np.ndarray:
        return np.array([self.number(x) for x in toks], dtype=np.float64)

    def mesh(self, t: Tree) -> MeshTable:
        node_tok = t.children[0]
        border_toks = [c for c in t.children[1:] if c.type == "NUMBER"]
        block = [c for c in t.children[1:] if c.type == "VERTEX_BLOCK"]
        borders = self.numbers(border_toks)
        problem = border_problem(borders)
        if problem:
            raise self.error(f"IndexedFaceSet {node_tok}: {problem}", border_toks[0])
        n = borders.size - 1
        if not block:
            return MeshTable(str(node_tok), borders, np.zeros(0), np.zeros((n, 0, 3)))
        vertices, disp = self.vertex_block(block[0], n)
        return MeshTable(str(node_tok), borders, vertices, disp)

    def vertex_block(self, tok: Token, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Parse all ``vertex i dx dy dz …`` lines of a block at once."""
        text = str(tok)
        width = 1 + 3 * n
        if "#" not in text:
            # without comments every line that is not blank is a vertex line (the grammar's
            # VERTEX_BLOCK): the words after the line starts' "vertex" are the numbers, found
            # by one substitution (a Python loop over the lines took twice as long)
            body, count = _VERTEX_WORD.subn("", text)
            try:
                values = parse_floats(body)
            except NumberError:
                values = None
            if values is not None and values.size == width * count:
                return self._vertex_table(tok, values.reshape(count, width), n, None)
        lines = text.split("\n")
        rows = []
        for k, raw in enumerate(lines):
            s = raw.strip()
            if not s or s.startswith("#"):
                continue
            rows.append((k, raw, s[len("vertex") :]))
        body = "\n".join(r[2] for r in rows)
        try:
            values = parse_floats(body)
        except NumberError:
            values = None
        if values is None or values.size != width * len(rows):
            # find the offending line for the message
            for k, raw, rest in rows:
                line_no = tok.line + k
                try:
                    vals = parse_floats(rest)
                except NumberError as e:
                    raise AdtError(
                        f"{e.word!r} is not a number",
                        file=self.file,
                        line=line_no,
                        column=raw.index("vertex") + 7 + e.offset,
                    ) from None
                if vals.size != width:
                    raise AdtError(
                        f"a vertex line needs the vertex index and {3 * n} displacement values "
                        f"(3 per interval, {n} interval{'s' if n != 1 else ''}), got "
                        f"{vals.size - 1}",
                        file=self.file,
                        line=line_no,
                        column=1,
                    )
            raise AssertionError("unreachable")  # pragma: no cover
        return self._vertex_table(tok, values.reshape(len(rows), width), n, [r[0] for r in rows])

    def _vertex_table(
        self, tok: Token, table: np.ndarray, n: int, offsets: list[int] | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The vertex indices ``(m,)`` and displacements ``(n, m, 3)`` of a block's ``table (m,
        1 + 3n)``, checked; ``offsets``: each row's line within the block (None: worked out
        for a message)."""
        idx = table[:, 0]
        # an index of 1e30 would wrap around in int64 and be reported as negative
        wrong = (idx != np.round(idx)) | (idx < 0) | (idx > MAX_VERTEX_INDEX)
        if wrong.any():
            bad = int(np.argmax(wrong))
            raise AdtError(
                f"vertex index must be a non-negative integer up to {MAX_VERTEX_INDEX}, got "
                f"{format_number(idx[bad])}",
                file=self.file,
                line=tok.line + (offsets or _vertex_lines(str(tok)))[bad],
                column=1,
            )
        uniq, first = np.unique(idx, return_index=True)
        if uniq.size != idx.size:
            dup = np.setdiff1d(np.arange(idx.size), first)[0]
            raise AdtError(
                f"vertex {int(idx[dup])} is listed twice",
                file=self.file,
                line=tok.line + (offsets or _vertex_lines(str(tok)))[dup],
                column=1,
            )
        disp = table[:, 1:].reshape(table.shape[0], n, 3).transpose(1, 0, 2)
        return idx.astype(np.int64), np.ascontiguousarray(disp)

    def transform(self, t: Tree) -> list[TransformTable]:
        node_tok = t.children[0]
        out = []
        for line in t.children[1:]:
            field_tok = line.children[0]
            neutral = self.numbers(
                [c for c in line.children[1:] if isinstance(c, Token) and c.type == "NUMBER"]
            )
            units = [c for c in line.children[1:] if isinstance(c, Tree)]
            if units:
                unit = self.numbers(units[0].children)
            elif str(field_tok) == "rotation":
                unit = np.array([AU])
            else:
                raise self.error(
                    f"Transform {node_tok}: a {field_tok} table needs a 'per unit:' line", field_tok
                )
            try:
                out.append(TransformTable(str(node_tok), str(field_tok), neutral, unit))
            except AdtError as e:
                raise self.error(e.message, field_tok) from None
        return out

    def timing(self, t: Tree, temporal: TemporalTables) -> None:
        words = [str(c) for c in t.children if isinstance(c, Token)]
        settings: dict[str, str | float] = {}
        for s in t.children:
            if isinstance(s, Tree):
                key, value = s.children
                if str(key) in settings:
                    raise self.error(f"setting '{key}' is given twice", key)
                settings[str(key)] = self.number(value) if value.type == "NUMBER" else str(value)
        try:
            temporal.set_entry(words, settings)
        except AdtError as e:
            raise self.error(e.message, t.children[0]) from None


def format_adt(tables: AnimationTables) -> str:
    """The ``.adt`` text of ``tables`` (exact: ``parse_adt(format_adt(t)) == t``)."""
    out = ["#AnimationDefinitionTables"]
    for adt in tables.adts.values():
        out += ["", f"MIAP {adt.miap}"]
        for m in adt.meshes:
            out.append(f"IndexedFaceSet: {m.node}")
            out.append("interval borders: " + " ".join(format_number(b) for b in m.borders))
            out.append("displacements:")
            if m.vertices.size:
                rows = np.concatenate(
                    [
                        m.vertices[:, None].astype(np.float64),
                        m.displacements.transpose(1, 0, 2).reshape(m.vertices.size, -1),
                    ],
                    axis=1,
                )
                out += ["vertex " + r for r in format_numbers(rows)]
        for tt in adt.transforms:
            out.append(f"Transform: {tt.node}")
            nv = " ".join(format_number(v) for v in tt.neutral)
            if tt.field == "rotation":
                axis = " ".join(format_number(v) for v in tt.neutral[:3])
                nv = f"{axis} (axis) {format_number(tt.neutral[3])} (angle)"
            out.append(f"{tt.field} neutral value: {nv}")
            if not (tt.field == "rotation" and tt.unit[0] == AU):
                out.append("per unit: " + " ".join(format_number(v) for v in tt.unit))
    if tables.temporal:
        out += ["", "#TemporalDefinitionTables", *tables.temporal.lines()]
    if tables.feature_points:
        out += ["", "#FeaturePoints"]
        out += [f"{p} {node} {v}" for p, (node, v) in tables.feature_points.items()]
    return "\n".join(out) + "\n"


def write_adt(tables: AnimationTables, path: str | os.PathLike[str]) -> None:
    """Write ``tables`` as a ``.adt`` file (atomically)."""
    write_text(path, format_adt(tables))


# ---- checking against the scene ------------------------------------------------------------------


def check_tables(tables: AnimationTables, scene, *, file: str | None = None) -> None:
    """Check that the tables fit the neutral scene: every DEF name exists and is of the right node
    type, vertex indices are within the IndexedFaceSet's points, Transform neutral values match
    the scene's. Raises :class:`AdtError` naming the MIAP, node and rule."""
    for adt in tables.adts.values():
        for m in adt.meshes:
            n = mesh_point_count(scene, m.node, what=f"MIAP {adt.miap}", file=file)
            if m.vertices.size and m.vertices.max() >= n:
                raise AdtError(
                    f"MIAP {adt.miap}: vertex {int(m.vertices.max())} is out of range for "
                    f"IndexedFaceSet {m.node}, which has {n} points",
                    file=file,
                )
        for t in adt.transforms:
            node = transform_node(scene, t.node, what=f"MIAP {adt.miap}", file=file)
            current = np.asarray(node[t.field], dtype=np.float64)
            if not _same_value(t.field, current, t.neutral):
                raise AdtError(
                    f"MIAP {adt.miap}: the {t.field} neutral value of Transform {t.node} is "
                    f"{' '.join(format_number(v) for v in t.neutral)} in the tables but "
                    f"{' '.join(format_number(v) for v in current)} in the scene",
                    file=file,
                )
    for point, (name, vertex) in tables.feature_points.items():
        n = mesh_point_count(scene, name, what=f"feature point {point}", file=file)
        if not 0 <= vertex < n:
            raise AdtError(
                f"feature point {point}: vertex {vertex} is out of range for IndexedFaceSet "
                f"{name}, which has {n} points",
                file=file,
            )


def _same_value(field_name: str, a: np.ndarray, b: np.ndarray) -> bool:
    if field_name != "rotation":
        return bool(np.allclose(a, b, atol=1e-6))
    if abs(a[3]) < 1e-9 and abs(b[3]) < 1e-9:
        return True  # any axis with angle 0 is the identity
    na, nb = a[:3] / np.linalg.norm(a[:3]), b[:3] / np.linalg.norm(b[:3])
    return bool(np.allclose(na, nb, atol=1e-6) and abs(a[3] - b[3]) < 1e-6) or bool(
        np.allclose(na, -nb, atol=1e-6) and abs(a[3] + b[3]) < 1e-6
    )


def _def_node(scene, name: str, what: str, file: str | None):
    try:
        return scene.node(name).expand()
    except KeyError:
        raise AdtError(f"{what}: no node is DEFed as '{name}' in the scene", file=file) from None


def mesh_point_count(scene, name: str, *, what: str = "table", file: str | None = None) -> int:
    """Number of Coordinate points of the IndexedFaceSet DEFed as ``name``."""
    node = _def_node(scene, name, what, file)
    if node.type.name != "IndexedFaceSet":
        raise AdtError(f"{what}: '{name}' is a {node.type.name}, not an IndexedFaceSet", file=file)
    coord = node["coord"]
    return 0 if coord is None else len(coord.expand()["point"])


def transform_node(scene, name: str, *, what: str = "table", file: str | None = None):
    node = _def_node(scene, name, what, file)
    if node.type.name != "Transform":
        raise AdtError(f"{what}: '{name}' is a {node.type.name}, not a Transform", file=file)
    return node


# ---- MPEG-4 FaceDefTables nodes ------------------------------------------------------------------

#: WorldInfo titles that carry the sections MPEG-4 has no nodes for.
TEMPORAL_TITLE = "vtts:TemporalDefinitionTables"
FEATURES_TITLE = "vtts:FeaturePoints"


def tables_from_scene(scene, *, file: str | None = None) -> AnimationTables | None:
    """The tables embedded in a scene as FaceDefTables nodes (and vtts WorldInfo nodes for the
    temporal tables and feature points), or None when the scene has none."""
    from vtts.vrml import Node

    defs = scene.find("FaceDefTables")
    infos = [w for w in scene.find("WorldInfo") if w["title"] in (TEMPORAL_TITLE, FEATURES_TITLE)]
    if not defs and not infos:
        return None
    tables = AnimationTables()
    names = {id(n): k for k, n in _all_defs(scene).items()}

    def target(n: Node | None, where: Node, kind: str) -> str:
        if n is None:
            raise AdtError(
                f"{kind} at line {where.line} has no faceSceneGraphNode", file=file, line=where.line
            )
        name = names.get(id(n)) or names.get(id(n.expand()))
        if name is None:
            raise AdtError(
                f"{kind} at line {where.line}: its faceSceneGraphNode must be a DEFed node "
                "(USE NAME)",
                file=file,
                line=where.line,
            )
        return name

    for fdt in defs:
        fap_id, select = fdt["fapID"], fdt["highLevelSelect"]
        try:
            if fap_id == 1:
                miap = Miap("viseme", select)
            elif fap_id == 2:
                miap = Miap("expression", select)
            else:
                miap = Miap("fap", fap_id)
        except FapError as e:
            raise AdtError(f"FaceDefTables: {e.message}", file=file, line=fdt.line) from None
        adt = Adt(miap)
        for mesh in fdt["faceDefMesh"]:
            mesh = mesh.expand()
            borders = np.asarray(mesh["intervalBorders"], dtype=np.float64)
            ci = np.asarray(mesh["coordIndex"], dtype=np.int64)
            disp = np.asarray(mesh["displacements"], dtype=np.float64)
            n = borders.size - 1
            if disp.shape[0] != ci.size * max(n, 0):
                raise AdtError(
                    f"FaceDefMesh at line {mesh.line}: {ci.size} vertices × {n} intervals need "
                    f"{ci.size * n} displacements, got {disp.shape[0]}",
                    file=file,
                    line=mesh.line,
                )
            try:
                adt.meshes.append(
                    MeshTable(
                        target(mesh["faceSceneGraphNode"], mesh, "FaceDefMesh"),
                        borders,
                        ci,
                        disp.reshape(ci.size, n, 3).transpose(1, 0, 2),
                    )
                )
            except VttsError as e:
                raise AdtError(f"FaceDefMesh: {e.message}", file=file, line=mesh.line) from None
        for tr in fdt["faceDefTransform"]:
            tr = tr.expand()
            name = target(tr["faceSceneGraphNode"], tr, "FaceDefTransform")
            field_name = {v: k for k, v in FIELD_IDS.items()}.get(tr["fieldId"])
            if field_name is None:
                raise AdtError(
                    f"FaceDefTransform at line {tr.line}: fieldId must be 1 (rotation), 2 (scale) "
                    f"or 3 (translation), got {tr['fieldId']}",
                    file=file,
                    line=tr.line,
                )
            node = scene.node(name).expand()
            neutral = np.asarray(node[field_name], dtype=np.float64)
            if field_name == "rotation":
                rdef = tr["rotationDef"]
                unit = np.array([rdef[3]])
                if abs(neutral[3]) < 1e-12:
                    neutral = np.r_[rdef[:3], 0.0]
                elif float(np.dot(rdef[:3], neutral[:3])) < 0:
                    # rotationDef about the opposite axis turns the other way round the scene's
                    unit = -unit
            else:
                unit = tr["scaleDef" if field_name == "scale" else "translationDef"]
            adt.transforms.append(TransformTable(name, field_name, neutral, unit))
        if miap in tables.adts:
            raise AdtError(f"MIAP {miap} is defined twice", file=file, line=fdt.line)
        tables.adts[miap] = adt
    for info in infos:
        header = "#" + info["title"].split(":", 1)[1]
        text = header + "\n" + "\n".join(info["info"]) + "\n"
        try:
            part = parse_adt(text, file=file or "<scene>")
        except AdtError as e:
            raise AdtError(
                f"WorldInfo '{info['title']}' at line {info.line}: {e.message}",
                file=file,
                line=info.line,
            ) from None
        tables.temporal.expressions.update(part.temporal.expressions)
        tables.temporal.habits.update(part.temporal.habits)
        tables.feature_points.update(part.feature_points)
    return tables


def _all_defs(scene) -> dict[str, Any]:
    """Every DEF name of the top-level namespace (including nodes DEFed inside fields)."""
    return dict(scene.defs)


def embed_tables(scene, tables: AnimationTables):
    """A copy of ``scene`` with ``tables`` added at its end as MPEG-4 FaceDefTables nodes (plus
    WorldInfo nodes for the temporal tables and feature points); existing ones are replaced."""
    from vtts.vrml import parse
    from vtts.vrml.writer import dumps

    check_tables(tables, scene)
    base = strip_tables(scene)
    lines = [dumps(base)]
    for adt in tables.adts.values():
        m = adt.miap
        fap_id, select = {
            "fap": (m.number, 1),
            "viseme": (1, m.number),
            "expression": (2, m.number),
        }[m.kind]
        lines.append(f"# MIAP {m}")
        lines.append(f"FaceDefTables {{ fapID {fap_id} highLevelSelect {select}")
        if adt.meshes:
            lines.append("  faceDefMesh [")
            for mt in adt.meshes:
                disp = mt.displacements.transpose(1, 0, 2).reshape(-1, 3)
                lines.append(f"    FaceDefMesh {{ faceSceneGraphNode USE {mt.node}")
                lines.append(
                    "      intervalBorders [ "
                    + " ".join(format_number(b) for b in mt.borders)
                    + " ]"
                )
                lines.append(
                    "      coordIndex [ " + " ".join(str(int(v)) for v in mt.vertices) + " ]"
                )
                lines.append("      displacements [ " + ", ".join(format_numbers(disp)) + " ]")
                lines.append("    }")
            lines.append("  ]")
        if adt.transforms:
            lines.append("  faceDefTransform [")
            for t in adt.transforms:
                fid = FIELD_IDS[t.field]
                if t.field == "rotation":
                    axis = " ".join(format_number(v) for v in t.neutral[:3])
                    spec = f"rotationDef {axis} {format_number(t.unit[0])}"
                else:
                    name = "scaleDef" if t.field == "scale" else "translationDef"
                    spec = f"{name} " + " ".join(format_number(v) for v in t.unit)
                lines.append(
                    f"    FaceDefTransform {{ faceSceneGraphNode USE {t.node} "
                    f"fieldId {fid} {spec} }}"
                )
            lines.append("  ]")
        lines.append("}")
    from vtts.vrml.fields import escape_string

    for title, body in (
        (TEMPORAL_TITLE, tables.temporal.lines()),
        (FEATURES_TITLE, [f"{p} {n} {v}" for p, (n, v) in tables.feature_points.items()]),
    ):
        if body:
            info = " ".join(escape_string(b) for b in body)
            lines.append(f'WorldInfo {{ title "{title}" info [ {info} ] }}')
    return parse("\n".join(lines) + "\n", file=str(scene.path) if scene.path else None)


def strip_tables(scene):
    """A copy of ``scene`` without FaceDefTables nodes and vtts table WorldInfo nodes (the plain
    neutral scene)."""
    import copy

    out = copy.copy(scene)
    out.statements = [s for s in scene.statements if not _is_table_node(s)]
    return out


def _is_table_node(s) -> bool:
    from vtts.vrml import Node

    if not isinstance(s, Node):
        return False
    t = s.type.name
    return t == "FaceDefTables" or (
        t == "WorldInfo" and s["title"] in (TEMPORAL_TITLE, FEATURES_TITLE)
    )
