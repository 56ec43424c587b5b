"""The wind feed-forward of the controller (controllers/ctc.py) and its wiring (fpr/sim/replanning.py).

Physics checks against independent computations: the planner's inverse dynamics with a known external
force (planners/problem/disturbance.py's Q_ext = J_p^T F, its J_p by complex step of the kind's task point, where
the controller takes Pinocchio's frame Jacobian), and the static force balance of the whole robot.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import fpr
from controllers.ctc import CascadedController, Reference
from fpr import _native as native
from fpr.model.inverse_dynamics import inverse_dynamics
from planners.problem.disturbance import task_jacobian

POSES = {"fpr": np.array([0.0, 0.0, 5 * np.pi / 4, np.pi / 2]), "prototype": np.array([-0.84, 1.68])}
GRAVITY = 9.81


def _state(robot, motion):
    """A full (q, v) on the chain state of ``motion`` (other coordinates 0)."""
    q, v = np.zeros(robot.nq), np.zeros(robot.nq)
    chain = robot.indices(robot.layout.chain)
    q[chain], v[chain] = motion[0, 0], motion[1, 0]
    return q, v


@pytest.mark.parametrize("name", ["fpr", "prototype"])
def test_the_fed_forward_wind_gives_the_planners_thrusts_in_that_wind(name):
    """On the reference (no error), F of the outer loop with a force on the task point equals the planning
    inverse dynamics flown in that force (J_h^T F = M_s s'' + c_s - J_p^T f): a moving state, not hover.
    """
    robot = fpr.load(name)
    rng = np.random.default_rng(3)
    n_s = len(robot.layout.chain)
    motion = np.zeros((5, 1, n_s))
    motion[0, 0] = POSES[name] + 0.05 * rng.normal(size=n_s)
    motion[1:3, 0] = 0.3 * rng.normal(size=(2, n_s))
    force = np.array([0.4, -8.0, 2.5])
    q_ext = task_jacobian(robot, motion[0])[0].T @ force[1:]
    planned = inverse_dynamics(robot, motion, external=q_ext[None])
    still = inverse_dynamics(robot, motion)
    assert np.abs(planned.thrust_vector - still.thrust_vector).max() > 1.0  # the force matters here
    q, v = (state[0] for state in planned.full_state(robot)[:2])  # the rolls and their rates on the plan too
    controller = CascadedController(robot)
    reference = Reference(motion[:, 0], planned.roll_rate[0], planned.roll_acceleration[0],
                          planned.thrust_vector[0], task_force=force)
    np.testing.assert_allclose(controller.outer(q, v, reference), planned.thrust_vector[0], atol=1e-9)
    np.testing.assert_allclose(controller.external_force(force), q_ext, atol=1e-9)


def test_a_force_on_a_drone_is_that_drones_joint_force():
    """A force on drone i enters as J_h,i^T f (the planning model's point mass at the joint): the outer loop's
    F_i with it is F_i without it minus f, the other drone's force unchanged (at rest: hover).
    """
    robot = fpr.load("fpr")
    motion = np.zeros((5, 1, 4))
    motion[0, 0] = POSES["fpr"]
    planned = inverse_dynamics(robot, motion)
    q, v = _state(robot, motion)
    controller = CascadedController(robot)
    plain = controller.outer(q, v, Reference(motion[:, 0], planned.roll_rate[0],
                                             planned.roll_acceleration[0]))
    drones = np.array([[0.0, 1.5, -2.0], [0.0, 0.0, 0.0]])
    pushed = controller.outer(q, v, Reference(motion[:, 0], planned.roll_rate[0],
                                              planned.roll_acceleration[0], drone_forces=drones))
    np.testing.assert_allclose(pushed[0], plain[0] - drones[0, 1:], atol=1e-9)
    np.testing.assert_allclose(pushed[1], plain[1], atol=1e-9)


def test_hover_in_a_wind_balances_the_forces_by_hand():
    """Static equilibrium of the FPR at s0 in 8 N along -y on the end-effector: the drones' forces add up to
    (+8 N, m_total g) (the whole robot at rest: external forces sum to zero), and their moment about the
    end-effector balances the links' weight (each link's weight at its middle, the drones' at the joints).
    """
    robot = fpr.load("fpr")
    motion = np.zeros((5, 1, 4))
    motion[0, 0] = POSES["fpr"]
    q, v = _state(robot, motion)
    controller = CascadedController(robot)
    wind = np.array([0.0, -8.0, 0.0])
    force = controller.outer(q, v, Reference(motion[:, 0], np.zeros(2), np.zeros(2), task_force=wind))
    p = robot.parameters
    links, drones = 2 * p["link_mass"], sum(robot.drone_masses)
    total = links + drones + p.get("end_effector_mass", 0.0)
    np.testing.assert_allclose(force.sum(axis=0), [8.0, total * GRAVITY], rtol=1e-3)
    # moments about the end-effector (at y = z = 0): drone joints at L u(phi), L u(phi + q21)
    length, (_, _, phi, q21) = p["link_length"], POSES["fpr"]
    joints = length * np.array([[np.cos(a), np.sin(a)] for a in (phi, phi + q21)])
    weights = np.array(robot.drone_masses) * GRAVITY
    moment = sum(j[0] * f[1] - j[1] * f[0] for j, f in zip(joints, force, strict=True))
    moment -= sum(j[0] * w for j, w in zip(joints, weights, strict=True))  # the drones' weight at the joints
    moment -= sum(j[0] / 2 * p["link_mass"] * GRAVITY for j in joints)  # each link's weight at its middle
    assert abs(moment) < 1e-3 * total * GRAVITY * length


def test_no_known_force_is_the_controller_as_it_was():
    """task_force and drone_forces None: the same bits as a Reference without them (the no-wind path)."""
    robot = fpr.load("fpr")
    rng = np.random.default_rng(8)
    motion = np.zeros((5, 1, 4))
    motion[0, 0] = POSES["fpr"]
    planned = inverse_dynamics(robot, motion)
    q, v = _state(robot, motion)
    q = q + 0.02 * rng.normal(size=q.size)
    a = CascadedController(robot).update(0.0, q, v, Reference(motion[:, 0], planned.roll_rate[0],
                                                                planned.roll_acceleration[0]))
    bare = Reference(motion[:, 0], planned.roll_rate[0], planned.roll_acceleration[0], None, None, None)
    b = CascadedController(robot).update(0.0, q, v, bare)
    assert np.array_equal(a.speeds, b.speeds) and np.array_equal(a.force, b.force)


def test_the_inner_loops_model_in_the_wind_is_the_forward_dynamics_with_the_force():
    """The attitude model (2.12) the allocation uses, with a known force on the end-effector: its attitude
    accelerations equal those of M a = B u - c + Q_ext, Q_ext = (d p / d q)^T f by central differences of the
    end-effector's position (forward kinematics only; the controller uses Pinocchio's frame Jacobian).
    """
    import pinocchio as pin

    robot = fpr.load("fpr")
    rng = np.random.default_rng(11)
    q = robot.configuration(**dict(zip(robot.layout.chain, POSES["fpr"], strict=True)))
    q = q + 0.05 * rng.normal(size=robot.nq)
    v = 0.3 * rng.normal(size=robot.nq)
    thrust, torque = rng.uniform(5, 12, robot.n_drones), 0.2 * rng.normal(size=(robot.n_drones, 3))
    force = np.array([0.7, -8.0, 1.5])
    data, frame = robot.model.createData(), robot.model.getFrameId(robot.kind.task_frame)

    def tip(qq):
        pin.framesForwardKinematics(robot.model, data, robot.to_pinocchio(qq))
        return data.oMf[frame].translation.copy()

    step = 1e-6
    jac = np.stack([(tip(q + step * e) - tip(q - step * e)) / (2 * step) for e in np.eye(robot.nq)], axis=-1)
    q_ext = force @ jac
    expected = np.linalg.solve(robot.mass_matrix(q), robot.generalized_input(q, thrust, torque)
                               - robot.nonlinear_effects(q, v) + q_ext)[robot.indices(robot.layout.attitude)]
    controller = CascadedController(robot)
    attitude = controller._attitude_in_wind(q, robot.attitude_model(q, v), force, None)
    np.testing.assert_allclose(attitude.attitude_acceleration(thrust, torque), expected, atol=1e-6)
    still = robot.attitude_model(q, v).attitude_acceleration(thrust, torque)
    assert np.abs(still - expected).max() > 1e-2  # the wind does move the attitude


def _short_flight(robot):
    """A 1.5 s rest-to-rest travel of the FPR from s0, 0.2 m along y (a stand-in for a plan: its trajectory
    and robot are all the simulation reads).
    """
    from types import SimpleNamespace

    from planners.trajectory.polynomial import PiecewisePolynomial

    points = np.zeros((2, 5, 4))
    points[0, 0] = POSES["fpr"]
    points[1, 0] = POSES["fpr"] + [0.2, 0.0, 0.0, 0.0]
    return SimpleNamespace(trajectory=PiecewisePolynomial(points, np.array([1.5])), robot=robot)


def _run(result, mission, triggers):
    from fpr.sim.closed_loop import SimulationSettings, simulate
    from fpr.sim.replanning import InFlight

    robot = result.robot
    settings = SimulationSettings(hold=0.3)
    chain = [robot.index[c] for c in robot.layout.chain]
    hooks = None if mission is None else InFlight(mission, None, triggers, settings.controller, chain, robot)
    return simulate(result, settings, in_flight=hooks)


def test_without_a_known_force_the_closed_loop_is_the_same_to_the_bit():
    """The hooks of the wind feed-forward change nothing when no force is known: a mission whose events move
    a way point only (ignored without a replanner) flies bit for bit as without any hook; a gust the
    controller is told of changes the run from its start on, and only from then.
    """
    import dataclasses

    from fpr.sim.replanning import TriggerSettings
    from planners.missions.events import GustEvent
    from planners.missions.mission import load_mission

    robot = fpr.load("fpr")
    result = _short_flight(robot)
    with native.switched(loop=False):  # the Python loop, as with hooks (the native loop: the same to round-off)
        plain = _run(result, None, None)
    moving = _run(result, load_mission("moving-target"), TriggerSettings())
    for name in ("q", "v", "speed_command", "speed", "thrust", "torque", "roll_desired", "planned_roll"):
        assert np.array_equal(getattr(plain, name), getattr(moving, name)), name

    gust = GustEvent(0.8, (0.0, -3.0, 0.0), 5.0, "end_effector", 0.3)
    windy = dataclasses.replace(load_mission("gust"), events=(gust,))
    told = _run(result, windy, TriggerSettings())
    blind = _run(result, windy, TriggerSettings(feed_forward=False))
    before = told.t < 0.8 - 1e-9
    assert np.array_equal(told.speed_command[before], blind.speed_command[before])
    assert np.abs(told.speed_command[~before] - blind.speed_command[~before]).max() > 1.0
    # told the wind, the controller holds the plan: the end-effector's y error is smaller than blind
    y = robot.layout.chain.index("y")
    assert np.abs(told.tracking_error[:, y]).max() < 0.5 * np.abs(blind.tracking_error[:, y]).max()


def test_the_wind_estimate_adds_what_the_controller_feeds_forward():
    """With the wind fed forward the feedback holds only the rest of it: on the plan (no error) the estimate
    is the fed force; held off by what a force G needs, it is the fed force plus G.
    """
    from controllers.ctc import ControllerSettings
    from fpr.sim.wind_estimate import WindEstimator
    from planners.problem.disturbance import task_jacobian

    robot = fpr.load("fpr")
    settings = ControllerSettings(chain_integral=0.0)
    s_d = np.array([0.3, 0.2, 4.0, 1.2])
    fed, rest = np.array([0.0, -6.0, 0.0]), np.array([0.0, -1.0, 0.5])
    mass = np.asarray(robot.planar("point").mass_matrix(s_d[None]))[0]
    push = np.linalg.solve(mass, task_jacobian(robot, s_d[None])[0].T @ rest[1:])  # M_s^-1 Q_ext of the rest
    error = push / settings.chain_frequency**2
    on_plan = WindEstimator(robot, settings, time_constant=0.1)
    held = WindEstimator(robot, settings, time_constant=0.1)
    for k in range(1001):
        a = on_plan.update(k * 0.002, s_d, np.zeros(4), np.stack([s_d, np.zeros(4)]), fed)
        b = held.update(k * 0.002, s_d, np.zeros(4), np.stack([s_d - error, np.zeros(4)]), fed)
    np.testing.assert_allclose(a, fed, atol=1e-9)
    np.testing.assert_allclose(b[1:], (fed + rest)[1:], rtol=1e-6)


def test_an_infeasible_wind_replan_is_solved_again_without_the_headroom_after_its_latency():
    """_wind_replan: the wind deadline for the solve; infeasible with the rotors' headroom, a second solve
    without it (ReplanOptions.wind_headroom 0 during it only), triggered when the first ends.
    """
    from types import SimpleNamespace

    from fpr.sim.closed_loop import SimulationSettings
    from fpr.sim.replanning import InFlight, TriggerSettings
    from planners.missions.mission import load_mission
    from planners.problem.disturbance import CONTROL_HEADROOM
    from planners.replanning.replanner import ReplanOptions

    calls = []

    def replan(t, trigger, through=None):
        calls.append((t, trigger, fake.options.deadline, fake.options.wind_headroom))
        used = len(calls) > 1
        return SimpleNamespace(used=used, feasible=used, solver="iteration limit reached", latency_s=0.084,
                               why="used" if used else "not used: infeasible (x)")

    robot = fpr.load("fpr")
    fake = SimpleNamespace(robot=robot, moves={}, options=ReplanOptions(), replan=replan, gusts=[],
                           assumed=None)
    hooks = InFlight(load_mission("gust"), fake, TriggerSettings(), SimulationSettings().controller,
                     [robot.index[c] for c in robot.layout.chain], robot)
    hooks._wind_replan(5.0, "way point 2 ahead in the wind", through=3)
    assert [(t, d, h) for t, _, d, h in calls] == [(5.0, 0.3, CONTROL_HEADROOM), (5.084, 0.3, 0.0)]
    assert "without the rotors' headroom" in calls[1][1]
    assert fake.options == ReplanOptions()  # the replanner's own options again


@pytest.mark.parametrize("value", [-1.0, float("nan"), "225", True])
def test_wind_headroom_refuses_absurd_values(value):
    from planners.replanning.replanner import ReplanOptions

    with pytest.raises(Exception, match="wind_headroom"):
        ReplanOptions(wind_headroom=value)


@pytest.mark.parametrize("field, value", [("wind_deadline", float("inf")), ("wind_deadline", "0.3"),
                                          ("wind_deadline", -1.0), ("wind_deadline", 1.5),
                                          ("feed_forward", "no"), ("known_gusts", 1), ("rate", 0.0),
                                          ("tracking_bound", float("nan")), ("wind_lead", 0.0)])
def test_trigger_settings_refuse_absurd_values_by_name(field, value):
    """A deadline that is not a finite time before the wind lead, a flag that is not a bool, a rate or a
    bound <= 0: refused at once with the field's name (they used to fail mid-flight or pass silently).
    """
    from fpr.sim.replanning import TriggerSettings

    with pytest.raises(Exception, match=field):
        TriggerSettings(**{field: value})


def test_an_estimate_is_fed_to_the_controller_as_a_ramp_from_its_take_up():
    """The replanner's first estimate is fully on when assumed; the controller's copy ramps on over its rise
    from that time (the feedback held the wind until then), and later blended estimates are as assumed.
    """
    from types import SimpleNamespace

    from fpr.sim.closed_loop import SimulationSettings
    from fpr.sim.replanning import InFlight, TriggerSettings
    from planners.missions.mission import load_mission

    robot = fpr.load("fpr")
    fake = SimpleNamespace(robot=robot, moves={}, gusts=[], assumed=None)
    blind = dataclasses.replace(SimulationSettings().controller, observer_bandwidth=0.0)  # the tracking-error
    hooks = InFlight(load_mission("gust"), fake, TriggerSettings(known_gusts=False, estimate_wind=True),  # estimate
                     blind, [robot.index[c] for c in robot.layout.chain], robot)
    t_up = 3.5
    nothing = np.zeros((robot.n_drones, 3))
    (first,) = hooks._estimated_gust(t_up, (np.array([0.0, -5.0, 0.0]), nothing))
    hooks._taken_up[(first.at, first.force)] = t_up
    fake.gusts.append(first)
    (fed,) = hooks.known_gusts()
    assert first.at + first.rise == pytest.approx(t_up)  # the planner's copy: fully on at take-up
    assert fed.at == t_up and fed.rise == first.rise and fed.at + fed.duration == first.at + first.duration
    task = [hooks.known_force(t)[0] for t in (t_up - 0.1, t_up, t_up + 0.25, t_up + first.rise + 0.1)]
    assert task[0] is None  # nothing fed before the take-up
    assert task[1] is None or not np.any(task[1])  # and no step at it
    assert 0.0 < -task[2][1] < 5.0 and task[3][1] == pytest.approx(-5.0)  # ramping, then all of it
    (later,) = hooks._estimated_gust(6.0, (np.array([0.0, -6.0, 0.0]), nothing), ramp_from=6.0)
    fake.gusts.append(later)
    assert hooks.known_gusts()[-1] == later
