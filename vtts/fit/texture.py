"""The fitted head's texture: the photo projected onto the skin, the rest filled.

The bundled heads' atlas (``models/src/texture.py``) keeps the skin of face, back of the head and
neck in one chart (its top three quarters, unwrapped around the skull's vertical axis: mirror
images of each other across ``u = 0.5``) and eye, teeth, tongue and ear tiles below. The fitted
head keeps those texture coordinates and a copy of the generic tiles (the ear tinted to the
photo's skin); only the skin chart is painted anew, at :data:`ATLAS_SIZE` texels:

1. Every skin texel finds the surface point it colours (the triangles rasterized in texture
   space), and that point's pixel in the photo.
2. The renderer shades what it draws (pyrender's lights, in linear light, then a 1/2.2 power): the
   fitted head rendered over the photo once with a mid-grey and once with a black skin gives, per
   pixel, the gain ``A`` and offset ``B`` with which a skin colour ``T`` (linear) becomes the
   pixel: ``pixel^2.2 = A·T + B``. The texel takes ``T = (photo^2.2 − B) / A``: the head then
   renders the photo back at the photo's view, and the photo's own light is not lit twice.
3. A texel counts as seen when its point is the one the photo's pixel shows (depth test against
   the rendered triangle numbers) and faces the camera; its weight falls to zero towards grazing
   views. Unseen texels take the mirrored texel (the other side of the face), and what neither
   side shows (the back of the head, under the chin) is filled by pull-push interpolation from
   what was seen: skin from the cheeks and neck, hair from the top of the head — no seams, since
   the weights blend smoothly.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from PIL import Image
from scipy import ndimage

from vtts.face.atlas import EAR_TILE, EYE_TILE, GAMMA, INSET, SKIN_TILE
from vtts.gltf.images import linear_to_srgb
from vtts.mesh import ray_barycentrics
from vtts.render.camera import Camera
from vtts.vrml import triangulate

#: Texels of the fitted head's atlas (square); the bundled heads' is 512.
ATLAS_SIZE = 1024
#: The parts that use the skin chart.
SKIN_PARTS = ("FACE", "HAIR", "NECK")
#: Parts with a tile of their own that the photo paints where it sees them (over the generic
#: tile): the eyeballs (each with its own tile, see :func:`split_eye_tiles`), teeth and tongue.
TILE_PARTS = ("L_EYEBALL", "R_EYEBALL", "UPPER_TEETH", "LOWER_TEETH", "TONGUE")
#: The ears, each painted in a tile of its own (:func:`split_ear_tiles`) where the photo paints
#: them.
EAR_PARTS = ("L_EAR", "R_EAR")
#: The parts a portrait paints: the skin, the hair, the neck (ended at the collar first,
#: :mod:`vtts.fit.neck`), the eyes and the ears (an ear under hair takes the hair). Teeth,
#: tongue and the mouth's inside are the model's own: a photo's open mouth is no texture for a
#: mouth that the model opens and closes.
PHOTO_PARTS = ("FACE", "HAIR", "NECK", "L_EYEBALL", "R_EYEBALL", *EAR_PARTS)
#: Every textured part the painter rasterizes.
PAINTED_PARTS = ("FACE", "HAIR", "NECK", *TILE_PARTS)
#: The fitted head's own eye tiles: the generic eye tile's upper half, split in two (the photo
#: shows each eye's iris where that eye looks).
EYE_TILES = {"L_EYEBALL": (0.0, 0.125, 0.125, 0.25), "R_EYEBALL": (0.125, 0.125, 0.25, 0.25)}
#: Each ear's own tile, for a head whose ears are painted from its picture (a video's first
#: frame, see :func:`split_ear_tiles`): the generic ear tile's upper half, split in two.
EAR_TILES = {"L_EAR": (0.75, 0.125, 0.875, 0.25), "R_EAR": (0.875, 0.125, 1.0, 0.25)}
#: How far (texels) the photo's colours reach beyond what it saw in the eye and teeth tiles.
TILE_REACH = 6.0
#: A texel's weight grows from 0 to 1 as the cosine between its normal and the view grows
#: between these.
GRAZING = (0.2, 0.5)
#: The parts whose outline the photo paints up to the edge: the hair shell and the ears only
#: approximate what the photo shows there, and what it shows at their silhouette is the hair's
#: or the ear's own edge, seen nearly edge-on; the grazing weight falls off only at
#: :data:`RIM_GRAZING`.
RIM_PARTS = ("HAIR", "L_EAR", "R_EAR")
RIM_GRAZING = (0.0, 0.02)
#: The face's part: where the photo shows no face (outside its face outline, hair over the
#: temples, a sideburn) a face texel the photo sees is painted up to the edge as well, with
#: what the photo shows there, not the mirrored skin of the other side.
FACE_PART = "FACE"
#: How far behind the surface the photo's pixel shows may be for the texel to be seen (model
#: units; the face is about 1.2 wide).
DEPTH_TOLERANCE = 0.01
#: At a grazing view a pixel spans a range of depths: the tolerance grows by the depth across
#: half a pixel there, up to this much more (model units).
GRAZING_DEPTH = 0.05
#: The grey (sRGB) the shading is measured with: bright enough to be above the 8-bit floor
#: everywhere, dark enough never to saturate.
PROBE_GREY = 0.5
#: The share of the seen skin texels that the skin's exposure (:func:`skin_exposure`) lights
#: brightly enough for the photo; the brightest rest stay clipped at texture 1.
EXPOSURE_QUANTILE = 0.99
#: The most the skin's exposure may brighten the renderer's shading (a guard: a turned head
#: shows the photo's brightness times the ratio of the renderer's shading there to that at the
#: photo's view, which the clipped texture used to bound).
MAX_EXPOSURE = 1.5
#: Texels the exposure counts: trusted at least this much (0–1).
EXPOSURE_WEIGHT = 0.5


@dataclass
class SkinTexels:
    """Every texel of the skin chart covered by a skin triangle.

    rows, cols  ``(N,)`` texel (row, column) in the atlas (row 0 at the top: v = 1)
    points      ``(N, 3)`` the surface point each texel colours (model units)
    normals     ``(N, 3)`` unit normals there
    photo       ``(N,)`` bool: the texel may take the photo's colour (its part is in
                :data:`PHOTO_PARTS`)
    skin        ``(N,)`` bool: the texel is of a skin part (:data:`SKIN_PARTS`)
    rim         ``(N,)`` bool: the texel is of a part whose outline the photo paints up to its
                edge (:data:`RIM_PARTS`)
    face        ``(N,)`` bool: the texel is of the face (:data:`FACE_PART`)
    """

    rows: np.ndarray
    cols: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    photo: np.ndarray
    skin: np.ndarray
    rim: np.ndarray
    face: np.ndarray


def skin_texels(
    parts: dict[str, object], size: int = ATLAS_SIZE, photo_parts: tuple[str, ...] = PHOTO_PARTS
) -> SkinTexels:
    """Rasterize the painted ``parts`` (IndexedFaceSet nodes by DEF name, already fitted) in
    texture space: texel centres inside a triangle's texture coordinates; those of
    ``photo_parts`` are the photo's to paint."""
    rows, cols, pts, nrm, photo, skin, rim, face = [], [], [], [], [], [], [], []
    for name in parts:
        tm = triangulate(parts[name])
        uv = tm.texcoords
        x = (uv[:, 0] * size - 0.5).astype(np.float32)
        y = ((1.0 - uv[:, 1]) * size - 0.5).astype(np.float32)
        tri = tm.faces
        tx, ty = x[tri], y[tri]  # (m, 3)
        x0 = np.ceil(tx.min(axis=1)).astype(np.int32)
        x1 = np.floor(tx.max(axis=1)).astype(np.int32)
        y0 = np.ceil(ty.min(axis=1)).astype(np.int32)
        y1 = np.floor(ty.max(axis=1)).astype(np.int32)
        wbox = np.maximum(x1 - x0 + 1, 0)
        count = wbox * np.maximum(y1 - y0 + 1, 0)
        t = np.repeat(np.arange(len(tri), dtype=np.int32), count)
        k = np.arange(count.sum(), dtype=np.int32) - np.repeat(np.cumsum(count) - count, count)
        down, across = np.divmod(k, np.take(wbox, t))
        px = np.take(x0, t) + across
        py = np.take(y0, t) + down
        # barycentric coordinates of the texel centre in its triangle's texture coordinates
        ax, bx, cx = (np.take(corner, t) for corner in tx.T)
        ay, by, cy = (np.take(corner, t) for corner in ty.T)
        e1x, e1y = bx - ax, by - ay
        e2x, e2y = cx - ax, cy - ay
        det = e1x * e2y - e1y * e2x
        ok = np.abs(det) > 1e-9
        det = np.where(ok, det, np.float32(1.0))
        qx, qy = px - ax, py - ay
        b1 = (qx * e2y - qy * e2x) / det
        b2 = (e1x * qy - e1y * qx) / det
        b0 = 1 - b1 - b2
        inside = ok & (b0 >= -1e-6) & (b1 >= -1e-6) & (b2 >= -1e-6)
        lam = np.stack([b0[inside], b1[inside], b2[inside]], axis=1).astype(np.float64)
        t = t[inside]
        corners = np.take(tri, t, axis=0)
        p = np.einsum("ij,ijk->ik", lam, np.take(tm.positions, corners, axis=0))
        n = np.einsum("ij,ijk->ik", lam, np.take(tm.normals, corners, axis=0))
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        rows.append(py[inside])
        cols.append(px[inside] % size)  # the chart repeats across the back seam
        pts.append(p)
        nrm.append(n)
        photo.append(np.full(len(p), name in photo_parts))
        skin.append(np.full(len(p), name in SKIN_PARTS))
        rim.append(np.full(len(p), name in RIM_PARTS))
        face.append(np.full(len(p), name == FACE_PART))
    parts_of = (rows, cols, pts, nrm, photo, skin, rim, face)
    return SkinTexels(*(np.concatenate(a) for a in parts_of))


