"""What the figures ask of a robot: its sizes, figure titles, task-space points and coordinate bounds.

The figures never test a robot's name: everything specific to a robot comes from its kind
(``robot.kind``, :class:`fpr.robots.base.RobotKind`): ``titles``, ``task_points``, ``task_point_labels``,
``joint_legends``, ``height_panels``, ``coordinate_axes``, ``drone_joint_velocities`` and ``fixed_point``.
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Mapping

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


#: What the figures being drawn show besides the robot (:func:`figure_context`); None outside one.
_CONTEXT: contextvars.ContextVar[dict | None] = contextvars.ContextVar("figure_context", default=None)


@contextlib.contextmanager
def figure_context(figure_numbers: Mapping[str, str] | str | None = None, crossing: bool = False,
                   min_thrust: float | None = None):
    """Draw the figures inside this block for a particular motion.

    Args:
        figure_numbers: the thesis figure(s) the motion reproduces, instead of the robot's default ones (e.g. the
            appendix' 1-step / 2-step runs are Fig. 4.11-4.18, not 3.11-3.18): one text for every figure, or
            figure name -> text; the title becomes "<text> — <what the figure shows>".
        crossing: the motion crosses the Type-2 singularity on purpose: the assembly-mode bounds it crosses are not
            drawn (they do not apply to it).
        min_thrust: the thrust floor the motion was planned with [N] (drawn on the thrust figures), or None.
    """
    token = _CONTEXT.set({"figure_numbers": figure_numbers, "crossing": crossing, "min_thrust": min_thrust})
    try:
        yield
    finally:
        _CONTEXT.reset(token)


def _context(key: str):
    """A value of the current :func:`figure_context` (None / False outside one)."""
    context = _CONTEXT.get()
    return None if context is None else context.get(key)


def _title(robot, which: str) -> str:
    """The title of figure ``which`` ("path", "sim_heights"...) for ``robot``; the figure's name if it has none.

    Inside a :func:`figure_context` with ``figure_numbers``, the thesis figure number is replaced.
    """
    title = _kind(robot).titles.get(which, which)
    numbers = _context("figure_numbers")
    if isinstance(numbers, Mapping):
        numbers = numbers.get(which)
    if numbers:
        title = f"{numbers} — {title.split(' — ', 1)[-1]}"
    return title


def _applicable_bounds(bounds, values: np.ndarray):
    """The bounds of a coordinate that apply to a motion taking ``values``: all of them, except, for a motion
    that crosses its singularity on purpose (:func:`figure_context`), those it crosses.
    """
    if not bounds:
        return ()
    if not _context("crossing"):
        return tuple(bounds)
    low, high = float(np.nanmin(values)), float(np.nanmax(values))
    return tuple(b for b in bounds if not (low < b < high))


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
