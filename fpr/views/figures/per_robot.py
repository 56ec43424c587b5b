"""What the figures know of each robot, by name: sizes, figure titles, task-space points, coordinate bounds.

Every per-robot table and every branch on ``robot.name`` of the figures that is not drawing code sits here
(the rest: :func:`fpr.views.figures.planning._path_axes`, ``_path_figure`` and
:func:`fpr.views.figures.simulation._sim_path`, ``_sim_heights``), so that the robot plug-ins can take
them over in one place.
"""

from __future__ import annotations

import numpy as np

from fpr.model.errors import FigureError
from fpr.robots.fpr import fpr_drone_joint_velocities, fpr_drone_joints
from fpr.robots.prototype import prototype_jacobian, prototype_joints

#: Titles of the figures of :func:`fpr.views.figures.plan_figures`: robot name -> file name -> title.
_TITLES = {
    "fpr": {
        "path": "Fig. 3.11 — path of the end-effector in the task space",
        "coordinates": "Fig. 3.12 — coordinates of the passive chain",
        "energy": "Fig. 3.13 — energy index $J_e$",
        "perturbation": r"Fig. 3.14 — perturbation index $J_\varphi$",
        "thrust": "Fig. 3.15-3.16 — thrust of each drone",
        "roll": "Fig. 3.17-3.18 — roll angle of each drone",
        "rotor_speeds": "Eq. 3.48 — rotor speeds of each drone",
        "rotor_forces": r"Eq. 3.48 — rotor forces $c_T \omega^2$ of each drone",
    },
    "prototype": {
        "path": "Fig. 3.36 — path of the drone of the prototype",
        "coordinates": "Fig. 3.37 — joint angles of the prototype",
        "energy": "Fig. 3.38 — energy index $J_e$ of the prototype",
        "perturbation": r"Fig. 3.39 — perturbation index $J_\varphi$ of the prototype",
        "thrust": "Fig. 3.40 — thrust of the drone of the prototype",
        "roll": "Fig. 3.41 — roll angle of the drone of the prototype",
        "rotor_speeds": "Eq. 3.47-3.48 — rotor speeds of the drone of the prototype",
        "rotor_forces": r"Eq. 3.47-3.48 — rotor forces $c_T \omega^2$ of the drone of the prototype",
    },
}

# robot name -> (n_s planning coordinates, n_d drones)
_SIZES = {"fpr": (4, 2), "prototype": (2, 1)}


#: Titles of the figures of :func:`fpr.views.figures.simulation_figures`: robot name -> file name -> title.
_SIM_TITLES = {
    "fpr": {
        "sim_path": "Fig. 3.19 — end-effector and drone joints, planned and simulated",
        "sim_coordinates": r"Fig. 3.21-3.22, 3.25-3.26 — tracking of y, z, $\varphi$, $q_{21}$",
        "sim_out_of_plane": r"Fig. 3.20, 3.23-3.24 — motion out of the plane: x, pitch $\theta$, yaw $\psi$",
        "sim_roll": "Fig. 3.27-3.28 — roll angle of each drone in simulation",
        "sim_heights": "Fig. 3.29-3.30 — height of each drone in simulation",
        "sim_rotor_speeds": "Eq. 3.48 — rotor speeds of each drone in simulation",
        "sim_rotor_forces": r"Fig. 3.31-3.32 — rotor forces $c_T \omega^2$ of each drone in simulation",
        "sim_energy": r"Energy $J_e$ and perturbation $J_\varphi$ in planning and simulation",
    },
    "prototype": {
        "sim_path": "Fig. 3.42 — drone trajectory in planning and simulation",
        "sim_coordinates": r"Fig. 3.43-3.45 — joint angles $q_1$, $q_2$ and their errors in simulation",
        "sim_out_of_plane": r"Motion out of the plane of the prototype: pitch $\theta$, yaw $\psi$",
        "sim_roll": "Fig. 3.48 — roll angle of the drone in simulation",
        "sim_heights": "Fig. 3.46-3.47 — height of joint 2 and of the drone joint 3 in simulation",
        "sim_rotor_speeds": "Eq. 3.47-3.48 — rotor speeds of the drone in simulation",
        "sim_rotor_forces": r"Fig. 3.49 — rotor forces $c_T \omega^2$ of the drone in simulation",
        "sim_energy": r"Fig. 3.50-3.51 — energy $J_e$ and perturbation $J_\varphi$, planned and simulated",
    },
}


def _robot_sizes(robot) -> tuple[int, int]:
    """(n_s planning coordinates, n_d drones) of the robot.

    Raises:
        FigureError: a robot the figures do not know.
    """
    name = getattr(robot, "name", None)
    if name not in _SIZES:
        raise FigureError("robot.name", name, f"robot.name={name!r}: figures exist for 'fpr' and 'prototype' "
                                              "(pass fpr.load('fpr') or fpr.load('prototype'))")
    return _SIZES[name]


def _task_space_joints(robot, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(main point, other joints) in the task space along s, shape (N, 2) and (N, k, 2) [m].

    FPR: the end-effector p and the drone joints r1, r2 (2.1); prototype: the drone joint (joint 3)
    and the elbow (joint 2) (3.35).
    """
    if robot.name == "fpr":
        return s[:, :2], fpr_drone_joints(s, robot.link_length)
    joints = prototype_joints(s, robot.link_length)
    return joints[:, 1], joints[:, :1]


def _coordinate_axes(robot) -> list[tuple[str, tuple[float, float] | None]]:
    """(y label, (lower, upper) bounds or None) of each planning coordinate (seed 3.28-3.29, 3.44-3.46)."""
    m = robot.margins.angle
    if robot.name == "fpr":
        return [("y [m]", None), ("z [m]", None), (r"$\varphi$ [rad]", (np.pi + m, 2 * np.pi - m)),
                (r"$q_{21}$ [rad]", (m, np.pi - m))]
    return [(r"$q_1$ [rad]", (-(np.pi / 2 - m), np.pi / 2 - m)), (r"$q_2$ [rad]", (m, np.pi - m))]


def _drone_joint_velocities(robot, s: np.ndarray, s_rate: np.ndarray) -> np.ndarray:
    """Velocities r_i' of the drone joints (y, z) along a chain motion s(t), shape (N, n_d, 2) [m/s].

    FPR: the time derivatives of r_i = p - L u(.) (2.1); prototype: J_pr xi' (3.35).
    """
    if robot.name == "fpr":
        return fpr_drone_joint_velocities(s, s_rate, robot.link_length)
    jac = prototype_jacobian(s, robot.link_length)
    return np.einsum("nij,nj->ni", jac, s_rate)[:, None]
