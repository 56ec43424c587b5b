"""The external-force observer (controllers/observer.py) and its place in the CTC (controllers/ctc.py).

Checked against independent things: a hand-integrated one-degree-of-freedom system; the closed-chain plant
(fpr/sim/plant.py, Pinocchio's constraint dynamics, not the controller's minimal model) pushed by a known
constant wind and by a step gust, whose generalised force is computed by hand from the hinge and task-point
Jacobians of the planning model; and the thesis' controller without the observer, on the same flights.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import fpr
from controllers.ctc import ControllerSettings
from controllers.observer import MomentumObserver
from fpr.sim.closed_loop import SimulationSettings, simulate
from fpr.sim.replanning import InFlight, TriggerSettings
from planners.missions.events import GustEvent
from planners.missions.mission import Mission, load_mission
from planners.optimize import plan
from planners.problem.disturbance import task_jacobian

S0 = [0.0, 0.0, 5 * np.pi / 4, np.pi / 2]


def test_the_discrete_observer_is_a_first_order_filter_of_the_force():
    """A mass-spring with a known force and a step of unknown force, integrated by hand: the estimate follows
    r' = K (Q - r) to within K dt / 2, whatever the known input does, and holds a constant force exactly.
    """
    mass, stiffness, k, dt, fine = 2.0, 3.0, 10.0, 1e-3, 50
    observer = MomentumObserver(k, 1)
    x, v, estimates, known = 0.0, 0.0, [], 0.0
    for step in range(3000):
        t = step * dt
        # the observer is given the input held over the last step; then the next step's input
        estimates.append(observer.update(dt, [[mass]], [v], [stiffness * x], [known])[0])
        known = np.sin(3 * t)  # the controller's input over this step (held), known to the observer
        unknown = 1.5 if t >= 0.5 else 0.0
        for _ in range(fine):  # the system, integrated finely (velocity Verlet)
            h = dt / fine
            v_half = v + 0.5 * h * (known + unknown - stiffness * x) / mass
            x = x + h * v_half
            v = v_half + 0.5 * h * (known + unknown - stiffness * x) / mass
    estimates = np.array(estimates)
    t = np.arange(3000) * dt
    after = t >= 0.5 + dt
    expected = 1.5 * (1 - np.exp(-k * (t[after] - 0.5)))
    assert np.abs(estimates[~after]).max() < 1e-3  # nothing unknown: nothing estimated
    np.testing.assert_allclose(estimates[after], expected, atol=1.5 * k * dt / 2 * 1.5)
    assert estimates[-1] == pytest.approx(1.5, rel=1e-3)


@pytest.fixture(scope="module")
def hover():
    """The FPR holding s0 (a 6 s 'mission' of 1 cm), its plan."""
    mission = Mission(name="hover", robot="fpr", way_points=[S0, [0.0, 0.01, *S0[2:]]], times=[6.0])
    return plan(mission, "none")


def _time_to(values, level, t):
    """First time ``values`` (1-d) reaches ``level`` (its sign)."""
    k = int(np.argmax(np.sign(level) * values >= abs(level)))
    return float(t[k])


def test_a_constant_wind_on_the_drones_is_estimated_with_the_documented_bandwidth(hover):
    """2 N along y on each drone's centre of mass in the plant from t = 0: the estimate converges to the
    hand-computed Q_ext = J_h^T f (f at each drone's joint: its centre's chain Jacobian is its joint's), 63 %
    after about 1 / K_O and within 1 % after 1 s.
    """
    robot = hover.robot
    k = ControllerSettings().observer_bandwidth
    log = simulate(hover, SimulationSettings(wind=(0.0, 2.0, 0.0), hold=0.0))
    jac = robot.planar("point").hinge_jacobian(np.array(S0)[None])[0]
    expected = jac.T @ np.array([2.0, 0.0, 2.0, 0.0])
    late = log.t >= 1.0
    np.testing.assert_allclose(log.disturbance[late], np.broadcast_to(expected, log.disturbance[late].shape),
                               atol=0.01 * np.abs(expected).max())
    rise = _time_to(log.disturbance[:, 0], (1 - np.exp(-1)) * expected[0], log.t)
    assert 0.7 / k <= rise <= 1.3 / k + 0.01  # the outer loop's period: 10 ms
    assert log.failure is None


def test_a_step_gust_on_the_end_effector_is_estimated_and_read_as_that_force(hover):
    """A 4 N step along z on the end-effector at 1 s (the plant: J^T F of the task point): the estimate reaches
    J_p^T F (J_p by complex step of the kind's task point) with the bandwidth, and the controller reads it
    back as that force on the task point and none on the drones (estimated_forces).
    """
    robot = hover.robot
    gust = GustEvent(1.0, (0.0, 0.0, 4.0), 10.0)
    mission = hover.mission.replace(events=(gust,))
    flown = dataclasses.replace(hover, mission=mission)
    chain = [robot.index[c] for c in robot.layout.chain]
    hooks = InFlight(mission, None, TriggerSettings(known_gusts=False), ControllerSettings(), chain, robot)
    log = simulate(flown, SimulationSettings(hold=0.0), in_flight=hooks)  # the controller: hooks._controller
    expected = task_jacobian(robot, np.array(S0)[None])[0].T @ np.array([0.0, 4.0])
    k = ControllerSettings().observer_bandwidth
    after = log.t >= 2.5  # settled
    np.testing.assert_allclose(log.disturbance[after].mean(axis=0), expected, atol=0.01 * 4.0)
    rise = _time_to(log.disturbance[:, 1], (1 - np.exp(-1)) * expected[1], log.t) - 1.0
    assert 0.7 / k <= rise <= 1.3 / k + 0.01
    task, drones = hooks._controller.estimated_forces()
    np.testing.assert_allclose(task, [0.0, 0.0, 4.0], atol=0.1)
    np.testing.assert_allclose(drones, 0.0, atol=0.1)


def test_estimated_forces_reproduce_the_estimate(hover):
    """J_p^T f_p + sum_i J_h,i^T f_i of the forces the controller reads = its generalised estimate; a wind on
    both drones is read as the same generalised force (the end-effector takes the share it can explain).
    """
    robot = hover.robot
    log_settings = SimulationSettings(wind=(0.0, -1.5, 0.5), hold=0.0)
    chain = [robot.index[c] for c in robot.layout.chain]
    hooks = InFlight(hover.mission, None, TriggerSettings(known_gusts=False), ControllerSettings(), chain, robot)
    simulate(hover, log_settings, in_flight=hooks)
    controller = hooks._controller
    task, drones = controller.estimated_forces()
    jac_task, jac_hinges = controller._seen
    rebuilt = jac_task.T @ task[1:] + jac_hinges.T @ drones[:, 1:].reshape(-1)
    np.testing.assert_allclose(rebuilt, controller.disturbance, atol=1e-9)
    np.testing.assert_allclose(task[1:], [-3.0, 1.0], atol=0.05)  # the two drones' y, z forces, summed


def test_the_observer_holds_winds_the_controller_without_it_does_not(hover):
    """Against the thesis' controller (observer_bandwidth 0, the integral clamped): a 3 N wind along y on each
    drone, and the square flown in 1.5 N along -y: the observer's worst tracking error is a fraction of it.
    """
    square = plan(load_mission("square"), "two-step")
    default = ControllerSettings().observer_bandwidth
    for flown, wind in ((hover, (0.0, 3.0, 0.0)), (square, (0.0, -1.5, 0.0))):
        worst = {}
        for k in (0.0, default):
            settings = SimulationSettings(wind=wind, controller=ControllerSettings(observer_bandwidth=k))
            log = simulate(flown, settings)
            assert log.failure is None
            worst[k] = np.abs(log.tracking_error).max()
        assert worst[default] < 0.5 * worst[0.0], worst


def test_without_the_observer_the_controller_estimates_nothing(hover):
    log = simulate(hover, SimulationSettings(wind=(0.0, 1.0, 0.0), hold=0.0,
                                             controller=ControllerSettings(observer_bandwidth=0.0)))
    assert not log.disturbance.any()


def test_the_observer_also_holds_for_the_prototype():
    """The prototype (one drone, the chain pinned): a 2 N wind along z on its drone is estimated as
    J_h^T f at the hover pose after 1 s, within 2 %.
    """
    robot = fpr.load("prototype")
    pose = np.array(robot.kind.reference_chain)
    mission = Mission(name="hover", robot="prototype", way_points=[pose, pose + [0.0, 0.01]], times=[4.0],
                      space="joint")
    log = simulate(plan(mission, "none", robot=robot), SimulationSettings(wind=(0.0, 0.0, 2.0), hold=0.0))
    jac = robot.planar("point").hinge_jacobian(pose[None])[0]
    expected = jac.T @ np.array([0.0, 2.0])
    late = log.t >= 1.5
    np.testing.assert_allclose(log.disturbance[late].mean(axis=0), expected, atol=0.02 * np.abs(expected).max())
