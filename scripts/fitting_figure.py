"""The contact sheet of docs/fitting.md: each development photo, the head ``adi fit`` makes of
it rendered at ``--viewpoint photo`` in the photo's expression over grey (everything the model
draws), the neutral head turned 30° each way, with joy, and speaking viseme 10 ("A:"); and
the same of the first frame of :data:`CLIPS` (a development clip whose man wears glasses: the
frame a part of the head, :mod:`vtts.fit.glasses`). ``lp_s9`` and ``lp_s12``, set aside until
stop 54, are development photos since stop 54.

usage: .venv/bin/python scripts/fitting_figure.py [OUT.png]   (default docs/fitting.png)
"""

from __future__ import annotations

import math
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
from PIL import Image

import vtts
from vtts.fit import fit_photo, load_photo
from vtts.render import FaceRenderer

ROOT = Path(__file__).resolve().parents[1]
#: The development photos (tests/data/photos).
PHOTOS = ("akiyo_frame0.png", "astronaut.png", "lp_s1.jpg", "lp_s2.jpg", "lp_s42.jpg", "lp_s7.jpg",
          "lp_s9.jpg", "lp_s12.jpg")  # fmt: skip
#: Development clips (tests/data/video) whose first frame gets a row: glasses.
CLIPS = ("lp_d13",)
CELL = 200
GREY = 128


def cell(image: np.ndarray) -> Image.Image:
    im = Image.fromarray(image[..., :3])
    return im.resize((CELL, round(CELL * im.height / im.width)), Image.Resampling.LANCZOS)


def crop_to_face(image: np.ndarray, box, margin: float = 0.45) -> np.ndarray:
    """A square crop around a face box, ``margin`` of its size on each side, moved (and, for a
    face that fills the photo, shrunk) to lie within the image, so that every cell is square."""
    x0, y0, x1, y1 = box
    h, w = image.shape[:2]
    s = min(max(x1 - x0, y1 - y0) * (1 + 2 * margin), w, h)
    a = int(round(min(max((x0 + x1) / 2 - s / 2, 0), w - s)))
    b = int(round(min(max((y0 + y1) / 2 - s / 2, 0), h - s)))
    return image[b : b + int(s), a : a + int(s)]


def row(name: str, folder: Path) -> list[Image.Image]:
    if name in CLIPS:
        from vtts.analysis.video import read_video

        video = ROOT / "tests" / "data" / "video" / f"{name}.mp4"
        image, focal = next(iter(read_video(video).frames())), None
    else:
        image, focal = load_photo(ROOT / "tests" / "data" / "photos" / name)
    stem = Path(name).stem
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        head = fit_photo(image, focal_35mm=focal, name=stem)
    image = head.photo  # at the working size
    head.write(folder / f"{stem}.wrl")
    model = vtts.load_model(folder / f"{stem}.wrl")
    h, w = image.shape[:2]
    grey = np.full_like(image, GREY)
    with FaceRenderer(model, size=(w, h), viewpoint="photo", background=grey) as r:
        over = r.render(model.params(head.expression))
    box = head.face.box
    cells = [cell(crop_to_face(image, box)), cell(crop_to_face(over, box))]
    au = math.radians(30) / 1e-5
    with FaceRenderer(model, size=(CELL, CELL), supersample=2) as r:
        for params in (
            model.params({49: -au}),
            model.params({49: au}),
            model.params({49: au / 2}, expressions={"joy": 1.0}),
            model.params({49: -au / 2}, visemes={10: 1.0}),
        ):
            cells.append(cell(r.render(params)))
    return cells


def main(argv: list[str]) -> int:
    out = Path(argv[0]) if argv else ROOT / "docs" / "fitting.png"
    with tempfile.TemporaryDirectory() as tmp:
        rows = [row(name, Path(tmp)) for name in (*PHOTOS, *CLIPS)]
    sheet = Image.new("RGB", (CELL * len(rows[0]), CELL * len(rows)), (255, 255, 255))
    for i, cells in enumerate(rows):
        for j, c in enumerate(cells):
            sheet.paste(c, (j * CELL, i * CELL + (CELL - c.height) // 2))
    sheet.save(out, optimize=True)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
