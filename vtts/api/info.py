"""``vtts info``: what a scene or model holds (its scene graph, and what the model can do), or
what a ``.fbs`` bitstream holds (:func:`info`)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class Info:
    """What :func:`info` found.

    ``path``: the file described (a bundled name's ``.wrl``); ``title``: its one-line summary
    (``"7 nodes, 184 triangles"``; None for a bitstream); ``lines``: the scene graph as
    indented lines, or the bitstream's description; ``model_name`` and ``model_lines``: what the
    model can do (none without animation tables).
    """

    path: Path
    title: str | None
    lines: list[str]
    model_name: str | None = None
    model_lines: list[str] = field(default_factory=list)


def describe_node(node, seen: set[int], depth: int, out: list[str]) -> None:
    """Append ``node`` and its children to ``out`` as indented lines (a node already ``seen``
    is a ``USE``)."""
    from vtts.vrml.geometry import polygon_triangle_count

    pad = "  " * depth
    label = f"DEF {node.name} " if node.name else ""
    if id(node) in seen:
        out.append(f"{pad}USE {node.name or '?'} ({node.type.name})")
        return
    seen.add(id(node))
    detail = ""
    shown = node.expand()
    kind = node.type.describe() if node.type.kind in ("proto", "externproto") else node.type.name
    if shown.type.name == "IndexedFaceSet":
        coord = shown["coord"]
        n_pts = 0 if coord is None else len(coord.expand()["point"])
        ci = shown["coordIndex"]
        n_faces = int((ci == -1).sum() + (1 if len(ci) and ci[-1] != -1 else 0))
        detail = f": {n_pts} vertices, {n_faces} faces, {polygon_triangle_count(ci)} triangles"
    elif shown.type.name == "Transform":
        bits = []
        for f in ("translation", "rotation", "scale", "center"):
            if f in shown.fields:
                bits.append(f"{f} " + " ".join(f"{v:g}" for v in shown.fields[f]))
        detail = (": " + ", ".join(bits)) if bits else ""
    elif shown.type.name in ("ImageTexture",) and shown["url"]:
        detail = f": {shown['url'][0]}"
    out.append(f"{pad}{label}{kind}{detail}")
    for fname, value in node.fields.items():
        children = value if isinstance(value, list) else [value]
        nodes = [c for c in children if hasattr(c, "type")]
        if not nodes:
            continue
        if fname != "children":
            out.append(f"{pad}  .{fname}")
            for c in nodes:
                describe_node(c, seen, depth + 2, out)
        else:
            for c in nodes:
                describe_node(c, seen, depth + 1, out)


def scene_tree(scene) -> list[str]:
    """The scene graph as indented lines (node type, DEF name, vertex and face counts)."""
    from vtts.vrml.scene import Node, Proto

    out: list[str] = []
    seen: set[int] = set()
    for s in scene.statements:
        if isinstance(s, Node):
            describe_node(s, seen, 0, out)
        elif isinstance(s, Proto):
            word = "PROTO" if s.kind == "proto" else "EXTERNPROTO"
            out.append(f"{word} {s.name} [{len(s.decls)} members]")
    return out


def info(file: str | os.PathLike[str], *, lenient: bool = False) -> Info:
    """Describe ``file``: a ``.wrl`` path or bundled model name (``lenient``: load VRML other
    browsers accept, each liberty a warning), or a ``.fbs`` bitstream (checked and decoded
    whole). Raises a :class:`~vtts.errors.VttsError` for what cannot be read."""
    from vtts.api.check import plural

    name = os.fspath(file)
    if Path(name).suffix.lower() == ".fbs":
        from vtts.api.coding import describe_fbs

        return Info(Path(name), None, describe_fbs(name))
    from vtts.face import find_model, load_model

    path = find_model(name)
    model = load_model(path, lenient=lenient)
    scene = model.scene
    title = f"{plural(scene.node_count, 'node')}, {plural(scene.triangle_count(), 'triangle')}"
    described = Info(path, title, scene_tree(scene))
    if model.tables:
        return Info(path, title, described.lines, model.name, model.describe())
    return described
