"""The syntax elements a frame is made of, and the interface each entropy coder implements.

A frame (:class:`~vtts.fap.coding.frame.FrameSyntax`) is a sequence of three kinds of element:
flags (one decision in a context), the high-level FAPs' fields and the quantized prediction
errors of the low-level FAPs and the head translation. Each coder
(:mod:`~vtts.fap.coding.huffman`, :mod:`~vtts.fap.coding.range_coder`) sends them its own way;
the same calls encode (a value given) and decode (``None``), so that encoder and decoder walk the
very same syntax.
"""

from __future__ import annotations

from vtts.errors import CodingError


class ElementIo:
    """One coder's way of sending the syntax elements. Each method sends ``value`` and returns
    it when encoding (``value`` given), and returns the value read when decoding (``None``)."""

    def begin_frame(self) -> None:
        pass

    def flag(self, ctx: tuple, bit: int | None) -> int:
        raise NotImplementedError

    def field(self, channel: int, nbits: int, value: int | None, prev: int) -> int:
        raise NotImplementedError

    def residual(self, channel: int, value: int | None) -> int:
        raise NotImplementedError

    def offset(self) -> int:
        """Byte offset (in the whole bitstream) of the data being read, for error messages."""
        return 0

    def error(self, message: str) -> CodingError:
        return CodingError(message, offset=self.offset(), file=getattr(self, "file", None))
