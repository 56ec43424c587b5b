r"""A primal-dual interior-point solver of the SQP's step QP, banded: the robust route beside the active set.

The step QP of :mod:`planners.optimisation.sqp`, elastic rows included (a constraint violated at x may stay
violated at a cost, :func:`planners.optimisation.active_set.solve_step_qp`):

.. math:: \\min_{d, e} \\tfrac12 d^T (H + \\sigma I) d + g^T d + c^T e \\quad \\text{s.t.}\\;
          A d + e \\ge b,\\; e \\ge 0,\\; -\\Delta \\le d \\le \\Delta

(e only on the elastic rows, c their penalty weights). Mehrotra's predictor-corrector method on its KKT
conditions: each iteration solves one linear system for the step of d,

.. math:: (H + \\sigma I + A^T D A + B) \\, \\delta d = r,

D and B diagonal (the rows' and the box's barrier terms), and recovers the other variables' steps row by row.
A row of A touches one segment's two points (a few dozen columns) and H is banded
(:class:`planners.problem.banded.Banded`), so that matrix is banded with H's bandwidth: A^T D A is summed group
by group (rows with the same columns, a segment's), one batched product, and factorised by a banded Cholesky
factorisation: O(n b^2) per iteration, whatever the mission's length, and about 15-30 iterations whatever the
active set. Where the active set's pivoting does not end (an ill-conditioned H with hundreds of bounds
active), this route does; its solution is then made exact by the active set started from the bounds and rows
it found active.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.linalg import cho_factor, cho_solve

from planners.problem.banded import Banded

#: Relative tolerance of the residuals and of the mean complementarity at which the iteration stops.
TOLERANCE = 1e-10
#: Where the factorisation fails or the iterations run out, the iterate is kept if its residuals are within this
#: factor of :data:`TOLERANCE` (the residuals' round-off: the barrier terms span 30 orders of magnitude then).
ROUND_OFF = 100.0
#: Iteration limit (a safeguard: Mehrotra's method takes 15-30 on these QPs).
MAX_ITERATIONS = 60
#: Fraction of the way to the boundary of the positive orthant a step goes.
TO_BOUNDARY = 0.995


class _RowGroups:
    """The rows of a CSR matrix grouped by their column sets, for sum_k D_k a_k a_k^T as batched products."""

    def __init__(self, rows: sparse.csr_matrix, n: int):
        rows = sparse.csr_matrix(rows)
        rows.sort_indices()
        starts, lengths = rows.indptr[:-1], np.diff(rows.indptr)
        groups = self._groups(rows, starts, lengths)
        self.width = max((cols.size for cols, _ in groups), default=0)
        self.height = max((len(members) for _, members in groups), default=0)
        size = len(groups)
        self.row_index = np.full((size, self.height), -1)  # the rows of each group (-1: padding)
        self.columns = np.full((size, self.width), -1)
        self.values = np.zeros((size, self.height, self.width))
        for i, (cols, members) in enumerate(groups):
            self.row_index[i, :len(members)] = members
            self.columns[i, :cols.size] = cols
            # the members' stored values, in column order (sorted indices): the block itself
            members = np.asarray(members)
            self.values[i, :members.size, :cols.size] = rows.data[starts[members][:, None] + np.arange(cols.size)]
        both = (self.columns[:, :, None] >= 0) & (self.columns[:, None, :] >= 0)
        upper = both & (self.columns[:, :, None] <= self.columns[:, None, :])
        self.span = int(np.max((self.columns[:, None, :] - self.columns[:, :, None])[upper], initial=0))
        self.upper = upper
        self.n = n

    @staticmethod
    def _groups(rows, starts, lengths) -> list[tuple[np.ndarray, list[int]]]:
        """(columns, rows) of each set of rows with the same columns. Rows are first sorted by (first column,
        last column, count), then each candidate group is checked entry by entry (a planning NLP's rows of one
        segment share its columns); a group that fails the check is split row by row.
        """
        m = rows.shape[0]
        if m == 0:
            return []
        ends = starts + np.maximum(lengths, 1) - 1
        first = np.where(lengths > 0, rows.indices[np.minimum(starts, max(rows.indices.size - 1, 0))], -1)
        last = np.where(lengths > 0, rows.indices[np.minimum(ends, max(rows.indices.size - 1, 0))], -1)
        key = np.stack([first, last, lengths], axis=1)
        _, label = np.unique(key, axis=0, return_inverse=True)
        groups = []
        for g in range(label.max() + 1):
            members = np.flatnonzero(label.reshape(-1) == g)
            count = int(lengths[members[0]])
            cols = rows.indices[starts[members[:, None]] + np.arange(count)]  # (members, count)
            same = np.all(cols == cols[:1], axis=1)
            if same.all():
                groups.append((cols[0], members.tolist()))
                continue
            by_columns: dict[bytes, list[int]] = {}
            for k, c in zip(members, cols, strict=True):
                by_columns.setdefault(c.tobytes(), []).append(int(k))
            groups += [(np.frombuffer(key_, dtype=rows.indices.dtype), ks) for key_, ks in by_columns.items()]
        return groups

    def gram(self, weight: np.ndarray, bandwidth: int) -> np.ndarray:
        """The upper band (bandwidth + 1, n) of sum_k weight_k a_k a_k^T."""
        w = np.where(self.row_index >= 0, weight[np.maximum(self.row_index, 0)], 0.0)
        blocks = np.matmul(self.values.transpose(0, 2, 1), w[..., None] * self.values)  # (groups, width, width)
        i = np.broadcast_to(self.columns[:, :, None], self.upper.shape)[self.upper]
        j = np.broadcast_to(self.columns[:, None, :], self.upper.shape)[self.upper]
        flat = Banded.flat_index(i, j, self.n, bandwidth)
        return np.bincount(flat, blocks[self.upper], minlength=(bandwidth + 1) * self.n).reshape(bandwidth + 1, -1)


@dataclass
class _Iterate:
    """The interior point's variables: d, the rows' slacks s and multipliers z, the elastic rows' violations e and
    the multipliers y = c - z of e >= 0, the box's slacks t (d + Delta, Delta - d) and their multipliers u.
    """

    d: np.ndarray
    s: np.ndarray
    z: np.ndarray
    e: np.ndarray
    y: np.ndarray
    t_low: np.ndarray
    t_high: np.ndarray
    u_low: np.ndarray
    u_high: np.ndarray

    def complementarity(self) -> float:
        """s z + e y + t u, summed."""
        return float(self.s @ self.z + self.e @ self.y + self.t_low @ self.u_low + self.t_high @ self.u_high)

    def moved(self, step: _Iterate, alpha: float, elastic) -> _Iterate:
        """This point plus alpha times ``step`` (e and y kept 0 off the elastic rows)."""
        out = _Iterate(*(a + alpha * b for a, b in zip(self.values(), step.values(), strict=True)))
        out.e, out.y = np.where(elastic, out.e, 0.0), np.where(elastic, out.y, 0.0)
        return out

    def values(self) -> tuple:
        return (self.d, self.s, self.z, self.e, self.y, self.t_low, self.t_high, self.u_low, self.u_high)

    def positive_pairs(self, step: _Iterate, elastic) -> list:
        """(value, change) of every variable that must stay positive."""
        return [(self.s, step.s), (self.z, step.z), (self.e[elastic], step.e[elastic]),
                (self.y[elastic], step.y[elastic]), (self.t_low, step.t_low), (self.t_high, step.t_high),
                (self.u_low, step.u_low), (self.u_high, step.u_high)]


def _longest(pairs) -> float:
    """The largest step in (0, 1] keeping every variable of ``pairs`` (value, change) positive."""
    step = 1.0
    for value, change in pairs:
        falling = change < 0.0
        if falling.any():
            step = min(step, float(np.min(-value[falling] / change[falling])))
    return step


def _direction(point: _Iterate, residuals: tuple, weights, solve, rows, elastic, targets) -> _Iterate:
    """The Newton step of the KKT conditions with complementarity targets ``targets`` = (s z, e y, t_l u_l,
    t_h u_h): the reduced system for d (module docstring), then every other variable row by row.
    """
    r_dual, r_primal, r_elastic, r_low, r_high = residuals
    row_weight = weights
    p = point
    r_sz, r_ey = p.s * p.z - targets[0], p.e * p.y - targets[1]
    r_l, r_h = p.t_low * p.u_low - targets[2], p.t_high * p.u_high - targets[3]
    # rows: delta z = D (-r_p - A dd + (r_ey + e r_y) / y - r_sz / z)
    y_safe = np.where(elastic, p.y, 1.0)
    row_rhs = -r_primal + np.where(elastic, (r_ey + p.e * r_elastic) / y_safe, 0.0) - r_sz / p.z
    box_const = (r_l - p.u_low * r_low) / p.t_low + (-r_h + p.u_high * r_high) / p.t_high
    dd = solve(-r_dual - box_const + rows.T @ (row_weight * row_rhs))
    dz = row_weight * (row_rhs - rows @ dd)
    dy = r_elastic - dz
    de = np.where(elastic, (-r_ey - p.e * dy) / y_safe, 0.0)
    ds = (-r_sz - p.s * dz) / p.z
    dt_low, dt_high = dd - r_low, -dd - r_high
    return _Iterate(dd, ds, dz, de, dy, dt_low, dt_high, (-r_l - p.u_low * dt_low) / p.t_low,
                    (-r_h - p.u_high * dt_high) / p.t_high)


def _converged(residuals: tuple, mu: float, tolerance: float, dual_scale: float, scale: float, size: float) -> bool:
    """Every residual and the mean complementarity within ``tolerance`` of their scales."""
    r_dual, r_primal, r_elastic, r_low, r_high = residuals
    return (np.abs(r_dual).max(initial=0.0) <= tolerance * dual_scale
            and max(np.abs(r_primal).max(initial=0.0), np.abs(r_low).max(initial=0.0),
                    np.abs(r_high).max(initial=0.0)) <= tolerance * max(1.0, size)
            and np.abs(r_elastic).max(initial=0.0) <= tolerance * scale and mu <= tolerance * scale * size)


def solve_interior_point(hess, gradient, rows, lower, radius, shift: float = 0.0, caps=None):
    """The QP of the module docstring by Mehrotra's predictor-corrector method, or None when it does not converge.

    Args:
        hess: H (n, n), symmetric positive semi-definite: a :class:`~planners.problem.banded.Banded` (with the
            rows as a CSR matrix: the banded route) or an array (the dense route).
        gradient: g (n,).
        rows: A (m, n), an array or a CSR matrix, best scaled to unit infinity norm.
        lower: b (m,).
        radius: the box's half-width Delta > 0.
        shift: sigma, added to H's diagonal.
        caps: (m,) the elastic rows' penalty weights c, inf for rows that must hold; None: all must.

    Returns:
        (d (n,), the rows' multipliers (m,) >= 0, the bound of each variable that is active (+1, -1, or 0) and
        the rows that are, judged by their multipliers and slacks), or None.
    """
    g = np.asarray(gradient, dtype=float)
    b = np.asarray(lower, dtype=float)
    n, m = g.size, rows.shape[0]
    caps = np.full(m, np.inf) if caps is None else np.asarray(caps, dtype=float)
    elastic = np.isfinite(caps)
    cap = np.where(elastic, caps, 0.0)
    banded = isinstance(hess, Banded)
    if banded:
        groups = _RowGroups(rows, n)
        bandwidth = max(hess.bandwidth, groups.span)
        h_band = hess.padded(bandwidth)
    else:
        dense_rows = rows.toarray() if sparse.issparse(rows) else np.asarray(rows, dtype=float)
        h_dense = np.asarray(hess, dtype=float)
    scale = max(1.0, float(np.abs(g).max()) if n else 1.0, float(np.max(caps, initial=0.0, where=elastic)))
    # start: d = 0, every slack and multiplier of the order of the problem's scale
    e = np.where(elastic, np.maximum(b, 0.0) + 1.0, 0.0)
    z = np.where(elastic, 0.5 * cap, 1.0)
    point = _Iterate(np.zeros(n), np.maximum(-b + e, 1.0), z, e, np.where(elastic, cap - z, 0.0),
                     np.full(n, float(radius)), np.full(n, float(radius)), np.ones(n), np.ones(n))
    pairs = m + int(elastic.sum()) + 2 * n
    residuals = mu = dual_scale = None
    for _ in range(MAX_ITERATIONS):
        p = point
        hd = (hess @ p.d) + shift * p.d
        pushed = rows.T @ p.z
        residuals = (hd + g - pushed - p.u_low + p.u_high, rows @ p.d - b + p.e - p.s,
                     np.where(elastic, cap - p.z - p.y, 0.0), p.t_low - p.d - radius, p.t_high + p.d - radius)
        mu = p.complementarity() / max(pairs, 1)
        # the dual residual relative to its terms' size (round-off of H d and A^T z), the rest to the problem's
        dual_scale = max(scale, float(np.abs(hd).max(initial=0.0)), float(np.abs(pushed).max(initial=0.0)),
                         float(np.abs(p.u_low - p.u_high).max(initial=0.0)))
        if _converged(residuals, mu, TOLERANCE, dual_scale, scale, radius):
            break
        # the barrier terms: rows D = 1 / (s / z + e / y) (a hard row: z / s), box B = u_l / t_l + u_h / t_h
        row_weight = 1.0 / (p.s / p.z + np.where(elastic, p.e / np.where(elastic, p.y, 1.0), 0.0))
        box_weight = p.u_low / p.t_low + p.u_high / p.t_high
        try:
            if banded:
                band = h_band + groups.gram(row_weight, bandwidth)
                band[-1] += shift + box_weight
                solve = Banded(band).cholesky_solver()
            else:
                matrix = h_dense + dense_rows.T @ (row_weight[:, None] * dense_rows)
                matrix[np.diag_indices_from(matrix)] += shift + box_weight
                factor = cho_factor(matrix, check_finite=False)
                solve = functools.partial(cho_solve, factor, check_finite=False)
        except np.linalg.LinAlgError:  # the barrier terms at round-off: stop here if nearly converged
            if _converged(residuals, mu, ROUND_OFF * TOLERANCE, dual_scale, scale, radius):
                break
            return None
        zeros = (np.zeros(m), np.zeros(m), np.zeros(n), np.zeros(n))
        affine = _direction(p, residuals, row_weight, solve, rows, elastic, zeros)
        alpha = _longest(p.positive_pairs(affine, elastic))
        mu_affine = p.moved(affine, alpha, elastic).complementarity() / max(pairs, 1)
        target = (mu_affine / mu) ** 3 * mu if mu > 0 else 0.0
        step = _direction(p, residuals, row_weight, solve, rows, elastic,
                          (target - affine.s * affine.z, np.where(elastic, target - affine.e * affine.y, 0.0),
                           target - affine.t_low * affine.u_low, target - affine.t_high * affine.u_high))
        point = p.moved(step, TO_BOUNDARY * _longest(p.positive_pairs(step, elastic)), elastic)
    else:
        if not _converged(residuals, mu, ROUND_OFF * TOLERANCE, dual_scale, scale, radius):
            return None
    p = point
    bounds = np.where(p.u_high > p.t_high, 1, np.where(p.u_low > p.t_low, -1, 0)).astype(np.int8)
    active = tuple(int(k) for k in np.flatnonzero((p.z > p.s) & ~(elastic & (p.e > p.y))))
    return np.clip(p.d, -radius, radius), np.clip(p.z, 0.0, caps), bounds, active


__all__ = ["solve_interior_point"]
