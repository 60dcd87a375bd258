"""The layers of vtts (docs/design.md, "Layers"): which package may import which.

Every module of ``vtts/`` and ``adt_tools/`` is parsed, not imported: its imports at module level
and inside functions, relative ones resolved; imports under ``if TYPE_CHECKING:`` are types only
and do not count. Each module belongs to a *package*: ``vtts.X`` for a sub-package and for a
top-level module alike (``vtts.face.cache`` and ``vtts.mesh`` are in ``vtts.face`` and
``vtts.mesh``), ``vtts`` for the package's own ``__init__``, ``adt_tools`` for the ADI. Then

- a package imports only packages on a lower layer of :data:`LAYERS` (never one above it, nor
  another on its own layer);
- no packages, and no modules, import each other in a cycle;
- no module imports another module's private name (``from x import _y``) or a private module
  of another package.

A failure names the importing file and line and what it imports.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]

#: The packages, lowest layer first. A package may import the packages of the layers below its
#: own, and no other (docs/design.md, Layers, draws the same).
LAYERS: tuple[tuple[str, ...], ...] = (
    ("vtts.errors",),
    # what every layer may need: files written atomically, limits on input, warnings, the user's
    # cache folder, BLAS threads, deferred imports, the ffmpeg binary
    (
        "vtts.atomic",
        "vtts.limits",
        "vtts.messages",
        "vtts.usercache",
        "vtts.threads",
        "vtts.deferred",
        "vtts.media",
    ),
    ("vtts.resources",),  # bundled data and grammars, found through the user cache's checks
    ("vtts.vrml",),
    ("vtts.fap",),
    ("vtts.face",),
    ("vtts.mesh",),
    ("vtts.gltf",),
    ("vtts.speech",),
    ("vtts.align",),
    ("vtts.utterance",),  # speech (and forced alignment) with bookmarks and timings
    ("vtts.animate",),
    ("vtts.render",),
    ("vtts.fit",),
    ("vtts.analysis",),
    ("vtts.avatar",),
    ("vtts.export",),
    ("vtts.warm",),
    ("vtts.api",),
    ("vtts.cluster",),  # Ray started or joined, for batch and serve
    ("vtts.batch",),
    ("vtts.serve",),  # vtts serve: speech and faces streamed over WebSockets
    ("vtts",),  # the package's front door: __version__, load_model
    ("vtts.cli", "adt_tools"),
)

#: Module imports that close a cycle and stay, each with the reason. Keep it short.
ALLOWED_CYCLE_IMPORTS: dict[tuple[str, str], str] = {}

#: ``(importing module, private name)`` pairs allowed to cross modules. Keep it empty.
ALLOWED_PRIVATE: frozenset[tuple[str, str]] = frozenset()


@dataclass(frozen=True)
class Import:
    """One imported module (or one name from it) of one module."""

    module: str  # the importing module, dotted
    file: str  # its path, relative to the root
    line: int
    target: str  # the imported module, dotted (a package's __init__ is the package's name)
    name: str | None  # the name of ``from target import name``; None for ``import target``


def package_of(module: str) -> str:
    """The package a module belongs to: ``vtts.X`` for a sub-package or a top-level module,
    ``vtts`` for the package's ``__init__``, ``adt_tools`` for the ADI."""
    parts = module.split(".")
    if parts[0] != "vtts" or len(parts) == 1:
        return parts[0]
    return ".".join(parts[:2])


