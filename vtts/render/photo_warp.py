"""A smooth 2-D warp of a photo that follows a head's projected motion (the talking photo's
hair, ears, neck and shoulders: :mod:`vtts.render.talking_photo`).

The head's vertices, projected into the photo at rest and in the current frame, are the handles: a
thin-plate spline through their displacements (``scipy.interpolate.RBFInterpolator``, with an affine
part, so a head that only moves, turns or nods in the picture carries the photo around it along
exactly) gives the displacement of every node of a coarse grid, and that displacement fades out with
the distance from the head (a smoothstep over :attr:`WarpOptions.reach` head sizes,
:attr:`WarpOptions.above` times that above the head), so that the picture far from the head stays as
it is. The photo is then resampled through the inverse of that map (found by fixed-point iteration
on the grid, then bilinear within the grid's cells), so every output pixel takes one place of the
photo: the map is continuous, and no gap opens (no tear).

Fold-free: the forward map ``x ↦ x + d(x)`` stays one-to-one while its Jacobian determinant
stays positive; the fade is widened (up to :data:`WIDENINGS` times by 1.5) until the least
determinant outside the head's outline is at least :data:`MIN_JACOBIAN`, and what is still
short of it is scaled down. Inside the head the model is drawn over the photo.

Layered by the person (``person``: the probability that a pixel of the photo shows the person,
:func:`vtts.fit.segment.person_probability`): only the person — face, hair, neck, shoulders and
clothes — is warped, and the photo's background is never dragged with it. The person (up to
the segmentation's edge, :data:`MARGIN`; the face's outline always) is a layer with a soft
edge (:data:`EDGE` of a head size beyond it), warped with its coverage and laid over the
background; the background behind the person (what a move reveals) is filled from the
background around it (each pixel the colour of the nearest background pixel, smoothed over
:data:`FILL_BLUR` of a head size). Where nothing moves the picture is the photo, exactly. A
segmentation that misses the face (a painting, a cartoon) is not used: the whole photo is then
one layer.

Coordinates are pixels, x right and y down, with the centre of pixel ``[i, j]`` at ``(j + 0.5,
i + 0.5)`` (as :meth:`vtts.render.Camera.project` gives them).

>>> warp = PhotoWarp(photo, rest_xy, depth)          # (H, W, 3) uint8, (n, 2), (n,)
>>> frame = warp(moved_xy)                            # (H, W, 3) uint8
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RBFInterpolator
from scipy.ndimage import distance_transform_edt, gaussian_filter, map_coordinates

from vtts.errors import RenderError

#: The least Jacobian determinant of the warp allowed outside the head: a fold has 0.
MIN_JACOBIAN = 0.25
#: How often the fade may be widened (each time by half) to keep the warp fold-free.
WIDENINGS = 4
#: Fixed-point steps that invert the warp on the grid.
INVERSE_STEPS = 8
#: The probability from which a pixel is the person's (the layer warped over the background).
PERSON = 0.5
#: How far the person's layer reaches beyond the segmentation's edge, in head sizes (below 0:
#: short of it).
MARGIN = 0.0
#: The width of the layer's soft edge beyond that, in head sizes.
EDGE = 1 / 24
#: The smoothing (a Gaussian's sigma, in head sizes) of the background filled in behind the
#: person.
FILL_BLUR = 1 / 12
#: The share of the face's outline the segmentation must hold as the person to be used.
FACE_IN_PERSON = 0.5


@dataclass(frozen=True)
class WarpOptions:
    """How the photo around the head follows it.

    ``reach``: how far beyond the head's outline (in head sizes: the square root of the area
    its outline encloses) the motion fades out to nothing; ``above``: and how many times as far
    from the outline's top up (the hair on the skull turns with the face; from the outline's
    lowest point down the reach is ``reach``: the neck and shoulders stay; a smoothstep in
    height between); ``motion``: and at least this many
    times the largest displacement of a handle (a gentle slope keeps the warp fold-free);
    ``cell``: the handles' spacing, in
    head sizes (one handle, the nearest to the camera, per cell of that size); ``grid``: the
    spacing of the warp's grid in pixels (0: a 24th of the photo's smaller side, at least 4);
    ``smoothing``: the thin-plate spline's smoothing (0: through every handle exactly)."""

    reach: float = 0.25
    above: float = 1.5
    motion: float = 1.5
    cell: float = 1 / 12
    grid: int = 0
    smoothing: float = 1e-3

    def __post_init__(self) -> None:
        checks = (
            ("reach", self.reach, 0.05, 20.0),
            ("above", self.above, 1.0, 20.0),
            ("motion", self.motion, 0.0, 20.0),
            ("cell", self.cell, 0.005, 1.0),
            ("grid", self.grid, 0, 512),
            ("smoothing", self.smoothing, 0.0, 10.0),
        )
        for name, value, lo, hi in checks:
            if not (isinstance(value, int | float) and lo <= value <= hi):  # NaN too
                raise RenderError(f"the warp's {name} must lie within {lo:g}–{hi:g}, got {value!r}")


