"""The thesis-like take-off of the simulation (SimulationSettings.takeoff, seed 3.3.3, Fig. 3.50).

From rest the drone starts level while its plan asks for a roll (it must pull the chain): the controller
rolls it over in a few tenths of a second, so J_phi jumps at the start, as the thesis saw; starting on the
plan it does not. Checked on the prototype tour's take-off travel.
"""

from __future__ import annotations

import numpy as np
import pytest

from fpr.sim.closed_loop import SimulationSettings, simulate
from fpr.views.figures import simulated_indices
from planners.missions.mission import load_mission
from planners.optimize import plan


@pytest.fixture(scope="module")
def takeoff():
    mission = load_mission("prototype-tour")
    first = mission.replace(way_points=mission.way_points[:2], times=mission.times[:1])
    return plan(first, "two-step")


def test_takeoff_starts_level_at_rest_and_makes_j_phi_jump(takeoff):
    robot = takeoff.robot
    on_plan = simulate(takeoff, SimulationSettings(hold=0.0))
    from_rest = simulate(takeoff, SimulationSettings(hold=0.0, takeoff=True))
    roll = robot.index[robot.layout.rolls[0]]
    planned_roll = takeoff.report.inputs.roll[0, 0]
    assert abs(planned_roll) > 0.05  # the plan starts rolled: the drone pulls the chain
    assert from_rest.q[0, roll] == 0.0 and on_plan.q[0, roll] == pytest.approx(planned_roll, abs=1e-9)
    assert np.allclose(from_rest.v[0], 0.0) and np.ptp(from_rest.speed[0, 0]) == pytest.approx(0.0, abs=1e-9)
    # the same total thrust at the start: c_T sum w^2 equal
    assert np.sum(from_rest.speed[0] ** 2) == pytest.approx(np.sum(on_plan.speed[0] ** 2), rel=1e-9)
    window = 0.5
    jump = {name: float(np.interp(window, log.t, simulated_indices(robot, log)[1]))
            for name, log in (("rest", from_rest), ("plan", on_plan))}
    # rolling by |phi_0| in ~0.2 s costs at least phi_0^2 / 0.2 s of J_phi (Cauchy-Schwarz): far above the plan's
    assert jump["rest"] > planned_roll**2 / 0.5 and jump["rest"] > 5 * jump["plan"]
    assert from_rest.failure is None and max(np.abs(from_rest.tracking_error[-1])) < 0.01