def depth_map(numbers: np.ndarray, sets, camera: Camera, world: np.ndarray) -> np.ndarray:
    """Distance from the camera ``(H, W)`` (model units, inf where nothing is drawn) of the
    surface each pixel shows, from the renderer's triangle numbers. ``sets`` is the renderer's
    ``triangle_sets``; ``world`` places the model in the renderer's world."""
    h, w = numbers.shape
    out = np.full((h, w), np.inf)
    rows, cols = np.nonzero(numbers >= 0)
    num = numbers[rows, cols]
    pixels = np.stack([cols + 0.5, rows + 0.5], axis=1)
    for node, first, count in sets:
        sel = (num >= first) & (num < first + count)
        if not sel.any():
            continue
        tm = triangulate(node)
        corners = tm.positions[tm.faces[num[sel] - first]]
        corners = corners @ world[:3, :3].T + world[:3, 3]
        _, cam_pts = ray_barycentrics(pixels[sel], camera, corners)
        out[rows[sel], cols[sel]] = np.linalg.norm(cam_pts, axis=1)
    return out


def sample(image: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Bilinear samples ``(N, C)`` of ``image (H, W, C)`` at pixel coordinates ``xy (N, 2)``
    (pixel centres at +0.5), clamped to the border."""
    return Taps.at(image.shape[:2], xy)(image)


@dataclass
class Taps:
    """Where :func:`sample` reads an image of ``size`` (H, W) at ``N`` points, for images of
    that size sampled at the same points again: the four pixels around each point, as flat
    indices ``(N,)`` into the image's ``H·W`` pixels (``i01`` is ``i00``'s right neighbour,
    ``i10`` the one below), and the bilinear weights ``(N, 1)`` float32 (``gx = 1 − fx``,
    ``gy = 1 − fy``)."""

    size: tuple[int, int]
    i00: np.ndarray
    i01: np.ndarray
    i10: np.ndarray
    i11: np.ndarray
    fx: np.ndarray
    fy: np.ndarray
    gx: np.ndarray
    gy: np.ndarray

    @classmethod
    def at(cls, size: tuple[int, int], xy: np.ndarray) -> Taps:
        """The taps of an image of ``size`` (H, W) at pixel coordinates ``xy (N, 2)``."""
        h, w = size
        x = np.clip(xy[:, 0] - 0.5, 0, w - 1)
        y = np.clip(xy[:, 1] - 0.5, 0, h - 1)
        x0 = np.minimum(x.astype(np.int64), w - 2 if w > 1 else 0)
        y0 = np.minimum(y.astype(np.int64), h - 2 if h > 1 else 0)
        fx, fy = (x - x0)[:, None].astype(np.float32), (y - y0)[:, None].astype(np.float32)
        x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
        corners = (y0 * w + x0, y0 * w + x1, y1 * w + x0, y1 * w + x1)
        return cls((h, w), *corners, fx, fy, 1 - fx, 1 - fy)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """The samples ``(N, C)`` of ``image (H, W, C)``."""
        if image.shape[:2] != self.size:
            raise ValueError(f"taps of a {self.size} image, got {image.shape[:2]}")
        img = image.astype(np.float32, copy=False).reshape(-1, image.shape[2])
        return (
            np.take(img, self.i00, axis=0) * self.gx * self.gy
            + np.take(img, self.i01, axis=0) * self.fx * self.gy
            + np.take(img, self.i10, axis=0) * self.gx * self.fy
            + np.take(img, self.i11, axis=0) * self.fx * self.fy
        )

    def select(self, keep: np.ndarray) -> Taps:
        """The taps of the points ``keep`` selects (a mask or indices)."""
        arrays = (self.i00, self.i01, self.i10, self.i11, self.fx, self.fy, self.gx, self.gy)
        return Taps(self.size, *(a[keep] for a in arrays))


def pull_push(color: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Fill ``color (H, W, C)`` where ``weight (H, W)`` (0–1) is low by pull-push: weighted
    averages down a pyramid, then back up, each level filling what the finer one lacks."""
    return PullPush(weight).fill(color)


