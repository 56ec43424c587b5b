"""A known external force in the planning model (planners/problem/disturbance.py), and the replanner's own SQP
(planners/replanning/solver.py).
"""

import dataclasses

import numpy as np
import pytest

from fpr.model.inverse_dynamics import inverse_dynamics
from fpr.model.jets import Jet
from fpr.robots import load
from planners.missions.events import GustEvent
from planners.missions.mission import builtin_mission_text, load_mission
from planners.optimize import plan
from planners.problem.disturbance import DisturbedProblem, dense_check, generalized_gust, gust_profile
from planners.problem.report import evaluate_motion
from planners.replanning.latency import LatencyModel
from planners.replanning.replanner import Replanner, ReplanOptions
from planners.replanning.solver import qp_step, solve_warm
from planners.trajectory.polynomial import PiecewisePolynomial

FREE = LatencyModel((0.0,) * 5)  # a solve takes no time: the deadline never decides


@pytest.fixture(scope="module")
def moving():
    mission = load_mission("moving-target")
    return mission, plan(mission, "two-step")


def _at_rest(robot, s):
    motion = np.zeros((5, 1, len(s)))
    motion[0, 0] = s
    return motion


@pytest.mark.parametrize("force", [(0.0, -8.0, 0.0), (0.0, 3.0, -12.0)])
def test_drones_take_the_external_force_at_rest(force):
    """Newton for the whole FPR at rest: the drones' thrusts change by exactly -F (independent of the model)."""
    robot = load("fpr")
    motion = _at_rest(robot, robot.kind.reference_chain)
    gust = GustEvent(0.0, force, 1.0)
    external = generalized_gust(robot, [gust], np.array([0.5]), motion[0], rise=0.0)[0]
    calm = inverse_dynamics(robot, motion).thrust_vector.sum(axis=1)
    pushed = inverse_dynamics(robot, motion, external=external).thrust_vector.sum(axis=1)
    np.testing.assert_allclose(pushed - calm, -np.array(force)[None, 1:], atol=1e-10)


def test_the_force_s_profile_drives_the_planned_roll_rates():
    """With the ramp's time derivatives in the jet, roll rate = d roll / dt (finite differences)."""
    robot = load("fpr")
    t = np.linspace(0.9, 1.6, 3501)
    motion = np.zeros((5, t.size, 4))
    motion[0] = robot.kind.reference_chain
    motion[0, :, 0] = 0.1 * np.sin(t)
    motion[1, :, 0], motion[2, :, 0] = 0.1 * np.cos(t), -0.1 * np.sin(t)
    motion[3, :, 0], motion[4, :, 0] = -0.1 * np.cos(t), 0.1 * np.sin(t)
    gust = GustEvent(1.0, (0.0, -5.0, -3.0), 0.3)
    profile = gust_profile(gust, t, 0.2)
    np.testing.assert_allclose(np.gradient(profile[0], t)[5:-5], profile[1][5:-5], atol=2e-3 * np.abs(profile[1]).max())
    inputs = inverse_dynamics(robot, motion, external=Jet(generalized_gust(robot, [gust], t, motion[0], rise=0.2)))
    fd = np.gradient(inputs.roll, t, axis=0)
    assert np.abs(inputs.roll_rate).max() > 0.5  # the ramp really rolls the drones
    np.testing.assert_allclose(fd[5:-5], inputs.roll_rate[5:-5], atol=1e-3 * np.abs(inputs.roll_rate).max())


