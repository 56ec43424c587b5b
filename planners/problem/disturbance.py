"""A known external force in the planning problem: the replanner plans *against* a gust.

A gust (:class:`planners.missions.events.GustEvent`) pushes with a world force F [N] (fixed direction, its strength
ramping in and out: :func:`gust_profile`) on the robot kind's task point (the FPR's end-effector) or on a
drone. In the planning model (the seed's point-mass drones,
3.12) it is the generalised force Q_ext = J_p(s)^T F on the chain coordinates, J_p the Jacobian of the point
it pushes (the task point: :meth:`fpr.robots.base.RobotKind.task_points`, differentiated by complex step;
a drone: its joint, where the planning model puts its mass), and the drones must then give
J_h^T F_drones = M_s s'' + c_s - Q_ext (:func:`fpr.model.inverse_dynamics.inverse_dynamics`'s
``external``): the thrusts, rolls, torques and rotor speeds (3.48) of a motion flown in the gust.

:class:`DisturbedProblem` is the planning NLP (:class:`planners.problem.motion.MotionProblem`, same objective and
constraints) with that force at its grid nodes; :func:`dense_check` is the dense-grid check of a motion
with it. Q_ext is evaluated at the first guess's positions and kept fixed while the NLP is solved: exact
for the FPR's end-effector (p = [y, z], J_p constant), an approximation for a force on a drone.

What the replanner knows of the gust is said by the caller (:mod:`fpr.sim.replanning`): here the force is
*given*.

**Control headroom in the wind.** The thesis bounds a rotor speed by w >= 0 (3.48) with no design margin on
that side (the high side keeps m_gr = 150 rad/s). A plan flown in a wind loads the drones unevenly: on the
``gust`` mission in 8 N along -y (its earlier force) the re-optimised travel has drone 2 carrying ~6 N rolled
by 0.3 rad
against the chain's pull at its offset joint, which takes a steady roll torque of 0.3-0.5 N m, and a rotor
of it down to 72 rad/s: at the drone's torque authority (f l / 2 = 0.53 N m), where any correction of the
controller saturates that rotor at 0. So the NLP of a motion in a known wind asks every rotor to keep
:data:`CONTROL_HEADROOM` above 0 (its ``rotor_speed_low`` rows are w^2 - w_h^2 >= 0); the check of the
result (:func:`dense_check`, which decides whether a replan is used) keeps the thesis' w >= 0, so that a
replan which does not reach the headroom within its iterations is still used when it holds every
constraint of the thesis (better than the plan in force, made without the wind). A motion without a known
gust keeps the thesis' bound in both.
"""

from __future__ import annotations

import numpy as np

from fpr.model.inverse_dynamics import inverse_dynamics
from fpr.model.jets import Jet
from planners.missions.events import smooth_ramp
from planners.problem.motion import (
    CONSTRAINT_KINDS,
    MotionProblem,
    constraint_kind,
    constraint_rows,
)
from planners.problem.report import FEASIBILITY_TOLERANCE, evaluate_motion
from planners.trajectory.polynomial import PiecewisePolynomial

_STEP = 1e-30

#: w_h [rad/s]: the least rotor speed of a plan flown in a known wind (module docstring).
CONTROL_HEADROOM = 225.0


def task_jacobian(robot, s) -> np.ndarray:
    """d p / d s of the robot kind's task point p at samples s (N, n_s), shape (N, len(force_axes), n_s)
    [m/m, m/rad].
    """
    s = np.atleast_2d(np.asarray(s, dtype=float))
    n = s.shape[-1]
    out = np.empty(s.shape[:-1] + (len(robot.kind.force_axes), n))
    for j in range(n):
        probe = s.astype(complex)
        probe[..., j] += 1j * _STEP
        out[..., j] = np.imag(np.asarray(robot.kind.task_points(probe)[0])) / _STEP
    return out


#: Rise time of the planned gust [s]: a step in the force cannot be flown (the drones must roll into it),
#: so the plan and the feed-forward take it as a smoothed box, rising over RISE from the gust's start and
#: falling over RISE from its end (:func:`gust_profile`).
RISE = 0.5


