"""A baseline planner in the manner of the thesis' fmincon runs: interior point, finite differences, BFGS.

The thesis solved its NLPs with MATLAB's fmincon (interior point, finite-difference gradients,
quasi-Newton Hessians); the 1-step optimisation of the square mission took it about 40 minutes.
:func:`plan_baseline` does the same here, on the very NLP of ``plan(mission, "one-step")``'s first
attempt (:func:`planners.methods.one_step.one_step_problem`): scipy's
``minimize(method="trust-constr")`` with 2-point finite-difference gradients of J and of the
constraints and BFGS Hessian approximations, from the stop-at-every-way-point motion, stopped by a
time cap. It is what the benchmark (``python -m fpr.bench --section planning``) compares the
exact-gradient SQP of :mod:`planners.optimisation.sqp` with; it is not a registered method.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

from scipy.optimize import BFGS, NonlinearConstraint, minimize

from planners.methods.one_step import one_step_problem
from planners.methods.way_points import WayPointTask
from planners.optimisation.solving import GRID_FEASIBILITY, Grid
from planners.problem.report import evaluate_motion
from planners.result import PlanResult
from planners.trajectory.polynomial import PiecewisePolynomial


@dataclass(eq=False)
class BaselineResult:
    """What the baseline reached, and when.

    Attributes:
        result: the last iterate as a :class:`~planners.result.PlanResult` (method ``"baseline"``; dense-grid
            report, J normalised by the stop-at-every-way-point motion; ``wall_time`` the solver's run).
        time_cap: the cap it was given [s].
        iterations: trust-constr iterations.
        objective_evaluations, constraint_evaluations: calls of J and of the constraints (finite
            differences included).
        success, status, message: scipy's verdict on its run.
        grid_J, grid_violation: J and the largest scaled constraint violation of the last iterate on
            the optimisation grid.
        trace: (elapsed time [s], grid J, grid violation) after every iteration.
    """

    result: PlanResult
    time_cap: float
    iterations: int
    objective_evaluations: int
    constraint_evaluations: int
    success: bool
    status: int
    message: str
    grid_J: float
    grid_violation: float
    trace: list = field(default_factory=list, repr=False)

    def time_to(self, J: float, rtol: float = 1e-4, feasibility: float = GRID_FEASIBILITY) -> float | None:
        """When an iterate first held the grid constraints (violation <= ``feasibility``) with a grid J
        at most ``J`` (1 + ``rtol``) [s], or None if none did.
        """
        for elapsed, value, violation in self.trace:
            if violation <= feasibility and value <= J * (1 + rtol):
                return elapsed
        return None


def plan_baseline(mission, robot, time_cap: float, *, grid: Grid | None = None, dense_rate: float = 500.0,
                  progress=None) -> BaselineResult:
    """Plan ``mission`` like the thesis' fmincon runs (see the module docstring), for ``time_cap`` [s].

    Args:
        mission: a way-point mission (:class:`planners.missions.mission.Mission`).
        robot: the robot.
        time_cap: the run stops at the first iteration after this much time [s] (it has no other
            stopping rule that a few minutes would meet).
        grid: the optimisation grid; None for ``plan``'s default, ``Grid()``.
        dense_rate: rate of the final check [Hz].
        progress: called as ``progress("baseline", iteration, grid J, grid violation)`` after every
            iteration, or None.

    Returns:
        the :class:`BaselineResult`.
    """
    grid = Grid() if grid is None else grid
    task = WayPointTask.of(mission, robot)
    reference = evaluate_motion(robot, task.stop, dense_rate)
    problem = one_step_problem(task, grid)
    x0 = problem.x_of(problem.points)
    calls = {"J": 0, "c": 0, "it": 0}
    trace = []

    def objective(x):
        calls["J"] += 1
        return problem.evaluate(x).J

    def constraints(x):
        calls["c"] += 1
        return problem.evaluate(x).constraints

    start = time.perf_counter()

    def callback(xk, state):
        calls["it"] += 1
        ev = problem.evaluate(xk)
        elapsed = time.perf_counter() - start
        violation = float(max(0.0, -ev.constraints.min()))
        trace.append((elapsed, ev.J, violation))
        if progress is not None:
            progress("baseline", calls["it"], ev.J, violation)
        return elapsed > time_cap

    nonlinear = NonlinearConstraint(constraints, 0.0, float("inf"), jac="2-point", hess=BFGS())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = minimize(objective, x0, method="trust-constr", jac="2-point", hess=BFGS(),
                       constraints=[nonlinear], options={"maxiter": 100000},
                       callback=callback)  # stopped by the time cap
    wall = time.perf_counter() - start
    trajectory = PiecewisePolynomial(problem.points_of(res.x), problem.durations)
    report = evaluate_motion(robot, trajectory, dense_rate)
    result = PlanResult(mission, "baseline", task.alpha, trajectory, task.via_layout[2], report, reference, [],
                        wall, robot)
    ev = problem.evaluate(res.x)
    return BaselineResult(result, float(time_cap), int(res.nit), calls["J"], calls["c"], bool(res.success),
                          int(res.status), str(res.message), float(ev.J),
                          float(max(0.0, -ev.constraints.min())), trace)
