"""Plan a mission: :func:`plan` looks the method up in the registry and runs it.

The methods (:data:`planners.methods.METHODS`, one module each under ``planners/methods/``):

* ``"none"``: stop at every way point, the reference motion that normalises the objective (3.26);
* ``"two-step"``, ``"one-step"``: the optimisations of the thesis' chapter 3 (seed 3.2.4);
* ``"crossing"``: the prototype crossing its Type-2 singularity (seed ch. 4, :mod:`planners.crossing.solve`).

Every optimisation solves its NLP with the exact gradients of :class:`planners.problem.motion.MotionProblem`
(:func:`planners.optimisation.solving.solve_stage`), then checks the result on a dense grid
(:func:`planners.problem.report.evaluate_motion`), which is what :attr:`PlanResult.feasible` and the constraint
report are based on; a result that holds on the optimisation grid but not on the dense grid is solved
again on a finer grid (:func:`planners.optimisation.solving.solve_refining`).

The result types are defined beside the code that makes them and are importable from here too:
:class:`~planners.result.PlanResult`, :class:`~planners.result.SampledPlan`,
:class:`~planners.problem.report.MotionReport`, :class:`~planners.problem.report.ConstraintReport`,
:func:`~planners.problem.report.evaluate_motion`, :class:`~planners.optimisation.solving.StageReport`.
"""

from __future__ import annotations

import time

from planners.methods import METHODS, method_for
from planners.optimisation.solving import StageReport
from planners.options import PlanOptions
from planners.problem.report import FEASIBILITY_TOLERANCE, ConstraintReport, MotionReport, evaluate_motion
from planners.result import PlanResult, SampledPlan


def plan(mission, method: str = "two-step", *, robot=None, progress=None, samples_per_segment: int = 17,
         windows_per_segment: int = 4, max_iterations: int = 100, tolerance: float = 1e-4,
         dense_rate: float = 500.0, solver: str = "sqp", max_refinements: int = 2, stop: str = "progress",
         kkt_tolerance: float = 1e-5, curvature: str = "smoothed", polish: bool = True,
         one_step_start: str = "way-points") -> PlanResult:
    """Plan ``mission`` with ``method`` (see the module docstring).

    Every keyword after ``robot`` is the field of the same name of the :class:`~planners.options.PlanOptions`
    given to the method, where each is described in full.

    Args:
        mission: a :class:`planners.missions.mission.Mission`.
        method: a name of :data:`planners.methods.METHODS` (``"two-step"``, ``"one-step"``, ``"none"``,
            ``"crossing"``). A singularity-crossing mission is planned by ``"crossing"`` whatever
            optimisation is asked, and ``"none"`` gives its first guess
            (:func:`planners.methods.method_for`).
        robot: the robot (default ``mission.load_robot()``).
        progress: called as ``progress(stage_name, iteration, J, violation)`` after every solver iteration,
            or None.
        samples_per_segment: odd number of grid nodes per segment for J and the constraints.
        windows_per_segment: constraint windows per segment.
        max_iterations: iteration limit per NLP solve.
        tolerance: stop when an iteration improves J (normalised, about 1) by less than this.
        dense_rate: sampling rate of the final check on the dense grid [Hz].
        solver: ``"sqp"`` (the trust-region SQP) or ``"slsqp"`` (scipy's SLSQP with the same exact
            gradients).
        max_refinements: how many times at most a result that holds the optimisation grid's constraints but
            not the dense grid's is solved again on a grid twice as fine.
        stop: the SQP's stopping rule, ``"progress"`` (the merit decrease below ``tolerance``) or ``"kkt"``
            (the KKT residual at most ``kkt_tolerance``).
        kkt_tolerance: the KKT residual at which the SQP converges with ``stop="kkt"``.
        curvature: the SQP's Hessian model, ``"smoothed"``, ``"gauss-newton"`` or ``"composite"``
            (``curvature="composite", stop="kkt"``: closer to the optimum, slower).
        polish: ``"two-step"`` only: finish with a one-step solve from the two-step motion, kept when its grid
            J is lower; False gives the thesis' two-step method alone.
        one_step_start: ``"one-step"`` only: ``"way-points"`` (from the motion whose way-point derivatives
            were optimised first) or ``"stop"`` (the thesis' one-step method, from the stop motion).

    Returns:
        the :class:`PlanResult`, its ``wall_time`` the whole call's (check ``feasible``; nothing is
        raised for an infeasible result).

    Raises:
        UnknownMethodError: ``method`` is not registered. Mission errors (WorkspaceError,
            SingularityError, MissionError) come from ``mission.positions``.
    """
    function = method_for(mission, method)
    start = time.perf_counter()
    robot = robot or mission.load_robot()
    options = PlanOptions(samples_per_segment=samples_per_segment, windows_per_segment=windows_per_segment,
                          max_iterations=max_iterations, tolerance=tolerance, dense_rate=dense_rate,
                          solver=solver, max_refinements=max_refinements, progress=progress, stop=stop,
                          kkt_tolerance=kkt_tolerance, curvature=curvature, polish=polish,
                          one_step_start=one_step_start)
    result = function(mission, robot, options)
    result.wall_time = time.perf_counter() - start
    return result


__all__ = [
    "FEASIBILITY_TOLERANCE",
    "METHODS",
    "ConstraintReport",
    "MotionReport",
    "PlanOptions",
    "PlanResult",
    "SampledPlan",
    "StageReport",
    "evaluate_motion",
    "plan",
]
