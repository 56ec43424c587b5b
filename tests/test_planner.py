"""The planning NLP and the planner (seed ch. 3): exact derivatives, optimised motions, the constraint report.

Tolerances, and why:

* derivatives: central differences with h = 1e-6 in the scaled decision vector x (every entry moves
  the motion by O(1)); truncation error ~ h^2 |f'''| ~ 1e-12, rounding ~ 1e-16 |f| / h ~ 1e-10 for the
  O(1) objective and scaled constraint rows. Hence relative 1e-6 (and 1e-8 absolute on rows).
* the dense-grid report is checked against an independent 2 kHz resampling: a smooth margin sampled
  every dt has its sampled minimum above the true one by at most sup|g''| (dt / 2)^2 / 2.
"""

from __future__ import annotations

import numpy as np
import pytest

from fpr.model.errors import MissionError, UnknownMethodError
from fpr.model.inverse_dynamics import inverse_dynamics
from fpr.robots.fpr import fpr_workspace_margins
from fpr.robots.prototype import prototype_workspace_margins
from planners.methods import METHODS, method_for
from planners.methods import crossing as crossing_method
from planners.missions.mission import load_mission, mission_from_dict
from planners.optimize import evaluate_motion, plan
from planners.options import PlanOptions
from planners.problem.motion import POWER_SMOOTHING, MotionProblem, constraint_kind, constraint_rows
from planners.trajectory.polynomial import PiecewisePolynomial, stop_points, with_via_points

P0, Q0 = 5 * np.pi / 4, np.pi / 2  # phi, q21 of s0: both drones above the end-effector
S0 = np.array([0.0, 0.0, P0, Q0])
XI_HOME = np.array([0.3, 1.2])  # a prototype pose well inside every margin
GEOMETRIC_KINDS = {"fpr": ("ground", "phi", "q21"), "prototype": ("ground", "fixed_point", "q1", "q2")}
REPORT_RATE = 500.0  # plan()'s dense_rate


# ---------------------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def square():
    return load_mission("square")


@pytest.fixture(scope="module")
def fpr_robot(square):
    return square.load_robot()


@pytest.fixture(scope="module")
def tour():
    return load_mission("prototype-tour")


@pytest.fixture(scope="module")
def proto_robot(tour):
    return tour.load_robot()


@pytest.fixture(scope="module")
def square_plans(square, fpr_robot):
    """plan(square, method) for the three methods, and the progress calls each made."""
    plans, calls = {}, {}
    for method in ("none", "two-step", "one-step"):
        log = calls.setdefault(method, [])
        plans[method] = plan(square, method, robot=fpr_robot, progress=lambda *a, log=log: log.append(a))
    return plans, calls


def _normalisation(robot, mission, alpha):
    """(J_e0, J_phi0) of the stop-at-every-way-point motion on the optimisation grid, as plan() does."""
    stop = stop_points(mission.positions(robot))
    none = np.zeros(stop.shape, dtype=bool)
    return MotionProblem(robot, stop, mission.times, none, alpha, (1.0, 1.0)).objective_terms(stop)


def fpr_step1(robot, mission, alpha=0.5):
    """plan()'s step-1 NLP of a mission: free = derivatives 1..4 at the interior way points."""
    stop = stop_points(mission.positions(robot))
    free = np.zeros(stop.shape, dtype=bool)
    free[1:-1, 1:] = True
    return MotionProblem(robot, stop, mission.times, free, alpha, _normalisation(robot, mission, alpha))


def proto_travel(robot, mission, alpha=0.5, travel=2):
    """plan()'s step-2 NLP of one travel: free = every entry of its via points (with_via_points)."""
    stop = PiecewisePolynomial(stop_points(mission.positions(robot)), mission.times)
    points, durations, is_way = with_via_points(stop, mission.times, mission.via_points)
    a, b = np.flatnonzero(is_way)[[travel, travel + 1]]
    free = np.zeros(points[a:b + 1].shape, dtype=bool)
    free[1:-1] = True
    normalisation = _normalisation(robot, mission, alpha)
    return MotionProblem(robot, points[a:b + 1], durations[a:b], free, alpha, normalisation)


