"""Every figure of a planned (and possibly simulated) motion at once (:func:`figure_set`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fpr.model.errors import FigureError
from fpr.sim.margins import thrust_floor
from fpr.views.figures.planning import PLAN_FIGURES, plan_figures
from fpr.views.figures.sampled import _traces
from fpr.views.figures.simulation import SIMULATION_FIGURES, _simulated, simulation_figures
from planners.optimize import SampledPlan

#: File names written by :func:`figure_set` with a simulation log, in order.
FIGURE_SET = PLAN_FIGURES + SIMULATION_FIGURES

#: Titles of a singularity crossing's figures: the thesis' chapter 4 has no figure of a successful crossing; its
#: failed approaches are Fig. 4.2-4.9.
CROSSING_FIGURES = "Singularity crossing (thesis ch. 4; cf. Fig. 4.2-4.9)"


def _as_sampled(what: str, plan, robot, rate: float) -> SampledPlan:
    """A :class:`planners.optimize.PlanResult` sampled at ``rate``, or a sampled plan as it is."""
    if hasattr(plan, "trajectory") and callable(getattr(plan, "sampled", None)):
        return plan.sampled(rate, robot=robot)
    if hasattr(plan, "motion"):
        return plan
    raise FigureError(what, plan, f"{what} is a {type(plan).__name__}: pass a planners.optimize.PlanResult "
                                  "or a sampled plan (PlanResult.sampled(rate))")


def figure_set(out_dir: str | Path, plan, log=None, reference=None, *, robot=None,
               rate: float = 200.0, figure_numbers=None) -> dict[str, Path]:
    """Write every figure of the thesis that applies to a planned (and possibly simulated) motion.

    FPR: Fig. 3.11-3.18 and the rotor limits of eq. 3.48 (:data:`PLAN_FIGURES`), and with ``log``
    Fig. 3.19-3.32 (:data:`SIMULATION_FIGURES`). Prototype: Fig. 3.36-3.41, and with ``log``
    Fig. 3.42-3.51. Calls :func:`plan_figures`, then :func:`simulation_figures` with the plan.

    Example::

        result = plan(load_mission("square"), "two-step")
        paths = figure_set("out", result, simulate(result), reference=plan(load_mission("square"), "none"))
        paths["sim_rotor_forces"]  # Path("out/sim_rotor_forces.png")

    Args:
        out_dir: output folder (created if needed).
        plan: a :class:`planners.optimize.PlanResult` (sampled at ``rate``) or a sampled plan.
        log: a :class:`fpr.sim.closed_loop.SimulationLog` of ``plan``, or None for the planning figures only.
        reference: the motion to compare with, typically ``plan(mission, "none")`` (stop at every
            way point): a PlanResult or a sampled plan, or None.
        robot: the robot; default ``plan.robot`` (required for a sampled plan).
        rate: sampling rate of PlanResults [Hz].
        figure_numbers: the thesis figure(s) in the titles instead of the robot's (see
            :func:`fpr.views.figures.robot_info.figure_context`); a singularity crossing (a PlanResult with
            ``crossing``) gets :data:`CROSSING_FIGURES`, the bounds it crosses are left out and its thrust floor drawn.

    Returns:
        name -> path of every written PNG file, in the order of :data:`FIGURE_SET` (the ``sim_``
        ones only with a log).

    Raises:
        FigureError: no robot, a rate that is not positive, or inputs that do not fit the robot
            (nothing is written then).
        ShapeError: a plan or log array whose shape does not fit the robot.
    """
    robot = robot if robot is not None else getattr(plan, "robot", None)
    if robot is None:
        raise FigureError("robot", None, "no robot: pass robot=fpr.load(...) with a sampled plan (a "
                                         "PlanResult carries its own)")
    if not (np.isfinite(rate) and rate > 0):
        raise FigureError("rate", rate, f"rate={rate!r}: give a positive sampling rate [Hz]")
    sampled = _as_sampled("plan", plan, robot, rate)
    sampled_reference = None if reference is None else _as_sampled("reference", reference, robot, rate)
    _traces(robot, sampled, sampled_reference)  # check everything before writing anything
    if log is not None:
        _simulated(robot, log)
    crossing = getattr(plan, "crossing", None) is not None
    if crossing and figure_numbers is None:
        figure_numbers = CROSSING_FIGURES
    floor = thrust_floor(plan.report) if hasattr(plan, "report") else None
    paths = dict(zip(PLAN_FIGURES, plan_figures(out_dir, robot, sampled, sampled_reference,
                                                figure_numbers=figure_numbers, crossing=crossing, min_thrust=floor),
                     strict=True))
    if log is not None:
        paths.update(zip(SIMULATION_FIGURES, simulation_figures(out_dir, robot, log, sampled,
                                                                figure_numbers=figure_numbers, crossing=crossing),
                         strict=True))
    return paths
