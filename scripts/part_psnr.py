"""Where the error of a tracked real video is: the face PSNR of the decoder's view per part of
the head (docs/analysis.md, "Where the error is"), with the neck weighed down or turning with
the head (vtts.fit.neck).

    .venv/bin/python scripts/part_psnr.py tests/data/video/akiyo_cif.mp4 --frames 60
    .venv/bin/python scripts/part_psnr.py ... --neck weighed      # with vtts.fit.neck
    .venv/bin/python scripts/part_psnr.py ... --frames 300 --anchor typical --texture mean
                                              # the head as vtts analyze makes it for a file

Tracks the video's first FRAMES frames (every second one, ``--model auto``, the paper's 17
parameters, as bench/bench_real_video.py does), then renders the uncoded stream through the
video's camera as :func:`vtts.analysis.quality.stream_psnr` does — the same pixels (the decoded
model's coverage, shrunk by 2) — and splits them by the part of the head each shows (the
rasterizer's triangle numbers). Prints the whole stream's mean / median / worst face PSNR (of
every analyzed frame, and of the frames after the first), each part's pixels per frame, PSNR
and share of the squared error (frames after the first), and the bit rate and mean PSNR of the
stream coded at 12.5 Hz (arithmetic coder, quantizer 1), as JSON. ``*_stream_psnr`` are
the same figures from the library's own measure (:func:`vtts.analysis.quality.stream_psnr`).

``--faps LIST`` tracks other unknowns (``vtts analyze --faps``); ``--searched 19,20`` has those
FAPs found by the image search alone with the head held (``Estimator(searched=)``), and
``--lid-floor V`` keeps the upper eyelids' search at V units or more (``Estimator(bounds=)``):
docs/analysis.md, "The 17 parameters lack the eyes".

``--neck-translation`` (with the neck weighed) is a trial of what is not built: the split's
renderings move the neck's points by ``(w − 1) · t`` (``w`` the neck's weights of
:func:`vtts.fit.neck.neck_weights`, ``t`` the stream's head translation in model units), so the
neck follows the translation as it follows the rotation; ``uncoded_*`` and the parts then show
that, while ``*_stream_psnr`` and the coded figures stay the decoder's (the whole neck
translated).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: The parts the split reports: IndexedFaceSet DEF names of a fitted head.
PARTS = {
    "neck": ("NECK",),
    "face skin": ("FACE",),
    "eyeballs": ("L_EYEBALL", "R_EYEBALL"),
    "eye sockets": ("SOCKETS",),
    "hair cap": ("HAIR",),
    "ears": ("L_EAR", "R_EAR"),
    "teeth, mouth, tongue": ("UPPER_TEETH", "LOWER_TEETH", "MOUTH", "TONGUE"),
}


def _db(mse: float) -> float:
    return float("inf") if mse == 0 else 10 * math.log10(255.0**2 / mse)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("video", type=Path)
    ap.add_argument("--frames", type=int, default=60, help="the video's first N frames")
    ap.add_argument("--step", type=int, default=2)
    ap.add_argument("--neck", choices=("weighed", "turning"), default="turning",
                    help="weighed: the neck follows the head near the skull only (vtts.fit.neck); "
                    "turning: the whole neck turns with the head (the default head)")  # fmt: skip
    ap.add_argument("--match-neck", action="store_true",
                    help="match the neck too (not in ignore=)")  # fmt: skip
    ap.add_argument("--neck-translation", action="store_true",
                    help="the neck follows the translation, weighed")  # fmt: skip
    ap.add_argument("--faps", default="paper17", help="the unknowns (vtts analyze --faps)")
    ap.add_argument("--searched", default="", help="FAPs found by the image search alone")
    ap.add_argument("--lid-floor", type=float, default=None,
                    help="the upper eyelids' lowest value in the search (FAPs 19, 20)")  # fmt: skip
    ap.add_argument("--track", action="store_true", help="the tracking mode (vtts analyze --track)")
    ap.add_argument("--anchor", choices=("first", "typical"), default="first",
                    help="the frame the head is made from: the first with a face, or the most "
                    "typical one, as vtts analyze chooses it for a file")  # fmt: skip
    ap.add_argument("--texture", choices=("anchor", "mean"), default="anchor",
                    help="the head's texture: that frame, or the mean of what the tracked "
                    "frames show (vtts analyze's default for a file)")  # fmt: skip
    ap.add_argument("--per-frame", action="store_true", help="each frame's figures too")
    args = ap.parse_args(argv)

    import vtts.fit.photo
    from vtts.analysis.quality import coverage, sequence_psnr
    from vtts.analysis.track import FITTED_IGNORED, track
    from vtts.analysis.unknowns import parse_unknowns
    from vtts.analysis.video import read_video
    from vtts.animate.fapstream import head_roots, stream_params
    from vtts.fap.coding import decode, encode
    from vtts.fit.neck import neck_weights
    from vtts.render import FaceRenderer

    if args.neck_translation:
        args.neck = "weighed"  # the trial weighs the translation as the tables weigh the rotation
    vtts.fit.photo.FREE_NECK = args.neck == "weighed"
    video = read_video(args.video)
    frames = [f for i, f in enumerate(video.frames()) if i < args.frames]
    h, w = frames[0].shape[:2]
    options = {}
    if args.searched:
        options["searched"] = tuple(int(x) for x in args.searched.split(","))
    if args.lid_floor is not None:
        options["bounds"] = {19: (args.lid_floor, math.inf), 20: (args.lid_floor, math.inf)}
    if args.match_neck:
        options["ignore"] = tuple(p for p in FITTED_IGNORED if p != "NECK")
    if args.anchor == "typical":
        from vtts.analysis.anchor import choose_anchor

        options["anchor"] = choose_anchor(frames, video.fps, len(frames), step=args.step)
    with tempfile.TemporaryDirectory(prefix="vtts-parts-") as tmp:
        t0 = time.perf_counter()
        tracked = track(frames, fps=video.fps, model_path=Path(tmp) / "m.wrl", step=args.step,
                        unknowns=parse_unknowns(args.faps), tracking=args.track,
                        **options)  # fmt: skip
        if args.texture == "mean":
            from vtts.analysis.texture import retexture

            tracked.model = retexture(tracked, frames, (w, h))
        seconds = time.perf_counter() - t0
        model = tracked.model
        stream = tracked.analysis.stream(args.video.stem, fapu=model.fapu)
        params = stream_params(stream, model.tables.adts).params
        psnr = np.full(stream.n_frames, np.nan)
        sse = {k: 0.0 for k in PARTS}
        count = {k: 0 for k in PARTS}
        neck_psnr = np.full(stream.n_frames, np.nan)
        with FaceRenderer(model, size=(w, h), viewpoint="photo", background="transparent") as r:
            roots = None
            if stream.translation is not None:
                roots = head_roots(r.model_matrix(0), stream.translation, model.fapu)
            weights = neck_weights(
                model.neutral_points("NECK"),
                float(model.scene.node("HEAD_PITCH").expand()["center"][1]),
            )
            owner = np.full(sum(c for _, _, c in r.triangle_sets), -1)
            names = list(PARTS)
            for node, first, n in r.triangle_sets:
                for j, part in enumerate(names):
                    if node.name in PARTS[part]:
                        owner[first : first + n] = j
            for i in range(stream.n_frames):
                k = round(i / stream.fps * video.fps)
                if k >= len(frames):
                    continue
                poses = None
                if args.neck_translation and stream.translation is not None:
                    pose = model.engine.deform(params[i])
                    t = stream.translation[i] * model.fapu.es
                    pose.points["NECK"] = pose.points["NECK"] + (weights - 1)[:, None] * t
                    poses = [pose]
                r.apply(r.prepare(params[i], poses, None if roots is None else [roots[i]]))
                rgba, numbers = r.render(triangles=True)
                mask = coverage(rgba)
                sq = ((frames[k].astype(np.float64) - rgba[..., :3]) ** 2).sum(axis=2)
                psnr[i] = _db(float(sq[mask].mean()) / 3)
                if i == 0:
                    continue
                part = np.where(numbers >= 0, owner[np.maximum(numbers, 0)], -1)
                for j, name in enumerate(names):
                    sel = mask & (part == j)
                    sse[name] += float(sq[sel].sum())
                    count[name] += int(sel.sum())
                    if name == "neck" and sel.any():
                        neck_psnr[i] = _db(float(sq[sel].mean()) / 3)
        data = encode(stream, rate=12.5, coder="arithmetic")
        duration = len(frames) / video.fps
        coded = _coded_psnr(frames, decode(data), model, video.fps)
        check = _coded_psnr(frames, stream, model, video.fps)  # the library's own measure
    later = psnr[1:][~np.isnan(psnr[1:])]
    total = sum(sse.values())
    n_later = max(len(later), 1)
    out = {
        "video": args.video.name,
        "frames": len(frames),
        "analyzed": int(np.sum(~np.isnan(psnr))),
        "neck": args.neck,
        "match_neck": args.match_neck,
        "faps": args.faps,
        "searched": args.searched,
        "lid_floor": args.lid_floor,
        "mode": "tracking" if args.track else "accurate",
        "anchor": options.get("anchor", "first"),
        "texture": args.texture,
        "seconds": round(seconds, 1),
        "restarts": len(tracked.restarts),
        "held": len(tracked.held),
        "uncoded_mean": round(sequence_psnr(psnr), 2),
        "uncoded_median": round(float(np.nanmedian(psnr)), 2),
        "uncoded_worst": round(float(np.nanmin(psnr)), 2),
        "uncoded_mean_stream_psnr": round(sequence_psnr(check), 2),
        "uncoded_median_stream_psnr": round(float(np.nanmedian(check)), 2),
        "uncoded_worst_stream_psnr": round(float(np.nanmin(check)), 2),
        "after_first_mean": round(sequence_psnr(later), 2),
        "coded_12.5Hz_kbps": round(len(data) * 8 / duration / 1000, 3),
        "coded_12.5Hz_mean": round(sequence_psnr(coded), 2),
        "parts": {
            k: {
                "pixels_per_frame": round(count[k] / n_later),
                "psnr": round(_db(sse[k] / max(3 * count[k], 1)), 1) if count[k] else None,
                "share_percent": round(100 * sse[k] / total, 1) if total else None,
            }
            for k in PARTS
        },
    }
    if args.per_frame:
        out["per_frame"] = {
            "psnr": np.round(psnr, 2).tolist(),
            "neck_psnr": np.round(neck_psnr, 2).tolist(),
            "fap48": [float(fe.params[47]) for fe in tracked.analysis.frames],
            "translation": [np.round(fe.translation, 4).tolist() for fe in tracked.analysis.frames],
        }
    json.dump(out, sys.stdout, indent=1)
    print()
    return 0


def _coded_psnr(frames, stream, model, fps) -> np.ndarray:
    from vtts.analysis.quality import stream_psnr

    return stream_psnr(frames, stream, model, video_fps=fps)


if __name__ == "__main__":
    raise SystemExit(main())
