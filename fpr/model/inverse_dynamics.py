"""Inverse dynamics of a planned motion: what each drone must do to fly it (seed 3.12-3.17, 3.31, 3.47).

From the chain motion s(t) (FPR: ``[y z phi q21]``; prototype: ``xi = [q1 q2]``) and its time
derivatives up to the 4th, for every sample at once:

1. **Thrust vectors** F_i (world y, z) with the seed's planning model, where each drone is a point
   mass at its joint (eq. 2.6-2.7 with p_i left out, 2.16, 3.12; 3.37 for the prototype):

   .. math:: J_h(s)^T F = M_s(s) \\ddot s + c_s(s, \\dot s),

   M_s, c_s being the chain plus the drones' point masses and J_h the Jacobian of the drone
   joints. This is what makes s a flat output: the drone roll is then the direction of F_i
   (eq. 2.20), phi_i = atan2(-F_iy, F_iz), and the thrust its norm f_i = |F_i|. F, F', F'' come
   exactly from the motion's derivatives by jet arithmetic, hence phi_i, phi_i', phi_i''.
2. **Torques** (eq. 2.24 with perfect tracking): the roll torque that gives the drone the roll
   acceleration phi_i'' in the *exact* multibody model (rigid drones whose joint is d_i below their
   centre of mass), given the thrusts. In the plane the yaw and pitch torques are zero: the
   attitude rows psi, theta of the full model are decoupled from the in-plane motion (tested).
3. **Rotor speeds** w_i^2 = R_f^-1 [f_i, tau_i] (eq. 3.31, 3.47).

With d_i > 0 the exact model does not follow s exactly under these inputs: the difference is the
perturbation p_i of eq. 2.7-2.8 that the controller compensates. With d_i = 0 the round trip is
exact (tested).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fpr.model import jets
from fpr.model.errors import ShapeError
from fpr.model.jets import Jet


@dataclass(frozen=True)
class MotionInputs:
    """What the drones must do along a motion; arrays over N samples and n_d drones.

    Attributes:
        motion: s and its derivatives 0..4, shape (5, N, n_s).
        thrust_vector: F_i in world (y, z), shape (N, n_d, 2) [N].
        thrust_vector_rate: dF_i/dt, shape (N, n_d, 2) [N/s].
        thrust: f_i = |F_i|, shape (N, n_d) [N].
        roll: phi_i, shape (N, n_d) [rad].
        roll_rate: phi_i', shape (N, n_d) [rad/s].
        roll_acceleration: phi_i'', shape (N, n_d) [rad/s^2].
        torque: [tau_x, tau_y, tau_z] of each drone, shape (N, n_d, 3) [N m].
        rotor_speed_squared: w^2 of each rotor, shape (N, n_d, 4) [(rad/s)^2]; negative = impossible.
        rotor_speed: sign(w^2) sqrt(|w^2|), shape (N, n_d, 4) [rad/s].
        joint_position: drone joints r_i, shape (N, n_d, 2) [m].
        joint_velocity: r_i', shape (N, n_d, 2) [m/s].
        joint_acceleration: r_i'', shape (N, n_d, 2) [m/s^2].
        chain_force: f_pi, force of drone i on the chain at its joint, shape (N, n_d, 2) [N].
    """

    motion: np.ndarray
    thrust_vector: np.ndarray
    thrust_vector_rate: np.ndarray
    thrust: np.ndarray
    roll: np.ndarray
    roll_rate: np.ndarray
    roll_acceleration: np.ndarray
    torque: np.ndarray
    rotor_speed_squared: np.ndarray
    rotor_speed: np.ndarray
    joint_position: np.ndarray
    joint_velocity: np.ndarray
    joint_acceleration: np.ndarray
    chain_force: np.ndarray

    @property
    def power(self) -> np.ndarray:
        """|F_i . r_i'|, the power estimate of the energy index J_e (seed 3.24), shape (N, n_d) [W]."""
        return np.abs(np.sum(self.thrust_vector * self.joint_velocity, axis=-1))

    def full_state(self, robot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Configurations, velocities and accelerations of the full model (x = psi = theta = 0),
        each of shape (N, n): the chain coordinates from the motion, the drone rolls from the plan."""
        n = self.motion.shape[1]
        out = [np.zeros((n, robot.nq)) for _ in range(3)]
        chain = robot.indices(robot.layout.chain)
        rolls = robot.indices(robot.layout.rolls)
        for k, roll in enumerate((self.roll, self.roll_rate, self.roll_acceleration)):
            out[k][:, chain] = self.motion[k]
            out[k][:, rolls] = roll
        return tuple(out)


def _motion_array(robot, motion) -> np.ndarray:
    n_s = len(robot.layout.chain)
    m = jets.inexact(motion.d if isinstance(motion, Jet) else motion)
    if m.ndim == 2:
        m = m[:, None, :]
    if m.ndim != 3 or m.shape[0] < 5 or m.shape[2] != n_s:
        raise ShapeError("motion", m.shape, f"(5, N, {n_s}): s and its derivatives 0..4 at N samples")
    return m


def thrust_vectors(robot, motion: Jet, order: int | None = None) -> Jet:
    """F = J_h^-T (M_s s'' + c_s) along a motion (planning model), Jet of shape (N, n_d, 2).

    For the prototype the solve is written so that it stays exact through its Type-2 singularity
    (see :func:`prototype_thrust_vectors`).

    Args:
        robot: the :class:`~fpr.model.robot.Robot`.
        motion: s as a Jet of order K >= 2, shape (N, n_s).
        order: derivative order of the result (default K - 2).
    """
    point = robot.planar("point")
    generalized = point.inverse_dynamics_jet(motion)
    if robot.name == "prototype":
        return prototype_thrust_vectors(motion, generalized, robot.link_length,
                                        generalized.order if order is None else order)[:, None, :]
    if order is not None:
        generalized = generalized.truncate(order)
    jac = point.hinge_jacobian_jet(motion.truncate(generalized.order))
    force = jets.solve(jac.mT, generalized)
    return force.reshape(force.shape[:-1] + (robot.n_drones, 2))


#: Derivative order at which to evaluate planned motions for :func:`inverse_dynamics` (0..6: the
#: prototype's crossing of its Type-2 singularity needs the 5th and 6th; elsewhere 0..4 suffice).
MOTION_ORDER = 6

#: |sin q2| below which a sample is examined for a nearby crossing of q2 = 0 (and the motion's 5th
#: and 6th derivatives are used, when given).
SINGULAR_SCREEN = 5e-2

#: Largest time [s] between a sample and the crossing (the root of sin q2's Taylor polynomial) at
#: which the link tension's limit is computed by deflation. Beyond it the plain quotient is accurate
#: (its error in F'' grows like eps / (q2' dt^3): ~1e-6 of the value at 3 ms and q2' = 0.2 rad/s).
SINGULAR_TIME = 3e-3

#: Largest criterion residual g(t*) [N m], relative to 1 + the size of g's Taylor coefficients,
#: for which the crossing is taken as meeting the criterion (finite force). A larger one is a real
#: singularity: the plain quotient is kept, and the force there is as large as it really is.
CRITERION_TOLERANCE = 1e-6


def prototype_thrust_vectors(motion: Jet, generalized: Jet, link_length: float, order: int) -> Jet:
    """The prototype's thrust vector F from J_pr^T F = b (seed 3.37), exact through q2 = 0.

    With e = u(q1 + q2) along the second link and e_perp = u_perp(q1 + q2) across it, the columns of
    J_pr are L (u_perp(q1) + e_perp) and L e_perp, so writing F = f_r e + f_p e_perp::

        b2 = L f_p,      b1 - b2 (1 + cos q2) = L f_r sin q2.

    The component across the link, f_p, is regular everywhere. The tension f_r = g / (L sin q2),
    g = b1 - b2 (1 + cos q2), is a 0/0 limit at the singularity when the motion satisfies the
    crossing criterion (seed 4.7: at q2 = 0, g = -[-1 2] b = 0), and there the plain quotient
    loses every digit. So at a sample where q2 crosses 0 nearby (cos q2 > 0, a simple real root t*
    of sin q2's Taylor polynomial within :data:`SINGULAR_TIME`) *and* g(t*) vanishes there (within
    :data:`CRITERION_TOLERANCE`), both Taylor polynomials are deflated by (t - t*) and
    f_r = g~ / s~, without cancellation. Everywhere else, a grazing q2 = 0 and a crossing that
    misses the criterion included, the plain quotient is used: the force there is really large.

    Args:
        motion: xi = [q1, q2] as a Jet of order K, shape (N, 2).
        generalized: b = M xi'' + c (point-mass drone), Jet of order >= ``order``, shape (N, 2).
        link_length: L [m].
        order: derivative order of F wanted. Deflation needs K >= order + 4 (F, F', F'' need xi up
            to its 6th derivative: with one order less the truncated Taylor polynomials leave, at
            3 ms from a crossing at 2.5 rad/s, ~1e-3 N in F and ~10 rad/s^2 in the roll
            acceleration; tested); with less, the plain quotient is used.

    Returns:
        F, Jet of the given order, shape (N, 2) [N].
    """
    xi = motion
    q12 = xi[..., 0] + xi[..., 1]
    s_e, c_e = jets.sincos(q12.truncate(order))
    sin2 = jets.sin(xi[..., 1])
    b1, b2 = generalized[..., 0], generalized[..., 1]
    g = b1 - b2 * (1.0 + jets.cos(xi[..., 1].truncate(b1.order)))
    f_p = b2.truncate(order) / link_length
    with np.errstate(divide="ignore", invalid="ignore"):
        plain = g.truncate(order) / sin2.truncate(order)
    d = np.array(plain.d)
    near = (np.abs(np.real(sin2.value)) < SINGULAR_SCREEN) & (np.cos(np.real(xi.value[..., 1])) > 0)
    if np.any(near) and g.order >= order + 2:
        k = min(g.order, sin2.order) + 1  # every Taylor coefficient available (more = more accurate)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            quotient, root, remainder, size = _deflated_quotient(g.d[:k, near], sin2.d[:k, near], order)
        use = (np.isfinite(np.real(root)) & (np.abs(np.real(root)) <= SINGULAR_TIME)
               & (np.abs(np.real(remainder)) <= CRITERION_TOLERANCE * (1.0 + size)))
        index = np.flatnonzero(near)[use]
        d[:, index] = quotient[:, use]
    f_r = Jet(d) / link_length
    fy = f_r * c_e - f_p * s_e
    fz = f_r * s_e + f_p * c_e
    return jets.stack([fy, fz], axis=-1)


def _deflated_quotient(num: np.ndarray, den: np.ndarray, order: int):
    """Derivatives 0..order of num/den at samples where den has a simple root t* near 0.

    ``num``, ``den``: derivatives 0..k-1 (leading axis, k >= order + 2) of each function at the samples.
    Both Taylor polynomials are divided by (eps - eps*), eps* the root of den's polynomial found
    by Newton's method from -den/den', and the quotient's Taylor coefficients follow from the
    deflated ones. Analytic in the inputs (complex-step safe).

    Returns:
        (derivatives (order+1, N), eps* (N,) [s], the dropped remainder num(t*) (N,), the size of num's
        Taylor coefficients (N,)), for the caller to accept the deflation or not.
    """
    k = num.shape[0]
    fact = np.cumprod(np.r_[1.0, np.arange(1, k)])[:, None]
    a = num / fact  # Taylor coefficients a_0..a_{k-1}
    c = den / fact
    root = -c[0] / c[1]
    for _ in range(6):
        value = sum(c[j] * root**j for j in range(k))
        slope = sum(j * c[j] * root ** (j - 1) for j in range(1, k))
        root = root - value / slope

    def deflate(p):
        q = [None] * (k - 1)
        q[k - 2] = p[k - 1]
        for j in range(k - 3, -1, -1):
            q[j] = p[j + 1] + root * q[j + 1]
        return q, p[0] + root * q[0]

    (at, remainder), (ct, _) = deflate(a), deflate(c)
    f = []
    for j in range(order + 1):
        acc = at[j] - sum(f[i] * ct[j - i] for i in range(j))
        f.append(acc / ct[0])
    size = np.max(np.abs(np.real(a)), axis=0)
    return np.stack(f) * fact[:order + 1], root, remainder, size


def roll_torques(robot, q, v, thrust, roll_acceleration) -> np.ndarray:
    """Roll torques giving the drones the roll accelerations phi_i'' in the exact planar model.

    .. math:: \\tau_x = (S M^{-1} S^T)^{-1} \\left(\\ddot\\phi - S M^{-1} (B_f f - c)\\right)

    (the roll rows of seed 2.24 with psi'' = theta'' = 0), S selecting the drone rolls and B_f f the
    generalised force of the thrusts applied at the drones' centres of mass along their body z.

    Args:
        robot: the robot.
        q, v: planar configuration and velocity ([chain..., rolls...]), shape (N, n).
        thrust: f_i, shape (N, n_d) [N].
        roll_acceleration: phi_i'', shape (N, n_d) [rad/s^2].

    Returns:
        tau_x of each drone, shape (N, n_d) [N m].
    """
    rigid = robot.planar("rigid")
    m, c = rigid.mass_matrix_and_bias(q, v)
    sel = np.array(rigid.drone_angles)  # (n_d, n)
    gen = -c
    for i, centre in enumerate(rigid.drone_centres):
        angle = q @ sel[i]
        body_z = np.stack([-np.sin(angle), np.cos(angle)], axis=-1)
        gen = gen + np.einsum("...in,...i->...n", centre.jacobian(q), body_z) * thrust[..., i : i + 1]
    rhs = np.concatenate([gen[..., None], np.broadcast_to(sel.T, m.shape[:-2] + sel.T.shape)], axis=-1)
    sol = np.linalg.solve(m, rhs)  # M^-1 [B_f f - c, S^T]
    drift = sol[..., 0] @ sel.T
    a_tau = np.einsum("ij,...jk->...ik", sel, sol[..., 1:])
    return np.linalg.solve(a_tau, (roll_acceleration - drift)[..., None])[..., 0]


def inverse_dynamics(robot, motion) -> MotionInputs:
    """Thrusts, rolls, torques and rotor speeds along a motion of the chain.

    Args:
        robot: the :class:`~fpr.model.robot.Robot` (FPR or prototype).
        motion: s and its time derivatives 0..4, shape (5, N, n_s) (or (5, n_s) for one sample),
            e.g. from :meth:`planners.polynomial.PiecewisePolynomial.evaluate`. Rows 5 and 6 (the
            5th and 6th derivatives) are used, and needed, where the prototype comes within
            :data:`SINGULAR_SCREEN` of its Type-2 singularity (the link tension's limit there).

    Returns:
        the :class:`MotionInputs` at the N samples.
    """
    m = _motion_array(robot, motion)
    near = robot.name == "prototype" and np.any(np.abs(np.sin(np.real(m[0, :, 1]))) < SINGULAR_SCREEN)
    s = Jet(m if near else m[:5])  # higher derivatives only where the tension's limit needs them
    force = thrust_vectors(robot, s, order=2)
    fy, fz = force[..., 0], force[..., 1]
    thrust = jets.sqrt(fy * fy + fz * fz)
    roll = jets.atan2(-fy, fz)

    point = robot.planar("point")
    hinges = jets.stack([h.position_jet(s.truncate(2)) for h in point.hinges], axis=-2)  # (N, n_d, 2)
    chain_force = force.value - robot.drone_mass * (hinges.d[2] - np.array([0.0, -point.gravity]))

    q = np.concatenate([m[0], roll.value], axis=-1)
    v = np.concatenate([m[1], roll.d[1]], axis=-1)
    tau_x = roll_torques(robot, q, v, thrust.value, roll.d[2])
    torque = np.zeros(tau_x.shape + (3,), tau_x.dtype)
    torque[..., 0] = tau_x
    w2 = np.stack([rotor.speeds_squared(thrust.value[:, i], torque[:, i]) for i, rotor in enumerate(robot.rotors)],
                  axis=1)
    return MotionInputs(
        motion=m[:5],
        thrust_vector=force.value,
        thrust_vector_rate=force.d[1],
        thrust=thrust.value,
        roll=roll.value,
        roll_rate=roll.d[1],
        roll_acceleration=roll.d[2],
        torque=torque,
        rotor_speed_squared=w2,
        rotor_speed=np.sign(w2) * np.sqrt(np.abs(w2)),
        joint_position=hinges.value,
        joint_velocity=hinges.d[1],
        joint_acceleration=hinges.d[2],
        chain_force=chain_force,
    )
