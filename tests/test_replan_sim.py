"""Events in the closed loop (fpr/sim/replanning.py): the gust's force, checked by the robot's momentum."""

import numpy as np
import pinocchio as pin
import pytest

from fpr.robots import load
from fpr.sim.replanning import ForcedPlant
from planners.missions.events import GustEvent


@pytest.mark.parametrize("body", ["end_effector", "drone_1", "drone_2"])
def test_a_gust_changes_the_centre_of_mass_acceleration_by_force_over_mass(body):
    """Newton for the whole (free-flying) FPR: an external force F adds F / m_total to its CoM acceleration.

    The chain's internal forces cancel wherever F acts: an independent check of the J^T F of the plant.
    """
    robot = load("fpr")
    rng = np.random.default_rng(1)
    q = robot.configuration(**dict(zip(robot.layout.chain, robot.kind.reference_chain, strict=True)))
    force = np.array([0.5, -3.0, 2.0])
    plant = ForcedPlant.with_events(
        (GustEvent(0.0, tuple(force), 1.0, body),),
        robot,
        q,
        rng.normal(scale=0.2, size=robot.nq),
        np.full((robot.n_drones, 4), 500.0),
    )
    model, data = plant.closed.model, plant.closed.data

    def com_acceleration(tip, drones):
        plant._tip_force = tip
        a = plant.acceleration(wind=drones)
        pin.centerOfMass(model, data, plant.qc, plant.vc, a)
        return data.acom[0].copy()

    base = com_acceleration(None, None)
    assert plant.tip_joint > 0
    if body == "end_effector":
        pushed = com_acceleration(force, None)
    else:
        drones = np.zeros((robot.n_drones, 3))
        drones[int(body[-1]) - 1] = force
        pushed = com_acceleration(None, drones)
    mass = sum(inertia.mass for inertia in model.inertias)
    np.testing.assert_allclose(pushed - base, force / mass, atol=1e-6 * np.abs(force).max() / mass + 1e-9)


def test_the_end_effector_gust_acts_at_the_task_point():
    """The joint found for an end-effector gust sits where the minimal model puts the end-effector."""
    robot = load("fpr")
    q = robot.configuration(y=0.3, z=0.2, phi=4.0, q21=1.2)
    plant = ForcedPlant.with_events((), robot, q)
    pin.forwardKinematics(plant.closed.model, plant.closed.data, plant.qc)
    np.testing.assert_allclose(plant.closed.data.oMi[plant.tip_joint].translation[1:], [0.3, 0.2], atol=1e-9)


def test_the_gust_mission_saturates_without_replanning_and_not_with_it():
    """The built-in gust (a sustained 6 N wind) in the closed loop, the controller told the wind (fed forward)
    in both runs. Without replanning it tracks the offline plan, which in that wind needs rotor speeds below
    0: the rotors saturate and the robot is lost. With the replanner told the wind (default deadline; the
    wind replans get ``wind_deadline``), no rotor saturates, the ground keeps its design margin, no physical
    limit breaks, and the executed plan holds every constraint flown in the wind (documentation:
    guides/replanning).
    """
    from fpr.cli.replanning import executed
    from fpr.sim.closed_loop import SimulationSettings, simulate
    from fpr.sim.margins import broken, closed_loop_margins, eaten
    from fpr.sim.replanning import InFlight, TriggerSettings
    from planners.missions.mission import load_mission
    from planners.optimize import plan
    from planners.replanning.replanner import Replanner, ReplanOptions

    mission = load_mission("gust")
    result = plan(mission, "two-step")
    robot = result.robot
    settings = SimulationSettings()
    chain = [robot.index[c] for c in robot.layout.chain]

    without = InFlight(mission, None, TriggerSettings(), settings.controller, chain, robot)  # no replanner
    assert without.known_gusts() == tuple(mission.events)
    alone = simulate(result, settings, in_flight=without)
    assert alone.summary()["saturated_ticks"] > 50 and alone.failure is not None

    replanner = Replanner(result, ReplanOptions())
    hooks = InFlight(mission, replanner, TriggerSettings(), settings.controller, chain, robot)
    log = simulate(result, settings, in_flight=hooks)
    done = executed(result, hooks)
    # the gust's start (through way point 2), then 1 s before way points 2 and 3 (through the next travel)
    assert [(r.time, r.used) for r in replanner.replans] == [(2.0, True), (5.0, True), (8.0, True)]
    assert done.report.feasible  # in the wind
    assert log.failure is None and log.summary()["saturated_ticks"] == 0
    margins = closed_loop_margins(done, log)
    kept = [m.name for m in eaten(margins)]
    assert not any(name.startswith("ground") for name in kept), kept
    assert not broken(margins), [m.name for m in broken(margins)]
