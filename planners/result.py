"""What a planning method returns: :class:`PlanResult`, and its motion sampled for plots and files; the
normalisation of the objective J (3.26).

Every method of :data:`planners.methods.METHODS` returns a :class:`PlanResult`: the motion (a
:class:`~planners.trajectory.polynomial.PiecewisePolynomial`), its dense-grid
:class:`~planners.problem.report.MotionReport`, the reference that normalises J (3.26), and the NLP solves
(:class:`~planners.optimisation.solving.StageReport`).

The normalisation (:func:`normalisation`). The seed divides each term of J by its value on the
stop-at-every-way-point motion: J = alpha J_e / J_e0 + (1 - alpha) J_phi / J_phi0, so that J = 1 there. A
term of that motion can be zero, or zero up to round-off: every term when the robot does not move (a hover:
all way points equal), J_phi0 when no drone rolls (an FPR that moves straight up or down keeps its rolls, and
J_phi0 comes out near 1e-33). Dividing by it makes J a ratio of round-off (or 0 / 0). Each term is therefore
divided by the larger of its reference value and a floor, the least value of the term that means anything:

* J_e: n_d eps T, the planner's own resolution of J_e (it smooths ``|P|`` with eps =
  :data:`planners.problem.motion.POWER_SMOOTHING` W, which changes J_e by up to eps per drone);
* J_phi: n_d theta^2 / T with theta = :data:`ROLL_RESOLUTION` (a micro-radian): every drone rolling by less than
  any attitude sensor resolves, at a steady rate over the mission.

(n_d drones, T the mission's duration.) A real motion's terms are far above the floors (on 120 seeded random
one-travel missions of the FPR and the prototype, J_e0 at least 2 times its floor and J_phi0 10^8 times; on the
built-in missions 75 to 400 times and 10^11 times or more), so J is the seed's there. A hover is then a valid mission:
its best motion is the hover (J = 0, nothing to gain); a vertical travel of the FPR weighs any roll its
optimisation would add against the micro-radian (it keeps the drones level).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fpr.model.inverse_dynamics import MOTION_ORDER, MotionInputs, inverse_dynamics
from planners.problem.motion import POWER_SMOOTHING
from planners.problem.report import MotionReport
from planners.trajectory.polynomial import PiecewisePolynomial

#: How tables and figures name a motion by its method; any other method ``m`` is "optimised (m)".
METHOD_LABELS = {"none": "stop at way points", "crossing": "optimised crossing",
                 "first guess": "first guess (crossing)"}


ROLL_RESOLUTION = 1e-6
"""A roll angle below what any drone's attitude sensing resolves [rad] (the floor of J_phi0, module docstring)."""


def normalisation_floors(robot, duration: float) -> tuple[float, float]:
    """The least values of J_e0 and J_phi0 that normalise J (module docstring) [J, rad^2/s].

    Args:
        robot: the robot (its number of drones).
        duration: the mission's duration [s].
    """
    n = robot.n_drones
    return n * POWER_SMOOTHING * duration, n * ROLL_RESOLUTION ** 2 / duration


def normalisation(robot, duration: float, reference_terms) -> tuple[float, float]:
    """(J_e0, J_phi0) that normalise J: the stop-at-way-points motion's terms, each at least its floor
    (:func:`normalisation_floors`, module docstring) [J, rad^2/s].

    Args:
        robot: the robot.
        duration: the mission's duration [s].
        reference_terms: (J_e, J_phi) of the stop-at-every-way-point motion (or of the first guess of a
            singularity crossing) [J, rad^2/s].
    """
    floors = normalisation_floors(robot, duration)
    return tuple(max(float(v), floor) for v, floor in zip(reference_terms, floors, strict=True))


def method_label(method: str) -> str:
    """How tables and figures name a motion planned with ``method`` (:data:`METHOD_LABELS`)."""
    return METHOD_LABELS.get(method, f"optimised ({method})")


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
        mission: the :class:`planners.missions.mission.Mission`.
        method: the method that planned it (a name of :data:`planners.methods.METHODS`; ``"first guess"``
            for a crossing mission's reference).
        alpha: the weight used.
        trajectory: the motion, a :class:`~planners.trajectory.polynomial.PiecewisePolynomial`.
        is_way: (m+1,) True for way points, False for via points.
        report: dense-grid :class:`~planners.problem.report.MotionReport` of ``trajectory``.
        reference: dense-grid report of the stop-at-every-way-point motion (J_e0, J_phi0).
        stages: the NLP solves, in order.
        wall_time: total planning time [s] (set by :func:`planners.optimize.plan`).
        robot: the robot it was planned for.
        crossing: for a singularity-crossing mission, the
            :class:`planners.crossing.solve.CrossingOutcome` (``reference`` is then its first guess, the
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
    def normalisation(self) -> tuple[float, float]:
        """(J_e0, J_phi0) that normalise J on the dense grid: the reference's, each at least its floor
        (:func:`normalisation`) [J, rad^2/s].
        """
        return normalisation(self.robot, float(self.trajectory.knots[-1] - self.trajectory.knots[0]),
                             (self.reference.J_e, self.reference.J_phi))

    @property
    def J(self) -> float:
        """alpha J_e / J_e0 + (1 - alpha) J_phi / J_phi0 (3.26), dense grid, normalised by :attr:`normalisation`."""
        energy, perturbation = self.normalisation
        return self.alpha * self.report.J_e / energy + (1 - self.alpha) * self.report.J_phi / perturbation

    @property
    def label(self) -> str:
        """How tables and figures name this motion ("stop at way points", "optimised (two-step)"...)."""
        return method_label(self.method)

    @property
    def solver_success(self) -> bool:
        """Every NLP solve ended with the solver reporting success."""
        return all(s.success for s in self.stages)

    def sampled(self, rate: float = 200.0, label: str | None = None, robot=None) -> SampledPlan:
        """The motion sampled at ``rate`` [Hz] (end time included) with its inputs."""
        robot = robot or self.robot
        t, motion = self.trajectory.sample(rate, order=MOTION_ORDER)
        return SampledPlan(label or method_label(self.method), t, motion[:5], inverse_dynamics(robot, motion),
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
            "J_normalisation": list(self.normalisation),
            **self.report.peaks(robot),
            "wall_time_s": self.wall_time,
            "constraints": {n: {"margin": c.margin, "unit": c.unit, "time_s": c.time, "detail": c.detail,
                                "satisfied": c.satisfied} for n, c in self.report.constraints.items()},
            "violated": [c.name for c in self.report.violations],
            "stages": [dict(vars(s)) for s in self.stages],  # copies: the document may be edited (split_timings)
            **({"crossing": self.crossing.summary(robot)} if self.crossing is not None else {}),
        }
