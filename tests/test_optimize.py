"""The planner of chapter 3: exact gradients, optimised missions, constraint report."""

from __future__ import annotations

import numpy as np
import pytest

import fpr
from planners.mission import load_mission
from planners.optimize import _with_via_points, evaluate_motion, plan
from planners.polynomial import PiecewisePolynomial, stop_points
from planners.problem import MotionProblem

S0 = [0.0, 0.0, 5 * np.pi / 4, np.pi / 2]


def _problems():
    """An FPR step-1 problem (interior way-point derivatives free) and a prototype travel with via points."""
    fpr_robot = fpr.load("fpr")
    square = load_mission("square")
    stop = stop_points(square.positions(fpr_robot))
    free = np.zeros(stop.shape, dtype=bool)
    free[1:-1, 1:] = True
    a = MotionProblem(fpr_robot, stop, square.times, free, 0.5, (50.0, 0.3))
    proto = fpr.load("prototype")
    tour = load_mission("prototype-tour")
    trajectory = PiecewisePolynomial(stop_points(tour.positions(proto)[:2]), tour.times[:1])
    points, durations, is_way = _with_via_points(trajectory, tour.times[:1], [2])
    free = np.zeros(points.shape, dtype=bool)
    free[~is_way] = True
    b = MotionProblem(proto, points, durations, free, 0.3, (5.0, 0.01))
    return [a, b]


@pytest.mark.parametrize("problem", _problems(), ids=["fpr-step1", "prototype-via"])
def test_gradients_match_finite_differences(problem):
    """dJ/dx and the constraint Jacobian (complex step + chain rule) against central differences."""
    rng = np.random.default_rng(7)
    x = problem.x_of(problem.points) + 0.05 * rng.normal(size=problem.n_x)
    ev = problem.evaluate(x, derivatives=True)
    h = 1e-6
    for k in rng.choice(problem.n_x, size=min(8, problem.n_x), replace=False):
        e = np.zeros(problem.n_x)
        e[k] = h
        plus, minus = problem.evaluate(x + e), problem.evaluate(x - e)
        fd = (plus.J - minus.J) / (2 * h)
        assert ev.gradient[k] == pytest.approx(fd, rel=1e-6, abs=1e-9)
        # windowed minima are piecewise smooth: compare the rows whose minimising sample is the
        # same at x - h, x and x + h (detected as a central difference that matches a one-sided one)
        fd_c = (plus.constraints - minus.constraints) / (2 * h)
        fd_f = (plus.constraints - ev.constraints) / h
        smooth = np.abs(fd_c - fd_f) <= 1e-4 * (1 + np.abs(fd_c))
        assert smooth.mean() > 0.9
        np.testing.assert_allclose(ev.jacobian[smooth, k], fd_c[smooth], rtol=1e-5, atol=1e-7)


def test_hessian_is_symmetric_positive_semidefinite():
    problem = _problems()[0]
    hess = problem.evaluate(problem.x_of(problem.points), True).hessian
    np.testing.assert_allclose(hess, hess.T, atol=1e-12 * np.abs(hess).max())
    assert np.linalg.eigvalsh(hess).min() >= -1e-10 * np.abs(hess).max()


@pytest.fixture(scope="module")
def square_results():
    mission = load_mission("square")
    return mission, {m: plan(mission, m) for m in ("none", "two-step", "one-step")}


@pytest.mark.parametrize("method", ["two-step", "one-step"])
def test_optimised_square_is_feasible_and_beats_stopping(square_results, method):
    mission, results = square_results
    result = results[method]
    assert results["none"].J == pytest.approx(1.0, abs=1e-12)
    assert result.feasible and result.solver_success
    assert result.J < 0.6  # measured 0.51: J_phi drops by ~95 %, J_e by ~2 %
    assert result.report.J_phi < 0.1 * result.reference.J_phi
    robot = result.robot
    points = result.trajectory.points
    np.testing.assert_allclose(points[result.is_way][:, 0], mission.positions(robot), atol=1e-12)
    np.testing.assert_array_equal(points[0, 1:], 0.0)
    np.testing.assert_array_equal(points[-1, 1:], 0.0)


