"""ARKit-blendshape glTF heads as personalized models: :func:`import_avatar` (``adi import``).

- **Scene.** Each glTF node of the default scene becomes a VRML ``Transform`` (its name kept as
  the DEF name where VRML allows, made unique), its local matrix as translation, rotation and
  scale; each triangle primitive of its mesh a ``Shape`` with a DEFed ``IndexedFaceSet``
  (positions, normals, texture coordinates with t = 1 − v, vertex colors) and an ``Appearance``
  (the base color as diffuseColor and transparency, emissive, roughness as shininess, the base
  color texture as an ``ImageTexture`` written beside the ``.wrl``). A skinned mesh is posed at
  its rest pose (the joints' world matrices times their inverse bind matrices) and placed at the
  top of the scene, as glTF places skinned meshes.
- **Tables.** Morph target names are matched to ARKit's 52 and Oculus's 15 in their common
  spellings (:mod:`vtts.avatar.names`); the others are listed in one warning. Every row of the
  recipe table (:mod:`vtts.avatar.arkit`) becomes an interval of the MIAP's table on each mesh:
  ``Σ weight · target`` is the displacement at the row's value, so the table's slope is that sum
  over the row's signed amplitude. A FAP with a ``+`` and a ``-`` row gets both intervals
  (borders −a, 0, +a). Oculus ``viseme_*`` targets, where a mesh has them, are that mesh's
  visemes 1–14 as they are.
- **Eyes.** A mesh whose node, mesh or only joint is named like an eye (``EyeLeft``, ``eye_L``,
  ``LeftEye``, ``Eye.R``, ``eyeball_l``) goes into a Transform centred on the eyeball: FAPs 23–26
  (yaw and pitch of each eyeball, recipe directions: + yaw to the face's left, + pitch down)
  rotate it by one AU per unit. The eye meshes then take no mesh tables for those FAPs (the
  ``eyeLook*`` targets would turn them twice); the lids keep theirs.
- **FAPUs** are measured on the mesh through the MPEG-4 feature points the targets reveal: the
  upper lid's middle is the vertex ``eyeBlinkLeft`` moves most (3.1), the lower lid the vertex it
  lands on (3.3); the pupils the front of the eyeballs, else between the lids (3.5, 3.6); the
  mouth corners the vertices ``mouthSmile*`` (else ``mouthStretch*``) move most (8.3, 8.4); the
  upper lip's middle the front vertex between them (2.2); the bottom of the nose the front
  vertex on the midline at the lowest point ``noseSneer*`` move (9.15). They are written as
  ``#FeaturePoints``, so ``model.fapu`` follows.
"""

from __future__ import annotations

import contextlib
import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vtts.avatar.arkit import OCULUS_VISEMES, RecipeTable, recipes
from vtts.avatar.names import eye_side, match_names
from vtts.errors import AvatarError, VttsError, VttsWarning
from vtts.face.adt import Adt, AnimationTables, MeshTable, TransformTable
from vtts.face.miap import Miap
from vtts.fap import AU
from vtts.gltf import GLTF_SUFFIXES, GltfReader, Image, Material, Primitive
from vtts.render.camera import MAX_EXTENT
from vtts.vrml import Node, Scene, standard_node_types

#: Target displacements smaller than this fraction of the mesh's size are left out of tables.
TOLERANCE = 1e-7
#: The deepest node tree imported.
MAX_DEPTH = 128
#: Eye FAPs: (yaw, pitch) per eye.
EYE_FAPS = {"left": (23, 25), "right": (24, 26)}

_VRML_ID = re.compile(r"[^A-Za-z0-9_]")
#: VRML97's reserved words (section 5.1.2): no DEF name may be one of them.
VRML_KEYWORDS = frozenset(
    "DEF EXTERNPROTO FALSE IS NULL PROTO ROUTE TO TRUE USE eventIn eventOut exposedField "
    "field".split()
)


