"""docs/camera.png: the real-video figure of docs/analysis.md.

Akiyo (``tests/data/video/akiyo_cif.mp4``, all 300 frames) analyzed every second frame as
``vtts analyze`` does with ``--model auto`` (:func:`vtts.analysis.anchor.choose_anchor`,
:func:`vtts.analysis.track.track` from that frame, :func:`vtts.analysis.texture.retexture`),
coded at 12.5 Hz with the default coder and decoded; rows of camera frame / the decoder's view /
difference ×4 at a few frames, and the face PSNR of the decoded stream over time.

usage: .venv/bin/python scripts/camera_figure.py [OUT.png]
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
VIDEO = ROOT / "tests" / "data" / "video" / "akiyo_cif.mp4"
STEP = 2
SHOWN = (0, 150, 230)


def main(out: Path) -> None:
    from matplotlib.figure import Figure

    from vtts.analysis.anchor import choose_anchor
    from vtts.analysis.quality import decoded_frames, sequence_psnr, side_by_side, stream_psnr
    from vtts.analysis.texture import retexture
    from vtts.analysis.track import track
    from vtts.analysis.video import read_video
    from vtts.atomic import atomic_path
    from vtts.fap.coding import decode, encode

    video = read_video(VIDEO)
    frames = list(video.frames())
    anchor = choose_anchor(frames, video.fps, len(frames), step=STEP)
    with tempfile.TemporaryDirectory() as tmp:
        tracked = track(frames, fps=video.fps, model_path=Path(tmp) / "akiyo.wrl", step=STEP,
                        anchor=anchor)  # fmt: skip
        model = retexture(tracked, frames, video.size)
        stream = tracked.analysis.stream("akiyo", fapu=model.fapu)
        data = encode(stream, rate=12.5)
        decoded = decode(data)
        psnr = stream_psnr(frames, decoded, model, video_fps=video.fps)
        views = list(decoded_frames(decoded, model, video.size))
    kbps = len(data) * 8 / (len(frames) / video.fps) / 1000
    n = len(SHOWN)
    height = 3.1 * n + 2.4  # inches: each row 288 pixels and its title, then the plot
    fig = Figure(figsize=(10.56, height), dpi=100)
    for k, index in enumerate(SHOWN):
        i = round(index / video.fps * decoded.fps)
        top = 1 - (k * 3.1 + 0.22) / height
        ax = fig.add_axes((0.0, top - 2.88 / height, 1.0, 2.88 / height))
        ax.imshow(side_by_side(frames[round(i / decoded.fps * video.fps)], views[i]))
        ax.set_axis_off()
        ax.set_title(f"frame {index}: camera | decoded from the .fbs | difference ×4 "
                     f"({psnr[i]:.1f} dB)", fontsize=8)  # fmt: skip
    ax = fig.add_axes((0.08, 0.5 / height, 0.9, 1.5 / height))
    t = np.arange(len(psnr)) / decoded.fps
    ax.plot(t, psnr, lw=1)
    ax.set_xlabel("s")
    ax.set_ylabel("face PSNR, dB")
    ax.set_title(f"Akiyo, {len(frames)} frames, the head made from frame {anchor}: 17 "
                 f"parameters at 12.5 Hz, {kbps:.2f} kbit/s, {sequence_psnr(psnr):.2f} dB",
                 fontsize=8)  # fmt: skip
    with atomic_path(out) as tmp_out:
        fig.savefig(tmp_out, format="png")
    print(f"wrote {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "camera.png")
