"""How many examples the suite's fuzz and property tests draw (Hypothesis's ``max_examples``).

`make test` draws a third of each such test's examples (at least 10): the fuzz tests took 45 s of
the suite's CPU, and the suite must stay within CI's five minutes on two cores. ``VTTS_FUZZ=full
make test`` (or pytest with that variable) draws them all — after changing a parser or a format,
and before a release. Hypothesis chooses new examples each run, so the runs add up."""

from __future__ import annotations

import os

_MODE = os.environ.get("VTTS_FUZZ", "")
if _MODE not in ("", "full"):
    raise ValueError(f"VTTS_FUZZ is 'full' or unset, got {_MODE!r}")
#: Whether every example is drawn (``VTTS_FUZZ=full``).
FULL = _MODE == "full"


def examples(n: int) -> int:
    """The examples to draw of a test written for ``n``: ``n`` under ``VTTS_FUZZ=full``, else a
    third of them, at least 10."""
    return n if FULL else max(10, n // 3)