@dataclass(eq=False)
class ImportedAvatar:
    """A glTF avatar as a personalized model: the neutral ``scene`` (VRML97 nodes), its
    ``tables`` (ADTs, feature points, default temporal tables), the texture ``images`` by the
    file name the scene's ``ImageTexture`` urls give them, the morph target names that matched
    nothing (``unknown``) and the ARKit/Oculus names found (``found``)."""

    scene: Scene
    tables: AnimationTables
    images: dict[str, Image] = field(default_factory=dict)
    unknown: list[str] = field(default_factory=list)
    found: list[str] = field(default_factory=list)
    eyes: list[str] = field(default_factory=list)
    sources: list[Path] = field(default_factory=list)

    def texture_names(self, path: str | Path) -> dict[str, str]:
        """The file name each image is written to beside ``path``: ``PATH-tex0.png`` …"""
        stem = Path(path).stem
        return {key: f"{stem}-tex{i}.{'jpg' if img.format == 'jpeg' else 'png'}"
                for i, (key, img) in enumerate(self.images.items())}  # fmt: skip

    def outputs(self, path: str | Path) -> list[Path]:
        """The files :meth:`write` writes for ``path``."""
        wrl = Path(path)
        return [wrl, wrl.with_suffix(".adt"),
                *(wrl.with_name(n) for n in self.texture_names(wrl).values())]  # fmt: skip

    def write(self, path: str | Path) -> list[Path]:
        """Write ``PATH.wrl``, ``PATH.adt`` and the textures (``PATH-tex0.png`` …) beside each
        other, each renamed into place only when all are written. Returns the paths."""
        from vtts.atomic import atomic_path
        from vtts.face.adt import check_tables, format_adt, parse_adt
        from vtts.vrml import dumps, parse

        wrl = Path(path)
        if wrl.suffix.lower() != ".wrl":
            raise AvatarError(f"the output must be a .wrl file, got {str(path)!r}")
        renamed = self.texture_names(wrl)
        for node in self.scene.find("ImageTexture"):
            url = list(node["url"])
            if url and url[0] in renamed:
                node.fields["url"] = [renamed[url[0]]]
        try:
            check_finite(self.scene, self.tables)
            text = dumps(self.scene, comment="imported from glTF by adi import")
            adt = format_adt(self.tables)
            # what is written is what loads back: read here, before any file is replaced
            check_tables(parse_adt(adt, file=str(wrl.with_suffix(".adt"))),
                         parse(text, file=str(wrl)), file=str(wrl))  # fmt: skip
        except VttsError as e:
            raise AvatarError(
                f"the imported model would not load back, so nothing was written: {e.message}",
                file=str(wrl),
            ) from None
        finally:
            self._restore_urls(renamed)
        paths = self.outputs(wrl)
        with contextlib.ExitStack() as stack:
            tmp = [stack.enter_context(atomic_path(p)) for p in paths]
            tmp[0].write_text(text, encoding="utf-8")
            tmp[1].write_text(adt, encoding="utf-8")
            for img, target in zip(self.images.values(), tmp[2:], strict=True):
                target.write_bytes(img.data)
        return paths

    def _restore_urls(self, renamed: dict[str, str]) -> None:
        """The scene's ImageTexture urls back to the images' keys after :meth:`write`."""
        back = {v: k for k, v in renamed.items()}
        for node in self.scene.find("ImageTexture"):
            url = list(node["url"])
            if url and url[0] in back:
                node.fields["url"] = [back[url[0]]]


def check_finite(scene: Scene, tables: AnimationTables) -> None:
    """Every number of ``scene``'s fields and of ``tables`` is finite: a glTF's huge values
    (a texture transform's scale of 1e308) can overflow on the way, and VRML has no
    ``inf``. Raises :class:`~vtts.errors.AvatarError` naming the node and the field."""
    seen: set[int] = set()
    stack = list(scene.roots)
    while stack:
        node = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        for name, value in node.fields.items():
            array = _numbers(value)
            if array is not None and not np.isfinite(array).all():
                label = f"DEF {node.name} {node.type_name}" if node.name else node.type_name
                raise AvatarError(f"{label} {name} holds a number that is not finite")
        stack.extend(node.children_nodes())
    for miap, adt in tables.adts.items():
        for table in (*adt.meshes, *adt.transforms):
            for name, value in vars(table).items():
                array = _numbers(value)
                if array is not None and not np.isfinite(array).all():
                    raise AvatarError(
                        f"the table of {miap.kind} {miap.number} for {table.node}: a number of "
                        f"its {name} is not finite"
                    )


def _numbers(value) -> np.ndarray | None:
    """``value`` as a float array when it is numbers (a number, a vector, an array), else None."""
    if isinstance(value, bool | str | Node) or value is None:
        return None
    if isinstance(value, list | tuple) and any(isinstance(v, str | Node) for v in value):
        return None
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        return None
    return array


@dataclass(eq=False)
class _FaceSet:
    """An imported IndexedFaceSet: DEF name, neutral points ``(p, 3)`` in its own coordinates,
    canonical target name → displacement ``(p, 3)``, whether it is an eyeball."""

    name: str
    points: np.ndarray
    targets: dict[str, np.ndarray]
    eye: str | None = None
    world: np.ndarray = field(default_factory=lambda: np.eye(4))


