"""Personalized models: a neutral VRML97 scene plus its animation and temporal tables.

A model is loaded from ``NAME.wrl`` with its tables either inside it (MPEG-4 FaceDefTables nodes)
or in a sidecar ``NAME.adt`` beside it; both carry the same information and load to the same
:class:`FaceModel`. Bundled models are found by short name (``load_model("cybatt")``).
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Mapping
from functools import cached_property
from pathlib import Path

import numpy as np

from vtts.errors import ModelError, VttsError, VttsWarning
from vtts.face import cache
from vtts.face.adt import (
    AnimationTables,
    check_tables,
    read_adt,
    strip_tables,
    tables_from_scene,
)
from vtts.face.deform import DeformationEngine, Pose
from vtts.face.miap import N_PARAMS, Miap, face_params
from vtts.face.temporal import TemporalTables
from vtts.fap import Fapu
from vtts.resources import models_dir
from vtts.vrml import Node, Scene, read, standard_node_types, url_roots


def bundled_models() -> list[str]:
    """Short names of the models that ship with vtts."""
    try:
        return sorted(p.stem for p in models_dir().glob("*.wrl"))
    except FileNotFoundError:
        return []


def find_model(name_or_path: str | Path) -> Path:
    """The ``.wrl`` of a model given as a path or a bundled short name."""
    p = Path(name_or_path)
    if p.is_file():
        return p
    if p.suffix == "" and p.with_suffix(".wrl").is_file():
        return p.with_suffix(".wrl")
    if len(p.parts) == 1 and p.suffix in ("", ".wrl"):
        try:
            bundled = models_dir() / f"{p.stem}.wrl"
        except FileNotFoundError:
            bundled = None
        if bundled is not None and bundled.is_file():
            return bundled
    names = ", ".join(bundled_models()) or "none"
    raise ModelError(
        f"no model '{name_or_path}': not a file, and not a bundled model (bundled: {names})"
    )


def load_model(
    name_or_path: str | Path,
    *,
    lenient: bool = False,
    url_root: str | Path | Iterable[str | Path] | None = None,
) -> FaceModel:
    """Load a personalized model by path or bundled short name.

    The tables come from FaceDefTables nodes in the ``.wrl`` or from a sidecar ``.adt`` beside it
    (not both). ``lenient`` and ``url_root`` (None: ``$VTTS_URL_ROOT``) are as in
    :func:`vtts.vrml.parse`. Raises :class:`~vtts.errors.ModelError` (or a parse error) for bad
    input. Large models come from :mod:`vtts.face.cache` after their first load.
    """
    path = find_model(name_or_path)
    roots = url_roots(url_root)
    sidecar = path.with_suffix(".adt")
    entry = None
    if not lenient:
        entry = cache.entry_path([path, sidecar] if sidecar.is_file() else [path])
        parts = cache.load(entry) if entry is not None else None
        if parts is not None:
            model = FaceModel.__new__(FaceModel)  # the scene is stripped of its tables already
            model.scene, model.tables = parts
            model.path = model.scene.path = path  # spelled as this call spells it
            # an entry was parsed without url roots: with them it parses the same
            model.scene.url_roots = roots
            return model
    model = _parse_model(path, lenient, roots)
    if entry is not None and not roots:
        # only what loads without url roots is kept: a url that needs one must fail without it
        cache.store(entry, model)
    return model


def _parse_model(path: Path, lenient: bool, roots: tuple[Path, ...] = ()) -> FaceModel:
    scene = read(path, lenient=lenient, url_root=roots)
    embedded = tables_from_scene(scene, file=str(path))
    sidecar = path.with_suffix(".adt")
    if sidecar.is_file():
        if embedded is not None and embedded.adts:
            raise ModelError(
                f"{path.name} embeds FaceDefTables and {sidecar.name} lies beside it: a model's "
                "tables must come from one place (remove one of them)",
                file=str(path),
            )
        tables = read_adt(sidecar)
        if embedded is not None:  # temporal tables embedded, spatial ones in the sidecar
            tables.temporal.expressions = {
                **embedded.temporal.expressions,
                **tables.temporal.expressions,
            }
            tables.temporal.habits = {**embedded.temporal.habits, **tables.temporal.habits}
        check_tables(tables, scene, file=str(sidecar))
    else:
        tables = embedded or AnimationTables()
        check_tables(tables, scene, file=str(path))
    return FaceModel(scene, tables, path)


class FaceModel:
    """A personalized talking-head model.

    ``scene``: the neutral VRML97 scene (tables removed); ``tables``: its
    :class:`~vtts.face.adt.AnimationTables`; ``path``: where it was loaded from.
    """

    def __init__(self, scene: Scene, tables: AnimationTables, path: Path | None = None) -> None:
        self.scene = strip_tables(scene)
        self.tables = tables
        self.path = path

    @property
    def name(self) -> str:
        return self.path.stem if self.path else "model"

    @property
    def temporal(self) -> TemporalTables:
        return self.tables.temporal

    @property
    def miaps(self) -> list[Miap]:
        """The MIAPs the model has tables for, in parameter order."""
        return sorted(self.tables.adts, key=lambda m: m.index)

    def neutral_points(self, name: str) -> np.ndarray:
        """``(p, 3)`` neutral Coordinate points of the IndexedFaceSet DEFed as ``name``."""
        ifs = self.scene.node(name).expand()
        coord = ifs["coord"]
        if coord is None:
            return np.zeros((0, 3))
        return np.asarray(coord.expand()["point"], dtype=np.float64)

    @cached_property
    def engine(self) -> DeformationEngine:
        points = {n: self.neutral_points(n) for n in self.tables.mesh_nodes()}
        transforms = {
            n: {
                f: np.asarray(self.scene.node(n).expand()[f], dtype=np.float64)
                for f in ("rotation", "translation", "scale")
            }
            for n in self.tables.transform_nodes()
        }
        return DeformationEngine(self.tables, points, transforms)

    @cached_property
    def fapu(self) -> Fapu | None:
        """The model's FAPUs from its feature points, or None when it gives too few."""
        fp = self.tables.feature_points
        if not fp:
            return None
        points = {k: self.neutral_points(node)[v] for k, (node, v) in fp.items()}
        try:
            return Fapu.from_feature_points(points)
        except VttsError:
            return None

    def params(
        self,
        faps: Mapping[int | str, float] | np.ndarray | None = None,
        *,
        visemes: Mapping[int | str, float] | None = None,
        expressions: Mapping[int | str, float] | None = None,
    ) -> np.ndarray:
        """A ``(N_PARAMS,)`` parameter vector (an array passes through)."""
        if isinstance(faps, np.ndarray):
            if faps.shape != (N_PARAMS,):
                raise ModelError(f"a parameter vector has shape ({N_PARAMS},), got {faps.shape}")
            p = faps.astype(np.float64, copy=True)
            return p + face_params(None, visemes, expressions)
        return face_params(faps, visemes, expressions)

    def deform(
        self,
        faps: Mapping[int | str, float] | np.ndarray | None = None,
        *,
        visemes: Mapping[int | str, float] | None = None,
        expressions: Mapping[int | str, float] | None = None,
    ) -> Pose:
        """The posed geometry: ``model.deform({19: 512}, expressions={"joy": 0.8})`` or
        ``model.deform(params)`` with a ``(N_PARAMS,)`` vector."""
        return self.engine.deform(self.params(faps, visemes=visemes, expressions=expressions))

    def posed_scene(self, pose: Pose) -> Scene:
        """A copy of the neutral scene with the pose applied: plain VRML97, no tables."""
        memo = {id(t): t for t in standard_node_types().values()}
        scene = copy.deepcopy(self.scene, memo)
        for name, pts in pose.points.items():
            coord = scene.node(name).expand()["coord"].expand()
            coord.fields["point"] = np.array(pts, dtype=np.float64)
        for name, fields in pose.transforms.items():
            node = scene.node(name).expand()
            for f, v in fields.items():
                node.fields[f] = np.array(v, dtype=np.float64)
        return scene

    def texture_file(self, node: Node) -> Path | None:
        """The file an ``ImageTexture`` ``node`` loads: the first of its urls that names a file
        inside the model's folder (or the allowed url roots); None when none does."""
        from vtts.vrml import resolve_url

        base = self.path.parent if self.path else None
        return resolve_url(node.expand()["url"], base, getattr(self.scene, "url_roots", ()))

    def missing_textures(self) -> list[tuple[Node, list[str]]]:
        """The ``ImageTexture`` nodes whose urls name no file that can be loaded (missing, or
        outside the allowed folders), with their urls: drawn untextured."""
        out = []
        for node in self.scene.find("ImageTexture"):
            urls = list(node.expand()["url"])
            if urls and self.texture_file(node) is None:
                out.append((node, urls))
        return out

    def texture_warning(self, node: Node, urls: list[str]) -> VttsWarning:
        """The warning for an ``ImageTexture`` whose ``urls`` load nothing (drawn untextured)."""
        return VttsWarning(
            f"texture {' '.join(repr(u) for u in urls)} not found (or outside the allowed "
            "folders): drawn untextured",
            file=str(self.path) if self.path else None,
            line=getattr(node, "line", None) or None,
        )

    def describe(self) -> list[str]:
        """What the model can do, as lines for ``vtts info``."""
        out = []
        kinds = {"fap": [], "viseme": [], "expression": []}
        for m in self.miaps:
            kinds[m.kind].append(m)
        low = kinds["fap"]
        out.append(
            f"MIAPs: {len(self.tables.adts)} ({len(low)} low-level FAPs, "
            f"{len(kinds['viseme'])} visemes, {len(kinds['expression'])} expressions)"
        )
        if low:
            out.append("  FAPs: " + ", ".join(f"{m.number} {m.name}" for m in low))
        if kinds["viseme"]:
            out.append("  visemes: " + ", ".join(f"{m.number} ({m.name})" for m in kinds["viseme"]))
        if kinds["expression"]:
            out.append("  expressions: " + ", ".join(m.name for m in kinds["expression"]))
        meshes = self.tables.mesh_nodes()
        transforms = self.tables.transform_nodes()
        if meshes:
            out.append(
                "animated IndexedFaceSets: "
                + ", ".join(f"{n} ({len(self.neutral_points(n))} points)" for n in meshes)
            )
        if transforms:
            out.append("animated Transforms: " + ", ".join(transforms))
        t = self.temporal
        if t.expressions:
            out.append("expression timing (onset/climax/offset s, shape):")
            for name, e in t.expressions.items():
                out.append(
                    f"  {name}: {e.onset:g}/{e.duration:g}/{e.offset:g} {e.shape}, "
                    f"climax {e.climax:g}"
                )
        if t.habits:
            out.append("habits (every s ± s, lasting s, amplitude):")
            for name, h in t.habits.items():
                out.append(
                    f"  {name}: {h.interval:g} ± {h.jitter:g}, {h.duration:g}, {h.amplitude:g}"
                )
        if not self.tables:
            out.append("no animation tables: a static scene")
        return out
