r"""An exact solver of the SQP's step QP when few constraints are active: a primal-dual active-set guess.

The step QP of :mod:`planners.optimisation.sqp` at a feasible point is

.. math:: \\min_d \\tfrac12 d^T H d + g^T d \\quad \\text{s.t.}\\; A d \\ge b,\\; |d|_\\infty \\le \\Delta

with H positive definite (after the SQP's regularisation). On the planning problems it has a hundred
or more variables, several hundred rows and a handful of active ones, and H is ill-conditioned
(eigenvalues from 1e-7 to 1e2): ProxQP needs hundreds of iterations there and often stops at its
iteration limit with an inexact step. Here one Cholesky factor of H serves a short sequence
of equality-constrained QPs on a working set W of rows held at their bound:

* solve min q(d) s.t. G_W d = h_W (the Schur complement G_W H^-1 G_W^T for the multipliers);
* a negative multiplier leaves W (the most negative one), else the rows the step violates join W
  (the worst ones first), else the step is returned.

A step is returned only when it satisfies the KKT conditions of the QP exactly (to round-off): every
row holds, every multiplier is >= 0, and the rows not in W have none. The sequence is a heuristic
(no anti-cycling rule) and is capped; when it does not end, :func:`solve_step_qp` returns None and
the caller solves the QP another way (ProxQP, capped at its iteration limit, whose step can be inexact).
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.linalg import cho_factor, cho_solve, cho_solve_banded, cholesky_banded

#: Relative violation of a row (in row-scaled units) that counts as holding.
ROW_TOLERANCE = 1e-10
#: Smallest eigenvalue of H, relative to |g|_inf / Delta, for which the solver is used (module docstring).
CONDITION = 1e-7
#: How many working-set changes before giving up.
MAX_CHANGES = 60
#: H is treated as banded (:func:`banded_solver`) when its bandwidth is at most this share of its size.
BANDED_SHARE = 0.25
#: ... and it has at least this many rows (below it one dense Cholesky factorisation is cheap).
BANDED_MIN_SIZE = 200


def shifted(hess, shift: float) -> np.ndarray:
    """A copy of H with ``shift`` added to its diagonal (float)."""
    out = np.array(hess, dtype=float)
    out[np.diag_indices_from(out)] += shift
    return out


def solve_step_qp(hess, gradient, rows, lower, radius: float, working=None, shift: float = 0.0):
    """The minimiser of 1/2 d^T (H + shift I) d + g^T d s.t. rows d >= lower, |d|_inf <= radius, or None.

    See the module docstring.

    Args:
        hess: H (n, n), symmetric positive definite.
        gradient: g (n,).
        rows: A (m, n), an array or a scipy CSR matrix (a long mission's few per cent non-zero), best
            scaled to unit infinity norm.
        lower: b (m,); b <= 0 (d = 0 is feasible).
        radius: the trust-region radius Delta > 0.
        working: indices into the m rows to start the working set with (e.g. the last QP's active
            rows), or None.
        shift: added to H's diagonal (a regularisation; no copy of a long mission's H is made for it).

    Returns:
        (d (n,), multipliers (m,) >= 0 of the rows, the final working set of rows), or None.
    """
    n = gradient.size
    m = rows.shape[0]
    solve = banded_solver(hess, shift)
    if solve is None:
        if shift:
            hess = shifted(hess, shift)
        # the range-space steps below lose about 1e-16 |H^-1 g| to cancellation: keep that below 1e-9 of the
        # radius, i.e. lambda_min(H) >= t = CONDITION |g|_inf / Delta, else leave the QP to a solver that does
        # not invert H. H - t I has a Cholesky factor exactly when lambda_min(H) > t: two Cholesky
        # factorisations (the test, then H's own for the solves) cost a fraction of H's eigendecomposition
        sym = 0.5 * (hess + hess.T)
        floor = CONDITION * max(float(np.abs(gradient).max()), 1e-300) / radius
        try:
            cho_factor(shifted(sym, -floor), check_finite=False)
            factor = cho_factor(sym, check_finite=False)
        except np.linalg.LinAlgError:
            return None

        def solve(y):
            return cho_solve(factor, y, check_finite=False)
    elif not float(np.abs(solve(gradient)).max()) <= radius / CONDITION:
        # the same bound on the cancellation, with |H^-1 g| itself instead of |g| / lambda_min(H)
        return None
    # all rows as G d >= h: the m constraint rows, then d_i >= -Delta, then -d_i >= -Delta
    def rows_of(work):
        out = np.zeros((len(work), n))
        mine = [i for i, k in enumerate(work) if k < m]
        if mine:
            picked = rows[[work[i] for i in mine]]
            out[mine] = picked.toarray() if sparse.issparse(picked) else picked
        for i, k in enumerate(work):
            if k >= m:
                out[i, (k - m) % n] = 1.0 if k < m + n else -1.0
        return out

    def values(d):
        return np.concatenate([rows @ d - lower, d + radius, radius - d])

    work = [int(k) for k in (working if working is not None else ()) if 0 <= k < m]
    h_inv_g = solve(gradient)
    for _ in range(MAX_CHANGES):
        if work:
            g_w = rows_of(work)
            h_w = np.array([lower[k] if k < m else -radius for k in work])
            h_inv_gt = solve(g_w.T)
            schur = g_w @ h_inv_gt
            rhs = h_w + g_w @ h_inv_g
            try:
                lam = np.linalg.solve(schur, rhs)
            except np.linalg.LinAlgError:
                return None
            if not np.all(np.isfinite(lam)):
                return None
            d = -h_inv_g + h_inv_gt @ lam
        else:
            lam = np.zeros(0)
            d = -h_inv_g
        if lam.size and lam.min() < 0.0:
            work.pop(int(np.argmin(lam)))
            continue
        slack = values(d)
        worst = float(slack.min())
        if worst >= -ROW_TOLERANCE * max(1.0, float(np.abs(d).max())):
            multipliers = np.zeros(m)
            for k, value in zip(work, lam, strict=True):
                if k < m:
                    multipliers[k] = value
            return d, multipliers, [k for k in work if k < m]
        violated = np.flatnonzero(slack < 0.5 * worst)
        in_work = set(work)
        added = [int(k) for k in violated[np.argsort(slack[violated])] if int(k) not in in_work][:8]
        if not added:
            return None
        # a box row and its opposite cannot both be in W
        work += [k for k in added if k < m or ((k - m + n) % (2 * n) + m) not in in_work]
    return None


def bandwidth(matrix) -> int:
    """The largest |i - j| with matrix[i, j] != 0 (0 for a diagonal or zero matrix).

    From each row's first and last non-zero column (no index arrays of the non-zeros: a long mission's
    H has millions of entries).
    """
    nz = np.asarray(matrix) != 0
    has = nz.any(axis=1)
    if not has.any():
        return 0
    i = np.arange(nz.shape[0])
    first = nz.argmax(axis=1)
    last = nz.shape[1] - 1 - nz[:, ::-1].argmax(axis=1)
    return int(max((i - first)[has].max(), (last - i)[has].max()))


def banded_solver(hess, shift: float = 0.0):
    """The solve y -> (H + shift I)^-1 y by a banded Cholesky factorisation when H is large and banded, else None.

    The planning problems' H is block-banded: a grid node's quantities depend on the two points of its
    segment only, and x holds the points' entries in order, so H couples entries of neighbouring points
    only (bandwidth about two points' entries, 40 for the FPR, whatever the mission's length). Factoring
    it costs O(n b^2) and each solve O(n b) (b the bandwidth), where the dense route's Cholesky
    factorisations cost O(n^3) and each solve O(n^2). Used when n >= :data:`BANDED_MIN_SIZE` and
    b <= :data:`BANDED_SHARE` n; None also when the factorisation fails (H not positive definite to
    round-off): the dense route decides then.
    """
    n = hess.shape[0]
    if n < BANDED_MIN_SIZE:
        return None
    b = bandwidth(hess)
    if b > BANDED_SHARE * n:
        return None
    upper = np.zeros((b + 1, n))  # LAPACK's upper banded storage: upper[b + i - j, j] = H[i, j], i <= j
    for k in range(b + 1):
        upper[b - k, k:] = 0.5 * (np.diagonal(hess, k) + np.diagonal(hess, -k))
    upper[b] += shift
    try:
        factor = cholesky_banded(upper, lower=False)
    except np.linalg.LinAlgError:
        return None
    return lambda y: cho_solve_banded((factor, False), y)
