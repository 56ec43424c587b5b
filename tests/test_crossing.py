"""Crossing the prototype's Type-2 singularity (seed ch. 4): inverse dynamics through q2 = 0, the
crossing criterion, the crossing NLP, the seed's approaches, the mission, and the closed loop.
"""

import numpy as np
import pytest

import fpr
import fpr.model.inverse_dynamics as idyn
from fpr.model import jets
from fpr.model.errors import MissionError
from fpr.model.jets import Jet
from fpr.robots import prototype_singularity as singularity
from fpr.robots import prototype_thrust
from fpr.robots.prototype import prototype_workspace_margins
from planners.crossing import problem as crossing_problem
from planners.crossing import solve as crossing
from planners.missions.mission import load_mission, mission_from_dict, mission_from_toml
from planners.trajectory.polynomial import PiecewisePolynomial


@pytest.fixture(scope="module")
def proto():
    return fpr.load("prototype")


def _crossing_motion(robot, q1=0.2, velocity=(-1.0, -2.5), times=(1.0, 1.2), mu=-3.0, satisfied=True):
    """A start -> crossing -> end motion whose crossing acceleration does (or not) meet the criterion."""
    v = np.array(velocity)
    point = np.zeros((5, 2))
    point[0] = [q1, 0.0]
    point[1] = v
    point[2] = singularity.criterion_acceleration(robot, q1, v, mu)
    if not satisfied:
        point[2] += 2.0 * singularity.NULL_VECTOR  # criterion residual 2 n^T M n
    point[3] = [1.0, -2.0]
    point[4] = [3.0, 5.0]
    return crossing_problem.crossing_motion(singularity.SEED_START, singularity.SEED_END, point, times)


# ------------------------------------------------------------------------ inverse dynamics at q2 = 0
def test_prototype_thrust_equals_the_plain_solve_away_from_the_singularity(proto):
    rng = np.random.default_rng(3)
    m = rng.normal(size=(7, 40, 2))
    m[0, :, 1] = rng.uniform(0.3, 2.8, 40) * rng.choice([-1, 1], 40)
    s = Jet(m)
    point = proto.planar("point")
    generalized = point.inverse_dynamics_jet(s)
    plain = jets.solve(point.hinge_jacobian_jet(s.truncate(generalized.order)).mT, generalized)
    ours = idyn.thrust_vectors(proto, s)
    np.testing.assert_allclose(ours.d[:, :, 0], plain.d, rtol=1e-9, atol=1e-9 * np.abs(plain.d).max())


def test_thrust_is_continuous_through_a_crossing_that_meets_the_criterion(proto):
    motion = _crossing_motion(proto)
    ts = motion.knots[1]
    offsets = np.array([-1e-3, -1e-6, -1e-9, 0.0, 1e-9, 1e-6, 1e-3])
    inputs = idyn.inverse_dynamics(proto, motion.evaluate(ts + offsets, order=6))
    force, rate = inputs.thrust_vector[:, 0], inputs.thrust_vector_rate[:, 0]
    assert np.all(np.isfinite(force)) and np.all(np.isfinite(inputs.roll_acceleration))
    scale = np.abs(force).max()
    # F and F' are continuous (within what 1e-6 s of motion changes them)
    np.testing.assert_allclose(force[1:6], np.broadcast_to(force[3], (5, 2)), atol=1e-4 * scale)
    np.testing.assert_allclose(rate[1:6], np.broadcast_to(rate[3], (5, 2)), atol=1e-3 * np.abs(rate).max())


def _plain(proto, m):
    """inverse_dynamics with the deflation switched off (the plain quotient everywhere)."""
    old = prototype_thrust.SINGULAR_TIME
    try:
        prototype_thrust.SINGULAR_TIME = 0.0
        return idyn.inverse_dynamics(proto, m)
    finally:
        prototype_thrust.SINGULAR_TIME = old


