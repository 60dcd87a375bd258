"""How far better geometry could take the decoded face: block motion compensation as an oracle.

    .venv/bin/python scripts/mc_bound.py tests/data/video/akiyo_cif.mp4
    .venv/bin/python scripts/mc_bound.py tests/data/video/carphone_qcif.mp4 --block 4 --reach 4

Analyzes the video as ``vtts analyze`` does for a file (``--model auto``, the most typical frame
as the anchor, every second frame, the paper's 17 parameters, the mean texture), decodes the
uncoded stream through the video's camera (:func:`vtts.analysis.quality.decoded_frames`) and
measures over the decoder's coverage (shrunk by 2 pixels, as the benchmark does), as JSON:

* ``decoded``: the face PSNR of the decoded frames (the benchmark's measure, mean over the
  summed error);
* ``decoded_block_shifted``: the same after every ``--block``×``--block`` block of the decoded
  frame has been moved by the whole-pixel shift within ±``--reach`` pixels that matches the
  camera frame best (the block's coverage counted where the camera frame is compared). No head
  can do better by its geometry alone — shape, deformation tables, pose — than a free shift of
  every small block of its image: this is an upper bound on what geometry is worth, the
  texture as it is;
* ``previous_frame`` and ``previous_frame_block_shifted``: the camera frame predicted from the
  one analyzed before it (two frames earlier) over the same pixels, as it is and block-shifted
  the same way — what a motion-compensating video coder gets from a real frame 80 ms old,
  before any residual.

See docs/analysis.md, "What the texture cannot show".
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def block_shifted_sse(target: np.ndarray, source: np.ndarray, mask: np.ndarray, block: int,
                      reach: int) -> tuple[float, int]:  # fmt: skip
    """The summed squared error (RGB) over ``mask`` ``(H, W)`` between ``target`` and
    ``source`` ``(H, W, 3)`` float64 when every ``block``×``block`` block of ``source`` takes
    the whole-pixel shift within ±``reach`` that makes its error least; and the pixels counted
    (the whole blocks within the image)."""
    h, w = mask.shape
    hb, wb = h // block, w // block
    inside = mask[: hb * block, : wb * block]
    best = None
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            shifted = np.roll(source, (dy, dx), axis=(0, 1))
            error = ((target - shifted) ** 2).sum(axis=-1)[: hb * block, : wb * block] * inside
            blocks = error.reshape(hb, block, wb, block).sum(axis=(1, 3))
            best = blocks if best is None else np.minimum(best, blocks)
    return float(best.sum()), int(inside.sum())


def _psnr(mse: float) -> float:
    return 10 * math.log10(255.0**2 / mse)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("video", type=Path)
    ap.add_argument("--block", type=int, default=8, help="block size, pixels (default 8)")
    ap.add_argument("--reach", type=int, default=3, help="largest shift, pixels (default 3)")
    return measure_video("mc_bound", ap.parse_args(argv), _measure)


def measure_video(tool: str, args: argparse.Namespace, measure) -> int:
    """Read the video ``args.video``, print ``measure(args, video, frames)`` (a dict) as JSON;
    a bad video, or one without a face, is said on stderr with ``tool``'s name (exit status 2),
    never a traceback. Shared by the scripts that measure a video (``eq18_regions.py``)."""
    from vtts.analysis.video import read_video
    from vtts.errors import VttsError

    try:
        video = read_video(args.video)
        result = measure(args, video, list(video.frames()))
    except VttsError as e:
        print(f"{tool}: {args.video}: {e.message}", file=sys.stderr)
        return 2
    print(json.dumps(result, indent=1))
    return 0


def _measure(args: argparse.Namespace, video, frames: list[np.ndarray]) -> dict:
    """The figures of the module's docstring for ``frames`` of ``video`` (a
    :func:`~vtts.analysis.video.read_video`), as a dict."""
    from vtts.analysis.anchor import choose_anchor
    from vtts.analysis.quality import coverage, decoded_frames
    from vtts.analysis.texture import retexture
    from vtts.analysis.track import track

    h, w = frames[0].shape[:2]
    anchor = choose_anchor(frames, video.fps, len(frames), step=2)
    sums = dict.fromkeys(("decoded", "decoded_block_shifted", "previous_frame",
                          "previous_frame_block_shifted"), 0.0)  # fmt: skip
    counts = dict.fromkeys(sums, 0)
    with tempfile.TemporaryDirectory(prefix="vtts-mc-") as tmp:
        tracked = track(frames, fps=video.fps, model_path=Path(tmp) / "m.wrl", step=2,
                        anchor=anchor)  # fmt: skip
        model = retexture(tracked, frames, (w, h))
        stream = tracked.analysis.stream(args.video.stem, fapu=model.fapu)
        for i, rgba in enumerate(decoded_frames(stream, model, (w, h), "photo")):
            k = round(i / stream.fps * video.fps)
            if k >= len(frames):
                break
            camera = frames[k].astype(np.float64)
            decoded = rgba[..., :3].astype(np.float64)
            mask = coverage(rgba)
            sums["decoded"] += float((((camera - decoded) ** 2).sum(-1) * mask).sum())
            counts["decoded"] += int(mask.sum())
            sse, n = block_shifted_sse(camera, decoded, mask, args.block, args.reach)
            sums["decoded_block_shifted"] += sse
            counts["decoded_block_shifted"] += n
            if k >= 2:
                previous = frames[k - 2].astype(np.float64)
                sums["previous_frame"] += float((((camera - previous) ** 2).sum(-1) * mask).sum())
                counts["previous_frame"] += int(mask.sum())
                sse, n = block_shifted_sse(camera, previous, mask, args.block, args.reach)
                sums["previous_frame_block_shifted"] += sse
                counts["previous_frame_block_shifted"] += n
    result = {"video": args.video.name, "block": args.block, "reach": args.reach,
              "analyzed": stream.n_frames, "anchor": anchor}  # fmt: skip
    result.update({key: round(_psnr(sums[key] / (3 * counts[key])), 2) for key in sums})
    return result


if __name__ == "__main__":
    sys.exit(main())
