"""Arithmetic mode: an adaptive binary range coder with context modelling.

LZMA's carry-propagating range coder (32-bit, 16-bit probabilities estimated from halved counts)
under context modelling, so no table is sent: q is binarized as zero? / sign / magnitude class
(unary) / mantissa bits, each decision with its own adaptive probability per channel,
conditioned on the previous error of the same channel and on whether the channel coded just
before it in the frame moved. A FAP may also be predicted from another FAP's error in the same
frame (:func:`choose_predictors`: the earlier FAP of the same unit and step that lowers its
estimated cost most, e.g. the right eyebrow from the left, FAP 54 from 53); the pairs are listed
in the header.

No library is used: entropy-coding libraries such as constriction take the probabilities as
given, so the adaptive modelling would be ours anyway, and the binary range coder under it is a
few dozen lines of exact integer arithmetic, one code path for encoder and decoder.
"""

from __future__ import annotations

import numpy as np

from vtts.fap.coding.elements import ElementIo
from vtts.fap.coding.quantizer import MAX_MAGNITUDE_BITS, Plan
from vtts.fap.table import FAPS

_PROB_BITS = 16
_PROB_ONE = 1 << _PROB_BITS
_PROB_MIN = 32
_HALF = _PROB_ONE // 2
_COUNT_LIMIT = 60  # counts are halved beyond this: the estimate follows changes in the stream
_TOP = 1 << 24
_MANTISSA_CONTEXT_BITS = 8  # magnitudes up to 2^8 have adaptive mantissa bits, larger bypass


def _magnitude_class(v: int) -> int:
    v = abs(v)
    return 0 if v == 0 else 1 if v == 1 else 2 if v < 4 else 3


class _Adaptive(ElementIo):
    """The context modelling of the arithmetic mode over an abstract binary coder ``code``."""

    def __init__(self) -> None:
        self.models: dict[tuple, list[int]] = {}
        self.prev: dict[int, int] = {}
        self.active = 0

    def code(self, bit: int | None, p0: int) -> int:
        raise NotImplementedError

    def bit(self, ctx: tuple | None, bit: int | None) -> int:
        if ctx is None:
            return self.code(bit, _HALF)
        m = self.models.get(ctx)
        if m is None:
            m = self.models[ctx] = [0, 0]
        n0, n1 = m
        p0 = ((2 * n0 + 1) << _PROB_BITS) // (2 * (n0 + n1) + 2)
        p0 = min(max(p0, _PROB_MIN), _PROB_ONE - _PROB_MIN)
        b = self.code(bit, p0)
        m[b] += 1
        if n0 + n1 >= _COUNT_LIMIT:
            m[0] = (m[0] + 1) // 2
            m[1] = (m[1] + 1) // 2
        return b

    def begin_frame(self) -> None:
        self.active = 0

    def flag(self, ctx: tuple, bit: int | None) -> int:
        return self.bit(ctx, bit)

    def field(self, channel: int, nbits: int, value: int | None, prev: int) -> int:
        d = self.residual(channel, None if value is None else value - prev)
        return prev + d

    def residual(self, channel: int, value: int | None) -> int:
        enc = value is not None
        prev = self.prev.get(channel, 0)
        c = _magnitude_class(prev)
        nonzero = self.bit(("z", channel, c, self.active), None if not enc else int(value != 0))
        if not nonzero:
            self.prev[channel] = 0
            self.active = 0
            return 0
        sign_ctx = 0 if prev == 0 else 1 if prev > 0 else 2
        negative = self.bit(("s", channel, sign_ctx), None if not enc else int(value < 0))
        m = abs(value) if enc else 0  # type: ignore[arg-type]
        e = m.bit_length()
        k = 1
        while k < MAX_MAGNITUDE_BITS:
            more = self.bit(("e", channel, min(c, 2), min(k, 12)), None if not enc else int(e > k))
            if not more:
                break
            k += 1
        magnitude = 1
        for b in range(k - 2, -1, -1):
            ctx = ("m", channel, k, b) if k <= _MANTISSA_CONTEXT_BITS else None
            magnitude = (magnitude << 1) | self.bit(ctx, None if not enc else (m >> b) & 1)
        v = -magnitude if negative else magnitude
        self.prev[channel] = v
        self.active = 1
        return v


