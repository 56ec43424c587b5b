"""A small trust-region SQP for the planning NLP: Gauss-Newton curvature, elastic QPs by ProxQP.

The planning objective is a weighted sum of integrals of squares (J_phi) and of absolute values
(J_e) of per-sample quantities whose exact Jacobians :class:`planners.problem.MotionProblem`
provides; their Gauss-Newton / reweighted least-squares matrix is a good positive semi-definite
model of the Hessian, far better than a quasi-Newton estimate built from scratch (SLSQP needs
hundreds of iterations on these problems, this method a handful).

Each iteration solves the elastic (S-l1-QP) subproblem

.. math:: \\min_{d, s} \\tfrac12 d^T H d + g^T d + \\rho \\mathbf 1^T s \\quad
          \\text{s.t.}\\; c + A d + s \\ge 0,\\; s \\ge 0,\\; |d|_\\infty \\le \\Delta,

with slacks s only on the constraints violated at x (always feasible), and accepts the step by the ratio of actual to predicted decrease of the exact l1 merit
J + rho * sum(max(0, -c)). Constraints that cannot become active inside the trust region
(c_i > |A_i|_1 Delta) are left out of the QP, which keeps it small.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from fpr.model.qp import proxsuite_module

# the portable build: its results do not depend on memory alignment (fpr.model.qp): plans repeat bit for bit
proxsuite = proxsuite_module()


@dataclass
class SqpOptions:
    """Settings of :func:`solve_sqp`.

    Attributes:
        max_iterations: iteration limit (each iteration is one exact-derivative evaluation).
        tolerance: stop when an accepted step decreases the merit by less than this (relative to
            max(1, |J|)) and the constraints hold.
        feasibility: largest accepted (scaled) constraint violation.
        radius: initial trust-region radius in the scaled variables.
        penalty: initial l1 penalty weight rho; raised while the linearised constraints cannot be met.
        patience: iterations without a 1 % decrease of the constraint violation after which an
            infeasible run stops.
        crawl: an infeasible run (violation above 1e-3) also stops when its violation decreased by less
            than this fraction over the last ``patience`` iterations (a crawl towards an unreachable
            feasible set: the infeasible square decreased it by 0.5 % an iteration for 90 iterations).
    """

    max_iterations: int = 100
    tolerance: float = 1e-4
    feasibility: float = 1e-7
    radius: float = 1.0
    penalty: float = 10.0
    patience: int = 10
    crawl: float = 0.1


@dataclass
class SqpOutcome:
    """What happened: x, success, message, iteration and evaluation counts, wall time."""

    x: np.ndarray
    success: bool
    message: str
    iterations: int
    evaluations: int
    gradient_evaluations: int
    wall_time: float
    J: float
    violation: float


def _violation(c) -> float:
    return float(np.maximum(0.0, -np.asarray(c)).sum())


def _qp_step(ev, radius: float, penalty: float):
    """Solve the elastic step QP; returns (d, predicted merit decrease, linearised violation, multiplier).

    Only the constraints violated at x get a slack (the others hold at d = 0, so the QP is always
    feasible). Rows are scaled to unit infinity norm and the objective to O(1): near a vanishing
    thrust the roll rows reach 1e7 and the QP would crawl; the minimiser is unchanged. ProxQP's work
    is bounded: an inexact step is judged by the merit ratio anyway.
    """
    n = ev.gradient.size
    c, a = ev.constraints, ev.jacobian
    keep = np.flatnonzero(c - np.abs(a).sum(axis=1) * radius <= 0.0)
    norms = np.maximum(np.abs(a[keep]).max(axis=1), 1.0)
    c_k, a_k = c[keep] / norms, a[keep] / norms[:, None]
    soft = np.flatnonzero(c_k < 0.0)
    p = soft.size
    scale = 1.0 / max(1.0, np.abs(ev.hessian).max())
    h = np.zeros((n + p, n + p))
    h[:n, :n] = (ev.hessian + (1e-9 * max(np.trace(ev.hessian) / n, 1e-12)) * np.eye(n)) * scale
    g = np.concatenate([ev.gradient * scale, penalty * norms[soft] * scale])  # slack in row-scaled units
    slack = np.zeros((keep.size, p))
    slack[soft, np.arange(p)] = 1.0
    rows = np.vstack([np.hstack([a_k, slack]), np.eye(n + p)])
    lower = np.concatenate([-c_k, np.full(n, -radius), np.zeros(p)])
    upper = np.concatenate([np.full(keep.size, np.inf), np.full(n, radius), np.full(p, np.inf)])
    res = proxsuite.proxqp.dense.solve(h, g, None, None, rows, lower, upper, eps_abs=1e-9, max_iter=300)
    d = np.clip(np.asarray(res.x)[:n], -radius, radius)
    model = ev.gradient @ d + 0.5 * d @ ev.hessian @ d
    linear = _violation(c + a @ d)  # the pruned constraints stay satisfied inside the region
    predicted = penalty * (_violation(c) - linear) - model
    # multipliers of the constraint rows, back in the units of c
    duals = np.abs(np.asarray(res.z)[:keep.size]) / (norms * scale) if keep.size else np.zeros(0)
    return d, predicted, linear, float(duals.max()) if duals.size else 0.0


def solve_sqp(problem, x0, options: SqpOptions | None = None, progress=None, name: str = "") -> SqpOutcome:
    """Minimise ``problem``'s J subject to its constraints >= 0, from x0.

    Args:
        problem: a :class:`planners.problem.MotionProblem` (``evaluate(x, derivatives)``).
        x0: start.
        options: :class:`SqpOptions`.
        progress: ``progress(name, iteration, J, violation)`` after each iteration, or None.
        name: stage name passed to ``progress``.
    """
    opt = options or SqpOptions()
    start = time.perf_counter()
    x = np.asarray(x0, dtype=float).copy()
    radius, penalty = opt.radius, opt.penalty
    evaluations = gradients = 0
    message, success = "iteration limit reached", False
    it = 0
    best_violation, last_progress = np.inf, 0
    history = []  # the violation after each iteration
    for it in range(1, opt.max_iterations + 1):
        ev = problem.evaluate(x, True)
        gradients += 1
        merit = ev.J + penalty * _violation(ev.constraints)
        d, predicted, linear, multiplier = _qp_step(ev, radius, penalty)
        # the l1 merit is exact only with rho above the multipliers; and while the linearisation cannot
        # be met, weigh feasibility more
        wanted = max(2.0 * multiplier, 10.0 * penalty if linear > 1e-9 else 0.0)
        if wanted > penalty and penalty < 1e6:
            penalty = min(wanted, 1e6)
            merit = ev.J + penalty * _violation(ev.constraints)
            d, predicted, linear, _ = _qp_step(ev, radius, penalty)
        if predicted <= 1e-12 * max(1.0, abs(ev.J)):
            viol = ev.violation
            success = viol <= opt.feasibility
            message = "converged: no decrease predicted" if success else \
                "stopped at a point where the linearised constraints cannot be met (locally infeasible)"
            break
        trial = problem.evaluate(x + d)
        evaluations += 1
        actual = merit - (trial.J + penalty * _violation(trial.constraints))
        ratio = actual / predicted
        accepted = ratio > 0.1
        if accepted:
            x = x + d
            if ratio > 0.75 and np.abs(d).max() > 0.9 * radius:
                radius *= 2.0
        else:
            radius *= 0.25
        viol = (trial if accepted else ev).violation
        if progress is not None:
            progress(name, it, (trial if accepted else ev).J, viol)
        # an infeasible request: stop once the violation has not improved by 1 % in `patience` iterations
        if viol < 0.99 * best_violation or (accepted and viol <= 1e-3):  # small violations: keep polishing
            best_violation, last_progress = min(viol, best_violation), it
        elif viol > opt.feasibility and it - last_progress >= opt.patience:
            message = (f"stopped: the constraint violation ({viol:.3g}) has not decreased for {opt.patience} "
                       "iterations (the request looks infeasible)")
            break
        history.append(viol)
        if len(history) > opt.patience and viol > max(opt.feasibility, 1e-3) \
                and viol > (1.0 - opt.crawl) * history[-1 - opt.patience]:
            message = (f"stopped: the constraint violation ({viol:.3g}) decreased by less than "
                       f"{opt.crawl:.0%} in {opt.patience} iterations (the request looks infeasible)")
            break
        if accepted and actual < opt.tolerance * max(1.0, abs(trial.J)) and viol <= opt.feasibility:
            success, message = True, "converged: merit decrease below tolerance"
            break
        if radius < 1e-10:
            viol = problem.evaluate(x).violation
            success = viol <= opt.feasibility
            message = "converged: trust region collapsed" if success else "trust region collapsed while infeasible"
            break
    final = problem.evaluate(x)
    return SqpOutcome(x, success, message, it, evaluations, gradients, time.perf_counter() - start, final.J,
                      final.violation)
