r"""An exact solver of the SQP's step QP: bounds by block pivoting, rows by a working set.

The step QP of :mod:`planners.optimisation.sqp` at a feasible point is

.. math:: \\min_d \\tfrac12 d^T (H + \\sigma I) d + g^T d \\quad \\text{s.t.}\\; A d \\ge b,\\;
          -\\Delta \\le d \\le \\Delta

with H positive semi-definite and banded (:class:`planners.problem.banded.Banded`: a node's quantities depend
on its segment's two points), sigma > 0 a small shift, b <= 0 (d = 0 is feasible) and A's rows scaled to unit
infinity norm; at an infeasible point the violated rows are elastic (:func:`solve_step_qp`). Its trust-region
box often binds on hundreds of variables at once (the model is flat along many directions: H's eigenvalues span
1e-7 to 1e2), and only a few of the rows.

The solver keeps a guess of the *active set*: each variable is free or fixed at one of its bounds +-Delta,
each row is in the working set W (held at its bound) or not. For a guess it solves the equality-constrained
QP in the free variables (one Cholesky factorisation of the free variables' H, banded; the rows of W by their
Schur complement) and reads the multipliers: mu_i = -sign_i (H d + g - A_W^T lambda)_i of each fixed
variable, lambda of each row of W. The guess is right when every free variable lies within the box, every
row holds, and every multiplier is >= 0 (the KKT conditions of the QP, exactly, to round-off). Otherwise:

* **bounds: block principal pivoting** (Judice and Pires, 1994), with the working set held: every infeasible
  bound changes at once (a free variable beyond the box is fixed there, a fixed one with mu_i < 0 is freed)
  while the number of infeasible bounds keeps decreasing, with three tries of grace. A block step changes
  hundreds of bounds in one factorisation where a one-at-a-time active set needs hundreds of steps. When the
  count stops decreasing (block pivoting can cycle where H is far from diagonally dominant), the solver gives
  up: the caller solves the QP by :mod:`planners.optimisation.interior_point`;
* **rows,** once the bounds agree with W: rows with a negative multiplier leave W, else rows that would
  rather be violated (an elastic row whose multiplier exceeds its cap, :func:`solve_step_qp`) are relaxed, else
  relaxed rows that hold come back, else violated rows join W, as in a primal active-set method; each such
  change takes, in order of priority, every row that shares no variable with one taken before it (rows of
  different segments do not interact: a long mission's changes do not wait for each other). A row of W that
  the free variables cannot hold frees its fixed variable of least multiplier, or leaves W when it has none
  (it depends on the others).

Started from the active set of the step before (the SQP passes it), a few changes usually suffice. The
row changes have no anti-cycling rule and are capped at :data:`MAX_CHANGES` changes in all; when the
solver gives up, or its solve of the free variables lost the step to cancellation (:data:`CONDITION`),
:func:`solve_step_qp` returns None and the caller solves the QP another way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.linalg import cho_factor, cho_solve

from planners.problem.banded import Banded

#: Relative violation of a row or bound (in row-scaled units, relative to max(1, |d|_inf)) that counts as
#: holding, and relative size of a negative multiplier (to max(1, |g|_inf)) that counts as zero.
ROW_TOLERANCE = 1e-10
#: The range-space solve of the free variables, d_F = -y + Z lambda (y = H_FF^-1 r, Z = H_FF^-1 A_WF^T), loses
#: about 1e-16 max(|y|, |Z lambda|) to cancellation: a step is returned only when that is below 1e-9 of the
#: radius, i.e. max(|y|_inf, |Z lambda|_inf) <= radius / CONDITION (else the caller solves the QP another way).
CONDITION = 1e-7
#: How many changes of the active set before giving up (a safeguard: a block change alters many bounds).
MAX_CHANGES = 60
#: Block changes tried without a decrease of the number of infeasible bounds before the solver gives up.
BLOCK_GRACE = 3


@dataclass(frozen=True)
class ActiveSet:
    """The active set of a step QP, to start the next one from.

    Attributes:
        bounds: per variable 0 (free), +1 (at +Delta) or -1 (at -Delta), int8 (n,).
        rows: indices of the rows held at their bound (the working set).
    """

    bounds: np.ndarray
    rows: tuple[int, ...] = ()


def shifted(hess, shift: float):
    """A copy of H with ``shift`` added to its diagonal (a :class:`Banded` stays banded)."""
    if isinstance(hess, Banded):
        return hess.shifted(shift)
    out = np.array(hess, dtype=float)
    out[np.diag_indices_from(out)] += shift
    return out


def _solver(hess, free: np.ndarray, shift: float):
    """The solve y -> (H_FF + shift I)^-1 y on the free variables ``free`` (indices); raises LinAlgError."""
    if isinstance(hess, Banded):
        return hess.principal(free).cholesky_solver(shift)
    sub = hess[np.ix_(free, free)]
    sub[np.diag_indices_from(sub)] += shift
    factor = cho_factor(sub, check_finite=False)
    return lambda y: cho_solve(factor, y, check_finite=False)


def _dense_rows(rows, index) -> np.ndarray:
    picked = rows[list(index)]
    return picked.toarray() if sparse.issparse(picked) else np.asarray(picked, dtype=float)


def _disjoint(rows, order, n: int) -> list[int]:
    """The rows of ``order`` (indices, by priority) that share no variable with a row before them that was kept:
    rows of different segments do not interact, and changing them together costs one factorisation.
    """
    used = np.zeros(n, dtype=bool)
    out = []
    for k in order:
        support = rows[int(k)].indices if sparse.issparse(rows) else np.flatnonzero(rows[int(k)])
        if not used[support].any():
            used[support] = True
            out.append(int(k))
    return out


def solve_step_qp(hess, gradient, rows, lower, radius: float, start: ActiveSet | None = None,
                  shift: float = 0.0, caps=None):
    """The minimiser of 1/2 d^T (H + shift I) d + g^T d (+ the elastic rows' penalty) s.t. rows d >= lower,
    |d|_inf <= radius, or None.

    See the module docstring. With ``caps``, row k costs caps[k] max(0, lower[k] - rows[k] d) instead of
    having to hold (an *elastic* row, for caps[k] finite: the SQP's l1 penalty of a constraint violated at x):
    its multiplier is at most caps[k], and a row whose multiplier would exceed it is *relaxed* (its penalty's
    gradient -caps[k] rows[k] joins g; it must then be violated or just hold).

    Args:
        hess: H (n, n), symmetric positive semi-definite (positive definite with the shift): a
            :class:`~planners.problem.banded.Banded` or an array.
        gradient: g (n,).
        rows: A (m, n), an array or a scipy CSR matrix, best scaled to unit infinity norm.
        lower: b (m,); b <= 0 for the rows that must hold (d = 0 is feasible).
        radius: the trust-region radius Delta > 0.
        start: the active set to start from (e.g. the last QP's), or None (all free, no row held).
        shift: added to H's diagonal (a regularisation; H itself is not copied for it).
        caps: (m,) the elastic rows' penalty weights, inf for rows that must hold; None: all must.

    Returns:
        (d (n,), multipliers (m,) of the rows (in [0, caps]), the final :class:`ActiveSet`), or None.
    """
    g = np.asarray(gradient, dtype=float)
    lower = np.asarray(lower, dtype=float)
    n, m = g.size, rows.shape[0]
    caps = np.full(m, np.inf) if caps is None else np.asarray(caps, dtype=float)
    signs = np.zeros(n, dtype=np.int8)
    work: list[int] = []
    relaxed = np.zeros(m, dtype=bool)
    if start is not None and start.bounds.shape == (n,):
        signs = start.bounds.astype(np.int8).copy()
        work = [int(k) for k in start.rows if 0 <= k < m]
    g_scale = max(1.0, float(np.abs(g).max()), float(np.max(caps, initial=0.0, where=np.isfinite(caps))))
    best, grace = np.inf, BLOCK_GRACE
    g_eff = g
    for _ in range(MAX_CHANGES):
        free = np.flatnonzero(signs == 0)
        d = signs * float(radius)
        try:
            solve = _solver(hess, free, shift) if free.size else None
        except np.linalg.LinAlgError:
            return None
        rhs = (g_eff + (hess @ d if signs.any() else 0.0))[free]
        lam = np.zeros(len(work))
        magnitude = 0.0  # max(|y|, |Z lambda|): the range-space solve's cancellation scale
        if free.size:
            y = solve(rhs)
            d_free = -y
            magnitude = float(np.abs(y).max())
            if work:
                a_w = _dense_rows(rows, work)
                a_free = a_w[:, free]
                live = np.flatnonzero(np.abs(a_free).max(axis=1) > 0.0)
                if live.size:
                    a_live = a_free[live]
                    z = solve(a_live.T).reshape(free.size, live.size)
                    schur = a_live @ z
                    target = (lower[work] - a_w @ d)[live] + a_live @ y
                    try:
                        lam_live = np.linalg.solve(schur, target)
                    except np.linalg.LinAlgError:
                        lam_live = np.linalg.lstsq(schur, target, rcond=None)[0]
                    if not np.all(np.isfinite(lam_live)):
                        return None
                    lam[live] = lam_live
                    pull = z @ lam_live
                    magnitude = max(magnitude, float(np.abs(pull).max()))
                    d_free = d_free + pull
            d[free] = d_free
        stationary = hess @ d + shift * d + g_eff
        if work:
            stationary -= _dense_rows(rows, work).T @ lam
        size = max(1.0, float(np.abs(d).max()))
        # infeasibilities: bounds (a free variable beyond the box, a fixed one pulling inwards), rows
        fixed_pull = (signs != 0) & (-signs * stationary < -ROW_TOLERANCE * g_scale)
        beyond = (signs == 0) & (np.abs(d) > radius * (1.0 + ROW_TOLERANCE))
        slack = (rows @ d - lower) if m else np.zeros(0)
        held = np.zeros(m, dtype=bool)
        held[work] = True
        violated = np.flatnonzero((slack < -ROW_TOLERANCE * size) & ~held & ~relaxed)
        leaving = np.flatnonzero(lam < -ROW_TOLERANCE * g_scale)
        over = np.flatnonzero(lam > caps[work] + ROW_TOLERANCE * g_scale)  # cheaper violated than held
        kept = np.flatnonzero(relaxed & (slack > ROW_TOLERANCE * size))  # relaxed, yet they hold
        unheld = [k for k in work if slack[k] < -ROW_TOLERANCE * size]  # W rows with no free variable left
        bounds = int(fixed_pull.sum() + beyond.sum())
        if bounds + violated.size + leaving.size + over.size + kept.size + len(unheld) == 0:
            if magnitude > radius / CONDITION:
                return None  # the range-space solve lost the step to cancellation (module docstring)
            multipliers = np.where(relaxed, caps, 0.0)
            multipliers[work] = np.clip(lam, 0.0, caps[work])
            return d, multipliers, ActiveSet(signs, tuple(work))
        elastic = [k for k in unheld if np.isfinite(caps[k])] + [work[i] for i in over]
        if elastic:  # elastic rows of W that cannot be held, or would rather be violated: relaxed at once
            work = [k for k in work if k not in set(elastic)]
            relaxed[elastic] = True
            g_eff = g - rows[np.flatnonzero(relaxed)].T @ caps[relaxed]
            continue
        if unheld:  # a row of W the free variables cannot hold: free its least held bound, or it leaves W
            k = unheld[0]
            bound = np.flatnonzero((_dense_rows(rows, [k])[0] != 0) & (signs != 0))
            if bound.size:
                signs[bound[np.argmin(-signs[bound] * stationary[bound])]] = 0
            else:
                work.remove(k)
            continue
        if bounds:  # the bounds first, the rows held (block pivoting while it makes progress)
            if bounds >= best and grace == 0:
                return None  # the pivoting stalls: the caller takes another route (interior_point)
            grace = BLOCK_GRACE if bounds < best else grace - 1
            best = min(best, bounds)
            signs[fixed_pull] = 0
            signs[beyond] = np.sign(d[beyond]).astype(np.int8)
            continue
        best, grace = np.inf, BLOCK_GRACE  # the bounds agree with the rows: change the rows
        held_rows = np.array(work)
        if leaving.size:  # the most negative multiplier of each group of rows that share no variable
            gone = set(_disjoint(rows, held_rows[leaving[np.argsort(lam[leaving], kind="stable")]], n))
            work = [k for k in work if k not in gone]
        elif kept.size:
            relaxed[_disjoint(rows, kept[np.argsort(-slack[kept], kind="stable")], n)] = False
        else:
            work += _disjoint(rows, violated[np.argsort(slack[violated], kind="stable")], n)
        pushed = np.flatnonzero(relaxed)
        g_eff = g - (rows[pushed].T @ caps[pushed] if pushed.size else 0.0)
    return None


__all__ = ["ActiveSet", "CONDITION", "MAX_CHANGES", "ROW_TOLERANCE", "shifted", "solve_step_qp"]