class PullPush:
    """:func:`pull_push` with one ``weight (H, W)`` (0–1) for several colours: the weights'
    pyramid is built once."""

    def __init__(self, weight: np.ndarray) -> None:
        w = weight.astype(np.float32)
        self._first = w[..., None]
        # per coarser level: what its summed colour is scaled by; per finer level: 1 − weight
        self._scales: list[np.ndarray] = []
        self._rest: list[np.ndarray] = []
        while min(w.shape) > 1:
            h2, w2 = (w.shape[0] + 1) // 2, (w.shape[1] + 1) // 2
            wp = np.zeros((h2 * 2, w2 * 2), np.float32)
            wp[: w.shape[0], : w.shape[1]] = w
            ws = wp.reshape(h2, 2, w2, 2).sum(axis=(1, 3))
            # a coarse texel is as sure as its surest child (clipped sum), its colour their mean
            scale = np.minimum(ws, 1.0) / np.maximum(ws, 1e-12)
            self._rest.append((1 - w)[..., None])
            self._scales.append(scale[..., None])
            w = np.minimum(ws, 1.0)
        self._last = np.maximum(w, 1e-12)[..., None]

    def fill(self, color: np.ndarray) -> np.ndarray:
        """``color (H, W, C)`` filled where the weight is low (float32)."""
        c = color.astype(np.float32) * self._first
        levels = [c]
        for scale in self._scales:
            h2, w2 = (c.shape[0] + 1) // 2, (c.shape[1] + 1) // 2
            cp = np.zeros((h2 * 2, w2 * 2, c.shape[2]), np.float32)
            cp[: c.shape[0], : c.shape[1]] = c
            c = cp.reshape(h2, 2, w2, 2, -1).sum(axis=(1, 3)) * scale
            levels.append(c)
        filled = levels[-1] / self._last
        for c, rest in zip(reversed(levels[:-1]), reversed(self._rest), strict=True):
            # bilinear, not blocky: the fill is as smooth as the pyramid allows
            up = _upsample2(_upsample2(filled, 0), 1)
            filled = c + rest * up[: c.shape[0], : c.shape[1]]
        return filled


