"""The watch for a lost robot (fpr.sim.watch), on states built by hand: a real plant at a pose of our
choosing, changed where a branch needs it. The closed-loop cases (free fall, wind, each bound crossed
by a simulation) are in test_simulate.py.
"""

import numpy as np
import pytest

import fpr
from fpr.sim.closed_loop import SimulationSettings
from fpr.sim.plant import Plant, hover_configuration
from fpr.sim.watch import Watch, _past


def state(name, **coordinates):
    """A plant hovering at the robot's reference chain (with the given coordinates changed) and what the
    watch is given about it.
    """
    robot = fpr.load(name)
    q = hover_configuration(robot, robot.kind.reference_chain)
    for c, value in coordinates.items():
        q[robot.index[c]] = value
    plant = Plant.from_minimal(robot, q)
    positions, closure = plant.drone_positions_and_closure_error()
    planned = hover_configuration(robot, robot.kind.reference_chain)[robot.indices(robot.layout.chain)]
    return robot, plant, q, positions, closure, planned


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_a_hovering_robot_is_not_lost(name):
    robot, plant, q, positions, closure, planned = state(name)
    watch = Watch(robot, SimulationSettings())
    assert watch.check(0.0, plant, q, np.zeros(robot.nq), positions, closure, planned) is None


def test_a_centre_of_mass_below_the_ground_with_its_hinge_above():
    """A drone whose centre of mass is given 0.04 m below the ground while the hinges hover (as for an upside
    down drone whose hinge is just above the ground): the centre of mass is what is reported.
    """
    robot, plant, q, positions, closure, planned = state("fpr")
    assert plant.drone_joint_positions()[:, 2].min() > 0.4
    positions = positions.copy()
    positions[1, 2] = robot.kind.ground_height - 0.04
    watch = Watch(robot, SimulationSettings(ground_tolerance=0.01))
    failure = watch.check(1.25, plant, q, np.zeros(robot.nq), positions, closure, planned)
    assert failure == ("drone 2 centre of mass below the ground (z = -0.79 m < -0.76 m: ground -0.75 m, "
                       "tolerance 0.01 m) at t = 1.250 s")


def test_the_first_failure_in_the_documented_order_is_reported():
    """A non-finite state beats everything; the ground beats the tracking error."""
    robot, plant, q, positions, closure, planned = state("prototype")
    watch = Watch(robot, SimulationSettings())
    far = planned + np.array([1.5, 2.0])  # both joints past 1 rad: the larger error is reported
    low = positions.copy()
    low[0, 2] = -5.0
    assert watch.check(0.5, plant, q, np.zeros(robot.nq), low, closure, far).startswith(
        "drone 1 centre of mass below the ground (z = -5 m")
    v = np.zeros(robot.nq)
    v[0] = np.nan
    assert watch.check(0.5, plant, q, v, low, closure, far) == (
        "the state diverged (non-finite numbers in the plant state) at t = 0.500 s")
    assert watch.check(0.5, plant, q, np.zeros(robot.nq), positions, closure, far) == (
        "tracking lost on q2 (error 2 rad > 1 rad) at t = 0.500 s")


def test_values_are_printed_past_their_bound():
    assert _past(0.20003, 0.2) == "0.20003"
    assert _past(1.0042, 1.0) == "1.004" and _past(-0.8061, -0.8) == "-0.8061"


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_the_cheap_screen_never_hides_a_failure(name):
    """The screen (plain Python, every tick) against the full check alone, on states scattered across every bound:
    whenever the full check finds a failure, the screen lets the state through to it.
    """
    robot, plant, q, positions, closure, planned = state(name)
    rng = np.random.default_rng(7)
    bounds = dict(max_drone_speed=0.5, max_drone_rate=0.5, max_tilt=0.3, max_tracking_error=0.2, ground_tolerance=0.0)
    screened, full = Watch(robot, SimulationSettings(**bounds)), Watch(robot, SimulationSettings(**bounds))
    full._may_be_lost = lambda *args: True  # the full check on every state
    qc0, vc0 = plant.qc.copy(), plant.vc.copy()
    # smaller pushes for a robot with more drones (each one's speeds checked) or drones nearer the ground, so that
    # some states pass (the planar robots' scales: 0.4 and 0.8)
    speed_scale = 0.4 * min(1.0, 2 / robot.n_drones)
    height_scale = min(0.8, float((positions[:, 2] - robot.kind.ground_height).min()))
    fired = 0
    for _ in range(300):
        plant.qc = qc0 + rng.normal(scale=0.3, size=qc0.shape) * (rng.random(qc0.shape) < 0.3)
        plant.vc = vc0 + rng.normal(scale=speed_scale, size=vc0.shape)
        offset = rng.normal(scale=0.15, size=planned.shape)
        low = positions.copy()
        low[:, 2] += rng.normal(scale=height_scale)
        args = (0.0, plant, q, np.zeros(robot.nq), low, closure, planned + offset)
        expected = full.check(*args)
        fired += expected is not None
        assert screened.check(*args) == expected
    assert 50 < fired < 300  # the cases reach both sides of the bounds