@pytest.mark.parametrize("speed", [-2.5, -0.2])
def test_deflated_tension_agrees_with_the_plain_quotient_at_the_window_edge(proto, speed):
    """Within SINGULAR_TIME of the crossing the limit formula is used; near that edge the plain quotient
    is still accurate, so the two formulations must agree there, for a fast crossing and for the
    slowest the planner allows (|q2'| >= 0.2 rad/s).
    """
    motion = _crossing_motion(proto, velocity=(-0.4 * speed, speed))
    ts = motion.knots[1]
    t = ts + np.array([-2.9e-3, -2.5e-3, 2.5e-3, 2.9e-3])
    m = motion.evaluate(t, order=6)
    banded, plain = idyn.inverse_dynamics(proto, m), _plain(proto, m)
    assert not np.allclose(banded.thrust_vector, plain.thrust_vector, rtol=0, atol=1e-15)  # deflation ran
    np.testing.assert_allclose(banded.thrust_vector, plain.thrust_vector, atol=1e-5)
    np.testing.assert_allclose(banded.thrust_vector_rate, plain.thrust_vector_rate, atol=1e-3)
    np.testing.assert_allclose(banded.roll_acceleration, plain.roll_acceleration, atol=5e-2)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_without_the_sixth_derivative_the_limit_is_not_taken(proto):
    """With derivatives 0..4 only the plain quotient is available: 0/0 at the crossing itself."""
    motion = _crossing_motion(proto)
    t = np.array([motion.knots[1]])
    assert not np.all(np.isfinite(idyn.inverse_dynamics(proto, motion.evaluate(t, order=4)).thrust_vector))
    assert np.all(np.isfinite(idyn.inverse_dynamics(proto, motion.evaluate(t, order=6)).thrust_vector))


def test_force_diverges_like_one_over_time_when_the_criterion_fails(proto):
    """Without the criterion the tension is g / (L sin q2) with g(t_s) != 0: 10x closer, ~10x the force,
    also inside the deflation window (a missed criterion is never deflated away).
    """
    motion = _crossing_motion(proto, satisfied=False)
    good = _crossing_motion(proto)
    ts = motion.knots[1]
    for near in (2.2e-3, 2.2e-4):
        t = ts - np.array([10 * near, near])
        bad = idyn.inverse_dynamics(proto, motion.evaluate(t, order=6)).thrust_vector[:, 0]
        ok = idyn.inverse_dynamics(proto, good.evaluate(t, order=6)).thrust_vector[:, 0]
        excess = np.linalg.norm(bad - ok, axis=-1)  # the two motions differ by O(dt^2) elsewhere
        assert excess[1] / excess[0] == pytest.approx(9.1 if near > 1e-3 else 10.0, rel=0.25)


def test_a_grazing_q2_is_not_taken_for_a_crossing(proto):
    """q2 touching 1e-3 rad without crossing: no root nearby, the plain quotient (large) is kept."""
    points = np.zeros((3, 5, 2))
    points[0, 0], points[2, 0] = [-0.5, 0.6], [0.5, 0.6]
    points[1, 0] = [0.0, 1e-3]
    points[1, 2] = [0.0, 2.0]  # q2 has a minimum of 1e-3 rad at the knot
    motion = PiecewisePolynomial(points, [1.0, 1.0])
    m = motion.evaluate(np.array([1.0 - 1e-3, 1.0]), order=6)
    ours, plain = idyn.inverse_dynamics(proto, m), _plain(proto, m)
    np.testing.assert_array_equal(ours.thrust_vector, plain.thrust_vector)
    assert ours.thrust.max() > 100.0  # the singularity's force is there


# ------------------------------------------------------------------------ the criterion
def test_criterion_acceleration_meets_the_criterion(proto):
    rng = np.random.default_rng(0)
    for _ in range(5):
        q1, v, mu = rng.uniform(-1.2, 1.2), rng.normal(size=2) * 2, rng.normal() * 5
        a = singularity.criterion_acceleration(proto, q1, v, mu)
        b = proto.planar("point").inverse_dynamics(np.array([q1, 0.0]), v, a)
        assert abs(singularity.NULL_VECTOR @ b) < 1e-10
        assert abs(singularity.criterion(proto, [q1, 0.0], v, a)) < 1e-10


def test_null_vector_is_the_jacobians_at_the_singularity(proto):
    for q1 in (-1.0, 0.0, 0.7):
        jac = proto.planar("point").hinge_jacobian(np.array([q1, 0.0]))
        np.testing.assert_allclose(jac @ singularity.NULL_VECTOR, 0.0, atol=1e-14)


