r"""What the spatial FPR's drones must do along a motion of its chain: thrust vectors, attitudes, torques, rotor speeds.

From the chain motion s(t) = [x y z psi theta phi q1 q2 q3] and its derivatives 0..4, for every sample at once:

1. **Thrust vectors** F_i (world x, y, z) of the planning model, the platform and legs with each drone a point mass
   at its leg's tip (:class:`fpr.model.spatial.SpatialChain` on the model with the ball joints locked):
   J^T F = M s'' + c - Q_ext, F, F', F'' exactly (jets).
2. **Attitudes** by the rule of :func:`fpr.robots.fpr3.ball_angles`: in leg i's radial frame P_i = R_p Rz(a_i),
   f = P_i^T F_i, beta_i = q_i + pitch_i = atan2(f_x, f_z), roll_i = atan2(-f_y, hypot(f_x, f_z)), yaw_i = 0,
   with their first two derivatives (jets). The drone's attitude is R_i = P_i Ry(beta_i) Rx(roll_i) and its angular
   velocity in its own axes

   .. math:: \omega_i = R_x(-r_i) \left( R_y(-\beta_i) R_z(-a_i)\, \omega_p + [\dot r_i, \dot\beta_i, 0]^T \right),

   omega_p the platform's (body axes, from the Z-Y-X rates); omega_i' is its time derivative (body axes too).
3. **Thrust and torques** of a rigid drone on a ball at its tip o, its centre of mass c = d z_i above the ball
   (d the URDF's ``ball_offset``, 0 by default):

   .. math:: f_i = z_i \cdot F_i - m d |\omega_{i\perp}|^2, \qquad
             \tau_i = I_o \dot\omega_i + \omega_i \times I_o \omega_i + m\, c \times R_i^T (a_o - g),

   I_o the drone's inertia about the ball. With d = 0 the drone's rotation is decoupled from the chain and the
   round trip through the full model is exact (tested); with d > 0 the point-drone plan leaves out the pendulum
   (the perturbation the controller compensates).
4. **Rotor speeds** w^2 = R_f^-1 [f_i, tau_i] of each drone's rotor model.

Every step is a jets or elementwise operation: the values may be complex (complex step) or dual numbers.
"""

from __future__ import annotations

import numpy as np

from fpr.model import dual, jets
from fpr.model.inverse_dynamics import MotionInputs, motion_array
from fpr.model.jets import Jet
from fpr.model.rotors import signed_speeds


def _value(x):
    """The real value of a plain, complex-step or dual array (for the fields nothing differentiates)."""
    x = x.value if isinstance(x, dual.Dual) else x
    return np.real(x)


def _turn_z(angle_cos, angle_sin, x, y):
    """(x, y) turned by Rz(-a): Rz(a)^T [x, y]."""
    return angle_cos * x + angle_sin * y, angle_cos * y - angle_sin * x


def _platform_axes(s: Jet, fx: Jet, fy: Jet, fz: Jet):
    """R_p^T [fx, fy, fz] (components (N, n_d)), R_p = Rz(psi) Ry(theta) Rx(phi) of the motion s (N, 9)."""
    order = fx.order
    spsi, cpsi = jets.sincos(s[..., 3:4].truncate(order))
    sth, cth = jets.sincos(s[..., 4:5].truncate(order))
    sphi, cphi = jets.sincos(s[..., 5:6].truncate(order))
    fx, fy = cpsi * fx + spsi * fy, cpsi * fy - spsi * fx  # Rz(-psi)
    fx, fz = cth * fx - sth * fz, sth * fx + cth * fz  # Ry(-theta)
    fy, fz = cphi * fy + sphi * fz, cphi * fz - sphi * fy  # Rx(-phi)
    return fx, fy, fz


def _platform_rate(s: Jet):
    """The platform's angular velocity in its own axes from the Z-Y-X rates, components (N, 1), jets of order
    K - 1 (s of order K).
    """
    rate = s.derivative()
    order = rate.order
    sth, cth = jets.sincos(s[..., 4:5].truncate(order))
    sphi, cphi = jets.sincos(s[..., 5:6].truncate(order))
    psi, theta, phi = rate[..., 3:4], rate[..., 4:5], rate[..., 5:6]
    return phi - psi * sth, theta * cphi + psi * sphi * cth, psi * cphi * cth - theta * sphi