@pytest.fixture(scope="module", params=["fpr-square-step1", "prototype-tour-travel3"])
def nlp(request, square, fpr_robot, tour, proto_robot):
    """(problem builder(alpha), random x near the stop-at-way-points x)."""
    if request.param.startswith("fpr"):
        build = lambda alpha: fpr_step1(fpr_robot, square, alpha)  # noqa: E731
    else:
        build = lambda alpha: proto_travel(proto_robot, tour, alpha)  # noqa: E731
    problem = build(0.5)
    x = problem.x_of(problem.points) + 0.1 * np.random.default_rng(3).normal(size=problem.n_x)
    return build, x


def window_argmins(problem, x):
    """Sample index of the minimum of every windowed constraint (order of Evaluation.constraints)."""
    motion = problem.motion(problem.points_of(x))
    rows, _, _ = constraint_rows(problem.robot, motion, inverse_dynamics(problem.robot, motion), scaled=True)
    return np.concatenate([a + np.argmin(rows[a:b], axis=0) for a, b in problem.windows])


# ---------------------------------------------------------------------------------------- 1. derivatives
def test_gradient_and_jacobian_match_central_differences(nlp):
    """dJ/dx and d(constraints)/dx (complex step through the inverse dynamics, chain rule through the
    Hermite basis) equal central differences. The constraints are windowed minima, smooth only while the
    minimising sample stays the same: rows whose argmin moves between x - h and x + h are left out.
    """
    build, x = nlp
    problem = build(0.5)
    ev = problem.evaluate(x, derivatives=True)
    h = 1e-6
    grad = np.empty(problem.n_x)
    jac = np.empty_like(ev.jacobian)
    smooth = np.ones(ev.constraints.size, dtype=bool)
    base = window_argmins(problem, x)
    for k in range(problem.n_x):
        e = np.zeros(problem.n_x)
        e[k] = h
        plus, minus = problem.evaluate(x + e), problem.evaluate(x - e)
        grad[k] = (plus.J - minus.J) / (2 * h)
        jac[:, k] = (plus.constraints - minus.constraints) / (2 * h)
        smooth &= (window_argmins(problem, x + e) == base) & (window_argmins(problem, x - e) == base)
    np.testing.assert_allclose(ev.gradient, grad, rtol=0, atol=1e-6 * np.abs(ev.gradient).max())
    assert smooth.mean() > 0.9  # the comparison is not vacuous
    assert np.abs(ev.jacobian[smooth]).max() > 0.01
    np.testing.assert_allclose(ev.jacobian[smooth], jac[smooth], rtol=1e-6, atol=1e-8)


def test_evaluation_without_derivatives_is_the_same(nlp):
    """evaluate(x) and evaluate(x, True) agree on J, the terms and the constraints (two code paths)."""
    build, x = nlp
    exact = build(0.5).evaluate(x, derivatives=True)
    plain = build(0.5).evaluate(x)
    assert plain.J == pytest.approx(exact.J, rel=1e-13)
    np.testing.assert_allclose(plain.terms, exact.terms, rtol=1e-13)
    np.testing.assert_allclose(plain.constraints, exact.constraints, rtol=1e-12, atol=1e-14)


# ---------------------------------------------------------------------------------------- 2. Hessian
def _power_and_rates(problem, x):
    inputs = inverse_dynamics(problem.robot, problem.motion(problem.points_of(x)))
    return np.sum(inputs.thrust_vector * inputs.joint_velocity, axis=-1), inputs.roll_rate  # (N, n_d) each


