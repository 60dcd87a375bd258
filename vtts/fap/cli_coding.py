"""The ``vtts encode`` and ``vtts decode`` commands; ``.fbs`` support for ``check`` and ``play``.

``vtts.cli`` calls :func:`register` to add the two sub-commands; :func:`check_fbs` is the
``vtts check`` summary of a ``.fbs`` file and :func:`read_stream` reads a ``.fap`` or ``.fbs``
stream by its suffix (for ``vtts play``). Errors are :class:`~vtts.errors.VttsError`\\ s: a
damaged bitstream is a :class:`~vtts.errors.CodingError` whose ``file`` is set and whose message
starts with ``byte N:``, so the CLI prints ``FILE: error: byte N: MESSAGE``.
"""

from __future__ import annotations

import argparse
import os
import warnings
from pathlib import Path

from vtts.atomic import write_bytes
from vtts.errors import FapError
from vtts.fap.coding import (
    CODERS,
    FAP_SETS,
    TRANSLATION_BASE_STEP,
    FbsHeader,
    decode,
    encode,
    error_stats,
    fap_set,
    read_header,
    source_stream,
)
from vtts.fap.stream import TRANSLATION_AXES, FapStream, FapWarning, read_fap, write_fap
from vtts.fap.table import FAPS
from vtts.limits import MAX_FBS_BYTES, read_bytes_capped

#: The suffix of FAP bitstreams.
FBS_SUFFIX = ".fbs"


def _read_bytes(path: str | os.PathLike[str]) -> bytes:
    try:
        return read_bytes_capped(path, MAX_FBS_BYTES, what="FAP bitstream")
    except OSError as e:
        raise FapError(
            f"cannot read FAP bitstream: {e.strerror or e}", file=os.fspath(path)
        ) from None


def read_stream(path: str | os.PathLike[str]) -> FapStream:
    """The FAP stream in ``path``: a ``.fbs`` bitstream (decoded) or else a ``.fap`` file."""
    if Path(path).suffix.lower() == FBS_SUFFIX:
        return decode(_read_bytes(path), file=os.fspath(path))
    return read_fap(path)


def check_fbs(path: str | os.PathLike[str]) -> str:
    """Decode a ``.fbs`` file completely and summarize it for ``vtts check``:
    ``"N frames at R Hz, K FAPs[ and the head translation], CODER, B bits/frame, X kbit/s"``
    (the bits count everything sent, the translation included)."""
    data = _read_bytes(path)
    decode(data, file=os.fspath(path))
    h = read_header(data, file=os.fspath(path))
    return f"{h.n_frames} frames at {h.fps:g} Hz, {_contents(h)}, {h.coder}, " + (
        f"{h.bits_per_frame:.1f} bits/frame, {h.kbit_per_s:.3f} kbit/s"
    )


def describe_fbs(path: str | os.PathLike[str]) -> list[str]:
    """``vtts info`` of a ``.fbs`` file: what its header says, and its frames' size (the whole
    bitstream is checked and decoded, a streamed one as well)."""
    data = _read_bytes(path)
    decode(data, file=os.fspath(path))
    h = read_header(data, file=os.fspath(path))
    form = "streamed (packets and an end marker)" if h.stream else "whole"
    lines = [
        f"{h.n_frames} frames at {h.fps:g} Hz from frame {h.first_frame}, name {h.name!r}",
        f"{form} bitstream, {h.coder} coder, quantizer {h.quantizer:g}"
        + (", constant mask" if h.constant_mask else ""),
        f"FAPs: {', '.join(map(str, h.faps)) or 'none'}"
        + ("; the head translation (tx, ty, tz)" if h.translation else ""),
    ]
    if h.predictors:
        pairs = ", ".join(f"{k}←{p}" for k, p in sorted(h.predictors.items()))
        lines.append(f"predicted FAPs: {pairs}")
    own = [f"{k} {b}" for k, b in zip(h.low, h.base_steps, strict=True)
           if b != FAPS[k - 1].quant_step]  # fmt: skip
    own += [f"{a} {b}" for a, b in zip(TRANSLATION_AXES, h.translation_base_steps, strict=False)
            if b != TRANSLATION_BASE_STEP]  # fmt: skip
    if own:  # e.g. vtts analyze's steps measured on the face
        lines.append(f"base steps of its own (MPEG-4's for the rest): {', '.join(own)}")
    lines.append(
        f"{h.size} bytes (header {h.header_size}): {h.bits_per_frame:.1f} bits/frame, "
        f"{h.kbit_per_s:.3f} kbit/s"
    )
    return lines


