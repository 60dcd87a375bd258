"""The bundled heads' texture maps, painted procedurally (numpy + Pillow), seeded.

One atlas per head (``models/NAME-face.png``, 512 × 512):

- the top three quarters: the skin of face, back of the head and neck, unwrapped around the
  skull's vertical axis (:func:`skin_chart`), with the features painted where the head's own
  geometry puts them — brows, lips, lids and lashes, cheeks, nostrils, the hair;
- the bottom row, four tiles: the eye (sclera, iris with radial fibres, pupil, by an azimuthal
  projection around the pupil), the teeth and gums, the tongue, the ear.

Skin and hair carry low-frequency colour variation and fine grain: the Eisert–Girod analysis
estimates motion from optical flow and needs texture to see it.
"""

from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw, ImageFilter

from vtts.face.atlas import (  # noqa: F401 - the layout, shared with adi fit
    EAR_TILE,
    EYE_TILE,
    GAMMA,
    INSET,
    SIZE,
    SKIN_TILE,
    TEETH_TILE,
    TONGUE_TILE,
)

#: The eye tile's radius grows as (angle from the pupil / π) ** EYE_POWER: more texels for the iris.
EYE_POWER = 0.6


def tile_uv(tile, uv: np.ndarray) -> np.ndarray:
    """Map ``uv (n, 2)`` in [0, 1]² into ``tile`` of the atlas (kept ``INSET`` from its edges)."""
    u0, v0, u1, v1 = tile
    uv = np.clip(np.asarray(uv, dtype=np.float64), 0, 1)
    return np.c_[
        u0 + INSET + uv[:, 0] * (u1 - u0 - 2 * INSET),
        v0 + INSET + uv[:, 1] * (v1 - v0 - 2 * INSET),
    ]


def skin_chart(points: np.ndarray, axis_z: float, y_range: tuple[float, float]) -> np.ndarray:
    """Texture coordinates ``(n, 2)`` of skin points: the angle about the vertical axis through
    ``(0, *, axis_z)`` (front = 0.5, the back seam at 0 and 1, more texels for the face) and
    the height."""
    theta = np.arctan2(points[:, 0], points[:, 2] - axis_z)
    u = 0.5 + 0.5 * np.sign(theta) * (np.abs(theta) / np.pi) ** GAMMA
    v = (points[:, 1] - y_range[0]) / (y_range[1] - y_range[0])
    return tile_uv(SKIN_TILE, np.c_[u, v])


