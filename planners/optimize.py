"""Optimal motions of the thesis' chapter 3: the 2-step and 1-step optimisations (seed 3.2.4).

* ``"none"``: stop at every way point (s' = s'' = s''' = s'''' = 0 there), the reference motion
  that normalises the objective (3.26).
* ``"two-step"``: step 1 optimises the derivatives 1..4 at the interior way points (S_d1, 3.20)
  of the motion through the way points only; step 2 then optimises, travel by travel, the via
  points (S_d2, 3.22) between the way points fixed by step 1. Each step-2 problem starts from
  the step-1 motion itself (its value and derivatives at the via times), so step 2 never ends
  worse than step 1.
* ``"one-step"``: all of them at once, from the stop-at-every-way-point motion.

The first and last way points keep zero derivatives (the robot starts and ends at rest).
The NLP is solved by the Gauss-Newton SQP of :mod:`planners.sqp` (or scipy's SLSQP) with the
exact gradients of :class:`planners.problem.MotionProblem`;
the result is then checked on a dense grid (:func:`evaluate_motion`), which is what
:attr:`PlanResult.feasible` and the constraint report are based on.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from fpr.model.inverse_dynamics import MOTION_ORDER, MotionInputs, inverse_dynamics
from fpr.model.kinematics import singularity_margin
from planners.polynomial import PiecewisePolynomial, stop_points
from planners.sqp import SqpOptions, solve_sqp
from planners.problem import (
    CONSTRAINT_KINDS,
    MotionProblem,
    constraint_kind,
    constraint_rows,
    objective_rates,
)

METHODS = ("two-step", "one-step", "none")
FEASIBILITY_TOLERANCE = {"m": 1e-6, "rad": 1e-6, "rad/s": 1e-3, "N": 1e-6}


@dataclass(frozen=True)
class ConstraintReport:
    """The worst value of one constraint along a motion.

    Attributes:
        name: e.g. ``ground_1``, ``roll_2``, ``rotor_speed_high_1``.
        kind: its kind (key of :data:`planners.problem.CONSTRAINT_KINDS`).
        margin: least signed margin (>= 0 satisfied) [unit].
        time: where it occurs [s].
        unit: unit of ``margin``.
        detail: e.g. which rotor, which side of a two-sided bound.
    """

    name: str
    kind: str
    margin: float
    time: float
    unit: str
    detail: str = ""

    @property
    def satisfied(self) -> bool:
        """Within the tolerance of the dense-grid check."""
        return self.margin >= -FEASIBILITY_TOLERANCE[self.unit]

    def describe(self) -> str:
        """One line for people."""
        state = "ok" if self.satisfied else "VIOLATED"
        extra = f", {self.detail}" if self.detail else ""
        return f"{self.name:20s} {state:8s} margin {self.margin:+.4g} {self.unit} at t = {self.time:.3f} s{extra}"


@dataclass(frozen=True, eq=False)
class MotionReport:
    """A motion sampled densely, with what the drones must do and every constraint's worst value.

    Attributes:
        t: sample times (N,) [s].
        motion: s and derivatives 0..4, (5, N, n_s).
        inputs: thrusts, rolls, torques, rotor speeds (:class:`fpr.model.inverse_dynamics.MotionInputs`).
        J_e: energy index (3.24, exact |.|) [J].
        J_phi: perturbation index (3.25) [rad^2/s].
        constraints: name -> :class:`ConstraintReport`.
    """

    t: np.ndarray
    motion: np.ndarray
    inputs: MotionInputs
    J_e: float
    J_phi: float
    constraints: dict

    @property
    def feasible(self) -> bool:
        """Every constraint holds on the dense grid."""
        return all(c.satisfied for c in self.constraints.values())

    @property
    def violations(self) -> list[ConstraintReport]:
        """The violated constraints, worst (most negative relative to tolerance) first."""
        bad = [c for c in self.constraints.values() if not c.satisfied]
        return sorted(bad, key=lambda c: c.margin / FEASIBILITY_TOLERANCE[c.unit])

    def peaks(self, robot) -> dict:
        """Peak values people compare (thrust, rotor force and speed, clearances)."""
        w2 = self.inputs.rotor_speed_squared
        singular = self.motion[0][:, -1]
        return {
            "peak_thrust_N": float(self.inputs.thrust.max()),
            "peak_rotor_force_N": float(robot.rotor_constants.thrust_coefficient * w2.max()),
            "peak_rotor_speed_rad_s": float(self.inputs.rotor_speed.max()),
            "least_rotor_speed_rad_s": float(self.inputs.rotor_speed.min()),
            "peak_roll_rad": float(np.abs(self.inputs.roll).max()),
            "least_ground_clearance_m": float(self.inputs.joint_position[..., 1].min() + robot.link_length),
            "least_singularity_margin_rad": float(singularity_margin(singular).min()),
        }


def evaluate_motion(robot, trajectory: PiecewisePolynomial, rate: float = 500.0,
                    crossing_time: float | None = None, min_thrust: float | None = None) -> MotionReport:
    """Sample ``trajectory`` at ``rate`` [Hz] (plus every knot) and check every constraint.

    Args:
        robot, trajectory, rate: what to check, and how densely [Hz].
        crossing_time: for a prototype motion that crosses its Type-2 singularity once
            (:mod:`planners.crossing`), the time of the crossing [s]: the assembly-mode bounds are
            then checked on each side of it.
        min_thrust: also check thrust >= this [N] (``thrust_low``), or None.

    Returns:
        the :class:`MotionReport` (J_e, J_phi by the trapezoidal rule on the samples).
    """
    t = np.unique(np.concatenate([trajectory.sample_times(rate), trajectory.knots]))
    motion = trajectory.evaluate(t, order=MOTION_ORDER)
    inputs = inverse_dynamics(robot, motion)
    rates = objective_rates(inputs)
    sign = None if crossing_time is None else np.sign(crossing_time - t) * (np.abs(t - crossing_time) > 1e-12)
    rows, names, details = constraint_rows(robot, motion, inputs, scaled=False, crossing_sign=sign,
                                           min_thrust=min_thrust)
    reports = {}
    for name in dict.fromkeys(names):
        cols = [c for c, n in enumerate(names) if n == name]
        sub = rows[:, cols]
        i, c = np.unravel_index(np.argmin(sub), sub.shape)
        kind = constraint_kind(name)
        reports[name] = ConstraintReport(name, kind, float(sub[i, c]), float(t[i]), CONSTRAINT_KINDS[kind][0],
                                         details[cols[c]])
    return MotionReport(t, motion[:5], inputs, float(np.trapezoid(rates[:, 0], t)), float(np.trapezoid(rates[:, 1], t)),
                        reports)


@dataclass
class StageReport:
    """One NLP solve.

    Attributes:
        name: e.g. ``"step 1"``, ``"step 2, travel 3"``, ``"one-step"``.
        n_variables, n_constraints: size of the NLP.
        success: the solver's own verdict; message, status: its words and code.
        iterations, evaluations, gradient_evaluations: the solver's counts.
        wall_time: [s].
        J_start, J_end: objective (on the optimisation grid) before and after.
        violation_end: largest scaled constraint violation on the grid at the end (0 = none).
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


