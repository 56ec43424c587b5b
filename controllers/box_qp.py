"""A small box-constrained QP solved exactly by a primal-dual active-set method (the allocation's bounded
route).

.. math:: \\min_x \\tfrac12 x^T H x + g^T x \\quad \\text{s.t.}\\; 0 \\le x \\le 1,

H symmetric positive definite, n small (the allocation: 8 variables for the FPR, 4 for the prototype).
The method (Hintermüller, Ito and Kunisch's primal-dual active set, a semi-smooth Newton method on the KKT
conditions) guesses which variables sit at 0 and which at 1, solves the others from
H_FF x_F = -(g_F + H_FA x_A) (a Cholesky solve), and revises the guess: a free variable outside [0, 1] joins
the bound it crossed, a bound variable whose multiplier has the wrong sign (the gradient pushes it inside)
leaves it. When the guess repeats, x is feasible and every multiplier has the right sign: the KKT conditions
of the convex QP hold and x is *the* minimiser, to round-off (no solver tolerance). Warm-started from the
previous control tick's active bounds it usually ends after one solve (1.24 on average along the saturating
closed loop of :mod:`fpr.cli.bench.loop_allocation`).

It is not guaranteed to converge for every H (it may cycle when H is far from an M-matrix): after
``max_iterations`` :func:`solve_box_qp` returns None and the caller falls back to ProxQP
(:class:`controllers.allocation.Allocator`).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

_posv = lapack.dposv
def solve_box_qp(h: np.ndarray, g: np.ndarray, lower: list[bool], upper: list[bool], max_iterations: int = 12,
                 tolerance: float = 1e-12):
    """Minimise 0.5 x^T H x + g^T x over the box [0, 1]^n from a guess of the active bounds.

    Args:
        h: H, shape (n, n), symmetric positive definite (the solves read its upper triangle).
        g: g, shape (n,).
        lower: the first guess of the variables at 0, n booleans (not modified).
        upper: the first guess of the variables at 1, n booleans (disjoint from ``lower``).
        max_iterations: linear solves before giving up.
        tolerance: slack on the bounds and on the multipliers' signs, relative to max(1, |g|_inf).

    Returns:
        (x, lower, upper, iterations): the minimiser, shape (n,), the final active bounds (lists of booleans)
        and the number of linear solves; or None when the guesses cycled or a solve failed.
    """
    n = g.shape[0]
    # plain Python on lists between the solves: each numpy call on so few numbers costs microseconds
    hl, gl = h.tolist(), g.tolist()
    lower, upper = list(lower), list(upper)
    slack = tolerance * max(1.0, max(abs(v) for v in gl))
    for iteration in range(1, max_iterations + 1):
        free = [i for i in range(n) if not (lower[i] or upper[i])]
        high = [j for j in range(n) if upper[j]]
        x = [1.0 if upper[i] else 0.0 for i in range(n)]
        if free:
            rows = [hl[i] for i in free]
            rhs = [-gl[i] - sum(row[j] for j in high) for i, row in zip(free, rows, strict=True)]
            solution, info = _posv([[row[j] for j in free] for row in rows], rhs)[1:]
            if info != 0:
                return None
            for i, value in zip(free, solution.tolist(), strict=True):
                x[i] = value
        grad = (h.dot(np.array(x)) + g).tolist()
        new_lower = [lower[i] and grad[i] >= -slack or (not lower[i] and not upper[i] and x[i] < -slack)
                     for i in range(n)]
        new_upper = [upper[i] and grad[i] <= slack or (not lower[i] and not upper[i] and x[i] > 1.0 + slack)
                     for i in range(n)]
        if new_lower == lower and new_upper == upper:
            return np.array([min(max(v, 0.0), 1.0) for v in x]), lower, upper, iteration
        lower, upper = new_lower, new_upper
    return None


__all__ = ["solve_box_qp"]
