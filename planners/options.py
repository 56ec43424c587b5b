"""The shape of a planning method, and the knobs every method is given.

A planning method is a function ``(mission, robot, options) -> PlanResult`` (:class:`PlanningMethod`),
registered by name in :data:`planners.methods.METHODS`; :func:`planners.optimize.plan` looks it up and
calls it with a :class:`PlanOptions`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from planners.result import PlanResult
from planners.solving import Grid

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
        dense_rate: rate of the final check [Hz] (:func:`planners.report.evaluate_motion`).
        solver: ``"sqp"`` (:mod:`planners.sqp`, Gauss-Newton trust-region SQP) or ``"slsqp"`` (scipy's
            SLSQP with the same exact gradients, quasi-Newton curvature).
        max_refinements: when a result holds every constraint on the optimisation grid but not on
            the dense grid, solve again on a grid twice as fine, at most this many times
            (:func:`planners.solving.solve_refining`).
        progress: called as ``progress(stage_name, iteration, J, violation)`` after every solver
            iteration, or None.
    """

    samples_per_segment: int = 17
    windows_per_segment: int = 4
    max_iterations: int = 100
    tolerance: float = 1e-4
    dense_rate: float = 500.0
    solver: str = "sqp"
    max_refinements: int = 2
    progress: Progress | None = field(default=None, compare=False)

    @property
    def grid(self) -> Grid:
        """The first optimisation grid."""
        return Grid(self.samples_per_segment, self.windows_per_segment)

    @property
    def solve_arguments(self) -> dict:
        """Keyword arguments of :func:`planners.solving.solve_stage`."""
        return {"progress": self.progress, "max_iterations": self.max_iterations, "tolerance": self.tolerance,
                "solver": self.solver}


class PlanningMethod(Protocol):
    """A planning method: plans ``mission`` for ``robot`` with ``options``.

    It returns a :class:`~planners.result.PlanResult` whether or not the motion is feasible (check
    ``feasible``); :func:`planners.optimize.plan` sets its ``wall_time``. Mission errors
    (:class:`~fpr.model.errors.MissionError`, WorkspaceError, SingularityError) are raised.
    """

    def __call__(self, mission, robot, options: PlanOptions) -> PlanResult:
        """Plan ``mission``."""
