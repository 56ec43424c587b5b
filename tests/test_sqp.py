"""The SQP (planners.optimisation.sqp) on small NLPs whose optimum, multipliers and KKT residual are known by hand.

Every problem is min J(x) s.t. c(x) >= 0 in two variables; the expected solutions come from the KKT
conditions solved on paper (stated at each problem). Tolerances: the SQP stops at a KKT residual of
1e-7 (``stop="kkt"``; its QPs are solved to 1e-9 in scaled units, which bounds what it can certify);
at a nondegenerate KKT point the distance to the solution and to the multipliers is of the order of
the residual (times the inverse of the KKT matrix, O(1) here), hence 1e-6 on x and 1e-5 on the
multipliers. The composite problem smooths |.| as the planner does
(eps = POWER_SMOOTHING = 1e-2): its minimiser moves by about 0.1 eps off the kink (stated there).
"""

from __future__ import annotations

import numpy as np
import pytest

from fpr.model.errors import PlannerArgumentError
from planners.optimisation.sqp import SqpOptions, damped_bfgs, kkt_residual, solve_sqp
from planners.problem.motion import POWER_SMOOTHING, Evaluation

TIGHT = SqpOptions(stop="kkt", kkt_tolerance=1e-7, max_iterations=200)


class SmallNlp:
    """min J s.t. c >= 0 from callables; ``hessian`` is J's exact Hessian (the SQP's Gauss-Newton input)."""

    def __init__(self, j, grad, hess, c, jac):
        self.j, self.grad, self.hess, self.c, self.jac = j, grad, hess, c, jac
        self.n_x = 2

    def evaluate(self, x, derivatives=False):
        x = np.asarray(x, dtype=float)
        c = np.atleast_1d(self.c(x)).astype(float)
        if not derivatives:
            return Evaluation(float(self.j(x)), np.zeros(2), c)
        return Evaluation(float(self.j(x)), np.zeros(2), c, np.asarray(self.grad(x), float),
                          np.atleast_2d(self.jac(x)).astype(float), np.asarray(self.hess(x), float))


def _distance_problem(c, jac):
    """J = (x1 - 1)^2 + (x2 - 2)^2 with the given constraints."""
    return SmallNlp(lambda x: (x[0] - 1) ** 2 + (x[1] - 2) ** 2, lambda x: 2 * (x - [1.0, 2.0]),
                    lambda x: 2 * np.eye(2), c, jac)


def _check(out, x_expected, multipliers_expected, options=TIGHT):
    assert out.success, out.message
    assert out.message.startswith("converged: KKT residual")
    np.testing.assert_allclose(out.x, x_expected, atol=1e-6)
    np.testing.assert_allclose(out.multipliers, multipliers_expected, atol=1e-5)
    assert out.kkt.residual <= options.kkt_tolerance


def test_inactive_constraint_gives_the_free_minimum_and_zero_multiplier():
    # x1 + x2 <= 10 does not touch the free minimum (1, 2): lambda = 0
    problem = _distance_problem(lambda x: 10 - x[0] - x[1], lambda x: [[-1.0, -1.0]])
    out = solve_sqp(problem, [5.0, -3.0], TIGHT)
    _check(out, [1.0, 2.0], [0.0])
    assert out.kkt.active == 0


def test_active_linear_constraint_gives_the_projection_and_its_multiplier():
    # x1 + x2 <= 1: the projection of (1, 2) on the line is (0, 1); grad J = (-2, -2) = lambda (-1, -1), lambda = 2
    problem = _distance_problem(lambda x: 1 - x[0] - x[1], lambda x: [[-1.0, -1.0]])
    out = solve_sqp(problem, [3.0, 3.0], TIGHT)
    _check(out, [0.0, 1.0], [2.0])
    assert out.kkt.active == 1


@pytest.mark.parametrize("curvature", ["gauss-newton", "composite"])
def test_active_curved_constraint_with_a_linear_objective(curvature):
    # min x1 + x2 s.t. x1^2 + x2^2 <= 2: x = (-1, -1), (1, 1) = lambda (2, 2), lambda = 1/2. J has no
    # curvature: the model's comes from the trust region (Gauss-Newton) or the damped BFGS update of the
    # Lagrangian (lambda * 2 I). Along the circle J changes to second order only, so the QPs' precision
    # (1e-9 on the model) bounds what is certified: a KKT residual of 1e-5, x within 3e-5 (sqrt(1e-9)).
    problem = SmallNlp(lambda x: x.sum(), lambda x: np.ones(2), lambda x: np.zeros((2, 2)),
                       lambda x: 2 - x @ x, lambda x: [-2 * x])
    options = SqpOptions(stop="kkt", kkt_tolerance=1e-5, max_iterations=300, curvature=curvature,
                         second_order=True)
    out = solve_sqp(problem, [0.3, -0.2], options)
    assert out.success, out.message
    assert out.kkt.residual <= 1e-5
    np.testing.assert_allclose(out.x, [-1.0, -1.0], atol=3e-5)
    assert out.multipliers[0] == pytest.approx(0.5, abs=1e-5)
    if curvature == "composite":  # the BFGS model knows the constraint's curvature: fewer iterations
        gn = solve_sqp(problem, [0.3, -0.2], SqpOptions(stop="kkt", kkt_tolerance=1e-5, max_iterations=300,
                                                        second_order=True))
        assert out.iterations < gn.iterations


