"""Exceptions of the fpr toolkit.

Every error the library raises on purpose derives from :class:`FprError`, so a caller can catch
them all at once; each subclass carries the offending data as attributes and says in its message
what was wrong and what to change.
"""

from __future__ import annotations

import numpy as np


class FprError(Exception):
    """Root of every error raised by fpr on purpose."""


class UnknownRobotError(FprError, ValueError):
    """A robot name that fpr does not know.

    Attributes:
        name: the name that was given.
        known: the names fpr knows.
    """

    def __init__(self, name: str, known: tuple[str, ...]):
        self.name = name
        self.known = tuple(known)
        super().__init__(f"unknown robot {name!r}: use one of {', '.join(map(repr, self.known))}")


class ShapeError(FprError, ValueError):
    """An array argument of the wrong shape.

    Attributes:
        argument: name of the argument.
        shape: the shape that was given.
        expected: a readable description of the expected shape.
    """

    def __init__(self, argument: str, shape: tuple[int, ...], expected: str):
        self.argument = argument
        self.shape = tuple(shape)
        self.expected = expected
        super().__init__(f"{argument}.shape={self.shape}, expected {expected}")


class WorkspaceError(FprError, ValueError):
    """A pose that the robot cannot reach, or that violates a workspace bound.

    Attributes:
        pose: the offending pose (task- or joint-space coordinates).
        reason: what is violated, in words.
    """

    def __init__(self, pose, reason: str):
        self.pose = np.asarray(pose, dtype=float)
        self.reason = reason
        super().__init__(f"pose {np.array2string(self.pose, precision=4)} is outside the workspace: {reason}")


class SingularityError(FprError, ValueError):
    """A configuration on, or closer than allowed to, a Type-2 (parallel) singularity.

    Attributes:
        configuration: the offending configuration.
        margin: its distance to the singular set [rad].
        required: the least distance accepted [rad].
    """

    def __init__(self, configuration, margin: float, required: float, hint: str = ""):
        self.configuration = np.asarray(configuration, dtype=float)
        self.margin = float(margin)
        self.required = float(required)
        msg = (
            f"configuration {np.array2string(self.configuration, precision=4)} is {self.margin:.3g} rad from a "
            f"Type-2 singularity (at least {self.required:.3g} rad required)"
        )
        super().__init__(msg + (f": {hint}" if hint else ""))


class MissionError(FprError, ValueError):
    """A mission (file or object) with a missing, malformed or inconsistent field.

    Attributes:
        field: the offending field, as written in the mission file (e.g. ``times[2]``).
        source: where the mission came from (file path or mission name), or ``""``.
    """

    def __init__(self, field: str, reason: str, source: str = ""):
        self.field = field
        self.source = str(source)
        self.reason = reason
        where = f"{self.source}: " if self.source else ""
        super().__init__(f"{where}field {field!r}: {reason}")


class PlanningError(FprError, RuntimeError):
    """The optimiser could not produce a motion that satisfies every constraint.

    Attributes:
        result: the best result obtained (a :class:`planners.optimize.PlanResult`), still usable.
    """

    def __init__(self, message: str, result=None):
        self.result = result
        super().__init__(message)


class SceneError(FprError, ValueError):
    """A wrong argument of a meshcat scene (:mod:`fpr.views.scene`).

    Attributes:
        argument: the offending argument (``plan``, ``log``, ``configuration``...).
        reason: what is wrong with it and what to give instead.
    """

    def __init__(self, argument: str, reason: str):
        self.argument = argument
        self.reason = reason
        super().__init__(f"{argument}: {reason}")


_FLOAT = np.dtype(float)


def check_shape(argument: str, x, expected: tuple[int | None, ...]) -> np.ndarray:
    """Return ``x`` as a float array after checking its shape.

    Args:
        argument: the argument's name, for the message.
        x: array-like.
        expected: expected shape; ``None`` entries match any size.

    Raises:
        ShapeError: when the number of dimensions or a fixed size differs.
    """
    if type(x) is np.ndarray and x.shape == expected and x.dtype == _FLOAT:  # the usual call: 2 comparisons
        return x
    a = np.asarray(x, dtype=float)
    if a.ndim != len(expected) or any(e is not None and e != s for e, s in zip(expected, a.shape, strict=True)):
        sizes = ", ".join("N" if e is None else str(e) for e in expected)
        shown = "(" + sizes + ("," if len(expected) == 1 else "") + ")"
        raise ShapeError(argument, a.shape, shown)
    return a


