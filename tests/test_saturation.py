"""The outer loop's forces kept within what the rotors can give (controllers/saturation.py), and the gust hold
check along a plan as flown (fpr/robustness/holding.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import gust_flight, turned

from controllers.ctc import CascadedController, ControllerSettings
from fpr.robustness.holding import hold_check
from fpr.robustness.outcomes import fly_event
from fpr.sim.closed_loop import SimulationSettings
from planners.missions.events import GustEvent


def _law_within(limiter, q, v, reference, force):
    z = limiter.speeds_squared(q, v, reference, force, limiter.attitude_at(q, v, reference))
    return np.all((z >= 0) & (z <= limiter._upper), axis=1)


def test_a_force_the_rotors_can_give_is_held_as_it_is(hover):
    robot, q, inputs, reference = hover
    controller = CascadedController(robot)
    v = np.zeros(robot.nq)
    planned = inputs.thrust_vector[0]
    wanted = 1.05 * planned
    assert controller.limiter.limit(q, v, reference, wanted) is wanted
    assert not controller.limiter.limited
    # in the loop: the first update of the hover is the plain controller's, to the bit
    plain = CascadedController(robot, ControllerSettings(force_limits=False))
    np.testing.assert_array_equal(controller.update(0.0, q, v, reference).speeds,
                                  plain.update(0.0, q, v, reference).speeds)


def test_a_force_the_rotors_cannot_follow_is_turned_until_they_can(hover):
    """A drone asked at once to tilt by 0.9 rad with half its thrust: beyond its rotors (checked); the limited
    force keeps the wanted size, turns the drone's target towards its attitude, not past it, the others as wanted,
    and the first tick's command on it is within the rotor bounds.
    """
    robot, q, inputs, reference = hover
    controller = CascadedController(robot)
    limiter = controller.limiter
    v = np.zeros(robot.nq)
    planned = inputs.thrust_vector[0]
    wanted = planned.copy()
    wanted[0] = 0.5 * turned(planned[0], 0.9)
    assert not _law_within(limiter, q, v, reference, wanted)[0]
    held = limiter.limit(q, v, reference, wanted)
    assert limiter.limited and 0.0 < limiter.scale[0] < 1.0
    assert _law_within(limiter, q, v, reference, held).all()
    np.testing.assert_allclose(np.linalg.norm(held, axis=1), np.linalg.norm(wanted, axis=1), rtol=1e-12)
    np.testing.assert_array_equal(held[1:], wanted[1:])
    kind, st = robot.kind, controller.settings
    place = controller._drone_places[0]
    roll = q[controller.attitude[place]]
    goal = kind.attitude_targets(q, v, wanted, reference, st).target[place]
    target = kind.attitude_targets(q, v, held, reference, st).target[place]
    assert min(roll, goal) < target < max(roll, goal)


@pytest.fixture(scope="module")
def square():
    return gust_flight("square")


def test_an_upward_push_on_a_drone_no_longer_saturates_the_rotors(square):
    """A gust of 5.9 N, upward, on drone 1 of the square (a campaign's draw): without the limits a rotor sits at a
    bound on more than 1 % of the ticks; with them on none of them, the robot held. Both with an observer of
    10 rad/s: the default, faster one takes the push's roll torque off the drone sooner, and this gust then
    saturates without the limits on just under 1 % of the ticks.
    """
    mission, robot, flight = square
    gust = GustEvent(3.834632, (0.0, -0.317712, 5.888095), 2.203838, "drone_1", 0.518279)
    rows = {}
    for limits in (False, True):
        controller = ControllerSettings(force_limits=limits, observer_bandwidth=10.0)
        settings = SimulationSettings(hold=flight.hold, controller=controller)
        rows[limits] = fly_event(flight, robot, settings, gust)
    assert rows[False]["saturated_share"] > 0.01 and not rows[False]["success"]
    assert rows[True]["saturated_share"] < 0.01 and rows[True]["success"] and not rows[True]["lost"]
    assert rows[True]["broken"] == ""


def test_the_hold_check_along_a_plan_asks_for_its_motion_in_the_steady_force(square):
    """A gust of 6.4 N on drone 2 (a campaign's draw): holdable at rest at the square's way points, but flying the
    plan's motion in it needs a rotor below 0; the poses checked are the plan's while it blows.
    """
    mission, robot, flight = square
    gust = GustEvent(8.240263, (0.0, 2.847966, 5.736304), 2.155774, "drone_2", 0.124727)
    at_way_points = hold_check(robot, mission, gust)
    along = hold_check(robot, mission, gust, flight.trajectory, flight.trajectory.total_duration + flight.hold)
    assert at_way_points.holdable
    assert not along.holdable and along.speed < 0 and along.way_point is None
    assert gust.at <= along.worst_time <= gust.at + gust.duration
    assert along.samples == pytest.approx(gust.duration * 100, abs=2)
    assert along.line().startswith("not holdable") and "on the plan" in along.line()
    calm = hold_check(robot, mission, GustEvent(8.240263, (0.0, 0.0, 0.0), 2.155774, "drone_2"),
                      flight.trajectory, flight.trajectory.total_duration + flight.hold)
    assert calm.holdable and calm.margin > along.margin