def test_degenerate_constraints_dependent_gradients():
    # the same bound twice (x1 <= 1 and 2 x1 <= 2): LICQ fails, the multipliers are not unique, but
    # their effect is: grad J = (-2, 0) at (1, 0) = -(lambda1 + 2 lambda2) (1, 0), lambda1 + 2 lambda2 = 2
    problem = SmallNlp(lambda x: (x[0] - 2) ** 2 + x[1] ** 2, lambda x: np.array([2 * (x[0] - 2), 2 * x[1]]),
                       lambda x: 2 * np.eye(2), lambda x: np.array([1 - x[0], 2 - 2 * x[0]]),
                       lambda x: [[-1.0, 0.0], [-2.0, 0.0]])
    out = solve_sqp(problem, [-1.0, 0.5], TIGHT)
    assert out.success and out.kkt.residual <= TIGHT.kkt_tolerance
    np.testing.assert_allclose(out.x, [1.0, 0.0], atol=1e-6)
    assert np.all(out.multipliers >= 0)
    assert out.multipliers[0] + 2 * out.multipliers[1] == pytest.approx(2.0, abs=1e-5)


def test_degenerate_weakly_active_constraint():
    # x1 <= 1 holds with equality at the free minimum (1, 0): active with a zero multiplier (no strict
    # complementarity)
    problem = SmallNlp(lambda x: (x[0] - 1) ** 2 + x[1] ** 2, lambda x: np.array([2 * (x[0] - 1), 2 * x[1]]),
                       lambda x: 2 * np.eye(2), lambda x: np.array([1 - x[0]]), lambda x: [[-1.0, 0.0]])
    out = solve_sqp(problem, [-2.0, 1.0], TIGHT)
    _check(out, [1.0, 0.0], [0.0])


def test_an_infeasible_start_is_brought_to_the_feasible_optimum():
    problem = _distance_problem(lambda x: 1 - x[0] - x[1], lambda x: [[-1.0, -1.0]])
    out = solve_sqp(problem, [10.0, 10.0], TIGHT)
    _check(out, [0.0, 1.0], [2.0])
    assert out.violation == 0.0


class PowerNlp(SmallNlp):
    """J = sum_k |P_k|_eps + 0.1 |x|^2 with P = (x1 - 1, x2 + 1/2) (the planner's smoothed |.|, the
    ``power`` fields of :class:`planners.problem.motion.Evaluation`), s.t. x1 <= 1/2.
    """

    def __init__(self):
        self.n_x = 2

    def evaluate(self, x, derivatives=False):
        x = np.asarray(x, dtype=float)
        p = x + np.array([-1.0, 0.5])
        smooth = np.sqrt(p * p + POWER_SMOOTHING**2)
        j = float((smooth - POWER_SMOOTHING).sum() + 0.1 * x @ x)
        c = np.array([0.5 - x[0]])
        if not derivatives:
            return Evaluation(j, np.zeros(2), c)
        grad = p / smooth + 0.2 * x
        hess = np.diag(1 / np.maximum(smooth, 1e-2)) + 0.2 * np.eye(2)  # the planner's majoriser
        return Evaluation(j, np.zeros(2), c, grad, np.array([[-1.0, 0.0]]), hess, power=p,
                          power_weight=np.ones(2), dense_power_jacobian=np.eye(2), rate_hessian=0.2 * np.eye(2))


def test_composite_model_of_absolute_values():
    # x1: min |x1 - 1| + 0.1 x1^2 s.t. x1 <= 1/2: active, P1 < 0 so xi1 = -1 and 0.2 x1 - 1 + lambda = 0,
    # lambda = 0.9. x2: min |x2 + 1/2| + 0.1 x2^2: the kink's subgradient 0.2 x2 = -0.1 lies in [-1, 1],
    # so x2 = -1/2 for |.| (the composite QP's model); for the smoothed |.| (the merit)
    # u / sqrt(u^2 + eps^2) = 0.1 at u = x2 + 1/2 = 0.1 eps / sqrt(0.99): both within 0.2 eps.
    options = SqpOptions(stop="kkt", kkt_tolerance=1e-8, max_iterations=100, curvature="composite")
    out = solve_sqp(PowerNlp(), [-1.0, 1.0], options)
    assert out.success, out.message
    np.testing.assert_allclose(out.x, [0.5, -0.5], atol=0.2 * POWER_SMOOTHING)
    assert out.x[0] == pytest.approx(0.5, abs=1e-7)
    assert out.multipliers[0] == pytest.approx(0.9, abs=1e-3)
    assert out.kkt.residual <= options.kkt_tolerance
    # the Gauss-Newton majoriser of |.| gets there too, in more iterations
    gn = solve_sqp(PowerNlp(), [-1.0, 1.0], SqpOptions(stop="kkt", kkt_tolerance=1e-8, max_iterations=100))
    assert out.iterations < gn.iterations


