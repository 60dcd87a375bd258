"""``vtts analyze VIDEO``: FAPs estimated from a video of a face (Eisert-Girod)."""

from __future__ import annotations

import argparse
import sys

from vtts.cli.options import add_url_root
from vtts.messages import echo


def add_parser(sub) -> None:
    an = sub.add_parser(
        "analyze",
        help="estimate FAPs from a video of a face (Eisert-Girod)",
        description=(
            "Estimate FAPs and head motion from a video by analysis by synthesis: the model is "
            "rendered with the current estimate and the optical-flow constraint at every face "
            "pixel gives a linear update, over a pyramid, frame after frame."
        ),
    )
    an.add_argument(
        "video",
        metavar="VIDEO",
        help="a video file (MP4, ...), a folder of PNGs, or - for raw rgb24 frames on stdin "
        "(ffmpeg ... -f rawvideo -pix_fmt rgb24 -; with --size)",
    )
    an.add_argument(
        "--model",
        action="append",
        help="auto (default): fit a head to the video's most typical face (the first face on "
        "stdin) and write it as OUT-model.wrl; or "
        "a bundled model name or .wrl path, placed on the first face's landmarks",
    )
    add_url_root(an)
    an.add_argument(
        "-o", "--output", metavar="OUT.fap", help="output .fap (or coded .fbs); or --stream"
    )
    an.add_argument(
        "--stream",
        action="store_true",
        dest="stream_out",
        help="write a streamed .fbs to stdout instead of -o, each frame as soon as it is "
        "estimated (vtts play - renders it)",
    )
    an.add_argument(
        "--model-out",
        metavar="HEAD.wrl",
        help="where --model auto writes the fitted head (default OUT-model.wrl; needed with "
        "--stream), complete before the stream's header; not with a given --model (nothing is "
        "fitted)",
    )
    an.add_argument(
        "--size",
        metavar="WxH",
        help="the size of raw frames on stdin (VIDEO -), such as 176x144",
    )
    an.add_argument(
        "--face", type=int, metavar="N", help="which face to track, 1 = the largest (default)"
    )
    an.add_argument(
        "--rate",
        type=float,
        metavar="HZ",
        help="frame rate of the coded .fbs (default: the analysis rate; the paper's is 12.5)",
    )
    an.add_argument(
        "--steps",
        choices=("face", "mpeg4"),
        default="face",
        help="base steps of the coded .fbs: face (default) spends the bits where the face's "
        "image shows them (measured on the model at the median pose, a --stream's at its "
        "first estimate: about a third fewer bits for the same face); mpeg4: the standard's",
    )
    an.add_argument(
        "--quantizer",
        type=float,
        metavar="Q",
        help="the coder's quantizer of the coded .fbs: its steps are the base steps times Q "
        "(default 4: about the paper's 0.58 kbit/s at --rate 12.5; 1 spends about 1.7 times "
        "the bits for 0.2 dB more)",
    )
    an.add_argument(
        "--faps",
        metavar="LIST",
        help="what to estimate: FAP numbers 3-68, ranges, names, tx,ty,tz (head translation) "
        "or a set (paper17, table1); default paper17",
    )
    an.add_argument(
        "--camera",
        metavar="FX,FY,X0,Y0",
        help="the video camera, Eisert-Girod Eq. 3 in pixels (default: the framing of "
        "vtts render for the video's size)",
    )
    an.add_argument("--step", type=int, default=1, metavar="N", help="analyze every N-th frame")
    an.add_argument(
        "--at-rate",
        action="store_true",
        help="analyze only the frames the coded stream shows: the frame nearest each 1/--rate "
        "s (needs --rate; a 30 fps video at --rate 12.5: frames 0, 2, 5, 7, 10, ...)",
    )
    mode = an.add_mutually_exclusive_group()
    mode.add_argument(
        "--track",
        action="store_true",
        default=None,
        help="the fast tracking mode: about one rendering a frame, solves on surface samples "
        "(the default for frames on stdin)",
    )
    mode.add_argument(
        "--accurate",
        dest="track",
        action="store_false",
        help="the accurate mode: each frame ends with a rendering after every solve at full "
        "size, started by solves on surface samples (the first frame: the whole pyramid); the "
        "default for a video file or folder",
    )
    an.add_argument(
        "--fps",
        type=float,
        metavar="F",
        help="frame rate of a PNG folder or of frames on stdin (default 25), or instead of a "
        "video's own",
    )
    an.add_argument(
        "--texture",
        choices=("mean", "anchor"),
        help="the fitted head's texture: mean (the default for a video file): what the tracked "
        "frames show (a robust least-squares average: what most of them show); anchor: the "
        "frame it was fitted to (always for frames on stdin or --stream)",
    )
    an.add_argument(
        "--report",
        metavar="DIR",
        help="also write frames.csv, psnr.png, faps.png and side-by-side.mp4 into DIR",
    )
    an.add_argument(
        "--fbs", action="store_true", help="also write the coded bitstream beside OUT (.fbs)"
    )
    an.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    an.set_defaults(func=cmd_analyze)


def cmd_analyze(args: argparse.Namespace) -> int:
    """Estimate (:func:`vtts.api.analyze.analyze`) and summarize what was found."""
    from vtts.analysis.report import mean_psnr
    from vtts.api.analyze import AnalyzeOptions, analyze

    coding = {} if args.quantizer is None else {"quantizer": args.quantizer}
    options = AnalyzeOptions(
        **coding,
        video=args.video,
        model=args.model,
        output=args.output,
        stream_out=args.stream_out,
        model_out=args.model_out,
        size=args.size,
        face=args.face,
        rate=args.rate,
        steps=args.steps,
        faps=args.faps,
        camera=args.camera,
        step=args.step,
        at_rate=args.at_rate,
        track=args.track,
        fps=args.fps,
        texture=args.texture,
        report=args.report,
        fbs=args.fbs,
        progress=not args.quiet,
    )
    found = analyze(options)
    if args.quiet:
        return 0
    written = [str(p) for p in (found.output, found.extra_fbs) if p]
    if args.stream_out:
        written.insert(
            0,
            f"the stream to stdout ({found.stream_bytes} bytes; coding and writing "
            f"{found.stream_ms_per_frame:.2f} ms a frame)",
        )
    if found.fitted:
        texture = f": what {found.textured} frames show" if found.textured else ""
        written.append(
            f"the fitted head {found.fitted[0]} (+ .adt, -face.png, -frame.png{texture})"
        )
    if args.report:
        written.append(f"report in {args.report}")
    analysis, tracked = found.analysis, found.tracked
    n = len(analysis.frames)
    restarts = len(tracked.restarts)
    unseen = f"; {len(tracked.unseen)} showed no face" if tracked.unseen else ""
    held = f", {len(tracked.held)} held (no estimate{unseen})" if tracked.held else ""
    # with --stream, stdout is the bitstream's
    echo(
        f"wrote {', '.join(written)}: {n} frame{'s' if n != 1 else ''} at "
        f"{analysis.fps:g} fps, {len(analysis.unknowns)} unknowns, "
        f"{'tracking' if options.tracking else 'accurate'} mode, "
        f"mean face PSNR {mean_psnr(analysis.psnr()):.2f} dB, "
        f"{restarts} re-initialization{'s' if restarts != 1 else ''}{held}",
        file=sys.stderr if args.stream_out else sys.stdout,
    )
    translation = any(isinstance(u, str) for u in analysis.unknowns)
    if not args.stream_out and not options.coded and not found.extra_fbs and translation:
        echo("note: a .fap file cannot carry the head translation; -o OUT.fbs or --fbs does")
    return 0