def _module_name(path: Path, root: Path) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _runtime_nodes(tree: ast.AST):
    """Every node of ``tree`` but those under ``if TYPE_CHECKING:`` (their ``else`` counts)."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        if isinstance(node, ast.If) and _type_checking(node):
            stack.extend(node.orelse)
        else:
            stack.extend(ast.iter_child_nodes(node))


def collect(root: Path = ROOT, tops: tuple[str, ...] = ("vtts", "adt_tools")) -> tuple:
    """``(modules, imports)``: every module under ``root/tops`` (dotted name → relative path)
    and their imports of one another, in file and line order."""
    files = sorted(f for top in tops for f in (root / top).rglob("*.py"))
    modules = {_module_name(f, root): f.relative_to(root).as_posix() for f in files}
    imports = []
    for f in files:
        name = _module_name(f, root)
        here = name.split(".") if f.name == "__init__.py" else name.split(".")[:-1]
        tree = ast.parse(f.read_text(encoding="utf-8"), filename=str(f))
        for node in _runtime_nodes(tree):
            found: list[tuple[str, str | None]] = []
            if isinstance(node, ast.Import):
                found = [(alias.name, None) for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here[: len(here) - node.level + 1]
                    source = ".".join(base + ([node.module] if node.module else []))
                else:
                    source = node.module or ""
                for alias in node.names:
                    sub = f"{source}.{alias.name}"
                    found.append((sub, None) if sub in modules else (source, alias.name))
            for target, imported in found:
                if target.split(".")[0] not in tops:
                    continue
                while target not in modules and "." in target:  # import a.b.c → the module a.b
                    target = target.rsplit(".", 1)[0]
                imports.append(Import(name, modules[name], node.lineno, target, imported))
    imports.sort(key=lambda i: (i.file, i.line))
    return modules, tuple(imports)


@cache
def _repository() -> tuple:
    """:func:`collect` of this repository, parsed once for all the tests."""
    return collect()


def layer_failures(imports, layers=LAYERS) -> list[str]:
    """One line per import of a package by a package that must not import it: one on a layer
    above or on its own, or one that has no layer."""
    level = {package: k for k, names in enumerate(layers) for package in names}
    out = []
    for i in imports:
        src, dst = package_of(i.module), package_of(i.target)
        if src == dst:
            continue
        where = f"{i.file}:{i.line}: {i.module} imports {i.target}"
        if src not in level or dst not in level:
            missing = src if src not in level else dst
            out.append(f"{where}: {missing} has no layer in LAYERS")
        elif level[dst] > level[src]:
            out.append(f"{where}: {src} may not import {dst}, a layer above it")
        elif level[dst] == level[src]:
            out.append(f"{where}: {src} may not import {dst}, on its own layer")
    return out


def _cycles(edges: dict[str, dict[str, Import]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out = []
    for start in sorted(edges):
        if start in index:
            continue
        work = [(start, iter(sorted(edges.get(start, ()))))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(edges.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    out.append(sorted(component))
    return out


def cycle_failures(imports, of=package_of, allowed=ALLOWED_CYCLE_IMPORTS) -> list[str]:
    """One message per cycle between the units ``of`` gives (packages; ``str`` for modules):
    the units that import each other, and the imports of a shortest loop among them (the
    first import of each pair of units)."""
    edges: dict[str, dict[str, Import]] = {}
    for i in imports:
        src, dst = of(i.module), of(i.target)
        if src != dst and (i.module, i.target) not in allowed:
            edges.setdefault(src, {}).setdefault(dst, i)
    out = []
    for component in _cycles(edges):
        loop = _shortest_loop(component[0], set(component), edges)
        arrows = [edges[a][b] for a, b in zip(loop, loop[1:] + loop[:1], strict=True)]
        out.append(
            f"cycle between {', '.join(component)}:\n    "
            + "\n    ".join(f"{i.file}:{i.line}: {i.module} imports {i.target}" for i in arrows)
        )
    return out


def _shortest_loop(start: str, members: set[str], edges: dict[str, dict[str, Import]]) -> list:
    """The units of a shortest cycle through ``start`` within ``members``, ``start`` first."""
    parent: dict[str, str] = {}
    queue = [start]
    for node in queue:
        for child in sorted(edges.get(node, {})):
            if child == start:
                loop = [node]
                while loop[-1] != start:
                    loop.append(parent[loop[-1]])
                return loop[::-1]
            if child in members and child not in parent:
                parent[child] = node
                queue.append(child)
    raise AssertionError(f"{start} is in no cycle")  # a component always has one


def private_failures(imports, allowed=ALLOWED_PRIVATE) -> list[str]:
    """One line per private name taken from another module (``from x import _y``) and per
    private module imported from outside its own package."""
    out = []
    for i in imports:
        where = f"{i.file}:{i.line}: {i.module} imports"
        name = i.name or ""
        if name.startswith("_") and not name.startswith("__") and i.target != i.module:
            if (i.module, name) not in allowed:
                out.append(f"{where} {name}, private to {i.target}")
        parts = i.target.split(".")
        for k, part in enumerate(parts):
            owner = ".".join(parts[:k])
            private = part.startswith("_") and not part.startswith("__")
            if private and not (i.module == owner or i.module.startswith(owner + ".")):
                out.append(f"{where} {i.target}, a module private to {owner}")
                break
    return out


def _report(failures: list[str]) -> str:
    head = f"{len(failures)} break(s) of the layers (docs/design.md, Layers):"
    return "\n".join([head, *failures])


def test_every_package_has_one_layer():
    modules, _ = _repository()
    declared = [p for names in LAYERS for p in names]
    assert len(declared) == len(set(declared)), "a package is on two layers"
    missing = sorted({package_of(m) for m in modules} - set(declared))
    assert not missing, f"packages without a layer in LAYERS: {missing}"


def test_packages_import_only_the_layers_below_them():
    _, imports = _repository()
    failures = layer_failures(imports)
    assert not failures, _report(failures)


def test_no_cycle_between_packages():
    _, imports = _repository()
    failures = cycle_failures(imports, allowed={})
    assert not failures, _report(failures)


def test_no_cycle_between_modules():
    _, imports = _repository()
    failures = cycle_failures(imports, of=str)
    assert not failures, _report(failures)


def test_no_private_name_crosses_modules():
    _, imports = _repository()
    failures = private_failures(imports)
    assert not failures, _report(failures)


def test_the_allow_lists_hold_only_imports_that_exist():
    _, imports = _repository()
    pairs = {(i.module, i.target) for i in imports}
    assert set(ALLOWED_CYCLE_IMPORTS) <= pairs
    assert ALLOWED_PRIVATE <= {(i.module, i.name) for i in imports}


# ---- the checks themselves fail where they should ------------------------------------------------

FAKE = {
    "vtts/__init__.py": "",
    "vtts/errors.py": "class VttsError(Exception): ...\n",
    "vtts/face/__init__.py": "from vtts.face.model import FaceModel\n",
    "vtts/face/model.py": (
        "from typing import TYPE_CHECKING\n"
        "from vtts.errors import VttsError\n"
        "if TYPE_CHECKING:\n"
        "    from vtts.render import Renderer\n"
        "class FaceModel: ...\n"
        "def _private(): ...\n"
    ),
    "vtts/face/cache.py": "def load():\n    from .model import FaceModel\n",
    "vtts/render/__init__.py": (
        "from vtts.face import FaceModel\nfrom vtts.face.model import _private\n"
    ),
    "vtts/speech/__init__.py": "from ..render import Renderer\nfrom vtts.face import _espeak\n",
    "vtts/face/_espeak.py": "",
}
FAKE_LAYERS = (("vtts.errors",), ("vtts.face",), ("vtts.speech", "vtts.render"), ("vtts",))


@pytest.fixture
def fake(tmp_path: Path):
    for name, text in FAKE.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    return tmp_path


def test_a_relative_import_beside_or_above_is_named_with_its_line(fake):
    _, imports = collect(fake, ("vtts",))
    assert layer_failures(imports, FAKE_LAYERS) == [
        "vtts/speech/__init__.py:1: vtts.speech imports vtts.render: "
        "vtts.speech may not import vtts.render, on its own layer"
    ]
    (fake / "vtts" / "face" / "cache.py").write_text("import vtts.speech\n")
    _, imports = collect(fake, ("vtts",))
    assert layer_failures(imports, FAKE_LAYERS)[0] == (
        "vtts/face/cache.py:1: vtts.face.cache imports vtts.speech: "
        "vtts.face may not import vtts.speech, a layer above it"
    )


def test_a_cycle_is_named_with_the_imports_that_close_it(fake):
    _, imports = collect(fake, ("vtts",))
    assert cycle_failures(imports, allowed={}) == []  # TYPE_CHECKING imports do not count
    (fake / "vtts" / "face" / "cache.py").write_text("def f():\n    from vtts import render\n")
    _, imports = collect(fake, ("vtts",))
    assert cycle_failures(imports, allowed={}) == [
        "cycle between vtts.face, vtts.render:\n"
        "    vtts/face/cache.py:2: vtts.face.cache imports vtts.render\n"
        "    vtts/render/__init__.py:1: vtts.render imports vtts.face"
    ]
    assert cycle_failures(imports, of=str, allowed={}) == []  # no cycle of modules


def test_a_cycle_of_modules_within_a_package_is_named(fake):
    with (fake / "vtts" / "face" / "model.py").open("a") as f:
        f.write("from . import cache\n")
    _, imports = collect(fake, ("vtts",))
    assert cycle_failures(imports, allowed={}) == []
    assert cycle_failures(imports, of=str, allowed={}) == [
        "cycle between vtts.face.cache, vtts.face.model:\n"
        "    vtts/face/cache.py:2: vtts.face.cache imports vtts.face.model\n"
        "    vtts/face/model.py:7: vtts.face.model imports vtts.face.cache"
    ]


def test_a_private_name_or_module_from_elsewhere_is_named(fake):
    _, imports = collect(fake, ("vtts",))
    assert private_failures(imports) == [
        "vtts/render/__init__.py:2: vtts.render imports _private, private to vtts.face.model",
        "vtts/speech/__init__.py:2: vtts.speech imports vtts.face._espeak, "
        "a module private to vtts.face",
    ]
