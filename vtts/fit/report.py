"""What ``adi fit --report DIR`` shows: how well the head fits its photo.

- ``landmarks.png``: the photo with the detected landmarks (green) and the fitted model's
  landmarks projected by the fitted camera (red);
- ``overlay.png``: the photo beside the model rendered at ``--viewpoint photo`` over it;
- ``turned.png``: the model turned 30° to its right, facing, and 30° to its left;
- ``figures.json``: landmark reprojection error (pixels and % of the eye distance), the face
  PSNR between the photo and the rendering over the face's pixels, whether the photo shows
  glasses (:mod:`vtts.fit.glasses`), how far the upper teeth were moved to the teeth the photo
  shows (:mod:`vtts.fit.teeth`; model units, + up, null where none were), timings and file
  sizes.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from vtts.atomic import atomic_path
from vtts.face import FaceModel
from vtts.fit.generic import landmark_map
from vtts.fit.glasses import GLASSES

#: The parts whose pixels make "the face" for the PSNR: skin, eyes and mouth, and the glasses
#: (:mod:`vtts.fit.glasses`) where the head has them.
FACE_PARTS = (
    "FACE",
    "L_EYEBALL",
    "R_EYEBALL",
    "MOUTH",
    "UPPER_TEETH",
    "LOWER_TEETH",
    "TONGUE",
    "GLASSES",
)
#: The report's files, in the order they are written (checked against the photo and the model's
#: files before the fit starts).
LANDMARKS, OVERLAY, TURNED, FIGURES = "landmarks.png", "overlay.png", "turned.png", "figures.json"
REPORT_FILES = (LANDMARKS, OVERLAY, TURNED, FIGURES)
#: The head's turn in ``turned.png`` (degrees), as FAP 49 (head yaw).
TURN_DEGREES = 30.0


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR (dB) between two equally shaped uint8 pixel sets (inf when equal)."""
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(255.0**2 / mse)


def photo_view(model: FaceModel, photo: np.ndarray, faps: dict[int, float] | None = None
               ) -> tuple[np.ndarray, dict[str, np.ndarray]]:  # fmt: skip
    """The model rendered at its ``photo`` Viewpoint over ``photo (H, W, 3) uint8``, in the
    photo's expression ``faps`` (:attr:`~vtts.fit.photo.FittedHead.expression`), and the masks
    ``(H, W) bool`` of the pixels its skin (``FACE``), its face (:data:`FACE_PARTS`) and the
    whole head (everything it draws) show."""
    from vtts.fit.photo import PHOTO_VIEWPOINT
    from vtts.render import FaceRenderer

    h, w = photo.shape[:2]
    with FaceRenderer(model, size=(w, h), viewpoint=PHOTO_VIEWPOINT) as r:
        image, numbers = r.render(model.params(faps), triangles=True)
        sets = r.triangle_sets
    image = np.where((numbers >= 0)[..., None], image[..., :3], photo)
    masks = {"skin": np.zeros((h, w), bool), "face": np.zeros((h, w), bool), "head": numbers >= 0}
    for node, first, count in sets:
        inside = (numbers >= first) & (numbers < first + count)
        if node.name == "FACE":
            masks["skin"] |= inside
        if node.name in FACE_PARTS:
            masks["face"] |= inside
    return image, masks


def figures(model: FaceModel, head, photo: np.ndarray) -> dict:
    """The figures of a fit: ``head`` is the :class:`~vtts.fit.photo.FittedHead`, ``model`` the
    written model loaded back, ``photo`` the photo it was fitted to."""
    shape = head.shape
    lmap = landmark_map()
    eyes = np.linalg.norm(
        head.face.landmarks[[33, 133], :2].mean(axis=0)
        - head.face.landmarks[[263, 362], :2].mean(axis=0)
    )
    err = shape.residual
    image, masks = photo_view(model, photo, head.expression)
    out = {
        "faces_found": head.faces,
        "landmarks_fitted": int(shape.used.sum()),
        "landmarks_mapped": len(lmap.landmark),
        "reprojection_px": {
            "median": float(np.median(err)),
            "rms": float(np.sqrt(np.mean(err**2))),
            "max": float(err.max()),
        },
        "reprojection_percent_of_eye_distance": {
            "median": float(100 * np.median(err) / eyes),
            "rms": float(100 * np.sqrt(np.mean(err**2)) / eyes),
        },
        "eye_distance_px": float(eyes),
        "psnr_db": {k: psnr(image[m], photo[m]) for k, m in masks.items() if m.any()},
        "pixels": {k: int(m.sum()) for k, m in masks.items()},
        "head_yaw_degrees": math.degrees(shape.yaw),
        "glasses": None
        if head.glasses is None
        else {"score": head.glasses, "found": head.glasses >= GLASSES},
        "photo_expression_faps": {str(k): v for k, v in head.expression.items()},
        "teeth_moved": head.teeth,
        "focal_px": shape.focal,
        "skin_seen_by_photo": head.seen,
        "seconds": head.timings,
    }
    return out


def write_report(folder: str | Path, model: FaceModel, head, photo: np.ndarray,
                 files: list[Path]) -> dict:  # fmt: skip
    """Write the report (see the module docstring) into ``folder``; returns the figures."""
    from vtts.render import FaceRenderer

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    figs = figures(model, head, photo)
    figs["files"] = {p.name: p.stat().st_size for p in files}
    # landmarks: detected (green) and the model's, projected (red)
    shape = head.shape
    lmap = landmark_map()
    m = lmap.matrix(len(model.neutral_points("FACE"))) @ model.neutral_points("FACE")
    projected = shape.camera.project(m)
    im = Image.fromarray(photo)
    scale = max(1, round(720 / max(im.size)))
    im = im.resize((im.width * scale, im.height * scale), Image.Resampling.LANCZOS)
    draw = ImageDraw.Draw(im)
    r = max(1.0, scale * 0.8)
    for x, y in head.face.landmarks[:, :2] * scale:
        draw.ellipse([x - r, y - r, x + r, y + r], fill=(40, 220, 60))
    for x, y in projected * scale:
        draw.ellipse([x - r, y - r, x + r, y + r], fill=(230, 40, 40))
    _save(im, folder / LANDMARKS)
    image, _ = photo_view(model, photo, head.expression)
    both = Image.new("RGB", (photo.shape[1] * 2, photo.shape[0]))
    both.paste(Image.fromarray(photo), (0, 0))
    both.paste(Image.fromarray(image), (photo.shape[1], 0))
    _save(both, folder / OVERLAY)
    au = math.radians(TURN_DEGREES) / 1e-5
    frames = []
    with FaceRenderer(model, size=(320, 320), supersample=2) as rr:
        for yaw in (-au, 0.0, au):
            frames.append(rr.render(model.params({49: yaw}))[..., :3])
    _save(Image.fromarray(np.concatenate(frames, axis=1)), folder / TURNED)
    with atomic_path(folder / FIGURES) as tmp:
        tmp.write_text(json.dumps(figs, indent=2) + "\n", encoding="utf-8")
    return figs


def _save(image: Image.Image, path: Path) -> None:
    with atomic_path(path) as tmp:
        image.save(tmp, format="PNG")