def _upsample2(a: np.ndarray, axis: int) -> np.ndarray:
    """``a`` twice as long along ``axis``, bilinear with pixel edges aligned (each new sample
    is 3/4 of its parent and 1/4 of the parent's neighbour on its side; the ends clamp)."""
    a = np.moveaxis(a, axis, 0)
    prev = np.concatenate([a[:1], a[:-1]])
    nxt = np.concatenate([a[1:], a[-1:]])
    out = np.empty((2 * a.shape[0], *a.shape[1:]), a.dtype)
    out[0::2] = 0.75 * a + 0.25 * prev
    out[1::2] = 0.75 * a + 0.25 * nxt
    return np.moveaxis(out, 0, axis)


def grazing_weight(cosine: np.ndarray, grazing: tuple[float, float] = GRAZING) -> np.ndarray:
    lo, hi = grazing
    t = np.clip((cosine - lo) / (hi - lo), 0, 1)
    return t * t * (3 - 2 * t)


@dataclass
class Projection:
    """Where the photo sees the skin: the texels it sees, their photo pixels and weights, and
    the renderer's shading there (see :func:`project_skin`).

    texels  the :class:`SkinTexels`
    index   ``(K,)`` the texels the photo sees
    xy      ``(K, 2)`` their photo pixels
    weight  ``(K,)`` how much each trusts the photo (0–1, falling towards grazing views)
    gain, offset  ``(K, 3)`` the renderer's shading there (pixel^2.2 = gain · T + offset)
    taps    the :class:`Taps` of ``xy`` in the photo (None: worked out when needed)
    """

    texels: SkinTexels
    index: np.ndarray
    xy: np.ndarray
    weight: np.ndarray
    gain: np.ndarray
    offset: np.ndarray
    taps: Taps | None = None