class ArgumentError(FprError, ValueError):
    """A wrong argument of a library function; the subclasses say which layer.

    Attributes:
        argument: the offending argument's name.
        value: what was given (as given, possibly an array).
        reason: what is wrong with it and what to give instead (the message).
    """

    def __init__(self, argument: str, value, reason: str):
        self.argument = argument
        self.value = value
        self.reason = reason
        super().__init__(reason)


class TrajectoryError(ArgumentError):
    """A wrong argument of a polynomial trajectory (:mod:`planners.trajectory.polynomial`): points, durations,
    query times, derivative orders, via-point counts (``argument``: ``points``, ``durations``, ``t``,
    ``order``...; ``value``, ``reason`` as in :class:`ArgumentError`).
    """


class PlannerArgumentError(ArgumentError):
    """A wrong argument of a planner, a planning NLP or a study (:mod:`planners`) (``argument``:
    ``solver``, ``free``, ``counts``...; ``value``, ``reason`` as in :class:`ArgumentError`).
    """


class UnknownMethodError(FprError, ValueError):
    """A planning method name that is not in the registry (:data:`planners.methods.METHODS`).

    Attributes:
        name: the name that was given.
        known: the registered names.
    """

    def __init__(self, name: str, known: tuple[str, ...]):
        self.name = name
        self.known = tuple(known)
        super().__init__(f"method={name!r}: use one of {', '.join(self.known)}")


class FigureError(ArgumentError):
    """A wrong argument of a figure (:mod:`fpr.views.figures`): a sampled plan, a simulation log, a robot,
    a study's numbers or a file name that the figures cannot draw or write (``argument``: ``plan.t``,
    ``log``, ``robot``, ``rate``, ``n_via``...; ``value``, ``reason`` as in :class:`ArgumentError`).
    """


class RobotDefinitionError(FprError, ValueError):
    """A robot description or robot kind that fpr cannot use: a URDF without a joint or frame the kind
    names, a Pinocchio model whose coordinates are not the kind's layout, a joint outside the plane of
    motion, an unknown xacro argument, a name registered twice (:mod:`fpr.model`, :mod:`fpr.robots`).

    Attributes:
        robot: the robot's name, or the xacro / URDF file, concerned.
        reason: what is wrong and what to change.
    """

    def __init__(self, robot: str, reason: str):
        self.robot = str(robot)
        self.reason = reason
        super().__init__(f"{self.robot}: {reason}")


class ModelArgumentError(ArgumentError):
    """A wrong argument of a model, robot, simulation or controller function (:mod:`fpr.model`,
    :mod:`fpr.robots`, :mod:`fpr.sim`, :mod:`controllers`) (``argument``: ``mode``, ``arm``, ``dt``, ``q``...;
    ``value``, ``reason`` as in :class:`ArgumentError`).
    """


class NotUniformError(FprError, ValueError):
    """One value asked of a quantity that differs between the robot's drones (or links), e.g.
    ``robot.drone_mass`` of a robot whose drones have different masses.

    Attributes:
        quantity: the quantity asked for (``drone_mass``, ``hinge_offset``...).
        values: its value for each drone (or link).
    """

    def __init__(self, quantity: str, values, hint: str):
        self.quantity = quantity
        self.values = tuple(float(v) for v in values)
        super().__init__(f"{quantity}: the robot's values differ ({', '.join(f'{v:.6g}' for v in self.values)}); "
                         f"{hint}")


class CampaignError(FprError, ValueError):
    """A robustness campaign that cannot run as written (:mod:`fpr.robustness`): a distribution that is not one,
    an unknown quantity, a campaign file with a wrong field, an output folder that holds something else.

    Attributes:
        what: what was given (``model_mass_scale=uniform(2, 1)``, ``runs = 0``, a file or folder...).
        reason: what is wrong and what to do.
    """

    def __init__(self, what: str, reason: str):
        self.what = str(what)
        self.reason = reason
        super().__init__(f"{self.what}: {reason}")
