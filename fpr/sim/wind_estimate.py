"""A steady force on the robot's task point, estimated in flight from the chain's tracking error.

The replanner's wind estimate when the controller has no observer (``observer_bandwidth = 0``); with one,
the observer's estimate (:mod:`controllers.observer`) is used instead (:mod:`fpr.sim.replanning`).

The cascaded controller (:mod:`controllers.ctc`) commands the chain acceleration
u = s_d'' - K_p e - K_d e' - K_i int(e) (e = s - s_d) and the generalised force M_s u + c_s. An unknown
external force Q_ext adds M_s^-1 Q_ext to the acceleration, so once the robot follows the plan's
acceleration again (s'' ~ s_d''), M_s^-1 Q_ext = K_p e + K_d e' + K_i int(e): the wind is what the
controller's feedback holds against. :class:`WindEstimator` evaluates

    Q_hat = M_s(s) (K_p e + K_d e' + K_i I),

with I the integrated error clamped like the controller's (``integral_limit``, updated at the outer-loop
rate), M_s the planning model's mass matrix (point drones, :mod:`fpr.model.inverse_dynamics`), reads it as a
force F on the task point (least squares of J_p^T F = Q_hat, J_p the task point's Jacobian, the in-plane
components y, z), and low-pass filters it (time constant ``time_constant``). It is exact in a steady state
of a model that matches the plant; on the ``gust`` mission in 8 N along -y (its earlier force) it settled
within 10 %
(about -7.2 N; the point-drone model is lighter in rotation than the plant). In transients (the wind
rising, a sharp turn of the plan) it is wrong: the replanner takes it only after it has stayed above a
threshold for a while (:class:`fpr.sim.replanning.TriggerSettings`).
"""

from __future__ import annotations

import numpy as np

from planners.problem.disturbance import task_jacobian


class WindEstimator:
    """Low-pass estimate of a force on the task point from the tracking error (module docstring).

    Args:
        robot: the robot (its planning model and task point).
        controller: the controller's :class:`controllers.ctc.ControllerSettings` (gains, outer rate,
            integral clamp).
        time_constant: the low-pass filter's time constant [s].

    Attributes:
        force: the current estimate, world [x, y, z] [N] (x is 0: the chain is planar).
    """

    def __init__(self, robot, controller, time_constant: float = 0.5):
        self.robot = robot
        self.planar = robot.planar("point")
        self.kp, self.kd = controller.chain_gains
        self.ki = controller.chain_integral
        self.limit = controller.integral_limit
        self.outer = 1.0 / controller.outer_rate
        self.time_constant = float(time_constant)
        self.force = np.zeros(3)
        self._integral = None
        self._last_outer = None
        self._last = None

    def update(self, t: float, s, ds, reference, fed=None) -> np.ndarray:
        """One tick at time t [s]: measured chain s, s' and the plan's [s_d, s_d', ...]; the new estimate.

        ``fed``: the force on the task point the controller feeds forward, world [x, y, z] [N], or None: the
        feedback then holds only the rest of the wind, and the estimate is ``fed`` plus what it holds.
        """
        s = np.asarray(s, dtype=float)
        error = s - reference[0]
        if self._integral is None:
            self._integral = np.zeros_like(error)
            self._last_outer = self._last = t
        elif t - self._last_outer >= self.outer - 1e-9:  # the controller integrates at its outer rate
            self._integral = np.clip(self._integral + error * (t - self._last_outer), -self.limit, self.limit)
            self._last_outer = t
        rate_error = np.asarray(ds, dtype=float) - reference[1]
        held = self.kp * error + self.kd * rate_error + self.ki * self._integral
        mass = np.asarray(self.planar.mass_matrix(s[None]))[0]
        jac = task_jacobian(self.robot, s[None])[0]  # (2, n_s)
        raw = np.linalg.lstsq(jac.T, mass @ held, rcond=None)[0]
        if fed is not None:
            raw = raw + np.asarray(fed, dtype=float)[1:]
        gain = min(1.0, (t - self._last) / self.time_constant)
        self.force[1:] += gain * (raw - self.force[1:])
        self._last = t
        return self.force


__all__ = ["WindEstimator"]
