"""The whole fitted head: every part of the generic head moved with the fitted face, and the
generic head's Animation Definition Tables carried over.

``FACE`` is the fitted control points through the subdivision matrix. The other parts (back of
the head, neck, ears, teeth, tongue, mouth cavity, eye sockets) follow a smooth space warp: a
thin-plate spline through the displacements of the face (:class:`ThinPlateWarp`),
so a wider face makes a wider skull and the teeth stay behind the lips. Points that coincide with
``FACE`` points (the back of the head starts on the face's border) take the face's own new
positions, so the seams stay closed. Eyeballs move rigidly with their centres (they stay
spheres, and their Transforms' centres move with them).

Tables transfer through the shared topology: vertex i of a table is vertex i of the fitted part.
A low-level FAP's displacement scales with its FAPU (MPEG-4's very idea: one unit is a fixed
fraction of a distance of the neutral face), so each of its tables is multiplied by the fitted
FAPU over the generic one; visemes take the mouth's FAPUs (MW across, MNS up and down and in
depth), expressions the eyes' and nose's (ES across, ENS up and down and in depth). Rotations
(AU) stay as they are.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from vtts.face import FaceModel
from vtts.face.adt import Adt, AnimationTables, MeshTable, TransformTable
from vtts.fap import Fapu, fap
from vtts.fit.candide import refined_face
from vtts.fit.generic import GenericHead
from vtts.fit.glasses import TEXTURE as GLASSES_TEXTURE
from vtts.vrml import Scene, standard_node_types

#: FACE points the warp passes through (every k-th): plenty for a smooth field, fast to solve.
WARP_STRIDE = 7
#: The fitted eyes' shininess (the generic eyes': 0.75; the renderer turns it into roughness).
EYE_SHININESS = 0.1
#: The Appearances of a portrait's head that the photo paints (skin, hair, ears, neck; the
#: eyes): drawn without the renderer's highlight (``specularColor 0 0 0``), since the photo
#: brings its own — with it, no texture could give a pixel darker than the highlight's floor
#: (about 30 of 255 at the photo's view), and dark hair rendered grey.
MATTE_APPEARANCES = ("SKIN", "EYE")
#: The Appearance of the parts the atlas's skin chart paints (skin, hair, neck, ears).
SKIN = "SKIN"
#: The eye Transforms whose ``center`` is the eyeball's centre.
EYE_TRANSFORMS = {"L_EYEBALL": ("L_EYE_YAW", "L_EYE_PITCH"),
                  "R_EYEBALL": ("R_EYE_YAW", "R_EYE_PITCH")}  # fmt: skip


@dataclass
class FittedGeometry:
    """Neutral points of every IndexedFaceSet ``{DEF name: (p, 3)}`` and Transform centres
    ``{DEF name: (3,)}`` of the fitted head (model units)."""

    points: dict[str, np.ndarray]
    centres: dict[str, np.ndarray]


def mesh_names(model: FaceModel) -> list[str]:
    """DEF names of the model's IndexedFaceSets, in scene order."""
    out = []
    for shape, _, _ in model.scene.shapes():
        geom = shape["geometry"]
        if geom is None:
            continue
        geom = geom.expand()
        if geom.type.name == "IndexedFaceSet" and geom.name and geom.name not in out:
            out.append(geom.name)
    return out


class ThinPlateWarp:
    """A smooth 3-D displacement field through ``anchors (k, 3)`` with ``displacements
    (k, 3)``: the biharmonic (thin-plate) spline of 3-D space, kernel ``|x − a|`` plus an affine
    part, so that a uniform scaling or shift of the face is carried over exactly and everything
    else falls off smoothly. ``warp(points (n, 3)) -> (n, 3)``."""

    def __init__(self, anchors: np.ndarray, displacements: np.ndarray, smoothing: float = 1e-6):
        k = len(anchors)
        kernel = np.linalg.norm(anchors[:, None, :] - anchors[None, :, :], axis=2)
        poly = np.c_[np.ones(k), anchors]
        system = np.zeros((k + 4, k + 4))
        system[:k, :k] = kernel + smoothing * np.eye(k)
        system[:k, k:] = poly
        system[k:, :k] = poly.T
        rhs = np.zeros((k + 4, 3))
        rhs[:k] = displacements
        coef = np.linalg.solve(system, rhs)
        self.anchors, self.weights, self.affine = anchors, coef[:k], coef[k:]

    def __call__(self, points: np.ndarray) -> np.ndarray:
        points = np.atleast_2d(points)
        d2 = (
            (points**2).sum(axis=1)[:, None]
            + (self.anchors**2).sum(axis=1)[None, :]
            - 2 * points @ self.anchors.T
        )
        kernel = np.sqrt(np.maximum(d2, 0.0))
        return kernel @ self.weights + np.c_[np.ones(len(points)), points] @ self.affine


