"""The photo's expression, fitted apart from the face's shape: a neutral head from an
expressive photo.

A photo of a smiling, talking or frowning face is not a neutral face. Fitted as shape alone,
its open jaw, stretched lips and raised brows become the head's neutral (a head that smiles
under every viseme). Here the landmarks see the shape *and* a handful of FAPs — the jaw, the
lips, the lip corners, the brows, the upper lids and the cheeks (:data:`EXPRESSION_FAPS`) — whose
displacements the generic head's own tables give (:func:`expression_basis`): the shape fit
(:func:`vtts.fit.shape.fit_shape`) solves for both, and the head keeps the shape without the
FAPs as its neutral. The texture is painted with the head posed in the photo's expression
(:func:`vtts.fit.photo.fit_photo`), so that the photo's lips land on the lips, closed in the
neutral head; the photo's open mouth and its eyes are kept off the skin
(:func:`skin_trust`): the mouth's inside is the model's (teeth, tongue, cavity), and the
lids take the skin around them, not the eye.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from PIL import Image, ImageDraw
from scipy import ndimage

from vtts.face import FaceModel
from vtts.fap import fap
from vtts.fit.landmarks import FACE_OVAL, LEFT_EYE, LIPS_INNER, RIGHT_EYE, eye_distance

#: The FAPs a photo's expression is fitted with, and each one's prior width (in its FAPU
#: units): the jaw, the lips' middles and corners, the upper lids, the brows and the cheeks a smile
#: lifts.
EXPRESSION_FAPS = {
    3: 600.0,  # open_jaw
    4: 150.0,  # lower_t_midlip
    5: 150.0,  # raise_b_midlip
    6: 150.0,  # stretch_l_cornerlip
    7: 150.0,  # stretch_r_cornerlip
    12: 200.0,  # raise_l_cornerlip
    13: 200.0,  # raise_r_cornerlip
    19: 300.0,  # close_t_l_eyelid
    20: 300.0,  # close_t_r_eyelid
    31: 150.0,  # raise_l_i_eyebrow
    32: 150.0,  # raise_r_i_eyebrow
    33: 150.0,  # raise_l_m_eyebrow
    34: 150.0,  # raise_r_m_eyebrow
    35: 150.0,  # raise_l_o_eyebrow
    36: 150.0,  # raise_r_o_eyebrow
    41: 400.0,  # lift_l_cheek
    42: 400.0,  # lift_r_cheek
}
#: The value at which each table's slope is read (FAPU units): within its first interval.
PROBE = 100.0
#: How much tighter a unidirectional FAP's prior is below zero (a jaw does not close beyond
#: shut).
ONE_WAY = 0.02
#: The inner lips' gap (a share of the eye distance) from which the jaw's prior is its full
#: width (:data:`EXPRESSION_FAPS`), and the least share of that width it keeps on a shut mouth.
OPEN_GAP, SHUT_JAW = 0.15, 0.05
#: The FAPs that lift the cheeks (lift_l_cheek, lift_r_cheek), and the mouth's widths between
#: its outer corners (landmarks 61 and 291, a share of the eye distance) over which their prior
#: grows to its full width (a smile's); on a narrower mouth they are not fitted at all (the
#: development portraits at rest are 0.65–0.9 eye distances wide): a smile's raised cheeks
#: face the light where the photo is bright, but on a face at rest even a few units of cheek
#: lift cost (`lp_s42`: 5 units, −0.13 dB over the face).
CHEEKS = (41, 42)
REST_WIDTH, SMILE_WIDTH = 0.85, 1.0
#: How far (pixels, as a share of the eye distance) beyond the photo's inner lip and eye
#: contours the skin takes nothing from the photo.
MARGIN = 0.01
#: How far inside the photo's face outline (a share of the eye distance) what the photo shows
#: still counts as beyond the face, fading to nothing (:func:`beyond_face`).
OUTLINE_BAND = 0.2
#: Inside that band, a pixel counts as not the face's lit skin from this share of the face's
#: median luminance down (fully at the first, not at all at the second).
DARKER = (0.5, 0.7)
#: Lips parted by less than this share of the eye distance (the inner lips' middles, landmarks
#: 13 and 14) show a dark seam, not the teeth: the head at the photo's view draws them shut
#: (:func:`close_lips`), and the seam is painted on the lips (:func:`skin_trust`).
SHUT_LIPS = 0.05
#: How far (pixels at the photo's view) the shut lips' middles overlap: no crack of the teeth
#: between them.
LIPS_OVERLAP = 0.5
#: The FAPs that close the lips' middles (lower_t_midlip, raise_b_midlip: positive closes).
CLOSING = (4, 5)


@dataclass
class ExpressionBasis:
    """How the expression FAPs move the landmarks' points.

    faps      ``(e,)`` FAP numbers
    up, down  ``(e, n, 3)`` displacement of each landmark point per FAP unit, for positive and
              negative values (model units per FAPU unit)
    sigma     ``(e,)`` prior widths (FAPU units)
    one_way   ``(e,)`` bool: unidirectional FAPs (negative values held near zero)
    """

    faps: np.ndarray
    up: np.ndarray
    down: np.ndarray
    sigma: np.ndarray
    one_way: np.ndarray

    def displacement(self, values: np.ndarray) -> np.ndarray:
        """``(n, 3)`` landmark points' displacement for FAP ``values (e,)``."""
        slope = np.where((values >= 0)[:, None, None], self.up, self.down)
        return np.einsum("e,enk->nk", values, slope)

    def slopes(self, values: np.ndarray) -> np.ndarray:
        """``(e, n, 3)`` the derivative of :meth:`displacement` by each value."""
        return np.where((values >= 0)[:, None, None], self.up, self.down)


