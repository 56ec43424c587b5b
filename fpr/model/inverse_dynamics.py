r"""Inverse dynamics of a planned motion: what each drone must do to fly it (seed 3.12-3.17, 3.31, 3.47).

From the chain motion s(t) (FPR: ``[y z phi q21]``; prototype: ``xi = [q1 q2]``) and its time
derivatives up to the 4th, for every sample at once:

1. **Thrust vectors** F_i (world y, z) with the seed's planning model, where each drone is a point
   mass at its joint (eq. 2.6-2.7 with p_i left out, 2.16, 3.12; 3.37 for the prototype):

   .. math:: J_h(s)^T F = M_s(s) \ddot s + c_s(s, \dot s),

   M_s, c_s being the chain plus the drones' point masses and J_h the Jacobian of the drone
   joints. This is what makes s a flat output: the drone roll is then the direction of F_i
   (eq. 2.20), phi_i = atan2(-F_iy, F_iz), and the thrust its norm f_i = ``|F_i|``. F, F', F'' come
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

import functools
from dataclasses import dataclass

import numpy as np

from fpr.model import dual, jets
from fpr.model.errors import ShapeError
from fpr.model.jets import Jet
from fpr.model.rotors import signed_speeds


@dataclass(frozen=True)
class MotionInputs:
    """What the drones must do along a motion; arrays over N samples and n_d drones.

    Attributes:
        motion: s and its derivatives 0..4, shape (5, N, n_s).
        thrust_vector: F_i in world (y, z), shape (N, n_d, 2) [N].
        thrust_vector_rate: dF_i/dt, shape (N, n_d, 2) [N/s].
        thrust: f_i = ``|F_i|``, shape (N, n_d) [N].
        roll: phi_i, shape (N, n_d) [rad].
        roll_rate: phi_i', shape (N, n_d) [rad/s].
        roll_acceleration: phi_i'', shape (N, n_d) [rad/s^2].
        torque: [tau_x, tau_y, tau_z] of each drone, shape (N, n_d, 3) [N m].
        rotor_speed_squared: w^2 of each rotor, shape (N, n_d, 4) [(rad/s)^2]; negative = impossible.
        rotor_speed: sign(w^2) sqrt(``|w^2|``), shape (N, n_d, 4) [rad/s].
        joint_position: drone joints r_i, shape (N, n_d, 2) [m].
        joint_velocity: r_i', shape (N, n_d, 2) [m/s].
        joint_acceleration: r_i'', shape (N, n_d, 2) [m/s^2].
        chain_force: f_pi, force of drone i on the chain at its joint, shape (N, n_d, 2) [N].
        attitude: each drone's attitude in its coordinates (``layout.drone_attitude``), shape (N, n_d, k_a)
            [rad]: a planar robot's roll phi_i (k_a = 1).
        attitude_rate: their time derivatives, shape (N, n_d, k_a) [rad/s].
        attitude_acceleration: their second time derivatives, shape (N, n_d, k_a) [rad/s^2].
        attitude_rate_squared: the square of each drone's angular speed, the integrand of the perturbation
            index J_phi (seed 3.25) summed over the drones, shape (N, n_d) [rad^2/s^2]: phi_i'^2 for a planar
            robot.
        angular_velocity: the components of each drone's angular velocity whose squares sum to
            ``attitude_rate_squared`` (what the planner's Gauss-Newton model of J_phi takes), shape
            (N, n_d, k_w) [rad/s]: a planar robot's roll rate phi_i' (k_w = 1), a spatial robot's angular velocity
            in the drone's axes (k_w = 3).

    A robot whose drones have more than a roll (the spatial FPR) fills the planar ``roll`` fields with what its
    files and figures show in their place (its kind's ``motion_inputs`` says what).

    The thrust vectors, joint positions and forces have one entry per axis of ``robot.kind.force_axes`` in
    their last axis (the planar robots': world y, z).
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
    attitude: np.ndarray
    attitude_rate: np.ndarray
    attitude_acceleration: np.ndarray
    attitude_rate_squared: np.ndarray
    angular_velocity: np.ndarray

    @property
    def power(self) -> np.ndarray:
        """``|F_i . r_i'|``, the power estimate of the energy index J_e (seed 3.24), shape (N, n_d) [W]."""
        return np.abs(np.sum(self.thrust_vector * self.joint_velocity, axis=-1))

    def full_state(self, robot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Configurations, velocities and accelerations of the full model, each of shape (N, n): the robot
        kind's (``robot.kind.full_state``).
        """
        return robot.kind.full_state(self)


def motion_array(robot, motion) -> np.ndarray:
    """A motion as an array (5 or 7, N, n_s) (a Jet's derivatives, one sample given as (5, n_s) made (5, 1, n_s)).

    Raises:
        ShapeError: not s and its derivatives 0..4 at N samples.
    """
    n_s = len(robot.layout.chain)
    m = jets.inexact(motion.d if isinstance(motion, Jet) else motion)
    if m.ndim == 2:
        m = m[:, None, :]
    if m.ndim != 3 or m.shape[0] < 5 or m.shape[2] != n_s:
        raise ShapeError("motion", m.shape, f"(5, N, {n_s}): s and its derivatives 0..4 at N samples")
    return m


def thrust_vectors(robot, motion: Jet, order: int | None = None, external=None) -> Jet:
    """F = J_h^-T (M_s s'' + c_s) along a motion (planning model), Jet of shape (N, n_d, 2).

    The generalised force b = M_s s'' + c_s comes from the robot kind's point-drone model
    (``robot.kind.generalized_forces``: the planar model's for the planar robots); the solve
    J_h^T F = b is the robot kind's (``robot.kind.thrust_vectors``): :func:`solve_thrust_vectors` for
    most robots, a solve that stays exact through a Type-2 singularity for the prototype.

    Args:
        robot: the :class:`~fpr.model.robot.Robot`.
        motion: s as a Jet of order K >= 2, shape (N, n_s).
        order: derivative order of the result (default K - 2).
        external: the generalised force Q_ext of external forces on the chain (a gust), shape (N, n_s)
            [N or N m] (constant: its time derivatives 0), or a Jet of it with its time derivatives, or
            None: then J_h^T F = M_s s'' + c_s - Q_ext.
    """
    generalized = robot.kind.generalized_forces(motion)
    if external is not None:
        generalized = generalized - (external if isinstance(external, Jet) else np.asarray(external))
    return robot.kind.thrust_vectors(motion, generalized, order)


def solve_thrust_vectors(robot, motion: Jet, generalized: Jet, order: int | None = None) -> Jet:
    """F from J_h(s)^T F = b by a plain solve along the motion, Jet of shape (N, n_d, 2) [N].

    Exact wherever J_h is invertible (away from Type-2 singularities).

    Args:
        robot: the robot.
        motion: s as a Jet of order K, shape (N, n_s).
        generalized: b = M_s s'' + c_s, Jet of order K - 2, shape (N, n_s) [N or N m].
        order: derivative order of the result (default: that of ``generalized``).
    """
    if order is not None:
        generalized = generalized.truncate(order)
    jac = robot.planar("point").hinge_jacobian_jet(motion.truncate(generalized.order))
    force = jets.solve(jac.mT, generalized)
    return force.reshape(force.shape[:-1] + (robot.n_drones, len(robot.kind.force_axes)))


#: Derivative order at which to evaluate planned motions for :func:`inverse_dynamics` (0..6: the
#: prototype's crossing of its Type-2 singularity needs the 5th and 6th; elsewhere 0..4 suffice).
MOTION_ORDER = 6


def roll_torques(robot, q, v, thrust, roll_acceleration, external=None) -> np.ndarray:
    r"""Roll torques giving the drones the roll accelerations phi_i'' in the exact planar model.

    .. math:: \tau_x = (S M^{-1} S^T)^{-1} \left(\ddot\phi - S M^{-1} (B_f f - c)\right)

    (the roll rows of seed 2.24 with psi'' = theta'' = 0), S selecting the drone rolls and B_f f the
    generalised force of the thrusts applied at the drones' centres of mass along their body z.

    Args:
        robot: the robot.
        q: planar configuration [chain..., rolls...], shape (N, n), in the units of ``kind.chain_units``
            for the chain coordinates [m or rad] and [rad] for the rolls.
        v: planar velocity, the time derivative of ``q``, shape (N, n) [m/s or rad/s].
        thrust: f_i, shape (N, n_d) [N].
        roll_acceleration: phi_i'', shape (N, n_d) [rad/s^2].
        external: generalised force of external forces on the chain coordinates, shape (N, n_s), or None
            (added to B_f f - c; zero on the rolls).

    Returns:
        tau_x of each drone, shape (N, n_d) [N m].
    """
    rigid = robot.planar("rigid")
    m, c, centre_jacobians = rigid.dynamics_and_centre_jacobians(q, v)  # (..., n_d, 2, n)
    sel = np.array(rigid.drone_angles)  # (n_d, n)
    gen = -c
    if external is not None:
        ext = external.value if isinstance(external, Jet) else np.asarray(external)
        gen = gen + np.concatenate([ext, np.zeros(ext.shape[:-1] + (gen.shape[-1] - ext.shape[-1],))], axis=-1)
    sin, cos = jets.sin_cos_value(q @ sel.T)  # every drone at once
    force = np.stack([-sin, cos], axis=-1) * thrust[..., None]  # thrust along each body z
    batch, rows = force.shape[:-2], force.shape[-2] * force.shape[-1]  # sum_d J_d^T f_d, one product per sample
    pushed = jets.small_matmul(force.reshape(batch + (1, rows)), centre_jacobians.reshape(batch + (rows, -1)))
    gen = gen + pushed[..., 0, :]
    return _roll_rows(m, gen, sel, roll_acceleration)


@functools.lru_cache(maxsize=32)
def _roll_layout(shape, data):
    """(chain, rolls) indices of a roll selection S (its shape and bytes: a cache key) that selects coordinates,
    as slices when the rolls come last ([chain..., rolls...]: views, no copies); None for another S.
    """
    sel = np.frombuffer(data).reshape(shape)
    rolls = np.flatnonzero(np.any(sel != 0, axis=0))
    if not (len(rolls) == len(sel) and np.array_equal(sel[:, rolls], np.eye(len(sel)))):
        return None
    chain = np.setdiff1d(np.arange(shape[1]), rolls)
    if np.array_equal(rolls, np.arange(len(chain), shape[1])):
        return slice(0, len(chain)), slice(len(chain), None)
    return chain, rolls


def _roll_rows(m, gen, sel, roll_acceleration):
    """tau = (S M^-1 S^T)^-1 (phi'' - S M^-1 g) by the partition of M into the chain (c) and the rolls (r).

    With the rolls the coordinates S selects, (S M^-1 S^T)^-1 is the Schur complement M_rr - M_rc M_cc^-1 M_cr
    and the formula is the roll rows of M a = g + S^T tau with the rolls' accelerations given: the chain's
    acceleration is a_c = M_cc^-1 (g_c - M_cr phi''), and tau = M_rr phi'' + M_rc a_c - g_r (one solve of the
    chain's size, one right-hand side). S is a selection of coordinates on the robots of this package; another
    S falls back on the formula as written.
    """
    sel = np.asarray(sel, dtype=float)
    layout = _roll_layout(sel.shape, sel.tobytes())
    if layout is None:
        rhs = np.concatenate([gen[..., None], np.broadcast_to(sel.T, m.shape[:-2] + sel.T.shape)], axis=-1)
        sol = np.linalg.solve(m, rhs)  # M^-1 [g, S^T]
        a_tau = np.einsum("ij,...jk->...ik", sel, sol[..., 1:])
        return np.linalg.solve(a_tau, (roll_acceleration - sol[..., 0] @ sel.T)[..., None])[..., 0]
    chain, rolls = layout
    # M_cr phi'' and M_rr phi'' as M [0; phi''], M_rc a_c as M [a_c; 0]: whole-M products of one call each
    known = dual.zeros(m.shape[:-1], m, roll_acceleration)
    known[..., rolls] = roll_acceleration
    pushed = jets.small_matmul(m, known[..., None])[..., 0]
    a_chain = jets.solve_matrices(m[..., chain, chain] if isinstance(chain, slice) else m[..., chain[:, None], chain],
                                  (gen[..., chain] - pushed[..., chain])[..., None])[..., 0]
    known[..., chain], known[..., rolls] = a_chain, 0.0
    return pushed[..., rolls] + jets.small_matmul(m, known[..., None])[..., 0][..., rolls] - gen[..., rolls]


def inverse_dynamics(robot, motion, external=None) -> MotionInputs:
    """What the drones must do along a motion of the chain: the robot kind's ``motion_inputs``.

    Args:
        robot: the :class:`~fpr.model.robot.Robot`.
        motion: s and its time derivatives 0..4 (and, where the robot needs them, 5 and 6), shape
            (5, N, n_s) (or (5, n_s) for one sample).
        external: generalised force Q_ext [N or N m] of known external forces on the chain coordinates,
            shape (N, n_s), or a Jet of it with its time derivatives, or None.

    Returns:
        the :class:`MotionInputs` at the N samples (:func:`planar_inverse_dynamics` for the planar robots).
    """
    return robot.kind.motion_inputs(motion, external)


def planar_inverse_dynamics(robot, motion, external=None) -> MotionInputs:
    """Thrusts, rolls, torques and rotor speeds along a motion of a planar robot's chain (drones with one roll
    each, thrust vectors in the world's y-z plane).

    Args:
        robot: the :class:`~fpr.model.robot.Robot`.
        motion: s and its time derivatives 0..4, shape (5, N, n_s) (or (5, n_s) for one sample),
            e.g. from :meth:`planners.trajectory.polynomial.PiecewisePolynomial.evaluate`. Rows 5 and 6 (the
            5th and 6th derivatives) are used, and needed, where the robot kind says so
            (``kind.needs_high_derivatives``: the prototype near its Type-2 singularity, where the
            link tension is a limit).
        external: generalised force Q_ext [N or N m] of known external forces (a gust) on the chain
            coordinates at each sample, shape (N, n_s) (constant), or a Jet of it with its time
            derivatives (then the roll rates and accelerations follow its changes), or None
            (:func:`thrust_vectors`): the drones then fly the motion against it (J_h^T F = M_s s'' + c_s - Q_ext,
            and in the torques' exact model).

    Returns:
        the :class:`MotionInputs` at the N samples.
    """
    m = motion_array(robot, motion)
    near = robot.kind.needs_high_derivatives(m[0])
    s = Jet(m if near else m[:5])  # higher derivatives only where the robot's solve needs them
    force = thrust_vectors(robot, s, order=2, external=external)
    fy, fz = force[..., 0], force[..., 1]
    thrust = jets.sqrt(fy * fy + fz * fz)
    roll = jets.atan2(-fy, fz)

    point = robot.planar("point")
    hinges = point.hinge_positions_jet(s.truncate(2))  # (N, n_d, 2)
    chain_force = force.value - robot.drone_masses[:, None] * (hinges.d[2] - np.array([0.0, -point.gravity]))

    # Duals (planners/problem/sensitivities.py): the rolls' and the thrusts' lower orders depend on fewer directions
    q = np.concatenate([m[0], dual.trimmed(roll.value)], axis=-1)
    v = np.concatenate([m[1], dual.trimmed(roll.d[1])], axis=-1)
    tau_x = roll_torques(robot, q, v, dual.trimmed(thrust.value), roll.d[2], external)
    torque = dual.zeros(tau_x.shape + (3,), tau_x)
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
        rotor_speed=signed_speeds(w2),
        joint_position=hinges.value,
        joint_velocity=hinges.d[1],
        joint_acceleration=hinges.d[2],
        chain_force=chain_force,
        attitude=roll.value[..., None],
        attitude_rate=roll.d[1][..., None],
        attitude_acceleration=roll.d[2][..., None],
        attitude_rate_squared=roll.d[1] ** 2,
        angular_velocity=roll.d[1][..., None],
    )
