"""A head for a video: the first frame itself is the texture of what it shows.

``adi fit`` paints a texture atlas that serves every view of the head: the photo is unlit
(divided by the renderer's shading), resampled into the atlas and resampled again by the
renderer, and it is lit again when drawn. Rendered back at the photo's own view, the head gives
the photo back only roughly (docs/analysis.md, "Camera video"): the two resamplings soften
every edge, the ears are generic, and no texture can make the lit hair as dark as real dark
hair (the renderer's specular light alone is brighter).

A video coder wants the first frame back as exactly as possible, since the next frames show the
same head from nearly the same view (Eisert & Girod's model is textured the same way, from the
scan of the person). :func:`project_frame` therefore textures the parts the frame shows
(:data:`FRAME_PARTS`: skin, hair, neck, ears, eyeballs) with the frame itself — each vertex's
texture coordinate is where the vertex lies in the frame at the fitted pose — and draws them
unlit (VRML97: an Appearance without a Material shows its texture's colours as they are), so
that the head rendered through the video's camera at the fitted pose gives the frame back texel
for pixel. The mouth's inside (teeth, tongue, cavity) keeps the atlas: the frame does not show
it; the teeth are darkened (:data:`MOUTH_SHADE`), as the shadow of the lips darkens them.

The texture is the frame in the top-left corner of a power-of-two canvas (the rest repeats the
frame's edge), so that texels and pixels stay aligned: ``u = x / W_tex``, ``v = 1 − y / H_tex``
for pixel coordinates ``(x, y)`` with pixel centres at +0.5.
"""

from __future__ import annotations

import numpy as np

from vtts.errors import FitError

#: The parts the frame textures.
FRAME_PARTS = ("FACE", "HAIR", "NECK", "L_EAR", "R_EAR", "L_EYEBALL", "R_EYEBALL")
#: Their Appearances (in the bundled heads, every Shape that uses them is one of FRAME_PARTS):
#: they lose their Material (unlit) and take the frame as their texture.
FRAME_APPEARANCES = ("SKIN", "EYE")
#: The teeth's Appearance, and the fraction of their colour they keep: inside the mouth they are
#: in the lips' shadow, lit by little more than the ambient light, while the renderer lights
#: them as fully as the face (white teeth in a mouth that the video shows dark). Chosen on one
#: real sequence (docs/analysis.md, "Camera video").
TEETH_APPEARANCE = "TEETH"
MOUTH_SHADE = 0.45


def texture_size(width: int, height: int) -> tuple[int, int]:
    """The texture ``(W_tex, H_tex)`` for a frame of ``width`` × ``height`` pixels: the powers of
    two that hold it."""
    return 1 << max(int(width) - 1, 1).bit_length(), 1 << max(int(height) - 1, 1).bit_length()


def frame_texture(image: np.ndarray) -> np.ndarray:
    """``image (H, W, 3) uint8`` in the top-left corner of a ``(H_tex, W_tex, 3) uint8`` canvas
    (:func:`texture_size`), the rest filled with the nearest edge pixel."""
    h, w = image.shape[:2]
    tw, th = texture_size(w, h)
    return np.pad(np.asarray(image, np.uint8)[..., :3], ((0, th - h), (0, tw - w), (0, 0)),
                  mode="edge")  # fmt: skip


def project_frame(scene, camera, size: tuple[int, int]) -> None:
    """Texture the :data:`FRAME_PARTS` of a fitted head's ``scene`` (changed in place) with the
    frame it was fitted to: each vertex's texture coordinate becomes its place in the frame as
    ``camera`` (a :class:`~vtts.render.Camera` in the model's frame, the fit's
    ``shape.camera``) sees it, for a frame of ``size`` (W, H) pixels textured by
    :func:`frame_texture`; the :data:`FRAME_APPEARANCES` lose their Material (unlit) and the
    teeth are shaded (:data:`MOUTH_SHADE`). The textures' urls are the caller's to set."""
    tw, th = texture_size(*size)
    for name in FRAME_APPEARANCES:
        if name not in scene.defs:
            raise FitError(f"the head has no {name} Appearance to texture with the frame")
    appearances = [scene.node(a).expand() for a in FRAME_APPEARANCES]
    parts = [scene.node(p).expand() for p in FRAME_PARTS if p in scene.defs]
    for shape in scene.find("Shape"):
        appearance, geometry = shape["appearance"], shape["geometry"]
        if appearance is None or geometry is None:
            continue
        if appearance.expand() in appearances and geometry.expand() not in parts:
            raise FitError("a part outside the frame's parts shares their Appearance")
    for name in FRAME_PARTS:
        if name not in scene.defs:
            continue
        ifs = scene.node(name).expand()
        points = np.asarray(ifs["coord"].expand()["point"], dtype=np.float64)
        xy = camera.project(points)
        coord = ifs["texCoord"]
        if coord is None:
            raise FitError(f"{name} has no texture coordinates to replace")
        coord.expand().fields["point"] = np.c_[xy[:, 0] / tw, 1.0 - xy[:, 1] / th]
        # one texture coordinate per point: the coordinates' own index serves both
        ifs.fields.pop("texCoordIndex", None)
    for name in FRAME_APPEARANCES:
        scene.node(name).expand().fields.pop("material", None)
    if TEETH_APPEARANCE in scene.defs:
        material = scene.node(TEETH_APPEARANCE).expand()["material"]
        if material is not None:
            material = material.expand()
            shaded = np.asarray(material["diffuseColor"], dtype=np.float64) * MOUTH_SHADE
            material.fields["diffuseColor"] = np.round(shaded, 4)
