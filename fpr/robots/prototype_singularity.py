r"""The prototype at its Type-2 singularity (seed ch. 4): the crossing criterion and the forces around it.

The prototype's chain obeys J_pr(xi)^T F = M_pt(xi) xi'' + c_pt(xi, xi') (seed 3.37, drone as a point
mass at its joint). At q2 = 0 the links are aligned and J_pr loses rank: its null vector n = [-1, 2]
(DESIGN.md) is the motion of the elbow across the straight chain with the drone still. No drone force
acts along it, so a motion can only pass q2 = 0 with a finite force if, there,

.. math:: n^T (M_{pt}(\xi_s) \ddot\xi_s + c_{pt}(\xi_s, \dot\xi_s)) = 0 \qquad (4.7)

the *crossing criterion* (:func:`criterion`). It is one linear equation in xi_s'': its solutions
form a line (:func:`criterion_acceleration`, :func:`nearest_criterion_acceleration`). The force is
then finite: across the second link it is regular everywhere, along it (the link's tension) it is
the 0/0 limit that :func:`fpr.robots.prototype_thrust.thrust_vector` computes exactly (the split of F along
and across the link, shared with the controller's regularised tension, is in :mod:`fpr.robots.prototype_thrust`).
Away from the planning model, :func:`acceleration_from_chain_force` gives the chain's direct
dynamics for a given push of the drone (seed 4.11) and :func:`thrust_at` the thrust that push needs.

Every function takes the prototype's :class:`~fpr.model.robot.Robot` (its planar models
``planar("point")``, the chain with the drone as a point mass, and ``planar("none")``, the chain
alone). Only the model layer is used here.
"""

from __future__ import annotations

import numpy as np

from fpr.model.jets import Jet

#: Null vector of J_pr at q2 = 0 (any q1): J_pr n = 0 (seed 4.3; DESIGN.md).
NULL_VECTOR = np.array([-1.0, 2.0])

#: Least thrust of a crossing, as a fraction of the drone's weight. The controller steers the thrust's
#: direction (the roll); at a small thrust a small force error turns it far, and with the drone's
#: joint d below its centre of mass the roll error feeds back into the chain. Measured with the
#: built-in mission (fpr.sim.closed_loop, default controller): planned C4 only at the crossing, with this
#: bound at 0 (least thrust 1.9 N) or 0.5 (4.9 N), the closed loop lost the drone shortly before
#: the crossing; planned C5 there (the default), it tracks at 0 and 0.5 but the allocation saturates
#: (34 and 242 ticks); at 0.8 it saturates on none (tests/test_crossing.py).
MIN_THRUST_FRACTION = 0.8

#: The seed's crossing task (4.1): start and end xi [rad] (the drone at the same point, both modes).
SEED_START = np.array([-0.9470, 1.8940])
SEED_END = np.array([0.9470, -1.8940])


def min_thrust(robot) -> float:
    """The least thrust of a crossing motion, :data:`MIN_THRUST_FRACTION` of m_d g [N]."""
    return MIN_THRUST_FRACTION * robot.drone_mass * robot.planar("point").gravity


def generalised_force(model, xi, xi_dot, xi_ddot) -> np.ndarray:
    """Generalised force M xi'' + c of a planar model at one state (complex-step safe), shape (2,) [N m]."""
    m = np.stack(np.broadcast_arrays(*(np.asarray(a) for a in (xi, xi_dot, xi_ddot))))[:, None, :]
    return model.inverse_dynamics_jet(Jet(m)).value[0]


def affine_dynamics(model, xi, xi_dot) -> tuple[np.ndarray, np.ndarray]:
    """(M, c) of a planar model at (xi, xi'): M xi'' + c is the generalised force [kg m^2, N m]."""
    c = generalised_force(model, xi, xi_dot, np.zeros(2))
    m = np.stack([generalised_force(model, xi, xi_dot, e) - c for e in np.eye(2)], axis=-1)
    return m, c


def criterion(robot, xi, xi_dot, xi_ddot) -> float:
    """n^T (M_pt xi'' + c_pt) (seed 4.7) [N m]: 0 is what a finite force at q2 = 0 needs."""
    return float(np.real(NULL_VECTOR @ generalised_force(robot.planar("point"), xi, xi_dot, xi_ddot)))


def _criterion_line(robot, q1, xi_dot):
    """The criterion's solutions xi'' = base + mu * direction at xi = [q1, 0] (direction unit)."""
    m, c = affine_dynamics(robot.planar("point"), np.array([q1, 0.0 * q1]), xi_dot)
    p = m.T @ NULL_VECTOR  # criterion: p . xi'' + n . c = 0
    norm2 = p @ p
    base = -(NULL_VECTOR @ c) * p / norm2
    direction = np.array([-p[1], p[0]]) / np.sqrt(norm2)
    return base, direction


def criterion_acceleration(robot, q1, xi_dot, mu=0.0) -> np.ndarray:
    """The crossing acceleration xi_s'' [rad/s^2] at xi_s = [q1, 0] that satisfies the criterion (4.7).

    The criterion leaves a line of accelerations; ``mu`` [rad/s^2] is the signed distance along it
    from its point closest to 0. Complex-step safe in all arguments.
    """
    base, direction = _criterion_line(robot, q1, np.asarray(xi_dot))
    return base + mu * direction


def nearest_criterion_acceleration(robot, q1, xi_dot, xi_ddot) -> tuple[np.ndarray, float]:
    """``xi_ddot`` moved onto the criterion's line along the null vector n, and its ``mu``.

    Moving along n leaves the drone's acceleration J_pr xi'' unchanged (J_pr n = 0 at q2 = 0):
    only the elbow's acceleration across the straight chain changes, by what the criterion needs.
    """
    xi_dot = np.asarray(xi_dot, dtype=float)
    xi_ddot = np.asarray(xi_ddot, dtype=float)
    base, direction = _criterion_line(robot, q1, xi_dot)
    residual = criterion(robot, np.array([q1, 0.0]), xi_dot, xi_ddot)
    m, _ = affine_dynamics(robot.planar("point"), np.array([q1, 0.0]), xi_dot)
    moved = xi_ddot - residual / (NULL_VECTOR @ m @ NULL_VECTOR) * NULL_VECTOR
    mu = float(direction @ (moved - base))
    return base + mu * direction, mu


def acceleration_from_chain_force(robot, xi, xi_dot, chain_force) -> np.ndarray:
    """xi'' [rad/s^2] of the passive chain when the drone pushes its joint with ``chain_force`` [N] (seed 4.11).

    M_c xi'' + c_c = J_pr^T f_p, M_c, c_c the chain without the drone (regular at q2 = 0).
    """
    m, c = affine_dynamics(robot.planar("none"), np.asarray(xi, float), np.asarray(xi_dot, float))
    jac = robot.planar("point").hinges[0].jacobian(np.asarray(xi, float))
    return np.linalg.solve(m, jac.T @ np.asarray(chain_force, float) - c)


def thrust_at(robot, xi, xi_dot, xi_ddot, chain_force) -> np.ndarray:
    """Thrust vector F = f_p + m_d (r'' + g e_z) [N] of the (point-mass) drone for a chain force f_p [N]."""
    point = robot.planar("point")
    m = np.stack([np.asarray(a, float) for a in (xi, xi_dot, xi_ddot)])[:, None, :]
    r_dd = point.hinges[0].position_jet(Jet(m)).d[2][0]
    return np.asarray(chain_force, float) + robot.drone_mass * (r_dd + np.array([0.0, point.gravity]))