def test_kkt_residual_by_hand():
    # at x with grad J = (1, -2), c = (0.5, -0.1), rows (2, 0) and (0, 1), lambda = (0.25, 3):
    # grad J - A^T lambda = (1 - 0.5, -2 - 3) = (0.5, -5); c_hat = (0.5 / 2, -0.1 / 1), lambda_hat =
    # (0.25 * 2, 3): complementarity max(0.5 * 0.25, 3 * 0.1) = 0.3; feasibility 0.1
    kkt = kkt_residual([1.0, -2.0], [0.5, -0.1], [[2.0, 0.0], [0.0, 1.0]], [0.25, 3.0])
    assert kkt.stationarity == pytest.approx(5.0)
    assert kkt.complementarity == pytest.approx(0.3)
    assert kkt.feasibility == pytest.approx(0.1)
    assert kkt.residual == pytest.approx(5.0)
    assert kkt.active == 2


def test_damped_bfgs_keeps_the_model_positive_definite_and_meets_the_secant_condition():
    rng = np.random.default_rng(3)
    b = np.diag([1.0, 2.0, 3.0])
    s = rng.normal(size=3)
    y = 2.5 * s  # positive curvature: the plain BFGS update, B+ s = y
    np.testing.assert_allclose(damped_bfgs(b, s, y) @ s, y, rtol=1e-12)
    y = -s  # negative curvature: damped, still positive definite, and B+ s = r with s^T r = 0.2 s^T B s
    updated = damped_bfgs(b, s, y)
    assert np.linalg.eigvalsh(updated).min() > 0
    assert s @ updated @ s == pytest.approx(0.2 * s @ b @ s, rel=1e-12)


def test_unknown_settings_are_refused_with_the_choices():
    with pytest.raises(PlannerArgumentError, match="kkt, progress"):
        SqpOptions(stop="optimal")
    with pytest.raises(PlannerArgumentError, match="gauss-newton, composite"):
        SqpOptions(curvature="newton")


class CountingNlp:
    """An NLP that records every evaluation asked of it: (x, with derivatives)."""

    def __init__(self, inner):
        self.inner, self.n_x, self.calls = inner, inner.n_x, []

    def evaluate(self, x, derivatives=False):
        self.calls.append((np.array(x, dtype=float), bool(derivatives)))
        return self.inner.evaluate(x, derivatives)


@pytest.mark.parametrize("second_order", [False, True])
def test_each_point_is_evaluated_once_and_the_counts_are_the_evaluations_made(second_order):
    # the curved problem above from a wide trust region: many steps are rejected (and with second_order,
    # corrected). A trial evaluated with its derivatives (the default) serves the next iteration when
    # accepted; after a rejection the evaluation at x is reused. Either way the iterates are those of
    # value-only trials, derivatives are evaluated at most once per point, and the counts are the calls.
    problem = SmallNlp(lambda x: x.sum(), lambda x: np.ones(2), lambda x: np.zeros((2, 2)),
                       lambda x: 2 - x @ x, lambda x: [-2 * x])
    options = SqpOptions(stop="kkt", kkt_tolerance=1e-5, max_iterations=300, second_order=second_order,
                         radius=10.0)
    lean, plain = CountingNlp(problem), CountingNlp(problem)
    out = solve_sqp(lean, [0.3, -0.2], options)
    ref = solve_sqp(plain, [0.3, -0.2], SqpOptions(**{**vars(options), "trial_derivatives": False}))
    assert out.success and ref.success
    np.testing.assert_array_equal(out.x, ref.x)
    assert out.iterations == ref.iterations and out.J == ref.J
    assert ref.gradient_evaluations < ref.iterations  # steps were rejected: x was kept, its derivatives too
    for run, nlp in ((out, lean), (ref, plain)):
        with_derivatives = [x.tobytes() for x, d in nlp.calls if d]
        assert run.gradient_evaluations == len(with_derivatives)
        assert run.evaluations == len(nlp.calls) - len(with_derivatives)
        assert len(set(with_derivatives)) == len(with_derivatives)  # never twice at one point
    assert len(lean.calls) <= len(plain.calls)
