"""The frame syntax, shared by encoder and decoder, by whole and streamed bitstreams.

For each frame, in this order: unless the mask is constant, *mask changed?* and the new mask;
FAP 1's and FAP 2's *same as before?* and their changed fields (high-level FAPs are lossless);
the quantized prediction error of each coded low-level FAP the frame sets (predicted, in the
arithmetic mode, from an earlier FAP's error in the same frame where the header pairs them);
the head translation's three errors when it is sent. Each element goes through an
:class:`~vtts.fap.coding.elements.ElementIo`, the coder's.
"""

from __future__ import annotations

import numpy as np

from vtts.fap.coding.elements import ElementIo
from vtts.fap.coding.header import FbsHeader
from vtts.fap.coding.quantizer import MAX_INDEX, Plan, grid_steps
from vtts.fap.stream import EXPRESSION_FIELDS, MAX_TRANSLATION, TRANSLATION_AXES, VISEME_FIELDS

_VISEME_BITS = tuple(hi.bit_length() for _, _, hi in VISEME_FIELDS)
_EXPRESSION_BITS = tuple(hi.bit_length() for _, _, hi in EXPRESSION_FIELDS)


class FrameSyntax:
    """The frame syntax, one frame at a time: what encoder and decoder carry from frame to frame
    (the current mask, each FAP's last index, the high-level fields, the translation's last
    index). :func:`code_frames` runs it over a whole stream,
    :class:`~vtts.fap.coding.packets.StreamEncoder` and
    :class:`~vtts.fap.coding.file.StreamDecoder` frame by frame, so that both forms send the
    very same decisions.

    Channels (a coder's error statistics and contexts): the low-level FAPs 0 … L−1, the
    translation's axes L … L+T−1 (T = 3 when sent, else 0), then the viseme fields (4) and the
    expression fields (6). Without translation they are numbered as in the first bitstreams."""

    def __init__(self, h: FbsHeader) -> None:
        self.h = h
        faps, low = h.faps, h.low
        self.nk, self.nl = len(faps), len(low)
        self.nt = len(h.translation_base_steps)
        self.pos = {k: i for i, k in enumerate(faps)}
        self.low_pos = [self.pos[k] for k in low]
        self.pred = [low.index(h.predictors[k]) if k in h.predictors else -1 for k in low]
        hl = self.nl + self.nt  # the first high-level field's channel
        self.v_fields = [
            (VISEME_FIELDS, _VISEME_BITS, hl),
            (EXPRESSION_FIELDS, _EXPRESSION_BITS, hl + 4),
        ]
        self.t_steps = grid_steps(h.translation_base_steps, h.quantizer).tolist()
        self.t_last = [0] * self.nt
        self.cur = [True] * self.nk
        self.last = [0] * self.nl
        self.last_high = [[0] * 4, [0] * 6]

    def frame(
        self,
        io: ElementIo,
        i: int,
        row: tuple | None = None,
    ) -> tuple[list[bool], list[int], list[int], list[int], list[int]]:
        """Send frame ``i`` (``row`` = ``(mask, index, viseme, expression, translation)``: the
        ``(K,)`` mask of the coded FAPs, the ``(L,)`` indices, the 4 viseme and 6 expression
        fields and the ``(T,)`` translation indices) or read it (``row`` None); return the row
        as the decoder sees it (high-level fields and indices held where not set)."""
        h, nk, nl, cur, pos = self.h, self.nk, self.nl, self.cur, self.pos
        low = h.low
        io.begin_frame()
        if not h.constant_mask:
            want = None if row is None else [bool(x) for x in row[0]]
            changed = io.flag(("mask?",), None if want is None else int(want != cur))
            if changed:
                for j in range(nk):
                    cur[j] = bool(io.flag(("mask", j, cur[j]), None if want is None else want[j]))
        mask = list(cur)
        high_rows = []
        for which in (0, 1):
            prev = self.last_high[which]
            if (which + 1) not in pos or not cur[pos[which + 1]]:
                high_rows.append([0] * len(prev))  # 0 where not set, as reconstruct() has it
                continue
            fields, widths, channel = self.v_fields[which]
            want = None if row is None else [int(x) for x in row[2 + which]]
            same = io.flag(("same", which), None if want is None else int(want == prev))
            if not same:
                for f, (label, lo, hi) in enumerate(fields):
                    value = io.field(
                        channel + f, widths[f], None if want is None else want[f], prev[f]
                    )
                    if not lo <= value <= hi:
                        raise io.error(f"{label} {value} in frame {i} is outside {lo}–{hi}")
                    prev[f] = value
            high_rows.append(list(prev))
        q_now = [0] * nl
        index = [0] * nl
        for j in range(nl):
            if not cur[self.low_pos[j]]:
                continue
            p = self.pred[j]
            base = q_now[p] if p >= 0 and cur[self.low_pos[p]] else 0
            q = None if row is None else int(row[1][j]) - self.last[j]
            v = io.residual(j, None if q is None else q - base)
            q = v + base
            value = self.last[j] + q
            if not -MAX_INDEX < value < MAX_INDEX:
                raise io.error(f"FAP {low[j]} leaves the codable range in frame {i}")
            self.last[j] = value
            q_now[j] = q
            index[j] = value
        t_row = [0] * self.nt
        for a in range(self.nt):
            q = None if row is None else int(row[4][a]) - self.t_last[a]
            value = self.t_last[a] + io.residual(nl + a, q)
            if not abs(value * self.t_steps[a]) <= MAX_TRANSLATION:
                raise io.error(
                    f"the head translation's {TRANSLATION_AXES[a]} leaves ±{MAX_TRANSLATION:g} "
                    f"ES units in frame {i}"
                )
            self.t_last[a] = value
            t_row[a] = value
        return mask, index, high_rows[0], high_rows[1], t_row