def project_skin(
    texels: SkinTexels,
    camera: Camera,
    size: tuple[int, int],
    depth: np.ndarray,
    gain: np.ndarray,
    offset: np.ndarray,
    trust: np.ndarray | None = None,
    skin_trust: np.ndarray | None = None,
    beyond: np.ndarray | None = None,
) -> Projection:
    """Which skin texels a photo of ``size`` (W, H) taken by ``camera`` (in the model's frame)
    sees: in the picture, facing the camera, and what the pixel shows (``depth``: the distance
    of what each pixel shows, :func:`depth_map`). ``gain`` and ``offset`` ``(H, W, 3)`` are the
    renderer's shading at the photo's view (see the module docstring). ``trust (H, W)`` (0–1,
    optional) weighs what each pixel may give the texture: the person's probability, so that
    the background never becomes hair or neck; ``skin_trust (H, W)`` the same for the skin
    parts' texels alone: 0 on the photo's open mouth and eyes
    (:func:`vtts.fit.expression.skin_trust`). ``beyond (H, W)`` (0–1, optional) is 1 where
    the photo shows no face (:func:`vtts.fit.expression.beyond_face`): a face texel seen there
    trusts the photo up to the outline (:data:`RIM_GRAZING`), as the hair does — at a grazing
    view the mirrored texel of the other side would draw skin where the photo shows hair."""
    w, h = size
    if not texels.photo.all():
        texels = _select(texels, texels.photo)
    xy = camera.project(texels.points)
    inside = (xy[:, 0] >= 0) & (xy[:, 0] < w) & (xy[:, 1] >= 0) & (xy[:, 1] < h)
    ray = texels.points - camera.pose[:3, 3]
    dist = np.linalg.norm(ray, axis=1)
    cosine = -np.einsum("ij,ij->i", texels.normals, ray) / dist
    col = np.clip(xy[:, 0].astype(np.int64), 0, w - 1)
    row = np.clip(xy[:, 1].astype(np.int64), 0, h - 1)
    # half a pixel's footprint across the surface, in depth: a grazing surface's texels lie
    # deeper than the depth the pixel's centre shows
    slope = np.sqrt(np.maximum(1 - cosine**2, 0.0)) / np.maximum(cosine, 1e-3)
    tolerance = DEPTH_TOLERANCE + np.minimum(0.5 * dist / camera.fx * slope, GRAZING_DEPTH)
    seen = inside & texels.photo & (cosine > 0) & (dist <= depth[row, col] + tolerance)
    idx = np.flatnonzero(seen)
    taps = Taps.at((h, w), xy[idx])
    a = taps(gain)
    cos = cosine[idx]
    rim = texels.rim[idx].astype(np.float64)
    if beyond is not None:
        rim = np.where(texels.face[idx], taps(beyond[..., None])[:, 0], rim)
    graze = rim * grazing_weight(cos, RIM_GRAZING) + (1 - rim) * grazing_weight(cos)
    weight = np.where(a.min(axis=1) > 0.02, graze, 0.0)
    if trust is not None:
        weight = weight * taps(trust[..., None])[:, 0]
    if skin_trust is not None:
        on_skin = texels.skin[idx]
        weight = np.where(on_skin, weight * taps(skin_trust[..., None])[:, 0], weight)
    keep = weight > 0
    idx, a, taps = idx[keep], a[keep], taps.select(keep)
    return Projection(texels, idx, xy[idx], weight[keep], a, taps(offset), taps)