def expression_basis(model: FaceModel, landmark_matrix, faps=EXPRESSION_FAPS) -> ExpressionBasis:
    """The :class:`ExpressionBasis` of ``model``'s tables (its ``FACE``), through
    ``landmark_matrix`` (sparse ``(n, p)``: the landmarks' points from ``FACE``'s ``p``)."""
    numbers = [k for k in faps if any(m.kind == "fap" and m.number == k for m in model.miaps)]
    neutral = model.neutral_points("FACE")
    up, down = [], []
    for k in numbers:
        for sign, out in ((1.0, up), (-1.0, down)):
            moved = model.engine.points(model.params({k: sign * PROBE})).get("FACE", neutral)
            out.append(np.asarray(landmark_matrix @ (moved - neutral)) / (sign * PROBE))
    one_way = np.array([not fap(k).bidirectional for k in numbers], bool)
    return ExpressionBasis(np.array(numbers, int), np.array(up), np.array(down),
                           np.array([faps[k] for k in numbers]), one_way)  # fmt: skip


def lips_gap(landmarks: np.ndarray) -> float:
    """The gap between the inner lips' middles (landmarks 13 and 14 of ``landmarks (468,
    ≥2)``, pixels) as a share of the eye distance."""
    pts = np.asarray(landmarks, np.float64)[:, :2]
    return float(np.linalg.norm(pts[13] - pts[14])) / max(eye_distance(pts), 1e-9)


def close_lips(model: FaceModel, camera, expression: dict[int, float]) -> dict[int, float]:
    """``expression`` ``{FAP: value}`` with the lips' middles (FAPs 4 and 5, by the same
    amount) closed until they overlap by :data:`LIPS_OVERLAP` pixels as ``camera``
    (:class:`~vtts.render.Camera`) sees ``model`` (its MPEG-4 feature points 2.2 and 2.3, the
    inner lips' middles): a photo whose lips are barely parted shows a dark seam there, which
    the model's lit teeth behind a crack would draw white. Unchanged where they already meet."""
    fp = model.tables.feature_points
    if not all(k in fp and fp[k][0] == "FACE" for k in ("2.2", "2.3")):
        return expression
    top, bottom = fp["2.2"][1], fp["2.3"][1]

    def gap(values: dict[int, float]) -> float:
        pts = model.engine.points(model.params(values)).get("FACE", model.neutral_points("FACE"))
        a, b = pts[top], pts[bottom]
        pa, pb, below = camera.project(np.array([a, b, a - [0.0, 0.1, 0.0]]))
        down = (below - pa) / max(float(np.linalg.norm(below - pa)), 1e-9)
        return float((pb - pa) @ down)

    now = gap(expression)
    if now <= -LIPS_OVERLAP:
        return expression
    probe = {**expression, **{k: expression.get(k, 0.0) + PROBE for k in CLOSING}}
    per_unit = (gap(probe) - now) / PROBE
    if per_unit >= 0:
        return expression
    more = round((-LIPS_OVERLAP - now) / per_unit)
    return {**expression, **{k: expression.get(k, 0.0) + more for k in CLOSING}}


