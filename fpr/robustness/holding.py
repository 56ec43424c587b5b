r"""Can the robot hold a gust at all? The static check of a steady force against the rotor limits.

A gust that the rotors cannot balance even when it blows steadily, the robot at rest, cannot be rejected by
any controller or plan: a campaign counts such gusts apart, and a user can ask before flying one
(:func:`hold_verdict`, one line).

**The check.** At a configuration s of the chain, the robot at rest (s' = s'' = 0), with the force F of the
gust on its body (the task point, or a drone's centre of mass), the drones' rolls phi_i, thrusts f_i and
roll torques tau_i must balance gravity and the gust in the robot's full model (seed 2.11, rigid drones on
their offset joints):

.. math:: g(q) = J(q)^T w(f, \tau) + J_b(q)^T F, \qquad q = (s, \phi), \quad \text{in-plane rows},

n_s + n_d equations in the 3 n_d unknowns (the chain is statically determinate: n_s = 2 n_d for the FPR and
the prototype). It is solved by Newton's method from the planning model's answer (the point-drone inverse
dynamics at rest, :func:`fpr.model.inverse_dynamics.inverse_dynamics`, whose thrust vectors are exact at
rest; the full model adds the drones' offset torques and a force at a drone's centre rather than its joint).
Each drone's rotor speeds follow from R_f^-1 [f_i, tau_i, 0, 0] (seed 3.31): the gust is **holdable** at s
when every rotor speed is within [0, w_max], the physical limits (no design margin: the question is whether
the robot can hold it at all).

**Where.** :func:`hold_check` asks it at the mission's way points the robot must reach while the gust blows
(those whose time falls in the gust, and at least the first one reached after it starts), with the gust at
its full force: poses the mission fixes, whatever the plan. (Between them the plan chooses its path, and a
replanner may move it where the gust can be held: the built-in ``gust`` mission's offline plan passes, at
7.6 s, a configuration where 6 N cannot be held at rest, which its replanned motion avoids.) A gust the
robot cannot hold at such a way point cannot be flown through within the rotor limits by any controller.

**Along a plan flown as it is** (``trajectory``: no replanner will move the path). The controller then tracks
the plan, so the robot must fly the plan's motion while the gust blows: the check asks what the drones must do
to fly it exactly with the gust's force of each instant held steady (its ramp,
:meth:`planners.missions.events.GustEvent.strength`, without the rate of its own change), from the gust's start
to its end or the end of the flight, every ``1 / rate`` s and at the way points in between: the inverse dynamics
of the plan's motion (:func:`fpr.model.inverse_dynamics.inverse_dynamics`, the planner's model, the gust's
generalised force as :func:`planners.problem.disturbance.generalized_gust` makes it), whose rotor speeds
(seed 3.48) must lie within [0, w_max]. It includes the plan's accelerations, which the robot must produce
whatever the gust: on the square, pushes of 5-6 N on a drone that can be held at rest at every pose of the plan
need a rotor below 0 where the plan turns under them. Way points are not enough either: the square passes,
between its way points, poses where an upward push on the end-effector leaves a drone tilted by 0.6-0.7 rad
with about 1-2 N of thrust, which cannot make the roll torque m_i g d_i sin(phi_i) that holds the tilt of a
drone whose joint sits d_i below its centre. (A closed loop that lags the plan need not fly it exactly: a run
counted apart may still succeed.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from fpr.model.inverse_dynamics import MOTION_ORDER, inverse_dynamics
from fpr.model.jets import Jet
from planners.missions.events import END_EFFECTOR
from planners.problem.disturbance import generalized_gust


@dataclass(frozen=True)
class StaticHold:
    """The inputs that hold the robot at rest at one configuration under a steady force.

    Attributes:
        s: the chain configuration (n_s,).
        roll: the drones' rolls phi_i (n_d,) [rad].
        thrust: f_i (n_d,) [N].
        torque: the roll torques tau_i (n_d,) [N m].
        speeds_squared: w^2 of every rotor (n_d, 4) [(rad/s)^2] (negative: no real rotor speed gives it).
        residual: the largest residual of the static equations [N or N m] (about 1e-10 when solved).
    """

    s: np.ndarray
    roll: np.ndarray
    thrust: np.ndarray
    torque: np.ndarray
    speeds_squared: np.ndarray
    residual: float

    @property
    def speeds(self) -> np.ndarray:
        """Signed rotor speeds ``sign(w^2) sqrt(|w^2|)`` (n_d, 4) [rad/s]."""
        return np.sign(self.speeds_squared) * np.sqrt(np.abs(self.speeds_squared))


def _external(robot, q, body: str, force) -> np.ndarray:
    """Generalised force of the world ``force`` (3,) on ``body`` at q, on the thesis coordinates (n,)."""
    model, data = robot.model, robot.data
    pin.computeJointJacobians(model, data, robot.to_pinocchio(q))
    pin.updateFramePlacements(model, data)
    if body == END_EFFECTOR:
        frame = model.getFrameId(robot.kind.task_frame)
    else:
        frame = robot.drone_frame_ids[int(body.split("_")[1]) - 1]
    jac = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[:3].dot(robot.T)
    return np.asarray(force, dtype=float).dot(jac)


def static_hold(robot, s, body: str = END_EFFECTOR, force=(0.0, 0.0, 0.0),
                iterations: int = 20) -> StaticHold:
    """The rolls, thrusts, roll torques and rotor speeds that hold ``robot`` at rest at ``s`` under ``force``
    on ``body`` (module docstring).

    Args:
        robot: the robot (:class:`fpr.model.robot.Robot`).
        s: the chain configuration (n_s,) [m, rad].
        body: ``"end_effector"`` (the kind's task point) or ``"drone_<i>"`` (its centre of mass).
        force: world [x, y, z] [N] (x does not act in the plane).
        iterations: Newton iterations at most.
    """
    s = np.asarray(s, dtype=float)
    n_s, n_d = s.size, robot.n_drones
    chain, rolls = robot.indices(robot.layout.chain), robot.indices(robot.layout.rolls)
    rows = np.concatenate([chain, rolls])
    force = np.asarray(force, dtype=float)
    # the planning model's answer: the thrust vectors at rest, the exact model's torques
    point_force = np.zeros((3, 1, n_s))
    jac_q = _external_chain(robot, s, body, force)
    point_force[0, 0] = jac_q
    rest = np.zeros((5, 1, n_s))
    rest[0, 0] = s
    guess = inverse_dynamics(robot, rest, external=Jet(point_force))
    unknown = np.concatenate([guess.roll[0], guess.thrust[0], guess.torque[0, :, 0]])

    def residual(u):
        q = np.zeros(robot.nq)
        q[chain], q[rolls] = s, u[:n_d]
        torque = np.zeros((n_d, 3))
        torque[:, 0] = u[2 * n_d:]
        out = robot.gravity_terms(q) - robot.generalized_input(q, u[n_d:2 * n_d], torque)
        return (out - _external(robot, q, body, force))[rows]

    value = residual(unknown)
    for _ in range(iterations):
        if np.abs(value).max() < 1e-10:
            break
        step = 1e-7
        jac = np.empty((rows.size, unknown.size))
        for k in range(unknown.size):
            probe = unknown.copy()
            probe[k] += step
            jac[:, k] = (residual(probe) - value) / step
        unknown = unknown - np.linalg.lstsq(jac, value, rcond=None)[0]
        value = residual(unknown)
    roll, thrust, torque = unknown[:n_d], unknown[n_d:2 * n_d], unknown[2 * n_d:]
    squared = np.array([robot.rotors[i].speeds_squared(thrust[i], np.array([torque[i], 0.0, 0.0]))
                        for i in range(n_d)])
    return StaticHold(s, roll, thrust, torque, squared, float(np.abs(value).max()))


def _external_chain(robot, s, body, force) -> np.ndarray:
    """Q_ext of the force on the chain coordinates at s in the planning model (rolls at 0: the chain rows of
    the full model's do not depend on the rolls for a force at the task point or a drone's joint).
    """
    q = np.zeros(robot.nq)
    q[robot.indices(robot.layout.chain)] = s
    return _external(robot, q, body, force)[robot.indices(robot.layout.chain)]


@dataclass(frozen=True)
class HoldVerdict:
    """Whether a gust can be held as a steady force where the robot must be while it blows (:func:`hold_check`).

    Attributes:
        holdable: every rotor within [0, w_max] at every way point checked.
        body, force: the gust's body and force (world [x, y, z] [N]).
        worst_time: the mission's time of the way point (or the plan's sample) with the least margin [s].
        drone, rotor: the rotor with the least margin there (1-based).
        speed: its rotor speed [rad/s] (signed: below 0 means no real speed gives it).
        margin: its distance to the nearer limit [rad/s] (negative: beyond it).
        limit: w_max [rad/s].
        samples: way points (or samples of the plan's motion) checked.
        way_point: the way point with the least margin (index), or None when a plan's motion was checked.
    """

    holdable: bool
    body: str
    force: tuple
    worst_time: float
    drone: int
    rotor: int
    speed: float
    margin: float
    limit: float
    samples: int
    way_point: int | None = 0

    def line(self) -> str:
        """One line for people."""
        size = float(np.linalg.norm(self.force[1:]))
        at = "on the plan" if self.way_point is None else f"at way point {self.way_point}"
        where = f"rotor {self.rotor} of drone {self.drone} at {self.speed:.0f} rad/s {at}, t = {self.worst_time:.2f} s"
        poses = "poses of the plan flown" if self.way_point is None else "way points"
        if self.holdable:
            return (f"holdable: {size:.2g} N on {self.body} can be held as a steady force at the {poses} "
                    f"it blows on (least margin {self.margin:.0f} rad/s to the rotor limits 0 .. "
                    f"{self.limit:.0f}: {where})")
        side = "below 0" if self.speed < self.limit / 2 else f"above {self.limit:.0f}"
        return (f"not holdable: {size:.2g} N on {self.body} cannot be held even as a steady force within the "
                f"rotor limits ({where}, {side})")


def hold_check(robot, mission, gust, trajectory=None, end: float | None = None, rate: float = 100.0) -> HoldVerdict:
    """Whether ``gust`` (a :class:`planners.missions.events.GustEvent`) can be held as a steady force where the
    robot must be while it blows (module docstring): at its full force at the way points of ``mission`` the
    robot must reach, or, with ``trajectory``, along the motion of that plan with the gust's force of each instant.

    Args:
        robot: the robot of the mission.
        mission: the :class:`planners.missions.mission.Mission` (its way points and times).
        gust: the gust (``body``, ``force``, ``at``, ``duration``, ``rise``).
        trajectory: the plan flown as it is (a :class:`planners.trajectory.polynomial.PiecewisePolynomial`,
            held at its last point after its end), or None (a replanner may move the path: the way points).
        end: with ``trajectory``, the last time flown [s] (default: the gust's end).
        rate: with ``trajectory``, samples of the plan checked per second [Hz].
    """
    times = np.concatenate([[0.0], np.cumsum(mission.times)])
    force = np.asarray(gust.force, dtype=float)
    if trajectory is None:
        poses = np.asarray(mission.positions(robot), dtype=float)
        inside = [j for j, t in enumerate(times) if gust.at <= t <= gust.at + gust.duration]
        after = [j for j, t in enumerate(times) if t >= gust.at]
        chosen = sorted(set(inside) | ({after[0]} if after else {len(times) - 1}))
        cases = [(float(times[j]), poses[j], force, j) for j in chosen]
    else:
        stop = gust.at + gust.duration if end is None else min(gust.at + gust.duration, float(end))
        when = np.arange(gust.at, stop, 1.0 / rate)
        when = np.union1d(when, times[(times >= gust.at) & (times < stop)])
        shares = np.atleast_1d(gust.strength(when)[0])
        keep = shares > 0.0
        when, shares = when[keep], shares[keep]
        if when.size == 0:  # blows after the flight: its start, at full force
            when, shares = np.array([gust.at]), np.array([1.0])
        return _along_plan(robot, gust, trajectory, when)
    limit = float(robot.rotor_constants.max_speed)
    worst = None
    for t, pose, push, way_point in cases:
        speeds = static_hold(robot, pose, gust.body, push).speeds
        margins = np.minimum(speeds, limit - speeds)
        i, k = np.unravel_index(np.argmin(margins), margins.shape)
        if worst is None or margins[i, k] < worst[0]:
            worst = (float(margins[i, k]), t, int(i) + 1, int(k) + 1, float(speeds[i, k]), way_point)
    margin, when, drone, rotor, speed, way_point = worst
    return HoldVerdict(margin >= 0.0, gust.body, tuple(float(f) for f in gust.force), when, drone, rotor,
                       speed, margin, limit, len(cases), way_point)


def _along_plan(robot, gust, trajectory, when) -> HoldVerdict:
    """:func:`hold_check` along a plan flown as it is, at the times ``when`` (module docstring): the inverse
    dynamics of the plan's motion there with the gust's force of each instant held steady.
    """
    motion = trajectory.evaluate_held(when, order=MOTION_ORDER)
    push = generalized_gust(robot, (gust,), when, motion[0], rise=0.0)  # its force as it blows
    steady = np.zeros((3, when.size, motion.shape[-1]))
    if push is not None:
        steady[0] = push[0]  # held steady: no rate of the force's own change
    squared = np.asarray(inverse_dynamics(robot, motion, external=Jet(steady)).rotor_speed_squared, dtype=float)
    squared = squared.reshape(when.size, robot.n_drones, -1)
    speeds = np.sign(squared) * np.sqrt(np.abs(squared))
    limit = float(robot.rotor_constants.max_speed)
    margins = np.minimum(speeds, limit - speeds)
    j, i, k = np.unravel_index(np.argmin(margins), margins.shape)
    return HoldVerdict(bool(margins[j, i, k] >= 0.0), gust.body, tuple(float(f) for f in gust.force),
                       float(when[j]), int(i) + 1, int(k) + 1, float(speeds[j, i, k]), float(margins[j, i, k]),
                       limit, int(when.size), None)


def hold_verdict(robot, mission, gust, trajectory=None, end: float | None = None) -> str:
    """:func:`hold_check`'s one line."""
    return hold_check(robot, mission, gust, trajectory, end).line()


__all__ = ["HoldVerdict", "StaticHold", "hold_check", "hold_verdict", "static_hold"]
