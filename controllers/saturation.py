r"""The outer loop's forces kept within what the rotors can give: a constraint-aware step of the chain loop.

The chain loop (:mod:`controllers.ctc`) asks each drone for a force F_i; the inner loop turns it into a thrust
and an attitude target (the robot kind's ``attitude_targets``: the direction of F_i, 2.20), and the attitude
loop (2.23) into accelerations u_a that the rotor allocation (:mod:`controllers.allocation`) must produce with
0 <= w^2 <= w_max^2. A drone's roll authority is about its thrust times half its arm, so a drone whose thrust is
small (a push from below takes weight off it) and that the chain loop asks to re-tilt by a large angle at once
(a gust turns the direction of F_i, by up to a radian for a push on the drone itself) gets an attitude demand
K_pa (phi_d - phi) beyond its rotors: a rotor sits at a bound for a few hundred milliseconds while the
allocation clips the command, the drone overshoots and the chain is pushed further off.

**The check** (at every outer-loop update, :meth:`CascadedController.update
<controllers.ctc.CascadedController.update>`): the first inner tick on the new F is computed as always; when its
allocation has a rotor at a bound, :meth:`ForceLimiter.limit` takes that tick's command (the kind's targets, the
attitude loop, the attitude model 2.12 with the known and estimated winds) and the allocation's unconstrained law
(2.24) on it; when every rotor's w^2 of the law lies within [0, w_max^2] the rotors can give it and F is held as
the chain loop computed it. A flight on which no rotor reaches a bound is the one of the controller without this
module, to the bit, and pays nothing for it.

**The limited force.** Otherwise each drone i whose rotors cannot give it has its F_i turned (its size kept)
so that the attitude loop's first tick on it is that of the same loop made slower by a factor sigma_i in
(0, 1] (natural frequency sigma_i w_a, the same damping) towards the wanted direction phi_w:

.. math:: \phi_d - \phi = \sigma^2 (\phi_w - \phi) + (1 - \sigma) \frac{K_{da}}{K_{pa}} (\dot\phi - \dot\phi_r),

with sigma_i the largest (bisection) for which the law is within the rotor bounds, found drone by drone, the
others at their own sigma. sigma = 1 is the wanted force; sigma = 0 asks for no attitude acceleration beyond
the plan's (the drone coasts); a drone for which not even that fits keeps its wanted force (nothing to gain: the
allocation then clips as before). A linear, critically damped attitude response, only slower, turns the drone
towards the wanted direction at the rate its authority allows without the overshoot of a clipped one, and as it
turns its thrust axis aligns with F_i, its thrust and authority grow and sigma returns to 1. The chain gets the
wanted force late rather than a clipped thrust. Nothing is tuned: the bounds are the allocator's (the rotor
model's), the gains the attitude loop's, the model the controller's. Thrust vectors in the plane
(``len(robot.kind.force_axes) == 2``) only: the force of another robot kind is held as wanted.

The integral of the chain loop is not advanced while the forces are limited (conditional integration: the error
the rotors cannot remove yet is not accumulated, to be released as an overshoot afterwards).
"""

from __future__ import annotations

import math

import numpy as np

from controllers.authority import AuthoritySet

_TWO_PI = 2 * math.pi