@dataclass(frozen=True)
class SampledPlan:
    """A motion sampled for plots and files (the attributes :mod:`fpr.views.figures` reads)."""

    label: str
    t: np.ndarray
    motion: np.ndarray
    inputs: MotionInputs
    knots: np.ndarray
    is_way: np.ndarray
    points: np.ndarray


@dataclass(eq=False)
class PlanResult:
    """An optimised (or reference) motion and everything known about it.

    Attributes:
        mission: the :class:`planners.mission.Mission`.
        method: ``"two-step"``, ``"one-step"`` or ``"none"``.
        alpha: the weight used.
        trajectory: the motion, a :class:`~planners.polynomial.PiecewisePolynomial`.
        is_way: (m+1,) True for way points, False for via points.
        report: dense-grid :class:`MotionReport` of ``trajectory``.
        reference: dense-grid report of the stop-at-every-way-point motion (J_e0, J_phi0).
        stages: the NLP solves, in order.
        wall_time: total planning time [s].
        robot: the robot it was planned for.
        crossing: for a singularity-crossing mission, the
            :class:`planners.crossing.CrossingOutcome` (``reference`` is then its first guess, the
            motion the optimisation started from); else None.
    """

    mission: object
    method: str
    alpha: float
    trajectory: PiecewisePolynomial
    is_way: np.ndarray
    report: MotionReport
    reference: MotionReport
    stages: list = field(default_factory=list)
    wall_time: float = 0.0
    robot: object = field(default=None, repr=False)
    crossing: object = field(default=None, repr=False)

    @property
    def feasible(self) -> bool:
        """Every constraint holds on the dense grid (and a crossing crosses exactly once)."""
        return self.report.feasible if self.crossing is None else self.crossing.feasible

    @property
    def J(self) -> float:
        """alpha J_e / J_e0 + (1 - alpha) J_phi / J_phi0 (3.26), dense grid."""
        return self.alpha * self.report.J_e / self.reference.J_e \
            + (1 - self.alpha) * self.report.J_phi / self.reference.J_phi

    @property
    def label(self) -> str:
        """How tables and figures name this motion ("stop at way points", "optimised (two-step)"...)."""
        return _label(self.method)

    @property
    def solver_success(self) -> bool:
        """Every NLP solve ended with the solver reporting success."""
        return all(s.success for s in self.stages)

    def sampled(self, rate: float = 200.0, label: str | None = None, robot=None) -> SampledPlan:
        """The motion sampled at ``rate`` [Hz] (end time included) with its inputs."""
        robot = robot or self.robot
        t, motion = self.trajectory.sample(rate, order=MOTION_ORDER)
        return SampledPlan(label or _label(self.method), t, motion[:5], inverse_dynamics(robot, motion),
                           self.trajectory.knots, self.is_way, self.trajectory.points)

    def summary(self, robot=None) -> dict:
        """JSON-friendly summary: objective terms, peaks, constraints, solver stages."""
        robot = robot or self.robot
        return {
            "method": self.method,
            "alpha": self.alpha,
            "feasible": self.feasible,
            "solver_success": self.solver_success,
            "J": self.J,
            "J_e": self.report.J_e,
            "J_phi": self.report.J_phi,
            "J_e0": self.reference.J_e,
            "J_phi0": self.reference.J_phi,
            **self.report.peaks(robot),
            "wall_time_s": self.wall_time,
            "constraints": {n: {"margin": c.margin, "unit": c.unit, "time_s": c.time, "detail": c.detail,
                                "satisfied": c.satisfied} for n, c in self.report.constraints.items()},
            "violated": [c.name for c in self.report.violations],
            "stages": [vars(s) for s in self.stages],
            **({"crossing": self.crossing.summary(robot)} if self.crossing is not None else {}),
        }