def seam_split(uv: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Texture coordinates and texCoordIndex for triangles that cross the back seam: their
    corners on the left of the seam get a copy with u + 1 (the texture repeats)."""
    u = uv[faces, 0]
    crossing = (u.max(axis=1) - u.min(axis=1)) > 0.5
    tex_faces = faces.copy()
    extra = []
    lookup: dict[int, int] = {}
    for t in np.flatnonzero(crossing):
        for k in range(3):
            v = faces[t, k]
            if uv[v, 0] < 0.5:
                if v not in lookup:
                    lookup[v] = len(uv) + len(extra)
                    extra.append((uv[v, 0] + 1.0, uv[v, 1]))
                tex_faces[t, k] = lookup[v]
    if extra:
        uv = np.vstack([uv, np.array(extra)])
    return uv, tex_faces


# ---- painting helpers -------------------------------------------------------------------------


def _noise(rng: np.random.Generator, h: int, w: int, cell: float) -> np.ndarray:
    """Smooth value noise ``(h, w)`` in about [-1, 1] with features ``cell`` pixels apart."""
    gh, gw = int(np.ceil(h / cell)) + 3, int(np.ceil(w / cell)) + 3
    grid = rng.uniform(-1, 1, (gh, gw)).astype(np.float32)
    big = Image.fromarray(grid, mode="F").resize(
        (int(gw * cell), int(gh * cell)), Image.Resampling.BICUBIC
    )
    a = np.asarray(big)
    o = int(cell)
    return a[o : o + h, o : o + w].astype(np.float64)


def _fbm(rng, h, w, cells, weights) -> np.ndarray:
    return sum(wt * _noise(rng, h, w, c) for c, wt in zip(cells, weights, strict=True))


def _mask(h: int, w: int, draw_fn, blur: float) -> np.ndarray:
    """A soft mask (h, w) in [0, 1] drawn by ``draw_fn(ImageDraw)`` and blurred."""
    im = Image.new("L", (w, h), 0)
    draw_fn(ImageDraw.Draw(im))
    if blur > 0:
        im = im.filter(ImageFilter.GaussianBlur(blur))
    return np.asarray(im, dtype=np.float64) / 255.0


def _blend(img: np.ndarray, color, mask: np.ndarray) -> None:
    img[:] = img * (1 - mask[..., None]) + np.asarray(color, dtype=np.float64) * mask[..., None]


def _smooth_curve(pts: np.ndarray, n: int = 12, closed: bool = False) -> np.ndarray:
    """Catmull–Rom through ``pts (k, 2)``, ``n`` samples per segment."""
    p = np.asarray(pts, dtype=np.float64)
    if closed:
        p = np.vstack([p[-1], p, p[0], p[1]])
    else:
        p = np.vstack([2 * p[0] - p[1], p, 2 * p[-1] - p[-2]])
    out = []
    t = np.linspace(0, 1, n, endpoint=False)[:, None]
    for i in range(1, len(p) - 2):
        p0, p1, p2, p3 = p[i - 1], p[i], p[i + 1], p[i + 2]
        out.append(
            0.5
            * (
                2 * p1
                + (-p0 + p2) * t
                + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t**2
                + (-p0 + 3 * p1 - 3 * p2 + p3) * t**3
            )
        )
    out.append(p[-2][None])
    return np.vstack(out)


# ---- the atlas ----------------------------------------------------------------------------


def paint_atlas(head) -> Image.Image:
    """The head's texture atlas (RGB, ``SIZE`` × ``SIZE``)."""
    look = head.person.look
    rng = np.random.default_rng(look.seed)
    img = np.zeros((SIZE, SIZE, 3))
    _paint_skin(head, look, rng, img)
    _paint_eye(head.person, look, rng, img)
    _paint_teeth(look, rng, img)
    _paint_tongue(look, rng, img)
    _paint_ear(look, rng, img)
    return Image.fromarray(np.clip(np.round(img), 0, 255).astype(np.uint8), mode="RGB")


def _px(uv: np.ndarray) -> np.ndarray:
    """Atlas uv → pixel coordinates (x right, y down)."""
    uv = np.atleast_2d(uv)
    return np.c_[uv[:, 0] * SIZE, (1 - uv[:, 1]) * SIZE]


def _region(tile) -> tuple[slice, slice]:
    u0, v0, u1, v1 = tile
    return slice(int(round((1 - v1) * SIZE)), int(round((1 - v0) * SIZE))), slice(
        int(round(u0 * SIZE)), int(round(u1 * SIZE))
    )


def _paint_skin(head, look, rng, img) -> None:
    h, w = SIZE, SIZE
    skin = np.asarray(look.skin, dtype=np.float64)
    # low-frequency mottling and fine grain (pores)
    low = _fbm(rng, h, w, (64, 24), (1.0, 0.5))
    grain = _fbm(rng, h, w, (2, 1.0), (0.6, 0.4))
    base = skin[None, None] * (1 + 0.05 * low[..., None]) + 11 * grain[..., None]
    base += np.array([6.0, -2.0, -3.0]) * _noise(rng, h, w, 40)[..., None]
    img[:] = base
    _shade_hollows(head, look, img)

    uv = head.skin_uv

    def fp(v):  # pixel position of Candide vertex v on the refined face
        return _px(uv["FACE"][head.candide_index[v]])[0]

    def curve(vs, n=10, closed=False):
        return _smooth_curve(np.array([fp(v) for v in vs]), n, closed)

    # cheeks: a soft blush
    for c in (27, 60):
        x, y = fp(c)
        r = 0.045 * SIZE
        box = [x - r, y - r * 0.8, x + r, y + r]
        m = _mask(h, w, lambda d, box=box: d.ellipse(box), r * 0.7)
        _blend(img, np.asarray(look.blush), m * 0.35)
    # nose tip a little warmer, nostrils dark
    x, y = fp(5)
    m = _mask(h, w, lambda d: d.ellipse([x - 9, y - 8, x + 9, y + 8]), 6)
    _blend(img, np.asarray(look.blush), m * 0.25)
    for a, b in ((75, 111), (76, 112)):
        pa, pb = fp(a), fp(b)
        c = 0.45 * pa + 0.55 * pb
        m = _mask(h, w, lambda d, c=c: d.ellipse([c[0] - 5, c[1] - 2.5, c[0] + 5, c[1] + 3]), 1.5)
        _blend(img, np.asarray(look.skin) * 0.35, m * 0.8)
    # upper lids a little darker, a crease line, lashes along the lid's edge
    for up, crease in (
        ((20, 97, 21, 105, 23), (20, 95, 19, 103, 23)),
        ((53, 98, 54, 106, 56), (53, 96, 52, 104, 56)),
    ):
        lid = curve(up)
        top = curve(crease)
        poly = np.vstack([lid, top[::-1]])
        m = _mask(h, w, lambda d, poly=poly: d.polygon([tuple(p) for p in poly], fill=255), 5)
        _blend(img, np.asarray(look.lid), m * 0.45)
        m = _mask(h, w, lambda d, top=top: d.line([tuple(p) for p in top], fill=255, width=2), 1.2)
        _blend(img, np.asarray(look.skin) * 0.7, m * 0.5)
        m = _mask(h, w, lambda d, lid=lid: d.line([tuple(p) for p in lid], fill=255, width=3), 0.7)
        _blend(img, np.asarray(look.lash), m * 0.95)
    for lo in ((20, 99, 22, 107, 23), (53, 100, 55, 108, 56)):
        low_lid = curve(lo)
        m = _mask(h, w, lambda d, c=low_lid: d.line([tuple(p) for p in c], fill=255, width=3), 1)
        _blend(img, np.asarray(look.lash) * 0.6 + np.asarray(look.skin) * 0.4, m * 0.6)
    # brows: many short hair strokes along the brow's band
    for band in ((17, 16, 15), (50, 49, 48)):
        upper = curve((band[0], band[1], band[2]))
        lower_vs = (band[0], 18 if band[0] == 17 else 51, band[2])
        lower = curve(lower_vs)
        _brow(img, rng, upper, lower, look)
    # lips: the outer contour, darker towards the mouth line
    outer = (31, 79, 33, 7, 66, 80, 64, 86, 8, 85)
    ring = curve(outer, 8, closed=True)
    m = _mask(h, w, lambda d: d.polygon([tuple(p) for p in ring], fill=255), 1.6)
    lip_col = np.asarray(look.lips) * (1 + 0.06 * _noise(rng, h, w, 6))[..., None]
    img[:] = img * (1 - m[..., None]) + lip_col * m[..., None]
    line = curve((31, 88, 81, 87, 82, 89, 64), 8)
    m = _mask(h, w, lambda d: d.line([tuple(p) for p in line], fill=255, width=3), 1.5)
    _blend(img, np.asarray(look.lips) * 0.45, m * 0.8)
    # hair: above the hairline, strands running down and back
    _hair(head, look, rng, img)


def concavity(points: np.ndarray, faces: np.ndarray, iterations: int = 25) -> np.ndarray:
    """How far each vertex lies below its smoothed neighbourhood, along its normal (model
    units; positive in hollows): a cheap stand-in for ambient occlusion."""
    import scipy.sparse as sp

    n = len(points)
    i = faces[:, [0, 1, 2, 1, 2, 0]].ravel()
    j = faces[:, [1, 2, 0, 0, 1, 2]].ravel()
    adj = sp.csr_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    adj.data[:] = 1.0
    avg = sp.diags(1.0 / np.maximum(adj.sum(axis=1).A1, 1)) @ adj
    smooth_pts = points.copy()
    for _ in range(iterations):
        smooth_pts = 0.5 * smooth_pts + 0.5 * (avg @ smooth_pts)
    p = points[faces]
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    vn = np.zeros_like(points)
    for k in range(3):
        np.add.at(vn, faces[:, k], fn)
    vn /= np.linalg.norm(vn, axis=1, keepdims=True) + 1e-12
    return np.einsum("ij,ij->i", smooth_pts - points, vn)


def _blur(a: np.ndarray, radius: float) -> np.ndarray:
    """Gaussian blur of a float array (separable, numpy only: deterministic everywhere)."""
    r = int(np.ceil(3 * radius))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / radius) ** 2)
    k /= k.sum()
    a = np.pad(a, r, mode="edge")
    a = np.apply_along_axis(lambda v: np.convolve(v, k, mode="valid"), 0, a)
    return np.apply_along_axis(lambda v: np.convolve(v, k, mode="valid"), 1, a)


