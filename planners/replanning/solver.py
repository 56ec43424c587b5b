"""The replanner's own small SQP: few iterations from a warm start, a dense active-set QP per iteration.

A replan starts from the plan in force, which is already near-optimal (the rest of the offline plan, or
that plan shifted to a moved way point): it needs a few Gauss-Newton SQP steps, not a general solver's
robustness. :func:`solve_warm` is the elastic trust-region SQP of :mod:`planners.optimisation.sqp` (same subproblem:
Gauss-Newton curvature of :class:`planners.problem.motion.MotionProblem`, slacks on the constraints violated at
x, constraints that cannot become active in the trust region left out, rows scaled to unit infinity
norm, exact l1 merit and ratio test), with two differences chosen for latency:

* the QP is solved by Goldfarb and Idnani's dual active-set method (``quadprog``), exact and, for the
  replanner's ~60 variables, about 20 times cheaper than ProxQP, whose cost barely depends on the size;
* an explicit iteration cap (:class:`planners.replanning.replanner.ReplanOptions`), and it stops as soon as an
  accepted, feasible step improves the merit by less than ``tolerance`` (relative);
* a budget: an iteration after the first starts only when the caller's ``afford`` says its cost fits
  (the replanner: the deterministic latency with one more derivative and value evaluation within the
  deadline), so a refinement never makes a plan late;
* the trial point likely to be the last (the last iteration's, or a step predicting a merit decrease
  below ``tolerance``) may be evaluated by the caller's ``final``, which fuses the value evaluation
  with the caller's dense check of it (:func:`planners.replanning.check.evaluate_and_check`): one
  inverse-dynamics call instead of two.

Its counts (derivative and value evaluations) feed the replanner's deterministic latency.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import quadprog


@dataclass
class WarmOutcome:
    """What :func:`solve_warm` did: x, J, violation, iterations and evaluation counts, and why it stopped."""

    x: np.ndarray
    J: float
    violation: float
    iterations: int
    gradient_evaluations: int
    value_evaluations: int
    message: str
    check: object = None


class QpFailure(RuntimeError):
    """quadprog could not solve a step QP (inconsistent or degenerate rows, a Hessian not positive definite)."""


def _l1(c) -> float:
    return float(np.maximum(0.0, -np.asarray(c)).sum())


def qp_step(ev, radius: float, penalty: float):
    """The elastic trust-region QP at ``ev`` (module docstring); returns (d, predicted decrease, multipliers).

    Raises :class:`QpFailure` when quadprog cannot solve it.

    min 1/2 d^T H d + g^T d + rho 1^T s  s.t.  c_k + A_k d + s_k >= 0 (s only on rows violated at x),
    s >= 0, |d|_inf <= radius; the multipliers (>= 0, one per constraint, in the units of c) bound rho.
    """
    g, hess, c, a = ev.gradient, ev.hessian, ev.constraints, ev.jacobian
    n = g.size
    keep = np.flatnonzero(c - np.abs(a).sum(axis=1) * radius <= 0.0)
    norms = np.maximum(np.abs(a[keep]).max(axis=1), 1.0) if keep.size else np.ones(0)
    c_k, a_k = c[keep] / norms, a[keep] / norms[:, None]
    soft = np.flatnonzero(c_k < 0.0)
    p = soft.size
    scale = 1.0 / max(1.0, np.abs(hess).max())
    size = n + p
    h = np.zeros((size, size))
    h[:n, :n] = hess * scale
    h[np.diag_indices(size)] += 1e-9 * max(np.trace(h[:n, :n]) / n, 1e-6)  # quadprog needs H > 0
    lin = np.concatenate([g * scale, penalty * norms[soft] * scale])
    slack = np.zeros((keep.size, p))
    slack[soft, np.arange(p)] = 1.0
    eye = np.eye(size)
    rows = np.vstack([np.hstack([a_k, slack]), eye[:n], -eye[:n], eye[n:]])  # C^T z >= b
    bound = np.concatenate([-c_k, np.full(n, -radius), np.full(n, -radius), np.zeros(p)])
    try:
        z, _, _, _, lagrange, _ = quadprog.solve_qp(h, -lin, rows.T, bound, 0)
    except ValueError as error:  # quadprog: "constraints are inconsistent" (degenerate rows), or H not > 0
        raise QpFailure(str(error)) from None
    d = np.clip(z[:n], -radius, radius)
    model = g @ d + 0.5 * d @ hess @ d
    predicted = penalty * (_l1(c) - _l1(c + a @ d)) - model
    multipliers = np.zeros(c.size)
    multipliers[keep] = lagrange[: keep.size] / (norms * scale)
    return d, predicted, multipliers


def solve_warm(problem, x0, max_iterations: int = 4, tolerance: float = 1e-3, radius: float = 0.3,
               penalty: float = 10.0, feasibility: float = 1e-7, afford=None, final=None) -> WarmOutcome:
    """Minimise ``problem``'s J subject to its constraints >= 0 from the warm start x0 (module docstring).

    Args:
        problem: the NLP (:class:`planners.problem.motion.MotionProblem` or a subclass).
        x0: the warm start (n_x,).
        max_iterations: iteration cap.
        tolerance: stop when an accepted feasible step improves the merit by less than this (relative).
        radius: initial trust region (infinity norm, in x's scaled units).
        penalty: initial l1 penalty rho (raised above twice the largest multiplier).
        feasibility: largest constraint violation counted as feasible (scaled units).
        afford: None (every iteration up to the cap), or ``afford(gradient_evaluations, value_evaluations)``,
            true when a solve of that many evaluations is within the caller's budget: an iteration after the
            first starts only if the counts after it (one more of each) are affordable.
        final: None, or ``final(x) -> (evaluation at x (values), check)``: the caller's value evaluation
            fused with its check of x, used for a trial point likely to be the last (module docstring). The
            outcome's ``check`` is that check when its point is the result (else None).
    """
    x = np.asarray(x0, dtype=float).copy()
    checked = check = None
    grads = values = 0
    message = "iteration limit reached"
    it = 0
    current = None
    for it in range(1, max_iterations + 1):
        if it > 1 and afford is not None and not afford(grads + 1, values + 1):
            message = "budget reached: another iteration would pass the deadline"
            it -= 1
            break
        ev = problem.evaluate(x, True)
        grads += 1
        current = ev
        try:
            d, predicted, lam = qp_step(ev, radius, penalty)
            top = float(lam.max()) if lam.size else 0.0
            if 2.0 * top > penalty and penalty < 1e6:
                penalty = min(2.0 * top, 1e6)
                d, predicted, lam = qp_step(ev, radius, penalty)
        except QpFailure as error:  # keep the last accepted point; the caller's dense check judges it
            message = f"QP failed: {error}"
            break
        merit = ev.J + penalty * _l1(ev.constraints)
        if predicted <= 1e-12 * max(1.0, abs(ev.J)):
            message = "converged: no decrease predicted"
            break
        last = (
            it == max_iterations
            or (afford is not None and not afford(grads + 1, values + 2))
            or predicted < tolerance * max(1.0, abs(ev.J))
        )
        if final is not None and last:
            trial, check = final(x + d)
            checked = x + d
        else:
            trial = problem.evaluate(x + d)
        values += 1
        actual = merit - (trial.J + penalty * _l1(trial.constraints))
        ratio = actual / predicted
        if ratio > 0.1:
            x, current = x + d, trial
            if ratio > 0.75 and np.abs(d).max() > 0.9 * radius:
                radius *= 2.0
            if actual < tolerance * max(1.0, abs(trial.J)) and trial.violation <= feasibility:
                message = "converged: merit decrease below tolerance"
                break
        else:
            radius *= 0.25
    if current is None:  # no iteration asked for
        current = problem.evaluate(x)
        values += 1
    done = check if checked is not None and np.array_equal(checked, x) else None
    return WarmOutcome(x, float(current.J), float(current.violation), it, grads, values, message, done)


__all__ = ["QpFailure", "WarmOutcome", "qp_step", "solve_warm"]
