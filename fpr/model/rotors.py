r"""Rotor model of a quadrotor: from squared rotor speeds to thrust and body torques (seed 3.2-3.11).

The mixing matrix is built from the rotor positions (read from the URDF frames) and their spin
senses, so that it follows the robot description; for the "+" layout of the parameter file it is
the seed's eq. 3.10:

.. math::
    \begin{bmatrix} f \\ \tau_x \\ \tau_y \\ \tau_z \end{bmatrix} = R_f
    \begin{bmatrix} \varpi_1^2 \\ \varpi_2^2 \\ \varpi_3^2 \\ \varpi_4^2 \end{bmatrix},\quad
    R_f = \begin{bmatrix} c_T & c_T & c_T & c_T \\ 0 & d c_T & 0 & -d c_T \\
    -d c_T & 0 & d c_T & 0 \\ -c_Q & c_Q & -c_Q & c_Q \end{bmatrix}
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fpr.model.dual import Dual
from fpr.model.errors import ShapeError
from fpr.model.jets import inexact
from fpr.model.parameters import RotorConstants


def signed_speeds(w2) -> np.ndarray:
    """sign(w^2) sqrt(|w^2|) [rad/s] of squared rotor speeds w^2 [rad^2/s^2], complex-step safe.

    Written sign * sqrt(sign * w^2) with the sign of the real part: the same bits as sign(w^2) sqrt(|w^2|)
    for real input, and an analytic function of a complex-step perturbed input (numpy's complex ``sign``
    and ``abs`` are not: sign(z) = z / |z| and |z| drop the perturbation's derivative).
    """
    if isinstance(w2, Dual):  # d sqrt|x| = dx / (2 sqrt|x|) (0 where x = 0, as below)
        sign = np.sign(w2.value)
        root = np.sqrt(sign * w2.value)
        scale = np.divide(0.5, root, out=np.zeros(root.shape), where=sign != 0.0)
        return Dual(sign * root, w2.tangents * scale, w2.lo)
    w2 = np.asarray(w2)
    if not np.iscomplexobj(w2):
        sign = np.sign(w2)
        return sign * np.sqrt(sign * w2)
    # a complex step w2 = x + i h b (h tiny): sign(x) sqrt|x| + i h b / (2 sqrt|x|) from real square roots
    # (numpy's complex square root costs several times more; 0 where x = 0, as sign * sqrt(sign * w2) gives)
    sign = np.sign(w2.real)
    root = np.sqrt(sign * w2.real)
    out = np.empty(w2.shape, w2.dtype)
    out.real = sign * root
    out.imag = np.divide(w2.imag, 2.0 * root, out=np.zeros(root.shape), where=sign != 0.0)
    return out


@dataclass(frozen=True)
class RotorModel:
    """Mixing of the four rotors of one quadrotor.

    Attributes:
        positions: rotor positions in the drone's centre-of-mass frame, shape (4, 3) [m].
        constants: rotor constants (c_T, c_Q, limits, spin senses).
    """

    positions: np.ndarray
    constants: RotorConstants

    def __post_init__(self):
        if np.shape(self.positions) != (4, 3):
            raise ShapeError("positions", np.shape(self.positions), "(4, 3)")

    @property
    def mixing_matrix(self) -> np.ndarray:
        """R_f (seed 3.10): [f, tau_x, tau_y, tau_z] = R_f @ w^2, shape (4, 4)."""
        c_t = self.constants.thrust_coefficient
        c_q = self.constants.drag_coefficient
        r = np.asarray(self.positions, dtype=float)
        # thrust c_T w^2 along body z at r: torque r x (0, 0, f) = (r_y f, -r_x f, 0); drag -spin c_Q w^2 on z.
        return np.vstack([np.full(4, c_t), c_t * r[:, 1], -c_t * r[:, 0], -self.constants.spin * c_q])

    @property
    def inverse_mixing_matrix(self) -> np.ndarray:
        """R_f^-1: w^2 = R_f^-1 @ [f, tau_x, tau_y, tau_z] (seed 3.31, 3.47)."""
        return np.linalg.inv(self.mixing_matrix)

    def wrench(self, speeds_squared) -> np.ndarray:
        """Thrust and body torques from squared rotor speeds.

        Args:
            speeds_squared: w^2 of the four rotors, shape (..., 4) [(rad/s)^2].

        Returns:
            [f, tau_x, tau_y, tau_z], shape (..., 4) [N, N m].
        """
        return inexact(speeds_squared) @ self.mixing_matrix.T

    def speeds_squared(self, thrust, torque) -> np.ndarray:
        """Squared rotor speeds that produce a thrust and body torques (seed 3.47).

        Args:
            thrust: f, shape (...) [N].
            torque: [tau_x, tau_y, tau_z], shape (..., 3) [N m].

        Returns:
            w^2, shape (..., 4); a negative entry means that no real rotor speed gives this wrench.
        """
        u = np.concatenate([inexact(thrust)[..., None], inexact(torque)], axis=-1)
        return u @ self.inverse_mixing_matrix.T

    def speeds(self, thrust, torque) -> np.ndarray:
        """Signed rotor speeds sign(w^2) sqrt(|w^2|), shape (..., 4) [rad/s].

        The sign keeps a physically impossible command (w^2 < 0) visible, so the constraint
        ``0 <= w <= w_max - m_gr`` (seed 3.48) can be evaluated and violated continuously.
        """
        return signed_speeds(self.speeds_squared(thrust, torque))

    def rotor_forces(self, thrust, torque) -> np.ndarray:
        """Force of each rotor c_T w^2 (seed 3.31), shape (..., 4) [N]."""
        return self.constants.thrust_coefficient * self.speeds_squared(thrust, torque)