def _contents(h: FbsHeader) -> str:
    faps = f"{len(h.faps)} FAP{'s' if len(h.faps) != 1 else ''}"
    return f"{faps} and the head translation" if h.translation else faps


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def cmd_encode(args: argparse.Namespace) -> int:
    """``vtts encode IN -o OUT.fbs``: code a FAP stream; print the size and the largest error."""
    stream = read_stream(args.input)
    faps = fap_set(args.faps) if args.faps else None
    words = set((args.faps or "").lower().replace(",", " ").split())
    if faps is not None and not words & {"all", "low"}:
        present = {int(k) + 1 for k in stream.mask.any(axis=0).nonzero()[0]}
        missing = [k for k in faps if k not in present]
        if missing:
            warnings.warn(
                FapWarning(
                    f"FAP{'s' if len(missing) > 1 else ''} {', '.join(map(str, missing))} of "
                    "--faps not in the stream: not sent",
                    file=args.input,
                ),
                stacklevel=2,
            )
    translation = not args.no_translation
    data = encode(
        stream,
        faps=faps,
        rate=args.rate,
        quantizer=args.quantizer,
        coder=args.coder,
        translation=translation,
    )
    write_bytes(args.output, data)
    if not args.quiet:
        h = read_header(data)
        decoded = decode(data)
        source = source_stream(stream, faps=faps, rate=args.rate, translation=translation)
        stats = error_stats(source, decoded)
        steps = h.steps
        if stats:
            worst = max(stats, key=lambda k: stats[k][0] / steps[k])
            where = f"ES units on the head translation's {worst}"
            if isinstance(worst, int):
                where = f"FAP units on FAP {worst}"
            err = (
                f"; max error {stats[worst][0] / steps[worst]:.2f} step "
                f"({stats[worst][0]:.4g} {where}, step {steps[worst]:g})"
            )
        else:
            err = ""
        print(
            f"wrote {args.output}: {h.n_frames} frames at {h.fps:g} Hz, {_contents(h)}, "
            f"{h.coder}, {h.size} bytes = {h.bits_per_frame:.1f} bits/frame, "
            f"{h.kbit_per_s:.3f} kbit/s{err}"
        )
    return 0


def cmd_decode(args: argparse.Namespace) -> int:
    """``vtts decode IN.fbs -o OUT.fap``: decode a bitstream into a ``.fap`` file (which cannot
    carry a head translation: :func:`~vtts.fap.stream.write_fap` warns that it is left out)."""
    stream = decode(_read_bytes(args.input), file=args.input)
    write_fap(stream, args.output)
    if not args.quiet:
        print(f"wrote {args.output}: {stream.n_frames} frames at {stream.fps:g} fps")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``encode`` and ``decode`` sub-commands (each sets ``func``)."""
    e = subparsers.add_parser(
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
        type=_positive,
        metavar="HZ",
        help="code at this frame rate (default: the stream's)",
    )
    e.add_argument(
        "--quantizer",
        type=_positive,
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

    d = subparsers.add_parser(
        "decode",
        help="decode a .fbs bitstream into a .fap file",
        description="Decode a .fbs bitstream into a .fap file. A .fap file has no place for the "
        "head translation a bitstream may carry: it is left out, with a warning.",
    )
    d.add_argument("input", metavar="IN.fbs", help="a FAP bitstream")
    d.add_argument("-o", "--output", required=True, metavar="OUT.fap", help="output .fap file")
    d.add_argument("--quiet", action="store_true", help="print nothing on success")
    d.set_defaults(func=cmd_decode)
