"""Lay out the bundled heads' golden images as one labelled contact sheet (``docs/heads.png``).

usage: python models/src/contact_sheet.py [--golden DIR] [-o OUT.png]

Each cell shows the same pose on cybatt and on lotta side by side — one parameter stream, two
personalities. The images come from ``tests/golden/`` (``make golden`` renders them).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

ROOT = Path(__file__).resolve().parents[2]
MODELS = ("cybatt", "lotta")
POSES = [
    ("neutral", "neutral"),
    ("joy", "joy"),
    ("sadness", "sadness"),
    ("anger", "anger"),
    ("fear", "fear"),
    ("disgust", "disgust"),
    ("surprise", "surprise"),
    ("eyes-closed", "eyes closed"),
    ("head-left", "head turned left"),
    ("head-down", "head pitched down"),
    ("viseme01", "viseme 1  p b m"),
    ("viseme02", "viseme 2  f v"),
    ("viseme03", "viseme 3  T D"),
    ("viseme04", "viseme 4  t d"),
    ("viseme05", "viseme 5  k g"),
    ("viseme06", "viseme 6  tS dZ S"),
    ("viseme07", "viseme 7  s z"),
    ("viseme08", "viseme 8  n l"),
    ("viseme09", "viseme 9  r"),
    ("viseme10", "viseme 10  A:"),
    ("viseme11", "viseme 11  e"),
    ("viseme12", "viseme 12  I"),
    ("viseme13", "viseme 13  Q"),
    ("viseme14", "viseme 14  U"),
]
#: Part of each 352 × 288 golden kept (the head; x0, y0, x1, y1) and the cell's scale.
CROP = (96, 16, 256, 272)
SCALE = 0.75
COLUMNS = 4
LABEL = 18
BG = (34, 38, 46)


def sheet(golden: Path) -> Image.Image:
    cw = int((CROP[2] - CROP[0]) * SCALE)
    ch = int((CROP[3] - CROP[1]) * SCALE)
    pair_w = 2 * cw + 6
    rows = (len(POSES) + COLUMNS - 1) // COLUMNS
    pad = 14
    title_h = 34
    width = COLUMNS * pair_w + (COLUMNS + 1) * pad
    height = title_h + rows * (ch + LABEL) + (rows + 1) * pad
    out = Image.new("RGB", (width, height), BG)
    draw = ImageDraw.Draw(out)
    font = ImageFont.load_default()
    draw.text(
        (pad, 10),
        "vtts bundled heads: cybatt (left) and lotta (right), one parameter set each cell",
        fill=(235, 235, 235),
        font=font,
    )
    for k, (pose, label) in enumerate(POSES):
        r, c = divmod(k, COLUMNS)
        x = pad + c * (pair_w + pad)
        y = title_h + pad + r * (ch + LABEL + pad)
        for j, model in enumerate(MODELS):
            img = Image.open(golden / f"{model}-{pose}.png").convert("RGB").crop(CROP)
            img = img.resize((cw, ch), Image.Resampling.LANCZOS)
            out.paste(img, (x + j * (cw + 6), y))
        draw.text((x + 2, y + ch + 3), label, fill=(220, 220, 220), font=font)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--golden", type=Path, default=ROOT / "tests" / "golden")
    ap.add_argument("-o", "--output", type=Path, default=ROOT / "docs" / "heads.png")
    args = ap.parse_args(argv)
    img = sheet(args.golden)
    # a 256-colour palette keeps the sheet small; the faces survive it well
    img = img.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    img.save(args.output, optimize=True)
    size = args.output.stat().st_size
    print(f"wrote {args.output}: {img.width}x{img.height}, {size / 1e3:.0f} kB")
    return 0 if np.isfinite(size) else 1


if __name__ == "__main__":
    sys.exit(main())