def skin_exposure(proj: Projection, target: np.ndarray, quantile: float = EXPOSURE_QUANTILE,
                  limit: float = MAX_EXPOSURE) -> np.ndarray:  # fmt: skip
    """``(3,)`` how much brighter (a factor per RGB channel, 1 to ``limit``) the skin must be
    lit than the renderer lights it for a texture of at most 1 to give ``target (H, W, 3)``
    (the photo, linear light) on all but the brightest ``1 − quantile`` of the seen skin texels
    of ``proj`` (those of :data:`SKIN_PARTS` the photo trusts at least
    :data:`EXPOSURE_WEIGHT`): per channel, the ``quantile`` of the texture they ask for,
    ``(target − offset) / gain``. 1 where the photo's light never outshines the renderer's —
    per channel, since a channel lit more than it needs loses the texture's precision (8 bits):
    a warm skin's red clips first."""
    keep = proj.texels.skin[proj.index] & (proj.weight >= EXPOSURE_WEIGHT)
    if not keep.any():
        return np.ones(3)
    taps = proj.taps if proj.taps is not None else Taps.at(target.shape[:2], proj.xy)
    want = (taps.select(keep)(target) - proj.offset[keep]) / np.maximum(proj.gain[keep], 1e-6)
    return np.clip(np.quantile(want, quantile, axis=0), 1.0, limit)


def _select(texels: SkinTexels, keep: np.ndarray) -> SkinTexels:
    return SkinTexels(*(getattr(texels, f)[keep] for f in texels.__dataclass_fields__))


def paint_skin(
    atlas: np.ndarray, proj: Projection, target: np.ndarray, *, fill: bool = True
) -> tuple[np.ndarray, float]:
    """Paint the skin chart of ``atlas`` (``(S, S, 3)`` float 0–1, changed in place) so that the
    head rendered at the photo's view shows ``target (H, W, 3)`` (linear light: the photo's
    pixels ** 2.2). With ``fill``, what the photo does not see is filled (mirror, then pull-push);
    without, it keeps the atlas's colours. Returns the atlas and the fraction of skin texels the
    photo saw. (:class:`SkinPainter` paints one projection again and again.)"""
    return SkinPainter(proj, atlas.shape[0]).paint(atlas, target, fill=fill)


class SkinPainter:
    """:func:`paint_skin` for one :class:`Projection` into atlases of ``size`` texels, for
    several targets (``adi fit`` paints in passes): what does not change with the target — which
    texels are painted and how far they are trusted, the tiles' reach, the fill's weights — is
    worked out once."""

    def __init__(self, proj: Projection, size: int) -> None:
        self.proj, self.size = proj, size
        tx = proj.texels
        rows, cols = tx.rows[proj.index], tx.cols[proj.index]
        self.r0 = int(round((1 - SKIN_TILE[3]) * size))
        self.r1 = r1 = int(round((1 - SKIN_TILE[1]) * size))
        skin_rows = tx.rows[tx.rows < r1]
        seen_rows = rows[rows < r1]
        self.seen = float(len(seen_rows) / max(len(skin_rows), 1))
        self.taps = proj.taps  # None: taken from the first target's size
        self.gain = np.maximum(proj.gain, 1e-6)
        self.tile = tile = rows >= r1
        self.tile_at = (rows[tile] - r1, cols[tile])
        self.skin_at = (rows[~tile], cols[~tile])
        self.weight = proj.weight[~tile]
        if tile.any():
            trust = np.zeros((size - r1, size), np.float32)
            trust[self.tile_at] = proj.weight[tile]
            reach = np.clip(1 - ndimage.distance_transform_edt(trust == 0) / TILE_REACH, 0, 1)
            near = reach * (trust == 0) + trust
            self.near, self.far = near[..., None], (1 - near[..., None])
            self.tile_fill = PullPush(trust)

    def paint(
        self,
        atlas: np.ndarray,
        target: np.ndarray,
        *,
        fill: bool = True,
        tiles: bool = True,
        skin: bool = True,
    ) -> tuple[np.ndarray, float]:
        """:func:`paint_skin` of ``target`` into ``atlas``; without ``tiles`` the skin chart
        alone (the eye, teeth and tongue tiles keep the atlas's colours), without ``skin`` the
        tiles alone (the skin chart keeps the atlas's: one painted before from the same
        target)."""
        size, r1 = self.size, self.r1
        if self.taps is None:
            self.taps = Taps.at(target.shape[:2], self.proj.xy)
        lin = (self.taps(target) - self.proj.offset) / self.gain
        colour = linear_to_srgb(lin)
        # tiles (eyes, teeth, tongue): the photo over the generic tile, as far as it is trusted,
        # and carried a few texels beyond what it saw: the renderer's texture filtering reaches
        # that far, and the generic white around a small painted eye would brighten it
        if tiles and self.tile.any():
            band = slice(r1, size)
            paint = np.zeros((size - r1, size, 3), np.float32)
            paint[self.tile_at] = colour[self.tile]
            filled = self.tile_fill.fill(paint)
            atlas[band] = self.near * filled + self.far * atlas[band]
        if not skin:
            return atlas, self.seen
        colour = colour[~self.tile]
        if not fill:
            atlas[self.skin_at] = colour
            return atlas, self.seen
        fill_at, own, other, total, skin_fill = self._fill
        # the other side of the face where this side was not seen
        skin = np.zeros((self.r1 - self.r0, size, 3), np.float32)
        skin[fill_at] = colour[self._in_band]
        mirror_skin = skin[:, ::-1]
        atlas[self.r0 : r1] = skin_fill.fill((skin * own + mirror_skin * other) / total)
        return atlas, self.seen

    @functools.cached_property
    def _in_band(self) -> np.ndarray:
        """``(K',)`` bool: the skin texels of the rows the fill paints."""
        return self.skin_at[0] >= self.r0

    @functools.cached_property
    def _fill(self) -> tuple:
        """What the fill of the skin chart's rows (``r0``–``r1``) takes from the weights: where
        the seen texels go in those rows, their own weight and the mirrored texels' (``(R, S,
        1)``), the sum of the two (at least 1e-12), and the pull-push of that sum."""
        rows, cols = self.skin_at
        inside = self._in_band
        at = (rows[inside] - self.r0, cols[inside])
        wmap = np.zeros((self.r1 - self.r0, self.size), np.float32)
        wmap[at] = self.weight[inside]
        mirror_w = wmap[:, ::-1]
        total = wmap + (1 - wmap) * mirror_w
        other = ((1 - wmap) * mirror_w)[..., None]
        return at, wmap[..., None], other, np.maximum(total, 1e-12)[..., None], PullPush(total)


