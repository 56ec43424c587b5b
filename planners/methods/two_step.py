"""Method ``"two-step"`` (seed 3.2.4): way points first, then the via points travel by travel.

Step 1 optimises the derivatives 1..4 at the interior way points (S_d1, 3.20) of the motion through
the way points only (:func:`step1_problem`); step 2 then optimises, travel by travel, the via points
(S_d2, 3.22) between the way points fixed by step 1 (:func:`travel_problem`). Each step-2 problem
starts from the step-1 motion itself (its value and derivatives at the via times), so step 2 never
ends worse than step 1. The first and last way points keep zero derivatives (the robot starts and
ends at rest). A motion that fails the dense check but holds on the grid is solved again on a finer grid
(:func:`planners.optimisation.solving.solve_refining`): by the polish alone, from that motion, when there is
one (below), else both steps.

With ``PlanOptions.polish`` (the default), when steps 1 and 2 hold the grid's constraints, there is
more than one travel (with one, step 2 is the 1-step NLP already) and there are via points (without,
step 1 is), a third
stage ``"polish (one-step)"`` solves the 1-step NLP (every entry at once,
:func:`planners.methods.one_step.one_step_problem`) from the 2-step motion, and keeps its result when
its grid J is lower and its grid violation no larger. Steps 1 and 2 each optimise part of
the entries with the rest fixed, so the 2-step motion is in general not a stationary point of the
whole problem (the prototype tour ends 7 % above it); the polish makes it one, at the price of a
1-step solve. Without it the method guarantees only that step 2 is no worse than step 1.
"""

from __future__ import annotations

import numpy as np

from planners.methods.one_step import one_step_problem
from planners.methods.way_points import WayPointTask, solve_travels, step1_problem, travel_problem
from planners.optimisation.solving import GRID_FEASIBILITY, Grid, solve_refining, solve_stage
from planners.options import PlanOptions
from planners.problem.motion import NodeDerivatives
from planners.problem.report import evaluate_motion
from planners.result import PlanResult
from planners.trajectory.polynomial import PiecewisePolynomial


def plan(mission, robot, options: PlanOptions) -> PlanResult:
    """``mission`` planned by the 2-step optimisation (see the module docstring)."""
    task = WayPointTask.of(mission, robot)
    reference = evaluate_motion(robot, task.stop, options.dense_rate)
    is_way = task.via_layout[2]

    # one travel: step 2 is the 1-step NLP already; no via points: step 1 is
    whole_differs = len(task.way_times) > 1 and task.n_via.sum() > 0

    def attempt(grid: Grid, previous: PiecewisePolynomial | None):
        normalisation = task.normalisation(grid)
        if previous is not None and options.polish and whole_differs:  # a refinement: the polish alone
            stages = []
            points = _polish(task, grid, previous.points, stages, options, normalisation, refining=True)
            return PiecewisePolynomial(points, task.via_layout[1]), stages
        shared = NodeDerivatives()  # the travels' last evaluations, where the polish starts
        step1 = step1_problem(task, grid, normalisation)
        start = task.stop.points if previous is None else previous.points[_way_mask(task, previous)]
        x, stage = solve_stage(step1, step1.x_of(start), "step 1" + grid.suffix, **options.solve_arguments)
        stages = [stage]
        points, durations, _ = task.with_via_points(PiecewisePolynomial(step1.points_of(x), task.way_times))
        points, travels = solve_travels(task, grid, points, durations, normalisation, options.solve_arguments, shared,
                                        None if previous is None else previous.points)
        stages += travels
        if options.polish and whole_differs and all(st.violation_end <= GRID_FEASIBILITY for st in stages):
            points = _polish(task, grid, points, stages, options, normalisation, shared)
        return PiecewisePolynomial(points, durations), stages

    trajectory, report, stages = solve_refining(
        attempt, lambda motion: evaluate_motion(robot, motion, options.dense_rate), options.grid,
        options.max_refinements)
    return task.result("two-step", trajectory, is_way, report, reference, stages)


def _polish(task: WayPointTask, grid: Grid, points, stages: list, options: PlanOptions, normalisation,
            shared: NodeDerivatives | None = None, refining: bool = False):
    """The 1-step NLP solved from the 2-step ``points`` (appends its stage); the better points.

    ``normalisation``: the steps' (J_e0, J_phi0) on ``grid`` (:meth:`WayPointTask.normalisation`, not
    computed again); ``shared``: the travels' :class:`~planners.problem.motion.NodeDerivatives` (its first evaluation
    with derivatives, at the points where the travels ended, takes their numbers), or None. ``refining``: the
    points are a finished plan that failed the dense check, solved again on a finer grid: the result is kept
    when it holds this grid's constraints, whatever its J.
    """
    whole = one_step_problem(task, grid, normalisation)
    if shared is not None:
        whole.share_node_derivatives(shared)
    x0 = whole.x_of(points)
    before = whole.evaluate(x0)
    x, stage = solve_stage(whole, x0, "polish (one-step)" + grid.suffix, **options.solve_arguments)
    stages.append(stage)
    if refining and stage.violation_end <= GRID_FEASIBILITY < before.violation:
        return whole.points_of(x)
    if stage.J_end <= before.J and stage.violation_end <= max(before.violation, GRID_FEASIBILITY):
        return whole.points_of(x)
    return points


def _way_mask(task: WayPointTask, motion: PiecewisePolynomial) -> np.ndarray:
    """Which points of ``motion`` are way points: all, or those of the via-point layout."""
    if len(motion.points) != len(task.stop.points):
        return task.via_layout[2]
    return np.ones(len(motion.points), dtype=bool)


__all__ = ["plan", "step1_problem", "travel_problem"]