class RangeWriter(_Adaptive):
    """LZMA's range encoder: 32-bit range, carries propagated through a cached byte."""

    def __init__(self) -> None:
        super().__init__()
        self.low = 0
        self.range = 0xFFFFFFFF
        self.cache = 0
        self.pending = 1
        self.out = bytearray()

    def code(self, bit: int | None, p0: int) -> int:
        bound = (self.range >> _PROB_BITS) * p0
        if bit:
            self.low += bound
            self.range -= bound
        else:
            self.range = bound
        while self.range < _TOP:
            self.range <<= 8
            self._shift_low()
        return int(bit)  # type: ignore[arg-type]

    def _shift_low(self) -> None:
        low = self.low
        if (low & 0xFFFFFFFF) < 0xFF000000 or low >> 32:
            carry = low >> 32
            temp = self.cache
            while self.pending:
                self.out.append((temp + carry) & 0xFF)
                temp = 0xFF
                self.pending -= 1
            self.cache = (low >> 24) & 0xFF
        self.pending += 1
        self.low = (low & 0x00FFFFFF) << 8

    def packet(self) -> bytes:
        """End a packet of a streamed bitstream: the fewest bytes that decode what was coded
        (the decoder reads zeros after them), then start the coder anew; the contexts stay.

        After renormalization the range is at least 2^24, so ``[low, low + range)`` holds a
        multiple of 2^24: coding it takes the pending bytes and at most one more, and the zero
        bytes at the end are left out."""
        self.low = (self.low + 0xFFFFFF) & ~0xFFFFFF
        self._shift_low()
        self._shift_low()
        out = self.out
        assert out[0] == 0  # the first byte is always 0: not sent
        data = bytes(out[1:]).rstrip(b"\0")
        self.low, self.range, self.cache, self.pending = 0, 0xFFFFFFFF, 0, 1
        self.out = bytearray()
        return data

    def finish(self) -> bytes:
        for _ in range(5):
            self._shift_low()
        assert self.out[0] == 0  # the first byte is always 0: not sent
        return bytes(self.out[1:])


class RangeReader(_Adaptive):
    """The range decoder. ``pad``: a packet of a streamed bitstream, read as if zeros followed
    it (:meth:`RangeWriter.packet`)."""

    def __init__(self, data: bytes, base: int, file: str | None, pad: bool = False) -> None:
        super().__init__()
        self.file = file
        self.pad = pad
        self.start(data, base)

    def start(self, data: bytes, base: int) -> None:
        """Start decoding ``data`` (at offset ``base`` of the bitstream); the contexts stay."""
        self.data = data
        self.pos = 0
        self.base = base
        self.range = 0xFFFFFFFF
        self.code_value = 0
        for _ in range(4):
            self.code_value = (self.code_value << 8) | self._byte()

    def offset(self) -> int:
        return self.base + self.pos

    def _byte(self) -> int:
        if self.pos >= len(self.data):
            if self.pad:
                self.pos += 1
                return 0
            raise self.error("unexpected end of the frame data")
        b = self.data[self.pos]
        self.pos += 1
        return b

    def code(self, bit: int | None, p0: int) -> int:
        bound = (self.range >> _PROB_BITS) * p0
        if self.code_value < bound:
            self.range = bound
            b = 0
        else:
            self.code_value -= bound
            self.range -= bound
            b = 1
        while self.range < _TOP:
            self.range <<= 8
            self.code_value = ((self.code_value << 8) | self._byte()) & 0xFFFFFFFF
        return b

    def finish(self) -> None:
        if self.pos != len(self.data):
            raise self.error(f"{len(self.data) - self.pos} unused bytes after the last frame")


def _errors(plan: Plan) -> np.ndarray:
    """``(n, L) int64``: each low-level FAP's quantized prediction error (0 where not set)."""
    q = np.zeros_like(plan.index)
    low_mask = plan.mask[:, [plan.faps.index(k) for k in plan.low]]
    for j in range(len(plan.low)):
        rows = np.flatnonzero(low_mask[:, j])
        idx = plan.index[rows, j]
        q[rows, j] = np.diff(idx, prepend=0)
    return q


def _cost(v: np.ndarray) -> float:
    """Estimated bits to send the errors ``v`` (1-D): the entropy of their magnitude classes and
    signs plus the mantissa bits — what the adaptive binarization approaches."""
    if v.size == 0:
        return 0.0
    a = np.abs(v)
    cls = np.where(a <= 8, v, np.sign(v) * (8 + np.ceil(np.log2(np.maximum(a, 1)))))
    _, counts = np.unique(cls, return_counts=True)
    p = counts / v.size
    mantissa = np.where(a > 8, np.floor(np.log2(np.maximum(a, 1))), 0).sum()
    return float(-(counts * np.log2(p)).sum() + mantissa)


def choose_predictors(plan: Plan) -> dict[int, int]:
    """For each low-level FAP, the earlier FAP (same unit and step) whose error in the same frame
    best predicts its error, where that saves more than the header entry costs."""
    q = _errors(plan)
    low_mask = plan.mask[:, [plan.faps.index(k) for k in plan.low]]
    chosen = {}
    for j, k in enumerate(plan.low):
        rows = low_mask[:, j]
        if rows.sum() < 2:
            continue
        best, best_cost = -1, _cost(q[rows, j]) - 24.0  # a header entry costs 16 bits
        for p in range(j):
            kp = plan.low[p]
            if FAPS[kp - 1].fapu != FAPS[k - 1].fapu or plan.base_steps[p] != plan.base_steps[j]:
                continue
            v = q[:, j] - np.where(low_mask[:, p], q[:, p], 0)
            cost = _cost(v[rows])
            if cost < best_cost:
                best, best_cost = p, cost
        if best >= 0:
            chosen[k] = plan.low[best]
    return chosen
