"""Huffman mode, the paper's: 7-bit symbols with an escape, canonical codes chosen per stream.

The quantized prediction error q is a 7-bit symbol: −63…63 directly, and −64 is an escape
followed by the Exp-Golomb code (order 0) of q's zigzag, for larger jumps and for errors a table
has no code for. The canonical codes (lengths ≤ 15 bits) are built from the stream's own symbol
counts (two passes: :class:`ErrorCounter`, then :class:`HuffmanWriter`) and their code lengths
are stored in the header (:func:`pack_table`). One to four tables serve the FAPs, whichever
needs the fewest bits (:func:`choose_tables`).
"""

from __future__ import annotations

import heapq
import math

from vtts.errors import CodingError
from vtts.fap.coding.elements import ElementIo
from vtts.fap.coding.quantizer import MAX_MAGNITUDE_BITS

#: Huffman mode: symbols −63…63 are errors sent directly, −64 escapes a larger one.
ESCAPE = -64
SYMBOL_MAX = 63
MAX_CODE_LENGTH = 15


def zigzag(s: int) -> int:
    """0, −1, 1, −2, 2, … ↦ 0, 1, 2, 3, 4, …: the order of a table's symbols and of an
    escaped error."""
    return 2 * s if s >= 0 else -2 * s - 1


def unzigzag(z: int) -> int:
    """The inverse of :func:`zigzag`."""
    return z >> 1 if not z & 1 else -((z + 1) >> 1)


def pack_table(lengths: dict[int, int]) -> bytes:
    """A code's lengths: the count n of entries, then 4-bit lengths of the escape and of the
    symbols 0, −1, 1, −2, 2, … (n of them), two per byte."""
    n = max((zigzag(s) + 1 for s in lengths if s != ESCAPE), default=0)
    nibbles = [lengths.get(ESCAPE, 0)] + [lengths.get(unzigzag(z), 0) for z in range(n)]
    if len(nibbles) % 2:
        nibbles.append(0)
    pairs = zip(nibbles[::2], nibbles[1::2], strict=True)
    return bytes([n]) + bytes((a << 4) | b for a, b in pairs)


def _symbol(q: int, lengths: dict[int, int] | None = None) -> int:
    """The symbol that sends error ``q``: q itself, or the escape for |q| > 63 and for errors
    the table has no code for."""
    if -SYMBOL_MAX <= q <= SYMBOL_MAX and (lengths is None or q in lengths):
        return q
    return ESCAPE


def _exp_golomb_bits(x: int) -> int:
    return 2 * (x + 1).bit_length() - 1


