r"""The external-force observer of the controller: a generalized-momentum observer on the chain model.

**Model.** The observer lives on the model the outer loop uses (:mod:`controllers.ctc`): the planning
model of the seed, the passive chain s with point-mass drones at their joints (3.12),

.. math:: M_s(s)\, \ddot s + C_s(s, \dot s)\, \dot s + g_s(s) = J_h(s)^T F + Q_{known} + Q_{ext},

F the drones' thrust vectors at their joints (the allocated thrust f_i along the measured thrust axis
b_z(phi_i) = (-sin phi_i, cos phi_i)), Q_known the generalised force of a wind the controller is told of,
and Q_ext what nobody told it: a gust, a wind, and what the model leaves out (the drones' offsets d_i and
their rotational inertia, the motor lag). The planning model is a Lagrangian system in s (Pinocchio's
model restricted by a constant map, M_s = T^T M T, C_s = T^T C T), so M_s' = C_s + C_s^T.

**Observer** (De Luca and Mattone 2003; the survey of Haddadin, De Luca and Albu-Schaeffer, IEEE T-RO 33(6),
2017; Tomic and Haddadin's external-wrench estimation for aerial robots, IROS 2014). With the generalised
momentum p = M_s s', the model gives p' = J_h^T F + Q_known + C_s^T s' - g_s + Q_ext, and

.. math:: r(t) = K_O \left( p(t) - p(0) - \int_0^t \left( J_h^T F + Q_{known} + C_s^T \dot s - g_s + r \right)
          d\tau \right)

obeys r' = K_O (Q_ext - r): each component of r is Q_ext through a first-order low pass of bandwidth K_O
[rad/s], without differentiating a measurement (only s and s' are used) and whatever the controller does
with r. A constant Q_ext is estimated exactly (63 % after 1/K_O, 95 % after 3/K_O); a step is followed
with that time constant.

**Discrete form.** The controller updates it at its outer-loop rate (period dt): the force the inputs
applied over the period is the mean of the inner-loop ticks' (each held over its tick); the state terms
enter through C^T q' - g = M' q' - (C q' + g), integrated over the period as (M_k - M_{k-1}) (q'_k +
q'_{k-1}) / 2 - dt (n_k + n_{k-1}) / 2 with n = C q' + g Pinocchio's nonlinear effects (second order, and
no Coriolis matrix: Pinocchio 4.1's ``computeCoriolisMatrix`` is wrong on the FPR's composite root joint,
C q' + g differing from the nonlinear effects by 0.7 N); r of the period's start (explicit):
r_k = r_{k-1} + K_O dt (Q_ext - r_{k-1}) for a constant Q_ext, stable for K_O dt < 2, a first-order
filter with the continuous bandwidth to within K_O dt / 2 for K_O dt << 1.

**Bandwidth** (``ControllerSettings.observer_bandwidth``, default 20 rad/s). The estimate does not pass through
the loops it feeds (the applied force is the allocation's thrusts along the measured thrust axes, and torques), so
their bandwidths do not bound it; these do:

* above the loops it serves: the chain loop's 3 rad/s, so that a disturbance is fed forward before the feedback
  has to hold it, and the drones' attitude loop's 15 rad/s, which takes the estimate in its model: a push on a
  drone's centre of mass is also a roll torque (d_i times the push across the drone), held by the attitude loop
  through the estimate. At 10 rad/s, a 7.4 N push on the prototype's drone tilted it 0.3 rad off its target
  before the estimate caught up, and the robot was lost;
* below the motor lag's 1 / T_m (50 rad/s): the observer takes up the lag as a force of its own, and fed forward
  that closes a loop, K_O T_m s / ((1 + T_m s)(s + K_O)), whose gain is below K_O T_m = 0.4 at every frequency;
* K_O dt = 0.2 at the 100 Hz outer rate: the discrete filter is within 10 % of the continuous one;
* measurement noise of s' reaches r as K_O M_s times the noise.

:class:`MomentumObserver` is the numbers only (testable without a model);
:class:`controllers.ctc.CascadedController` gives it the momentum and the generalised forces from Pinocchio.
"""

from __future__ import annotations

import numpy as np


class MomentumObserver:
    """The discrete generalized-momentum observer (module docstring).

    Args:
        bandwidth: K_O [rad/s], > 0.
        size: number of generalised coordinates.

    Attributes:
        estimate: r, the estimated external generalised force (size,) [N or N m] (zeros before the second
            update).
    """

    def __init__(self, bandwidth: float, size: int):
        self.bandwidth = float(bandwidth)
        self.size = int(size)
        self.reset()

    def reset(self) -> None:
        """Forget everything (a new run): the next update starts from r = 0."""
        self.estimate = np.zeros(self.size)
        self._start = None  # p(0)
        self._integral = np.zeros(self.size)
        self._last = None  # (M, q', nonlinear effects) at the last update

    def update(self, dt: float, mass, velocity, nonlinear, applied) -> np.ndarray:
        """One update, ``dt`` [s] after the last one.

        Args:
            dt: time since the last update [s] (ignored at the first).
            mass: M(q) now (size, size).
            velocity: q' now (size,).
            nonlinear: C(q, q') q' + g(q) now (size,).
            applied: the mean generalised force of the inputs over the period (and of the known wind) (size,).

        Returns:
            r, the estimate (size,) (:attr:`estimate`).
        """
        mass, velocity = np.asarray(mass, dtype=float), np.asarray(velocity, dtype=float)
        nonlinear = np.asarray(nonlinear, dtype=float)
        momentum = mass.dot(velocity)
        if self._start is None:
            self._start, self._last = momentum, (mass, velocity, nonlinear)
            return self.estimate
        last_mass, last_velocity, last_nonlinear = self._last
        drift = ((mass - last_mass).dot(0.5 * (velocity + last_velocity))
                 - 0.5 * dt * (nonlinear + last_nonlinear))
        self._integral = self._integral + drift + dt * (np.asarray(applied, dtype=float) + self.estimate)
        self._last = (mass, velocity, nonlinear)
        self.estimate = self.bandwidth * (momentum - self._start - self._integral)
        return self.estimate


__all__ = ["MomentumObserver"]
