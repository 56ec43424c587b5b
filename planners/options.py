"""The shape of a planning method, and the knobs every method is given.

A planning method is a function ``(mission, robot, options) -> PlanResult`` (:class:`PlanningMethod`),
registered by name in :data:`planners.methods.METHODS`; :func:`planners.optimize.plan` looks it up and
calls it with a :class:`PlanOptions`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from fpr.model.errors import PlannerArgumentError
from planners.optimisation.solving import GRID_FEASIBILITY, Grid
from planners.optimisation.sqp import SqpOptions
from planners.result import PlanResult

#: The starts of the one-step method (``PlanOptions.one_step_start``).
ONE_STEP_STARTS = ("way-points", "stop")

#: progress(stage_name, iteration, J, violation), called after every solver iteration.
Progress = Callable[[str, int, float, float], None]


@dataclass(frozen=True)
class PlanOptions:
    """What :func:`planners.optimize.plan` takes beside the mission, the method and the robot.

    Attributes:
        samples_per_segment: odd number of grid nodes per segment for J and the constraints.
        windows_per_segment: constraint windows per segment.
        max_iterations: iteration limit per NLP solve.
        tolerance: stop when an iteration improves J (about 1) by less than this.
        dense_rate: rate of the final check [Hz] (:func:`planners.problem.report.evaluate_motion`).
        solver: ``"sqp"`` (:mod:`planners.optimisation.sqp`, trust-region SQP, curvature as ``curvature`` says) or
            ``"slsqp"`` (scipy's SLSQP with the same exact gradients, quasi-Newton curvature).
        max_refinements: when a result holds every constraint on the optimisation grid but not on
            the dense grid, solve again on a grid twice as fine, at most this many times
            (:func:`planners.optimisation.solving.solve_refining`).
        progress: called as ``progress(stage_name, iteration, J, violation)`` after every solver
            iteration, or None.
        stop: the SQP's stopping rule, ``"progress"`` (the merit decrease below ``tolerance``) or
            ``"kkt"`` (the KKT residual at most ``kkt_tolerance``), see :mod:`planners.optimisation.sqp`; the KKT
            residual is reported either way (``StageReport.kkt``).
        kkt_tolerance: the KKT residual at which the SQP converges with ``stop="kkt"``.
        curvature: the SQP's Hessian model: ``"smoothed"`` (default, :mod:`planners.optimisation.curvature`:
            J_e's ``|P|`` with a wider smoothing), ``"gauss-newton"`` (the earlier default: stops about 1 % above
            the optimum) or ``"composite"`` (J_e's ``|P|`` piecewise linear in the QP, a
            damped BFGS correction: converges to the optimum in far fewer iterations, each far slower),
            see :mod:`planners.optimisation.sqp`.
        polish: ``"two-step"`` only: after both steps (when they hold the grid's constraints and the
            1-step NLP is neither step's), solve the 1-step NLP from the 2-step motion and keep it when its
            grid J is lower
            (:mod:`planners.methods.two_step`); False gives the thesis' 2-step method alone.
        one_step_start: ``"one-step"`` only: ``"way-points"`` (default: start from the motion whose
            way-point derivatives were optimised first, :func:`planners.methods.one_step.way_point_start`)
            or ``"stop"`` (the thesis: from the stop-at-every-way-point motion); :data:`ONE_STEP_STARTS`.
    """

    samples_per_segment: int = 17
    windows_per_segment: int = 4
    max_iterations: int = 100
    tolerance: float = 1e-4
    dense_rate: float = 500.0
    solver: str = "sqp"
    max_refinements: int = 2
    progress: Progress | None = field(default=None, compare=False)
    stop: str = "progress"
    kkt_tolerance: float = 1e-5
    curvature: str = "smoothed"
    polish: bool = True
    one_step_start: str = "way-points"

    def __post_init__(self):
        if self.one_step_start not in ONE_STEP_STARTS:
            raise PlannerArgumentError("one_step_start", self.one_step_start,
                                       f"one_step_start={self.one_step_start!r}: use one of "
                                       f"{', '.join(ONE_STEP_STARTS)}")

    @property
    def grid(self) -> Grid:
        """The first optimisation grid."""
        return Grid(self.samples_per_segment, self.windows_per_segment)

    @property
    def solve_arguments(self) -> dict:
        """Keyword arguments of :func:`planners.optimisation.solving.solve_stage`."""
        return {"progress": self.progress, "max_iterations": self.max_iterations, "tolerance": self.tolerance,
                "solver": self.solver, "sqp": self.sqp_options}

    @property
    def sqp_options(self) -> SqpOptions:
        """The :class:`~planners.optimisation.sqp.SqpOptions` of these options.

        A stage's accepted violation is the planner's grid feasibility
        (:data:`planners.optimisation.solving.GRID_FEASIBILITY`, what the methods and the grid refinement count as
        holding the grid; the dense check decides the plan's feasibility): along curved active rows the accepted
        steps of a converging SQP leave violations of a few 1e-7 (their linearisation's second-order error), and
        a stricter threshold kept the SQP crawling at a radius of 1e-4 for tens of iterations without changing J
        in its fourth digit.
        """
        return SqpOptions(max_iterations=self.max_iterations, tolerance=self.tolerance, stop=self.stop,
                          kkt_tolerance=self.kkt_tolerance, curvature=self.curvature,
                          second_order=self.stop == "kkt" or self.curvature == "composite",
                          feasibility=GRID_FEASIBILITY)


class PlanningMethod(Protocol):
    """A planning method: plans ``mission`` for ``robot`` with ``options``.

    It returns a :class:`~planners.result.PlanResult` whether or not the motion is feasible (check
    ``feasible``); :func:`planners.optimize.plan` sets its ``wall_time``. Mission errors
    (:class:`~fpr.model.errors.MissionError`, WorkspaceError, SingularityError) are raised.
    """

    def __call__(self, mission, robot, options: PlanOptions) -> PlanResult:
        """Plan ``mission``."""
