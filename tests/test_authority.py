"""Every drone's force kept where its rotors can hold its tilt and turn it back (controllers/authority.py)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import gust_flight, turned

from controllers import authority
from controllers.ctc import CascadedController, ControllerSettings
from fpr.robustness.outcomes import fly_event
from fpr.sim.closed_loop import SimulationSettings
from planners.missions.events import GustEvent


def test_the_torque_limit_is_the_rotors_by_hand(hover):
    """tau_max(T) against a hand derivation for the drones' "+" layout: the roll rotors at w^2 = T / (4 c_T) +-
    tau / (2 l c_T), the others at T / (4 c_T), every one within [m_gr, w_max].
    """
    robot, *_ = hover
    limits = CascadedController(robot).limiter.authority
    constants, margin = robot.rotor_constants, robot.margins.rotor_speed
    c_t, arm = constants.thrust_coefficient, robot.parameters["rotor_arm"]
    low, high = margin**2, constants.max_speed**2
    for thrust in (0.5, 3.0, 9.8, 20.0, 30.0, 40.0):
        z = thrust / (4 * c_t)
        expected = min(z - low, high - z) * 2 * arm * c_t
        got = limits.torque_limit(np.full(robot.n_drones, thrust))
        np.testing.assert_allclose(got, expected if expected >= 0 else -abs(expected), rtol=1e-3)


def test_a_force_within_every_drones_set_is_held_as_it_is(hover):
    robot, q, inputs, reference = hover
    controller = CascadedController(robot)
    limits = controller.limiter.authority
    v = np.zeros(robot.nq)
    planned = inputs.thrust_vector[0]
    assert np.all(limits.slack(planned) > 0)
    assert controller.limiter.hold(q, v, planned) is planned
    assert not controller.limiter.limited


def test_a_tilt_the_rotors_cannot_hold_is_traded_for_the_least_chain_acceleration(hover):
    """Drone 1 asked for half its thrust tilted 0.9 rad further: the torque that holds that tilt is beyond its
    rotors (checked). The forces held are in every drone's set, cost less in the chain's kinetic metric than any
    other point of the sets tried (the planned forces, the wanted ones pulled back towards them), and differ from
    the wanted ones only where the trade asks it.
    """
    robot, q, inputs, reference = hover
    controller = CascadedController(robot)
    limits = controller.limiter.authority
    v = np.zeros(robot.nq)
    planned = inputs.thrust_vector[0]
    wanted = planned.copy()
    wanted[0] = 0.5 * turned(planned[0], 0.9)
    assert limits.slack(wanted)[0] < 0
    held = controller.limiter.hold(q, v, wanted)
    assert controller.limiter.limited and held is not wanted
    assert np.all(limits.slack(held) >= -1e-6)
    chain = controller.chain
    m, _, jac = controller._point_dynamics(q[chain], v[chain])
    weight = jac.dot(np.linalg.solve(m, jac.T))

    def cost(force):
        d = (np.asarray(force) - wanted).reshape(-1)
        return d.dot(weight.dot(d))

    candidates = [planned] + [wanted + a * (planned - wanted) for a in np.linspace(0.05, 1.0, 20)]
    feasible = [f for f in candidates if np.all(limits.slack(f) >= 0)]
    assert feasible
    assert cost(held) <= min(cost(f) for f in feasible) + 1e-9


@pytest.fixture(scope="module")
def square():
    return gust_flight("square")


@pytest.mark.parametrize("gust", [
    GustEvent(5.581481, (0.0, 4.962977, 0.396673), 3.927544, "end_effector", 0.929014),
    GustEvent(4.842504, (0.0, 2.427182, 3.781112), 5.447254, "end_effector", 0.544648),
], ids=["sideways-5N", "up-and-sideways-4.5N"])
def test_pushes_on_the_end_effector_that_lost_the_robot_are_held(square, gust, monkeypatch):
    """Two gusts of a campaign's draws on the square, holdable along the plan: pushes of 5 N sideways and of 4.5 N
    up and sideways on the end-effector. Without the authority set the chain loop sends a drone to a tilt its few
    newtons of thrust cannot hold (the first: 1.25 rad at 2.9 N) and the robot is lost; with it the robot is
    held, no physical limit broken, a rotor at a bound on fewer than 1 % of the ticks.
    """
    mission, robot, flight = square
    settings = SimulationSettings(hold=flight.hold, controller=ControllerSettings())
    held = fly_event(flight, robot, settings, gust)
    assert held["holdable"]
    assert held["success"] and not held["lost"] and held["broken"] == ""
    assert held["saturated_share"] < 0.01
    with monkeypatch.context() as patch:
        patch.setattr(authority.AuthoritySet, "hold", lambda self, q, v, wanted: wanted)
        plain = fly_event(flight, robot, settings, gust)
    assert plain["lost"] and not plain["success"]