def _shade_hollows(head, look, img) -> None:
    """Darken the face's hollows (eye sockets, beside the nose, under the lip), as ambient
    occlusion would: the renderer has no shadows, and a frontal light flattens a face."""
    face = head.parts["FACE"]
    c = concavity(face.points, face.faces)
    dark = np.clip(c / 0.006, 0, 1) ** 0.8
    # splat the vertices' values into the chart and normalise (vertices lie 2–3 texels apart)
    px = _px(head.skin_uv["FACE"])
    rows, cols = _region(SKIN_TILE)
    h, w = rows.stop - rows.start, cols.stop - cols.start
    ix = np.clip(np.round(px[:, 0] - 0.5).astype(int) - cols.start, 0, w - 1)
    iy = np.clip(np.round(px[:, 1] - 0.5).astype(int) - rows.start, 0, h - 1)
    acc = np.zeros((h, w))
    wts = np.zeros((h, w))
    np.add.at(acc, (iy, ix), dark)
    np.add.at(wts, (iy, ix), 1.0)
    acc, wts = (_blur(a, 2.5) for a in (acc, wts))
    d = np.divide(acc, wts, out=np.zeros_like(acc), where=wts > 1e-3)
    shade = np.asarray(look.skin) * np.array([0.55, 0.42, 0.4])
    img[rows, cols] = img[rows, cols] * (1 - 0.45 * d[..., None]) + shade * 0.45 * d[..., None]


