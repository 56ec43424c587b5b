"""Method ``"one-step"``: the derivatives 1..4 at the interior way points (S_d1, 3.20) and every entry
of the via points (S_d2, 3.22) optimised at once, from the stop-at-every-way-point motion (seed 3.2.4).

The first and last way points keep zero derivatives (the robot starts and ends at rest). The NLP is
solved by :func:`planners.solving.solve_stage`, again on finer grids when the dense check asks for it
(:func:`planners.solving.solve_refining`).
"""

from __future__ import annotations

import numpy as np

from planners.methods.way_points import WayPointTask
from planners.options import PlanOptions
from planners.polynomial import PiecewisePolynomial
from planners.problem import MotionProblem
from planners.report import evaluate_motion
from planners.result import PlanResult
from planners.solving import Grid, solve_refining, solve_stage


def one_step_problem(task: WayPointTask, grid: Grid, normalisation=None) -> MotionProblem:
    """The 1-step NLP of ``task`` on ``grid``: its template is the stop motion cut at the via times
    (:attr:`WayPointTask.via_layout`), which is also its start.

    Args:
        task: the mission.
        grid: the optimisation grid.
        normalisation: (J_e0, J_phi0); default :meth:`WayPointTask.normalisation` on ``grid``.
    """
    points, durations, is_way = task.via_layout
    free = np.zeros(points.shape, dtype=bool)
    free[~is_way] = True
    free[np.flatnonzero(is_way)[1:-1], 1:] = True
    normalisation = task.normalisation(grid) if normalisation is None else normalisation
    return task.problem(points, durations, free, normalisation, grid)


def plan(mission, robot, options: PlanOptions) -> PlanResult:
    """``mission`` planned by the 1-step optimisation (see the module docstring)."""
    task = WayPointTask.of(mission, robot)
    reference = evaluate_motion(robot, task.stop, options.dense_rate)
    is_way = task.via_layout[2]

    def attempt(grid: Grid, previous: PiecewisePolynomial | None):
        whole = one_step_problem(task, grid)
        start = whole.points if previous is None else previous.points
        x, stage = solve_stage(whole, whole.x_of(start), "one-step" + grid.suffix, **options.solve_arguments)
        return PiecewisePolynomial(whole.points_of(x), whole.durations), [stage]

    trajectory, report, stages = solve_refining(
        attempt, lambda motion: evaluate_motion(robot, motion, options.dense_rate), options.grid,
        options.max_refinements)
    return task.result("one-step", trajectory, is_way, report, reference, stages)
