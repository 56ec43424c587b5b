r"""A small box-constrained QP solved exactly by a primal-dual active-set method (the allocation's bounded
route).

.. math:: \min_x \tfrac12 x^T H x + g^T x \quad \text{s.t.}\; 0 \le x \le 1,

H symmetric positive definite, n small (the allocation: 8 variables for the FPR, 4 for the prototype).
The method (Hintermüller, Ito and Kunisch's primal-dual active set, a semi-smooth Newton method on the KKT
conditions) guesses which variables sit at 0 and which at 1, solves the others from
H_FF x_F = -(g_F + H_FA x_A) (a Cholesky solve), and revises the guess: a free variable outside [0, 1] joins
the bound it crossed, a bound variable whose multiplier has the wrong sign (the gradient pushes it inside)
leaves it. When the guess repeats, x is feasible and every multiplier has the right sign: the KKT conditions
of the convex QP hold and x is *the* minimiser, to round-off (no solver tolerance). Warm-started from the
previous control tick's active bounds it usually ends after one solve (1.24 on average along the saturating
closed loop of :mod:`fpr.cli.bench.loop_allocation`).

:func:`solve_box_qp` takes the guess as two lists of booleans; :func:`solve_box_qp_state`, the allocator's
per-tick path, as one tuple of states (:data:`FREE`, :data:`AT_LOWER`, :data:`AT_UPPER`) and returns x as
plain floats: a Python step or a numpy call fewer wherever it could (each costs about a microsecond here).

It is not guaranteed to converge for every H (it may cycle when H is far from an M-matrix): after
``max_iterations`` :func:`solve_box_qp` returns None and the caller falls back to ProxQP
(:class:`controllers.allocation.Allocator`).
"""

from __future__ import annotations

import functools
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
    not positive definite (as posv's info > 0). :func:`solve_box_qp_state` has these lines inline (a call and
    the lists fewer per tick); tests hold the two equal, and this one equal to posv.
    """
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


#: the state of one variable in a guess (:func:`solve_box_qp_state`)
FREE, AT_LOWER, AT_UPPER = 0, 1, 2


def solve_box_qp(h: np.ndarray, g: np.ndarray, lower, upper, max_iterations: int = 12, tolerance: float = 1e-12):
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
    state = tuple([AT_UPPER if up else AT_LOWER if lo else FREE for lo, up in zip(lower, upper, strict=True)])
    found = solve_box_qp_state(h, g, state, max_iterations, tolerance)
    if found is None:
        return None
    x, state, iterations = found
    return np.array(x), [s == AT_LOWER for s in state], [s == AT_UPPER for s in state], iterations


def solve_box_qp_state(h: np.ndarray, g: np.ndarray, state: tuple[int, ...], max_iterations: int = 12,
                       tolerance: float = 1e-12):
    """:func:`solve_box_qp` on a guess given as one tuple of :data:`FREE`, :data:`AT_LOWER`, :data:`AT_UPPER`, x
    returned as a sequence of floats (the allocator's per-tick path: fewer Python steps).

    Each iteration, for the guess (F free, the others at their bounds): t = H x_0 + g, the gradient with the free
    variables at 0 (one product); x_F from H_FF x_F = -t_F; the gradient H x + g = t + H[:, F] x_F, and the
    next guess, in one pass. The index sets of a guess are computed once (:func:`_guess`, cached).

    Returns:
        (x, state, iterations), or None (as :func:`solve_box_qp`).
    """
    gl = g.tolist()
    slack = tolerance * max(1.0, max(gl), -min(gl))  # max(1, |g|_inf)
    above, below = 1.0 + slack, -slack
    for iteration in range(1, max_iterations + 1):
        free, corner, corner_list, block = _guess(state)
        t = (h.dot(corner) + g).tolist()
        k = len(free)
        x = corner_list
        if k == 0:
            grad = t
        elif k <= _SMALL:  # plain Python (_small_solve written out): H's rows of the free variables (= columns)
            x = list(corner_list)
            if k == 1:
                (i,) = free
                row = h[i].tolist()
                if row[i] <= 0.0:
                    return None
                value = -t[i] / row[i]
                x[i] = value
                grad = [d + c * value for d, c in zip(t, row, strict=True)]
            else:
                i, j = free
                row_i, row_j = h[i].tolist(), h[j].tolist()
                if row_i[i] <= 0.0:
                    return None
                r00 = math.sqrt(row_i[i])
                r01 = row_i[j] / r00
                d11 = row_j[j] - r01 * r01
                if d11 <= 0.0:
                    return None
                r11 = math.sqrt(d11)
                y0 = -t[i] / r00
                value_j = (-t[j] - r01 * y0) / r11 / r11
                value_i = (y0 - r01 * value_j) / r00
                x[i], x[j] = value_i, value_j
                grad = [d + ci * value_i + cj * value_j for d, ci, cj in zip(t, row_i, row_j, strict=True)]
        else:
            solution, info = _posv(h.take(block).reshape(k, k), [-t[i] for i in free])[1:]
            if info != 0:
                return None
            x = list(corner_list)
            for i, value in zip(free, solution.tolist(), strict=True):
                x[i] = value
            grad = (h.dot(np.array(x)) + g).tolist()
        # at 0: stays while its multiplier (the gradient) is >= 0; at 1: stays while the gradient is <= 0;
        # free: joins the bound it crossed
        new = tuple([(AT_LOWER if d >= below else FREE) if s == AT_LOWER
                     else (AT_UPPER if d <= slack else FREE) if s
                     else AT_LOWER if v < below else AT_UPPER if v > above else FREE
                     for s, v, d in zip(state, x, grad, strict=True)])
        if new == state:
            if k and (min(x) < 0.0 or max(x) > 1.0):  # a free variable within the slack of a bound, outside it
                x = [0.0 if v < 0.0 else 1.0 if v > 1.0 else v for v in x]
            return x, state, iteration
        state = new
    return None


@functools.lru_cache(maxsize=4096)
def _guess(state: tuple):
    """The index sets of a guess: (free indices, x with the free variables at 0 as a read-only array and as a
    tuple, the flat positions of H_FF in H when it is solved by LAPACK, else None).
    """
    n = len(state)
    free = tuple(i for i in range(n) if state[i] == FREE)
    corner_list = tuple(1.0 if s == AT_UPPER else 0.0 for s in state)
    corner = np.array(corner_list)
    corner.flags.writeable = False
    block = np.array([i * n + j for i in free for j in free], dtype=np.intp) if len(free) > _SMALL else None
    return free, corner, corner_list, block


__all__ = ["AT_LOWER", "AT_UPPER", "FREE", "solve_box_qp", "solve_box_qp_state"]