def _label(method: str) -> str:
    return {"none": "stop at way points", "crossing": "optimised crossing",
            "first guess": "first guess (crossing)"}.get(method, f"optimised ({method})")


# ---------------------------------------------------------------------------------------- solving
def _solve(problem: MotionProblem, x0, name: str, progress, max_iterations: int, tolerance: float,
           solver: str = "sqp"):
    """Solve ``problem`` from x0 with ``solver``; returns (x, StageReport)."""
    ev0 = problem.evaluate(x0)
    stage = StageReport(name, problem.n_x, ev0.constraints.size, J_start=ev0.J)
    if problem.n_x == 0:
        stage.success, stage.message, stage.status = True, "nothing to optimise", 0
        stage.J_end, stage.violation_end = ev0.J, ev0.violation
        return np.asarray(x0, dtype=float), stage
    if solver == "sqp":
        out = solve_sqp(problem, x0, SqpOptions(max_iterations=max_iterations, tolerance=tolerance),
                        progress, name)
        stage.success, stage.message, stage.status = out.success, out.message, 0 if out.success else 1
        stage.iterations, stage.evaluations = out.iterations, out.evaluations + out.gradient_evaluations
        stage.gradient_evaluations, stage.wall_time = out.gradient_evaluations, out.wall_time
        stage.J_end, stage.violation_end = out.J, out.violation
        return out.x, stage
    if solver != "slsqp":
        raise ValueError(f"solver={solver!r}: use 'sqp' or 'slsqp'")
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
    return best[0], stage


