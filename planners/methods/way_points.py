"""What the way-point methods share (seed 3.2.4): the mission's travels, the stop-at-every-way-point
motion, and the NLPs built on them.

A way-point mission goes through k+1 way points in k travels, each with n_vp via points. Its
*stop-at-every-way-point* motion (every derivative 1..4 zero at every way point) is the reference of
the objective (J_e0, J_phi0 of 3.26) and the first guess of the optimisations. A :class:`WayPointTask`
holds these and builds the :class:`~planners.problem.motion.MotionProblem` s of the methods.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from planners.optimisation.solving import Grid, solve_stage
from planners.problem.motion import MotionProblem, NodeDerivatives
from planners.problem.report import MotionReport
from planners.result import PlanResult, normalisation
from planners.trajectory.polynomial import PiecewisePolynomial, stop_points, with_via_points


@dataclass(frozen=True, eq=False)
class WayPointTask:
    """A way-point mission made ready for planning.

    Attributes:
        mission: the :class:`planners.missions.mission.Mission`.
        robot: the robot it is planned for.
        way_times: travel times (k,) [s].
        n_via: via points per travel (k,).
        stop: the stop-at-every-way-point motion, one segment per travel.
    """

    mission: object
    robot: object
    way_times: np.ndarray
    n_via: np.ndarray
    stop: PiecewisePolynomial

    @classmethod
    def of(cls, mission, robot) -> WayPointTask:
        """The task of ``mission`` for ``robot``.

        Raises:
            MissionError, WorkspaceError, SingularityError: from ``mission.positions(robot)``.
        """
        way_times = np.asarray(mission.times, dtype=float)
        n_via = np.broadcast_to(np.asarray(mission.via_points, dtype=int), way_times.shape)
        stop = PiecewisePolynomial(stop_points(mission.positions(robot)), way_times)
        return cls(mission, robot, way_times, n_via, stop)

    @property
    def alpha(self) -> float:
        """The energy weight of the objective (3.26)."""
        return float(self.mission.alpha)

    @cached_property
    def via_layout(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(points, durations, is_way) of the stop motion cut at the via times
        (:func:`planners.trajectory.polynomial.with_via_points`): the layout of every motion with via points.
        """
        return with_via_points(self.stop, self.way_times, self.n_via)

    def with_via_points(self, trajectory: PiecewisePolynomial) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(points, durations, is_way) of ``trajectory`` (one segment per travel) cut at the via times."""
        return with_via_points(trajectory, self.way_times, self.n_via)

    def problem(self, points, durations, free, normalisation, grid: Grid) -> MotionProblem:
        """The NLP of the motion through ``points`` (mask ``free`` of the unknown entries) on ``grid``."""
        return MotionProblem(self.robot, points, durations, free, self.alpha, normalisation,
                             samples_per_segment=grid.samples_per_segment,
                             windows_per_segment=grid.windows_per_segment, dips=True)

    def normalisation(self, grid: Grid) -> tuple[float, float]:
        """(J_e0, J_phi0) of the stop motion on ``grid`` (smoothed |.|, as the optimiser sees them, 3.26), each at
        least its floor (:func:`planners.result.normalisation`).

        Computed once per grid (a method asks for it in each of its stages).
        """
        known = self.__dict__.setdefault("_normalisations", {})
        if grid not in known:
            free_way = np.zeros(self.stop.points.shape, dtype=bool)
            free_way[1:-1, 1:] = True
            problem = self.problem(self.stop.points, self.way_times, free_way, (1.0, 1.0), grid)
            known[grid] = normalisation(self.robot, float(np.sum(self.way_times)),
                                        problem.objective_terms(self.stop.points))  # floored: planners.result
        return known[grid]

    def result(self, method: str, trajectory: PiecewisePolynomial, is_way, report: MotionReport,
               reference: MotionReport, stages: list) -> PlanResult:
        """The :class:`PlanResult` of a motion planned for this task (``wall_time`` left to ``plan``)."""
        return PlanResult(self.mission, method, self.alpha, trajectory, is_way, report, reference, stages,
                          robot=self.robot)


def step1_problem(task: WayPointTask, grid: Grid, normalisation) -> MotionProblem:
    """The two-step method's step 1: the motion through the way points only, their derivatives 1..4 free (it
    ends at rest).
    """
    free = np.zeros(task.stop.points.shape, dtype=bool)
    free[1:-1, 1:] = True
    return task.problem(task.stop.points, task.way_times, free, normalisation, grid)


def travel_problem(task: WayPointTask, points, durations, begin: int, end: int, normalisation,
                   grid: Grid) -> MotionProblem:
    """The two-step method's step 2 on one travel: the motion through ``points[begin:end + 1]`` (way point, via
    points, way point; ``durations[begin:end]``), every entry of its via points free.
    """
    free = np.zeros(points[begin:end + 1].shape, dtype=bool)
    free[1:-1] = True
    return task.problem(points[begin:end + 1], durations[begin:end], free, normalisation, grid)


def solve_travels(task: WayPointTask, grid: Grid, points, durations, normalisation, solve_arguments: dict,
                  shared: NodeDerivatives | None = None, previous=None) -> tuple[np.ndarray, list]:
    """The two-step method's step 2: the via points optimised travel by travel, the way points fixed.

    Args:
        task: the mission.
        grid: the optimisation grid.
        points: the points of the via-point layout (:attr:`WayPointTask.via_layout`) to start from; not changed.
        durations: the layout's segment durations.
        normalisation: (J_e0, J_phi0) of ``grid``.
        solve_arguments: keyword arguments of :func:`~planners.optimisation.solving.solve_stage`.
        shared: a :class:`~planners.problem.motion.NodeDerivatives` the travels' problems share, or None.
        previous: the points of an earlier motion of the same layout whose via points each travel starts from
            (a refinement), or None.

    Returns:
        (the points with every travel's via points optimised, one stage ``"step 2, travel j"`` per travel with
        via points).
    """
    points = np.array(points, dtype=float)
    way_index = np.flatnonzero(task.via_layout[2])
    stages = []
    for j in range(len(task.way_times)):
        if task.n_via[j] == 0:
            continue
        a, b = way_index[j], way_index[j + 1]
        if previous is not None:  # a refinement restarts from the earlier via points
            points[a + 1:b] = previous[a + 1:b]
        travel = travel_problem(task, points, durations, a, b, normalisation, grid)
        if shared is not None:
            travel.share_node_derivatives(shared)
        x, stage = solve_stage(travel, travel.x_of(points[a:b + 1]), f"step 2, travel {j + 1}{grid.suffix}",
                               **solve_arguments)
        stages.append(stage)
        points[a:b + 1] = travel.points_of(x)
    return points, stages
