r"""The drones' forces chosen together so that every drone keeps the authority to turn: a prioritised least squares.

The chain loop (:mod:`controllers.ctc`) asks for the forces F = (F_1 .. F_n) with J_h^T F = b (2.16). Where a
drone is sent to a tilt phi_i (the direction of F_i, 2.20) that its thrust can barely hold, it has no authority
left to turn back: its joint sits d_i below its centre of mass, so holding the tilt at rest takes the roll
torque m_i g d_i |sin phi_i| (the torque the hold check of :mod:`fpr.robustness.holding` counts), and a drone
whose thrust |F_i| is small (a push from below takes weight off it) can give little roll torque. The rotors
then sit at a bound, the drone does not turn back when the chain loop asks it to, and the chain is lost.

**The set each drone's force is kept in.** Drone i's roll torque at thrust T is bounded by the allocation's
unconstrained law (2.24) on [T, tau, 0, 0] with every rotor speed within [m_gr, w_max]: |tau| <= tau_max(T)
((l / 2) (T - 4 c_T m_gr^2) at low thrust for the "+" layout of the drones here, l their arm; read from the
allocator's law, not assumed). F_i is kept where

.. math:: m_i g d_i |\sin\phi(F_i)| + I_i K_{pp} |\phi(F_i) - \phi_i| \le \tau_{max}(|F_i|),

phi(F_i) the tilt of F_i (2.20), phi_i the drone's measured roll: the torque that holds the new tilt at rest,
plus the torque that turns the drone (roll inertia I_i) from where it is to that tilt at the chain loop's own rate
(the acceleration K_pp |phi(F_i) - phi_i| of a roll error under the chain loop's proportional gain K_pp = w_c^2):
the margin to turn is the chain loop's demand, not a tuned constant. The turn is counted from the drone's roll,
not from upright: a set that counted it from upright had no room left at a tilt the drone already held (the chain
was starved of the force it needed and lost, on a push on the prototype's drone), and its corner at low thrust and
no tilt drew a force wanted beyond the set to a drone at 0.66 rad sent upright on 1 N, a turn that thrust cannot
make (on a push on the square's drone); counted from the roll, that corner costs the turn's torque.
The rotor margin m_gr is the toolkit's (seed 3.48): the plan keeps it below w_max as the closed loop's room, the set
keeps it above 0, where a drone that runs out of authority sits (on the set's edge at 0 itself a rotor would sit
exactly at its bound, saturated); up to w_max the closed loop may use that room (a set bounded at w_max - m_gr
held back pushes of 7-8 N on a drone that the controller flies without a rotor at a bound). And |phi(F_i)| <= pi/2 -
m_ga, the plan's roll bound: near upside down the holding torque is small again, but such a drone carries
nothing.

**The force held.** When every drone's wanted F_i lies in its set, F is the chain loop's, the same object (to
the bit: a flight in which no drone leaves its set is the controller's without this module). Otherwise the
forces of all drones are chosen together,

.. math:: \min_F (F - F_w)^T J_h M_s^{-1} J_h^T (F - F_w) \quad \text{s.t. every } F_i \text{ in its set},

F_w the wanted forces: rotor authority first, the chain's J_h^T F = b second, met in the least-squares sense
of the chain's own kinetic metric (with J_h^T F_w = b the cost is (J_h^T F - b)^T M_s^{-1} (J_h^T F - b), the
acceleration error u - u_p weighed by M_s, Gauss's least constraint: the chain gives up the accelerations
that cost it least). Near a Type-2 singularity, where J_h M_s^{-1} J_h^T is singular, the directions that do
not act on the chain cost a tie-breaking 1e-9 of its scale, so the answer stays the nearest to F_w there. The
problem is small (2 n_d unknowns) and solved by SLSQP from F_w; when it finds no point within the sets
(not even the drones' own hover fits), F is held as wanted. The chain loop's integral is not advanced while F is
changed (as for :mod:`controllers.saturation`).

Planar thrust vectors (``len(robot.kind.force_axes) == 2``) only; the force of another robot kind is held as
wanted.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from scipy.optimize import minimize

logger = logging.getLogger(__name__)

_TWO_PI = 2 * math.pi
_TIE = 1e-9  # relative weight of the directions J_h^T does not see (a tie-breaker, module docstring)


class AuthoritySet:
    """Each drone's set of forces its rotors can give with the authority to turn (module docstring).

    Args:
        controller: the :class:`controllers.ctc.CascadedController` (its robot, allocator, settings).

    Attributes:
        limited: whether the last :meth:`hold` changed the force.
        from_roll: :meth:`hold` counts each drone's turn from its measured roll (True, the default) or from upright
            (False: the set as it was first made, for comparison; the native loop's test follows it).
    """

    def __init__(self, controller):
        self.controller = controller
        r = controller.robot
        allocator = controller.allocator
        n_d = r.n_drones
        self.limited = False
        self.from_roll = True
        self.active = len(r.kind.force_axes) == 2
        if not self.active:
            return
        self.max_tilt = 0.5 * math.pi - float(r.margins.angle)  # the plan's roll bound (3.33, 3.45)
        self.mass = np.asarray(r.drone_masses, dtype=float)
        self.offset = np.asarray(r.hinge_offsets, dtype=float)
        parameters = r.parameters
        self.gravity = float(parameters.get("gravity", 9.81))
        self.inertia = np.full(n_d, float(parameters["drone_ixx"]))  # roll about the body x axis
        margin = float(r.margins.rotor_speed)  # m_gr (module docstring)
        self._lower, self._upper = margin**2, float(allocator.scale)  # w^2 within [m_gr^2, w_max^2]
        inv_f = np.asarray(allocator._inv_f, dtype=float).reshape(n_d, 4, -1)
        inv_tau = np.asarray(allocator._inv_tau, dtype=float).reshape(n_d, 4, -1)
        k_tau = inv_tau.shape[2] // n_d
        # w^2 of drone i's rotors = a_i T + b_i tau (its roll torque tau, its other torques 0)
        self._a = np.array([inv_f[i, :, i] for i in range(n_d)])
        self._b = np.array([inv_tau[i, :, k_tau * i] for i in range(n_d)])

    def torque_limit(self, thrust) -> np.ndarray:
        """tau_max (n_d,) [N m]: the largest roll torque of either sign each drone's rotors give at ``thrust``
        (n_d,) [N] by the allocation's law, every w^2 in [0, w_max^2] (negative: not even tau = 0 fits).
        """
        a, b = self._a, self._b
        z = a * np.asarray(thrust, dtype=float)[:, None]  # w^2 at tau = 0
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(b != 0.0, np.minimum(z - self._lower, self._upper - z) / np.abs(b), np.inf)
        out = room.min(axis=1)
        inside = np.all((z >= self._lower) & (z <= self._upper), axis=1)
        return np.where(inside, out, -np.abs(out))

    def torque_needed(self, force, roll=None) -> np.ndarray:
        """The roll torque (n_d,) [N m] that holds each drone at the tilt of its ``force`` (n_d, 2) [N] at rest
        and turns it there from its roll ``roll`` (n_d,) [rad] at the chain loop's rate (module docstring);
        ``roll`` None: from upright.
        """
        tilt = _tilt(force)
        kp, _ = self.controller.settings.chain_gains
        hold = self.mass * self.gravity * self.offset * np.abs(np.sin(tilt))
        return hold + self.inertia * kp * np.abs(_turn(tilt, roll))

    def slack(self, force, roll=None) -> np.ndarray:
        """tau_max(|F_i|) - the torque needed (n_d,) [N m] (:meth:`torque_needed`, the drones at ``roll``): >= 0
        where the drone's force is in its set.
        """
        force = np.asarray(force, dtype=float)
        return self.torque_limit(np.linalg.norm(force, axis=1)) - self.torque_needed(force, roll)

    def tilt_room(self, force) -> np.ndarray:
        """pi/2 - m_ga - |phi_i| (n_d,) [rad]: >= 0 where the tilt of each drone's ``force`` (n_d, 2) [N] is within
        the plan's roll bound (a drone turned upside down needs little torque to hold, but cannot carry the chain).
        """
        return self.max_tilt - np.abs(_tilt(force))

    def inside(self, force, tolerance: float = 0.0, roll=None) -> np.ndarray:
        """Per drone: its ``force`` (n_d, 2) [N] in its set, the drones at ``roll`` (n_d,) [rad] (None: upright),
        within ``tolerance`` [N m, rad] of its bounds.
        """
        return (self.slack(force, roll) >= -tolerance) & (self.tilt_room(force) >= -tolerance)

    def compiled_constants(self) -> np.ndarray | None:
        """The set's numbers for the native closed loop's test of :meth:`inside` (``fpr/_native/cpp/outer.cpp``'s
        ``authority_inside``, the same operations in the same order), which hands an outer-loop update whose force
        leaves a set back to :meth:`hold`: n_d, the bounds of w^2, g, the chain loop's K_p, the tilt bound, then per
        drone its mass, offset, roll inertia, the four rotors' a_i and b_i and the index of its roll in q (-1: the
        turn counted from upright, :attr:`from_roll` False); None when the set does not act (a robot kind whose
        thrust vectors are not planar).
        """
        if not self.active:
            return None
        kp, _ = self.controller.settings.chain_gains
        head = [len(self.mass), self._lower, self._upper, self.gravity, kp, self.max_tilt]
        rolls = np.asarray(self.controller.rolls if self.from_roll else np.full(len(self.mass), -1), dtype=float)
        drones = np.column_stack([self.mass, self.offset, self.inertia, self._a, self._b, rolls])
        return np.ascontiguousarray(np.concatenate([head, drones.reshape(-1)]), dtype=float)

    def _smooth_slack(self, force, roll) -> np.ndarray:
        """:meth:`slack` >= 0 as smooth constraints, all >= 0 exactly where it is (for SLSQP, whose steps stall on
        the kinks of its minimum and absolute values): every rotor's room on either side, less either sign of the
        holding and the turning torque; and every rotor's w^2 within its bounds (the rotors the roll torque does
        not move), in the same units.
        """
        force = np.asarray(force, dtype=float)
        tilt = _tilt(force)
        turn = _turn(tilt, roll)
        kp, _ = self.controller.settings.chain_gains
        hold = (self.mass * self.gravity * self.offset * np.sin(tilt))[:, None] * np.array([1.0, 1.0, -1.0, -1.0])
        hold += (self.inertia * kp * turn)[:, None] * np.array([1.0, -1.0, 1.0, -1.0])  # (n_d, 4): the signs
        z = self._a * np.linalg.norm(force, axis=1)[:, None]  # w^2 at tau = 0, (n_d, 4)
        unit = np.where(self._b != 0.0, np.abs(self._b), np.max(np.abs(self._b)))  # [(rad/s)^2 / (N m)]
        room = np.concatenate([(z - self._lower) / unit, (self._upper - z) / unit], axis=1)  # (n_d, 8)
        turning = np.concatenate([self._b != 0.0] * 2, axis=1)
        out = [room[~turning]] + [(room[i, turning[i]][:, None] - hold[i][None, :]).reshape(-1) for i in range(len(z))]
        return np.concatenate(out)

    def hold(self, q, v, wanted):
        """The force to hold: ``wanted`` itself (the same object) when every drone's force is in its set, else
        the forces of all drones chosen together (module docstring). ``wanted``: (n_d, 2) [N].
        """
        self.limited = False
        if not self.active:
            return wanted
        c = self.controller
        roll = np.asarray(q, dtype=float)[c.rolls] if self.from_roll else None
        if np.all(self.inside(wanted, roll=roll)):
            return wanted
        chain = c.chain
        m, _, jac = c._point_dynamics(q[chain], v[chain])
        weight = jac.dot(np.linalg.solve(m, jac.T))  # J_h M_s^-1 J_h^T
        weight = 0.5 * (weight + weight.T)
        weight += _TIE * max(float(np.trace(weight)), 1e-300) / len(weight) * np.eye(len(weight))
        start = np.asarray(wanted, dtype=float)
        x0 = start.reshape(-1)
        scale = max(float(np.max(np.diag(weight))), 1e-300)
        size = max(float(np.linalg.norm(x0)), 1.0)

        def cost(x):
            d = x - x0
            return float(d.dot(weight.dot(d))) / (scale * size**2)

        def gradient(x):
            return 2.0 * weight.dot(x - x0) / (scale * size**2)

        n_d = len(start)
        result = minimize(cost, x0, jac=gradient, method="SLSQP",
                          constraints=[{"type": "ineq", "fun": lambda x: self._smooth_slack(x.reshape(n_d, 2), roll)},
                                       {"type": "ineq", "fun": lambda x: self.tilt_room(x.reshape(n_d, 2))}],
                          options={"maxiter": 100, "ftol": 1e-12})
        held = result.x.reshape(n_d, 2)
        if not np.all(np.isfinite(held)) or not np.all(self.inside(held, 1e-6, roll)):
            logger.debug("no force within every drone's set (%s): F held as wanted", result.message)
            return wanted
        self.limited = True
        return held


def _tilt(force) -> np.ndarray:
    """The tilt phi(F_i) (n_d,) [rad] of each drone's ``force`` (n_d, 2) [N] (2.20)."""
    force = np.asarray(force, dtype=float)
    return np.arctan2(-force[:, 0], force[:, 1])


def _turn(tilt, roll) -> np.ndarray:
    """The turn (n_d,) [rad] from each drone's ``roll`` (n_d,) to ``tilt``, the shortest angle; ``roll`` None: from
    upright (the tilt itself).
    """
    return tilt if roll is None else np.remainder(tilt - np.asarray(roll, dtype=float) + np.pi, _TWO_PI) - np.pi


__all__ = ["AuthoritySet"]
