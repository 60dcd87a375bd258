"""``vtts encode`` and ``vtts decode``: a FAP stream as a compact ``.fbs`` bitstream, and back."""

from __future__ import annotations

import argparse

from vtts.cli.options import positive_type
from vtts.messages import echo


def add_parser(sub) -> None:
    """Add the ``encode`` and ``decode`` sub-commands (each sets ``func``)."""
    from vtts.fap.coding import CODERS, FAP_SETS

    e = sub.add_parser(
        "encode",
        help="code a FAP stream as a compact .fbs bitstream",
        description=(
            "Code a FAP stream (Eisert & Girod): each FAP predicted from the previous decoded "
            "frame, the error quantized and entropy coded. 17 FAPs at 12.5 Hz take under "
            "0.5 kbit/s with --quantizer 4."
        ),
    )
    e.add_argument("input", metavar="IN", help="a .fap file (or a .fbs bitstream)")
    e.add_argument("-o", "--output", required=True, metavar="OUT.fbs", help="output bitstream")
    e.add_argument(
        "--faps",
        metavar="LIST",
        help="FAPs to send: numbers, ranges, names or a set ("
        + ", ".join(FAP_SETS)
        + "), e.g. 3-13,48 or paper17 (default: every FAP of the stream)",
    )
    e.add_argument(
        "--rate",
        type=positive_type,
        metavar="HZ",
        help="code at this frame rate (default: the stream's)",
    )
    e.add_argument(
        "--quantizer",
        type=positive_type,
        default=1.0,
        metavar="Q",
        help="quantizer steps = the MPEG-4 steps of each FAP x Q (default 1; larger: fewer bits, "
        "errors up to half a step)",
    )
    e.add_argument(
        "--coder",
        choices=tuple(CODERS),
        default="arithmetic",
        help="entropy coder: huffman (the paper's) or adaptive arithmetic (default, fewer bits)",
    )
    e.add_argument(
        "--no-translation",
        action="store_true",
        help="leave out the head translation a .fbs input carries (default: sent)",
    )
    e.add_argument("--quiet", action="store_true", help="print nothing on success")
    e.set_defaults(func=cmd_encode)

    d = sub.add_parser(
        "decode",
        help="decode a .fbs bitstream into a .fap file",
        description="Decode a .fbs bitstream into a .fap file. A .fap file has no place for the "
        "head translation a bitstream may carry: it is left out, with a warning.",
    )
    d.add_argument("input", metavar="IN.fbs", help="a FAP bitstream")
    d.add_argument("-o", "--output", required=True, metavar="OUT.fap", help="output .fap file")
    d.add_argument("--quiet", action="store_true", help="print nothing on success")
    d.set_defaults(func=cmd_decode)


def cmd_encode(args: argparse.Namespace) -> int:
    """``vtts encode IN -o OUT.fbs``: code a FAP stream; print the size and the largest error."""
    from vtts.api.coding import EncodeOptions, contents, encode

    done = encode(
        EncodeOptions(
            input=args.input,
            output=args.output,
            faps=args.faps,
            rate=args.rate,
            quantizer=args.quantizer,
            coder=args.coder,
            translation=not args.no_translation,
        )
    )
    if args.quiet:
        return 0
    h = done.header
    worst = done.max_error()
    err = ""
    if worst is not None:
        key, error, step = worst
        where = f"ES units on the head translation's {key}"
        if isinstance(key, int):
            where = f"FAP units on FAP {key}"
        err = f"; max error {error / step:.2f} step ({error:.4g} {where}, step {step:g})"
    echo(
        f"wrote {args.output}: {h.n_frames} frames at {h.fps:g} Hz, {contents(h)}, "
        f"{h.coder}, {h.size} bytes = {h.bits_per_frame:.1f} bits/frame, "
        f"{h.kbit_per_s:.3f} kbit/s{err}"
    )
    return 0


def cmd_decode(args: argparse.Namespace) -> int:
    """``vtts decode IN.fbs -o OUT.fap``: decode a bitstream into a ``.fap`` file (which cannot
    carry a head translation: :func:`~vtts.fap.stream.write_fap` warns that it is left out)."""
    from vtts.api.coding import DecodeOptions, decode

    stream = decode(DecodeOptions(input=args.input, output=args.output))
    if not args.quiet:
        echo(f"wrote {args.output}: {stream.n_frames} frames at {stream.fps:g} fps")
    return 0