def _brow(img, rng, upper, lower, look) -> None:
    h, w = img.shape[:2]
    im = Image.new("L", (w, h), 0)
    d = ImageDraw.Draw(im)
    n = len(upper)
    for _ in range(260):
        t = rng.uniform(0.02, 0.98)
        k = t * (n - 1)
        i = int(k)
        f = k - i
        a = upper[i] * (1 - f) + upper[min(i + 1, n - 1)] * f
        b = lower[i] * (1 - f) + lower[min(i + 1, n - 1)] * f
        s = rng.uniform(0, 1)
        p = a * s + b * (1 - s)
        direction = upper[min(i + 1, n - 1)] - upper[max(i - 1, 0)]
        direction = direction / (np.linalg.norm(direction) + 1e-9)
        direction = direction + np.array([0, -0.35]) * (1 - t) + rng.normal(0, 0.15, 2)
        length = rng.uniform(3, 7) * (1.2 - 0.5 * t)
        q = p + direction * length
        d.line([tuple(p), tuple(q)], fill=int(rng.uniform(150, 255)), width=1)
    m = np.asarray(im.filter(ImageFilter.GaussianBlur(0.6)), dtype=np.float64) / 255.0
    _blend(img, np.asarray(look.brow), np.clip(m * 1.6, 0, 1) * 0.9)