def test_moving_onto_the_criterion_keeps_the_drones_acceleration(proto):
    q1, v, a = 0.4, np.array([0.8, -2.0]), np.array([1.0, -3.0])
    moved, _ = singularity.nearest_criterion_acceleration(proto, q1, v, a)
    assert abs(singularity.criterion(proto, [q1, 0.0], v, moved)) < 1e-10
    jac = proto.planar("point").hinge_jacobian(np.array([q1, 0.0]))
    np.testing.assert_allclose(jac @ moved, jac @ a, atol=1e-12)


def test_across_the_straight_chain_only_gravity_acts(proto):
    """n^T c at q2 = 0 does not depend on the velocity; it is minus the derivative of the potential
    energy along n (a finite difference of the model's energy, an independent formulation).
    """
    point = proto.planar("point")
    n = singularity.NULL_VECTOR
    rng = np.random.default_rng(1)
    for q1 in (-0.9, 0.0, 1.1):
        xi = np.array([q1, 0.0])
        still = n @ point.bias(xi, np.zeros(2))
        for _ in range(3):
            assert abs(n @ point.bias(xi, rng.normal(size=2) * 3) - still) < 1e-12
        h = 1e-6
        dv = (point.energy(xi + h * n, np.zeros(2)) - point.energy(xi - h * n, np.zeros(2))) / (2 * h)
        assert still == pytest.approx(dv, rel=1e-7)


def test_chain_force_acceleration_meets_the_criterion_and_gives_the_force_across_the_link(proto):
    xi, v, f_p = np.array([1e-4, 0.0]), np.array([-3.0, 3.0]), np.array([0.0, 5.0])
    a = singularity.acceleration_from_chain_force(proto, xi, v, f_p)
    assert abs(singularity.criterion(proto, xi, v, a)) < 1e-9
    thrust = singularity.thrust_at(proto, xi, v, a, f_p)
    # J^T F = M_pt a + c_pt: the component of F across the link is what the point model needs
    point = proto.planar("point")
    b = point.inverse_dynamics(xi, v, a)
    across = np.array([-np.sin(xi.sum()), np.cos(xi.sum())])
    assert thrust @ across == pytest.approx(b[1] / proto.link_length, rel=1e-9)


# ------------------------------------------------------------------------ the NLP's derivatives
@pytest.mark.parametrize("smooth", [True, False])
def test_crossing_problem_derivatives_match_central_differences(proto, smooth):
    """Every column (crossing state, mu, 3rd/4th derivatives, via points, travel times) against central
    differences: the objective, the windowed motion rows (where the window's active node is stable) and,
    exactly, the extra rows (time bounds, crossing speed, 5th-derivative continuity).
    """
    guess = crossing.first_guess(proto, singularity.SEED_START, singularity.SEED_END, 8.0, (1, 1))
    times = crossing_problem.travel_times(guess, (1, 1))
    problem = crossing_problem.CrossingProblem(proto, guess.points, times, (1, 1),
                                               crossing_problem.GROUPS, 0.5, (30.0, 0.05), samples_per_segment=9,
                                               windows_per_segment=2, smooth_crossing=smooth)
    x = problem.x0() * (1 + 0.01 * np.random.default_rng(2).normal(size=problem.n_x))  # off the template
    ev = problem.evaluate(x, True)
    n_extra = 9 if smooth else 5
    assert problem.constraint_names[-n_extra:] == ["travel_time"] * 4 + ["crossing_speed"] + ["crossing_c5"] * (
        n_extra - 5)
    for col in range(problem.n_x):
        h = 1e-6 * max(1.0, abs(x[col]))
        xp, xm = x.copy(), x.copy()
        xp[col] += h
        xm[col] -= h
        plus, minus = problem.evaluate(xp), problem.evaluate(xm)
        assert ev.gradient[col] == pytest.approx((plus.J - minus.J) / (2 * h), rel=1e-4, abs=1e-7), col
        fd = (plus.constraints - minus.constraints) / (2 * h)
        np.testing.assert_allclose(ev.jacobian[-n_extra:, col], fd[-n_extra:], rtol=1e-5, atol=1e-5,
                                   err_msg=f"column {col}: {problem.variables[col][0]}")
        # windowed minima may switch node between x +- h for a few rows
        close = np.abs(ev.jacobian[:-n_extra, col] - fd[:-n_extra]) <= 1e-4 * (1 + np.abs(fd[:-n_extra]))
        assert close.mean() > 0.97, (col, np.flatnonzero(~close)[:5])


