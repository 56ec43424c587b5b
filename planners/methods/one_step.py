"""Method ``"one-step"``: the derivatives 1..4 at the interior way points (S_d1, 3.20) and every entry
of the via points (S_d2, 3.22) optimised at once (seed 3.2.4).

The thesis starts from the stop-at-every-way-point motion (``PlanOptions.one_step_start="stop"``). By
default (``"way-points"``) the solve starts from the motion whose way-point derivatives were optimised
first, alone (:func:`way_point_start`, a stage of its own): on the prototype tour the start from the
stop motion ends in a local minimum 0.7 % above the best J known.

**Never above the two-step motion.** The start stage is the two-step method's step 1, so with the default start
the method also makes the unpolished two-step motion: step 2, the via points travel by travel from the start
(:func:`planners.methods.way_points.solve_travels`, a few per cent of the plan's time: each travel is a small NLP
that converges in one or two iterations). The 1-step NLP is a different problem whose local minima need not
contain the two-step motion's basin: a 1-step solve can end above it (a random mission of the prototype did, by
0.17 %). When it does (:func:`held_to_floor`), the 1-step NLP is solved again from the two-step motion and the
better is kept, so the method's grid J is never above the unpolished two-step motion's, by construction (no
threshold: any excess triggers it). With ``one_step_start="stop"`` (the thesis) there is no such floor.

The first and last way points keep zero derivatives (the robot starts and ends at rest). The NLP is
solved by :func:`planners.optimisation.solving.solve_stage`, again on finer grids when the dense check asks for it
(:func:`planners.optimisation.solving.solve_refining`; a refined attempt starts from the motion before it and
has no floor).
"""

from __future__ import annotations

import logging

import numpy as np

from planners.methods.way_points import WayPointTask, solve_travels
from planners.optimisation.solving import GRID_FEASIBILITY, Grid, solve_refining, solve_stage
from planners.optimisation.sqp import prepare
from planners.options import PlanOptions
from planners.problem.motion import MotionProblem, NodeDerivatives
from planners.problem.report import evaluate_motion
from planners.result import PlanResult
from planners.trajectory.polynomial import PiecewisePolynomial

logger = logging.getLogger(__name__)


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
    # one travel: step 2 is the 1-step NLP already; no via points: step 1 is
    whole_differs = len(task.way_times) > 1 and task.n_via.sum() > 0

    def attempt(grid: Grid, previous: PiecewisePolynomial | None):
        whole = one_step_problem(task, grid)
        stages = []
        floor = None
        if previous is not None:
            start = previous.points
        elif options.one_step_start == "way-points" and len(task.way_times) > 1:
            start, stage = way_point_start(task, grid, options)
            stages.append(stage)
            if whole_differs:  # the two-step motion: the start stage is its step 1
                # the 1-step solve's first evaluation (at the start, with derivatives) first: the travels' first
                # evaluations, at the same segments, take its nodes' numbers (NodeDerivatives)
                shared = NodeDerivatives()
                whole.share_node_derivatives(shared)
                if options.solver == "sqp":
                    prepare(whole, options.sqp_options)
                    whole.evaluate(whole.x_of(start), True)
                floor, travels = solve_travels(task, grid, start, whole.durations, task.normalisation(grid),
                                               options.solve_arguments, shared)
                stages += travels
        else:
            start = whole.points
        x, stage = solve_stage(whole, whole.x_of(start), "one-step" + grid.suffix, **options.solve_arguments)
        stages.append(stage)
        points = whole.points_of(x)
        if floor is not None:
            points = held_to_floor(whole, points, stage, floor, grid, options, stages)
        return PiecewisePolynomial(points, whole.durations), stages

    trajectory, report, stages = solve_refining(
        attempt, lambda motion: evaluate_motion(robot, motion, options.dense_rate), options.grid,
        options.max_refinements)
    return task.result("one-step", trajectory, is_way, report, reference, stages)


def no_worse(J: float, violation: float, J_other: float, violation_other: float) -> bool:
    """Whether a motion (grid J, largest scaled grid violation) is at least as good as another on the same NLP.

    Holding the grid's constraints (:data:`~planners.optimisation.solving.GRID_FEASIBILITY`) comes first; of two
    motions that hold them, the lower J is better; of two that do not, the smaller violation.
    """
    holds, other_holds = violation <= GRID_FEASIBILITY, violation_other <= GRID_FEASIBILITY
    if holds != other_holds:
        return holds
    return J <= J_other if holds else violation <= violation_other


def held_to_floor(whole: MotionProblem, points, stage, floor, grid: Grid, options: PlanOptions, stages: list):
    """The 1-step result ``points`` (its stage ``stage``), or better when the two-step motion ``floor`` beats it.

    ``floor``: the unpolished two-step motion (step 1, which is the start stage, then step 2 travel by travel,
    :func:`planners.methods.way_points.solve_travels`). When the 1-step solve ended in a worse local minimum
    (:func:`no_worse` on the 1-step NLP ``whole``), the 1-step NLP is solved again from ``floor`` (the stage
    ``"one-step (from the two-step motion)"``, appended to ``stages``) and the better of that result and
    ``floor`` is returned: the method's J is never above the two-step motion's.
    """
    ev = whole.evaluate(whole.x_of(floor))
    if no_worse(stage.J_end, stage.violation_end, ev.J, ev.violation):
        return points
    logger.info("one-step: J %.6g (violation %.2g) above the two-step motion's %.6g (%.2g): solving again from it",
                stage.J_end, stage.violation_end, ev.J, ev.violation)
    x, again = solve_stage(whole, whole.x_of(floor), "one-step (from the two-step motion)" + grid.suffix,
                           **options.solve_arguments)
    stages.append(again)
    return whole.points_of(x) if no_worse(again.J_end, again.violation_end, ev.J, ev.violation) else floor


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