def iris_colour(
    photo: np.ndarray, gain: np.ndarray, offset: np.ndarray, contour: np.ndarray
) -> np.ndarray | None:
    """The texture colour (sRGB 0–1, ``(3,)``) of the iris inside an eye's ``contour (k, 2)``
    (photo pixels): the median of the darker half of the pixels within it, unshaded as the skin
    is (``photo`` linear, ``gain`` and ``offset`` the renderer's shading). None when the eye is
    too small or closed."""
    from PIL import ImageDraw

    h, w = photo.shape[:2]
    mask_img = Image.new("L", (w, h), 0)
    ImageDraw.Draw(mask_img).polygon([tuple(p) for p in contour - 0.5], fill=1)
    rows, cols = np.nonzero(np.asarray(mask_img))
    if len(rows) < 6:
        return None
    lin = (photo[rows, cols] - offset[rows, cols]) / np.maximum(gain[rows, cols], 1e-3)
    lum = lin @ np.array([0.2126, 0.7152, 0.0722])
    dark = lin[lum <= np.median(lum)]
    return linear_to_srgb(np.median(dark, axis=0))


def tint_eye(atlas: np.ndarray, iris_colour: np.ndarray, tile) -> None:
    """Recolour the iris of an eye tile ``tile`` (u0, v0, u1, v1) of ``atlas (S, S, 3)`` (the
    bundled heads' eye: a saturated ring between a dark pupil and the white) to ``iris_colour
    (3,)``, keeping its pattern's light and dark."""
    size = atlas.shape[0]
    u0, v0, u1, v1 = tile
    r0, r1 = int(round((1 - v1) * size)), int(round((1 - v0) * size))
    c0, c1 = int(round(u0 * size)), int(round(u1 * size))
    tile = atlas[r0:r1, c0:c1]
    n = tile.shape[0]
    yy, xx = np.mgrid[0:n, 0:n]
    near = np.hypot(yy - (n - 1) / 2, xx - (n - 1) / 2) < 0.2 * n
    mx, mn = tile.max(axis=2), tile.min(axis=2)
    iris = near & (mx > 0.12) & ((mx - mn) / np.maximum(mx, 1e-6) > 0.2)
    lum = tile @ np.array([0.2126, 0.7152, 0.0722])
    if iris.any():
        rel = lum[iris] / max(float(lum[iris].mean()), 1e-6)
        tile[iris] = np.clip(iris_colour[None, :] * rel[:, None], 0, 1)
    # the white keeps the generic colour: in a photo the lids' skin and shadow crowd it


def split_eye_tiles(atlas: np.ndarray, scene) -> None:
    """Give each eyeball a tile of its own (:data:`EYE_TILES`): the generic eye tile, halved,
    copied into both, and the eyeballs' texture coordinates moved there (in ``scene``)."""
    split_tile(atlas, scene, EYE_TILE, EYE_TILES)