# ------------------------------------------------------------------------ planning the crossing
@pytest.fixture(scope="module")
def crossing_plan():
    from planners.optimize import plan

    return plan(load_mission("cross-singularity"), "two-step")


def test_the_planned_crossing_holds_every_limit_on_a_dense_grid(crossing_plan, proto):
    res = crossing_plan
    assert res.method == "crossing" and res.feasible, res.report.violations
    outcome = res.crossing
    assert outcome.crossings == 1
    assert abs(outcome.criterion_residual(proto)) < 1e-9
    # an independent resampling at 2 kHz, every knot included
    trajectory = res.trajectory
    t = np.unique(np.concatenate([trajectory.sample_times(2000.0), trajectory.knots]))
    m = trajectory.evaluate(t, order=6)
    inputs = idyn.inverse_dynamics(proto, m)
    limit = proto.rotor_constants.max_speed - proto.margins.rotor_speed
    assert inputs.rotor_speed.min() >= 0.0 and inputs.rotor_speed.max() <= limit + 1e-3
    assert np.abs(inputs.roll).max() <= np.pi / 2 - proto.margins.angle
    assert inputs.thrust.min() >= singularity.min_thrust(proto) - 1e-6
    margins = prototype_workspace_margins(m[0], proto.link_length, proto.margins)
    for name in ("ground_2", "ground_3", "fixed_point_2", "fixed_point_3", "q1_low", "q1_high"):
        assert margins[name].min() >= -1e-9, name
    q2 = m[0][:, 1]
    ts = outcome.crossing_time
    assert np.all(q2[t < ts - 1e-9] > 0) and np.all(q2[t > ts + 1e-9] < 0)
    assert abs(m[1][np.searchsorted(t, ts), 1]) >= 0.2  # a simple crossing


def test_the_planned_crossing_is_c4_at_every_knot(crossing_plan):
    trajectory = crossing_plan.trajectory
    scale = np.abs(trajectory.evaluate(trajectory.sample_times(200.0), order=4)).max(axis=(1, 2))
    for knot in trajectory.knots[1:-1]:
        left = trajectory.evaluate(np.array([knot - 1e-9]), order=4)[:, 0]
        right = trajectory.evaluate(np.array([knot + 1e-9]), order=4)[:, 0]
        for r in range(5):
            np.testing.assert_allclose(left[r], right[r], atol=1e-6 * scale[r])


def test_the_crossing_does_better_than_its_first_guess_and_starts_and_ends_at_rest(crossing_plan):
    res = crossing_plan
    assert res.J < 1.0  # J = 1 at the first guess (the normalisation)
    points = res.trajectory.points
    np.testing.assert_allclose(points[0, 0], singularity.SEED_START)
    np.testing.assert_allclose(points[-1, 0], singularity.SEED_END)
    assert np.all(points[[0, -1], 1:] == 0.0)


# ------------------------------------------------------------------------ the seed's approaches
@pytest.fixture(scope="module")
def seed_outcomes(proto):
    return {a: crossing.seed_approach(proto, a, max_iterations=20) for a in (1, 2)}


@pytest.mark.parametrize("approach", [1, 2])
def test_the_seeds_approaches_fail_as_in_the_seed(proto, seed_outcomes, approach):
    """With the seed's fixed crossing states and travel times, both approaches end far outside the
    drone's limits (the seed's conclusion), and their crossing velocity (q2' > 0) heads back into
    the start's assembly mode, so q2 changes sign more than once.
    """
    out = seed_outcomes[approach]
    assert not out.feasible
    assert abs(out.criterion_residual(proto)) < 1e-9  # finite force at the crossing, as designed
    limit = proto.rotor_constants.max_speed - proto.margins.rotor_speed
    assert out.report.peaks(proto)["peak_rotor_speed_rad_s"] > 2 * limit
    assert out.crossing_point[1, 1] > 0 and out.crossings >= 2


# ------------------------------------------------------------------------ missions
def _crossing_mission(**changes):
    data = {"robot": "prototype", "space": "joint", "arm": "down", "way_points": [[-0.947, 1.894], [0.947, -1.894]],
            "times": [4.0, 4.0], "via_points": 2, "cross_singularity": True}
    data.update(changes)
    return mission_from_dict(data)


