"""Static poses of a robot and the rotor speeds that hold them (the simulator's usual start), from the planning
model's inverse dynamics of a motionless chain.
"""

from __future__ import annotations

import numpy as np

from fpr.model.errors import ModelArgumentError, check_shape
from fpr.model.inverse_dynamics import inverse_dynamics


def _static_inputs(robot, chain):
    """Inverse dynamics of a motionless chain (:func:`fpr.model.inverse_dynamics.inverse_dynamics`), one sample."""
    s = check_shape("chain", chain, (len(robot.layout.chain),))
    motion = np.zeros((5, s.size))
    motion[0] = s
    return inverse_dynamics(robot, motion)


def hover_configuration(robot, chain) -> np.ndarray:
    """The static pose of a chain configuration: the ``out_of_plane`` coordinates 0 and the drones' attitudes
    (``layout.drone_attitude``: the rolls of a planar robot) that hold it.

    Args:
        robot: the :class:`~fpr.model.robot.Robot`.
        chain: the planning coordinates ``robot.layout.chain`` (FPR s = [y z phi q21] [m, m, rad, rad],
            prototype xi = [q1 q2] [rad]), e.g. ``robot.kind.reference_chain``.

    Returns:
        q, shape (n,), with the drones' thrust axes along their static thrust vectors (seed 2.20).
    """
    q = np.zeros(robot.nq)
    q[robot.indices(robot.layout.chain)] = chain
    q[robot.indices(robot.layout.rolls)] = _static_inputs(robot, chain).attitude[0].reshape(-1)
    return q


def hover_speeds(robot, q, tolerance: float = 1e-6) -> np.ndarray:
    """Rotor speeds that hold the robot still at a static pose.

    The thrusts and roll torques come from :func:`fpr.model.inverse_dynamics.inverse_dynamics` with a
    motionless chain: at rest the planning model's thrust vectors are exact (the forces on a drone
    do not depend on where its mass sits), and the roll torques balance the drones' weight about
    their hinges in the exact model. A static pose has the drones' attitudes along these thrusts (use
    :func:`hover_configuration`) and, for a planar robot, a vertical plane (theta = 0, when theta is among the
    kind's ``out_of_plane`` coordinates); x and psi are free.

    Args:
        robot: the :class:`~fpr.model.robot.Robot`.
        q: a static configuration, shape (n,).
        tolerance: accepted difference of the rolls and theta from the static ones [rad].

    Returns:
        w, shape (n_d, 4) [rad/s].

    Raises:
        ModelArgumentError: q is not a static pose, or holding it needs a rotor speed outside [0, w_max].
    """
    q = check_shape("q", q, (robot.nq,))
    inputs = _static_inputs(robot, q[robot.indices(robot.layout.chain)])
    plane = ("theta",) if "theta" in robot.kind.out_of_plane else ()
    names = robot.layout.rolls + plane
    actual = q[robot.indices(names)]
    static = np.append(inputs.attitude[0].reshape(-1), np.zeros(len(plane)))
    off = np.abs(np.mod(actual - static + np.pi, 2 * np.pi) - np.pi)
    if off.max() > tolerance:
        raise ModelArgumentError("q", q, f"q is not a static pose: ({', '.join(names)}) = "
                                         f"{np.array2string(actual, precision=6)} where holding the chain still "
                                         f"needs {np.array2string(static, precision=6)} (use hover_configuration)")
    w2 = inputs.rotor_speed_squared[0]
    w_max = robot.rotor_constants.max_speed
    if w2.min() < 0 or w2.max() > w_max**2:
        raise ModelArgumentError("q", q, f"holding this pose needs rotor speeds^2 {np.array2string(w2, precision=1)} "
                                         f"(rad/s)^2, outside [0, {w_max:g}^2]")
    return np.sqrt(w2)


__all__ = ["hover_configuration", "hover_speeds"]