def _hair(head, look, rng, img) -> None:
    h, w = img.shape[:2]
    rows, cols = _region(SKIN_TILE)
    # hair mask in the chart: the hairline as height over the angle about the skull's axis
    u = (np.arange(w) + 0.5) / w
    v_img = (np.arange(h) + 0.5) / h
    uu, vv = np.meshgrid(u, 1 - v_img)
    su = (uu - SKIN_TILE[0]) / (SKIN_TILE[2] - SKIN_TILE[0])
    sv = (vv - SKIN_TILE[1]) / (SKIN_TILE[3] - SKIN_TILE[1])
    x = (su - 0.5) * 2
    theta = np.sign(x) * np.abs(x) ** (1 / GAMMA) * np.pi
    y = head.skin_y_range[0] + sv * (head.skin_y_range[1] - head.skin_y_range[0])
    line = head.person.hairline(np.abs(theta), theta)
    edge = 0.04 + 0.025 * _noise(rng, h, w, 3)
    mask = np.clip((y - line) / edge + 0.5, 0, 1) * (vv > SKIN_TILE[1])
    # strands: noise stretched along the chart's vertical, plus broad light/dark locks
    strands = np.asarray(
        Image.fromarray(rng.uniform(-1, 1, (h // 16, w * 2)).astype(np.float32), mode="F").resize(
            (w, h), Image.Resampling.BICUBIC
        ),
        dtype=np.float64,
    )
    locks = _noise(rng, h, w, 28)
    shade = 1 + 0.22 * strands + 0.12 * locks
    col = np.asarray(look.hair)[None, None] * shade[..., None]
    img[:] = img * (1 - mask[..., None]) + col * mask[..., None]


def _paint_eye(person, look, rng, img) -> None:
    rows, cols = _region(EYE_TILE)
    n = rows.stop - rows.start
    yy, xx = np.mgrid[0:n, 0:n]
    ins = INSET * SIZE
    # the tile's uv in [0, 1]² (as tile_uv maps it) → distance from the pupil as an angle
    tu = (xx + 0.5 - ins) / (n - 2 * ins)
    tv = 1 - (yy + 0.5 - ins) / (n - 2 * ins)
    dx, dy = (tu - 0.5) * 2, (tv - 0.5) * 2
    alpha = np.hypot(dx, dy) ** (1 / EYE_POWER) * np.pi
    ang = np.arctan2(dy, dx)
    sclera = np.array([236.0, 232, 226]) * (1 - 0.04 * _noise(rng, n, n, 10))[..., None]
    veins = np.clip(_noise(rng, n, n, 3) * 3 - 2.2, 0, 1) * smooth(alpha, 1.0, 1.6)
    sclera = sclera * (1 - 0.35 * veins[..., None]) + np.array([200.0, 90, 90]) * (
        0.35 * veins[..., None]
    )
    iris_a, pupil_a = person.iris_angle, person.pupil_angle
    fibres = _noise(rng, 1, 64, 1.5)[0]
    fib = np.interp((ang + np.pi) / (2 * np.pi) * 63, np.arange(64), fibres)
    radial = (alpha - pupil_a) / (iris_a - pupil_a)
    iris = np.asarray(look.iris)[None, None] * (
        1 + 0.28 * fib[..., None] + 0.25 * (0.5 - radial)[..., None]
    )
    limbus = smooth(radial, 0.8, 1.0)
    iris = iris * (1 - 0.55 * limbus[..., None])
    out = np.where((alpha < iris_a)[..., None], iris, sclera)
    out = np.where((alpha < pupil_a)[..., None], np.array([12.0, 10, 10]), out)
    img[rows, cols] = out


def smooth(x, e0, e1):
    t = np.clip((x - e0) / (e1 - e0), 0, 1)
    return t * t * (3 - 2 * t)


def _paint_teeth(look, rng, img) -> None:
    rows, cols = _region(TEETH_TILE)
    n = rows.stop - rows.start
    yy, xx = np.mgrid[0:n, 0:n]
    u = (xx + 0.5) / n
    v = 1 - (yy + 0.5) / n
    # v: lower teeth in [0, 0.5], upper in [0.5, 1]; within each the cross-section runs from
    # the gum (front) over the edge to the gum (back)
    local = np.where(v < 0.5, v * 2, (v - 0.5) * 2)
    gum = (local < 0.2) | (local > 0.8)
    # tooth boundaries along the arch: incisors in the middle, narrower towards the back
    s = np.abs(u - 0.5) * 2
    edges = np.cumsum([0.0, 0.10, 0.08, 0.085, 0.09, 0.1, 0.12, 0.14, 0.3])
    k = np.searchsorted(edges, s)
    pos = (s - edges[np.clip(k - 1, 0, len(edges) - 1)]) / np.diff(edges)[
        np.clip(k - 1, 0, len(edges) - 2)
    ]
    gap = np.clip(1 - np.abs(pos - 0.5) * 2, 0, 1) ** 0.25
    tooth = np.asarray(look.teeth)[None, None] * (0.72 + 0.28 * gap[..., None])
    tooth = tooth * (1 + 0.03 * _noise(rng, n, n, 4))[..., None]
    out = np.where(gum[..., None], np.array([190.0, 95, 100]), tooth)
    img[rows, cols] = out


def _paint_tongue(look, rng, img) -> None:
    rows, cols = _region(TONGUE_TILE)
    n = rows.stop - rows.start
    yy, xx = np.mgrid[0:n, 0:n]
    u = (xx + 0.5) / n
    col = np.array([190.0, 85, 90]) * (1 + 0.08 * _fbm(rng, n, n, (6, 2), (0.6, 0.4)))[..., None]
    groove = np.exp(-(((u - 0.5) / 0.04) ** 2)) * 0.25
    img[rows, cols] = col * (1 - groove[..., None])


def _paint_ear(look, rng, img) -> None:
    rows, cols = _region(EAR_TILE)
    n = rows.stop - rows.start
    yy, xx = np.mgrid[0:n, 0:n]
    u = (xx + 0.5) / n - 0.5
    v = 0.5 - (yy + 0.5) / n
    r = np.hypot(u / 0.5, v / 0.5)
    skin = np.asarray(look.skin)[None, None] * (1 + 0.05 * _noise(rng, n, n, 8))[..., None]
    concha = smooth(r, 0.55, 0.3) * 0.35
    rim = np.exp(-(((r - 0.85) / 0.06) ** 2)) * 0.12
    img[rows, cols] = skin * (1 - concha[..., None] + rim[..., None])
