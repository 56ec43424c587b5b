"""What a motion does, checked on a dense grid: :func:`evaluate_motion` and its :class:`MotionReport`.

A motion planned on the optimisation grid (:mod:`planners.problem.motion`) is sampled again at 500 Hz (and at
every knot): the inverse dynamics (:func:`fpr.model.inverse_dynamics.inverse_dynamics`) gives the
thrusts, rolls, torques and rotor speeds; J_e (3.24, exact |.|) and J_phi (3.25) are integrated by the
trapezoidal rule; every constraint of :data:`planners.problem.motion.CONSTRAINT_KINDS` is reported by its
worst value (:class:`ConstraintReport`), in natural units, against :data:`FEASIBILITY_TOLERANCE`.
A plan's feasibility is this report's, not the optimiser's verdict.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fpr.model.inverse_dynamics import MOTION_ORDER, MotionInputs, inverse_dynamics
from planners.problem.motion import CONSTRAINT_KINDS, constraint_kind, constraint_rows, objective_rates
from planners.trajectory.polynomial import PiecewisePolynomial

#: Largest violation of a constraint still counted as satisfied on the dense grid, per unit.
FEASIBILITY_TOLERANCE = {"m": 1e-6, "rad": 1e-6, "rad/s": 1e-3, "N": 1e-6, "1": 1e-6}


@dataclass(frozen=True)
class ConstraintReport:
    """The worst value of one constraint along a motion.

    Attributes:
        name: e.g. ``ground_1``, ``roll_2``, ``rotor_speed_high_1``.
        kind: its kind (key of :data:`planners.problem.motion.CONSTRAINT_KINDS`).
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
        J_e: energy index (3.24, exact ``|.|``) [J].
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
        kind = robot.kind
        height = self.inputs.joint_position[..., kind.force_axes.index("z")]
        return {
            "peak_thrust_N": float(self.inputs.thrust.max()),
            "peak_rotor_force_N": float(robot.rotor_constants.thrust_coefficient * w2.max()),
            "peak_rotor_speed_rad_s": float(self.inputs.rotor_speed.max()),
            "least_rotor_speed_rad_s": float(self.inputs.rotor_speed.min()),
            "peak_roll_rad": float(np.abs(self.inputs.roll).max()),
            "least_ground_clearance_m": float(height.min() - kind.ground_height),
            "least_singularity_margin_rad": float(kind.singularity_distance(self.motion[0]).min()),
        }


def evaluate_motion(robot, trajectory: PiecewisePolynomial, rate: float = 500.0,
                    crossing_time: float | None = None, min_thrust: float | None = None,
                    external=None) -> MotionReport:
    """Sample ``trajectory`` at ``rate`` [Hz] (plus every knot) and check every constraint.

    Args:
        robot: the robot that flies the motion.
        trajectory: the planned motion of the planning coordinates s(t).
        rate: sampling rate of the check [Hz]; the knots are sampled as well.
        crossing_time: for a prototype motion that crosses its Type-2 singularity once
            (:mod:`planners.crossing.solve`), the time of the crossing [s]: the assembly-mode bounds are
            then checked on each side of it.
        min_thrust: also check thrust >= this [N] (``thrust_low``), or None.
        external: known external forces the motion is flown against (a gust), or None: a function of the
            sample times t (N,) [s] and positions s (N, n_s) giving what
            :func:`fpr.model.inverse_dynamics.inverse_dynamics` takes as ``external`` (or None: no force),
            e.g. :func:`planners.problem.disturbance.evaluate_in_gusts`'s.

    Returns:
        the :class:`MotionReport` (J_e, J_phi by the trapezoidal rule on the samples).
    """
    t = np.unique(np.concatenate([trajectory.sample_times(rate), trajectory.knots]))
    motion = trajectory.evaluate(t, order=MOTION_ORDER)
    inputs = inverse_dynamics(robot, motion, external=None if external is None else external(t, motion[0]))
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