def test_disturbed_problem_gradient_matches_finite_differences(moving):
    """The perturbed copies of the nodes carry the node's force (tiling): exact derivatives, checked by FD."""
    _, result = moving
    replanner = Replanner(result, ReplanOptions())
    replanner.move(0)
    problem, x0, times, _ = replanner.problem(4.05)
    gust = GustEvent(4.2, (0.0, -8.0, -4.0), 0.8)
    disturbed = DisturbedProblem(problem.robot, problem.points, problem.durations, problem.free, problem.alpha,
                                 problem.normalisation, samples_per_segment=problem.samples_per_segment,
                                 gusts=[gust], start_time=4.05)
    ev = disturbed.evaluate(x0, True)
    assert abs(ev.J - problem.evaluate(x0).J) > 1e-3  # the force changes the objective
    rng = np.random.default_rng(0)
    for _ in range(3):
        direction = rng.normal(size=x0.size)
        h = 1e-6
        fd = (disturbed.evaluate(x0 + h * direction).J - disturbed.evaluate(x0 - h * direction).J) / (2 * h)
        assert fd == pytest.approx(ev.gradient @ direction, rel=1e-5, abs=1e-9)
        cfd = (disturbed.evaluate(x0 + h * direction).constraints
               - disturbed.evaluate(x0 - h * direction).constraints) / (2 * h)
        smooth = np.abs(cfd - ev.jacobian @ direction) < 1e-4 * (1 + np.abs(cfd))  # window minima may switch
        assert smooth.mean() > 0.95


def test_a_zero_force_gust_leaves_the_problem_exactly_the_motion_problem(moving):
    """DisturbedProblem differs from MotionProblem only by Q_ext in the inverse dynamics (its ``_inputs``):
    with a gust of no force, J, its terms, every constraint (the between-node workspace rows included) and
    the exact derivatives are MotionProblem's, bit for bit.
    """
    _, result = moving
    replanner = Replanner(result, ReplanOptions())
    replanner.move(0)
    problem, x0, _, _ = replanner.problem(4.05)
    calm = DisturbedProblem(problem.robot, problem.points, problem.durations, problem.free, problem.alpha,
                            problem.normalisation, samples_per_segment=problem.samples_per_segment,
                            windows_per_segment=len(problem.windows) // problem.durations.size,
                            gusts=[GustEvent(3.0, (0.0, 0.0, 0.0), 5.0, rise=0.5)], start_time=4.05)
    assert calm.external is not None and not calm.external.any()  # the force is there, and zero
    x = x0 + 0.01 * np.random.default_rng(2).normal(size=x0.size)  # off the plan: the workspace rows move
    free, windy = problem.evaluate(x, True), calm.evaluate(x, True)
    assert windy.J == free.J
    np.testing.assert_array_equal(windy.terms, free.terms)
    np.testing.assert_array_equal(windy.constraints, free.constraints)
    np.testing.assert_array_equal(windy.gradient, free.gradient)
    np.testing.assert_array_equal(windy.jacobian, free.jacobian)
    assert calm.constraint_names == problem.constraint_names
    np.testing.assert_array_equal(calm.objective_terms(calm.points), problem.objective_terms(problem.points))


def test_dense_check_without_gusts_agrees_with_evaluate_motion(moving):
    _, result = moving
    part = result.trajectory
    feasible, violated, n = dense_check(result.robot, part, 100.0)
    report = evaluate_motion(result.robot, part, 100.0)
    assert feasible == report.feasible and violated == [c.name for c in report.violations]
    assert n == report.t.size
    # a gust the offline plan was not made for: the check sees the rotors it needs
    strong = GustEvent(3.0, (0.0, 0.0, -25.0), 3.0)
    feasible, violated, _ = dense_check(result.robot, part, 100.0, 0.0, [strong])
    assert not feasible and any(v.startswith("rotor_speed_high") for v in violated)


def test_qp_step_without_active_constraints_is_the_newton_step():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(6, 6))
    hess = a @ a.T + 6 * np.eye(6)
    grad = rng.normal(size=6)

    class Ev:
        gradient, hessian = grad, hess
        constraints = np.full(4, 100.0)  # far from active: left out of the QP
        jacobian = rng.normal(size=(4, 6))

    d, predicted, multipliers = qp_step(Ev, radius=1e3, penalty=10.0)
    newton = -np.linalg.solve(hess, grad)
    np.testing.assert_allclose(d, newton, rtol=1e-6, atol=1e-9)
    assert predicted == pytest.approx(-(grad @ newton + 0.5 * newton @ hess @ newton), rel=1e-6)
    assert not multipliers.any()