def test_crossing_mission_validation():
    mission = _crossing_mission()
    assert mission.cross_singularity and list(mission.times) == [4.0, 4.0]
    assert mission_from_toml(mission.to_toml()) == mission.replace(name="unnamed")
    with pytest.raises(MissionError, match=r"prototype.*exactly 2 way points"):
        _crossing_mission(way_points=[[-0.947, 1.894], [0.5, 1.5], [0.947, -1.894]], times=[1.0, 1.0, 1.0])
    with pytest.raises(MissionError, match=r"times.*2 travel"):
        _crossing_mission(times=[4.0])
    with pytest.raises(MissionError, match=r"way_points\[1\].*other"):
        _crossing_mission(way_points=[[-0.947, 1.894], [0.947, 1.894]])
    with pytest.raises(MissionError, match="true or false"):
        _crossing_mission(cross_singularity="yes")


def test_crossing_mission_in_task_space_uses_both_assembly_modes(proto):
    mission = _crossing_mission(space="task", way_points=[[0.876, 0.0], [0.876, 0.0]])
    xi = mission.positions(proto)
    assert xi[0, 1] > 0 > xi[1, 1]
    np.testing.assert_allclose(xi[0], -xi[1], atol=1e-12)


# ------------------------------------------------------------------------ control and closed loop
def test_controller_force_near_the_singularity(crossing_plan, proto):
    """With a tracking error: far from q2 = 0 the outer loop is the plain CTC solve J^-T b; at q2 = 0
    its tension is the planned one and its force across the link the CTC's (b2 / L).
    """
    from controllers.ctc import CascadedController, ControllerSettings, Reference

    res = crossing_plan
    ts = res.crossing.crossing_time
    controller = CascadedController(proto, ControllerSettings(momentum_feedback=False))  # the thesis' feedback
    band = controller.settings.singular_band
    for t in (ts - 0.5, ts):
        m = res.trajectory.evaluate(np.array([t]), order=6)
        inputs = idyn.inverse_dynamics(proto, m)
        ref = Reference(m[:5, 0], inputs.roll_rate[0], inputs.roll_acceleration[0], inputs.thrust_vector[0])
        q, v = np.zeros(proto.nq), np.zeros(proto.nq)
        q[controller.chain] = m[0, 0] + [0.01, 0.0]  # q2 kept: on the singularity at t_s
        v[controller.chain] = m[1, 0] + [0.05, -0.05]
        force = controller.outer(q, v, ref)[0]
        s, ds = q[controller.chain], v[controller.chain]
        st = controller.settings
        u = m[2, 0] - st.chain_frequency**2 * (s - m[0, 0]) - 2 * st.chain_damping * st.chain_frequency * (ds - m[1, 0])
        mass, bias, jac = controller._point_dynamics(s, ds)
        b = mass @ u + bias
        q12 = s.sum()
        along, across = np.array([np.cos(q12), np.sin(q12)]), np.array([-np.sin(q12), np.cos(q12)])
        assert force @ across == pytest.approx(b[1] / proto.link_length, rel=1e-9)
        if abs(np.sin(s[1])) >= 10 * np.sin(band):
            np.testing.assert_allclose(force, np.linalg.solve(jac.T, b), rtol=1e-9)
        else:
            assert s[1] == 0.0
            assert force @ along == pytest.approx(inputs.thrust_vector[0, 0] @ along, rel=1e-9)
            assert np.all(np.isfinite(force))


@pytest.fixture(scope="module")
def crossing_simulation(crossing_plan):
    from fpr.sim.closed_loop import simulate

    return simulate(crossing_plan)


def test_the_simulated_crossing_ends_in_the_other_assembly_mode(crossing_simulation, crossing_plan, proto):
    log = crossing_simulation
    q2 = log.column("q2")
    assert q2[0] > 0 and q2[-1] < 0
    assert np.count_nonzero(np.diff(np.sign(q2))) == 1  # crosses once
    error = log.tracking_error
    assert np.abs(error).max() < 0.1  # rad, during the whole motion
    assert np.abs(error[-1]).max() < 0.01  # rad, at the end
    assert log.speed.min() >= 0.0 and log.speed.max() <= proto.rotor_constants.max_speed
    assert not log.saturated.any()


