"""Crossing the prototype's Type-2 singularity (seed ch. 4): the seed's approaches and ours.

A motion of the prototype can pass q2 = 0 (links aligned) with finite drone forces only if the crossing
criterion (4.7) holds there (:mod:`fpr.robots.prototype_singularity`). The motions are two travels
meeting at the crossing point, and :class:`planners.crossing.problem.CrossingProblem` is their NLP
(which unknowns are free, which constraints hold). Here are the ways of solving it:

* :func:`seed_approach` reproduces the seed's two approaches (4.2.1, 4.2.2) with this package's
  model and parameters: their fixed crossing state and travel times, their two steps, their
  constraints (C4 only at the crossing).
* :func:`optimise_crossing` frees everything together: the crossing state, the travel times and
  the via points, from a first guess in the drone's polar coordinates (:func:`first_guess`), which
  is what finds a motion within the limits. It is the planning method ``"crossing"``
  (:mod:`planners.methods.crossing`), which :func:`planners.optimize.plan` runs for a mission with
  ``cross_singularity = true``.

Each returns a :class:`CrossingOutcome`: the motion, its dense-grid report (crossing-side
constraints and the least thrust, :func:`crossing_report`) and the NLP solves.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from fpr.model import jets
from fpr.model.errors import PlannerArgumentError
from fpr.model.jets import Jet
from fpr.robots.prototype_singularity import (
    SEED_END,
    SEED_START,
    acceleration_from_chain_force,
    criterion,
    min_thrust,
    nearest_criterion_acceleration,
)
from planners.crossing.problem import (
    GROUPS,
    CrossingProblem,
    add_via_points,
    crossing_layout,
    crossing_motion,
    travel_times,
)
from planners.optimisation.solving import Grid, solve_refining, solve_stage
from planners.problem.report import MotionReport, evaluate_motion
from planners.trajectory.polynomial import N_DERIVS, PiecewisePolynomial

#: The successive first guesses of :func:`optimise_crossing`: (drone polar angle at the crossing
#: [rad], fraction of the mission's total time). The chain nearly upright, where gravity acts least
#: across it; the travel times are optimised anyway, the fraction only changes where they start.
CROSSING_STARTS = ((1.2, 1.0), (1.3, 1.0), (1.1, 1.0), (1.2, 0.75), (1.3, 0.75))

#: A solve that stops infeasible on its grid by at most this (the SQP's scaled violation) is continued on a finer
#: grid from where it stopped, as a feasible one that fails the dense check is (:func:`optimise_crossing`): near
#: the singularity the SQP can stall a hair from the feasible set ("locally infeasible" at 1e-6, the constraint
#: Jacobian nearly rank-deficient), and whether it does is decided by round-off.
REFINE_BELOW = 1e-4

#: Violations are compared between starts relative to these sizes (per unit of the report).
FEASIBILITY_SCALE = {"m": 0.1, "rad": 0.1, "rad/s": 100.0, "N": 1.0}

#: The crossing's NLP solves stop when an iteration improves J by less than this (SQP).
CROSSING_TOLERANCE = 1e-4


# ---------------------------------------------------------------------------------------- a first guess
def _smoothstep(x):
    """The 9th-degree step: 0 -> 1 on [0, 1] with derivatives 1..4 zero at both ends (works on Jets)."""
    return x**5 * (126.0 - 420.0 * x + 540.0 * x**2 - 315.0 * x**3 + 70.0 * x**4)


def designed_motion(start, end, duration: float, crossing_angle: float, t) -> np.ndarray:
    """A smooth crossing motion built in the drone's polar coordinates, derivatives 0..6 at times t.

    The drone joint's polar angle theta = q1 + q2/2 and the elbow angle q2 are prescribed:
    q2 = c (q2_a (1 + c)/2 - q2_b (1 - c)/2), c = cos(pi S(t/T)), S the 9th-degree step, so q2
    leaves q2_a at rest, passes 0 once at T/2 and stops at q2_b; theta goes from its start to its
    end value with S and bulges to ``crossing_angle`` at T/2 (a sin^6 bump). With the chain
    nearly vertical at the crossing, gravity barely acts across it (the criterion then asks for
    little), which is what makes this a good start. Not a solution: the criterion does not hold.

    Returns:
        shape (7, N, 2): xi and its derivatives 1..6.
    """
    start, end = np.asarray(start, float), np.asarray(end, float)
    x = Jet.variable(np.atleast_1d(np.asarray(t, float)), 6) / duration
    step = _smoothstep(x)
    c = jets.cos(np.pi * step)
    q2 = c * (0.5 * start[1] * (1.0 + c) - 0.5 * end[1] * (1.0 - c))
    theta_a, theta_b = start[0] + 0.5 * start[1], end[0] + 0.5 * end[1]
    bump = jets.sin(np.pi * x) ** 6
    theta = theta_a + (theta_b - theta_a) * step + (crossing_angle - 0.5 * (theta_a + theta_b)) * bump
    q1 = theta - 0.5 * q2
    return np.stack([q1.d, q2.d], axis=-1)


def first_guess(robot, start, end, duration: float, n_via, crossing_angle: float = 1.2) -> PiecewisePolynomial:
    """The :func:`designed_motion` as a crossing motion (travels of ``duration``/2, ``n_via`` via
    points each), its crossing acceleration moved onto the criterion's line (along n: the drone's
    acceleration is kept).
    """
    half = 0.5 * float(duration)
    d = designed_motion(start, end, duration, crossing_angle, [half])[:, 0]
    point = np.array(d[:N_DERIVS])
    point[0, 1] = 0.0
    point[2], _ = nearest_criterion_acceleration(robot, point[0, 0], point[1], point[2])
    motion = add_via_points(crossing_motion(start, end, point, [half, half]), n_via)
    points = np.array(motion.points)
    index, _ = crossing_layout(n_via)
    for i in range(1, len(points) - 1):
        if i != index:
            points[i] = designed_motion(start, end, duration, crossing_angle, [motion.knots[i]])[:N_DERIVS, 0]
    return PiecewisePolynomial(points, motion.durations)


def count_crossings(trajectory: PiecewisePolynomial, rate: float = 2000.0) -> int:
    """How many times q2 changes sign along ``trajectory`` (sampled at ``rate`` [Hz])."""
    t = trajectory.sample_times(rate)
    q2 = trajectory.evaluate(t, order=0)[0][:, 1]
    signs = np.sign(q2[np.abs(q2) > 1e-9])
    return int(np.count_nonzero(np.diff(signs)))


# ---------------------------------------------------------------------------------------- solving
@dataclass
class CrossingOutcome:
    """A crossing motion and what it takes.

    Attributes:
        name: what produced it.
        trajectory: the motion (points laid out by :func:`crossing_layout` with ``n_via``).
        n_via: via points per travel.
        report: dense-grid :class:`planners.problem.report.MotionReport` (crossing-side constraints,
            :func:`crossing_report`).
        initial: the same for the motion the optimisation started from.
        stages: the NLP solves (:class:`planners.optimisation.solving.StageReport`).
        wall_time: [s].
    """

    name: str
    trajectory: PiecewisePolynomial
    n_via: tuple
    report: object
    initial: object
    stages: list = field(default_factory=list)
    wall_time: float = 0.0

    @property
    def index(self) -> int:
        """Index of the crossing point."""
        return crossing_layout(self.n_via)[0]

    @property
    def crossing_time(self) -> float:
        """When q2 = 0 [s]."""
        return float(self.trajectory.knots[self.index])

    @property
    def crossing_point(self) -> np.ndarray:
        """xi_s and its derivatives 1..4 at the crossing, (5, 2)."""
        return np.array(self.trajectory.points[self.index])

    @property
    def times(self) -> np.ndarray:
        """The two travel times [s]."""
        return travel_times(self.trajectory, self.n_via)

    def criterion_residual(self, robot) -> float:
        """n^T (M xi_s'' + c) at the crossing [N m] (4.7; 0 for a finite force)."""
        p = self.crossing_point
        return criterion(robot, p[0], p[1], p[2])

    @property
    def crossings(self) -> int:
        """Sign changes of q2 along the motion (1 wanted)."""
        return count_crossings(self.trajectory)

    @property
    def feasible(self) -> bool:
        """Every constraint holds on the dense grid, and q2 changes sign exactly once."""
        return self.report.feasible and self.crossings == 1

    def summary(self, robot) -> dict:
        """JSON-friendly numbers: peaks, crossing, constraints, stages."""
        peaks = self.report.peaks(robot)
        peaks.pop("least_singularity_margin_rad", None)
        return {
            "name": self.name,
            "feasible": self.feasible,
            "crossings": self.crossings,
            "crossing_time_s": self.crossing_time,
            "crossing_point": self.crossing_point.tolist(),
            "travel_times_s": self.times.tolist(),
            "criterion_residual_Nm": self.criterion_residual(robot),
            **peaks,
            "J_e": self.report.J_e,
            "J_phi": self.report.J_phi,
            "violated": [c.name for c in self.report.violations],
            "wall_time_s": self.wall_time,
            "stages": [dict(vars(st)) for st in self.stages],  # copies: the document may be edited (split_timings)
        }


def crossing_report(robot, trajectory: PiecewisePolynomial, n_via, rate: float = 500.0) -> MotionReport:
    """:func:`planners.problem.report.evaluate_motion` of a crossing motion laid out by
    :func:`~planners.crossing.problem.crossing_layout` with ``n_via``: the assembly-mode bounds on
    each side of the crossing, and the least thrust (:func:`~fpr.robots.prototype_singularity.min_thrust`).
    """
    index, _ = crossing_layout(n_via)
    return evaluate_motion(robot, trajectory, rate, crossing_time=float(trajectory.knots[index]),
                           min_thrust=min_thrust(robot))


def _normalisation(robot, trajectory, n_via, grid: Grid) -> tuple[float, float]:
    """(J_e, J_phi) of ``trajectory`` on ``grid`` (smoothed |.|), floored at 1e-9: the J_e0, J_phi0 of 3.26."""
    problem = CrossingProblem(robot, trajectory.points, travel_times(trajectory, n_via), n_via, (), 0.5,
                              (1.0, 1.0), samples_per_segment=grid.samples_per_segment,
                              windows_per_segment=grid.windows_per_segment)
    terms = problem.evaluate(problem.x0()).terms
    return float(max(terms[0], 1e-9)), float(max(terms[1], 1e-9))


def _stage(robot, trajectory, n_via, free, alpha, normalisation, name, progress, grid: Grid,
           max_iterations, smooth_crossing=True):
    """One :class:`CrossingProblem` solve from ``trajectory``: (its motion, its StageReport)."""
    problem = CrossingProblem(robot, trajectory.points, travel_times(trajectory, n_via), n_via, free, alpha,
                              normalisation, samples_per_segment=grid.samples_per_segment,
                              windows_per_segment=grid.windows_per_segment, smooth_crossing=smooth_crossing)
    x, stage = solve_stage(problem, problem.x0(), name, progress, max_iterations, CROSSING_TOLERANCE)
    return problem.trajectory(x), stage


#: The seed's two approaches (4.2.1, 4.2.2): crossing point q1_s, velocity, how the acceleration is
#: set, and the travel times of their initial guesses.
SEED_APPROACHES = {
    1: {"q1": 1e-4, "velocity": (-1.0, 2.0), "acceleration": (-10.7243, 24.6296), "times": (0.4, 1.5)},
    2: {"q1": 1e-4, "velocity": (-3.0, 3.0), "chain_force": (0.0, 5.0), "times": (1.25, 1.2)},
}


def seed_approach(robot, approach: int, *, alpha: float = 0.5, progress=None, samples_per_segment: int = 17,
                  windows_per_segment: int = 4, max_iterations: int = 60, dense_rate: float = 500.0,
                  start=SEED_START, end=SEED_END) -> CrossingOutcome:
    """One of the seed's approaches, with this package's model, parameters and solver.

    Approach 1 (4.2.1): xi_s' = [-1, 2]; the seed's xi_s'' (4.9) does not satisfy the criterion
    with our parameters, so it is moved onto the criterion's line along n (the drone's
    acceleration kept). Approach 2 (4.2.2): xi_s' = [-3, 3] and the chain force f_p1 = [0, 5] N at
    the crossing give xi_s'' by the chain's direct dynamics (4.11). Both: q1_s = 1e-4 (4.1, q2_s = 0
    exactly here), the seed's travel times; step 1 optimises xi_s''', xi_s'''' (from 0), step 2 one
    via point per travel, J normalised by the initial guess (as the seed does).
    """
    if approach not in SEED_APPROACHES:
        raise PlannerArgumentError("approach", approach,
                                   f"approach={approach!r}: the seed has approaches 1 and 2")
    spec = SEED_APPROACHES[approach]
    start_time = time.perf_counter()
    q1 = spec["q1"]
    velocity = np.array(spec["velocity"])
    if approach == 1:
        acceleration, _ = nearest_criterion_acceleration(robot, q1, velocity, spec["acceleration"])
    else:
        acceleration = acceleration_from_chain_force(robot, [q1, 0.0], velocity, spec["chain_force"])
    point = np.zeros((N_DERIVS, 2))
    point[0] = [q1, 0.0]
    point[1], point[2] = velocity, acceleration
    guess = crossing_motion(start, end, point, spec["times"])
    grid = Grid(samples_per_segment, windows_per_segment)
    args = dict(grid=grid, max_iterations=max_iterations, smooth_crossing=False)  # the seed's: C4 only
    normalisation = _normalisation(robot, guess, (0, 0), grid)
    step1, stage1 = _stage(robot, guess, (0, 0), ("high",), alpha, normalisation,
                           f"seed approach {approach}, step 1", progress, **args)
    with_via = add_via_points(step1, (1, 1))
    step2, stage2 = _stage(robot, with_via, (1, 1), ("vias",), alpha, normalisation,
                           f"seed approach {approach}, step 2", progress, **args)
    return CrossingOutcome(f"seed approach {approach}", step2, (1, 1),
                           crossing_report(robot, step2, (1, 1), dense_rate),
                           crossing_report(robot, guess, (0, 0), dense_rate), [stage1, stage2],
                           time.perf_counter() - start_time)


def optimise_crossing(robot, start, end, duration: float, n_via=(2, 2), *, alpha: float = 0.5,
                      starts=CROSSING_STARTS, progress=None, samples_per_segment: int = 17,
                      windows_per_segment: int = 4, max_iterations: int = 100, dense_rate: float = 500.0,
                      max_refinements: int = 2) -> CrossingOutcome:
    """Our method: everything the seed held fixed is free.

    From :func:`first_guess` (total ``duration`` [s] times ``starts[0][1]``, crossing with the drone at
    polar angle ``starts[0][0]``), one NLP frees the crossing state (q1_s, xi_s', xi_s'' on the criterion's
    line, xi_s''', xi_s''''), the via points and both travel times. As for the other methods
    (:func:`planners.optimisation.solving.solve_refining`), a result that holds on the optimisation grid (to
    :data:`REFINE_BELOW`) but not on the dense grid is solved again on a grid twice as fine (at most
    ``max_refinements`` times). A start that ends infeasible is followed by the next of ``starts``; the
    first feasible result is returned, else the one with the least (relative) violation. Every solve is in
    ``stages``.
    """
    start_time = time.perf_counter()
    n_via = tuple(int(n) for n in n_via)
    best, best_worst, all_stages = None, -np.inf, []
    for attempt, (angle, fraction) in enumerate(starts):
        guess = first_guess(robot, start, end, fraction * duration, n_via, angle)
        grid = Grid(samples_per_segment, windows_per_segment)
        normalisation = _normalisation(robot, guess, n_via, grid)
        label = "crossing" if attempt == 0 else \
            f"crossing, start {attempt + 1} (crossing angle {angle:g} rad, {fraction * duration:g} s)"

        def solve(grid, previous, guess=guess, normalisation=normalisation, label=label):
            trajectory, stage = _stage(robot, guess if previous is None else previous, n_via, GROUPS, alpha,
                                       normalisation, label + grid.suffix, progress, grid, max_iterations)
            return trajectory, [stage]

        trajectory, report, stages = solve_refining(
            solve, lambda motion: crossing_report(robot, motion, n_via, dense_rate), grid, max_refinements,
            refine_below=REFINE_BELOW)
        all_stages += stages
        outcome = CrossingOutcome("optimised crossing", trajectory, n_via, report,
                                  crossing_report(robot, guess, n_via, dense_rate))
        if outcome.feasible:
            best = outcome
            break
        worst = min((c.margin / FEASIBILITY_SCALE[c.unit] for c in report.violations), default=0.0)
        if best is None or worst > best_worst:
            best, best_worst = outcome, worst
    best.stages = all_stages
    best.wall_time = time.perf_counter() - start_time
    return best