def _mul(a, b):
    """Elementwise product of two 3-tuples' entries summed: a . b."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _matvec(m, v):
    """m v for a constant 3 x 3 array m (per drone: (n_d, 3, 3)) and a 3-tuple of arrays (N, n_d)."""
    return tuple(m[:, k, 0] * v[0] + m[:, k, 1] * v[1] + m[:, k, 2] * v[2] for k in range(3))


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def spatial_motion_inputs(kind, motion, external=None) -> MotionInputs:
    """The :class:`~fpr.model.inverse_dynamics.MotionInputs` of the spatial FPR along a motion (module docstring).

    Args:
        kind: the bound :class:`~fpr.robots.fpr3.Fpr3` (its chain model, geometry, drones and rotors).
        motion: s and its time derivatives 0..4, shape (5, N, 9) (or (5, 9)).
        external: generalised force Q_ext on the chain coordinates, shape (N, 9) [N, N m] (constant), or a Jet of
            it with its time derivatives, or None.
    """
    robot = kind.robot
    m = motion_array(robot, motion)
    s = Jet(m[:5])
    n_d = robot.n_drones
    spatial = kind.spatial_chain.evaluate(s, forces=False)
    b = spatial.b
    if external is not None:
        b = b - (external if isinstance(external, Jet) else np.asarray(external))
    force = jets.solve(spatial.jacobian.mT, b)  # order 2
    force = force.reshape(force.shape[:-1] + (n_d, 3))

    # the thrust vectors in each leg's radial frame P_i = R_p Rz(a_i)
    px, py, pz = _platform_axes(s, force[..., 0], force[..., 1], force[..., 2])
    ca, sa = np.cos(kind.geometry.directions), np.sin(kind.geometry.directions)
    fx, fy = _turn_z(ca, sa, px, py)
    fz = pz
    across = jets.hypot(fx, fz)
    beta = jets.atan2(fx, fz)  # q_i + pitch_i
    roll = jets.atan2(-fy, across)
    magnitude = jets.sqrt(across * across + fy * fy)

    # the drones' angular velocities (body axes), order 1
    wx, wy, wz = _platform_rate(s.truncate(2))
    ux, uy = _turn_z(ca, sa, wx, wy)
    uz = wz
    sb, cb = jets.sincos(beta.truncate(1))
    sr, cr = jets.sincos(roll.truncate(1))
    vx = cb * ux - sb * uz + roll.derivative()
    vy = uy + beta.derivative()
    vz = sb * ux + cb * uz
    omega = (vx, cr * vy + sr * vz, cr * vz - sr * vy)
    w = tuple(c.value for c in omega)
    w_dot = tuple(c.d[1] for c in omega)

    # thrust and torques of rigid drones on balls (I_o about the ball, c its centre of mass)
    mass, lever, inertia = kind.drone_inertias  # (n_d,), (n_d, 3), (n_d, 3, 3) about the ball
    tip_velocity = jets.matvec(spatial.jacobian, s.derivative().truncate(2))  # order 2: r', r''
    tip_velocity = tip_velocity.reshape(tip_velocity.shape[:-1] + (n_d, 3))
    accel = tip_velocity.d[1]
    spin = _matvec(inertia, w)
    torque = [a + b for a, b in zip(_matvec(inertia, w_dot), _cross(w, spin), strict=True)]
    thrust = magnitude.value
    if np.any(lever != 0.0):
        gravity = kind.spatial_chain.gravity
        ax, ay, az = _platform_axes(s.truncate(0), Jet((accel[..., 0] - gravity[0])[None]),
                                    Jet((accel[..., 1] - gravity[1])[None]), Jet((accel[..., 2] - gravity[2])[None]))
        ax, ay = _turn_z(ca, sa, ax.value, ay.value)
        sb0, cb0, sr0, cr0 = sb.value, cb.value, sr.value, cr.value
        bx, bz = cb0 * ax - sb0 * az.value, sb0 * ax + cb0 * az.value  # Ry(-beta)
        body = (bx, cr0 * ay + sr0 * bz, cr0 * bz - sr0 * ay)  # Rx(-roll): a_o - g in the drone's axes
        arm = tuple(mass * lever[:, k] for k in range(3))
        torque = [t + c for t, c in zip(torque, _cross(arm, body), strict=True)]
        thrust = thrust - mass * lever[:, 2] * (w[0] * w[0] + w[1] * w[1])  # d = lever_z: the centre on z
    torque = np.stack(torque, axis=-1)
    w2 = np.stack([rotor.speeds_squared(thrust[:, i], torque[:, i]) for i, rotor in enumerate(robot.rotors)], axis=1)

    legs = [s[..., 6:9].truncate(2).d[k] for k in range(3)]
    attitude = [np.stack([beta.d[k] - legs[k], 0.0 * beta.d[k], roll.d[k]], axis=-1) for k in range(3)]
    rate_squared = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    angular_velocity = np.stack(w, axis=-1)
    gravity = kind.spatial_chain.gravity
    chain_force = force.value - robot.drone_masses[:, None] * (accel - gravity)

    # the planar robots' roll fields, for files and figures (nothing differentiates them): each drone's tilt
    # from the world's vertical, its angular speed |w_i| and the magnitude of its angular acceleration
    f_value = _value(force.value)
    tilt = np.arctan2(np.hypot(f_value[..., 0], f_value[..., 1]), f_value[..., 2])
    speed = np.sqrt(np.maximum(_value(rate_squared), 0.0))  # (a complex step's real part may dip below 0)
    w_dot_value = np.stack([_value(c) for c in w_dot], axis=-1)
    return MotionInputs(
        motion=m[:5],
        thrust_vector=force.value,
        thrust_vector_rate=force.d[1],
        thrust=thrust,
        roll=tilt,
        roll_rate=speed,
        roll_acceleration=np.sqrt(np.sum(w_dot_value**2, axis=-1)),
        torque=torque,
        rotor_speed_squared=w2,
        rotor_speed=signed_speeds(w2),
        joint_position=kind.geometry.tips(m[0]),
        joint_velocity=tip_velocity.value,
        joint_acceleration=accel,
        chain_force=chain_force,
        attitude=attitude[0],
        attitude_rate=attitude[1],
        attitude_acceleration=attitude[2],
        attitude_rate_squared=rate_squared,
        angular_velocity=angular_velocity,
    )


__all__ = ["spatial_motion_inputs"]