class PhotoWarp:
    """The warp of ``photo`` ``(H, W, 3) uint8`` driven by handles: the head's points projected
    at rest, ``rest`` ``(n, 2)`` pixels, with their depth from the camera ``depth`` ``(n,)``
    (None: all alike). Of points that fall into the same cell (:attr:`WarpOptions.cell`) the
    nearest to the camera is the handle there (the visible surface: a turned head's far side
    moves the other way). Calling it with the points' positions in a frame, ``(n, 2)``, gives
    that frame's photo. ``person`` ``(H, W)`` (0–1): the probability that each pixel shows the
    person (None: the whole photo is warped as one layer); see the module's docstring."""

    def __init__(self, photo: np.ndarray, rest: np.ndarray, depth: np.ndarray | None = None,
                 options: WarpOptions | None = None,
                 person: np.ndarray | None = None) -> None:  # fmt: skip
        photo = np.asarray(photo)
        if photo.ndim != 3 or photo.shape[2] != 3 or photo.dtype != np.uint8:
            raise RenderError(f"the photo must be (H, W, 3) uint8, got {photo.shape} {photo.dtype}")
        rest = np.asarray(rest, np.float64)
        if rest.ndim != 2 or rest.shape[1] != 2 or not np.isfinite(rest).all():
            raise RenderError(f"the handles must be (n, 2) finite pixels, got {rest.shape}")
        self.options = options or WarpOptions()
        self.photo = photo
        h, w = photo.shape[:2]
        if person is not None:
            person = np.asarray(person, np.float32)
            if person.shape != (h, w) or not np.isfinite(person).all():
                raise RenderError(
                    f"the person's probability must be ({h}, {w}) finite, got {person.shape}"
                )
        self.size = (w, h)
        inside = (rest[:, 0] >= 0) & (rest[:, 0] <= w) & (rest[:, 1] >= 0) & (rest[:, 1] <= h)
        if inside.sum() < 3:
            raise RenderError("the head lies outside the photo: nothing to warp")
        hull = _hull(rest[inside])
        area = _polygon_area(hull)
        #: the head's size in pixels (the square root of the area its outline encloses)
        self.head_size = float(np.sqrt(max(area, 1.0)))
        self.handles = _handles(rest, depth, inside, self.options.cell * self.head_size)
        self.rest = rest[self.handles]
        g = self.options.grid or max(4, round(min(w, h) / 24))
        self.step = int(g)
        # grid nodes at pixel coordinates 0, g, 2g, …, the last at or beyond the photo's edge
        self.gx = np.arange(0.0, w + g, g)[: int(np.ceil(w / g)) + 1]
        self.gy = np.arange(0.0, h + g, g)[: int(np.ceil(h / g)) + 1]
        nodes_x, nodes_y = np.meshgrid(self.gx, self.gy)
        self.nodes = np.stack([nodes_x, nodes_y], axis=-1)  # (gh, gw, 2)
        from matplotlib.path import Path as Polygon

        self.head = Polygon(hull).contains_points(self.nodes.reshape(-1, 2)).reshape(nodes_x.shape)
        #: the person's layer's coverage ``(H, W)`` (0–1) and the background behind it ``(H, W,
        #: 3) uint8``; None: one layer, the whole photo
        self.coverage, self.background = (None, None)
        if person is not None:
            self.coverage, self.background = _layers(photo, person, hull, self.head_size)
        self._packed = packed(photo, self.coverage)
        # distance (pixels) of every node from the head's outline, 0 inside
        self.distance = distance_transform_edt(~self.head) * g if self.head.any() else None
        # the fade's width at each node, as a share of the reach: ``above`` times as wide from
        # the face's top up (the skull and the hair on it turn with the face), 1 from its lowest
        # point down (the neck and shoulders stay), a smoothstep in height between
        top, chin = float(hull[:, 1].min()), float(hull[:, 1].max())
        u = np.clip((chin - self.nodes[..., 1]) / max(chin - top, 1.0), 0.0, 1.0)
        self._widths = 1.0 + (self.options.above - 1.0) * u * u * (3.0 - 2.0 * u)
        #: the fade's widest reach (pixels, above the head) in the last frame, and the factor the
        #: motion outside the head was scaled by
        self.last_reach = 0.0
        self.last_scale = 1.0

    # ---- the field --------------------------------------------------------------------------

    def field(self, moved: np.ndarray) -> np.ndarray:
        """The forward displacement ``(gh, gw, 2)`` (pixels) at the grid's nodes for the points
        at ``moved`` ``(n, 2)`` (the rest points' order): where the photo's content at each
        node goes."""
        moved = np.asarray(moved, np.float64)
        if moved.shape[0] <= int(self.handles.max(initial=0)) or moved.ndim != 2:
            raise RenderError(
                f"the moved points must be (n, 2) as the rest points, got {moved.shape}"
            )
        d = moved[self.handles] - self.rest
        if not np.isfinite(d).all():
            raise RenderError("a moved point is not finite (behind the camera?)")
        if np.abs(d).max(initial=0.0) < 1e-3:
            return np.zeros((*self.nodes.shape[:2], 2))
        spline = self._spline(d)
        # the motion, as the head's, within the head and as far as it reaches
        nodes = self.nodes.reshape(-1, 2)
        reach0 = self.options.reach * self.head_size
        reach = max(reach0, self.options.motion * float(np.abs(d).max())) * self._widths
        near = (
            self.distance.ravel() < np.max(reach) * 1.5**WIDENINGS
            if self.distance is not None
            else (np.ones(len(nodes), bool))
        )
        values = np.zeros((len(nodes), 2))
        values[near] = spline((nodes[near] - self._origin) / self.head_size) * self.head_size
        values = values.reshape(*self.nodes.shape[:2], 2)
        outside = ~self.head
        scale = 1.0
        for _ in range(WIDENINGS + 1):
            f = values * _fade(self.distance, reach)[..., None]
            det = _jacobian(f, self.step)
            if not outside.any() or det[outside].min() >= MIN_JACOBIAN:
                break
            reach *= 1.5
        else:
            # still folding: scale the motion outside the head down until it does not
            lo, hi = 0.0, 1.0
            for _ in range(12):
                mid = (lo + hi) / 2
                g = f * np.where(outside, mid, 1.0)[..., None]
                if _jacobian(g, self.step)[outside].min() >= MIN_JACOBIAN:
                    lo = mid
                else:
                    hi = mid
            scale = lo
            f = f * np.where(outside, scale, 1.0)[..., None]
        self.last_reach, self.last_scale = float(np.max(reach)), scale
        return f

    def _spline(self, d: np.ndarray):
        """The thin-plate spline through the handles' displacements, in head-size units."""
        self._origin = self.rest.mean(axis=0)
        return RBFInterpolator(
            (self.rest - self._origin) / self.head_size,
            d / self.head_size,
            kernel="thin_plate_spline",
            smoothing=self.options.smoothing,
            degree=1,
        )

    # ---- the picture ------------------------------------------------------------------------

    def source(self, moved: np.ndarray) -> tuple[np.ndarray, tuple[int, int, int, int]]:
        """Where the grid's nodes take the photo from: ``(gh, gw, 2)`` pixel coordinates
        ``(x, y)`` of the photo for each node of the output, and the window of nodes ``(first
        row, end row, first column, end column)`` that the motion reaches (the photo stays as it
        is outside it; empty when nothing moves)."""
        f = self.field(moved)
        moving = np.abs(f).max(axis=-1) > 1e-3
        if not moving.any():
            return self.nodes, (0, 0, 0, 0)
        # invert x = y + f(y) on the grid: y ← x − f(y)
        y = self.nodes.copy()
        for _ in range(INVERSE_STEPS):
            y = self.nodes - _sample_grid(f, y, self.step)
        rows, cols = np.nonzero(moving)
        # one node more each way: a node's displacement reaches into its neighbours' cells
        r0, r1 = max(rows.min() - 1, 0), min(rows.max() + 2, len(self.gy))
        c0, c1 = max(cols.min() - 1, 0), min(cols.max() + 2, len(self.gx))
        return y, (int(r0), int(r1), int(c0), int(c1))

    def __call__(self, moved: np.ndarray, needed: np.ndarray | None = None) -> np.ndarray:
        """The photo warped for the points at ``moved`` ``(n, 2)``: ``(H, W, 3) uint8``. Within
        each cell of the grid the place a pixel takes the photo from is bilinear in the cell's
        corners, and the photo is sampled there bilinearly. ``needed`` ``(H, W) bool``: only
        these pixels are warped (the others keep the photo's: a caller that covers them with
        something else saves the time)."""
        y, (r0, r1, c0, c1) = self.source(moved)
        out = self.photo.copy()
        if r1 - r0 < 2 or c1 - c0 < 2:
            return out
        w, h = self.size
        i0, i1 = int(self.gy[r0]), min(int(self.gy[r1 - 1]), h)
        j0, j1 = int(self.gx[c0]), min(int(self.gx[c1 - 1]), w)
        # the grid's bilinear interpolation as two matrices: pixel rows × grid rows, columns ×
        # grid columns (each pixel centre between its cell's nodes)
        rows = _upsampling(np.arange(i0, i1), self.step, len(self.gy))
        cols = _upsampling(np.arange(j0, j1), self.step, len(self.gx))
        sx = rows @ y[..., 0] @ cols.T
        sy = rows @ y[..., 1] @ cols.T
        window = out[i0:i1, j0:j1]
        if needed is None:
            mask = np.ones(window.shape[:2], bool)
        else:
            mask = np.asarray(needed, bool)[i0:i1, j0:j1]
        if self.coverage is None:
            window[mask] = sample(self._packed, (w, h), sx[mask], sy[mask])
            return out
        # the person's layer, warped with its coverage, over the background behind it
        warped = sample(self._packed, (w, h), sx[mask], sy[mask], channels=4)
        a = warped[:, 3:].astype(np.float32) / 255.0
        behind = self.background[i0:i1, j0:j1][mask].astype(np.float32)
        window[mask] = (warped[:, :3] * a + behind * (1.0 - a) + 0.5).astype(np.uint8)
        return out