def test_crossing_comparison_figure(proto, seed_outcomes, crossing_plan, tmp_path):
    from fpr.views.figures import _crossing_comparison, crossing_comparison_figure

    outcomes = [seed_outcomes[1], seed_outcomes[2], crossing_plan.crossing]
    fig = _crossing_comparison(proto, outcomes, 200.0)
    axes = fig.axes
    assert [ax.get_ylabel() for ax in axes] == ["$q_2$ [rad]", "thrust $|F|$ [N]",
                                                "rotor speeds, max / min [rad/s]"]
    assert all(ax.get_xlabel() == "time from the crossing [s]" for ax in axes)
    limits = [line.get_ydata()[0] for line in axes[2].lines if line.get_gid() == "limit"]
    assert sorted(limits) == [0.0, pytest.approx(750.0)]
    thrust_limit = [line.get_ydata()[0] for line in axes[1].lines if line.get_gid() == "limit"]
    assert thrust_limit == [pytest.approx(4 * proto.rotor_constants.thrust_coefficient * 750.0**2)]
    labels = [line.get_label() for line in axes[0].lines if not line.get_label().startswith("_")]
    assert labels == ["seed approach 1 (limits violated)", "seed approach 2 (limits violated)",
                      "optimised crossing"]
    path = crossing_comparison_figure(tmp_path / "crossing.png", proto, outcomes)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_planned_crossing_is_c5_there_so_the_rotor_speeds_do_not_step(crossing_plan, proto):
    """9th-degree segments are C4 at knots; at the crossing the plan also keeps the 5th derivative
    continuous (a jump there steps the roll acceleration: F is only C1 where it is 0/0).
    """
    res = crossing_plan
    i, ts = res.crossing.index, res.crossing.crossing_time
    segments = res.trajectory.segments
    left = segments[i - 1].evaluate(segments[i - 1].duration, order=5)[5, 0]
    right = segments[i].evaluate(0.0, order=5)[5, 0]
    np.testing.assert_allclose(crossing_problem.fifth_derivative_jump(res.trajectory, i), left - right, rtol=1e-9,
                               atol=1e-9)
    dt = res.trajectory.durations[i - 1:i + 1].mean()  # the optimiser scales by the grid's first durations
    assert np.abs(left - right).max() * dt**5 / 120 <= 1.5 * crossing_problem.JUMP_TOLERANCE  # in Taylor units
    inputs = idyn.inverse_dynamics(proto, res.trajectory.evaluate(np.array([ts - 1e-9, ts + 1e-9]), order=6))
    assert abs(inputs.roll_acceleration[0, 0] - inputs.roll_acceleration[1, 0]) < 0.5  # rad/s^2
    assert np.abs(inputs.rotor_speed[0] - inputs.rotor_speed[1]).max() < 5.0  # rad/s


def test_a_solve_that_stalls_next_to_the_feasible_set_is_refined_not_dropped():
    """solve_refining: an attempt whose stage ends infeasible on its grid by a hair (the crossing's SQP stalls at
    ~1e-6 near the singularity, round-off deciding) is continued on a finer grid up to ``refine_below``; above
    it, or with the default threshold, the loop stops there as before.
    """
    from types import SimpleNamespace

    from planners.optimisation.solving import GRID_FEASIBILITY, Grid, solve_refining

    def run(first_violation, **kwargs):
        calls = []

        def attempt(grid, previous):
            calls.append((grid, previous))
            violation = first_violation if previous is None else 0.0
            return f"motion {len(calls)}", [SimpleNamespace(violation_end=violation)]

        def check(motion):  # the dense check passes on the refined attempt's motion only
            return SimpleNamespace(feasible=motion != "motion 1")

        trajectory, report, stages = solve_refining(attempt, check, Grid(), 2, **kwargs)
        return calls, trajectory, report

    calls, trajectory, report = run(5 * GRID_FEASIBILITY, refine_below=1e-4)
    assert len(calls) == 2 and calls[1][1] == "motion 1" and calls[1][0] == Grid().refined()
    assert trajectory == "motion 2" and report.feasible
    for violation, kwargs in ((5 * GRID_FEASIBILITY, {}), (1e-3, {"refine_below": 1e-4})):
        calls, trajectory, report = run(violation, **kwargs)
        assert len(calls) == 1 and trajectory == "motion 1" and not report.feasible
