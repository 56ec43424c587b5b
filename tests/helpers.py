"""Shared test helpers."""

import math

#: The planar robots' hover poses of the controller's tests (the FPR's s0 = [0 0 5pi/4 pi/2], DESIGN.md; the
#: prototype's elbow-down pose), planning coordinates.
HOVER_POSES = {"fpr": (0.0, 0.0, 5 * math.pi / 4, math.pi / 2), "prototype": (-0.84, 1.68)}


def random_state(robot, rng, scale=1.0):
    """A random configuration near the reference pose of ``robot`` and a random velocity of size ``scale``."""
    q = 0.3 * rng.normal(size=robot.nq)
    q[robot.indices(robot.layout.chain)] += robot.kind.reference_chain
    return q, scale * rng.normal(size=robot.nq)


def near_hover(robot, seed):
    """A minimal state near hover at the reference pose, with a random velocity, and a rotor command 5 % off
    hover: (q, v, hover rotor speeds w, command, the rng after these draws).
    """
    import numpy as np

    from fpr.sim.plant import hover_configuration, hover_speeds

    rng = np.random.default_rng(seed)
    q = hover_configuration(robot, robot.kind.reference_chain)
    w = hover_speeds(robot, q)
    q = q + 0.05 * rng.normal(size=robot.nq)
    v = 0.5 * rng.normal(size=robot.nq)
    return q, v, w, w * (1 + 0.05 * rng.normal(size=w.shape)), rng


def hover_thrusts(robot):
    """The reference pose's hover configuration and each drone's hover thrust [N]: (q0, thrusts (n_d,))."""
    import numpy as np

    from fpr.sim.plant import hover_configuration, hover_speeds

    q0 = hover_configuration(robot, robot.kind.reference_chain)
    w = hover_speeds(robot, q0)
    return q0, np.array([rotor.wrench(wi**2)[0] for rotor, wi in zip(robot.rotors, w, strict=True)])


def saturating_factor(robot, hover, factor=3.0):
    """A factor on the hover thrusts ``hover`` (n_d,) past every drone's full thrust: ``factor`` (3, past it on the
    planar robots), or 1.1 times the full thrust over the least hover thrust where ``factor`` is not enough (the
    spatial FPR's drones hover at a third of theirs).
    """
    full = 4 * robot.rotor_constants.thrust_coefficient * robot.rotor_constants.max_speed**2
    return max(factor, 1.1 * full / float(min(hover)))


# A one-travel prototype mission short enough for campaign tests (tests/test_campaign*.py).
SHORT_HOP = """description = "a short hop of the prototype's drone, for tests"
robot = "prototype"
space = "task"
arm = "down"
way_points = [[1.2, -0.45], [1.2, -0.3]]
times = [1.0]
via_points = 0
alpha = 0.5
"""


def planned_hover(name):
    """The robot ``name`` at rest at its :data:`HOVER_POSES` pose as the planner sees it: (robot, configuration
    (rolls from the plan), the plan's inputs, the controller's reference).
    """
    import numpy as np

    import fpr
    from controllers.ctc import Reference
    from fpr.model.inverse_dynamics import inverse_dynamics

    robot = fpr.load(name)
    s0 = np.array(HOVER_POSES[name])
    motion = np.zeros((5, 1, s0.size))
    motion[0, 0] = s0
    inputs = inverse_dynamics(robot, motion)
    q = inputs.full_state(robot)[0][0]
    reference = Reference(motion[:, 0], inputs.roll_rate[0], inputs.roll_acceleration[0])
    return robot, q, inputs, reference


def turned(vector, angle):
    """The planar ``vector`` (y, z) turned by ``angle`` [rad]."""
    import numpy as np

    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * vector[0] - s * vector[1], s * vector[0] + c * vector[1]])


def gust_flight(name):
    """The built-in mission ``name`` planned by the two-step method, and a flight of it that a campaign's gust events
    run on (1 s held after the plan): (mission, robot, :class:`fpr.robustness.outcomes.Flight`).
    """
    from fpr.robustness.events import GustFamily
    from fpr.robustness.outcomes import EventSetup, Flight
    from planners.missions.mission import load_mission
    from planners.optimize import plan

    mission = load_mission(name)
    result = plan(mission, "two-step")
    robot = result.robot
    flight = Flight(robot.name, (), tuple(robot.layout.chain), result.trajectory, 1.0, None, mission,
                    result.report.constraints, EventSetup("gust", GustFamily(), 0))
    return mission, robot, flight