def import_avatar(path: str | Path, *, table: RecipeTable | None = None) -> ImportedAvatar:
    """Read the glTF avatar at ``path`` and make it a personalized model (see the module
    docstring). ``table``: the recipe table (default: vtts's, :func:`vtts.avatar.recipes`).
    Raises :class:`~vtts.errors.AvatarError` for a file that cannot be imported; warns
    (:class:`~vtts.errors.VttsWarning`) about unknown target names and dropped textures."""
    path = Path(path)
    if path.suffix.lower() not in GLTF_SUFFIXES:
        raise AvatarError(
            f"an avatar is a .glb or .gltf file, not {path.suffix or 'no suffix'}", file=str(path)
        )
    asset = GltfReader(path, error=AvatarError)
    try:
        return _Importer(asset, table or recipes()).run()
    except VttsError as e:
        e.file = e.file or asset.file
        raise
    except (TypeError, AttributeError, KeyError, IndexError, ValueError, OverflowError) as e:
        # a property of the wrong JSON type somewhere the reader takes the file's word for it
        raise AvatarError(
            f"malformed glTF: a property has the wrong type or value ({type(e).__name__}: "
            f"{str(e)[:200]})",
            file=asset.file,
        ) from None


class _Importer:
    def __init__(self, asset: GltfReader, table: RecipeTable) -> None:
        self.asset = asset
        self.table = table
        self.types = standard_node_types()
        self.names: set[str] = set()
        self._next_suffix: dict[str, int] = {}  # the suffix to try next for a name taken
        self.defs: dict[str, Node] = {}
        self.face_sets: list[_FaceSet] = []
        self.images: dict[str, Image] = {}
        self.unknown: list[str] = []
        self.found: set[str] = set()
        # side -> [(DEF name, world-to-local rotation)]: an eye may be several meshes (a cornea)
        self.eye_transforms: dict[str, list[tuple[str, np.ndarray]]] = {}
        self.world: dict[int, np.ndarray] = {}
        self.materials: dict[int | None, Node] = {}

    def node(self, type_name: str, name: str | None = None, **fields) -> Node:
        n = Node(self.types[type_name], fields=fields, name=name)
        if name:
            self.defs[name] = n
        return n

    def unique(self, name: str | None, fallback: str) -> str:
        base = _VRML_ID.sub("_", name or "") or fallback
        if base[0].isdigit():
            base = f"_{base}"
        if base in VRML_KEYWORDS:  # DEF USE would not read back
            base = f"{base}_"
        out = base
        if out in self.names:
            # from where the last search for this name stopped: thousands of nodes of one name
            # would otherwise try every suffix taken before (quadratic)
            k = self._next_suffix.get(base, 2)
            while (out := f"{base}_{k}") in self.names:
                k += 1
            self._next_suffix[base] = k + 1
        self.names.add(out)
        return out

    # ---- the scene ----------------------------------------------------------------------------

    def run(self) -> ImportedAvatar:
        roots = self.asset.scene_roots()
        for r in roots:
            self._world(r, np.eye(4), 0, set())
        top: list[Node] = []
        top_level: list[Node] = []  # skinned meshes, and animated ones in turned frames
        for r in roots:
            top.append(self._transform(r, top_level))
        top += top_level
        if not self.face_sets:
            raise AvatarError("the file holds no triangle mesh to import", file=self.asset.file)
        if self.unknown:
            shown = ", ".join(self.unknown[:40]) + (" …" if len(self.unknown) > 40 else "")
            warnings.warn(
                VttsWarning(
                    f"{len(self.unknown)} morph targets are neither ARKit blendshapes nor Oculus "
                    f"visemes and are not used: {shown}",
                    file=self.asset.file,
                ),
                stacklevel=3,
            )
        info = self.node("WorldInfo", title=f"imported from {self.asset.path.name}",
                         info=[f"vtts: {len(self.found)} ARKit/Oculus targets"])  # fmt: skip
        scene = Scene(statements=[info, *top], defs=dict(self.defs), path=None)
        tables = self._tables()
        tables.feature_points = self._feature_points()
        if not self.found:
            warnings.warn(VttsWarning(
                "no morph target is an ARKit blendshape or an Oculus viseme: the model imports "
                "without animation tables (a static scene)", file=self.asset.file),
                stacklevel=3)  # fmt: skip
        return ImportedAvatar(scene, tables, self.images, self.unknown, sorted(self.found),
                              sorted(self.eye_transforms), list(self.asset.sources))  # fmt: skip

    def _world(self, index: int, parent: np.ndarray, depth: int, path: set[int]) -> None:
        if depth > MAX_DEPTH:
            raise AvatarError(f"the node tree nests deeper than {MAX_DEPTH} levels",
                              file=self.asset.file)  # fmt: skip
        if index in path:
            raise AvatarError(f"node {index} is its own ancestor (a cycle in the node tree)",
                              file=self.asset.file)  # fmt: skip
        local = self.asset.local_matrix(index)
        m = parent @ local
        for matrix, frame in ((local, "its own"), (m, "the scene's")):
            if not (np.isfinite(matrix).all() and np.abs(matrix).max() <= MAX_EXTENT):
                raise AvatarError(
                    f"node {index}: its transform reaches {_largest(matrix):g} in {frame} frame, "
                    f"beyond ±{MAX_EXTENT:g} (a model nothing can render; vtts.render.camera."
                    "MAX_EXTENT)",
                    file=self.asset.file,
                )
        self.world[index] = m
        n = self.asset.doc.nodes[index]
        for c in n.children or []:
            self.asset.item(self.asset.doc.nodes, c, f"node {index}: child node")
            self._world(c, m, depth + 1, path | {index})

    def _transform(self, index: int, top_level: list[Node]) -> Node:
        gn = self.asset.doc.nodes[index]
        local = self.asset.local_matrix(index)
        t, r, s = _trs(local)
        children: list[Node] = []
        if gn.mesh is not None:
            mesh = self.asset.mesh(gn.mesh)
            eye = eye_side(gn.name) or eye_side(mesh.name)
            if gn.skin is not None:
                joints = self._skin_joint_names(gn.skin)
                eye = eye or (eye_side(joints[0]) if len(joints) == 1 else None)
                start = len(self.face_sets)
                shapes = self._shapes(mesh, gn, eye, skin=gn.skin)
                top_level.append(self._eye_wrap(shapes, eye, np.eye(4), start) if eye else
                               self.node("Group", children=shapes))  # fmt: skip
            elif _turned(self.world[index]) and match_names(mesh.target_names)[0]:
                # an animated mesh in a turned frame (a Z-up rig under a turning node) is placed
                # in the scene's frame: FAPs and FAPUs are defined on the face's y-up, z-forward
                # axes, and vtts measures them in the mesh's own coordinates
                start = len(self.face_sets)
                shapes = self._shapes(mesh, gn, eye, bake=self.world[index])
                top_level.append(self._eye_wrap(shapes, eye, np.eye(4), start) if eye else
                               self.node("Group", children=shapes))  # fmt: skip
            else:
                start = len(self.face_sets)
                shapes = self._shapes(mesh, gn, eye, world=self.world[index])
                children += (
                    [self._eye_wrap(shapes, eye, self.world[index], start)] if eye else shapes
                )
        # named after the meshes below it: a mesh keeps its own name as its IndexedFaceSet's DEF
        name = self.unique(gn.name, f"node{index}")
        for c in gn.children or []:
            children.append(self._transform(c, top_level))
        fields: dict = {"children": children}
        if np.any(t != 0):
            fields["translation"] = t
        if r[3] != 0:
            fields["rotation"] = r
        if np.any(s != 1):
            fields["scale"] = s
        return self.node("Transform", name, **fields)

    def _skin_joint_names(self, skin: int) -> list[str]:
        sk = self.asset.item(self.asset.doc.skins, skin, "skin")
        return [str(self.asset.doc.nodes[j].name or "") for j in (sk.joints or [])
                if isinstance(j, int) and 0 <= j < len(self.asset.doc.nodes)]  # fmt: skip

    def _eye_wrap(self, shapes: list[Node], side: str, world: np.ndarray, start: int) -> Node:
        """The eyeball's shapes in a Transform centred on it, rotated by FAPs 23–26."""
        pts = np.concatenate([fs.points for fs in self.face_sets[start:]] or [np.zeros((1, 3))])
        centre = eyeball_centre(pts)
        name = self.unique(f"{side[0].upper()}_EYE_ROTATION", "eye")
        lin = world[:3, :3]
        to_local = np.linalg.inv(lin) if abs(np.linalg.det(lin)) > 1e-30 else np.eye(3)
        self.eye_transforms.setdefault(side, []).append((name, to_local))
        return self.node("Transform", name, center=centre, rotation=np.array([0.0, 1, 0, 0]),
                         children=shapes)  # fmt: skip

    def _shapes(self, mesh, gn, eye: str | None, *, world=None, skin=None,
                bake=None) -> list[Node]:  # fmt: skip
        matched, unknown = match_names(mesh.target_names)
        for u in unknown:
            if u not in self.unknown:
                self.unknown.append(u)
        out = []
        for pi, prim in enumerate(mesh.primitives):
            if not prim.faces.size:
                continue
            positions, targets, normals = prim.positions, prim.targets, prim.normals
            where = world if world is not None else np.eye(4)
            if skin is not None:
                positions, targets, normals = self._skinned(prim, skin)
            elif bake is not None:
                lin = bake[:3, :3]
                positions = positions @ lin.T + bake[:3, 3]
                targets = [d @ lin.T for d in targets]
                if normals is not None:
                    normals = normals @ np.linalg.inv(lin)  # the inverse transpose, row vectors
            name = self.unique(f"{mesh.name or gn.name or 'mesh'}_{pi}" if len(mesh.primitives) > 1
                               else (mesh.name or gn.name), "mesh")  # fmt: skip
            used = [(matched[t], d) for t, d in zip(mesh.target_names, targets, strict=True)
                    if t in matched]  # fmt: skip
            # glTF splits a vertex where its texture coordinates or normals differ (seams); one
            # Coordinate point per position and motion keeps the surface (and its normals) whole
            key = np.concatenate([positions, *(d for _, d in used)], axis=1)
            _, first, point = np.unique(key, axis=0, return_index=True, return_inverse=True)
            order = np.argsort(first)  # points in the order the file first uses them
            rank = np.empty_like(order)
            rank[order] = np.arange(order.size)
            point = rank[point.reshape(-1)]
            keep = first[order]
            by_name: dict[str, np.ndarray] = {}
            for c, d in used:
                by_name[c] = d[keep]
                self.found.add(c)
            self._check_extent(positions, targets, where, f"mesh {name}")
            self.face_sets.append(_FaceSet(name, positions[keep], by_name, eye, where))
            out.append(self._shape(prim, name, positions[keep], point, normals))
        return out

    def _check_extent(self, positions, targets, world, what: str) -> None:
        """Refuse a mesh whose positions (or positions moved by a target), in its own frame or
        the scene's, lie beyond :data:`~vtts.render.camera.MAX_EXTENT`: the written model would
        hold numbers nothing can render or frame (or ``inf``)."""
        with np.errstate(over="ignore", invalid="ignore"):
            moved = [positions, *(positions + d for d in targets)]
            placed = [p @ world[:3, :3].T + world[:3, 3] for p in moved]
            worst = max((_largest(p) for p in [*moved, *placed]), default=0.0)
        if not worst <= MAX_EXTENT:
            raise AvatarError(
                f"{what}: its positions reach {worst:g}, beyond ±{MAX_EXTENT:g} (a model nothing "
                "can render; vtts.render.camera.MAX_EXTENT)",
                file=self.asset.file,
            )

    def _skinned(self, prim: Primitive, skin: int):
        """Positions, targets and normals of a skinned primitive at the rest pose (world)."""
        if prim.joints is None:
            return prim.positions, prim.targets, prim.normals
        mats = self.asset.skin_matrices(skin, self.world)
        j = prim.joints
        if j.size and (j.min() < 0 or j.max() >= len(mats)):
            raise AvatarError(f"a JOINTS_0 value names joint {int(j.max())}, the skin has "
                              f"{len(mats)}", file=self.asset.file)  # fmt: skip
        w = prim.weights
        total = w.sum(axis=1, keepdims=True)
        w = np.where(total > 0, w / np.where(total > 0, total, 1), 0.0)
        per = np.einsum("vk,vkij->vij", w, mats[j])  # (v, 4, 4)
        per[total[:, 0] <= 0] = np.eye(4)
        pos = np.einsum("vij,vj->vi", per[:, :3, :3], prim.positions) + per[:, :3, 3]
        targets = [np.einsum("vij,vj->vi", per[:, :3, :3], d) for d in prim.targets]
        normals = None
        if prim.normals is not None:
            normals = np.einsum("vij,vj->vi", per[:, :3, :3], prim.normals)
        return pos, targets, normals

    def _shape(self, prim: Primitive, name: str, points, point, normals) -> Node:
        """A Shape of ``points`` ``(p, 3)``; ``point`` ``(v,)`` is each glTF vertex's point."""
        ends = np.full((len(prim.faces), 1), -1)
        vertex_index = np.c_[prim.faces, ends].reshape(-1).astype(np.int32)
        coord_index = np.c_[point[prim.faces], ends].reshape(-1).astype(np.int32)
        material = self.asset.material(prim.material)
        fields: dict = {
            "coord": self.node("Coordinate", point=np.round(points, 7) + 0.0),
            "coordIndex": coord_index,
            "solid": not material.double_sided,
        }
        if normals is not None:
            n = np.asarray(normals, dtype=np.float64)
            norm = np.linalg.norm(n, axis=1, keepdims=True)
            n = np.where(norm > 0, n / np.where(norm > 0, norm, 1), [0.0, 0.0, 1.0])
            fields["normal"] = self.node("Normal", vector=np.round(n, 6) + 0.0)
            fields["normalIndex"] = vertex_index
        uv = prim.uv1 if material.texcoord == 1 else prim.uv
        if uv is not None and material.image is not None:
            uv = np.c_[uv, np.ones(len(uv))] @ material.uv_transform.T
            st = np.c_[uv[:, 0], 1.0 - uv[:, 1]]
            fields["texCoord"] = self.node("TextureCoordinate", point=np.round(st, 7) + 0.0)
            fields["texCoordIndex"] = vertex_index
        if prim.colors is not None:
            fields["color"] = self.node("Color", color=np.clip(prim.colors, 0, 1))
            fields["colorIndex"] = vertex_index
        geometry = self.node("IndexedFaceSet", name, **fields)
        return self.node("Shape", appearance=self._appearance(prim.material, material),
                         geometry=geometry)  # fmt: skip

    def _appearance(self, index: int | None, m: Material) -> Node:
        if index in self.materials:
            return self.materials[index]
        fields: dict = {}
        if not m.unlit:  # VRML97 draws an Appearance without a Material unlit
            fields["material"] = self.node(
                "Material",
                diffuseColor=m.base_color[:3].copy(),
                transparency=float(1.0 - m.base_color[3]),
                emissiveColor=m.emissive.copy(),
                shininess=float(np.clip((1.0 - m.roughness) / 0.8, 0.0, 1.0)),
            )
        if m.image is not None:
            img = self.asset.image(m.image)
            key = f"image{m.image}"
            self.images[key] = img
            fields["texture"] = self.node("ImageTexture", url=[key])
        app = self.materials[index] = self.node("Appearance", **fields)
        return app

    # ---- the tables ---------------------------------------------------------------------------

    def _tables(self) -> AnimationTables:
        tables = AnimationTables()
        per_miap: dict[Miap, Adt] = {}

        def adt(miap: Miap) -> Adt:
            if miap not in per_miap:
                per_miap[miap] = Adt(miap)
            return per_miap[miap]

        eyes = set(self.eye_transforms)
        for fs in self.face_sets:
            size = float(np.ptp(fs.points, axis=0).max()) if len(fs.points) else 1.0
            tol = TOLERANCE * max(size, 1e-12)
            for number in range(3, 69):
                if fs.eye and fs.eye in eyes and number in (23, 24, 25, 26):
                    continue
                sides = []
                for sign in (-1, 1):
                    row = self.table.fap(number, sign)
                    d = _combine(row.shapes, fs.targets) if row is not None else None
                    if d is not None:
                        sides.append((row.value, d))
                if sides:
                    _add_mesh(adt(Miap("fap", number)), fs.name, sides, tol)
            oculus = {v: fs.targets[OCULUS_VISEMES[v]] for v in range(1, 15)
                      if OCULUS_VISEMES[v] in fs.targets}  # fmt: skip
            for v in range(1, 15):
                if v in oculus:
                    d = oculus[v]
                else:
                    d = _combine(self.table.viseme(v).shapes, fs.targets)
                if d is not None:
                    _add_mesh(adt(Miap("viseme", v)), fs.name, [(1.0, d)], tol)
            for e in range(1, 7):
                d = _combine(self.table.expression(e).shapes, fs.targets)
                if d is not None:
                    _add_mesh(adt(Miap("expression", e)), fs.name, [(1.0, d)], tol)
        for side, name, to_local in (
            (side, n, r) for side, items in self.eye_transforms.items() for n, r in items
        ):
            yaw, pitch = EYE_FAPS[side]
            for number, axis in ((yaw, (0.0, 1.0, 0.0)), (pitch, (1.0, 0.0, 0.0))):
                a = to_local @ np.array(axis)
                a = a / np.linalg.norm(a)
                adt(Miap("fap", number)).transforms.append(
                    TransformTable(
                        name, "rotation", np.r_[np.round(a, 9) + 0.0, 0.0], np.array([AU])
                    )  # fmt: skip
                )
        for miap in sorted(per_miap, key=lambda m: m.index):
            a = per_miap[miap]
            if a.meshes or a.transforms:
                tables.add(a)
        return tables

    # ---- feature points -----------------------------------------------------------------------

    def _feature_points(self) -> dict[str, tuple[str, int]]:
        """The FAPU feature points found through the targets (none when a part is missing),
        searched in the scene's coordinates (y up, the face towards +z, as glTF has it) whatever
        the meshes' own frames are."""
        fp: dict[str, tuple[str, int]] = {}
        sets = []
        for f in self.face_sets:
            lin, shift = f.world[:3, :3], f.world[:3, 3]
            moved = {k: d @ lin.T for k, d in f.targets.items()}
            sets.append(_FaceSet(f.name, f.points @ lin.T + shift, moved, f.eye, f.world))

        def most(shape: str) -> tuple[_FaceSet, int, float] | None:
            best = None
            for fs in sets:
                d = fs.targets.get(shape)
                if d is None or fs.eye:
                    continue
                mag = np.linalg.norm(d, axis=1)
                i = int(np.argmax(mag))
                if mag[i] > 0 and (best is None or mag[i] > best[2]):
                    best = (fs, i, float(mag[i]))
            return best

        blink = most("eyeBlinkLeft")
        if blink is not None:
            fs, i, _ = blink
            fp["3.1"] = (fs.name, i)
            landed = fs.points[i] + fs.targets["eyeBlinkLeft"][i]
            still = np.linalg.norm(fs.targets["eyeBlinkLeft"], axis=1) < 0.2 * blink[2]
            cand = np.flatnonzero(still)
            if cand.size:
                j = cand[np.argmin(np.linalg.norm(fs.points[cand] - landed, axis=1))]
                fp["3.3"] = (fs.name, int(j))
        for side, point, shape in (("left", "3.5", "eyeBlinkLeft"),
                                   ("right", "3.6", "eyeBlinkRight")):  # fmt: skip
            eye = [fs for fs in sets if fs.eye == side]
            if eye:
                fs = eye[0]
                fp[point] = (fs.name, int(np.argmax(fs.points[:, 2])))
                continue
            b = most(shape)
            if b is not None:
                fs, i, _ = b
                mid = fs.points[i] + fs.targets[shape][i] / 2
                fp[point] = (fs.name, int(np.argmin(np.linalg.norm(fs.points - mid, axis=1))))
        corners = {}
        corner_shapes = (("8.3", ("mouthSmileLeft", "mouthStretchLeft"), 1.0),
                         ("8.4", ("mouthSmileRight", "mouthStretchRight"), -1.0))  # fmt: skip
        for point, shapes, side in corner_shapes:
            for shape in shapes:
                b = most(shape)
                if b is not None:
                    # the corner: the outermost of the vertices the shape moves nearly as much as
                    # its most moved one (the lips' inner and outer corners move alike)
                    fs, _, top = b
                    mag = np.linalg.norm(fs.targets[shape], axis=1)
                    strong = np.flatnonzero(mag >= 0.7 * top)
                    i = int(strong[np.argmax(side * fs.points[strong, 0])])
                    fp[point] = (fs.name, i)
                    corners[point] = fs.points[i]
                    break
        if len(corners) == 2 and fp["8.3"][0] == fp["8.4"][0]:
            fs = next(f for f in sets if f.name == fp["8.3"][0])
            mid = (corners["8.3"] + corners["8.4"]) / 2
            width = abs(corners["8.3"][0] - corners["8.4"][0])
            x, y, z = fs.points[:, 0], fs.points[:, 1], fs.points[:, 2]
            midline = np.abs(x - mid[0]) < 0.08 * width
            # the inner upper lip's middle: on the midline, in front of the corners, at their
            # height (a closed mouth's line)
            near = np.flatnonzero(midline & (z >= mid[2]) & (np.abs(y - mid[1]) < 0.15 * width))
            if near.size:
                i = near[np.lexsort((-z[near], np.round(np.abs(y[near] - mid[1]) / width, 3)))][0]
                fp["2.2"] = (fs.name, int(i))
                # the bottom of the nose: the midline point between the nose's tip (the
                # frontmost midline point above the mouth, below the eyes) and the upper lip
                # that lies deepest behind the straight line from one to the other (the
                # profile's concave corner where the nose's underside meets the philtrum)
                eyes_y = max(p[1] for p in (corners["8.3"], corners["8.4"])) + width
                if "3.5" in fp:
                    e = next(f for f in sets if f.name == fp["3.5"][0])
                    eyes_y = e.points[fp["3.5"][1], 1]
                above = np.flatnonzero(midline & (y > y[i] + 0.05 * width) & (y < eyes_y))
                if above.size:
                    tip = above[np.argmax(z[above])]
                    between = np.flatnonzero(midline & (y > y[i] + 0.05 * width) & (y < y[tip]))
                    if between.size:
                        t = (y[between] - y[i]) / (y[tip] - y[i])
                        behind = z[i] + t * (z[tip] - z[i]) - z[between]
                        fp["9.15"] = (fs.name, int(between[np.argmax(behind)]))
        needed = ("3.1", "3.3", "3.5", "3.6", "9.15", "2.2", "8.3", "8.4")
        missing = [p for p in needed if p not in fp]
        if missing:
            warnings.warn(VttsWarning(
                f"feature points {', '.join(missing)} not found through the morph targets "
                "(eyeBlink*, mouthSmile*/mouthStretch*, eye meshes): the model has "
                "no FAPUs of its own", file=self.asset.file), stacklevel=3)  # fmt: skip
        return fp