def test_warm_sqp_improves_within_its_cap_and_stays_feasible(moving):
    _, result = moving
    replanner = Replanner(result, ReplanOptions())
    replanner.move(0)
    problem, x0, _, _ = replanner.problem(4.05)
    start = problem.evaluate(x0)
    out = solve_warm(problem, x0, max_iterations=2)
    assert out.iterations <= 2 and out.gradient_evaluations <= 2
    assert out.J < start.J - 1e-3 and out.violation <= 1e-7
    part = PiecewisePolynomial(problem.points_of(out.x), problem.durations)
    assert dense_check(result.robot, part, 500.0)[0]


def test_a_known_sustained_wind_is_planned_against_and_keeps_the_planned_rotors_within_limits():
    """The built-in gust (8 N along -y, rising over 1 s from 2 s, then steady), told to the replanner.

    It replans at the gust's start and ``wind_lead`` (1 s) before each way point, through the travel after
    it (the splice in the part already planned for the wind), not on the tracking error the wind causes,
    and the executed plan flown in the wind holds every constraint (rotor speeds 3.48 included), where the
    offline plan in the same wind needs rotor speeds below 0. Blind (neither told nor estimating), it
    replans only on the tracking error.
    """
    from fpr.sim.closed_loop import SimulationSettings
    from fpr.sim.replanning import InFlight, TriggerSettings
    from planners.problem.disturbance import evaluate_in_gusts

    mission = load_mission("gust")
    [gust] = mission.events
    assert gust.rise > 0 and gust.at + gust.duration > sum(mission.times)  # sustained to the end
    result = plan(mission, "two-step")
    robot = result.robot
    chain = [robot.index[c] for c in robot.layout.chain]

    def fly(triggers):
        replanner = Replanner(result, ReplanOptions(deadline=0.3, latency=FREE))
        hooks = InFlight(mission, replanner, triggers, SimulationSettings().controller, chain, robot)
        for t in (1.99, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 11.0):
            reference = replanner.trajectory.evaluate(np.array([t]), 4)[:, 0]
            off = reference[0] + (0.0 if t < 2.0 else np.array([0.3, 0.0, 0.0, 0.0]))  # blown 30 cm off
            q = robot.configuration(**dict(zip(robot.layout.chain, off, strict=True)))
            hooks.after_tick(t, q, np.zeros(robot.nq), reference)
        return replanner

    known = fly(TriggerSettings(known_gusts=True))
    assert [(r.time, r.trigger.split(":")[0]) for r in known.replans] == [
        (2.0, "event"),  # way point 1 is 1 s ahead: through way point 2
        (5.0, "way point 2 ahead in the wind"),
        (8.0, "way point 3 ahead in the wind"),
    ]
    assert [r.splice_time + r.work["horizon_s"] for r in known.replans] == pytest.approx([6.0, 9.0, 12.0])
    assert all(r.used for r in known.replans) and known.gusts == [gust]
    offline = evaluate_in_gusts(robot, result.trajectory, [gust])
    assert min(offline.constraints[f"rotor_speed_low_{i}"].margin for i in (1, 2)) < -50.0  # w < 0 needed
    flown = evaluate_in_gusts(robot, known.trajectory, [gust])
    assert flown.feasible, [c.name for c in flown.violations]
    # without the wind the check is evaluate_motion's own
    assert evaluate_in_gusts(robot, result.trajectory, []).constraints.keys() == evaluate_motion(
        robot, result.trajectory
    ).constraints.keys()
    blind = fly(TriggerSettings(known_gusts=False))  # estimate_wind is off by default
    assert blind.replans and all(r.trigger.startswith("tracking error") for r in blind.replans)
    assert not blind.gusts