def _via_points(trajectory: PiecewisePolynomial, begin: float, duration: float, count: int) -> np.ndarray:
    """Value and derivatives 0..4 of ``trajectory`` at ``count`` evenly spaced interior times."""
    if count == 0:
        return np.zeros((0,) + trajectory.points.shape[1:])
    t = begin + duration * np.arange(1, count + 1) / (count + 1)
    return np.moveaxis(trajectory.evaluate(t, order=4), 1, 0)  # (count, 5, n)


def _with_via_points(trajectory: PiecewisePolynomial, way_times, n_via):
    """Points, durations and way mask of ``trajectory`` split at the via times (same motion)."""
    knots = np.concatenate([[0.0], np.cumsum(way_times)])
    points, durations, is_way = [trajectory.points[0]], [], [True]
    for j, (duration, count) in enumerate(zip(way_times, n_via)):
        for via in _via_points(trajectory, knots[j], duration, int(count)):
            points.append(via)
            is_way.append(False)
        points.append(trajectory.points[j + 1])
        is_way.append(True)
        durations += [duration / (count + 1)] * (int(count) + 1)
    return np.array(points), np.array(durations), np.array(is_way)


def plan(mission, method: str = "two-step", *, robot=None, progress=None, samples_per_segment: int = 17,
         windows_per_segment: int = 4, max_iterations: int = 100, tolerance: float = 1e-4,
         dense_rate: float = 500.0, solver: str = "sqp", max_refinements: int = 2) -> PlanResult:
    """Plan ``mission`` with ``method`` (see the module docstring).

    Args:
        mission: a :class:`planners.mission.Mission`.
        method: ``"two-step"``, ``"one-step"`` or ``"none"``.
        robot: the robot (default ``mission.load_robot()``).
        progress: called as ``progress(stage_name, iteration, J, violation)`` after every
            solver iteration, or None.
        samples_per_segment: odd number of grid nodes per segment for J and the constraints.
        windows_per_segment: constraint windows per segment.
        max_iterations: iteration limit per solve.
        tolerance: stop when an iteration improves J (about 1) by less than this.
        dense_rate: rate of the final check [Hz].
        max_refinements: when the result holds every constraint on the optimisation grid but not on
            the dense grid, solve again on a grid twice as fine, at most this many times.
        solver: ``"sqp"`` (:mod:`planners.sqp`, Gauss-Newton trust-region SQP, the default) or
            ``"slsqp"`` (scipy's SLSQP with the same exact gradients, quasi-Newton curvature).

    Returns:
        the :class:`PlanResult` (check ``feasible``; nothing is raised for an infeasible result).

    Raises:
        ValueError: unknown method. Mission errors (WorkspaceError, SingularityError,
            MissionError) come from ``mission.positions``.
    """
    if method not in METHODS:
        raise ValueError(f"method={method!r}: use one of {', '.join(METHODS)}")
    start = time.perf_counter()
    robot = robot or mission.load_robot()
    positions = mission.positions(robot)
    if getattr(mission, "cross_singularity", False):
        return _plan_crossing(mission, method, robot, positions, progress, samples_per_segment,
                              windows_per_segment, max_iterations, dense_rate, max_refinements, start)
    way_times = np.asarray(mission.times, dtype=float)
    n_via = np.broadcast_to(np.asarray(mission.via_points, dtype=int), way_times.shape)
    alpha = float(mission.alpha)
    stop = PiecewisePolynomial(stop_points(positions), way_times)
    reference = evaluate_motion(robot, stop, dense_rate)

    solve_args = {"progress": progress, "max_iterations": max_iterations, "tolerance": tolerance,
                  "solver": solver}

    def attempt(samples: int, windows: int, suffix: str, previous=None):
        """One solve on a grid; ``previous`` (points of an earlier solve, same layout) is the start."""
        def problem(points, durations, free, normalisation):
            return MotionProblem(robot, points, durations, free, alpha, normalisation,
                                 samples_per_segment=samples, windows_per_segment=windows)

        free_way = np.zeros(stop.points.shape, dtype=bool)
        free_way[1:-1, 1:] = True
        normalisation = tuple(problem(stop.points, way_times, free_way, (1.0, 1.0)).objective_terms(stop.points))
        stages = []
        if method == "two-step":
            step1 = problem(stop.points, way_times, free_way, normalisation)
            start = stop.points if previous is None else previous[is_way_of(previous)]
            x, stage = _solve(step1, step1.x_of(start), "step 1" + suffix, **solve_args)
            stages.append(stage)
            first = PiecewisePolynomial(step1.points_of(x), way_times)
            points, durations, is_way = _with_via_points(first, way_times, n_via)
            way_index = np.flatnonzero(is_way)
            for j in range(len(way_times)):
                if n_via[j] == 0:
                    continue
                a, b = way_index[j], way_index[j + 1]
                free = np.zeros(points[a:b + 1].shape, dtype=bool)
                free[1:-1] = True
                if previous is not None:  # a refinement restarts from the earlier via points
                    points[a + 1:b] = previous[a + 1:b]
                travel = problem(points[a:b + 1], durations[a:b], free, normalisation)
                x, stage = _solve(travel, travel.x_of(points[a:b + 1]), f"step 2, travel {j + 1}{suffix}",
                                  **solve_args)
                stages.append(stage)
                points[a:b + 1] = travel.points_of(x)
            return PiecewisePolynomial(points, durations), is_way, stages
        points, durations, is_way = _with_via_points(stop, way_times, n_via)
        free = np.zeros(points.shape, dtype=bool)
        free[~is_way] = True
        free[np.flatnonzero(is_way)[1:-1], 1:] = True
        whole = problem(points, durations, free, normalisation)
        start = points if previous is None else previous
        x, stage = _solve(whole, whole.x_of(start), "one-step" + suffix, **solve_args)
        return PiecewisePolynomial(whole.points_of(x), durations), is_way, [stage]

    def is_way_of(points):
        return _with_via_points(stop, way_times, n_via)[2] if len(points) != len(positions) \
            else np.ones(len(points), dtype=bool)

    if method == "none":
        trajectory, is_way, stages = stop, np.ones(len(positions), dtype=bool), []
        report = reference
    else:
        samples, windows, stages = samples_per_segment, windows_per_segment, []
        for refinement in range(max_refinements + 1):
            suffix = "" if refinement == 0 else f" (grid refined x{2 ** refinement})"
            trajectory, is_way, new = attempt(samples, windows, suffix,
                                              None if refinement == 0 else trajectory.points)
            stages += new
            report = evaluate_motion(robot, trajectory, dense_rate)
            grid_feasible = all(st.violation_end <= 1e-6 for st in new)
            if report.feasible or not grid_feasible:
                break
            # feasible on the optimisation grid but not between its nodes: refine the grid, and start
            # from this solution
            samples, windows = 2 * samples - 1, 2 * windows
    return PlanResult(mission, method, alpha, trajectory, is_way, report, reference, stages,
                      time.perf_counter() - start, robot)


