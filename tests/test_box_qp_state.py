"""The allocation's per-tick box-QP path (controllers/box_qp.py ``solve_box_qp_state``) and the
bounded allocation's result fields, against independent computations.

* Every branch of the solver (no free variable, one, two in plain Python, three or more by LAPACK) meets the
  KKT conditions and gives ProxQP's minimiser, and the state API gives the boolean API's answer.
* Along warm-started saturating allocations the result's thrusts, torques and saturation mask are the
  definitions' (S_f z, S_tau z, within 1e-6 w_max^2 of a bound), computed here from w^2 alone.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import hover_thrusts, saturating_factor

import fpr
from controllers.allocation import Allocator, selectors
from controllers.box_qp import AT_LOWER, AT_UPPER, FREE, solve_box_qp, solve_box_qp_state
from fpr.model.qp import proxsuite_module

proxsuite = proxsuite_module()


def test_every_branch_meets_the_kkt_conditions_and_is_proxqps_minimiser():
    """Random positive definite QPs of the allocation's size (n = 8) with g spread so that the minimisers have
    0 to 8 free variables; each start guess random (mostly wrong).
    """
    rng = np.random.default_rng(21)
    free_counts = set()
    for _trial in range(400):
        a = rng.normal(size=(8, 8))
        h = a @ a.T + 0.1 * np.eye(8)
        g = (0.5 + 10.0 * rng.random()) * rng.normal(size=8) - 0.5 * h.sum(axis=1) * rng.random()
        state = tuple(int(s) for s in rng.integers(0, 3, size=8))
        found = solve_box_qp_state(h, g, state, max_iterations=30)
        if found is None:
            continue  # may cycle: the allocator falls back to ProxQP then
        x, final, _ = found
        x = np.array(x)
        free_counts.add(final.count(FREE))
        grad = h @ x + g
        tol = 1e-9 * max(1.0, np.abs(g).max())
        assert x.min() >= 0.0 and x.max() <= 1.0
        at_low = np.array([s == AT_LOWER for s in final])
        at_high = np.array([s == AT_UPPER for s in final])
        np.testing.assert_array_equal(x[at_low], 0.0)
        np.testing.assert_array_equal(x[at_high], 1.0)
        assert np.all(grad[at_low] >= -tol) and np.all(grad[at_high] <= tol)
        assert np.abs(grad[~at_low & ~at_high]).max(initial=0.0) <= tol
        reference = proxsuite.proxqp.dense.solve(h, g, l_box=np.zeros(8), u_box=np.ones(8), eps_abs=1e-12,
                                                 eps_rel=0.0, verbose=False)
        np.testing.assert_allclose(x, reference.x, rtol=0, atol=1e-7)
        # the boolean API: the same answer
        lower, upper = [s == AT_LOWER for s in state], [s == AT_UPPER for s in state]
        x_b, lower_b, upper_b, _ = solve_box_qp(h, g, lower, upper, max_iterations=30)
        np.testing.assert_array_equal(x_b, x)
        assert lower_b == list(at_low) and upper_b == list(at_high)
    assert {0, 1, 2} <= free_counts and max(free_counts) >= 4  # the Python branches and LAPACK's


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_bounded_result_is_its_definition(name):
    """Three times the hover thrust, 30 warm ticks: f = S_f z, tau = S_tau z, the mask is "within 1e-6 w_max^2 of
    a bound", read-only, and z within the bounds.
    """
    robot = fpr.load(name)
    rng = np.random.default_rng(4)
    q0, hover = hover_thrusts(robot)
    allocator = Allocator(robot)
    s_f, s_tau = selectors(robot)
    w_max2 = robot.rotor_constants.max_speed**2
    seen = 0
    for _ in range(30):
        q, v = q0 + 0.02 * rng.normal(size=robot.nq), 0.02 * rng.normal(size=robot.nq)
        thrust = saturating_factor(robot, hover) * hover * (1 + 0.02 * rng.normal(size=hover.size))
        result = allocator.solve(robot.attitude_model(q, v), thrust, 0.3 * rng.normal(size=len(robot.layout.attitude)))
        z = result.speeds_squared.reshape(-1)
        assert result.iterations > 0 and z.min() >= 0.0 and z.max() <= w_max2
        np.testing.assert_allclose(result.thrust, s_f @ z, rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(result.torque.reshape(-1), s_tau @ z, rtol=1e-13, atol=1e-12)
        expected = (z <= 1e-6 * w_max2) | (z >= (1 - 1e-6) * w_max2)
        np.testing.assert_array_equal(result.saturated, expected.reshape(-1, 4))
        assert not result.saturated.flags.writeable
        seen += int(expected.any())
    assert seen == 30 and allocator.routes["active set"] == 30


def test_written_out_small_solves_are_small_solve():
    """One and two free variables, g made so that the guess is the answer (x_F inside the box, multipliers of the
    right sign): one iteration, and x_F is _small_solve's, bit for bit.
    """
    from controllers.box_qp import _small_solve
    rng = np.random.default_rng(8)
    for k in (1, 2):
        for _ in range(200):
            a = rng.normal(size=(4, 4))
            h = a @ a.T + 0.1 * np.eye(4)
            free = sorted(rng.choice(4, size=k, replace=False).tolist())
            state = tuple(FREE if i in free else int(rng.integers(1, 3)) for i in range(4))
            x_star = np.array([rng.uniform(0.2, 0.8) if s == FREE else 1.0 if s == AT_UPPER else 0.0 for s in state])
            multipliers = np.array([0.0 if s == FREE else rng.uniform(0.1, 1.0) * (1 if s == AT_LOWER else -1)
                                    for s in state])
            g = multipliers - h @ x_star
            x, final, iterations = solve_box_qp_state(h, g, state, max_iterations=1)
            assert final == state and iterations == 1
            x0 = np.array([1.0 if s == AT_UPPER else 0.0 for s in state])
            t = (h.dot(x0) + g).tolist()
            expected = _small_solve([[h[i, j] for j in free] for i in free], [-t[i] for i in free])
            assert [x[i] for i in free] == expected
            np.testing.assert_allclose(x, x_star, rtol=0, atol=1e-12)
