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
        segment share its columns); a group that fails the check is split row by row."""
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


def solve_interior_point(hess, gradient, rows, lower, radius: float, shift: float = 0.0, caps=None):
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
    banded = isinstance(hess, Banded)
    if banded:
        groups = _RowGroups(rows, n)
        bandwidth = max(hess.bandwidth, groups.span)
        h_band = hess._with_bandwidth(bandwidth) if bandwidth >= hess.bandwidth else hess.band
    else:
        dense_rows = rows.toarray() if sparse.issparse(rows) else np.asarray(rows, dtype=float)
        h_dense = np.asarray(hess, dtype=float)
    scale = max(1.0, float(np.abs(g).max()) if n else 1.0, float(np.max(caps, initial=0.0, where=elastic)))
    # start: d = 0, every slack and multiplier of the order of the problem's scale
    d = np.zeros(n)
    e = np.where(elastic, np.maximum(b, 0.0) + 1.0, 0.0)
    s = np.maximum(rows @ d - b + e, 1.0)
    z = np.where(elastic, 0.5 * np.where(elastic, caps, 0.0), 1.0)
    y = np.where(elastic, caps - z, 0.0)
    t_low, t_high = np.full(n, radius), np.full(n, radius)
    u_low, u_high = np.ones(n), np.ones(n)
    pairs = m + int(elastic.sum()) + 2 * n
    for _ in range(MAX_ITERATIONS):
        hd = (hess @ d) + shift * d
        pushed = rows.T @ z
        r_dual = hd + g - pushed - u_low + u_high
        r_primal = rows @ d - b + e - s
        r_elastic = np.where(elastic, np.where(elastic, caps, 0.0) - z - y, 0.0)
        r_low, r_high = t_low - d - radius, t_high + d - radius
        mu = (s @ z + e @ y + t_low @ u_low + t_high @ u_high) / max(pairs, 1)
        # the dual residual relative to its terms' size (round-off of H d and A^T z), the rest to the problem's
        dual_scale = max(scale, float(np.abs(hd).max(initial=0.0)), float(np.abs(pushed).max(initial=0.0)),
                         float(np.abs(u_low - u_high).max(initial=0.0)))
        def converged(tolerance):
            return (np.abs(r_dual).max(initial=0.0) <= tolerance * dual_scale
                    and max(np.abs(r_primal).max(initial=0.0), np.abs(r_low).max(initial=0.0),
                            np.abs(r_high).max(initial=0.0)) <= tolerance * max(1.0, radius)
                    and np.abs(r_elastic).max(initial=0.0) <= tolerance * scale
                    and mu <= tolerance * scale * radius)

        if converged(TOLERANCE):
            break
        # the barrier terms: rows D = 1 / (s / z + e / y) (a hard row: z / s), box B = u_l / t_l + u_h / t_h
        row_weight = 1.0 / (s / z + np.where(elastic, e / np.where(elastic, y, 1.0), 0.0))
        box_weight = u_low / t_low + u_high / t_high
        if banded:
            band = h_band + groups.gram(row_weight, bandwidth)
            band[-1] += shift + box_weight
            try:
                solve = Banded(band).cholesky_solver()
            except np.linalg.LinAlgError:  # the barrier terms at round-off: stop here if nearly converged
                if converged(ROUND_OFF * TOLERANCE):
                    break
                return None
        else:
            matrix = h_dense + dense_rows.T @ (row_weight[:, None] * dense_rows)
            matrix[np.diag_indices_from(matrix)] += shift + box_weight
            try:
                factor = cho_factor(matrix, check_finite=False)
            except np.linalg.LinAlgError:
                if converged(ROUND_OFF * TOLERANCE):
                    break
                return None

            def solve(v, factor=factor):
                return cho_solve(factor, v, check_finite=False)

        def direction(c_sz, c_ey, c_low, c_high):
            """The Newton step for complementarity targets s z = c_sz, e y = c_ey, t u = c_low, c_high."""
            r_sz, r_ey = s * z - c_sz, e * y - c_ey
            r_l, r_h = t_low * u_low - c_low, t_high * u_high - c_high
            # rows: delta z = D (-r_p - A dd + (r_ey + e r_y) / y - r_sz / z)
            elastic_part = np.where(elastic, (r_ey + e * r_elastic) / np.where(elastic, y, 1.0), 0.0)
            row_rhs = -r_primal + elastic_part - r_sz / z
            box_const = (r_l - u_low * r_low) / t_low + (-r_h + u_high * r_high) / t_high
            rhs = -r_dual - box_const + rows.T @ (row_weight * row_rhs)
            dd = solve(rhs)
            dz = row_weight * (row_rhs - rows @ dd)
            dy = r_elastic - dz
            de = np.where(elastic, (-r_ey - e * dy) / np.where(elastic, y, 1.0), 0.0)
            ds = (-r_sz - s * dz) / z
            dt_low, dt_high = dd - r_low, -dd - r_high
            du_low, du_high = (-r_l - u_low * dt_low) / t_low, (-r_h - u_high * dt_high) / t_high
            return dd, ds, dz, de, dy, dt_low, dt_high, du_low, du_high

        def longest(*pairs_):
            """The largest step in (0, 1] keeping every variable of ``pairs_`` (value, step) positive."""
            step = 1.0
            for value, change in pairs_:
                falling = change < 0.0
                if falling.any():
                    step = min(step, float(np.min(-value[falling] / change[falling])))
            return step

        affine = direction(np.zeros(m), np.zeros(m), np.zeros(n), np.zeros(n))
        dd, ds, dz, de, dy, dtl, dth, dul, duh = affine
        ey = (e[elastic], de[elastic]), (y[elastic], dy[elastic])
        alpha = longest((s, ds), (z, dz), *ey, (t_low, dtl), (t_high, dth), (u_low, dul), (u_high, duh))
        mu_affine = ((s + alpha * ds) @ (z + alpha * dz) + (e + alpha * de) @ (y + alpha * dy)
                     + (t_low + alpha * dtl) @ (u_low + alpha * dul)
                     + (t_high + alpha * dth) @ (u_high + alpha * duh)) / max(pairs, 1)
        target = (mu_affine / mu) ** 3 * mu if mu > 0 else 0.0
        corrected = direction(target - ds * dz, np.where(elastic, target - de * dy, 0.0),
                              target - dtl * dul, target - dth * duh)
        dd, ds, dz, de, dy, dtl, dth, dul, duh = corrected
        ey = (e[elastic], de[elastic]), (y[elastic], dy[elastic])
        alpha = TO_BOUNDARY * longest((s, ds), (z, dz), *ey, (t_low, dtl), (t_high, dth), (u_low, dul),
                                      (u_high, duh))
        d, s, z = d + alpha * dd, s + alpha * ds, z + alpha * dz
        e, y = np.where(elastic, e + alpha * de, 0.0), np.where(elastic, y + alpha * dy, 0.0)
        t_low, t_high = t_low + alpha * dtl, t_high + alpha * dth
        u_low, u_high = u_low + alpha * dul, u_high + alpha * duh
    else:
        if not converged(ROUND_OFF * TOLERANCE):
            return None
    d = np.clip(d, -radius, radius)
    bounds = np.where(u_high > t_high, 1, np.where(u_low > t_low, -1, 0)).astype(np.int8)
    active = tuple(int(k) for k in np.flatnonzero((z > s) & ~(elastic & (e > y))))
    return d, np.clip(z, 0.0, caps), bounds, active


__all__ = ["solve_interior_point"]