def _plan_crossing(mission, method, robot, positions, progress, samples, windows, max_iterations, dense_rate,
                   max_refinements, start) -> PlanResult:
    """A singularity-crossing mission (:mod:`planners.crossing`): ``method`` "none" gives the first
    guess, any other the optimised crossing (the crossing has its own method)."""
    from planners.crossing import CrossingOutcome, _report, crossing_layout, first_guess, optimise_crossing

    n_via = tuple(int(n) for n in mission.via_points)
    duration = float(np.sum(mission.times))
    if method == "none":
        guess = first_guess(robot, positions[0], positions[-1], duration, n_via)
        report = _report(robot, guess, n_via, dense_rate)
        outcome = CrossingOutcome("first guess", guess, n_via, report, report)
    else:
        outcome = optimise_crossing(robot, positions[0], positions[-1], duration, n_via, alpha=mission.alpha,
                                    progress=progress, samples_per_segment=samples, windows_per_segment=windows,
                                    max_iterations=max_iterations, dense_rate=dense_rate,
                                    max_refinements=max_refinements)
    index, _ = crossing_layout(n_via)
    is_way = np.zeros(len(outcome.trajectory.points), dtype=bool)
    is_way[[0, index, -1]] = True
    return PlanResult(mission, "first guess" if method == "none" else "crossing", float(mission.alpha),
                      outcome.trajectory, is_way, outcome.report, outcome.initial, outcome.stages,
                      time.perf_counter() - start, robot, outcome)