#: Candide vertices of each eye opening: (outer corner, inner corner, upper lid, lower lid) at
#: the middle (models/src/modeler.py builds the eyeballs from the same vertices).
EYE_OPENINGS = {"L_EYEBALL": (20, 23, 21, 22), "R_EYEBALL": (53, 56, 54, 55)}


def eye_opening(face: np.ndarray, eyeball: str) -> np.ndarray:
    """``(3,)`` the middle of an eye's opening on ``face (p, 3)``: between the corners across,
    between the lids' middles up and down, the lids' depth."""
    index = refined_face().candide_index
    outer, inner, upper, lower = (face[index[v]] for v in EYE_OPENINGS[eyeball])
    return np.array([(outer[0] + inner[0]) / 2, (upper[1] + lower[1]) / 2,
                     (upper[2] + lower[2]) / 2])  # fmt: skip


def fitted_geometry(head: GenericHead, control: np.ndarray) -> FittedGeometry:
    """Every part of ``head`` moved for the fitted control points ``(c, 3)``."""
    model = head.model
    face0 = head.face
    face = head.face_points(control)
    moved = face - face0
    anchors = np.arange(0, len(face0), WARP_STRIDE)
    warp = ThinPlateWarp(face0[anchors], moved[anchors])
    # seams: a point that is a FACE point (the same numbers: the back of the head starts on the
    # face's border) takes that point's new position
    on_face = {row.tobytes(): i for i, row in enumerate(face0)}
    points = {"FACE": face}
    centres: dict[str, np.ndarray] = {}
    for name in mesh_names(model):
        if name == "FACE":
            continue
        p0 = model.neutral_points(name)
        if name in EYE_TRANSFORMS:
            centre = np.asarray(model.scene.node(EYE_TRANSFORMS[name][0]).expand()["center"])
            shift = warp(centre[None])[0]
            # the pupil stays where it was in the eye opening: across and up, the eyeball follows
            # the fitted lids and corners, not the smooth warp
            opening0, opening = eye_opening(face0, name), eye_opening(face, name)
            shift[:2] = (opening - opening0)[:2]
            points[name] = p0 + shift
            for t in EYE_TRANSFORMS[name]:
                centres[t] = centre + shift
            continue
        p = p0 + warp(p0)
        for k, row in enumerate(p0):
            i = on_face.get(row.tobytes())
            if i is not None:
                p[k] = face[i]
        points[name] = p
    for name in ("HEAD_YAW", "HEAD_PITCH", "HEAD_ROLL"):
        try:
            c = np.asarray(model.scene.node(name).expand()["center"], dtype=np.float64)
        except KeyError:
            continue
        centres[name] = c + warp(c[None])[0]
    return FittedGeometry(points, centres)


#: ImageTextures of a fitted head that are not the atlas (DEF names): the glasses' RGBA image
#: (:mod:`vtts.fit.glasses`).
OWN_TEXTURES = (GLASSES_TEXTURE,)


def set_texture_url(scene: Scene, url: str) -> None:
    """Point every ``ImageTexture`` of ``scene`` at ``url`` (the head has one atlas), but for
    the :data:`OWN_TEXTURES`."""
    for node in scene.find("ImageTexture"):
        if node.name not in OWN_TEXTURES:
            node.fields["url"] = [url]


def fitted_scene(model: FaceModel, geometry: FittedGeometry, texture_url: str,
                 title: str) -> Scene:  # fmt: skip
    """A copy of ``model``'s neutral scene with the fitted geometry, the texture at
    ``texture_url`` and ``title`` as the first WorldInfo's title."""
    memo = {id(t): t for t in standard_node_types().values()}
    scene = copy.deepcopy(model.scene, memo)
    for name, pts in geometry.points.items():
        coord = scene.node(name).expand()["coord"].expand()
        coord.fields["point"] = np.round(pts, 6) + 0.0
    for name, c in geometry.centres.items():
        scene.node(name).expand().fields["center"] = np.round(c, 6) + 0.0
    set_texture_url(scene, texture_url)
    # the photo's eyes carry their own catch lights: the generic eyes' strong highlight on top
    # would be two (and it hides the photo's colours under it)
    if "EYE" in scene.defs:
        material = scene.node("EYE").expand()["material"]
        if material is not None:
            material.expand().fields["shininess"] = EYE_SHININESS
    infos = scene.find("WorldInfo")
    if infos:
        infos[0].fields["title"] = title
    return scene