def test_the_wind_estimate_reads_a_steady_held_error_as_the_force_on_the_end_effector():
    """In a steady state the controller's feedback holds M_s^-1 Q_ext (fpr/sim/wind_estimate.py): an error
    held at K_p e = M_s^-1 J_p^T F (no integral term, at rest) is read back as F, through the low-pass.
    """
    import dataclasses

    from controllers.ctc import ControllerSettings
    from fpr.sim.wind_estimate import WindEstimator
    from planners.problem.disturbance import task_jacobian

    robot = load("fpr")
    settings = dataclasses.replace(ControllerSettings(), chain_integral=0.0)
    s_d = np.array([0.3, 0.2, 4.0, 1.2])
    force = np.array([0.0, -8.0, 2.5])
    mass = np.asarray(robot.planar("point").mass_matrix(s_d[None]))[0]
    push = np.linalg.solve(mass, task_jacobian(robot, s_d[None])[0].T @ force[1:])  # M_s^-1 Q_ext
    error = push / settings.chain_frequency**2
    estimator = WindEstimator(robot, settings, time_constant=0.5)
    reference = np.stack([s_d - error, np.zeros(4)])  # the plan the robot is held off (s = s_d here)
    history = [estimator.update(k * 0.002, s_d, np.zeros(4), reference)[1:].copy() for k in range(2001)]
    # after one time constant about 1 - 1/e of it, then all of it (the mass matrix is taken at s)
    np.testing.assert_allclose(history[250], (1 - np.exp(-1.0)) * force[1:], rtol=0.01)
    np.testing.assert_allclose(history[-1], force[1:], rtol=1e-3)


def test_an_estimated_wind_is_planned_against_once_it_has_held_and_silences_the_tracking_trigger():
    """estimate_wind: a robot held 30 cm off the plan in y from 2 s reads as a steady force; the replanner
    assumes it after ``estimate_delay`` (one replan, "wind estimated"), not before, and no tracking-error
    replan fires while the estimate is up (the error is the wind's).
    """
    from fpr.sim.closed_loop import SimulationSettings
    from fpr.sim.replanning import InFlight, TriggerSettings

    mission = load_mission("gust")
    result = plan(mission, "two-step")
    robot = result.robot
    chain = [robot.index[c] for c in robot.layout.chain]
    replanner = Replanner(result, ReplanOptions(deadline=0.3, latency=FREE))
    triggers = TriggerSettings(known_gusts=False, estimate_wind=True, tracking_bound=0.25)
    blind = dataclasses.replace(SimulationSettings().controller, observer_bandwidth=0.0)  # no observer: the
    hooks = InFlight(mission, replanner, triggers, blind, chain, robot)  # estimate from the tracking error
    offset = np.array([-0.3, 0.0, 0.0, 0.0])
    for t in np.arange(1.5, 4.0, 0.002):
        reference = replanner.trajectory.evaluate(np.array([t]), 4)[:, 0]
        s = reference[0] + (offset if t >= 2.0 else 0.0)
        q = robot.configuration(**dict(zip(robot.layout.chain, s, strict=True)))
        v = np.zeros(robot.nq)
        v[chain] = reference[1]
        hooks.after_tick(float(t), q, v, reference)
    records = [(r.time, r.trigger) for r in replanner.replans]
    estimated = [t for t, why in records if why.startswith("wind estimated")]
    assert len(estimated) == 1 and 3.0 <= estimated[0] <= 3.5, records  # 1 N reached within 0.5 s, held 1 s
    assert replanner.assumed is not None and replanner.assumed[0].force[1] < -1.0  # pushed towards -y
    # the first tracking replan comes before the estimate rises (30 cm > 0.25 from 2 s); none after it
    tracking = [t for t, why in records if why.startswith("tracking")]
    assert tracking and max(tracking) < estimated[0] - triggers.estimate_delay + 0.01