def huffman_lengths(counts: dict[int, int], limit: int = MAX_CODE_LENGTH) -> dict[int, int]:
    """Code lengths of a Huffman code for symbol ``counts`` (ties broken by symbol, so the
    result is deterministic), no longer than ``limit`` bits: if the optimal code is deeper, the
    counts are halved until it fits. A single symbol gets length 1."""
    items = sorted((s, c) for s, c in counts.items() if c > 0)
    if not items:
        return {}
    if len(items) == 1:
        return {items[0][0]: 1}
    while True:
        depth = _leaf_depths([c for _, c in items])
        if max(depth) <= limit:
            return {s: d for (s, _), d in zip(items, depth, strict=True)}
        items = [(s, (c + 1) // 2) for s, c in items]


def _leaf_depths(weights: list[int]) -> list[int]:
    """The depth of each leaf of the Huffman tree of ``weights`` (at least two): the two lightest
    nodes merged first, ties to the one made first (the leaves in order, then the merged nodes
    as they are made)."""
    n = len(weights)
    heap = [(c, i) for i, c in enumerate(weights)]
    heapq.heapify(heap)
    parent = [0] * (2 * n - 1)
    for node in range(n, 2 * n - 1):
        c1, a = heapq.heappop(heap)
        c2, b = heapq.heappop(heap)
        parent[a] = parent[b] = node
        heapq.heappush(heap, (c1 + c2, node))
    depth = [0] * (2 * n - 1)  # the root, node 2n - 2, at 0
    for node in range(2 * n - 3, -1, -1):  # a parent is made after its children
        depth[node] = depth[parent[node]] + 1
    return depth[:n]


def _code_cost(errors: dict[int, int], lengths: dict[int, int]) -> float:
    """Bits to send the errors (error → count) with a code; inf if it cannot."""
    bits = 0
    for q, c in errors.items():
        s = _symbol(q, lengths)
        if s not in lengths:
            return math.inf
        bits += c * lengths[s]
        if s == ESCAPE:
            bits += c * _exp_golomb_bits(zigzag(q))
    return bits


def _group_code(errors: list[dict[int, int]], escape: bool, trim: bool = False) -> dict[int, int]:
    """The Huffman code for a group of FAPs' errors. ``escape``: give the escape a code even if
    no error needs it (so that any FAP can use the table). ``trim``: also choose how many
    symbols the table lists, the rarer large errors going through the escape, for the fewest
    bits of table plus data."""
    merged: dict[int, int] = {}
    for e in errors:
        for q, c in e.items():
            merged[q] = merged.get(q, 0) + c
    # The table lists the first n symbols of the zigzag order (n = the cutoff); the other errors
    # go through the escape. Symbols: (zigzag, error, count), in zigzag order.
    symbols = sorted((zigzag(q), q, c) for q, c in merged.items() if -SYMBOL_MAX <= q <= SYMBOL_MAX)
    # escaped by every cutoff: errors beyond the symbols, (count, bits)
    beyond = [(c, c * _exp_golomb_bits(zigzag(q))) for q, c in merged.items()
              if not -SYMBOL_MAX <= q <= SYMBOL_MAX]  # fmt: skip
    if not trim:
        return huffman_lengths(_counts(symbols, beyond, escape))
    best: tuple[float, dict[int, int]] | None = None
    sent = [(c, c * _exp_golomb_bits(z)) for z, _, c in symbols]  # each symbol escaped
    for k in range(len(symbols) + 1):  # the cutoffs 0, then each symbol's zigzag + 1
        escaped = beyond + sent[k:]
        counts = _counts(symbols[:k], escaped, escape)
        lengths = huffman_lengths(counts)
        bits = sum(b for _, b in escaped) + sum(c * lengths[s] for s, c in counts.items())
        bits += 8 * _table_size(lengths)
        if best is None or bits < best[0]:
            best = (bits, lengths)
    return best[1] if best else {}


def _counts(
    listed: list[tuple[int, int, int]], escaped: list[tuple[int, int]], escape: bool
) -> dict[int, int]:
    """Symbol counts of a table that lists ``listed`` ((zigzag, error, count)) and sends the
    ``escaped`` errors ((count, bits)) through the escape, which has a code if any error needs
    it or ``escape``."""
    counts = {q: c for _, q, c in listed}
    if escape or escaped:
        counts[ESCAPE] = int(escape) + sum(c for c, _ in escaped)
    return counts


def _table_size(lengths: dict[int, int]) -> int:
    """``len(pack_table(lengths))``: the count byte, then two 4-bit lengths to a byte."""
    n = max((zigzag(s) + 1 for s in lengths if s != ESCAPE), default=0)
    return 1 + (n + 2) // 2


def choose_tables(errors: list[dict[int, int]]) -> tuple[tuple[dict[int, int], ...], tuple]:
    """Huffman tables for the FAPs' errors (``errors[j]``: error → count of low-level FAP j) and
    the table of each FAP: 1 to 4 tables, the FAPs grouped by k-means on their code cost, the
    number that needs the fewest bits with the tables' header bytes counted."""
    used = [j for j, e in enumerate(errors) if e]
    if not used:
        return (), ()
    single = _group_code(errors, escape=False, trim=True)
    best = (_code_cost_all(errors, [single], [0] * len(errors)), (single,), (0,) * len(errors))
    # start groups: FAPs ordered by how often they do not move
    order = sorted(used, key=lambda j: -errors[j].get(0, 0) / sum(errors[j].values()))
    for n_tables in range(2, min(4, len(used)) + 1):
        assign = [0] * len(errors)
        for rank, j in enumerate(order):
            assign[j] = rank * n_tables // len(order)
        for _ in range(10):
            groups = [[errors[j] for j in used if assign[j] == t] for t in range(n_tables)]
            if not all(groups):
                break
            tables = [_group_code(g, escape=True) for g in groups]
            new = list(assign)
            for j in used:
                costs = [_code_cost(errors[j], tb) for tb in tables]
                new[j] = costs.index(min(costs))
            if new == assign:
                break
            assign = new
        groups = [[errors[j] for j in used if assign[j] == t] for t in range(n_tables)]
        if not all(groups):
            continue
        tables = [_group_code(g, escape=True, trim=True) for g in groups]
        bits = _code_cost_all(errors, tables, assign) + 8 * ((2 * len(errors) + 7) // 8)
        if bits < best[0]:
            best = (bits, tuple(tables), tuple(assign))
    return best[1], best[2]


def _code_cost_all(errors: list[dict[int, int]], tables: list, assign: list[int]) -> float:
    data = sum(_code_cost(e, tables[assign[j]]) for j, e in enumerate(errors) if e)
    return data + 8 * sum(len(pack_table(t)) for t in tables)


def _canonical(lengths: dict[int, int]) -> tuple[dict[int, tuple[int, int]], list[int], list[int]]:
    """Canonical codes ``symbol → (code, length)``, and for decoding the number of codes of each
    length (index 0…15) and the symbols in code order."""
    order = sorted(lengths, key=lambda s: (lengths[s], s))
    codes = {}
    code = prev = 0
    for s in order:
        code <<= lengths[s] - prev
        prev = lengths[s]
        codes[s] = (code, prev)
        code += 1
    counts = [0] * (MAX_CODE_LENGTH + 1)
    for n in lengths.values():
        counts[n] += 1
    return codes, counts, order


class ErrorCounter(ElementIo):
    """First pass of the Huffman encoder: counts each FAP's errors."""

    def __init__(self, n_low: int) -> None:
        self.errors: list[dict[int, int]] = [{} for _ in range(n_low)]

    def flag(self, ctx: tuple, bit: int | None) -> int:
        return int(bit)  # type: ignore[arg-type]

    def field(self, channel: int, nbits: int, value: int | None, prev: int) -> int:
        return int(value)  # type: ignore[arg-type]

    def residual(self, channel: int, value: int | None) -> int:
        q = int(value)  # type: ignore[arg-type]
        e = self.errors[channel]
        e[q] = e.get(q, 0) + 1
        return q


class HuffmanWriter(ElementIo):
    """Second pass of the Huffman encoder: the frames' bits with the chosen tables
    (``table_of``: the table of each channel), the last byte padded with zeros."""

    def __init__(self, tables: tuple[dict[int, int], ...], table_of: tuple[int, ...]) -> None:
        self.tables = [(lengths, _canonical(lengths)[0]) for lengths in tables]
        self.table_of = table_of
        self.out = bytearray()
        self.acc = 0
        self.nbits = 0

    def bits(self, value: int, n: int) -> None:
        self.acc = (self.acc << n) | value
        self.nbits += n
        while self.nbits >= 8:
            self.nbits -= 8
            self.out.append((self.acc >> self.nbits) & 0xFF)
        self.acc &= (1 << self.nbits) - 1

    def flag(self, ctx: tuple, bit: int | None) -> int:
        self.bits(int(bit), 1)  # type: ignore[arg-type]
        return int(bit)  # type: ignore[arg-type]

    def field(self, channel: int, nbits: int, value: int | None, prev: int) -> int:
        self.bits(int(value), nbits)  # type: ignore[arg-type]
        return int(value)  # type: ignore[arg-type]

    def residual(self, channel: int, value: int | None) -> int:
        q = int(value)  # type: ignore[arg-type]
        lengths, codes = self.tables[self.table_of[channel]]
        s = _symbol(q, lengths)
        self.bits(*codes[s])
        if s == ESCAPE:  # Exp-Golomb (order 0) of the zigzagged error
            x = zigzag(q) + 1
            n = x.bit_length()
            self.bits(0, n - 1)
            self.bits(x, n)
        return q

    def finish(self) -> bytes:
        if self.nbits:
            self.bits(0, 8 - self.nbits)
        return bytes(self.out)


class HuffmanReader(ElementIo):
    """The Huffman decoder of the frame data ``data``, which starts at byte ``base`` of the
    bitstream (for error messages)."""

    def __init__(
        self,
        data: bytes,
        base: int,
        tables: tuple[dict[int, int], ...],
        table_of: tuple[int, ...],
        file: str | None,
    ) -> None:
        self.tables = [_canonical(lengths)[1:] for lengths in tables]
        self.table_of = table_of
        self.data = data
        self.end = 8 * len(data)
        self.pos = 0
        self.base = base
        self.file = file

    def offset(self) -> int:
        return self.base + min(self.pos, self.end) // 8

    def bit(self) -> int:
        pos = self.pos
        if pos >= self.end:
            raise self.error("unexpected end of the frame data")
        self.pos = pos + 1
        return (self.data[pos >> 3] >> (7 - (pos & 7))) & 1

    def read(self, n: int) -> int:
        value = 0
        for _ in range(n):
            value = (value << 1) | self.bit()
        return value

    def flag(self, ctx: tuple, bit: int | None) -> int:
        return self.bit()

    def field(self, channel: int, nbits: int, value: int | None, prev: int) -> int:
        return self.read(nbits)

    def residual(self, channel: int, value: int | None) -> int:
        start = self.offset()
        if not self.tables:
            raise self.error("a frame sends a FAP error but the header has no Huffman table")
        counts, symbols = self.tables[self.table_of[channel]]
        code = first = index = 0
        for length in range(1, MAX_CODE_LENGTH + 1):
            code |= self.bit()
            count = counts[length]
            if code - first < count:
                s = symbols[index + code - first]
                break
            index += count
            first = (first + count) << 1
            code <<= 1
        else:
            raise CodingError("invalid Huffman code", offset=start, file=self.file)
        if s != ESCAPE:
            return s
        zeros = 0
        while not self.bit():
            zeros += 1
            if zeros > MAX_MAGNITUDE_BITS:
                raise self.error("escape code longer than any codable error")
        return unzigzag(((1 << zeros) | self.read(zeros)) - 1)

    def finish(self) -> None:
        if self.end - self.pos >= 8:
            raise self.error(f"{(self.end - self.pos) // 8} unused bytes after the last frame")
        if self.pos < self.end and self.read(self.end - self.pos):
            raise self.error("non-zero padding bits after the last frame")
