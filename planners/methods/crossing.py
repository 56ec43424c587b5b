"""Method ``"crossing"``: a prototype mission that crosses its Type-2 singularity once (seed ch. 4).

The mission (``cross_singularity = true``) gives a start and an end in the two assembly modes and a
total time; :func:`planners.crossing.solve.optimise_crossing` frees the crossing state, the travel times and
the via points (``mission.via_points`` per travel). :func:`first_guess` is the motion it starts from,
the reference of such a mission (what ``"none"`` gives it, :func:`planners.methods.method_for`).
"""

from __future__ import annotations

import numpy as np

from fpr.model.errors import MissionError
from planners.crossing.problem import crossing_layout
from planners.crossing.solve import CrossingOutcome, crossing_report, optimise_crossing
from planners.crossing.solve import first_guess as designed_first_guess
from planners.options import PlanOptions
from planners.result import PlanResult


def _task(mission, robot):
    """(start xi, end xi, total time [s], via points per travel) of a crossing mission."""
    if not getattr(mission, "cross_singularity", False):
        raise MissionError("cross_singularity", "the crossing method plans singularity-crossing missions only "
                           "(cross_singularity = true): use two-step, one-step or none", mission.name)
    positions = mission.positions(robot)
    return positions[0], positions[-1], float(np.sum(mission.times)), tuple(int(n) for n in mission.via_points)


def _result(mission, method: str, outcome: CrossingOutcome, robot) -> PlanResult:
    index, _ = crossing_layout(outcome.n_via)
    is_way = np.zeros(len(outcome.trajectory.points), dtype=bool)
    is_way[[0, index, -1]] = True
    return PlanResult(mission, method, float(mission.alpha), outcome.trajectory, is_way, outcome.report,
                      outcome.initial, outcome.stages, robot=robot, crossing=outcome)


def plan(mission, robot, options: PlanOptions) -> PlanResult:
    """The optimised crossing of ``mission`` (its ``crossing`` is the :class:`CrossingOutcome`; its
    ``reference`` the first guess' report). The crossing's solves use the SQP with tolerance
    :data:`planners.crossing.solve.CROSSING_TOLERANCE` whatever ``options.solver`` and ``options.tolerance`` say.

    Raises:
        MissionError: ``mission`` is not a singularity-crossing mission.
    """
    start, end, duration, n_via = _task(mission, robot)
    outcome = optimise_crossing(robot, start, end, duration, n_via, alpha=mission.alpha,
                                progress=options.progress, samples_per_segment=options.samples_per_segment,
                                windows_per_segment=options.windows_per_segment,
                                max_iterations=options.max_iterations, dense_rate=options.dense_rate,
                                max_refinements=options.max_refinements)
    return _result(mission, "crossing", outcome, robot)


def first_guess(mission, robot, options: PlanOptions) -> PlanResult:
    """The first guess of :func:`plan` (:func:`planners.crossing.solve.first_guess`), not optimised.

    Raises:
        MissionError: ``mission`` is not a singularity-crossing mission.
    """
    start, end, duration, n_via = _task(mission, robot)
    guess = designed_first_guess(robot, start, end, duration, n_via)
    report = crossing_report(robot, guess, n_via, options.dense_rate)
    return _result(mission, "first guess", CrossingOutcome("first guess", guess, n_via, report, report), robot)