class ForceLimiter:
    """The constraint-aware step of one controller's outer loop (module docstring).

    Args:
        controller: the :class:`controllers.ctc.CascadedController` (its robot, allocator, gains).
        steps: bisection steps on each drone's sigma (its resolution 2^-steps).

    Attributes:
        limited: whether the last :meth:`limit` changed the force.
        scale: sigma of each drone at the last :meth:`limit` (1: its wanted force).
    """

    def __init__(self, controller, steps: int = 10):
        self.controller = controller
        self.steps = int(steps)
        self.limited = False
        self.scale = np.ones(controller.robot.n_drones)
        allocator = controller.allocator
        self._upper = float(allocator.scale)  # w_max^2: the law's z is in (rad/s)^2
        self.authority = AuthoritySet(controller)  # every drone's F with the authority to turn

    def hold(self, q, v, wanted):
        """The chain loop's new force ``wanted`` (n_d, len(force_axes)) [N] kept where every drone has the authority
        to turn (:class:`controllers.authority.AuthoritySet`): ``wanted`` itself when it is, else the forces chosen
        together; sets :attr:`limited` when it changed them.
        """
        held = self.authority.hold(q, v, wanted)
        self.limited = self.authority.limited
        return held

    def _command(self, q, v, reference, force):
        """The inner loop's first tick on ``force`` at (q, v): (f_d (n_d,), u_a (n_a,), its targets)."""
        c = self.controller
        targets = c.robot.kind.attitude_targets(q, v, force, reference, c.settings)
        kp, kd = c._attitude_gains()
        att = c.attitude
        error = q[att] - np.asarray(targets.target, dtype=float)
        wrap = np.asarray(c._wrap)
        error[wrap] = np.remainder(error[wrap] + np.pi, _TWO_PI) - np.pi
        u_a = np.asarray(targets.acceleration) - kp * error - kd * (v[att] - np.asarray(targets.rate))
        return np.asarray(targets.thrust, dtype=float), u_a, targets

    def _law(self, attitude, f_d, u_a) -> np.ndarray:
        """w^2 (n_d, 4) [(rad/s)^2] of the allocation's unconstrained law (2.24) for f_d and u_a."""
        allocator = self.controller.allocator
        a_tau = attitude.a_tau
        x = np.linalg.solve(a_tau.dot(a_tau.T), u_a + attitude.m_inv_a.dot(attitude.c - attitude.j_f.T.dot(f_d)))
        return (allocator._inv_f.dot(f_d) + allocator._inv_tau.dot(a_tau.T.dot(x))).reshape(-1, 4)

    def speeds_squared(self, q, v, reference, force, attitude) -> np.ndarray:
        """w^2 of every rotor (n_d, 4) [(rad/s)^2] that the allocation's unconstrained law (2.24) gives for the
        inner loop's first tick on ``force`` (n_d, len(force_axes)) [N] at the measured (q, v), ``attitude`` the
        attitude model there with the winds the controller uses (:meth:`attitude_at`).
        """
        f_d, u_a, _ = self._command(q, v, reference, force)
        return self._law(attitude, f_d, u_a)

    def attitude_at(self, q, v, reference):
        """The attitude model at (q, v) with the known wind of ``reference`` and the observer's estimate, as the
        controller's inner loop uses it.
        """
        c = self.controller
        attitude = c.robot.attitude_model(q, v)
        if reference.task_force is not None or reference.drone_forces is not None:
            attitude = c._attitude_in_wind(q, attitude, reference.task_force, reference.drone_forces)
        if c.observer is not None:
            attitude = type(attitude)(attitude.m_inv_a, attitude.j_tau, attitude.j_f, attitude.a_tau,
                                      attitude.c - c.observer.estimate)
        return attitude

    def _within(self, z) -> np.ndarray:
        """Per drone: every rotor's w^2 within [0, w_max^2]."""
        return np.all((z >= 0.0) & (z <= self._upper), axis=1)

    def limit(self, q, v, reference, wanted, attitude=None):
        """The force to hold: ``wanted`` itself (the same object) when the rotors can give its command, else each
        drone's force turned, its size kept, so that the attitude loop's first tick on it is that of a slower
        loop (module docstring). ``wanted``: the new force (n_d, len(force_axes)) [N]; ``attitude``: the attitude
        model at (q, v) with the winds the controller uses, or None (:meth:`attitude_at`).
        """
        # self.limited is left as hold() set it at this update (the controller clears it before the outer loop)
        self.scale = np.ones(len(wanted))
        if np.shape(wanted)[1] != 2:
            return wanted
        attitude = self.attitude_at(q, v, reference) if attitude is None else attitude
        within = self._within(self.speeds_squared(q, v, reference, wanted, attitude))
        if within.all():
            return wanted
        c = self.controller
        kind, st = c.robot.kind, c.settings
        kp, kd = c._attitude_gains()
        places = c._drone_places
        columns = c.attitude[places]  # the drones' attitude coordinates in q
        _, _, targets = self._command(q, v, reference, wanted)
        goal = np.asarray(targets.target, dtype=float)[places]
        error = np.remainder(goal - q[columns] + np.pi, _TWO_PI) - np.pi  # phi_w - phi
        lead = (kd[places] / kp[places]) * (v[columns] - np.asarray(targets.rate, dtype=float)[places])
        # the sign of each drone's target's change when its force turns counter-clockwise
        signs = np.empty(len(places))
        for i, k in enumerate(places):
            probe = np.array(wanted, dtype=float)
            probe[i] = _rotate(probe[i], 1e-6)
            signs[i] = math.copysign(1.0, kind.attitude_targets(q, v, probe, reference, st).target[k] - goal[i])

        def force_of(scales):
            out = np.array(wanted, dtype=float)
            for i in range(len(places)):
                if scales[i] < 1.0:
                    turn = (scales[i]**2 - 1.0) * error[i] + (1.0 - scales[i]) * lead[i]  # phi_d - phi_w
                    out[i] = _rotate(out[i], signs[i] * turn)
            return out

        def fits(scales):
            return self._within(self.speeds_squared(q, v, reference, force_of(scales), attitude))

        scales = np.ones(len(places))
        for _ in range(2):
            for i in np.flatnonzero(~fits(scales)):
                trial = scales.copy()
                trial[i] = 0.0
                if not fits(trial)[i]:  # not even coasting fits: nothing to gain
                    continue
                low, high = 0.0, 1.0
                for _ in range(self.steps):
                    trial[i] = 0.5 * (low + high)
                    if fits(trial)[i]:
                        low = trial[i]
                    else:
                        high = trial[i]
                scales[i] = low
        if np.all(scales == 1.0):
            return wanted
        self.limited, self.scale = True, scales
        return force_of(scales)


def _rotate(vector, angle: float) -> np.ndarray:
    """A 2-vector turned by ``angle`` [rad] (counter-clockwise)."""
    cos, sin = math.cos(angle), math.sin(angle)
    return np.array([cos * vector[0] - sin * vector[1], sin * vector[0] + cos * vector[1]])


__all__ = ["ForceLimiter"]