def matte(scene: Scene) -> None:
    """Give the :data:`MATTE_APPEARANCES` of ``scene`` (changed in place) no highlight of the
    renderer's (``specularColor 0 0 0``; :data:`vtts.render.scene.SPECULAR`)."""
    for name in MATTE_APPEARANCES:
        if name in scene.defs:
            material = scene.node(name).expand()["material"]
            if material is not None:
                material.expand().fields["specularColor"] = np.zeros(3)


def skin_parts(scene: Scene) -> list[str]:
    """The DEF names of the IndexedFaceSets of ``scene`` drawn with the ``SKIN`` Appearance
    (skin, hair, neck, ears: the painted atlas's chart), in file order; none without one."""
    if SKIN not in scene.defs:
        return []
    skin = scene.node(SKIN).expand()
    out = []
    for shape in scene.find("Shape"):
        app, geom = shape["appearance"], shape["geometry"]
        if app is not None and geom is not None and app.expand() is skin and geom.expand().name:
            out.append(geom.expand().name)
    return out


def set_exposure(scene: Scene, exposure: np.ndarray | float) -> None:
    """Light the ``SKIN`` Appearance of ``scene`` (changed in place) ``exposure`` times as
    brightly as the renderer's lights do (factors ≥ 1, ``(3,)`` per RGB channel or one for all:
    its Material's ``diffuseColor``, which the renderer multiplies the texture by): the texture,
    divided by it, has room for a photo lit more brightly than the renderer lights the head
    (:func:`vtts.fit.texture.skin_exposure`)."""
    material = scene.node(SKIN).expand()["material"] if SKIN in scene.defs else None
    if material is not None:
        material.expand().fields["diffuseColor"] = np.round(np.broadcast_to(exposure, 3), 4) + 0.0


def transfer_tables(generic: AnimationTables, fapu0: Fapu, fapu: Fapu) -> AnimationTables:
    """The generic head's tables for the fitted head (see the module docstring): mesh
    displacements scaled by the FAPU ratios, Transform tables as they are (their neutral values
    are the same fields of the same nodes)."""
    ratio = {k: getattr(fapu, k) / getattr(fapu0, k) for k in ("irisd", "es", "ens", "mns", "mw")}
    out = AnimationTables(temporal=generic.temporal, feature_points=dict(generic.feature_points))
    for miap, adt in generic.adts.items():
        scale = _scale(miap, ratio)
        meshes = [
            MeshTable(
                m.node, m.borders.copy(), m.vertices.copy(), _scaled(m.displacements, scale)
            )  # fmt: skip
            for m in adt.meshes
        ]
        transforms = []
        for t in adt.transforms:
            unit = t.unit
            if t.field == "translation":
                unit = t.unit * scale
            transforms.append(TransformTable(t.node, t.field, t.neutral.copy(), np.array(unit)))
        out.add(Adt(miap, meshes, transforms))
    return out


def _scaled(a: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Displacements ``a`` times ``scale``, to 7 significant digits (far below a pixel; the
    tables are written as text, and a scaled 1.234e-4 would otherwise take 17 digits); a scale
    of 1 leaves them as they are."""
    if np.all(scale == 1):
        return a.copy()
    out = a * scale
    nz = out != 0
    digits = 6 - np.floor(np.log10(np.abs(out[nz])))
    out[nz] = np.round(out[nz] * 10.0**digits) / 10.0**digits
    return out + 0.0


def fitted_fapu(tables: AnimationTables, points: dict[str, np.ndarray]) -> Fapu:
    """The FAPUs of the fitted head, from the tables' feature points on the fitted points."""
    return Fapu.from_feature_points(
        {k: points[node][v] for k, (node, v) in tables.feature_points.items()}
    )


def _scale(miap, ratio: dict[str, float]) -> np.ndarray:
    """``(3,)`` per-axis scale of a MIAP's displacements."""
    if miap.kind == "fap":
        unit = fap(miap.number).fapu
        if unit is None or unit == "AU":
            return np.ones(3)
        return np.full(3, ratio[unit.lower()])
    if miap.kind == "viseme":
        return np.array([ratio["mw"], ratio["mns"], ratio["mns"]])
    return np.array([ratio["es"], ratio["ens"], ratio["ens"]])