def code_frames(io: ElementIo, h: FbsHeader, plan: Plan | None) -> tuple[np.ndarray, ...]:
    """Send (``plan`` given) or read the frames; return ``(mask, index, viseme, expression,
    translation)`` as the decoder sees them: ``(n, K) bool``, ``(n, L) int64``, ``(n, 4)`` and
    ``(n, 6) int64``, and the translation's indices ``(n, 3) int64`` (``(n, 0)`` when not sent).
    The channels are :class:`FrameSyntax`'s."""
    n = h.n_frames
    nk, nl, nt = len(h.faps), len(h.low), len(h.translation_base_steps)
    syntax = FrameSyntax(h)
    t_index = np.zeros((n, nt), dtype=np.int64)
    mask = np.zeros((n, nk), dtype=bool)
    index = np.zeros((n, nl), dtype=np.int64)
    high = [np.zeros((n, 4), dtype=np.int64), np.zeros((n, 6), dtype=np.int64)]
    for i in range(n):
        row = None if plan is None else _plan_row(plan, i)
        m, x, v, e, t = syntax.frame(io, i, row)
        mask[i], index[i], high[0][i], high[1][i], t_index[i] = m, x, v, e, t
    if plan is not None:
        assert np.array_equal(mask, plan.mask) and np.array_equal(index, plan.index)
        assert nt == 0 or np.array_equal(t_index, plan.translation_index)
    return mask, index, high[0], high[1], t_index


def _plan_row(plan: Plan, i: int) -> tuple:
    """Frame ``i`` of ``plan`` as :meth:`FrameSyntax.frame` sends it. Where FAP 1 or 2 is not
    coded its fields are not read."""
    src = plan.source
    return (
        plan.mask[i].tolist(),
        plan.index[i].tolist(),
        None if src.viseme is None else src.viseme[i].tolist(),
        None if src.expression is None else src.expression[i].tolist(),
        () if plan.translation_index is None else plan.translation_index[i].tolist(),
    )
