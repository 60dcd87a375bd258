"""One BLAS thread for the analysis's small dense algebra.

The estimator solves, per frame and pyramid level, normal equations of a few unknowns over tens
of thousands of pixels (``(N, k)`` by ``(N, k)`` products with ``k`` ≈ 17–25). OpenBLAS splits
such products over all cores and its threads spin while they wait for work; beside Mesa's
rasterizer threads, which the same estimator keeps busy, that made the analysis of Akiyo's first
16 frames take 26.6 s instead of 13.9 s on the 2-core machine (measured 2026-11-25, both
orders). The split also changes the order of the sums from run to run, so that two analyses of
the same video drifted apart by a few FAP units within eight frames; with one thread they are
identical. :func:`one_blas_thread` limits every BLAS library loaded (NumPy's and SciPy's
OpenBLAS) to one thread while its block runs, with threadpoolctl.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

_controller = None


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with one thread in every BLAS library loaded; the previous limits after."""
    global _controller
    from threadpoolctl import ThreadpoolController

    if _controller is None:  # the libraries loaded now: NumPy's and SciPy's are, once imported
        import scipy.linalg  # noqa: F401  (loads SciPy's OpenBLAS, if it is not yet)

        _controller = ThreadpoolController()
    with _controller.limit(limits=1, user_api="blas"):
        yield
