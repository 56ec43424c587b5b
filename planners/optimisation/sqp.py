r"""A small trust-region SQP for the planning NLP: elastic QPs, the KKT residual.

Gauss-Newton curvature, the "smoothed" model of J_e's absolute values (:mod:`planners.optimisation.curvature`, the
planner's default), or a composite model of them with a damped BFGS correction. The step QP is solved exactly by
an active set that pivots the trust region's bounds in blocks (:mod:`planners.optimisation.active_set`,
warm-started from the last step's), or where it gives up by a banded interior point
(:mod:`planners.optimisation.interior_point`); ProxQP is the last resort.

The planning objective is a weighted sum of integrals of squares (J_phi) and of absolute values
(J_e) of per-sample quantities whose exact Jacobians :class:`planners.problem.motion.MotionProblem`
provides; their Gauss-Newton / reweighted least-squares matrix is a good positive semi-definite
model of the Hessian, far better than a quasi-Newton estimate built from scratch (SLSQP needs
hundreds of iterations on these problems, this method a handful).

Each iteration solves the elastic (S-l1-QP) subproblem

.. math:: \min_{d, s} \tfrac12 d^T H d + g^T d + \rho \mathbf 1^T s \quad
          \text{s.t.}\; c + A d + s \ge 0,\; s \ge 0,\; |d|_\infty \le \Delta,

with slacks s only on the constraints violated at x (always feasible), and accepts the step by the ratio of actual
to predicted decrease of the exact l1 merit J + rho * sum(max(0, -c)). Constraints that cannot become active inside
the trust region (c_i > |A_i|_1 Delta) are left out of the QP, which keeps it small.

**Curvature** (``SqpOptions.curvature``). ``"smoothed"`` (:mod:`planners.optimisation.curvature`; the default of
:class:`planners.options.PlanOptions`): J_phi's Gauss-Newton matrix plus, for
each |P_k|, the curvature of a wider smoothing sqrt(P^2 + mu^2) (mu = 0.1 W) and 5 % of the
majoriser below; with the planner's defaults it ends within 0.2 % of the best known J of the square,
the tour and the study (19-52 iterations). ``"gauss-newton"`` (this class's default, the earlier
rule, which the replanner and the singularity crossing keep): H is the problem's Gauss-Newton
matrix, where J_e's |P| (drone powers P, seed 3.24) gets the reweighted majoriser
a_e w |nabla P|^2 / |P|. It overestimates the curvature along the steps (accepted steps decrease the
merit by twice the prediction) and converges linearly: the square one-step stops 1 % above the best
known J, and reaches 0.5036 only after 305 iterations. ``"composite"``:
J = a_phi J_phi + sum_k pw_k |P_k| is modelled as what it is, a smooth part plus a weighted l1 sum:
each |P_k| that can change sign inside the trust region becomes a QP variable
t_k >= |P_k + nabla P_k d| (the rest are linear there),
and H is J_phi's Gauss-Newton matrix plus a structured quasi-Newton correction S: after each accepted
step s, B = H_phi(x + s) + S gets Powell's damped BFGS update with y = nabla L(x + s) - nabla L(x)
(L = a_phi J_phi + sum_k pw_k xi_k P_k - lambda^T c, xi_k the QP's subgradient of |.|, lambda its
multipliers; y replaced by theta y + (1 - theta) B s so that s^T y >= 0.2 s^T B s: B stays positive
definite), and S = B - H_phi(x + s) is kept; B's eigenvalues are floored at 1e-8 of the largest. It
reaches the best known J of the square in 41 iterations (0.50359 on the dense grid, the peers' 0.5037),
but its QPs have one more variable and two more rows per drone and grid node that can change sign
(the square: 400 variables, ~1,700 rows instead of 128, ~960) and ProxQP needs 400-800 iterations on
each (its sparse backend and quadprog are no faster there): measured about 6 times slower per SQP
iteration than Gauss-Newton, so it is not the default.

**Step length** (``SqpOptions.kinks``, off by default, used with ``"smoothed"``). The QP's direction d is kept; its
length is the minimiser along d of a second, convex model of the merit in which each drone power is linearised but
its absolute value is exact (:func:`planners.optimisation.curvature.along_step`), and that model's decrease is the
one the trust region's ratio test compares with the actual decrease. Without it, a step that takes powers across
zero from afar is predicted a decrease where J grows, rejected, and the radius falls by a factor of 4 per rejection.
On random missions of 32 way points it ends 0.3-0.5 % lower in J on average (up to 2.6 %) in a similar median
time, but the runs that go deeper take longer (the 95th percentile of the plan times rose by about 10 % on the
FPR's one-step and more on the prototype's two-step): it is an option, not the planner's default.

**Stop** (``SqpOptions.stop``). ``"kkt"``: at x, with the multipliers lambda >= 0 of the QP
solved there (constraint rows scaled to unit infinity norm, c_hat_i = c_i / max(1, |nabla c_i|_inf)),

* stationarity  = |nabla J - sum_i lambda_i nabla c_hat_i|_inf (J is O(1) by its normalisation 3.26,
  x is in local Taylor units: both are scaled),
* complementarity = max_i lambda_i |min(c_hat_i, 0) or c_hat_i| = max_i lambda_i |c_hat_i|,
* feasibility = the largest violation max_i max(0, -c_i) (the problem's scaled units),

and the **KKT residual** is the largest of the three; the run converges when it is at most
``kkt_tolerance`` (:func:`kkt_residual`); with ``"composite"`` nabla J is J_e's subgradient sum
nabla (a_phi J_phi) + sum_k pw_k xi_k nabla P_k. ``"progress"`` (default, the rule the planner's
timings were set with): an accepted step that decreases the merit by less than ``tolerance``
(relative). Either way the final KKT residual is computed and reported (:class:`SqpOutcome`,
``StageReport.kkt``): a stop on progress far from a stationary point shows there.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from fpr.model.errors import PlannerArgumentError
from fpr.model.qp import proxsuite_module
from planners.optimisation.active_set import ActiveSet, shifted, solve_step_qp
from planners.optimisation.curvature import MAJORISER_SHARE, POWER_WIDTH, along_step, smoothed_hessian
from planners.optimisation.interior_point import solve_interior_point
from planners.problem.banded import Banded
from planners.problem.motion import POWER_SMOOTHING

logger = logging.getLogger(__name__)


#: The curvature models of :class:`SqpOptions` (see the module docstring).
CURVATURES = ("gauss-newton", "composite", "smoothed")
#: The stopping rules of :class:`SqpOptions` (see the module docstring).
STOPS = ("kkt", "progress")


@dataclass
class SqpOptions:
    """Settings of :func:`solve_sqp`.

    Attributes:
        max_iterations: iteration limit (each iteration is one exact-derivative evaluation).
        tolerance: with ``stop="progress"``: stop when an accepted step decreases the merit by less than
            this (relative to max(1, |J|)) and the constraints hold. With ``stop="kkt"``: the run also
            stops (as converged when feasible) when the merit decreased by less than ``tolerance**2``
            relative over the last ``patience`` iterations (a stall at round-off).
        feasibility: largest accepted (scaled) constraint violation.
        radius: initial trust-region radius in the scaled variables.
        penalty: initial l1 penalty weight rho; raised while the linearised constraints cannot be met.
        patience: iterations without a 1 % decrease of the constraint violation after which an
            infeasible run stops.
        crawl: an infeasible run (violation above 1e-3) also stops when its violation decreased by less
            than this fraction over the last ``patience`` iterations (a crawl towards an unreachable
            feasible set: the infeasible square decreased it by 0.5 % an iteration for 90 iterations).
        stop: ``"progress"`` (the merit-decrease rule of ``tolerance``) or ``"kkt"`` (converged when the
            KKT residual is at most ``kkt_tolerance``); :data:`STOPS`.
        kkt_tolerance: the KKT residual at which ``stop="kkt"`` converges (module docstring: J and x
            scaled to O(1), constraint rows to unit gradient).
        curvature: ``"gauss-newton"``, ``"composite"`` or ``"smoothed"`` (:data:`CURVATURES`; the
            composite model needs the problem's ``power`` fields, else it is Gauss-Newton with the BFGS
            correction; ``"smoothed"`` (:mod:`planners.optimisation.curvature`) too, else it is Gauss-Newton).
        second_order: after a rejected step that raised the constraint violation, try it once more with
            a second-order correction (the least-norm step back to the linearised working set): along
            curved constraints the l1 merit rejects good steps (the Maratos effect).
        extrapolate: after an accepted step d whose actual merit decrease exceeds 1.25 times the
            model's prediction, try 2 d and then 4 d and keep the best (one evaluation without
            derivatives each): where the model overestimates the curvature (J_e is close to linear
            along the step), it can save iterations (with the ``"smoothed"`` defaults it did not pay).
        power_width, majoriser_share: mu [W] and the majoriser's share of the ``"smoothed"`` curvature
            (:func:`planners.optimisation.curvature.power_curvature`).
        kinks: with ``curvature="smoothed"``, cut each step d to t d, the minimiser over t in (0, 1] of the merit's
            model with J_e's kinks (:func:`planners.optimisation.curvature.along_step`), and judge it (the trust
            region's ratio) by that model's predicted decrease (module docstring, "Step length"). False (the
            default): the QP's step and its own predicted decrease.
        trial_derivatives: evaluate a trial point with its derivatives (unless the trial before was
            rejected): an accepted trial is the next iterate, whose derivatives the next iteration needs,
            so one evaluation serves both; a rejected one costs the derivatives in vain. The planning
            problems accept nearly every step, and a value-only evaluation costs 2-22 % of one with
            derivatives. The values of an evaluation with derivatives agree with the value-only ones to
            round-off, so the iterates are the same either way unless an acceptance test falls within
            round-off of its threshold (on the built-in missions they are the same bit for bit).
    """

    max_iterations: int = 100
    tolerance: float = 1e-4
    feasibility: float = 1e-7
    radius: float = 1.0
    penalty: float = 10.0
    patience: int = 10
    crawl: float = 0.1
    stop: str = "progress"
    kkt_tolerance: float = 1e-5
    curvature: str = "gauss-newton"
    second_order: bool = False
    extrapolate: bool = False
    power_width: float = POWER_WIDTH
    majoriser_share: float = MAJORISER_SHARE
    trial_derivatives: bool = True
    kinks: bool = False

    def __post_init__(self):
        if self.stop not in STOPS:
            raise PlannerArgumentError("stop", self.stop,
                                       f"stop={self.stop!r}: use one of {', '.join(STOPS)}")
        if self.curvature not in CURVATURES:
            raise PlannerArgumentError("curvature", self.curvature,
                                       f"curvature={self.curvature!r}: use one of {', '.join(CURVATURES)}")
        if not self.kkt_tolerance > 0:
            raise PlannerArgumentError("kkt_tolerance", self.kkt_tolerance,
                                       f"kkt_tolerance={self.kkt_tolerance!r}: must be > 0")


@dataclass(frozen=True)
class Kkt:
    """The KKT residual of a point and its multipliers (see the module docstring for the scaling).

    Attributes:
        stationarity: |nabla J - sum_i lambda_i nabla c_hat_i|_inf.
        complementarity: max_i lambda_i |c_hat_i|.
        feasibility: max_i max(0, -c_i).
        residual: the largest of the three.
        active: how many constraints carry a multiplier above 1e-9.
    """

    stationarity: float
    complementarity: float
    feasibility: float
    active: int = 0

    @property
    def residual(self) -> float:
        """max(stationarity, complementarity, feasibility)."""
        return max(self.stationarity, self.complementarity, self.feasibility)


@dataclass
class SqpOutcome:
    """What happened: x, success, message, counts, wall time, and the KKT residual.

    ``evaluations`` counts the problem's evaluations without derivatives, ``gradient_evaluations`` those
    with (each evaluation once: one after a rejected step is reused, one of a trial serves the next
    iteration and the end).

    ``kkt`` is the KKT residual of the returned x with the multipliers of the last QP solved
    (``multipliers``: one per constraint, >= 0, in the units of the problem's constraints).
    """

    x: np.ndarray
    success: bool
    message: str
    iterations: int
    evaluations: int
    gradient_evaluations: int
    wall_time: float
    J: float
    violation: float
    kkt: Kkt | None = None
    multipliers: np.ndarray | None = None


def _violation(c) -> float:
    return float(np.maximum(0.0, -np.asarray(c)).sum())


def row_norms(jacobian) -> np.ndarray:
    """max(1, |nabla c_i|_inf) of every constraint row: the scaling of c_hat (module docstring)."""
    if sparse.issparse(jacobian):
        if jacobian.shape[0] == 0 or jacobian.shape[1] == 0:
            return np.ones(jacobian.shape[0])
        return np.maximum(abs(jacobian).max(axis=1).toarray().reshape(-1), 1.0)
    a = np.asarray(jacobian)
    return np.maximum(np.abs(a).max(axis=1), 1.0) if a.size else np.ones(a.shape[0])


def kkt_residual(gradient, constraints, jacobian, multipliers) -> Kkt:
    """The KKT residual of min J s.t. c >= 0 at a point (module docstring).

    Args:
        gradient: nabla J (n,).
        constraints: c (m,), >= 0 where satisfied.
        jacobian: nabla c (m, n), an array or a scipy sparse matrix.
        multipliers: lambda (m,) in the units of c (negative entries are taken as 0).
    """
    c = np.asarray(constraints, dtype=float)
    a = jacobian if sparse.issparse(jacobian) else np.asarray(jacobian, dtype=float).reshape(c.size, -1)
    lam = np.maximum(np.asarray(multipliers, dtype=float), 0.0)
    norms = row_norms(a)
    lam_hat = lam * norms  # multipliers of c_hat = c / norms
    stationarity = float(np.abs(np.asarray(gradient) - a.T @ lam).max()) if a.shape[1] else 0.0
    complementarity = float((lam_hat * np.abs(c / norms)).max()) if c.size else 0.0
    feasibility = float(max(0.0, -c.min())) if c.size else 0.0
    return Kkt(stationarity, complementarity, feasibility, int(np.count_nonzero(lam_hat > 1e-9)))


def _jacobian(ev):
    """The constraints' Jacobian of an Evaluation: its sparse copy when it has one, else the array."""
    sparse_copy = getattr(ev, "jacobian_sparse", None)
    return ev.jacobian if sparse_copy is None else sparse_copy


def _qp_step(ev, radius: float, penalty: float, hessian=None, start: ActiveSet | None = None,
             interior_first: bool = False):
    """Solve the elastic step QP; returns (d, predicted merit decrease, linearised violation, multipliers,
    the active set at the solution or None, whether the active set gave up (or was not tried)).

    Only the constraints violated at x get a slack (the others hold at d = 0, so the QP is always
    feasible; in the active set a violated constraint is an elastic row, its multiplier capped at the
    penalty). Rows are scaled to unit infinity norm (and, for ProxQP, the objective to O(1)): near a vanishing
    thrust the roll rows reach 1e7 and the QP would crawl; the minimiser is unchanged. The QP is solved
    exactly by :func:`planners.optimisation.active_set.solve_step_qp`, from ``start`` (an
    :class:`~planners.optimisation.active_set.ActiveSet` whose rows are indices of the constraints, e.g. the
    last step's); where it gives up, by the interior point
    (:func:`planners.optimisation.interior_point.solve_interior_point`); where that fails too, by ProxQP, whose
    work is bounded: an inexact step is judged by the merit ratio anyway. ``hessian`` is the model's curvature
    (default the problem's Gauss-Newton matrix; banded or an array); the multipliers (m,) are >= 0, in the
    units of the constraints, 0 for the rows left out. ``interior_first``: go to the interior point directly
    (the SQP's choice after the active set gave up twice in a row). The Jacobian's CSR copy (each row touches one
    segment: a few per cent of its entries are non-zero on a long mission) stays a CSR matrix from the selection to
    the solvers.
    """
    hess = ev.hessian if hessian is None else hessian
    n = ev.gradient.size
    c, a = ev.constraints, _jacobian(ev)
    keep = np.flatnonzero(c - np.asarray(abs(a).sum(axis=1)).ravel() * radius <= 0.0)
    a_keep = a[keep]
    norms = row_norms(a_keep)
    c_k, a_k = c[keep] / norms, _rows_divided(a_keep, norms)
    soft = np.flatnonzero(c_k < 0.0)
    p = soft.size
    if start is not None:  # its rows as indices of the kept rows
        position = {int(k): i for i, k in enumerate(keep)}
        start = ActiveSet(start.bounds, tuple(position[k] for k in start.rows if k in position))
    caps = np.full(keep.size, np.inf)
    caps[soft] = penalty * norms[soft]  # a violated row's penalty, in row-scaled units (elastic rows)
    caps = caps if p else None
    solved = None if interior_first else \
        solve_step_qp(hess, ev.gradient, a_k, -c_k, radius, start=start, shift=_shift(hess), caps=caps)
    gave_up = solved is None
    if solved is None:  # the active set gave up: the interior-point route (planners.optimisation.interior_point)
        inner = solve_interior_point(hess, ev.gradient, a_k, -c_k, radius, shift=_shift(hess), caps=caps)
        if inner is not None:
            solved = inner[0], inner[1], ActiveSet(inner[2], inner[3])
    if solved is not None:
        d, lam, active = solved
        multipliers = np.zeros(c.size)
        multipliers[keep] = lam / norms
        linear = _violation(c + a @ d)
        model = ev.gradient @ d + 0.5 * d @ (hess @ d)
        return (d, penalty * (_violation(c) - linear) - model, linear, multipliers,
                ActiveSet(active.bounds, tuple(int(keep[k]) for k in active.rows)), gave_up)
    scale = 1.0 / max(1.0, _abs_max(hess))
    g = np.concatenate([ev.gradient * scale, penalty * norms[soft] * scale])  # slack in row-scaled units
    if isinstance(hess, Banded) or sparse.issparse(a_k):  # the sparse backend (_proxqp): no dense copies
        h = sparse.block_diag([_upper(_regularised(hess)) * scale, sparse.csc_matrix((p, p))], format="csc")
        slack = sparse.csr_matrix((np.ones(p), (soft, np.arange(p))), shape=(keep.size, p))
        rows = sparse.vstack([sparse.hstack([sparse.csr_matrix(a_k), slack]), sparse.identity(n + p)],
                             format="csc")
        rows.eliminate_zeros()
    else:
        h = np.zeros((n + p, n + p))
        h[:n, :n] = _regularised(hess) * scale
        slack = np.zeros((keep.size, p))
        slack[soft, np.arange(p)] = 1.0
        rows = np.vstack([np.hstack([a_k, slack]), np.eye(n + p)])
    lower = np.concatenate([-c_k, np.full(n, -radius), np.zeros(p)])
    upper = np.concatenate([np.full(keep.size, np.inf), np.full(n, radius), np.full(p, np.inf)])
    res = _proxqp(h, g, rows, lower, upper)
    d = np.clip(np.asarray(res.x)[:n], -radius, radius)
    model = ev.gradient @ d + 0.5 * d @ (hess @ d)
    linear = _violation(c + a @ d)  # the pruned constraints stay satisfied inside the region
    predicted = penalty * (_violation(c) - linear) - model
    # multipliers of the constraint rows, back in the units of c (ProxQP: z < 0 on an active lower bound)
    multipliers = np.zeros(c.size)
    if keep.size:
        multipliers[keep] = np.maximum(-np.asarray(res.z)[:keep.size], 0.0) / (norms * scale)
    return d, predicted, linear, multipliers, None, True


def _abs_max(hess) -> float:
    """max |H_ij| of an array or a :class:`~planners.problem.banded.Banded` matrix."""
    return hess.abs_max() if isinstance(hess, Banded) else float(np.abs(hess).max())


def _upper(hess) -> sparse.csc_matrix:
    """The upper triangle of H (banded or an array) as a CSC matrix."""
    return hess.to_sparse_upper() if isinstance(hess, Banded) else sparse.csc_matrix(np.triu(hess))


def _proxqp(h, g, rows, lower, upper):
    """ProxQP on min 1/2 y^T h y + g^T y s.t. lower <= rows y <= upper (capped at 300 iterations).

    Its sparse backend when h is a sparse matrix (its upper triangle: a long mission's H is banded and each
    row touches one or two segments, a few per cent of the entries), the dense one for arrays.
    """
    proxqp = proxsuite_module().proxqp  # the portable build (fpr.model.qp): plans repeat bit for bit
    if not sparse.issparse(h):
        rows = rows.toarray() if sparse.issparse(rows) else rows
        return proxqp.dense.solve(h, g, None, None, rows, lower, upper, eps_abs=1e-9, max_iter=300)
    return proxqp.sparse.solve(sparse.csc_matrix(h), g, None, None, sparse.csc_matrix(rows),
                               lower, upper, eps_abs=1e-9, max_iter=300)


def _shift(hess) -> float:
    """1e-9 mean(diag H) (at least 1e-21): what the step QP adds to H's diagonal to make it positive definite."""
    trace = hess.trace() if isinstance(hess, Banded) else np.trace(hess)
    return 1e-9 * max(trace / hess.shape[0], 1e-12)


def _regularised(hess):
    """H + :func:`_shift` (H) I: the step QP's curvature made positive definite."""
    return shifted(hess, _shift(hess))


def _rows_divided(a, norms):
    """The rows of ``a`` (an array or a CSR matrix) divided by ``norms``, in the same format (same numbers)."""
    if not sparse.issparse(a):
        return a / norms[:, None]
    out = sparse.csr_matrix(a, copy=True)
    out.data /= np.repeat(norms, np.diff(out.indptr))
    return out


def _smooth_abs(p):
    return np.sqrt(p * p + POWER_SMOOTHING**2) - POWER_SMOOTHING


def _composite_qp_step(ev, radius: float, penalty: float, hessian):
    """The elastic step QP with J's sum of weighted |P_k| (J_e) modelled piecewise linearly.

    J = a_phi J_phi + sum_k pw_k |P_k| (``ev.power``...). Terms that cannot change sign inside the trust
    region (|P_k| > |nabla P_k|_1 Delta) are linear there and go to the gradient; each of the others
    gets a variable t_k >= |P_k + nabla P_k d| (two rows) and pw_k t_k in the objective. ``hessian``
    models the rest (J_phi's Gauss-Newton matrix and the quasi-Newton correction).

    Returns:
        (d, predicted merit decrease, linearised violation, constraint multipliers (m,), xi (K,)):
        xi_k in [-1, 1] is the subgradient of |.| at P_k the QP's multipliers give (sign(P_k) for the
        terms left linear).
    """
    n = ev.gradient.size
    c, a = ev.constraints, ev.jacobian
    pw, pv, pj = ev.power_weight, ev.power, ev.power_jacobian
    smooth_slope = pv / np.sqrt(pv * pv + POWER_SMOOTHING**2)
    g_phi = ev.gradient - pj.T @ (pw * smooth_slope)  # the J_phi part of the gradient
    near = np.flatnonzero(np.abs(pv) <= np.abs(pj).sum(axis=1) * radius)
    far = np.setdiff1d(np.arange(pv.size), near)
    xi = np.sign(pv)
    g_lin = g_phi + pj[far].T @ (pw[far] * xi[far])
    keep = np.flatnonzero(c - np.abs(a).sum(axis=1) * radius <= 0.0)
    norms = np.maximum(np.abs(a[keep]).max(axis=1), 1.0)
    c_k, a_k = c[keep] / norms, a[keep] / norms[:, None]
    soft = np.flatnonzero(c_k < 0.0)
    p, q = soft.size, near.size
    p_norms = np.maximum(np.abs(pj[near]).max(axis=1), 1.0) if q else np.ones(0)
    pj_k, pv_k = pj[near] / p_norms[:, None], pv[near] / p_norms
    scale = 1.0 / max(1.0, np.abs(hessian).max())
    size = n + q + p
    h = np.zeros((size, size))
    h[:n, :n] = _regularised(hessian) * scale
    g = np.concatenate([g_lin * scale, pw[near] * p_norms * scale, penalty * norms[soft] * scale])
    m_c = keep.size
    rows = np.zeros((m_c + 2 * q + size, size))
    rows[:m_c, :n] = a_k
    rows[soft, n + q + np.arange(p)] = 1.0
    rows[m_c:m_c + q, :n], rows[m_c + q:m_c + 2 * q, :n] = -pj_k, pj_k  # t - dP >= P, t + dP >= -P
    rows[m_c + np.arange(q), n + np.arange(q)] = 1.0
    rows[m_c + q + np.arange(q), n + np.arange(q)] = 1.0
    rows[m_c + 2 * q:] = np.eye(size)
    lower = np.concatenate([-c_k, pv_k, -pv_k, np.full(n, -radius), np.full(q, -np.inf), np.zeros(p)])
    upper = np.concatenate([np.full(m_c + 2 * q, np.inf), np.full(n, radius), np.full(q + p, np.inf)])
    proxqp = proxsuite_module().proxqp  # the portable build (fpr.model.qp)
    res = proxqp.dense.solve(h, g, None, None, rows, lower, upper, eps_abs=1e-9, max_iter=300)
    d = np.clip(np.asarray(res.x)[:n], -radius, radius)
    z = np.asarray(res.z)
    model = g_phi @ d + 0.5 * d @ hessian @ d + pw @ (_smooth_abs(pv + pj @ d) - _smooth_abs(pv))
    linear = _violation(c + a @ d)
    predicted = penalty * (_violation(c) - linear) - model
    multipliers = np.zeros(c.size)
    if m_c:
        multipliers[keep] = np.maximum(-z[:m_c], 0.0) / (norms * scale)
    if q:  # xi pw = (-z_plus) - (-z_minus), back from the row and objective scaling
        plus, minus = np.maximum(-z[m_c:m_c + q], 0.0), np.maximum(-z[m_c + q:m_c + 2 * q], 0.0)
        xi[near] = np.clip((plus - minus) / (p_norms * scale * pw[near]), -1.0, 1.0)
    return d, predicted, linear, multipliers, xi


def _model_gradient(ev, xi, composite: bool) -> np.ndarray:
    """The objective's gradient the KKT residual uses.

    nabla J, or with J_e's |P_k| as a nonsmooth sum, nabla (a_phi J_phi) + sum_k pw_k xi_k nabla P_k
    (xi_k a subgradient of |.| at P_k, from the QP).
    """
    if not composite:
        return ev.gradient
    pv, pj, pw = ev.power, ev.power_jacobian, ev.power_weight
    g_phi = ev.gradient - pj.T @ (pw * pv / np.sqrt(pv * pv + POWER_SMOOTHING**2))
    return g_phi + pj.T @ (pw * (np.sign(pv) if xi is None else xi))


def _second_order_correction(ev, d, multipliers, trial_constraints) -> np.ndarray:
    """The second-order correction of the Maratos effect.

    The least-norm dd with A_W dd = -c_W(x + d) on the working set W (rows with a positive multiplier,
    or violated at x + d).
    """
    work = np.flatnonzero((multipliers > 0.0) | (trial_constraints < 0.0))
    if work.size == 0:
        return np.zeros_like(d)
    a = ev.jacobian[work]
    gram = a @ a.T
    gram += 1e-12 * max(float(np.trace(gram)), 1e-300) * np.eye(work.size)
    return -a.T @ np.linalg.solve(gram, trial_constraints[work])


def _floored(b: np.ndarray) -> np.ndarray:
    """The symmetric b with its eigenvalues floored at 1e-8 of the largest (positive definite)."""
    b = 0.5 * (b + b.T)
    w, v = np.linalg.eigh(b)
    top = max(float(w[-1]), 1e-12)
    if w[0] >= 1e-8 * top:
        return b
    return (v * np.maximum(w, 1e-8 * top)) @ v.T


def damped_bfgs(b: np.ndarray, s: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Powell's damped BFGS update of a positive definite b with the step s and gradient change y.

    y is replaced by r = theta y + (1 - theta) b s, theta the largest in [0, 1] with s^T r >= 0.2 s^T b s,
    so the update stays positive definite (Nocedal & Wright, procedure 18.2).
    """
    bs = b @ s
    sbs = float(s @ bs)
    if not sbs > 0.0:
        return b
    sy = float(s @ y)
    theta = 1.0 if sy >= 0.2 * sbs else 0.8 * sbs / (sbs - sy)
    r = theta * y + (1.0 - theta) * bs
    return b - np.outer(bs, bs) / sbs + np.outer(r, r) / float(s @ r)


def prepare(problem, options: SqpOptions) -> None:
    """Set ``problem`` up for ``options`` before its first evaluation.

    The ``"composite"`` and ``"smoothed"`` curvatures need the powers and their derivatives with every
    gradient (``problem.power_model``); an evaluation cached without them is dropped.
    """
    if options.curvature in ("composite", "smoothed") and hasattr(problem, "power_model") \
            and not problem.power_model:
        problem.power_model = True
        problem._cache = None


def solve_sqp(problem, x0, options: SqpOptions | None = None, progress=None, name: str = "") -> SqpOutcome:
    """Minimise ``problem``'s J subject to its constraints >= 0, from x0.

    Args:
        problem: a :class:`planners.problem.motion.MotionProblem` (``evaluate(x, derivatives)`` returning J,
            constraints, gradient, jacobian, a positive semi-definite ``hessian`` and ``violation``).
        x0: start.
        options: :class:`SqpOptions`.
        progress: ``progress(name, iteration, J, violation)`` after each iteration, or None.
        name: stage name passed to ``progress``.
    """
    opt = options or SqpOptions()
    start = time.perf_counter()
    prepare(problem, opt)
    x = np.asarray(x0, dtype=float).copy()
    radius, penalty = opt.radius, opt.penalty
    evaluations = gradients = 0
    message, success = "iteration limit reached", False
    it = 0
    best_violation, last_progress = np.inf, 0
    history, merits = [], []  # the violation and the merit after each iteration
    correction = None  # S of the structured quasi-Newton model H_GN + S
    pending = None  # (s, grad L at the point before, multipliers) of the last accepted step
    kkt = multipliers = xi = None
    composite = False
    known = None  # the evaluation with derivatives at x, when one is at hand (x unchanged, or a trial's)
    active_set = None  # the active set of the last step QP solved exactly (bounds and rows)
    # how many step QPs in a row the active set gave up on: from two on, the interior point goes first (the
    # active set's give-ups come in runs of tens where the model's H is far from diagonally dominant, and a
    # failed attempt costs about half an interior-point solve; an isolated one leaves it tried again)
    give_ups = 0
    trial_derivatives = opt.trial_derivatives
    for it in range(1, opt.max_iterations + 1):
        if known is None:
            known = problem.evaluate(x, True)
            gradients += 1
        ev = known
        composite = opt.curvature == "composite" and getattr(ev, "power", None) is not None
        hessian = None
        if opt.curvature == "composite":
            base = np.asarray(ev.rate_hessian if composite else ev.hessian)
            model = _floored(base + (correction if correction is not None else 0.0))
            if pending is not None:
                step, before, lam, xi = pending
                change = _model_gradient(ev, xi, composite) - ev.jacobian.T @ lam - before
                model = damped_bfgs(model, step, change)
            correction, hessian = model - base, model
        elif opt.curvature == "smoothed":
            hessian = smoothed_hessian(ev, opt.power_width, opt.majoriser_share)

        def solve_qp(rho, ev=ev, hessian=hessian, composite=composite, radius=radius, start=active_set,
                     interior_first=give_ups >= 2):
            if composite:
                return (*_composite_qp_step(ev, radius, rho, hessian), None)
            d, predicted, linear, multipliers, active, gave_up = _qp_step(
                ev, radius, rho, hessian, start=start, interior_first=interior_first)
            return d, predicted, linear, multipliers, None, (active, gave_up)

        merit = ev.J + penalty * _violation(ev.constraints)
        d, predicted, linear, multipliers, xi, active = solve_qp(penalty)
        # the l1 merit is exact only with rho above the multipliers; and while the linearised constraints
        # cannot be met, weigh feasibility more
        top = float(multipliers.max()) if multipliers.size else 0.0
        wanted = max(2.0 * top, 10.0 * penalty if linear > 1e-9 else 0.0)
        if wanted > penalty and penalty < 1e6:
            penalty = min(wanted, 1e6)
            merit = ev.J + penalty * _violation(ev.constraints)
            d, predicted, linear, multipliers, xi, active = solve_qp(penalty)
        if active is not None:  # (the composite QP's is None)
            active, gave_up = active
            active_set = active if active is not None else active_set  # where the next step QP starts
            give_ups = give_ups + 1 if gave_up else 0
        objective_gradient = _model_gradient(ev, xi, composite)
        kkt = kkt_residual(objective_gradient, ev.constraints, _jacobian(ev), multipliers)
        if opt.stop == "kkt" and kkt.residual <= opt.kkt_tolerance and ev.violation <= opt.feasibility:
            success, message = True, f"converged: KKT residual {kkt.residual:.2g} <= {opt.kkt_tolerance:g}"
            break
        if predicted <= (1e-12 if opt.stop == "progress" else 1e-16) * max(1.0, abs(ev.J)):
            viol = ev.violation
            success = viol <= opt.feasibility
            message = f"converged: no decrease predicted (KKT residual {kkt.residual:.2g})" if success else \
                "stopped at a point where the linearised constraints cannot be met (locally infeasible)"
            break
        if opt.kinks and opt.curvature == "smoothed" and getattr(ev, "power", None) is not None:
            # the step's length along d by the model with J_e's kinks (the QP's smoothed curvature misses them)
            d, predicted = along_step(ev, d, penalty, predicted)
        trial = problem.evaluate(x + d, trial_derivatives)
        gradients, evaluations = (gradients + 1, evaluations) if trial_derivatives else (gradients, evaluations + 1)
        actual = merit - (trial.J + penalty * _violation(trial.constraints))
        ratio = actual / predicted
        if ratio <= 0.1 and opt.second_order and trial.violation > ev.violation:
            # the Maratos effect: a good step along curved constraints raises their violation; correct
            # it back to the constraints' linearisation (least-norm step, the Jacobian at x)
            corrected = d + _second_order_correction(ev, d, multipliers, trial.constraints)
            if np.abs(corrected).max() <= radius:
                again = problem.evaluate(x + corrected)
                evaluations += 1
                if merit - (again.J + penalty * _violation(again.constraints)) > 0.1 * predicted:
                    d, trial = corrected, again
                    actual = merit - (trial.J + penalty * _violation(trial.constraints))
                    ratio = actual / predicted
        accepted = ratio > 0.1
        step_size = float(np.abs(d).max())  # the trust-region step's, before any extrapolation past it
        logger.debug("%s iteration %d: radius %.3g, step %.3g, predicted %.3g, ratio %.3g, J %.6g, violation %.2g",
                     name, it, radius, step_size, predicted, ratio, trial.J, trial.violation)
        if accepted and opt.extrapolate and ratio > 1.25:
            # the model was pessimistic along d (J_e is close to linear there): try 2 d, then 4 d
            for _ in range(2):
                longer = problem.evaluate(x + 2.0 * d)
                evaluations += 1
                if longer.J + penalty * _violation(longer.constraints) >= \
                        trial.J + penalty * _violation(trial.constraints):
                    break
                d, trial = 2.0 * d, longer
            actual = merit - (trial.J + penalty * _violation(trial.constraints))
        trial_derivatives = opt.trial_derivatives and accepted  # after a rejection, the next trial values only
        if accepted:
            pending = (d, objective_gradient - _jacobian(ev).T @ multipliers, multipliers, xi)
            x = x + d
            known = trial if trial.gradient is not None else None  # (an extrapolated trial has no derivatives)
            if ratio > 0.75 and step_size > 0.9 * radius:
                radius *= 2.0
        else:
            radius *= 0.25
        now = trial if accepted else ev
        viol = now.violation
        if progress is not None:
            progress(name, it, now.J, viol)
        # an infeasible request: stop once the violation has not improved by 1 % in `patience` iterations
        if viol < 0.99 * best_violation or (accepted and viol <= 1e-3):  # small violations: keep polishing
            best_violation, last_progress = min(viol, best_violation), it
        elif viol > opt.feasibility and it - last_progress >= opt.patience:
            message = (f"stopped: the constraint violation ({viol:.3g}) has not decreased for {opt.patience} "
                       "iterations (the request looks infeasible)")
            break
        history.append(viol)
        merits.append(now.J + penalty * _violation(now.constraints))
        if len(history) > opt.patience and viol > max(opt.feasibility, 1e-3) \
                and viol > (1.0 - opt.crawl) * history[-1 - opt.patience]:
            message = (f"stopped: the constraint violation ({viol:.3g}) decreased by less than "
                       f"{opt.crawl:.0%} in {opt.patience} iterations (the request looks infeasible)")
            break
        if opt.stop == "progress":
            if accepted and actual < opt.tolerance * max(1.0, abs(trial.J)) and viol <= opt.feasibility:
                success, message = True, "converged: merit decrease below tolerance"
                break
        elif len(merits) > opt.patience and viol <= opt.feasibility \
                and merits[-1 - opt.patience] - merits[-1] < opt.tolerance**2 * max(1.0, abs(now.J)):
            success = True
            message = (f"converged: the merit decreased by less than {opt.tolerance**2:.2g} in "
                       f"{opt.patience} "
                       "iterations (round-off)")
            break
        if radius < 1e-10:
            if known is None:
                known = problem.evaluate(x, True)
                gradients += 1
            viol = known.violation
            success = viol <= opt.feasibility
            message = "converged: trust region collapsed" if success else "trust region collapsed while infeasible"
            break
    if known is None:
        known = problem.evaluate(x, True)
        gradients += 1
    final = known
    if kkt is None or final is not ev:
        # the returned x moved after the last QP: its KKT residual with the last multipliers
        kkt = kkt_residual(_model_gradient(final, xi, composite), final.constraints, _jacobian(final),
                           multipliers)
    return SqpOutcome(x, success, message, it, evaluations, gradients, time.perf_counter() - start, final.J,
                      final.violation, kkt, multipliers)