def split_ear_tiles(atlas: np.ndarray, scene) -> None:
    """Give each ear a tile of its own (:data:`EAR_TILES`), as :func:`split_eye_tiles` does for
    the eyes: the bundled heads' ears share one tile, which a picture can paint for one ear
    only."""
    split_tile(atlas, scene, EAR_TILE, EAR_TILES)


def split_tile(atlas: np.ndarray, scene, shared, tiles: dict) -> None:
    """Copy the tile ``shared`` (u0, v0, u1, v1) of ``atlas (S, S, 3)``, halved, into each of
    ``tiles`` (part name → its tile, half the size of ``shared``) and move each part's texture
    coordinates (in ``scene``) from ``shared`` to its own tile."""
    size = atlas.shape[0]
    u0, v0, u1, v1 = shared
    r0, r1 = int(round((1 - v1) * size)), int(round((1 - v0) * size))
    c0, c1 = int(round(u0 * size)), int(round(u1 * size))
    tile = Image.fromarray((np.clip(atlas[r0:r1, c0:c1], 0, 1) * 255).astype(np.uint8))
    half = (
        np.asarray(
            tile.resize(((c1 - c0) // 2, (r1 - r0) // 2), Image.Resampling.LANCZOS), np.float64
        )
        / 255.0
    )
    for name, (a0, b0, a1, b1) in tiles.items():
        rr0, cc0 = int(round((1 - b1) * size)), int(round(a0 * size))
        atlas[rr0 : rr0 + half.shape[0], cc0 : cc0 + half.shape[1]] = half
        if name not in scene.defs:
            continue
        coord = scene.node(name).expand()["texCoord"].expand()
        uv = np.asarray(coord["point"], dtype=np.float64)
        coord.fields["point"] = np.c_[
            a0 + (uv[:, 0] - u0) / (u1 - u0) * (a1 - a0),
            b0 + (uv[:, 1] - v0) / (v1 - v0) * (b1 - b0),
        ]


def rechart_skin(scene) -> None:
    """Give the skin parts (:data:`SKIN_PARTS` in ``scene``) a chart without the bundled
    heads' infinitely steep middle: u = 0.5 ± s(|θ|/π) / 2 with s(t) = t (2 − t) (twice the
    texels of an even unwrap at the front, none squeezed at the midline).

    The bundled chart's slope at the midline is infinite (|θ|^0.6): fine for a smooth painted
    skin, but the renderer's mip level follows the steepest direction, so a photo texture shows
    a blurred streak down the middle of the face. Same v, same seams, same mirror symmetry."""
    for name in SKIN_PARTS:
        if name not in scene.defs:
            continue
        coord = scene.node(name).expand()["texCoord"]
        if coord is None:
            continue
        coord = coord.expand()
        uv = np.asarray(coord["point"], dtype=np.float64).copy()
        wrap = np.floor(uv[:, 0])  # copies past the back seam carry u + 1
        u = (uv[:, 0] - wrap - INSET) / (1 - 2 * INSET)
        t = np.clip(np.abs(2 * u - 1), 0, 1) ** (1 / GAMMA)  # |θ| / π
        new = 0.5 + 0.5 * np.sign(u - 0.5) * t * (2 - t)
        uv[:, 0] = wrap + INSET + new * (1 - 2 * INSET)
        coord.fields["point"] = uv


def tint_tile(atlas: np.ndarray, tile, gain: np.ndarray) -> None:
    """Multiply the texels of ``tile`` (u0, v0, u1, v1) of ``atlas (S, S, 3)`` by ``gain (3,)``."""
    size = atlas.shape[0]
    u0, v0, u1, v1 = tile
    r0, r1 = int(round((1 - v1) * size)), int(round((1 - v0) * size))
    c0, c1 = int(round(u0 * size)), int(round(u1 * size))
    atlas[r0:r1, c0:c1] = np.clip(atlas[r0:r1, c0:c1] * gain, 0, 1)


def upscale(image: Image.Image, size: int = ATLAS_SIZE) -> np.ndarray:
    """``image`` as ``(size, size, 3)`` float 0–1 (Lanczos)."""
    img = image.convert("RGB")
    if img.size != (size, size):
        img = img.resize((size, size), Image.Resampling.LANCZOS)
    return np.asarray(img, dtype=np.float64) / 255.0