@pytest.mark.parametrize("alpha", [0.0, 0.5])
def test_hessian_is_the_gauss_newton_matrix(nlp, alpha):
    """H is symmetric PSD and equals, built from finite-difference Jacobians of the per-sample residuals,
    sum_i w_i [2 a_phi J_r^T J_r + a_e J_P^T J_P / |P|_eps], a_phi = (1 - alpha) / J_phi0, a_e = alpha / J_e0.

    For alpha = 0, J = a_phi sum w r^2 is a sum of squares and this is its Gauss-Newton matrix. It is
    not the full Hessian (which adds 2 a_phi sum w r d^2 r): the roll rates r are not small along a
    motion, so comparing with d^2 J would need a tolerance that proves nothing; the exact identity is
    the honest check. For alpha > 0 the J_e part is the reweighted least-squares curvature that the
    docstring promises (the curvature of the quadratic majorising |P|_eps at P).
    """
    build, x = nlp
    problem = build(alpha)
    hess = np.asarray(problem.evaluate(x, derivatives=True).hessian)  # the banded matrix as an array
    scale = np.abs(hess).max()
    np.testing.assert_allclose(hess, hess.T, rtol=0, atol=1e-13 * scale)
    assert np.linalg.eigvalsh(hess).min() >= -1e-10 * scale
    h = 1e-6
    power, rate = _power_and_rates(problem, x)
    jp = np.empty(power.shape + (problem.n_x,))
    jr = np.empty_like(jp)
    for k in range(problem.n_x):
        e = np.zeros(problem.n_x)
        e[k] = h
        (pp, rp), (pm, rm) = _power_and_rates(problem, x + e), _power_and_rates(problem, x - e)
        jp[..., k], jr[..., k] = (pp - pm) / (2 * h), (rp - rm) / (2 * h)
    a_e, a_phi = alpha / problem.normalisation[0], (1 - alpha) / problem.normalisation[1]
    w = problem.weights[:, None]
    curv_p = w * a_e / np.sqrt(power**2 + POWER_SMOOTHING**2)
    expected = np.einsum("id,idu,idv->uv", 2 * a_phi * w * np.ones_like(rate), jr, jr) \
        + np.einsum("id,idu,idv->uv", curv_p, jp, jp)
    np.testing.assert_allclose(hess, expected, rtol=0, atol=1e-6 * scale)


# ---------------------------------------------------------------------------------------- 3. optimised square
def test_stop_at_way_points_has_J_one(square_plans):
    """J of the reference is 1 by definition (it normalises J_e and J_phi, seed 3.26)."""
    plans, _ = square_plans
    assert plans["none"].J == pytest.approx(1.0, abs=1e-12)
    assert plans["none"].stages == []


@pytest.mark.parametrize("method", ["two-step", "one-step"])
def test_optimised_square_is_feasible_and_beats_stopping(square_plans, method):
    """The optimised square holds every constraint on the dense grid, every NLP solve succeeds, and it
    costs less than stopping at every way point (J < 1).
    """
    plans, _ = square_plans
    result = plans[method]
    assert result.feasible and result.report.violations == []
    assert result.stages and all(stage.success for stage in result.stages)
    assert result.J < 1.0
    report, reference = result.report, result.reference
    expected = result.alpha * report.J_e / reference.J_e + (1 - result.alpha) * report.J_phi / reference.J_phi
    assert result.J == pytest.approx(expected, rel=1e-14)


