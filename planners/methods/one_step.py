"""Method ``"one-step"``: the derivatives 1..4 at the interior way points (S_d1, 3.20) and every entry
of the via points (S_d2, 3.22) optimised at once (seed 3.2.4).

The thesis starts from the stop-at-every-way-point motion (``PlanOptions.one_step_start="stop"``). By
default (``"way-points"``) the solve starts from the motion whose way-point derivatives were optimised
first, alone (:func:`way_point_start`, a stage of its own): on the prototype tour the start from the
stop motion ends in a local minimum 0.7 % above the best J known.

The first and last way points keep zero derivatives (the robot starts and ends at rest). The NLP is
solved by :func:`planners.optimisation.solving.solve_stage`, again on finer grids when the dense check asks for it
(:func:`planners.optimisation.solving.solve_refining`).
"""

from __future__ import annotations

import numpy as np

from planners.methods.way_points import WayPointTask
from planners.optimisation.solving import Grid, solve_refining, solve_stage
from planners.options import PlanOptions
from planners.problem.motion import MotionProblem
from planners.problem.report import evaluate_motion
from planners.result import PlanResult
from planners.trajectory.polynomial import PiecewisePolynomial


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
        stages = []
        if previous is not None:
            start = previous.points
        elif options.one_step_start == "way-points" and len(task.way_times) > 1:
            start, stage = way_point_start(task, grid, options)
            stages.append(stage)
        else:
            start = whole.points
        x, stage = solve_stage(whole, whole.x_of(start), "one-step" + grid.suffix, **options.solve_arguments)
        return PiecewisePolynomial(whole.points_of(x), whole.durations), stages + [stage]

    trajectory, report, stages = solve_refining(
        attempt, lambda motion: evaluate_motion(robot, motion, options.dense_rate), options.grid,
        options.max_refinements)
    return task.result("one-step", trajectory, is_way, report, reference, stages)


def way_point_start(task: WayPointTask, grid: Grid, options: PlanOptions):
    """The start of ``one_step_start="way-points"``: the way points' derivatives optimised first.

    The motion through the way points alone, their derivatives 1..4 free (the two-step method's step 1,
    :func:`planners.methods.two_step.step1_problem`: half the grid nodes, a fraction of the variables),
    cut at the via times. Returns (points of the 1-step layout, the stage ``"start (way points)"``).
    From the stop motion the prototype tour's 1-step solve ends in a local minimum 0.7 % above the best
    J known; from this start, at the best.
    """
    free = np.zeros(task.stop.points.shape, dtype=bool)
    free[1:-1, 1:] = True
    problem = task.problem(task.stop.points, task.way_times, free, task.normalisation(grid), grid)
    x, stage = solve_stage(problem, problem.x_of(task.stop.points), "start (way points)" + grid.suffix,
                           **options.solve_arguments)
    points, _, _ = task.with_via_points(PiecewisePolynomial(problem.points_of(x), task.way_times))
    return points, stage
