"""What the figures ask of a robot: its sizes, figure titles, task-space points and coordinate bounds.

The figures never test a robot's name: everything specific to a robot comes from its kind
(``robot.kind``, :class:`fpr.robots.base.RobotKind`): ``titles``, ``task_points``, ``task_point_labels``,
``joint_legends``, ``height_panels``, ``coordinate_axes``, ``drone_joint_velocities`` and ``fixed_point``.
"""

from __future__ import annotations

import numpy as np

from fpr.model.errors import FigureError


def _kind(robot):
    """The robot's kind, or a FigureError saying what to pass."""
    kind = getattr(robot, "kind", None)
    if kind is None or not hasattr(robot, "layout"):
        raise FigureError("robot", robot, f"robot={robot!r} is not a robot: pass fpr.load(name) "
                                          "(a fpr.model.robot.Robot with its kind)")
    return kind


def _robot_sizes(robot) -> tuple[int, int]:
    """(n_s planning coordinates, n_d drones) of the robot.

    Raises:
        FigureError: not a robot.
    """
    _kind(robot)
    return len(robot.layout.chain), robot.n_drones


def _title(robot, which: str) -> str:
    """The title of figure ``which`` ("path", "sim_heights"...) for ``robot``; the figure's name if it has none."""
    return _kind(robot).titles.get(which, which)


def _task_space_joints(robot, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(main point, other joints) in the task space along s, shape (N, 2) and (N, k, 2) [m].

    FPR: the end-effector p and the drone joints r1, r2 (2.1); prototype: the drone joint (joint 3)
    and the elbow (joint 2) (3.35).
    """
    return _kind(robot).task_points(s)


def _coordinate_axes(robot) -> list[tuple[str, tuple[float, float] | None]]:
    """(y label, (lower, upper) bounds or None) of each planning coordinate (seed 3.28-3.29, 3.44-3.46)."""
    return _kind(robot).coordinate_axes()


def _drone_joint_velocities(robot, s: np.ndarray, s_rate: np.ndarray) -> np.ndarray:
    """Velocities r_i' of the drone joints (y, z) along a chain motion s(t), shape (N, n_d, 2) [m/s].

    FPR: the time derivatives of r_i = p - L u(.) (2.1); prototype: J_pr xi' (3.35).
    """
    return _kind(robot).drone_joint_velocities(s, s_rate)