def _upsampling(pixels: np.ndarray, step: int, nodes: int) -> np.ndarray:
    """``(len(pixels), nodes)``: the weights of the grid's nodes (every ``step`` pixels) that
    interpolate linearly at the centres of ``pixels``."""
    t = (pixels + 0.5) / step
    k = np.minimum(t.astype(np.intp), nodes - 2)
    f = t - k
    m = np.zeros((len(pixels), nodes))
    m[np.arange(len(pixels)), k] = 1.0 - f
    m[np.arange(len(pixels)), k + 1] = f
    return m


def packed(image: np.ndarray, alpha: np.ndarray | None = None) -> np.ndarray:
    """``image`` ``(H, W, 3) uint8`` (and its coverage ``alpha`` ``(H, W)`` 0–1, the fourth
    byte; None: 0) as ``(H·W,) uint32``, a pixel's bytes in one word (what :func:`sample`
    gathers: one load per corner instead of three)."""
    h, w = image.shape[:2]
    rgba = np.zeros((h, w, 4), np.uint8)
    rgba[..., :3] = image
    if alpha is not None:
        rgba[..., 3] = np.round(np.clip(alpha, 0.0, 1.0) * 255.0).astype(np.uint8)
    return rgba.view(np.uint32).reshape(-1)


def sample(pixels: np.ndarray, size: tuple[int, int], x: np.ndarray, y: np.ndarray,
           channels: int = 3) -> np.ndarray:  # fmt: skip
    """The image :func:`packed` as ``pixels`` (of ``size`` (W, H)) sampled bilinearly at the
    pixel coordinates ``x``, ``y`` (any shape; pixel centres at +0.5; beyond the edge the edge's
    pixels): ``(*x.shape, channels) uint8`` (3: RGB; 4: and the coverage byte)."""
    w, h = size
    x = np.clip(np.asarray(x, np.float64) - 0.5, 0.0, w - 1.0)
    y = np.clip(np.asarray(y, np.float64) - 0.5, 0.0, h - 1.0)
    x0 = np.minimum(x.astype(np.intp), max(w - 2, 0))
    y0 = np.minimum(y.astype(np.intp), max(h - 2, 0))
    dx, dy = (1 if w > 1 else 0), (w if h > 1 else 0)
    fx = (x - x0).astype(np.float32)[..., None]
    fy = (y - y0).astype(np.float32)[..., None]
    i = y0 * w + x0

    def corner(at: np.ndarray) -> np.ndarray:
        return pixels[at].view(np.uint8).reshape(*at.shape, 4)[..., :channels].astype(np.float32)

    a, b, c, d = corner(i), corner(i + dx), corner(i + dy), corner(i + dy + dx)
    top = a + (b - a) * fx
    value = top + (c + (d - c) * fx - top) * fy
    return (value + 0.5).astype(np.uint8)


