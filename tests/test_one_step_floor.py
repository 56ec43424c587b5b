"""The one-step method's floor (planners.methods.one_step): its J is never above the unpolished two-step motion's.

The floor inside the one-step is the two-step method's own unpolished motion (the same step 1 and step 2), the rule
that solves the 1-step NLP again from it fires exactly when the 1-step result is worse, and what it returns is no
worse than the floor.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planners.methods import METHODS
from planners.methods.one_step import held_to_floor, no_worse, one_step_problem
from planners.methods.way_points import WayPointTask
from planners.missions.mission import load_mission
from planners.optimisation.solving import GRID_FEASIBILITY, Grid, StageReport
from planners.options import PlanOptions

SHORT = {"max_iterations": 3, "max_refinements": 0}


@pytest.fixture(scope="module")
def square():
    mission = load_mission("square")
    robot = mission.load_robot()
    return mission, robot, WayPointTask.of(mission, robot)


def test_no_worse_puts_the_grid_constraints_first():
    held, broken = 0.5 * GRID_FEASIBILITY, 10 * GRID_FEASIBILITY
    assert no_worse(0.50, 0.0, 0.51, 0.0) and not no_worse(0.51, 0.0, 0.50, 0.0)
    assert no_worse(0.60, held, 0.50, broken)  # holding the grid's constraints beats a lower J that does not
    assert not no_worse(0.40, broken, 0.50, held)
    assert no_worse(0.60, broken, 0.50, 2 * broken)  # neither holds: the smaller violation


def test_the_floor_is_the_unpolished_two_step_motion(square):
    mission, robot, _ = square
    one = METHODS["one-step"](mission, robot, PlanOptions(**SHORT))
    two = METHODS["two-step"](mission, robot, PlanOptions(polish=False, **SHORT))
    floor = [s for s in one.stages if s.name.startswith("step 2")]
    travels = [s for s in two.stages if s.name.startswith("step 2")]
    assert [s.name for s in floor] == [s.name for s in travels] and floor
    # the same NLPs from the same points: the same results (up to the round-off of shared node derivatives)
    for mine, theirs in zip(floor, travels, strict=True):
        assert mine.iterations == theirs.iterations
        np.testing.assert_allclose(mine.J_end, theirs.J_end, rtol=1e-12)
    # and the one-step ends no worse than that motion on its NLP
    problem = one_step_problem(WayPointTask.of(mission, robot), Grid())
    mine = problem.evaluate(problem.x_of(one.trajectory.points)).J
    theirs = problem.evaluate(problem.x_of(two.trajectory.points)).J
    assert mine <= theirs


def test_held_to_floor_solves_again_from_the_floor_only_when_the_result_is_worse(square):
    mission, robot, task = square
    options = PlanOptions(**SHORT)
    grid = Grid()
    whole = one_step_problem(task, grid)
    two = METHODS["two-step"](mission, robot, PlanOptions(polish=False, **SHORT))
    floor = two.trajectory.points
    at_floor = whole.evaluate(whole.x_of(floor))
    stop = task.via_layout[0]  # the stop motion: worse than the floor
    at_stop = whole.evaluate(whole.x_of(stop))
    assert at_stop.J > at_floor.J
    worse = replace(StageReport("one-step", whole.n_x, at_stop.constraints.size), J_end=at_stop.J,
                    violation_end=at_stop.violation)
    stages = []
    points = held_to_floor(whole, stop, worse, floor, grid, options, stages)
    assert [s.name for s in stages] == ["one-step (from the two-step motion)"]
    again = whole.evaluate(whole.x_of(points))
    assert no_worse(again.J, again.violation, at_floor.J, at_floor.violation)
    assert again.J <= at_floor.J
    # a result better than the floor is returned as it is, with no further stage
    better = replace(worse, J_end=at_floor.J * (1 - 1e-9), violation_end=0.0)
    stages = []
    assert held_to_floor(whole, stop, better, floor, grid, options, stages) is stop and stages == []