def eyeball_centre(points: np.ndarray) -> np.ndarray:
    """``(3,)`` the centre an eyeball turns about: of the sphere that best fits its ``points``
    ``(n, 3)`` (least squares), since an eye mesh is often only the front of a sphere, whose
    bounding box's centre lies too far forward; the bounding box's centre when no sphere fits
    (too few points, or a radius beyond the mesh's size)."""
    box = (points.min(axis=0) + points.max(axis=0)) / 2
    size = float(np.ptp(points, axis=0).max()) if len(points) else 0.0
    if len(points) < 4 or not size > 0:
        return box
    a = np.c_[2 * points, np.ones(len(points))]
    b = (points**2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    centre = sol[:3]
    radius2 = sol[3] + centre @ centre
    if not (np.isfinite(sol).all() and 0 < radius2 <= size**2 and
            np.linalg.norm(centre - box) <= size):  # fmt: skip
        return box
    return centre


def _turned(world: np.ndarray) -> bool:
    """Whether a world matrix does more than scale uniformly and shift (it turns, mirrors or
    stretches)."""
    lin = world[:3, :3]
    k = abs(float(np.linalg.det(lin))) ** (1 / 3)
    return not (k > 0 and np.allclose(lin, k * np.eye(3), atol=1e-9 * max(k, 1.0)))


def _combine(shapes, targets: dict[str, np.ndarray]) -> np.ndarray | None:
    """``Σ weight · target`` over the shapes a mesh has (None when it has none of them)."""
    d = None
    for name, w in shapes.items():
        t = targets.get(name)
        if t is not None:
            d = w * t if d is None else d + w * t
    return d


def _add_mesh(adt: Adt, node: str, sides: list[tuple[float, np.ndarray]], tol: float) -> None:
    """A MeshTable from the displacements at signed values (one interval per value, from 0)."""
    sides = sorted(sides, key=lambda s: s[0])
    moved = np.zeros(len(sides[0][1]), dtype=bool)
    for _, d in sides:
        moved |= np.abs(d).max(axis=1) > tol
    verts = np.flatnonzero(moved)
    if not verts.size:
        return
    borders = sorted({0.0, *(v for v, _ in sides)})
    slopes = []
    for v, d in sides:
        slopes.append(d[verts] / v)  # the integral from 0 to v of the slope is d
    if len(sides) == 1 and sides[0][0] < 0:
        borders = [sides[0][0], 0.0]
    disp = np.stack(slopes)  # (n, v, 3), in border order: negative side first
    adt.meshes.append(MeshTable(node, np.array(borders), verts, _round(disp)))


def _largest(a: np.ndarray) -> float:
    """The largest magnitude in ``a`` (inf where any is not finite; 0 for an empty array)."""
    if not a.size:
        return 0.0
    return float(np.abs(a).max()) if np.isfinite(a).all() else math.inf


def _round(a: np.ndarray) -> np.ndarray:
    """7 significant digits (the tables are written as text)."""
    out = np.array(a, dtype=np.float64)
    nz = out != 0
    digits = 6 - np.floor(np.log10(np.abs(out[nz])))
    out[nz] = np.round(out[nz] * 10.0**digits) / 10.0**digits
    return out + 0.0


def _trs(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Translation ``(3,)``, VRML axis-angle rotation ``(4,)`` and scale ``(3,)`` of a local
    matrix (a shear is lost; a mirror goes into the scale's sign)."""
    from scipy.spatial.transform import Rotation

    t = m[:3, 3].copy()
    lin = m[:3, :3]
    s = np.linalg.norm(lin, axis=0)
    s[s == 0] = 1.0
    rot = lin / s
    if np.linalg.det(rot) < 0:
        s[0], rot[:, 0] = -s[0], -rot[:, 0]
    u, _, vt = np.linalg.svd(rot)
    rv = Rotation.from_matrix(u @ vt).as_rotvec()
    angle = float(np.linalg.norm(rv))
    r = np.r_[rv / angle, angle] if angle > 1e-12 else np.array([0.0, 0.0, 1.0, 0.0])
    return np.round(t, 9) + 0.0, np.round(r, 9) + 0.0, np.round(s, 9) + 0.0
