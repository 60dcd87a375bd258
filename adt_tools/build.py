"""Building Animation Definition Tables from deformed exports of a neutral model (the ADI).

Ostermann & Haratsch, section 3.3 ("Rapid Synthesis of ADTs"): the modeler deforms the neutral
head for one MIAP, exports it in one or more phases of the animation, and the ADI compares the
vertex positions of each export with the neutral model to make the table.

Each deformed export is a :class:`DeformedPose`: which MIAP it shows, at which amplitude, and the
posed Coordinate points of the IndexedFaceSets (and changed Transform fields) it carries.
:func:`load_poses` reads them from VRML97 (``.wrl``), OBJ, PLY and glTF (``.glb``/``.gltf``)
files, including glTF morph targets named after MIAPs; :func:`build_tables` turns a list of
poses into :class:`~vtts.face.AnimationTables`.

Interval construction: for one MIAP with poses at amplitudes a_1 < … < a_k, the interval borders
are the amplitudes plus 0, and each interval's displacement per unit is
``(d(b[i+1]) - d(b[i])) / (b[i+1] - b[i])`` with ``d(0) = 0``, so that the MPEG-4 integration of
the piecewise-constant slope (:func:`vtts.face.interval_weights`) reproduces every exported pose
exactly and extends the outer intervals beyond the borders.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from vtts.errors import AdtError, FapError, VttsError, VttsWarning
from vtts.face import Adt, AnimationTables, MeshTable, Miap, TransformTable
from vtts.face.adt import strip_tables, tables_from_scene
from vtts.fap import AU
from vtts.vrml import Node, Scene, read
from vtts.vrml.fields import format_number

if TYPE_CHECKING:
    from vtts.gltf import GltfReader

TRANSFORM_FIELDS = ("rotation", "translation", "scale")

#: Default tolerance (model units; radians for rotations): smaller motion counts as none.
DEFAULT_TOLERANCE = 1e-6


@dataclass
class DeformedPose:
    """One deformed export of the neutral model: the model showing ``miap`` at ``amplitude``.

    miap          the MIAP the pose shows
    amplitude     its value in the MIAP's units (FAPU or AU for FAPs, weight for visemes and
                  expressions); never 0, which is the neutral model
    source        where it came from: the file, or ``file#target`` for a glTF morph target
    points        IndexedFaceSet DEF name → ``(p, 3) float64`` posed Coordinate points, for
                  the IndexedFaceSets the source carries (all DEFed ones for a ``.wrl``, one
                  per mesh for mesh files)
    transforms    Transform DEF name → {field → value}: the rotation ``(4,)`` axis + angle (rad),
                  translation ``(3,)`` or scale ``(3,)`` fields that differ from the neutral scene
    has_transforms  whether the source describes Transforms at all (a ``.wrl`` does, mesh files
                  do not: a Transform missing from ``transforms`` is then unchanged)
    """

    miap: Miap
    amplitude: float
    source: str
    points: dict[str, np.ndarray] = field(default_factory=dict)
    transforms: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    has_transforms: bool = True


# ---- naming the MIAP and amplitude ---------------------------------------------------------------

_INFO_WORD = re.compile(r"\s*miap(\s|$)", re.IGNORECASE)


def parse_miap_name(
    name: str,
    amplitude: str | None,
    *,
    what: str,
    file: str,
    line: int | None = None,
) -> tuple[Miap, float]:
    """The MIAP and amplitude named by ``name`` (``close_t_l_eyelid``, ``19``, ``viseme3``,
    ``joy``) and ``amplitude`` (text, or None when not given: 1 for visemes and expressions, an
    error for FAPs). ``what`` says where the name was found, for error messages."""
    try:
        miap = Miap.parse(name)
    except (FapError, ValueError) as e:
        reason = getattr(e, "message", str(e))
        raise AdtError(f"unknown MIAP '{name}' in {what}: {reason}", file=file, line=line) from None
    if amplitude is None:
        if miap.kind == "fap":
            raise AdtError(
                f"{what} names FAP MIAP {miap} without an amplitude: a FAP pose needs one "
                f"(write {miap.name}@AMPLITUDE, in FAP units)",
                file=file,
                line=line,
            )
        return miap, 1.0
    try:
        value = float(amplitude)
    except ValueError:
        raise AdtError(
            f"amplitude '{amplitude}' in {what} is not a number", file=file, line=line
        ) from None
    if not math.isfinite(value):
        raise AdtError(f"amplitude '{amplitude}' in {what} is not finite", file=file, line=line)
    if value == 0:
        raise AdtError(
            f"amplitude 0 in {what}: MIAP {miap} at 0 is the neutral model, not a deformed pose",
            file=file,
            line=line,
        )
    return miap, value


def miap_from_label(label: str, *, what: str, file: str) -> tuple[Miap, float]:
    """MIAP and amplitude from ``NAME@AMPLITUDE`` or ``NAME`` (a file stem, a morph target)."""
    name, sep, amp = label.rpartition("@")
    if not sep:
        return parse_miap_name(label, None, what=what, file=file)
    return parse_miap_name(name, amp, what=what, file=file)


def miap_from_info(text: str, *, file: str, line: int | None) -> tuple[Miap, float]:
    """MIAP and amplitude from a WorldInfo info string ``miap NAME_OR_NUMBER [AMPLITUDE]``."""
    words = text.split()[1:]
    what = f"WorldInfo string {text.strip()!r}"
    if not words:
        raise AdtError(
            f"{what} names no MIAP: write 'miap NAME AMPLITUDE' (e.g. 'miap 19 1024')",
            file=file,
            line=line,
        )
    if len(words) >= 2 and _is_number(words[-1]):
        name = " ".join(words[:-1])
        try:
            Miap.parse(name)
        except (FapError, ValueError):
            try:  # 'miap viseme 3': the number belongs to the name, the amplitude is 1
                whole = Miap.parse(" ".join(words))
            except (FapError, ValueError):
                whole = None
            if whole is not None and whole.kind != "fap":
                return whole, 1.0
        return parse_miap_name(name, words[-1], what=what, file=file, line=line)
    return parse_miap_name(" ".join(words), None, what=what, file=file, line=line)


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def _miap_of_scene(scene: Scene, file: str) -> tuple[Miap, float] | None:
    """The ``miap …`` WorldInfo string of a deformed scene, parsed; None when it has none."""
    found: list[tuple[str, int]] = []
    for info in scene.find("WorldInfo"):
        for s in info["info"]:
            if _INFO_WORD.match(s):
                found.append((s, info.line))
    if not found:
        return None
    if len(found) > 1:
        raise AdtError(
            f"{len(found)} WorldInfo 'miap' strings ({', '.join(repr(s) for s, _ in found)}): "
            "a deformed file shows one MIAP",
            file=file,
            line=found[1][1],
        )
    text, line = found[0]
    return miap_from_info(text, file=file, line=line)


def _miap_of_file(path: Path) -> tuple[Miap, float]:
    """MIAP and amplitude from a file name ``NAME@AMPLITUDE.ext`` (or ``NAME.ext`` for a viseme
    or expression at weight 1)."""
    stem = path.name[: -len(path.suffix)] if path.suffix else path.name
    if "@" not in stem:
        try:
            Miap.parse(stem)
        except (FapError, ValueError):
            raise AdtError(
                f'no MIAP given: {path.name} has no WorldInfo "miap NAME AMPLITUDE" string and '
                f"its name is not NAME@AMPLITUDE{path.suffix} (e.g. close_t_l_eyelid@1024"
                f"{path.suffix}, viseme3@1{path.suffix})",
                file=str(path),
            ) from None
    return miap_from_label(stem, what=f"file name {path.name}", file=str(path))


# ---- the neutral scene ---------------------------------------------------------------------------


def mesh_nodes(scene: Scene) -> dict[str, Node]:
    """DEF name → IndexedFaceSet node for every DEFed IndexedFaceSet, in file order."""
    return {n.name: n for n in scene.find("IndexedFaceSet") if n.name}


def transform_nodes(scene: Scene) -> dict[str, Node]:
    """DEF name → Transform node for every DEFed Transform, in file order."""
    return {n.name: n for n in scene.find("Transform") if n.name}


def node_points(node: Node) -> np.ndarray:
    """``(p, 3) float64`` Coordinate points of an IndexedFaceSet (``(0, 3)`` without coord)."""
    coord = node["coord"]
    if coord is None:
        return np.zeros((0, 3))
    return np.asarray(coord.expand()["point"], dtype=np.float64).reshape(-1, 3)


def _scene_name(scene: Scene) -> str:
    return str(scene.path) if scene.path else "the neutral scene"


def _transform_values(node: Node) -> dict[str, np.ndarray]:
    return {f: np.asarray(node[f], dtype=np.float64) for f in TRANSFORM_FIELDS}


# ---- loaders -------------------------------------------------------------------------------------


def load_poses(
    path: str | os.PathLike[str], neutral: Scene, *, node: str | None = None
) -> list[DeformedPose]:
    """The deformed poses in one file: one for a ``.wrl``, ``.obj``, ``.ply`` or a glTF without
    morph targets, one per morph target for a glTF with morph targets.

    ``neutral`` is the neutral scene the poses are compared with; ``node`` names the
    IndexedFaceSet a single-mesh file (OBJ, PLY) maps onto (default: the only IndexedFaceSet of
    the neutral scene with the same number of points). Raises :class:`AdtError` (or a VRML parse
    error) naming the file.
    """
    p = Path(path)
    loader = LOADERS.get(p.suffix.lower())
    if loader is None:
        known = ", ".join(sorted(LOADERS))
        raise AdtError(
            f"unknown file type '{p.suffix}' for a deformed pose (the ADI reads {known})",
            file=str(p),
        )
    if not p.is_file():
        raise AdtError("no such file", file=str(p))
    return loader(p, neutral, node)


def load_pose(
    path: str | os.PathLike[str], neutral: Scene, *, node: str | None = None
) -> DeformedPose:
    """The one deformed pose in ``path`` (see :func:`load_poses`; a file with several morph
    targets is an error here)."""
    poses = load_poses(path, neutral, node=node)
    if len(poses) != 1:
        raise AdtError(
            f"the file holds {len(poses)} poses (morph targets); use load_poses", file=str(path)
        )
    return poses[0]


def _load_wrl(path: Path, neutral: Scene, node: str | None) -> list[DeformedPose]:
    file = str(path)
    scene = read(path)
    named = _miap_of_scene(scene, file)
    miap, amplitude = named if named is not None else _miap_of_file(path)
    pose = DeformedPose(miap, amplitude, file)
    deformed_meshes = mesh_nodes(scene)
    for name, n0 in mesh_nodes(neutral).items():
        n1 = deformed_meshes.get(name)
        if n1 is None:
            raise AdtError(
                f"topology differs: {_scene_name(neutral)} has an IndexedFaceSet DEFed as {name} "
                f"but {path.name} has none",
                file=file,
            )
        p0, p1 = node_points(n0), node_points(n1)
        if p0.shape != p1.shape:
            raise AdtError(
                f"topology differs: {name} has {len(p0)} points in {_scene_name(neutral)} but "
                f"{len(p1)} in {path.name}",
                file=file,
                line=n1.line,
            )
        if not np.array_equal(np.asarray(n0["coordIndex"]), np.asarray(n1["coordIndex"])):
            raise AdtError(
                f"topology differs: the faces (coordIndex) of {name} in {path.name} differ from "
                f"those in {_scene_name(neutral)} (were vertices reordered?)",
                file=file,
                line=n1.line,
            )
        pose.points[name] = p1
    deformed_transforms = transform_nodes(scene)
    for name, t0 in transform_nodes(neutral).items():
        t1 = deformed_transforms.get(name)
        if t1 is None:
            raise AdtError(
                f"topology differs: {_scene_name(neutral)} has a Transform DEFed as {name} but "
                f"{path.name} has none",
                file=file,
            )
        v0, v1 = _transform_values(t0), _transform_values(t1)
        changed = {f: v1[f] for f in TRANSFORM_FIELDS if not np.array_equal(v0[f], v1[f])}
        if changed:
            pose.transforms[name] = changed
    return [pose]


def _read_obj_vertices(path: Path) -> np.ndarray:
    """``(v, 3)`` the ``v`` lines of an OBJ file in file order.

    Read directly rather than through trimesh: trimesh drops unreferenced vertices and splits
    vertices at texture seams, and either breaks the vertex order the tables index into."""
    rows: list[list[float]] = []
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise AdtError(f"cannot read file: {e.strerror}", file=str(path)) from None
    for lineno, line in enumerate(text.splitlines(), 1):
        if line.startswith("v ") or line.startswith("v\t"):
            parts = line.split()[1:4]
            try:
                if len(parts) != 3:
                    raise ValueError
                rows.append([float(x) for x in parts])
            except ValueError:
                raise AdtError(
                    "a 'v' line needs three numbers", file=str(path), line=lineno
                ) from None
    return np.array(rows, dtype=np.float64).reshape(-1, 3)


def _read_trimesh_vertices(path: Path) -> np.ndarray:
    """``(v, 3)`` vertices of a PLY (or other trimesh format) in file order."""
    import trimesh

    try:
        # process=False keeps the vertices as written; fix_texture=False keeps PLY vertices
        # from being split at texture seams.
        loaded = trimesh.load(path, process=False, fix_texture=False)
    except Exception as e:  # trimesh raises many types for malformed files
        raise AdtError(f"cannot read the mesh: {e}", file=str(path)) from None
    if isinstance(loaded, trimesh.Scene):
        geoms = list(loaded.geometry.values())
        if len(geoms) != 1:
            raise AdtError(
                f"the file holds {len(geoms)} meshes; a deformed pose in {path.suffix} must "
                "hold one",
                file=str(path),
            )
        loaded = geoms[0]
    vertices = getattr(loaded, "vertices", None)
    if vertices is None:
        raise AdtError("the file holds no vertices", file=str(path))
    return np.asarray(vertices, dtype=np.float64).reshape(-1, 3)


def _target_mesh(
    neutral: Scene,
    count: int,
    *,
    file: str,
    node: str | None,
    mesh_name: str | None = None,
    what: str = "the mesh",
) -> str:
    """The DEF name of the neutral IndexedFaceSet a mesh of ``count`` vertices maps onto: the
    one named like the mesh, else ``node``, else the only one with ``count`` points."""
    meshes = mesh_nodes(neutral)
    name = mesh_name if mesh_name in meshes else node
    if name is not None:
        if name not in meshes:
            raise AdtError(
                f"--node {name}: {_scene_name(neutral)} has no IndexedFaceSet DEFed as {name} "
                f"(it has {', '.join(meshes) or 'none'})",
                file=file,
            )
        n = len(node_points(meshes[name]))
        if n != count:
            raise AdtError(
                f"topology differs: {name} has {n} points in {_scene_name(neutral)} but "
                f"{what} in {Path(file).name} has {count} vertices",
                file=file,
            )
        return name
    same = [k for k, v in meshes.items() if len(node_points(v)) == count]
    if len(same) == 1:
        return same[0]
    sizes = ", ".join(f"{k} ({len(node_points(v))})" for k, v in meshes.items()) or "none"
    if not same:
        raise AdtError(
            f"topology differs: {what} in {Path(file).name} has {count} vertices but no "
            f"IndexedFaceSet of {_scene_name(neutral)} has that many points "
            f"(IndexedFaceSets: {sizes})",
            file=file,
        )
    raise AdtError(
        f"ambiguous: {what} in {Path(file).name} has {count} vertices, as have the "
        f"IndexedFaceSets {', '.join(same)} of {_scene_name(neutral)}; name one with --node",
        file=file,
    )


PoseLoader = Callable[[Path, Scene, str | None], list[DeformedPose]]


def _load_mesh(reader: Callable[[Path], np.ndarray]) -> PoseLoader:
    """A loader of single-mesh files (OBJ, PLY) whose vertices ``reader`` returns."""

    def load(path: Path, neutral: Scene, node: str | None) -> list[DeformedPose]:
        miap, amplitude = _miap_of_file(path)
        vertices = reader(path)
        _check_finite(vertices, str(path))
        name = _target_mesh(neutral, len(vertices), file=str(path), node=node)
        return [
            DeformedPose(miap, amplitude, str(path), {name: vertices}, {}, has_transforms=False)
        ]

    return load


def _check_finite(a: np.ndarray, file: str) -> None:
    if not np.isfinite(a).all():
        raise AdtError("the mesh has non-finite coordinates (nan or inf)", file=file)


# ---- glTF ----------------------------------------------------------------------------------------
# trimesh's glTF loader ignores morph targets (primitive "targets") entirely, and flattens meshes
# into world coordinates; the ADI needs mesh-local positions and the target displacements: vtts's
# own reader (vtts.gltf) gives them.


@dataclass
class GltfMesh:
    """One glTF mesh, its primitives' vertices concatenated in order.

    name      the mesh name (may be None)
    base      ``(v, 3) float64`` POSITION of the base mesh (mesh-local coordinates)
    targets   morph target name → ``(v, 3) float64`` POSITION displacements
    intervals morph target name → (from, to): the ADT interval a target of a vtts export
              (``vtts say -o x.glb``) spans, in the MIAP's units; empty for other files

    A vtts export says in the mesh's ``extras.vtts`` how many of its vertices are the
    IndexedFaceSet's Coordinate points (the first ``points``; the rest are copies at seams):
    ``base`` and the targets keep those.
    """

    name: str | None
    base: np.ndarray
    targets: dict[str, np.ndarray]
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)


def read_gltf_meshes(path: str | os.PathLike[str]) -> list[GltfMesh]:
    """Every mesh of a ``.glb``/``.gltf`` file with its morph targets (see :class:`GltfMesh`),
    read with :class:`vtts.gltf.GltfReader`. Raises :class:`AdtError` naming the file."""
    from vtts.gltf import GltfReader  # pygltflib only when a glTF is read

    reader = GltfReader(path, error=AdtError)
    try:
        return [_gltf_mesh(reader, mi) for mi in range(len(reader.doc.meshes or []))]
    except (TypeError, AttributeError, KeyError, IndexError, ValueError, OverflowError) as e:
        # a property of the wrong JSON type somewhere the reader takes the file's word for it
        raise AdtError(
            f"malformed glTF: a property has the wrong type or value ({type(e).__name__}: "
            f"{str(e)[:200]})",
            file=reader.file,
        ) from None


def _gltf_mesh(reader: GltfReader, index: int) -> GltfMesh:
    """Mesh ``index``: every primitive's POSITION, concatenated in order, and its morph targets
    by name."""
    from vtts.gltf.reader import target_names

    mesh = reader.item(reader.doc.meshes, index, "mesh")
    label = f"mesh {mesh.name or index}"
    names = target_names(mesh)
    bases: list[np.ndarray] = []
    deltas: list[list[np.ndarray]] = []
    for pi, p in enumerate(reader.primitives(mesh, label)):
        prim = reader.primitive(p, f"{label}, primitive {pi}")
        bases.append(prim.positions)
        if pi and len(prim.targets) != len(deltas):
            raise reader.error(
                f"{label}: primitive {pi} has {len(prim.targets)} morph targets but primitive "
                f"0 has {len(deltas)} (glTF requires the same number)"
            )
        if not pi:
            deltas = [[] for _ in prim.targets]
        for ti, delta in enumerate(prim.targets):
            deltas[ti].append(delta)
    base = np.concatenate(bases) if bases else np.zeros((0, 3))
    if deltas and len(names) != len(deltas):
        raise reader.error(
            f"{label} has {len(deltas)} morph targets but "
            f"{'no' if not names else len(names)} target names: name each target after "
            "its MIAP (mesh extras 'targetNames', e.g. close_t_l_eyelid@1024, viseme3, joy)"
        )
    targets_by_name: dict[str, np.ndarray] = {}
    for tname, parts in zip(names, deltas, strict=False):
        if tname in targets_by_name:
            raise reader.error(f"{label}: morph target '{tname}' is named twice")
        targets_by_name[tname] = np.concatenate(parts)
    points, intervals = _vtts_extras(reader, mesh, label, len(base), names)
    if points is not None:
        base = base[:points]
        targets_by_name = {k: v[:points] for k, v in targets_by_name.items()}
    return GltfMesh(mesh.name, base, targets_by_name, intervals)


def _vtts_extras(
    reader: GltfReader, mesh: Any, label: str, n_vertices: int, names: list[str]
) -> tuple[int | None, dict[str, tuple[float, float]]]:
    """(points, intervals) from a vtts export's mesh ``extras.vtts`` (see :class:`GltfMesh`);
    (None, {}) for other files."""
    extras = getattr(mesh, "extras", None)
    info = extras.get("vtts") if isinstance(extras, dict) else None
    if not isinstance(info, dict):
        return None, {}
    points = info.get("points")
    if points is not None and (
        isinstance(points, bool) or not isinstance(points, int) or not 0 <= points <= n_vertices
    ):
        raise reader.error(
            f"{label}: extras.vtts.points must be an integer within 0–{n_vertices} (the "
            f"vertices that are Coordinate points), got {points!r}"
        )
    given = info.get("intervals")
    if given is None:
        return points, {}
    ok = isinstance(given, list) and len(given) == len(names)
    pairs: dict[str, tuple[float, float]] = {}
    for tname, pair in zip(names, given if ok else [], strict=False):
        valid = (
            isinstance(pair, list)
            and len(pair) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in pair)
            and all(math.isfinite(v) for v in pair)
            and pair[0] != pair[1]
        )
        if not valid:
            ok = False
            break
        pairs[tname] = (float(pair[0]), float(pair[1]))
    if not ok:
        raise reader.error(
            f"{label}: extras.vtts.intervals must give [from, to] (two different finite "
            f"numbers) for each of its {len(names)} morph targets"
        )
    return points, pairs


def _load_gltf(path: Path, neutral: Scene, node: str | None) -> list[DeformedPose]:
    file = str(path)
    meshes = read_gltf_meshes(path)
    if not meshes:
        raise AdtError("the glTF file holds no mesh", file=file)
    for m in meshes:
        _check_finite(m.base, file)
        for d in m.targets.values():
            _check_finite(d, file)
    morphing = [m for m in meshes if m.targets]
    if not morphing:
        miap, amplitude = _miap_of_file(path)
        pose = DeformedPose(miap, amplitude, file, has_transforms=False)
        for m in meshes:
            name = _map_gltf_mesh(m, meshes, neutral, file, node)
            if name in pose.points:
                raise AdtError(f"two meshes map onto IndexedFaceSet {name}", file=file)
            pose.points[name] = m.base
        return [pose]
    poses: dict[Any, DeformedPose] = {}
    interval_meshes = []
    for m in morphing:
        name = _map_gltf_mesh(m, morphing, neutral, file, node)
        neutral_pts = node_points(mesh_nodes(neutral)[name])
        _check_base(m, name, neutral_pts, neutral, file)
        if m.intervals:
            interval_meshes.append((m, name, neutral_pts))
            continue
        for tname, delta in m.targets.items():
            pose = poses.get(tname)
            if pose is None:
                miap, amplitude = miap_from_label(
                    tname, what=f"morph target name '{tname}' of mesh {m.name}", file=file
                )
                pose = poses[tname] = DeformedPose(
                    miap, amplitude, f"{file}#{tname}", has_transforms=False
                )
            if name in pose.points:
                raise AdtError(
                    f"two meshes with morph target '{tname}' map onto IndexedFaceSet {name}",
                    file=file,
                )
            pose.points[name] = neutral_pts + delta
    for pose in _interval_poses(interval_meshes, file):
        if (pose.miap, pose.amplitude) in poses:
            raise AdtError(f"two meshes give MIAP {pose.miap} at {pose.amplitude:g}", file=file)
        poses[(pose.miap, pose.amplitude)] = pose
    return list(poses.values())


def _interval_poses(meshes: list[tuple[GltfMesh, str, np.ndarray]], file: str) -> list:
    """The poses of a vtts export's morph targets (one per ADT interval, named ``MIAP#K``, with
    their borders in :attr:`GltfMesh.intervals`): for each MIAP, one pose at each of its interval
    borders but 0, the sum of every target of the MIAP weighted by how far the border lies
    through its interval (0–1), so that :func:`build_tables` gives back the tables' borders and
    slopes."""
    from vtts.export.morph import parse_target_name, target_label

    per_miap: dict[Miap, list] = {}
    borders: dict[Miap, set[float]] = {}
    for m, name, neutral_pts in meshes:
        items: dict[Miap, list] = {}
        for tname, delta in m.targets.items():
            try:
                miap, _ = parse_target_name(tname)
            except FapError as e:
                raise AdtError(f"mesh {m.name}: {e.message}", file=file) from None
            if tname not in m.intervals:
                raise AdtError(f"mesh {m.name}: morph target '{tname}' has no interval", file=file)
            start, end = m.intervals[tname]
            items.setdefault(miap, []).append((start, end, delta))
            borders.setdefault(miap, set()).update(b for b in (start, end) if b != 0)
        for miap, parts in items.items():
            per_miap.setdefault(miap, []).append((name, neutral_pts, parts))
    out = []
    for miap in sorted(per_miap, key=lambda x: x.index):
        for b in sorted(borders[miap]):
            source = f"{file}#{target_label(miap)}@{format_number(b)}"
            pose = DeformedPose(miap, b, source, has_transforms=False)
            for name, neutral_pts, parts in per_miap[miap]:
                if name in pose.points:
                    raise AdtError(
                        f"two meshes with MIAP {miap}'s targets map onto IndexedFaceSet {name}",
                        file=file,
                    )
                d = np.zeros_like(neutral_pts)
                for start, end, delta in parts:
                    d += delta * float(np.clip((b - start) / (end - start), 0.0, 1.0))
                pose.points[name] = neutral_pts + d
            out.append(pose)
    return out


def _map_gltf_mesh(
    m: GltfMesh, meshes: list[GltfMesh], neutral: Scene, file: str, node: str | None
) -> str:
    # --node can only name the target of a file's single mesh
    single = node if len(meshes) == 1 else None
    return _target_mesh(
        neutral,
        len(m.base),
        file=file,
        node=single,
        mesh_name=m.name,
        what=f"glTF mesh {m.name or '(unnamed)'}",
    )


def _check_base(m: GltfMesh, name: str, neutral_pts: np.ndarray, neutral: Scene, file: str) -> None:
    """Morph targets are displacements from the glTF base mesh: it must be the neutral pose, in
    the same vertex order (float32 storage allowed for)."""
    if not len(neutral_pts):
        return
    extent = float(np.ptp(neutral_pts, axis=0).max()) or 1.0
    err = np.linalg.norm(m.base - neutral_pts, axis=1)
    worst = int(err.argmax())
    if err[worst] > 1e-5 * extent:
        raise AdtError(
            f"topology differs: the base of glTF mesh {m.name or '(unnamed)'} is not the neutral "
            f"{name} of {_scene_name(neutral)}: vertex {worst} is at "
            f"{' '.join(format_number(v) for v in m.base[worst])} but at "
            f"{' '.join(format_number(v) for v in neutral_pts[worst])} in the neutral (export "
            "the neutral pose as the base, in the same vertex order)",
            file=file,
        )


#: File suffix → loader of the poses in a file.
LOADERS: dict[str, PoseLoader] = {
    ".wrl": _load_wrl,
    ".obj": _load_mesh(_read_obj_vertices),
    ".ply": _load_mesh(_read_trimesh_vertices),
    ".glb": _load_gltf,
    ".gltf": _load_gltf,
}


# ---- building the tables -------------------------------------------------------------------------


def build_tables(
    neutral: Scene,
    poses: Sequence[DeformedPose],
    tolerance: float = DEFAULT_TOLERANCE,
) -> AnimationTables:
    """The Animation Definition Tables that reproduce ``poses`` from ``neutral``.

    Per MIAP (in parameter order): for each DEFed IndexedFaceSet some pose moves, a
    :class:`~vtts.face.MeshTable` with borders = the poses' amplitudes plus 0 and, per interval,
    the displacement per unit ``(d(b[i+1]) - d(b[i])) / (b[i+1] - b[i])`` (``d(0) = 0``) of every
    vertex that moves more than ``tolerance`` (model units, Euclidean) in some pose; for each
    DEFed Transform field that changes by more than ``tolerance``, a
    :class:`~vtts.face.TransformTable` with the change per unit (radians per unit for a rotation,
    about the neutral axis, or the deformed axis when the neutral angle is 0), which must be the
    same for every pose of the MIAP (a Transform moves linearly).

    Temporal tables and feature points embedded in ``neutral`` are kept. Raises
    :class:`AdtError` for duplicate amplitudes, non-linear or axis-changing Transform motion and
    poses whose IndexedFaceSets are unknown or of another size. A MIAP whose poses move nothing
    gets no table (with a :class:`~vtts.errors.VttsWarning`).
    """
    if not tolerance >= 0:
        raise AdtError(f"tolerance must be a non-negative number, got {tolerance}")
    try:
        embedded = tables_from_scene(neutral, file=_scene_name(neutral))
    except VttsError as e:
        warnings.warn(
            VttsWarning(
                f"the tables embedded in the neutral scene are ignored: {e.message}",
                file=e.file,
                line=e.line,
            ),
            stacklevel=2,
        )
        embedded = None
    neutral = strip_tables(neutral)
    meshes = {k: node_points(v) for k, v in mesh_nodes(neutral).items()}
    transforms = {k: _transform_values(v) for k, v in transform_nodes(neutral).items()}
    groups: dict[Miap, list[DeformedPose]] = {}
    for p in poses:
        for name, pts in p.points.items():
            if name not in meshes:
                raise AdtError(
                    f"{_scene_name(neutral)} has no IndexedFaceSet DEFed as {name}", file=p.source
                )
            if pts.shape != meshes[name].shape:
                raise AdtError(
                    f"topology differs: {name} has {len(meshes[name])} points in "
                    f"{_scene_name(neutral)} but {len(pts)} in {p.source}",
                    file=p.source,
                )
        if p.amplitude == 0 or not math.isfinite(p.amplitude):
            raise AdtError(
                f"MIAP {p.miap}: amplitude {p.amplitude} is not a deformed pose", file=p.source
            )
        groups.setdefault(p.miap, []).append(p)

    tables = AnimationTables()
    for miap in sorted(groups, key=lambda m: m.index):
        group = sorted(groups[miap], key=lambda p: p.amplitude)
        for a, b in zip(group, group[1:], strict=False):
            if a.amplitude == b.amplitude:
                raise AdtError(
                    f"MIAP {miap}: amplitude {format_number(a.amplitude)} is given twice, by "
                    f"{a.source} and {b.source}",
                    file=b.source,
                )
        adt = Adt(miap)
        for name, neutral_pts in meshes.items():
            table = _mesh_table(name, neutral_pts, group, tolerance)
            if table is not None:
                adt.meshes.append(table)
        for name, values in transforms.items():
            for fld in TRANSFORM_FIELDS:
                table = _transform_table(name, fld, values[fld], miap, group, tolerance)
                if table is not None:
                    adt.transforms.append(table)
        if adt.meshes or adt.transforms:
            tables.add(adt)
        else:
            warnings.warn(
                VttsWarning(
                    f"MIAP {miap}: its poses move nothing by more than {tolerance:g} "
                    f"({', '.join(p.source for p in group)}): no table",
                    file=group[0].source,
                ),
                stacklevel=2,
            )
    if embedded is not None:
        tables.temporal = embedded.temporal
        tables.feature_points = dict(embedded.feature_points)
    return tables


def _mesh_table(
    name: str, neutral_pts: np.ndarray, group: list[DeformedPose], tolerance: float
) -> MeshTable | None:
    covering = [p for p in group if name in p.points]
    if not covering:
        return None
    disp = np.stack([p.points[name] - neutral_pts for p in covering])  # (k, p, 3)
    moved = (np.linalg.norm(disp, axis=2) > tolerance).any(axis=0)
    if not moved.any():
        return None
    vertices = np.flatnonzero(moved)
    amps = np.array([p.amplitude for p in covering])
    zero_at = int(np.searchsorted(amps, 0.0))
    borders = np.insert(amps, zero_at, 0.0)
    d = np.insert(disp[:, vertices], zero_at, 0.0, axis=0)  # (n+1, v, 3) displacement at borders
    slopes = np.diff(d, axis=0) / np.diff(borders)[:, None, None]
    return MeshTable(name, borders, vertices, round_significant(slopes))


def _transform_table(
    name: str,
    fld: str,
    neutral: np.ndarray,
    miap: Miap,
    group: list[DeformedPose],
    tolerance: float,
) -> TransformTable | None:
    poses = [p for p in group if p.has_transforms]
    if not any(fld in p.transforms.get(name, {}) for p in poses):
        return None
    if fld == "rotation":
        return _rotation_table(name, neutral, miap, poses, tolerance)
    deltas = np.array(
        [p.transforms.get(name, {}).get(fld, neutral) - neutral for p in poses]
    )  # (k, 3)
    if not (np.abs(deltas) > tolerance).any():
        return None
    amps = np.array([p.amplitude for p in poses])
    unit = _linear_unit(amps, deltas, tolerance, name, fld, miap, poses)
    return TransformTable(name, fld, neutral, round_significant(unit))


def _linear_unit(
    amps: np.ndarray,
    deltas: np.ndarray,
    tolerance: float,
    name: str,
    fld: str,
    miap: Miap,
    poses: list[DeformedPose],
) -> np.ndarray:
    """The change per unit that fits every pose (least squares), checked to be linear."""
    deltas = deltas.reshape(len(amps), -1)
    unit = (amps @ deltas) / (amps @ amps)
    residual = np.abs(np.outer(amps, unit) - deltas).max(axis=1)
    allowed = tolerance + 1e-9 * np.abs(deltas).max()
    bad = int(residual.argmax())
    if residual[bad] > allowed:
        ref = int(np.abs(amps).argmax())
        if ref == bad:
            ref = int(np.argsort(np.abs(amps))[-2])
        units = {"rotation": " rad"}.get(fld, "")

        def show(i: int) -> str:
            d = " ".join(format_number(v) for v in deltas[i])
            return f"{d}{units} at {format_number(amps[i])} ({poses[i].source})"

        raise AdtError(
            f"Transform {name}: {fld} is not linear in MIAP {miap}: it changes by {show(ref)} "
            f"but by {show(bad)}; a Transform table has one change per unit (model non-linear "
            "motion with an IndexedFaceSet)",
            file=poses[bad].source,
        )
    return unit


def _unit_axis(r: np.ndarray) -> np.ndarray | None:
    n = float(np.linalg.norm(r[:3]))
    return r[:3] / n if n > 0 else None


def _rotation_table(
    name: str,
    neutral: np.ndarray,
    miap: Miap,
    poses: list[DeformedPose],
    tolerance: float,
) -> TransformTable | None:
    axis0 = _unit_axis(neutral)
    identity = abs(neutral[3]) <= tolerance or axis0 is None
    axis = None if identity else axis0
    deltas: list[float] = []
    for p in poses:
        r = p.transforms.get(name, {}).get("rotation", neutral)
        a = _unit_axis(r)
        angle = float(r[3])
        if a is None or abs(angle) <= tolerance:  # the identity rotation
            deltas.append(0.0 if identity else -float(neutral[3]))
            continue
        if axis is None:
            axis = a
        if np.allclose(a, axis, atol=1e-6):
            pass
        elif np.allclose(a, -axis, atol=1e-6):
            angle = -angle
        else:
            fmt = " ".join(format_number(v) for v in axis)
            what = (
                f"its neutral axis {fmt} (neutral angle {format_number(neutral[3])})"
                if not identity
                else f"axis {fmt} of the other poses"
            )
            raise AdtError(
                f"Transform {name}: the rotation axis changes in MIAP {miap}: "
                f"{' '.join(format_number(v) for v in r[:3])} in {p.source} but {what}; a "
                "MIAP rotates a Transform about one axis (the neutral one when the neutral angle "
                "is not 0)",
                file=p.source,
            )
        deltas.append(angle - (0.0 if identity else float(neutral[3])))
    d = np.array(deltas)
    if axis is None or not (np.abs(d) > tolerance).any():
        return None
    amps = np.array([p.amplitude for p in poses])
    unit = float(_linear_unit(amps, d, tolerance, name, "rotation", miap, poses)[0])
    if identity:
        if unit < 0:  # the same rotation about the opposite axis: keep the unit positive
            axis, unit = -axis, -unit
        neutral_value = np.r_[axis, 0.0]
    else:
        neutral_value = neutral  # axis is the neutral axis here
    unit = float(round_significant(np.array([unit]))[0])
    if abs(unit - AU) <= 1e-9 * AU:
        unit = AU  # the angle unit of FAPs: keeps the .adt free of a 'per unit' line
    return TransformTable(name, "rotation", neutral_value + 0.0, np.array([unit]))


#: Significant digits kept in displacements and units: subtracting and dividing exported
#: coordinates leaves float noise in the last digits (9.999999999999999e-05 for 1e-4); rounding it
#: away changes a displacement by a 1e-12 fraction, far below any tolerance.
SIGNIFICANT_DIGITS = 12


def round_significant(a: np.ndarray, digits: int = SIGNIFICANT_DIGITS) -> np.ndarray:
    """``a`` (any shape, float64) rounded to ``digits`` significant decimal digits."""
    a = np.asarray(a, dtype=np.float64)
    flat = [float(f"{v:.{digits}g}") for v in a.reshape(-1).tolist()]
    return np.array(flat, dtype=np.float64).reshape(a.shape) + 0.0


def summary(tables: AnimationTables) -> str:
    """``12 MIAPs, 3 nodes``."""
    n = len(tables.adts)
    k = len(tables.mesh_nodes()) + len(tables.transform_nodes())
    return f"{n} MIAP{'' if n == 1 else 's'}, {k} node{'' if k == 1 else 's'}"


def build(
    neutral_path: str | os.PathLike[str],
    deformed: Sequence[str | os.PathLike[str]],
    *,
    tolerance: float = DEFAULT_TOLERANCE,
    node: str | None = None,
) -> tuple[Scene, AnimationTables]:
    """Read the neutral model and the deformed files and build the tables: what ``adi build``
    does before writing. Returns the neutral scene (tables stripped) and the tables."""
    neutral = read(neutral_path)
    poses: list[DeformedPose] = []
    for path in deformed:
        poses.extend(load_poses(path, neutral, node=node))
    return neutral, build_tables(neutral, poses, tolerance)
