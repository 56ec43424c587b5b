"""Plan seeded families of random missions and summarise them: what the bench's planning and scaling sections
report, and what a user runs on a robot of their own.

:func:`plan_family` plans every seed of a :class:`~fpr.bench.missions.MissionFamily` with each method and
returns one :class:`FamilyRow` per method: the wall times of ``plan`` (reference and dense check included),
their median and 95th percentile, the failures (a plan infeasible on the 500 Hz grid, or an error), J, and for
each seed whether J is no worse than the unpolished two-step motion's (the thesis' two steps, before the
polish): both compared on the optimisation grid of the two-step's polish (:func:`unpolished_comparison`).
::

    from fpr.bench.families import plan_family
    from fpr.bench.missions import MissionFamily
    rows = plan_family(MissionFamily("prototype", way_points=32, arm="up"), seeds=range(20))
    print(rows[0].median_s, rows[0].p95_s, rows[0].failures)
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field

import numpy as np

from fpr import robots
from fpr.bench.missions import MissionFamily
from planners.methods.one_step import one_step_problem
from planners.methods.way_points import WayPointTask
from planners.optimisation.solving import Grid
from planners.optimize import plan

#: The methods a family is planned with by default.
METHODS = ("two-step", "one-step")
#: A J "no worse" than the unpolished two-step's: within this relative margin (the SQP's stopping tolerance).
SAME_J_RTOL = 1e-4


@dataclass
class FamilyRow:
    """One method on one family of missions.

    Attributes:
        robot, space, arm, way_points, via_points: the family (``via_points`` the (least, most) per travel).
        method: the planning method.
        seeds: the seeds planned.
        times_s: wall time of each plan [s] (``plan``'s own, reference and dense check included).
        J: each plan's J (dense grid, 3.26); NaN for an error.
        feasible: each plan's dense-grid feasibility (False for an error).
        iterations: each plan's SQP iterations, all stages.
        errors: the error of each seed that raised ("" for none).
        J_grid, J_unpolished_grid: each plan's J and the unpolished two-step motion's on the two-step polish's
            grid (:func:`unpolished_comparison`), NaN where not compared.
    """

    robot: str
    space: str
    arm: str
    way_points: int
    via_points: tuple[int, int]
    method: str
    seeds: list[int] = field(default_factory=list)
    times_s: list[float] = field(default_factory=list)
    J: list[float] = field(default_factory=list)
    feasible: list[bool] = field(default_factory=list)
    iterations: list[int] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    J_grid: list[float] = field(default_factory=list)
    J_unpolished_grid: list[float] = field(default_factory=list)

    @property
    def median_s(self) -> float:
        """Median wall time [s]."""
        return float(np.median(self.times_s)) if self.times_s else float("nan")

    @property
    def p95_s(self) -> float:
        """95th percentile of the wall times [s] (numpy's linear interpolation between order statistics)."""
        return float(np.percentile(self.times_s, 95)) if self.times_s else float("nan")

    @property
    def failures(self) -> int:
        """Plans infeasible on the dense grid, or that raised."""
        return int(sum(not f for f in self.feasible))

    @property
    def worse_than_unpolished(self) -> int:
        """Plans whose grid J exceeds the unpolished two-step motion's by more than :data:`SAME_J_RTOL`."""
        pairs = zip(self.J_grid, self.J_unpolished_grid, strict=True)
        return int(sum(j > u * (1.0 + SAME_J_RTOL) for j, u in pairs if np.isfinite(j) and np.isfinite(u)))

    def summary(self) -> dict:
        """The row as plain types, with its statistics (for JSON)."""
        out = asdict(self)
        finite = [j for j in self.J if np.isfinite(j)]
        out.update(median_s=self.median_s, p95_s=self.p95_s, max_s=max(self.times_s, default=float("nan")),
                   failures=self.failures, worse_than_unpolished=self.worse_than_unpolished,
                   J_median=float(np.median(finite)) if finite else float("nan"),
                   J_min=min(finite, default=float("nan")), J_max=max(finite, default=float("nan")),
                   via_points=list(self.via_points))
        return out


def unpolished_comparison(mission, robot, two_step, other, grid: Grid | None = None) -> tuple[float, float]:
    """(other's J, the unpolished two-step motion's J), both on the optimisation grid of the two-step's polish.

    The polish (:mod:`planners.methods.two_step`) starts from the motion of the thesis' two steps: its first
    stage's ``J_start`` is that motion's J on the first grid (``grid``, default :class:`Grid`), and ``other``'s
    motion is evaluated on the same NLP (the 1-step NLP of the mission,
    :func:`planners.methods.one_step.one_step_problem`). Without a polish (one travel, no via points) the
    two-step result is the unpolished motion. NaN, NaN when the layouts differ.
    """
    grid = grid or Grid()
    polish = [st for st in two_step.stages if st.name == "polish (one-step)" + grid.suffix]
    problem = one_step_problem(WayPointTask.of(mission, robot), grid)
    if other.trajectory.points.shape != problem.points.shape:
        return float("nan"), float("nan")
    mine = float(problem.evaluate(problem.x_of(other.trajectory.points)).J)
    reference = polish[0].J_start if polish else float(problem.evaluate(problem.x_of(two_step.trajectory.points)).J)
    return mine, float(reference)


def plan_family(family: MissionFamily, seeds, methods=METHODS, robot=None, progress=None,
                missions: dict | None = None) -> list[FamilyRow]:
    """Plan every seed of ``family`` with each method (module docstring).

    Args:
        family: the family.
        seeds: the seeds (each gives one mission, :meth:`MissionFamily.mission`).
        methods: planning method names (the unpolished comparison needs "two-step" among them).
        robot: the robot (default ``fpr.robots.load(family.robot)``).
        progress: ``progress(text)`` after each plan, or None.
        missions: a cache {(family, seed): Mission} to read and fill, or None.

    Returns:
        one :class:`FamilyRow` per method.
    """
    robot = robot if robot is not None else robots.load(family.robot)
    rows = {m: FamilyRow(family.robot, family.space, family.arm, family.way_points, tuple(family.via_points), m)
            for m in methods}
    for seed in seeds:
        key = (family, int(seed))
        mission = (missions or {}).get(key) or family.mission(int(seed), robot)
        if missions is not None:
            missions[key] = mission
        results = {}
        for method in methods:
            row = rows[method]
            row.seeds.append(int(seed))
            start = time.perf_counter()
            try:
                result = plan(mission, method, robot=robot)
            except Exception as error:  # a failure of the family, reported (the bench goes on)
                row.times_s.append(time.perf_counter() - start)
                row.J.append(float("nan"))
                row.feasible.append(False)
                row.iterations.append(0)
                row.errors.append(f"{type(error).__name__}: {error}")
                continue
            results[method] = result
            row.times_s.append(float(result.wall_time))
            row.J.append(float(result.J))
            row.feasible.append(bool(result.feasible))
            row.iterations.append(int(sum(st.iterations for st in result.stages)))
            row.errors.append("")
            if progress is not None:
                progress(f"{family.label}, {family.way_points} way points, seed {seed}, {method}: "
                         f"{result.wall_time:.2f} s, J {result.J:.4f}{'' if result.feasible else ', INFEASIBLE'}")
        for method in methods:
            mine = reference = float("nan")
            if "two-step" in results and method in results:
                mine, reference = unpolished_comparison(mission, robot, results["two-step"], results[method])
            rows[method].J_grid.append(mine)
            rows[method].J_unpolished_grid.append(reference)
    return list(rows.values())


__all__ = ["FamilyRow", "METHODS", "SAME_J_RTOL", "plan_family", "unpolished_comparison"]