def test_c4_continuity_at_every_knot(square_results):
    _, results = square_results
    trajectory = results["one-step"].trajectory
    for i, knot in enumerate(trajectory.knots[1:-1], start=1):
        left = trajectory.evaluate(knot - 1e-9, order=4)[:, 0]
        right = trajectory.evaluate(knot + 1e-9, order=4)[:, 0]
        scale = 1 + np.abs(trajectory.points[i])
        np.testing.assert_allclose(left, right, atol=1e-5 * scale.max())
        np.testing.assert_allclose(trajectory.evaluate(knot, order=4)[:, 0], trajectory.points[i], atol=1e-9)


def test_report_is_the_minimum_on_a_finer_grid(square_results):
    """Every reported worst margin agrees with a 4x finer resampling to within what the grid allows."""
    _, results = square_results
    result = results["two-step"]
    fine = evaluate_motion(result.robot, result.trajectory, rate=2000.0)
    for name, report in result.report.constraints.items():
        finer = fine.constraints[name]
        assert finer.margin <= report.margin + 1e-12  # a finer grid can only find a smaller minimum
        slope = {"m": 2.0, "rad": 2.0, "rad/s": 500.0}[report.unit]  # generous bound on |d margin / dt|
        assert report.margin - finer.margin <= slope / 500.0


def test_two_step_is_never_worse_than_its_step_one():
    mission = load_mission("study")
    with_via = plan(mission, "two-step")
    without = plan(mission.replace(via_points=0), "two-step")
    assert with_via.J <= without.J + 1e-9


@pytest.mark.parametrize("times, expected", [
    ([1.0] * 4, "rotor_speed_low"),   # measured: w^2 < 0 on drone 1 near t = 1.7 s
    ([0.6] * 4, "rotor_speed_high"),
])
def test_rotor_limits_fail_and_are_named(times, expected):
    result = plan(load_mission("square").replace(times=times), "none")
    assert not result.feasible
    assert any(c.name.startswith(expected) for c in result.report.violations)
    assert all(c.kind in ("rotor_speed_low", "rotor_speed_high", "roll") for c in result.report.violations)


def test_prototype_rotor_limits_fail_and_are_named():
    tour = load_mission("prototype-tour")
    result = plan(tour.replace(times=[0.8] * len(tour.times)), "none")
    assert not result.feasible
    assert any(c.kind.startswith("rotor_speed") for c in result.report.violations)


def test_roll_limit_fails_and_is_named():
    """A 1 m sideways hop in 0.45 s needs ~10 g sideways: the thrust tilts past pi/2 - m_ga."""
    robot = fpr.load("fpr")
    trajectory = PiecewisePolynomial(stop_points([S0, [1.0, 0.0, S0[2], S0[3]]]), [0.45])
    report = evaluate_motion(robot, trajectory)
    assert {"roll_1", "roll_2"} & {c.name for c in report.violations}


GEOMETRIC = [
    ("fpr", [0.0, -1.5, S0[2], S0[3]], {"ground_1", "ground_2"}),
    ("fpr", [0.0, 0.0, np.pi + 0.05, S0[3]], {"phi_low"}),
    ("fpr", [0.0, 0.0, S0[2], 0.05], {"q21_low"}),
    ("prototype", [-1.2, 2.0], {"ground_2"}),
    ("prototype", [0.3, 2.5], {"fixed_point_3"}),
    ("prototype", [1.45, 0.6], {"q1_high"}),
    ("prototype", [0.3, 0.1], {"q2_low"}),
]


@pytest.mark.parametrize("robot_name, bad, expected", GEOMETRIC)
def test_geometric_constraints_fail_and_are_named(robot_name, bad, expected):
    """A motion through a point outside the workspace (as a via point between legal ends)."""
    robot = fpr.load(robot_name)
    good = S0 if robot_name == "fpr" else [-0.84, 1.68]
    points = stop_points([good, bad, good])
    report = evaluate_motion(robot, PiecewisePolynomial(points, [3.0, 3.0]))
    violated = {c.name for c in report.violations}
    assert expected <= violated
    worst = report.constraints[sorted(expected)[0]]
    assert worst.time == pytest.approx(3.0, abs=0.01)  # where the bad point is
