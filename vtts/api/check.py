"""``vtts check``: whether a ``.wrl``, ``.adt``, ``.fap`` or ``.fbs`` file is valid, and a one-line
summary of it (:func:`check_file`, :func:`check`)."""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from vtts.errors import VttsError


def plural(n: int, noun: str) -> str:
    """``3 nodes``, ``1 node``."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def check_wrl(path: Path, lenient: bool = False) -> str:
    """A scene or model: it loads, and what render would refuse (an out-of-range coordIndex)
    is refused too, checked without triangulating; its missing textures are warnings."""
    from vtts.face import load_model
    from vtts.vrml import check_face_set

    model = load_model(path, lenient=lenient)
    scene = model.scene
    for shape, _, _ in scene.shapes():
        geom = shape["geometry"]
        if geom is not None and geom.expand().type.name == "IndexedFaceSet":
            try:
                check_face_set(geom)
            except VttsError as e:
                e.file = e.file or str(path)
                raise
    for node, urls in model.missing_textures():
        warnings.warn(model.texture_warning(node, urls), stacklevel=1)
    text = f"{plural(scene.node_count, 'node')}, {plural(scene.triangle_count(), 'triangle')}"
    if model.tables.adts:
        text += f", {plural(len(model.tables.adts), 'MIAP')}"
    return text


def check_adt(path: Path, lenient: bool = False) -> str:
    """Animation tables, checked against the ``.wrl`` beside them."""
    from vtts.errors import AdtError
    from vtts.face import check_tables, read_adt
    from vtts.vrml import read

    tables = read_adt(path)
    wrl = path.with_suffix(".wrl")
    if not wrl.is_file():
        raise AdtError(
            f"no {wrl.name} beside it: an .adt is checked against the scene it animates",
            file=str(path),
        )
    if not tables:
        raise AdtError("no tables in it (an .adt holds MIAP, temporal or feature-point tables)",
                       file=str(path))  # fmt: skip
    check_tables(tables, read(wrl, lenient=lenient), file=str(path))
    nodes = len(tables.mesh_nodes()) + len(tables.transform_nodes())
    return f"{plural(len(tables.adts), 'MIAP')} on {plural(nodes, 'node')} of {wrl.name}"


def check_fap(path: Path, lenient: bool = False) -> str:
    """A FAP file: it reads completely."""
    from vtts.fap import read_fap

    stream = read_fap(path)
    masked = int(stream.mask.any(axis=0).sum())
    return f"{stream.n_frames} frames at {stream.fps:g} fps, {masked} FAPs"


def check_fbs_file(path: Path, lenient: bool = False) -> str:
    """A FAP bitstream: it decodes completely (:func:`vtts.api.coding.check_fbs`)."""
    from vtts.api.coding import check_fbs

    return check_fbs(path)


#: File suffix → checker ``(path, lenient)`` returning the summary printed after ``OK FILE``.
CHECKERS: dict[str, Callable[[Path, bool], str]] = {
    ".wrl": check_wrl,
    ".adt": check_adt,
    ".fap": check_fap,
    ".fbs": check_fbs_file,
}


class CheckError(VttsError):
    """A file ``vtts check`` cannot check: an unknown type, or no such file."""


def check_file(path: str | os.PathLike[str], *, lenient: bool = False) -> str:
    """Check one file by its suffix (:data:`CHECKERS`); its summary, such as ``"7 nodes, 184
    triangles"``. ``lenient``: load VRML that other browsers accept, each liberty a warning.
    Raises a :class:`~vtts.errors.VttsError` locating what is wrong."""
    name = os.fspath(path)
    path = Path(name)
    checker = CHECKERS.get(path.suffix.lower())
    if checker is None:
        known = ", ".join(sorted(CHECKERS))
        raise CheckError(f"unknown file type '{path.suffix}' (vtts checks {known})", file=name)
    if not path.is_file():
        raise CheckError("no such file", file=name)
    return checker(path, lenient)


@dataclass(frozen=True)
class Checked:
    """One file's check: ``summary`` when valid, else the ``error``."""

    file: str
    summary: str | None = None
    error: VttsError | None = None

    @property
    def ok(self) -> bool:
        return self.error is None


def check(files: Iterable[str | os.PathLike[str]], *, lenient: bool = False) -> list[Checked]:
    """Check each of ``files`` (:func:`check_file`), one :class:`Checked` each; a bad file does
    not stop the others."""
    out = []
    for f in files:
        try:
            out.append(Checked(os.fspath(f), check_file(f, lenient=lenient)))
        except VttsError as e:
            out.append(Checked(os.fspath(f), error=e))
    return out
