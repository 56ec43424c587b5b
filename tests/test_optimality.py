"""The planner's optimality reporting and the polished two-step method, on the square mission.

The two-step method's polish is a 1-step solve from the 2-step motion, kept only when its grid J is
lower: the polished plan can be no worse on the grid than the thesis' two-step plan, and like every
plan it is checked on the dense grid. The KKT residual of every stage is what
:func:`planners.optimisation.sqp.kkt_residual` gives for the stage's last point: finite, >= 0, in ``plan.json``.
"""

from __future__ import annotations

import json
import math

import pytest

from planners.methods import METHODS
from planners.methods.one_step import one_step_problem
from planners.methods.way_points import WayPointTask
from planners.missions.mission import load_mission
from planners.optimisation.solving import Grid
from planners.options import PlanOptions


@pytest.fixture(scope="module")
def square_two_step():
    mission = load_mission("square")
    robot = mission.load_robot()
    polished = METHODS["two-step"](mission, robot, PlanOptions())
    thesis = METHODS["two-step"](mission, robot, PlanOptions(polish=False))
    return mission, robot, polished, thesis


def test_polish_is_a_last_stage_and_never_worse_on_the_grid(square_two_step):
    mission, robot, polished, thesis = square_two_step
    assert [s.name for s in polished.stages][:-1] == [s.name for s in thesis.stages]
    assert polished.stages[-1].name == "polish (one-step)"
    whole = one_step_problem(WayPointTask.of(mission, robot), Grid())
    grid_j = [whole.evaluate(whole.x_of(r.trajectory.points)).J for r in (polished, thesis)]
    assert grid_j[0] <= grid_j[1]
    assert polished.feasible and thesis.feasible


def test_every_stage_reports_its_kkt_residual_in_the_summary(square_two_step):
    _, robot, polished, _ = square_two_step
    document = json.loads(json.dumps(polished.summary(robot)))
    for stage in document["stages"]:
        parts = [stage[k] for k in ("kkt_stationarity", "kkt_complementarity", "kkt_feasibility")]
        assert all(math.isfinite(v) and v >= 0 for v in parts)
        assert stage["kkt"] == max(parts)
        assert stage["kkt_feasibility"] == pytest.approx(stage["violation_end"], abs=1e-15)


def test_slsqp_stages_report_a_kkt_residual_too():
    mission = load_mission("study")
    result = METHODS["one-step"](mission, mission.load_robot(), PlanOptions(solver="slsqp", max_iterations=5))
    assert all(math.isfinite(s.kkt) and s.kkt >= 0 for s in result.stages)
