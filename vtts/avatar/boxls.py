"""Box-bounded least squares for many right-hand sides of one small matrix, all at once.

The curves export solves, for every frame, ``min ‖A w − f‖² + λ‖w‖²`` with ``0 ≤ w ≤ 1`` for a
handful of ARKit shapes (``A`` is at most 8 × 5 in the recipe table's blocks). A general solver
(SciPy's ``lsq_linear``) takes a fraction of a millisecond per frame and per block, which adds up
to minutes for a long stream; here the problem is small enough to be solved exactly by its faces.

With ``λ > 0`` the objective is strictly convex, so its minimum over the box is unique and lies
in the relative interior of exactly one face of the box: some variables at 0, some at 1, the
rest free. On that face it is the unconstrained minimum of the restricted problem, a linear
function of ``f``. :func:`box_lstsq` therefore visits every face (3^c of them), solves the
restricted problem for all frames with one matrix product, and keeps, per frame, the feasible
candidate with the lowest objective: each candidate is a point of the box, so none is lower than
the minimum, and the minimum's own face yields it.
"""

from __future__ import annotations

import itertools

import numpy as np

#: Above this many unknowns the 3^c faces cost more than a general solver.
MAX_UNKNOWNS = 8
#: How far outside 0–1 a restricted solution may lie and still count as on its face.
FEASIBLE = 1e-9


def box_lstsq(a: np.ndarray, f: np.ndarray, ridge: float) -> np.ndarray:
    """``(n, c) float64``: for each row of ``f (n, r)`` the ``w`` in ``[0, 1]^c`` minimizing
    ``‖a w − f_i‖² + ridge·‖w‖²``, with ``a (r, c)`` and ``ridge > 0``. Rows of ``f`` that
    repeat are solved once."""
    a = np.asarray(a, dtype=np.float64)
    f = np.asarray(f, dtype=np.float64)
    r, c = a.shape
    if not ridge > 0:
        raise ValueError(f"the ridge must be > 0 (a unique minimum), got {ridge}")
    if not 1 <= c <= MAX_UNKNOWNS:
        raise ValueError(f"box_lstsq solves 1 to {MAX_UNKNOWNS} unknowns, got {c}")
    if f.ndim != 2 or f.shape[1] != r:
        raise ValueError(f"f must be (n, {r}), got shape {f.shape}")
    unique, inverse = np.unique(f, axis=0, return_inverse=True)
    n = unique.shape[0]
    best = np.zeros((n, c))
    best_cost = np.full(n, np.inf)
    gram = a.T @ a + ridge * np.eye(c)
    for states in itertools.product((0, 1, 2), repeat=c):  # 0: at 0, 1: at 1, 2: free
        state = np.array(states)
        free = np.flatnonzero(state == 2)
        w = np.zeros((n, c))
        w[:, state == 1] = 1.0
        if free.size:
            fixed = a[:, state == 1].sum(axis=1)
            # the free variables' normal equations with the others held at their bounds
            rhs = (unique - fixed) @ a[:, free]
            sol = np.linalg.solve(gram[np.ix_(free, free)], rhs.T).T
            ok = np.all((sol >= -FEASIBLE) & (sol <= 1 + FEASIBLE), axis=1)
            w[:, free] = np.clip(sol, 0.0, 1.0)
        else:
            ok = np.ones(n, dtype=bool)
        residual = w @ a.T - unique
        cost = np.einsum("ij,ij->i", residual, residual) + ridge * np.einsum("ij,ij->i", w, w)
        better = ok & (cost < best_cost)
        best[better] = w[better]
        best_cost[better] = cost[better]
    return best[inverse.reshape(-1)]
