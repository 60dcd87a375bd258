"""``vtts encode`` and ``vtts decode`` (:func:`encode`, :func:`decode`), and reading a FAP
stream from a ``.fap`` file or a ``.fbs`` bitstream by its suffix (:func:`read_stream`), with the
``check`` and ``info`` summaries of a ``.fbs`` (:func:`check_fbs`, :func:`describe_fbs`).

Errors are :class:`~vtts.errors.VttsError`\\ s: a damaged bitstream is a
:class:`~vtts.errors.CodingError` whose ``file`` is set and whose message starts with
``byte N:``, so the command prints ``FILE: error: byte N: MESSAGE``.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

from vtts.errors import FapError
from vtts.fap import coding
from vtts.fap.stream import TRANSLATION_AXES, FapStream, FapWarning, read_fap, write_fap
from vtts.limits import MAX_FBS_BYTES, read_bytes_capped

#: The suffix of FAP bitstreams.
FBS_SUFFIX = ".fbs"


def read_fbs_bytes(path: str | os.PathLike[str]) -> bytes:
    """The bytes of a ``.fbs`` file, at most :data:`vtts.limits.MAX_FBS_BYTES`."""
    try:
        return read_bytes_capped(path, MAX_FBS_BYTES, what="FAP bitstream")
    except OSError as e:
        raise FapError(
            f"cannot read FAP bitstream: {e.strerror or e}", file=os.fspath(path)
        ) from None


def read_stream(path: str | os.PathLike[str]) -> FapStream:
    """The FAP stream in ``path``: a ``.fbs`` bitstream (decoded) or else a ``.fap`` file."""
    if Path(path).suffix.lower() == FBS_SUFFIX:
        return coding.decode(read_fbs_bytes(path), file=os.fspath(path))
    return read_fap(path)


def contents(h: coding.FbsHeader) -> str:
    """What a bitstream sends: ``"17 FAPs"``, ``"2 FAPs and the head translation"``."""
    faps = f"{len(h.faps)} FAP{'s' if len(h.faps) != 1 else ''}"
    return f"{faps} and the head translation" if h.translation else faps


def check_fbs(path: str | os.PathLike[str]) -> str:
    """Decode a ``.fbs`` file completely and summarize it for ``vtts check``:
    ``"N frames at R Hz, K FAPs[ and the head translation], CODER, B bits/frame, X kbit/s"``
    (the bits count everything sent, the translation included)."""
    data = read_fbs_bytes(path)
    coding.decode(data, file=os.fspath(path))
    h = coding.read_header(data, file=os.fspath(path))
    return f"{h.n_frames} frames at {h.fps:g} Hz, {contents(h)}, {h.coder}, " + (
        f"{h.bits_per_frame:.1f} bits/frame, {h.kbit_per_s:.3f} kbit/s"
    )


def describe_fbs(path: str | os.PathLike[str]) -> list[str]:
    """``vtts info`` of a ``.fbs`` file: what its header says, and its frames' size (the whole
    bitstream is checked and decoded, a streamed one as well)."""
    from vtts.fap.table import FAPS

    data = read_fbs_bytes(path)
    coding.decode(data, file=os.fspath(path))
    h = coding.read_header(data, file=os.fspath(path))
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
            if b != coding.TRANSLATION_BASE_STEP]  # fmt: skip
    if own:  # e.g. vtts analyze's steps measured on the face
        lines.append(f"base steps of its own (MPEG-4's for the rest): {', '.join(own)}")
    lines.append(
        f"{h.size} bytes (header {h.header_size}): {h.bits_per_frame:.1f} bits/frame, "
        f"{h.kbit_per_s:.3f} kbit/s"
    )
    return lines


def check_positive(value: float | None, name: str) -> None:
    """``value`` (None: not given) is a positive finite number."""
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise FapError(f"{name} must be a number, got {value!r}")
    if not 0 < value < math.inf:
        raise FapError(f"{name} must be a positive number, got {value!r}")


@dataclass(kw_only=True)
class EncodeOptions:
    """What ``vtts encode`` codes.

    ``input``: a ``.fap`` file or a ``.fbs`` bitstream; ``output``: the ``.fbs`` written;
    ``faps``: the FAPs sent, numbers, ranges, names or a set (:data:`vtts.fap.coding.FAP_SETS`;
    None: every FAP of the stream); ``rate``: the coded frame rate in Hz (None: the stream's);
    ``quantizer``: the steps are MPEG-4's times this; ``coder``: ``arithmetic`` or ``huffman``
    (:data:`vtts.fap.coding.CODERS`); ``translation``: send the head translation an input
    carries.
    """

    input: str
    output: str
    faps: str | None = None
    rate: float | None = None
    quantizer: float = 1.0
    coder: str = "arithmetic"
    translation: bool = True

    def __post_init__(self) -> None:
        check_positive(self.rate, "--rate")
        check_positive(self.quantizer, "--quantizer")
        if self.coder not in coding.CODERS:
            raise FapError(f"--coder must be one of {', '.join(coding.CODERS)}, got {self.coder!r}")


@dataclass(frozen=True)
class Encoded:
    """What :func:`encode` wrote: ``output``, its ``data`` (the bitstream) and ``header``;
    ``stream``: the stream it coded, with the options it was coded by."""

    output: str
    data: bytes
    header: coding.FbsHeader
    stream: FapStream
    faps: tuple[int, ...] | None
    rate: float | None
    translation: bool

    def max_error(self) -> tuple[int | str, float, float] | None:
        """The largest coding error relative to its step: (FAP number or translation axis,
        error in FAP units or ES units, the step); None when nothing is sent."""
        decoded = coding.decode(self.data)
        source = coding.source_stream(
            self.stream, faps=self.faps, rate=self.rate, translation=self.translation
        )
        stats = coding.error_stats(source, decoded)
        if not stats:
            return None
        steps = self.header.steps
        worst = max(stats, key=lambda k: stats[k][0] / steps[k])
        return worst, stats[worst][0], steps[worst]


def encode(options: EncodeOptions) -> Encoded:
    """Code the FAP stream of ``options.input`` as a ``.fbs`` bitstream at
    ``options.output``; warns about FAPs of ``faps`` the stream does not set."""
    from vtts.api.options import check_io
    from vtts.atomic import write_bytes

    check_io(options)
    stream = read_stream(options.input)
    faps = coding.fap_set(options.faps) if options.faps else None
    words = set((options.faps or "").lower().replace(",", " ").split())
    if faps is not None and not words & {"all", "low"}:
        present = {int(k) + 1 for k in stream.mask.any(axis=0).nonzero()[0]}
        missing = [k for k in faps if k not in present]
        if missing:
            warnings.warn(
                FapWarning(
                    f"FAP{'s' if len(missing) > 1 else ''} {', '.join(map(str, missing))} of "
                    "--faps not in the stream: not sent",
                    file=options.input,
                ),
                stacklevel=2,
            )
    data = coding.encode(
        stream,
        faps=faps,
        rate=options.rate,
        quantizer=options.quantizer,
        coder=options.coder,
        translation=options.translation,
    )
    write_bytes(options.output, data)
    header = coding.read_header(data)
    return Encoded(options.output, data, header, stream, faps, options.rate, options.translation)


@dataclass(kw_only=True)
class DecodeOptions:
    """What ``vtts decode`` decodes: ``input``, a ``.fbs`` bitstream, into ``output``, a
    ``.fap`` file (which cannot carry a head translation: it is left out, with a warning)."""

    input: str
    output: str


def decode(options: DecodeOptions) -> FapStream:
    """Decode ``options.input`` into ``options.output``; the decoded stream."""
    from vtts.api.options import check_io

    check_io(options)
    stream = coding.decode(read_fbs_bytes(options.input), file=options.input)
    write_fap(stream, options.output)
    return stream
