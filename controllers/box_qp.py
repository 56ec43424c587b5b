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

import math

import numpy as np
from scipy.linalg import lapack

_posv = lapack.dposv

#: free variables up to which the linear solve is done in plain Python (:func:`_small_solve`), cheaper than
#: LAPACK's call and its list conversions on so few numbers (most bounded ticks of the allocation); posv above
_SMALL = 2


def _small_solve(a: list[list[float]], b: list[float]) -> list[float] | None:
    """x with A x = b for k <= 2 unknowns, A symmetric positive definite given as k lists of k floats (its upper
    triangle read, as LAPACK's posv, by the same Cholesky factorisation A = R^T R written out); None when A is
    not positive definite (as posv's info > 0)."""
    a00 = a[0][0]
    if a00 <= 0.0:
        return None
    if len(b) == 1:
        return [b[0] / a00]
    r00 = math.sqrt(a00)
    r01 = a[0][1] / r00
    d = a[1][1] - r01 * r01
    if d <= 0.0:
        return None
    r11 = math.sqrt(d)
    y0 = b[0] / r00
    x1 = (b[1] - r01 * y0) / r11 / r11
    return [(y0 - r01 * x1) / r00, x1]


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
    slack = tolerance * max(1.0, max(gl), -min(gl))  # max(1, |g|_inf)
    above, indices = 1.0 + slack, range(n)
    for iteration in range(1, max_iterations + 1):
        free = [i for i, lo, up in zip(indices, lower, upper) if not (lo or up)]
        high = [i for i, up in zip(indices, upper) if up]
        x = [1.0 if up else 0.0 for up in upper]
        if free:
            rows = [hl[i] for i in free]
            rhs = [-gl[i] - sum(row[j] for j in high) for i, row in zip(free, rows, strict=True)]
            matrix = [[row[j] for j in free] for row in rows]
            if len(free) <= _SMALL:
                solution = _small_solve(matrix, rhs)
                if solution is None:
                    return None
            else:
                solution, info = _posv(matrix, rhs)[1:]
                if info != 0:
                    return None
                solution = solution.tolist()
            for i, value in zip(free, solution, strict=True):
                x[i] = value
        xa = np.array(x)
        grad = (h.dot(xa) + g).tolist()
        # at 0: stays while its multiplier (the gradient) is >= 0; free: joins the bound it crossed; at 1: stays
        # while the gradient is <= 0 (lower and upper are disjoint)
        new_lower = [d >= -slack if lo else not up and v < -slack for lo, up, v, d in zip(lower, upper, x, grad)]
        new_upper = [d <= slack if up else not lo and v > above for lo, up, v, d in zip(lower, upper, x, grad)]
        if new_lower == lower and new_upper == upper:
            if min(x) < 0.0 or max(x) > 1.0:  # a free variable within the slack of a bound, outside it
                xa = np.minimum(np.maximum(xa, 0.0), 1.0)
            return xa, lower, upper, iteration
        lower, upper = new_lower, new_upper
    return None


__all__ = ["solve_box_qp"]