@pytest.mark.parametrize("method", ["none", "two-step", "one-step"])
def test_way_points_kept_and_rest_at_both_ends(square_plans, square, fpr_robot, method):
    """The motion passes exactly through the mission's way points and starts and ends at rest."""
    plans, _ = square_plans
    result = plans[method]
    points = result.trajectory.points
    assert result.is_way.sum() == square.n_way_points and result.is_way[0] and result.is_way[-1]
    np.testing.assert_allclose(points[result.is_way][:, 0], square.positions(fpr_robot), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(points[0, 1:], 0.0)
    np.testing.assert_array_equal(points[-1, 1:], 0.0)


@pytest.mark.parametrize("method", ["two-step", "one-step"])
def test_c4_continuity_at_every_knot(square_plans, method):
    """s, s', s'', s''', s'''' are continuous at every knot (9th-degree Hermite segments), and both
    one-sided limits at a knot are the stored point.
    """
    plans, _ = square_plans
    trajectory = plans[method].trajectory
    order_scale = np.abs(plans[method].report.motion).max(axis=(1, 2))  # size of each derivative order
    segments = trajectory.segments
    for i, knot in enumerate(trajectory.knots[1:-1], start=1):
        left = trajectory.evaluate(knot - 1e-9, order=4)[:, 0]
        right = trajectory.evaluate(knot + 1e-9, order=4)[:, 0]
        from_left = segments[i - 1].evaluate(segments[i - 1].duration, order=4)[:, 0]
        from_right = segments[i].evaluate(0.0, order=4)[:, 0]
        for r, scale in enumerate(order_scale):
            np.testing.assert_allclose(left[r], right[r], rtol=0, atol=1e-6 * scale)
            np.testing.assert_allclose(from_left[r], trajectory.points[i, r], rtol=0, atol=1e-12 * scale)
            np.testing.assert_allclose(from_right[r], trajectory.points[i, r], rtol=0, atol=1e-12 * scale)


def independent_margins(robot, trajectory, t):
    """name -> (N, k) margins computed here from the constraints' definitions (DESIGN.md, seed 3.27-3.48)."""
    motion = trajectory.evaluate(t, order=4)
    inputs = inverse_dynamics(robot, motion)
    geometric = fpr_workspace_margins if robot.name == "fpr" else prototype_workspace_margins
    cols = {name: v[:, None] for name, v in geometric(motion[0], robot.link_length, robot.margins).items()}
    roll_limit = np.pi / 2 - robot.margins.angle
    speed_limit = robot.rotor_constants.max_speed - robot.margins.rotor_speed
    for i in range(robot.n_drones):
        cols[f"roll_{i + 1}"] = roll_limit - np.abs(inputs.roll[:, i:i + 1])
        cols[f"rotor_speed_low_{i + 1}"] = inputs.rotor_speed[:, i]
        cols[f"rotor_speed_high_{i + 1}"] = speed_limit - inputs.rotor_speed[:, i]
    if robot.name == "fpr":  # the drone joints' height, from the inverse dynamics this time
        for i in range(2):
            height = inputs.joint_position[:, i, 1] + robot.link_length - robot.margins.ground
            np.testing.assert_allclose(cols[f"ground_{i + 1}"][:, 0], height, atol=1e-12)
    return cols


@pytest.mark.parametrize("method", ["none", "two-step", "one-step"])
def test_report_is_not_lying(square_plans, method):
    """Every reported worst margin is the minimum of an independent 2 kHz resampling (which contains
    the report's 500 Hz grid and the knots, so it is never above the report), and the report is above it
    by no more than sampling every dt = 1/500 s allows: at an interior minimum t* of a margin g (g' = 0;
    g is smooth inside a segment and the knots are samples) the nearest sample is within dt / 2, so
    g(sample) - g(t*) <= sup|g''| (dt/2)^2 / 2, sup|g''| estimated from the 2 kHz samples with a 25 %
    allowance. (A report on a grid 2x coarser already breaks this bound on the optimised squares.)
    The reported time and detail (which rotor) reproduce the margin.
    """
    plans, _ = square_plans
    result = plans[method]
    trajectory, robot = result.trajectory, result.robot
    total = trajectory.total_duration
    t = np.unique(np.concatenate([np.arange(int(total * 2000) + 1) / 2000, trajectory.knots]))
    t = t[t <= total]
    cols = independent_margins(robot, trajectory, t)
    assert set(cols) == set(result.report.constraints)
    for name, report in result.report.constraints.items():
        g = cols[name]
        assert report.kind == constraint_kind(name)
        fine = g.min()
        curvature = np.abs(np.gradient(np.gradient(g, t, axis=0), t, axis=0)).max()
        tiny = 1e-9 * max(1.0, np.abs(g).max())
        assert fine <= report.margin + tiny
        assert report.margin - fine <= 1.25 * curvature * (0.5 / REPORT_RATE) ** 2 / 2 + tiny, name
        at = independent_margins(robot, trajectory, np.array([report.time]))[name][0]
        assert at.min() == pytest.approx(report.margin, abs=tiny)
        if report.detail.startswith("rotor"):
            assert report.detail == f"rotor {np.argmin(at) + 1}"


# ---------------------------------------------------------------------------------- 4. two-step monotone
def test_two_step_is_never_worse_than_its_step_one(square_plans, square, fpr_robot):
    """Step 2 starts from the step-1 motion (via points read off it), so it can only lower J: the
    two-step result is no worse than the same plan without via points (= step 1 alone).
    """
    plans, _ = square_plans
    step_one = plan(square.replace(via_points=0), "two-step", robot=fpr_robot)
    assert [s.name for s in step_one.stages] == ["step 1"]
    assert plans["two-step"].J <= step_one.J + 1e-9


# ---------------------------------------------------------------------------------------- 5. violations named
def _fpr_mission(way_points, times):
    return mission_from_dict({"robot": "fpr", "way_points": way_points, "times": times})


DROP = [[0, 1, P0, Q0], [0, 0, P0, Q0]]  # the end-effector goes 1 m straight down
SIDEWAYS = [[0, 0, P0, Q0], [1.5, 0, P0, Q0]]
DIP = [[0, 0, 4.7, 2.25], [0, 0, 5.9, 2.85]]  # legal ends; phi + q21 sweeps through 5 pi/2
HIGH = {"rotor_speed_high_1", "rotor_speed_high_2"}
DYNAMIC_CASES = {
    # id: (mission builder (square, tour), constraint names that must be violated, exactly those?)
    # 1 m sides in 0.6 s: the rotors cannot give the accelerations.
    "fpr-square-0.6s": (lambda sq, tour: sq.replace(times=[0.6] * 4), HIGH, False),
    # 1 m drop in 1 s: braking at the bottom needs more than w_max - m_gr, nothing else fails.
    "fpr-drop-1s": (lambda sq, tour: _fpr_mission(DROP, [1.0]), HIGH, True),
    # 1 m drop in 0.8 s: it starts falling faster than g, so the thrust must point down: the drones roll over.
    "fpr-drop-0.8s": (lambda sq, tour: _fpr_mission(DROP, [0.8]), {"roll_1", "roll_2"}, False),
    # 1.5 m sideways in 1 s: the quick roll needs more differential thrust than the low rotors can shed.
    "fpr-sideways-1s": (lambda sq, tour: _fpr_mission(SIDEWAYS, [1.0]),
                        {"rotor_speed_low_1", "rotor_speed_low_2"}, False),
    # drone 2 swings under the end-effector into the ground margin between two legal way points.
    "fpr-ground-dip": (lambda sq, tour: _fpr_mission(DIP, [4.0]), {"ground_2"}, True),
    "prototype-tour-x0.2": (lambda sq, tour: tour.replace(times=list(0.2 * tour.times)),
                            {"rotor_speed_low_1"}, False),
    "prototype-tour-x0.1": (lambda sq, tour: tour.replace(times=list(0.1 * tour.times)),
                            {"rotor_speed_low_1", "rotor_speed_high_1"}, False),
}


@pytest.mark.parametrize("case", DYNAMIC_CASES)
def test_violated_constraints_are_named(case, square, tour):
    """Stopping at legal way points too fast (or along a path that dips) fails, and the report names the
    constraint; the geometric constraints of a stop motion whose path stays legal are reported satisfied.
    """
    build, expected, exact = DYNAMIC_CASES[case]
    mission = build(square, tour)
    result = plan(mission, "none")
    violated = {c.name for c in result.report.violations}
    assert not result.feasible
    assert expected <= violated
    if exact:
        assert violated == expected
    if case != "fpr-ground-dip":
        kinds = GEOMETRIC_KINDS[mission.robot]
        geometric = [c for c in result.report.constraints.values() if c.kind in kinds]
        assert geometric and all(c.satisfied for c in geometric)
    for c in result.report.violations:
        assert c.margin < 0 and 0.0 <= c.time <= mission.duration


GEOMETRIC_CASES = {
    # id: (robot, bad pose (FPR s or prototype xi), names that must be violated, exact set?)
    "fpr-phi_low": ("fpr", [0, 0, np.pi + 0.1, Q0], {"phi_low"}, True),
    "fpr-phi_high": ("fpr", [0, 0, 2 * np.pi - 0.1, Q0], {"phi_high"}, False),  # drone 2 also low
    "fpr-q21_low": ("fpr", [0, 0, P0 + 0.5, 0.1], {"q21_low"}, True),
    # near the Type-2 singularity the forces diverge: rotors and roll fail too
    "fpr-q21_high": ("fpr", [0, 0, P0 - 0.3, np.pi - 0.1], {"q21_high"}, False),
    "fpr-ground_1": ("fpr", [0, -0.9, np.pi + 0.3, 2.0], {"ground_1"}, True),
    "prototype-q1_high": ("prototype", [1.38, 0.22], {"q1_high"}, True),
    # q1 < -(pi/2 - m_ga) puts the elbow below z = -L + m_gd
    "prototype-q1_low": ("prototype", [-1.40, 2.2], {"q1_low", "ground_2"}, True),
    "prototype-q2_low": ("prototype", [0.3, 0.1], {"q2_low"}, False),  # near-singular: rotors fail too
    "prototype-q2_high": ("prototype", [-1.0, 2.96], {"q2_high"}, True),
    "prototype-fixed_point_3": ("prototype", [0.8, 2.5], {"fixed_point_3"}, True),
    # y2 = L cos q1 < m_gd needs |q1| > acos(m_gd / L) > pi/2 - m_ga, and then y3 < y2
    "prototype-fixed_point_2": ("prototype", [1.45, 0.2], {"fixed_point_2", "fixed_point_3", "q1_high"},
                                True),
    "prototype-ground_2": ("prototype", [-1.2, 2.2], {"ground_2"}, True),
    "prototype-ground_3": ("prototype", [-1.0, 0.3], {"ground_3"}, True),
}


@pytest.mark.parametrize("case", GEOMETRIC_CASES)
def test_geometric_constraints_fail_and_are_named(case, fpr_robot, proto_robot):
    """A motion from a legal pose through a pose outside one bound and back (stop points, 6 s each way):
    the kinematics say which margin the bad pose breaks; evaluate_motion names it, at the bad pose or
    worse, and the optimiser's scaled rows (constraint_rows(scaled=True)) agree in sign with the
    natural-unit rows everywhere (so the NLP sees the same violation).
    """
    robot_name, bad, expected, exact = GEOMETRIC_CASES[case]
    robot = fpr_robot if robot_name == "fpr" else proto_robot
    home = S0 if robot_name == "fpr" else XI_HOME
    geometric = fpr_workspace_margins if robot_name == "fpr" else prototype_workspace_margins
    at_home = geometric(np.array(home, dtype=float), robot.link_length, robot.margins)
    at_bad = geometric(np.array(bad, dtype=float), robot.link_length, robot.margins)
    assert min(at_home.values()) > 0
    broken = {n for n, v in at_bad.items() if v < 0}
    assert expected & set(at_bad) <= broken
    if exact:
        assert broken == expected & set(at_bad)
    trajectory = PiecewisePolynomial(stop_points([home, bad, home]), [6.0, 6.0])
    report = evaluate_motion(robot, trajectory)
    violated = {c.name for c in report.violations}
    assert expected <= violated
    if exact:
        assert violated == expected
    for name in expected & set(at_bad):
        assert report.constraints[name].margin <= at_bad[name] + 1e-12
    motion = trajectory.evaluate(np.linspace(0.0, 12.0, 601), order=4)
    inputs = inverse_dynamics(robot, motion)
    natural, names, _ = constraint_rows(robot, motion, inputs, scaled=False)
    scaled, names_scaled, _ = constraint_rows(robot, motion, inputs, scaled=True)
    assert names == names_scaled
    clear = np.abs(natural) > 1e-9
    np.testing.assert_array_equal(np.sign(natural[clear]), np.sign(scaled[clear]))


def test_arm_up_prototype_mission_is_not_reported_singular(proto_robot):
    """Arm up (q2 < 0) is a legal assembly mode (Mission.positions mirrors the q2 bounds for it); a slow
    motion between two arm-up poses far from q2 = 0 must be feasible.
    """
    mission = mission_from_dict({"robot": "prototype", "arm": "up", "way_points": [[1.2, 0.3], [1.0, 0.6]],
                                 "times": [3.0]})
    xi = mission.positions(proto_robot)
    assert np.all(xi[:, 1] < -0.5)  # well inside -pi + m_ga <= q2 <= -m_ga
    result = plan(mission, "none", robot=proto_robot)
    assert [c.name for c in result.report.violations] == []
    # the mirrored bounds -pi + m_ga <= q2 <= -m_ga; the straight path in xi is extreme at its ends
    m_ga = proto_robot.margins.angle
    assert result.report.constraints["q2_low"].margin == pytest.approx(np.min(-xi[:, 1]) - m_ga, abs=1e-12)
    q2_high = result.report.constraints["q2_high"].margin
    assert q2_high == pytest.approx(np.pi - m_ga + np.min(xi[:, 1]), abs=1e-12)


# ---------------------------------------------------------------------------------------- 6. progress
@pytest.mark.parametrize("method", ["two-step", "one-step"])
def test_progress_is_called_for_every_stage(square_plans, method):
    """progress(stage name, iteration, J, violation) is called at least once per stage that has
    variables, with iterations counting 1, 2, ... within a stage and J, violation finite, violation >= 0.
    """
    plans, calls = square_plans
    log = calls[method]
    for stage in plans[method].stages:
        if stage.n_variables == 0:
            continue
        mine = [c for c in log if c[0] == stage.name]
        assert mine, stage.name
        assert [c[1] for c in mine] == list(range(1, len(mine) + 1))
        assert all(np.isfinite(c[2]) and np.isfinite(c[3]) and c[3] >= 0 for c in mine)
    assert {c[0] for c in log} <= {s.name for s in plans[method].stages}
    assert calls["none"] == []


# ---------------------------------------------------------------------------------- 7. infeasible requests
@pytest.mark.parametrize("mission_case, options", [
    ("square-0.5s", {"solver": "slsqp", "max_iterations": 5}),
    ("ground-dip-no-via", {}),  # nothing to optimise: the stop motion is the answer, and it is infeasible
])
def test_infeasible_request_returns_a_report(square, mission_case, options):
    """An infeasible request ends with feasible False and the violations listed, not with an exception."""
    if mission_case == "square-0.5s":
        mission, expected_kind = square.replace(times=[0.5] * 4), "rotor_speed_high"
    else:
        mission = _fpr_mission(DIP, [4.0]).replace(via_points=0)
        expected_kind = "ground"
    result = plan(mission, "two-step", **options)
    assert not result.feasible
    assert result.report.violations
    assert expected_kind in {c.kind for c in result.report.violations}
    assert result.summary()["violated"] == [c.name for c in result.report.violations]


def test_infeasible_request_with_the_default_solver_ends(square, fpr_robot):
    """The infeasible square (0.5 s travels: constraint Jacobian entries ~3.6e7 where the thrust nearly
    vanishes) with the default SQP settings ends with a report: the step QPs have bounded work and a
    stage stops once its violation stalls (this once ran for more than 15 min).
    """
    result = plan(square.replace(times=[0.5] * 4), "two-step", robot=fpr_robot)
    assert not result.feasible and result.report.violations
    assert all(stage.iterations < 60 for stage in result.stages)
    assert any("infeasible" in stage.message for stage in result.stages)


# ---------------------------------------------------------------------------------------- 8. the registry
def test_plan_looks_the_method_up_in_the_registry(square, fpr_robot, monkeypatch):
    """A method is a function (mission, robot, options) -> PlanResult registered by name: one defined
    here (outside the library) is found by plan(), given the options, and timed; unknown names are
    refused before anything is planned, and the crossing method refuses a way-point mission.
    """
    with pytest.raises(UnknownMethodError, match="three-step") as error:
        plan(square, "three-step", robot=fpr_robot)
    assert error.value.known == tuple(METHODS)
    seen = []

    def stop_twice(mission, robot, options: PlanOptions):
        seen.append(options)
        return METHODS["none"](mission, robot, options)

    monkeypatch.setitem(METHODS, "stop-twice", stop_twice)
    result = plan(square, "stop-twice", robot=fpr_robot, dense_rate=100.0, max_iterations=7)
    assert seen == [PlanOptions(dense_rate=100.0, max_iterations=7)]
    assert result.method == "none" and result.J == pytest.approx(1.0) and result.wall_time > 0
    with pytest.raises(MissionError, match="cross_singularity"):
        plan(square, "crossing", robot=fpr_robot)


def test_a_crossing_mission_is_planned_by_the_crossing_methods():
    mission = load_mission("cross-singularity")
    assert method_for(mission, "two-step") is METHODS["crossing"]
    assert method_for(mission, "none") is crossing_method.first_guess
    assert method_for(load_mission("square"), "none") is METHODS["none"]
