"""Solving one planning NLP (a *stage*), and solving again on a finer grid when the dense check asks for it.

* :func:`solve_stage` runs the trust-region SQP of :mod:`planners.optimisation.sqp` (or scipy's SLSQP with the
  same exact gradients) on any NLP with the shape of :class:`planners.problem.motion.MotionProblem`
  (``n_x``, ``evaluate(x, derivatives) -> Evaluation``) and reports it as a :class:`StageReport`.
* :func:`solve_refining` is the grid refinement every optimising method shares: a motion that holds
  every constraint on the optimisation :class:`Grid` but not on the dense grid is solved again, from
  itself, on a grid twice as fine.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import minimize, nnls

from fpr.model.errors import PlannerArgumentError
from planners.optimisation.sqp import SqpOptions, kkt_residual, prepare, solve_sqp

#: The NLP solvers :func:`solve_stage` knows.
SOLVERS = ("sqp", "slsqp")

#: Largest scaled grid-constraint violation at the end of a stage for which a result that fails the
#: dense check is solved again on a finer grid (:func:`solve_refining`).
GRID_FEASIBILITY = 1e-6


@dataclass(frozen=True)
class Grid:
    """The optimisation grid of a stage.

    Attributes:
        samples_per_segment: odd number of nodes per segment for J and the constraints.
        windows_per_segment: constraint windows per segment.
        refinement: how many times it was refined (0 = as given).
    """

    samples_per_segment: int = 17
    windows_per_segment: int = 4
    refinement: int = 0

    def refined(self) -> Grid:
        """The grid twice as fine: every interval halved, twice the windows."""
        return Grid(2 * self.samples_per_segment - 1, 2 * self.windows_per_segment, self.refinement + 1)

    @property
    def suffix(self) -> str:
        """What a stage name gets on a refined grid, e.g. ``" (grid refined x2)"``; ``""`` on the first."""
        return "" if self.refinement == 0 else f" (grid refined x{2 ** self.refinement})"



@dataclass
class StageReport:
    """One NLP solve.

    Attributes:
        name: e.g. ``"step 1"``, ``"step 2, travel 3"``, ``"one-step"``.
        n_variables, n_constraints: size of the NLP.
        success: the solver's own verdict; message, status: its words and code.
        iterations, evaluations, gradient_evaluations: the solver's counts (SQP: evaluations of the
            problem, with derivatives or not, each point once; gradient_evaluations: those with).
        wall_time: [s].
        J_start, J_end: objective (on the optimisation grid) before and after.
        violation_end: largest scaled constraint violation on the grid at the end (0 = none).
        kkt: the KKT residual at the end (:func:`planners.optimisation.sqp.kkt_residual`: the largest of the three
            below; SQP: with its last QP's multipliers; SLSQP: with the non-negative least-squares
            multipliers of the constraints within 1e-6 of their bound), kkt_stationarity,
            kkt_complementarity, kkt_feasibility: its parts, active: constraints with a positive multiplier.
    """

    name: str
    n_variables: int
    n_constraints: int
    success: bool = False
    message: str = ""
    status: int = -1
    iterations: int = 0
    evaluations: int = 0
    gradient_evaluations: int = 0
    wall_time: float = 0.0
    J_start: float = float("nan")
    J_end: float = float("nan")
    violation_end: float = float("nan")
    kkt: float = float("nan")
    kkt_stationarity: float = float("nan")
    kkt_complementarity: float = float("nan")
    kkt_feasibility: float = float("nan")
    active: int = 0

    def set_kkt(self, kkt) -> None:
        """Copy a :class:`planners.optimisation.sqp.Kkt` into the report."""
        self.kkt, self.kkt_stationarity = kkt.residual, kkt.stationarity
        self.kkt_complementarity, self.kkt_feasibility = kkt.complementarity, kkt.feasibility
        self.active = kkt.active


def solve_stage(problem, x0, name: str, progress=None, max_iterations: int = 100, tolerance: float = 1e-4,
                solver: str = "sqp", sqp: SqpOptions | None = None) -> tuple[np.ndarray, StageReport]:
    """Solve ``problem`` from x0 with ``solver``.

    Args:
        problem: the NLP (``n_x``, ``evaluate(x, derivatives)``, e.g. a
            :class:`~planners.problem.motion.MotionProblem`), constraints ``>= 0``.
        x0: the start, shape (n_x,).
        name: the stage's name (reports and ``progress``).
        progress: called as ``progress(name, iteration, J, violation)`` after every iteration, or None.
        max_iterations: iteration limit.
        tolerance: stop when an iteration improves J (about 1) by less than this.
        solver: one of :data:`SOLVERS`: ``"sqp"`` (:func:`planners.optimisation.sqp.solve_sqp`) or ``"slsqp"`` (scipy;
            its best iterate is returned, a feasible one first).
        sqp: further :class:`~planners.optimisation.sqp.SqpOptions` of the SQP (its ``max_iterations`` and
            ``tolerance`` are replaced by the arguments above); default: the earlier rule
            (``stop="progress"``, ``curvature="gauss-newton"``), as the singularity crossing uses it.

    Returns:
        (x, :class:`StageReport`).

    Raises:
        PlannerArgumentError: an unknown solver.
    """
    settings = replace(sqp or SqpOptions(stop="progress", curvature="gauss-newton"),
                       max_iterations=max_iterations, tolerance=tolerance)
    if solver == "sqp":
        prepare(problem, settings)
    # the SQP's first evaluation (with derivatives: the problem's cache serves the SQP's first iteration)
    ev0 = problem.evaluate(x0, solver == "sqp" and problem.n_x > 0)
    stage = StageReport(name, problem.n_x, ev0.constraints.size, J_start=ev0.J)
    if problem.n_x == 0:
        stage.success, stage.message, stage.status = True, "nothing to optimise", 0
        stage.J_end, stage.violation_end = ev0.J, ev0.violation
        stage.kkt = stage.kkt_feasibility = ev0.violation  # no variables: feasibility is all there is
        stage.kkt_stationarity = stage.kkt_complementarity = 0.0
        return np.asarray(x0, dtype=float), stage
    if solver == "sqp":
        del ev0  # not kept alive through the solve: with derivatives, a long mission's holds ~100 MB
        out = solve_sqp(problem, x0, settings, progress, name)
        stage.success, stage.message, stage.status = out.success, out.message, 0 if out.success else 1
        stage.iterations, stage.evaluations = out.iterations, out.evaluations + out.gradient_evaluations
        stage.gradient_evaluations, stage.wall_time = out.gradient_evaluations, out.wall_time
        stage.J_end, stage.violation_end = out.J, out.violation
        stage.set_kkt(out.kkt)
        return out.x, stage
    if solver != "slsqp":
        raise PlannerArgumentError("solver", solver, f"solver={solver!r}: use one of {', '.join(SOLVERS)}")
    start = time.perf_counter()
    best = [None, np.inf, np.inf]  # x, J, violation of the best iterate (feasible first)
    counts = {"it": 0}

    def consider(x):
        ev = problem.evaluate(x)
        viol = ev.violation
        key = (viol > 1e-9, viol if viol > 1e-9 else ev.J)
        if best[0] is None or key < (best[2] > 1e-9, best[2] if best[2] > 1e-9 else best[1]):
            best[:] = [np.array(x), ev.J, viol]
        return ev.J, viol

    def callback(xk, *_):
        counts["it"] += 1
        j, viol = consider(xk)
        if progress is not None:
            progress(name, counts["it"], j, viol)

    consider(x0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = minimize(
            lambda x: problem.evaluate(x).J, x0, jac=lambda x: problem.evaluate(x, True).gradient,
            method="SLSQP",
            constraints=[{"type": "ineq", "fun": lambda x: problem.evaluate(x).constraints,
                          "jac": lambda x: problem.evaluate(x, True).jacobian}],
            options={"maxiter": max_iterations, "ftol": tolerance}, callback=callback,
        )
    consider(res.x)
    stage.wall_time = time.perf_counter() - start
    stage.success, stage.message, stage.status = bool(res.success), str(res.message), int(res.status)
    stage.iterations, stage.evaluations = int(res.nit), int(res.nfev)
    stage.gradient_evaluations = int(getattr(res, "njev", 0))
    stage.J_end, stage.violation_end = best[1], best[2]
    stage.set_kkt(kkt_with_best_multipliers(problem.evaluate(best[0], True)))
    return best[0], stage


def kkt_with_best_multipliers(ev):
    """The :class:`~planners.optimisation.sqp.Kkt` residual of an Evaluation (with derivatives), best multipliers.

    The multipliers: lambda >= 0 on the constraints within 1e-6 of their bound, by non-negative least
    squares on nabla J = A^T lambda (for a solver that gives none, SLSQP, and to compare methods).
    """
    near = np.flatnonzero(ev.constraints <= 1e-6)
    lam = np.zeros(ev.constraints.size)
    if near.size:
        lam[near] = nnls(ev.jacobian[near].T, ev.gradient)[0]
    return kkt_residual(ev.gradient, ev.constraints, ev.jacobian, lam)


def solve_refining(attempt: Callable, check: Callable, grid: Grid, max_refinements: int,
                   refine_below: float = GRID_FEASIBILITY):
    """Solve on ``grid``, then again on finer grids while the dense check fails but the grid's holds.

    Args:
        attempt: ``attempt(grid, previous) -> (trajectory, stages)``: one solve (one or more stages)
            on ``grid``; ``previous`` is None the first time, then the trajectory of the attempt before,
            to start from.
        check: ``check(trajectory) -> MotionReport`` (:func:`planners.problem.report.evaluate_motion`).
        grid: the first grid.
        max_refinements: at most this many refined attempts after the first.
        refine_below: a grid violation (the stages' ``violation_end``) up to which a finer grid is tried.

    Returns:
        (trajectory, report, stages): the last attempt's motion and dense-grid report, and the stages
        of every attempt in order. It stops at the first attempt whose motion passes the dense check,
        or whose stages end with a grid violation above ``refine_below`` (:data:`GRID_FEASIBILITY` by
        default: a finer grid would not help), or after ``max_refinements`` refinements.
    """
    stages, previous = [], None
    for _ in range(max_refinements + 1):
        trajectory, new = attempt(grid, previous)
        stages += new
        report = check(trajectory)
        if report.feasible or not all(st.violation_end <= refine_below for st in new):
            break
        # feasible (or nearly) on the optimisation grid but not between its nodes: refine the grid, start from
        # this motion
        grid, previous = grid.refined(), trajectory
    return trajectory, report, stages