def test_an_estimated_wind_that_drops_is_forgotten_and_kept_as_the_record_of_what_was_planned():
    """An estimate of 5 N towards -y from 2 s to 4 s, then none: the replanner assumes it once it has held for
    ``estimate_delay``; once it has stayed under its threshold as long, the replanner stops planning against
    it (``assumed`` None, a replan saying so), and the estimated gust stays in ``gusts``, ending (fully off)
    one ramp after it was dropped, so the executed plan is checked against the wind it was made for.
    """
    from fpr.sim.closed_loop import SimulationSettings
    from fpr.sim.replanning import InFlight, TriggerSettings

    class Scripted:  # the estimator's output, scripted: this test is about what the replanner does with it
        def update(self, t, s, ds, reference, fed=None):
            return np.array([0.0, -5.0, 0.0]) if 2.0 <= t < 4.0 else np.zeros(3)

    mission = load_mission("gust")
    result = plan(mission, "two-step")
    robot = result.robot
    chain = [robot.index[c] for c in robot.layout.chain]
    replanner = Replanner(result, ReplanOptions(deadline=0.3, latency=FREE))
    triggers = TriggerSettings(known_gusts=False, estimate_wind=True, tracking_bound=None)
    blind = dataclasses.replace(SimulationSettings().controller, observer_bandwidth=0.0)
    hooks = InFlight(mission, replanner, triggers, blind, chain, robot)
    hooks.estimator = Scripted()
    assumed = []
    for t in np.arange(1.5, 6.5, 0.002):
        reference = replanner.trajectory.evaluate(np.array([t]), 4)[:, 0]
        q = robot.configuration(**dict(zip(robot.layout.chain, reference[0], strict=True)))
        v = np.zeros(robot.nq)
        v[chain] = reference[1]
        hooks.after_tick(float(t), q, v, reference)
        if replanner.assumed is not None and not assumed:
            assumed.append(replanner.assumed)
    records = [(r.time, r.trigger) for r in replanner.replans]
    estimated = [t for t, why in records if why.startswith("wind estimated")]
    dropped = [t for t, why in records if why.startswith("wind estimate below")]
    delay = triggers.estimate_delay
    assert len(estimated) == 1 and estimated[0] == pytest.approx(2.0 + delay, abs=0.003), records
    assert len(dropped) == 1 and dropped[0] == pytest.approx(4.0 + delay, abs=0.003), records
    assert replanner.assumed is None
    # every estimate planned against is kept: each ends where the next is fully on (a way point passed in
    # the wind re-estimates it), the last one ramp after it was dropped
    kept = sorted((g for g in replanner.gusts if g.force == assumed[0][0].force), key=lambda g: g.at)
    assert kept[0].at + kept[0].rise == pytest.approx(estimated[0], abs=1e-9), kept  # fully on when estimated
    for g, after in zip(kept, kept[1:], strict=False):
        assert g.at + g.duration == pytest.approx(after.at + after.rise, abs=1e-9)
    last = kept[-1]
    assert last.at + last.duration == pytest.approx(dropped[0] + last.rise, abs=1e-9)
    assert last.active(dropped[0]) and not last.active(dropped[0] + last.rise + 1e-6)


def test_the_replanner_learns_a_gust_listed_twice_twice():
    """Two identical gust events push twice as hard in the plant; the replanner plans against both."""
    from planners.missions.mission import mission_from_toml

    text = builtin_mission_text("gust")
    start = text.index("\n[[events]]")
    twice = text + "\n" + text[start:]
    mission = mission_from_toml(twice, "twice")
    assert len(mission.events) == 2 and mission.events[0] == mission.events[1]
    replanner = Replanner(plan(mission, "two-step"), ReplanOptions(deadline=0.3))
    replanner.learn(0)
    replanner.learn(1)
    replanner.learn(1)
    assert len(replanner.gusts) == 2


def test_a_step_qp_that_quadprog_cannot_solve_stops_the_replan_without_using_it(monkeypatch, moving):
    """quadprog's "constraints are inconsistent" ends the SQP with a message; the replan is not used."""
    import planners.replanning.solver as rs

    def fail(*args, **kwargs):
        raise ValueError("constraints are inconsistent, no solution")

    monkeypatch.setattr(rs.quadprog, "solve_qp", fail)
    replanner = Replanner(moving[1], ReplanOptions(deadline=0.3, latency=FREE))
    before = replanner.trajectory
    record = replanner.replan(2.0, "rate")
    assert record.solver.startswith("QP failed") and not record.used
    assert "solver failed" in record.why and replanner.trajectory is before


@pytest.mark.parametrize("field, value", [("radius", 0.0), ("radius", float("nan")), ("dense_rate", -1.0),
                                          ("max_iterations", 0), ("tolerance", 0.0)])
def test_replan_options_refuse_absurd_numbers(field, value):
    from fpr.model.errors import PlannerArgumentError

    with pytest.raises(PlannerArgumentError, match=field):
        ReplanOptions(**{field: value})
