"""``vtts play STREAM``: a FAP stream played on models (``-``: a ``.fbs`` from stdin, live)."""

from __future__ import annotations

import argparse
import sys

from vtts.cli.options import (
    add_curves,
    add_detail,
    add_models,
    add_view,
    add_web,
    seed_type,
)
from vtts.messages import echo


def add_parser(sub) -> None:
    pl = sub.add_parser("play", help="play a FAP stream on one or more models")
    pl.add_argument(
        "stream",
        nargs="?",
        help="a .fap file or a coded .fbs stream; - reads a .fbs (streamed by vtts analyze "
        "--stream) from stdin and renders each frame as it arrives",
    )
    add_models(pl)
    pl.add_argument(
        "--audio",
        help="sound to mux into the MP4 and --web (WAV, FLAC, OGG, MP3, M4A …); - (with no "
        "stream): a voice on stdin, raw PCM s16le mono at --rate, which the face follows live",
    )
    pl.add_argument(
        "--rate",
        type=int,
        help="sample rate of the voice on stdin (--audio -), Hz (default 16000)",
    )
    pl.add_argument(
        "--seed", type=seed_type, default=0, help="seed of the autonomous behaviour (--audio -)"
    )
    pl.add_argument(
        "--no-autonomous",
        action="store_true",
        help="no autonomous blinks, nods, head motion or gaze (--audio -)",
    )
    pl.add_argument(
        "--fps",
        type=float,
        help="output frame rate (default 30; a stream from stdin plays at its own)",
    )
    pl.add_argument("--png-dir", help="also (or only) write lossless PNG frames into this folder")
    pl.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    add_curves(pl)
    add_web(pl)
    add_view(pl)
    add_detail(pl)
    pl.add_argument(
        "-o",
        "--output",
        help="output .mp4, or an animated .glb/.gltf; with a stream from stdin, - writes raw "
        "rgb24 frames of --size to stdout (ffplay -f rawvideo -pixel_format rgb24 ...)",
    )
    pl.set_defaults(func=cmd_play)


def cmd_play(args: argparse.Namespace) -> int:
    """Play the stream (:func:`vtts.api.play.play`) and say what was written."""
    from vtts.api.play import PlayOptions, play
    from vtts.cli.options import curves_options, view_options

    options = PlayOptions(
        stream=args.stream,
        model=args.model,
        output=args.output,
        png_dir=args.png_dir,
        web=args.web,
        audio=args.audio,
        rate=args.rate,
        seed=args.seed,
        no_autonomous=args.no_autonomous,
        fps=args.fps,
        progress=not args.quiet,
        **curves_options(args),
        **view_options(args),
    )
    played = play(options, on_first_frame=args.first_frame)
    if not args.quiet:
        live = args.stream == "-" or args.audio == "-"
        echo(
            f"wrote {' and '.join(played.written)}: {played.n_frames} frames at "
            f"{played.fps:g} fps ({played.seconds:.2f} s)",
            file=sys.stderr if live else sys.stdout,
        )
    return 0