def gust_profile(gust, t, rise: float = RISE) -> np.ndarray:
    """The planned share (0..1) of ``gust``'s force at times t [s] and its two time derivatives, (3, N).

    A gust with its own onset (``gust.rise`` > 0) is planned as it blows (:meth:`GustEvent.strength`);
    a step gust as a box from ``at`` to ``at + duration`` smoothed by a C2 ramp of ``rise`` [s] at both
    ends, lagging the true force (``rise`` 0: the box itself).
    """
    t = np.asarray(t, dtype=float)
    if gust.rise > 0.0 or rise <= 0:  # its own onset, or the box itself (a step gust's strength)
        return gust.strength(t)
    return smooth_ramp((t - gust.at) / rise, rise) - smooth_ramp((t - gust.at - gust.duration) / rise, rise)


def generalized_gust(robot, gusts, t, s, rise: float = RISE) -> np.ndarray | None:
    """Q_ext [N or N m] of the ``gusts`` at each time t (N,) [s], at positions s (N, n_s), with its first
    two time derivatives: shape (3, N, n_s), or None when none pushes.

    Only the components of each force along the robot kind's force axes act on the chain (a planar robot's:
    world y, z); each force is weighted by its :func:`gust_profile` (``rise`` [s]). The derivatives are those of
    the profile (J_p held: exact for the FPR's end-effector).
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    s = np.atleast_2d(np.asarray(s, dtype=float))
    out, jac_task, jac_hinges = None, None, None
    axes = ["xyz".index(a) for a in robot.kind.force_axes]
    k = len(axes)
    for gust in gusts:
        on = gust_profile(gust, t, rise)
        if not on.any():
            continue
        force = np.asarray(gust.force, dtype=float)[axes]
        index = gust.drone_index()
        if index is None:
            jac_task = task_jacobian(robot, s) if jac_task is None else jac_task
            jac = jac_task
        else:
            if jac_hinges is None:
                jac_hinges = robot.kind.chain_jacobian(s)
            jac = jac_hinges[..., k * index : k * (index + 1), :]
        q = np.einsum("nij,i->nj", jac, force)[None] * on[:, :, None]
        out = q if out is None else out + q
    return out


class DisturbedProblem(MotionProblem):
    """:class:`planners.problem.motion.MotionProblem` flown against known gusts (module docstring).

    Args:
        *args, **kwargs: those of :class:`~planners.problem.motion.MotionProblem`.
        gusts: the gust events the planner knows.
        start_time: the absolute time of the problem's first point [s] (its node times start at 0).
        headroom: w_h [rad/s], the least rotor speed asked for at every node of a problem in which a gust
            pushes somewhere (0: the thesis' w >= 0).
    """

    def __init__(self, *args, gusts=(), start_time: float = 0.0, headroom: float = CONTROL_HEADROOM,
                 **kwargs):
        super().__init__(*args, **kwargs)
        #: w_h, the rotors' headroom the NLP asks for at every node when a gust pushes in it [rad/s]
        self.headroom = float(headroom)
        self.gusts = tuple(gusts)
        self.start_time = float(start_time)
        first = self.motion(self.points)[0]
        self.external = generalized_gust(self.robot, self.gusts, self.start_time + self.t, first)

    def _external(self, n_samples: int):
        if self.external is None:
            return None
        # one force a node; with the complex step (MotionProblem.derivatives "complex"), each of a node's
        # perturbed copies gets its node's force
        return Jet(np.tile(self.external, (1, n_samples // self.external.shape[1], 1)))

    def _inputs(self, motion):
        """The inverse-dynamics inputs of ``motion`` flown in the gusts (Q_ext at each node)."""
        return inverse_dynamics(self.robot, motion, external=self._external(motion.shape[1]))

    def _quantities(self, motion):
        """:meth:`MotionProblem._quantities` with the rotors kept :data:`CONTROL_HEADROOM` above 0 when a
        gust pushes (the scaled rows w^2 / w_lim^2 become (w^2 - w_h^2) / w_lim^2).
        """
        integrands, rows = super()._quantities(motion)
        if self.external is not None and self.external.any() and self.headroom > 0:
            low = [i for i, name in enumerate(self._rows_names) if name.startswith("rotor_speed_low")]
            rows[:, low] -= (self.headroom / _speed_limit(self.robot)) ** 2
        return integrands, rows


def dense_check(robot, part: PiecewisePolynomial, rate: float, start_time: float = 0.0, gusts=()):
    """Every planning constraint of ``part`` at ``rate`` [Hz] plus its knots, flown in the ``gusts``.

    The check of :func:`planners.problem.report.evaluate_motion` (same rows, natural units, same tolerances), with
    the gusts' Q_ext, and derivatives 0..4 only (no singularity crossing in a replanned part).

    Args:
        robot: the robot.
        part: the motion, its time 0 at ``start_time`` [s] (absolute).
        rate: sampling rate [Hz].
        start_time: absolute time of the part's start [s] (when the gusts push).
        gusts: known gust events.

    Returns:
        (feasible, the violated constraint names (worst first), the number of samples).
    """
    t = dense_times(part, rate)
    motion = part.evaluate(t, order=4)
    feasible, violated = verdict(robot, motion, inputs_in_gusts(robot, motion, start_time + t, gusts))
    return feasible, violated, int(t.size)


def inputs_in_gusts(robot, motion, t, gusts=()):
    """:func:`fpr.model.inverse_dynamics.inverse_dynamics` of ``motion`` (its derivatives at absolute times t
    [s]) flown in the ``gusts`` (their Q_ext and its time derivatives, :func:`generalized_gust`); no gust
    pushing: the motion's own inputs.
    """
    external = generalized_gust(robot, gusts, t, motion[0]) if gusts else None
    return inverse_dynamics(robot, motion, external=None if external is None else Jet(external))


def dense_times(part: PiecewisePolynomial, rate: float) -> np.ndarray:
    """The times [s] of :func:`dense_check`: ``part`` sampled at ``rate`` [Hz], plus its knots, sorted."""
    return np.unique(np.concatenate([part.sample_times(rate), part.knots]))


def verdict(robot, motion, inputs) -> tuple[bool, list[str]]:
    """Feasibility of dense samples (:func:`dense_check`'s): every planning row (natural units) within its
    unit's tolerance; a constraint is violated when its smallest margin is below -``FEASIBILITY_TOLERANCE``
    of its unit (1 mm, 1 mrad, 1 rad/s...).

    Args:
        robot: the robot.
        motion: the samples' s and derivatives, (5, N, n_s).
        inputs: their :class:`fpr.model.inverse_dynamics.MotionInputs`.

    Returns:
        (feasible, the violated constraint names, worst first).
    """
    rows, names, _ = constraint_rows(robot, motion, inputs, scaled=False)
    worst: dict[str, float] = {}
    for col, name in enumerate(names):
        tolerance = FEASIBILITY_TOLERANCE[CONSTRAINT_KINDS[constraint_kind(name)][0]]
        worst[name] = min(worst.get(name, np.inf), float(rows[:, col].min()) / tolerance)
    bad = sorted((m, name) for name, m in worst.items() if m < -1.0)
    return not bad, [name for _, name in bad]


def evaluate_in_gusts(robot, trajectory: PiecewisePolynomial, gusts, rate: float = 500.0):
    """:func:`planners.problem.report.evaluate_motion` of a motion flown in known ``gusts`` (absolute times [s]).

    The same rows, sampling and report, with the gusts' Q_ext in the inverse dynamics (the rotor speeds
    3.48 of the motion in the wind). No gust pushing: :func:`~planners.problem.report.evaluate_motion` as it is.
    """

    def external(t, s):
        force = generalized_gust(robot, gusts, t, s)
        return None if force is None else Jet(force)

    return evaluate_motion(robot, trajectory, rate, external=external if gusts else None)


def _speed_limit(robot) -> float:
    """w_lim = w_max - m_gr [rad/s], the scale of the NLP's rotor rows (``constraint_rows``)."""
    return robot.rotor_constants.max_speed - robot.margins.rotor_speed



__all__ = ["DisturbedProblem", "dense_check", "dense_times", "evaluate_in_gusts", "generalized_gust",
           "inputs_in_gusts", "task_jacobian", "verdict"]