def for_photo(basis: ExpressionBasis, landmarks: np.ndarray) -> ExpressionBasis:
    """``basis`` with the jaw's prior (open_jaw, FAP 3) narrowed to what the photo's lips show:
    the gap between the inner lips' middles (landmarks 13, 14 of ``landmarks (468, ≥2)``,
    pixels) over :data:`OPEN_GAP` of the eye distance, at least :data:`SHUT_JAW`. Opening the
    jaw also lengthens the chin, which the shape can as well: on a shut mouth, and on a turned
    face whose chin the landmarks place less surely, a loose jaw took up what was the face's
    length (a neutral head fitted at 20° of yaw opened it by 200–450 units). The cheeks' lift
    (:data:`CHEEKS`) is narrowed likewise to the smile the mouth's width between its outer
    corners shows (landmarks 61, 291: from :data:`REST_WIDTH` to :data:`SMILE_WIDTH` of the eye
    distance), and left out of the basis on a mouth no wider than :data:`REST_WIDTH`."""
    pts = np.asarray(landmarks, np.float64)[:, :2]
    eyes = max(eye_distance(pts), 1e-9)
    gap = float(np.linalg.norm(pts[13] - pts[14])) / eyes
    share = float(np.clip(gap / OPEN_GAP, SHUT_JAW, 1.0))
    width = float(np.linalg.norm(pts[61] - pts[291])) / eyes
    smile = float(np.clip((width - REST_WIDTH) / (SMILE_WIDTH - REST_WIDTH), 0.0, 1.0))
    cheeks = np.isin(basis.faps, CHEEKS)
    sigma = np.where(basis.faps == 3, basis.sigma * share, basis.sigma)
    sigma = np.where(cheeks, sigma * smile, sigma)
    keep = ~cheeks | (smile > 0)
    return replace(basis, faps=basis.faps[keep], up=basis.up[keep], down=basis.down[keep],
                   sigma=sigma[keep], one_way=basis.one_way[keep])  # fmt: skip


def skin_trust(size: tuple[int, int], landmarks: np.ndarray, mouth: bool = True) -> np.ndarray:
    """``(H, W) float32`` for a photo of ``size`` (W, H): 0 inside the inner lip contour (an
    open mouth; not where ``mouth`` is False: lips drawn shut, :func:`close_lips`) and the two
    eyes' contours, grown by :data:`MARGIN` of the eye distance, 1 elsewhere: what the skin
    may take from the photo (``landmarks (468, ≥2)`` pixels)."""
    w, h = size
    pts = np.asarray(landmarks, np.float64)[:, :2]
    eyes = eye_distance(pts)
    grow = max(1, round(MARGIN * eyes))
    im = Image.new("L", (w, h), 255)
    draw = ImageDraw.Draw(im)
    for contour in (LIPS_INNER, RIGHT_EYE, LEFT_EYE)[0 if mouth else 1 :]:
        poly = [tuple(p) for p in pts[list(contour)] - 0.5]
        draw.polygon(poly, fill=0, outline=0, width=grow)
        draw.line([*poly, poly[0]], fill=0, width=2 * grow + 1)
    return np.asarray(im, np.float32) / 255.0


def beyond_face(size: tuple[int, int], landmarks: np.ndarray,
                image: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """``(H, W) float32`` for a photo of ``size`` (W, H): how far each pixel shows something
    else than the face's lit skin near its outline — 1 outside the photo's face outline (the
    landmarks' :data:`~vtts.fit.landmarks.FACE_OVAL`, ``landmarks (468, ≥2)`` pixels: hair, an
    ear, the background), falling to 0 over :data:`OUTLINE_BAND` of the eye distance inside it
    (the outline's landmarks lie on the skin's last pixels), and there, with ``image (H, W, 3)``
    (uint8), only where the pixel is darker than the face (:data:`DARKER`: a sideburn, hair
    over the temple, the shadowed side of the face). Whatever of the head's face is drawn there
    takes what the photo shows, not the mirrored skin (:func:`vtts.fit.texture.project_skin`)."""
    w, h = size
    pts = np.asarray(landmarks, np.float64)[:, :2]
    im = Image.new("L", (w, h), 255)
    ImageDraw.Draw(im).polygon([tuple(p) for p in pts[list(FACE_OVAL)] - 0.5], fill=0)
    inside = np.asarray(im) == 0
    depth = ndimage.distance_transform_edt(inside) / max(OUTLINE_BAND * eye_distance(pts), 1.0)
    out = np.clip(1.0 - depth, 0.0, 1.0)
    if image is not None and inside.any():
        lum = np.asarray(image, np.float64)[..., :3] @ np.array([0.299, 0.587, 0.114])
        share = lum / max(float(np.median(lum[inside])), 1.0)
        dark, lit = DARKER
        out = np.where(inside, out * np.clip((lit - share) / (lit - dark), 0.0, 1.0), out)
    return out.astype(np.float32)