def bilinear(image: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``image`` ``(H, W, 3) uint8`` sampled bilinearly at the pixel coordinates ``at`` ``(...,
    2)`` (x, y; pixel centres at +0.5; beyond the edge the edge's pixels): ``(..., 3) uint8``
    (:func:`sample` of :func:`packed`)."""
    h, w = image.shape[:2]
    return sample(packed(np.asarray(image, np.uint8)), (w, h), at[..., 0], at[..., 1])


def _handles(rest: np.ndarray, depth: np.ndarray | None, inside: np.ndarray,
             cell: float) -> np.ndarray:  # fmt: skip
    """Indices of the handles: of the points inside the photo, per cell of ``cell`` pixels the
    one nearest the camera."""
    idx = np.flatnonzero(inside)
    z = np.zeros(len(rest)) if depth is None else np.asarray(depth, np.float64)
    if z.shape != (len(rest),):
        raise RenderError(f"the depths must be (n,) as the points, got {z.shape}")
    keys = np.floor(rest[idx] / max(cell, 1.0)).astype(np.int64)
    key = keys[:, 0] * 1_000_003 + keys[:, 1]
    order = np.lexsort((z[idx], key))  # by cell, then nearest first
    first = np.r_[True, key[order][1:] != key[order][:-1]]
    return np.sort(idx[order][first])


def _layers(photo: np.ndarray, person: np.ndarray, hull: np.ndarray,
            head_size: float) -> tuple[np.ndarray | None, np.ndarray | None]:  # fmt: skip
    """The person's layer's coverage ``(H, W) float32`` (1 on the person, to :data:`MARGIN`
    from its edge, and within the face's outline ``hull``; falling to 0 over :data:`EDGE`) and
    the background ``(H, W, 3) uint8`` (the photo where the coverage is below 1, filled from
    the nearest background pixels where it is 1); ``(None, None)`` when the segmentation holds
    less than :data:`FACE_IN_PERSON` of the face's outline as the person (then one layer)."""
    from matplotlib.path import Path as Polygon

    h, w = person.shape
    ys, xs = np.mgrid[0:h, 0:w]
    centres = np.c_[xs.ravel() + 0.5, ys.ravel() + 0.5]
    face = Polygon(hull).contains_points(centres).reshape(h, w)
    shown = person >= PERSON
    if not face.any() or shown[face].mean() < FACE_IN_PERSON:
        return None, None
    # the signed distance of every pixel from the person's edge (and its face's): out positive
    body = shown | face
    outside = distance_transform_edt(~body) - distance_transform_edt(body)
    margin, edge = MARGIN * head_size, max(EDGE * head_size, 1.0)
    layer = (outside <= margin) | face
    if layer.all():
        return None, None
    t = np.clip(1.0 - (outside - margin) / edge, 0.0, 1.0)
    coverage = (t * t * (3.0 - 2.0 * t)).astype(np.float32)
    coverage[layer] = 1.0
    # behind the person: the nearest background pixel's colour, smoothed within the layer
    _, (iy, ix) = distance_transform_edt(layer, return_indices=True)
    filled = photo[iy, ix].astype(np.float32)
    sigma = max(FILL_BLUR * head_size, 1.0)
    smooth = gaussian_filter(filled, (sigma, sigma, 0), mode="nearest")
    background = photo.copy()
    background[layer] = np.clip(np.round(smooth[layer]), 0, 255).astype(np.uint8)
    return coverage, background


def _hull(points: np.ndarray) -> np.ndarray:
    """The convex hull ``(m, 2)`` of ``points`` (Andrew's monotone chain), counter-clockwise."""
    pts = np.unique(points, axis=0)
    if len(pts) < 3:
        return pts

    def half(seq):
        out: list = []
        for p in seq:
            while len(out) >= 2:
                a, b = out[-2], out[-1]
                if (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) > 0:
                    break
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _polygon_area(ring: np.ndarray) -> float:
    if len(ring) < 3:
        return 0.0
    x, y = ring[:, 0], ring[:, 1]
    return float(abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) / 2)


def _fade(distance: np.ndarray | None, reach: float) -> np.ndarray | float:
    """1 inside the head, falling smoothly (a smoothstep) to 0 at ``reach`` pixels from it."""
    if distance is None:
        return 1.0
    t = np.clip(1.0 - distance / reach, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _jacobian(f: np.ndarray, step: float) -> np.ndarray:
    """The Jacobian determinant ``(gh, gw)`` of ``x ↦ x + f(x)`` on the grid."""
    dfx_dy, dfx_dx = np.gradient(f[..., 0], step)
    dfy_dy, dfy_dx = np.gradient(f[..., 1], step)
    return (1.0 + dfx_dx) * (1.0 + dfy_dy) - dfx_dy * dfy_dx


def _sample_grid(f: np.ndarray, at: np.ndarray, step: float) -> np.ndarray:
    """``f`` ``(gh, gw, 2)`` sampled bilinearly at the pixel coordinates ``at`` ``(..., 2)``."""
    coords = np.stack([at[..., 1] / step, at[..., 0] / step])
    return np.stack([map_coordinates(f[..., k], coords, order=1, mode="nearest")
                     for k in (0, 1)], axis=-1)  # fmt: skip


def fold_free(f: np.ndarray, step: float, mask: np.ndarray | None = None) -> float:
    """The least Jacobian determinant of the forward map of the displacement ``f`` ``(gh, gw,
    2)`` on a grid of ``step`` pixels (over ``mask`` ``(gh, gw)``, default everywhere): above 0
    where the warp does not fold."""
    det = _jacobian(np.asarray(f, np.float64), step)
    return float(det[mask].min() if mask is not None else det.min())
