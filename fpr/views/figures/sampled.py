"""Sampled plans as the figures read them: the checks of a sampled plan against its robot, and the
cumulative integrals of the indices J_e(t), J_phi(t) (seed 3.24-3.25).

A sampled plan is a :class:`planners.optimize.SampledPlan` (``PlanResult.sampled(rate)``) or any object
with the same attributes (see :mod:`fpr.views.figures`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from fpr.model.errors import FigureError, ShapeError
from fpr.views.figures.robot_info import _robot_sizes
from fpr.views.figures.style import STYLE
from planners.optimize import SampledPlan


# ------------------------------------------------------------------------------------------ numbers
def cumulative_integral(t, values) -> np.ndarray:
    r"""Cumulative trapezoidal integral of samples along the first axis, starting from 0.

    .. math:: I_0 = 0, \quad I_k = I_{k-1} + \tfrac{1}{2} (t_k - t_{k-1}) (v_k + v_{k-1})

    Its last entry is ``np.trapezoid(values, t, axis=0)``.

    Args:
        t: sample times, shape (N,) [s], non-decreasing.
        values: samples, shape (N, ...) [unit].

    Returns:
        The integral from t_0 to each t_k, shape of ``values`` [unit s].

    Raises:
        ShapeError: ``t`` is not 1-D or ``values`` does not have N rows.
        FigureError: ``t`` decreases somewhere or a value is not finite.
    """
    t = np.asarray(t, dtype=float)
    v = np.asarray(values, dtype=float)
    if t.ndim != 1:
        raise ShapeError("t", t.shape, "(N,): one time per sample [s]")
    if v.ndim == 0 or v.shape[0] != t.shape[0]:
        raise ShapeError("values", v.shape, f"({t.shape[0]}, ...): one row per time in t")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
        raise FigureError("t, values", (t, v), "t or values contain NaN or inf: integrate finite samples "
                                               "only")
    dt = np.diff(t)
    if np.any(dt < 0):
        k = int(np.flatnonzero(dt < 0)[0])
        raise FigureError("t", t, f"t decreases from t[{k}]={t[k]:.6g} s to t[{k + 1}]={t[k + 1]:.6g} s: "
                                  "sort the samples by time")
    out = np.zeros_like(v)
    if t.size > 1:
        steps = 0.5 * dt.reshape((-1,) + (1,) * (v.ndim - 1)) * (v[1:] + v[:-1])
        np.cumsum(steps, axis=0, out=out[1:])
    return out


# ------------------------------------------------------------------------------------ sampled plans
@dataclass(frozen=True)
class _Trace:
    """A validated sampled plan, with the way it is drawn."""

    label: str
    t: np.ndarray  # (N,) [s]
    s: np.ndarray  # (N, n_s) positions in planning coordinates
    joints: np.ndarray  # (N, n_d, len(force_axes)) drone joints [m]
    thrust: np.ndarray  # (N, n_d) [N]
    roll: np.ndarray  # (N, n_d) [rad] (a spatial robot's: its kind's motion_inputs says what)
    roll_rate: np.ndarray  # (N, n_d) [rad/s]: roll_rate**2 is the perturbation index's integrand
    rotor_speed: np.ndarray  # (N, n_d, 4) [rad/s]
    power: np.ndarray  # (N, n_d) [W]
    knots: np.ndarray  # (m+1,) [s]
    is_way: np.ndarray  # (m+1,) bool
    point_positions: np.ndarray  # (m+1, n_s)
    is_reference: bool

    @property
    def line(self) -> dict[str, Any]:
        """Keyword arguments of ``Axes.plot`` for this trace."""
        if self.is_reference:
            return {"color": STYLE["reference_color"], "linestyle": STYLE["reference_style"],
                    "linewidth": STYLE["line_width"], "zorder": 2}
        return {"color": STYLE["plan_color"], "linestyle": "-", "linewidth": STYLE["line_width"], "zorder": 3}

    @property
    def energy(self) -> np.ndarray:
        """J_e(t) = int_0^t sum_i |F_i . v_i| dt (seed 3.24), shape (N,) [J]."""
        return cumulative_integral(self.t, self.power.sum(axis=1))

    @property
    def perturbation(self) -> np.ndarray:
        """J_phi(t) = int_0^t sum_i phidot_i^2 dt (seed 3.25), shape (N,) [rad^2/s]."""
        return cumulative_integral(self.t, np.sum(self.roll_rate**2, axis=1))


def _field(owner: str, obj, attribute: str, shape: tuple, what: str) -> np.ndarray:
    """obj.attribute as a float (bool for ``is_way``) array whose shape matches ``shape`` (None = any size).

    Args:
        owner: how the caller names ``obj`` (``plan``, ``reference``, ``plan.inputs``, ``log``).
        obj: the object read.
        attribute: the attribute read.
        shape: the expected shape; None entries match any size.
        what: what the attribute holds, for the message.

    Raises:
        FigureError: the attribute is missing or not finite.
        ShapeError: it has another shape.
    """
    if not hasattr(obj, attribute):
        if owner.endswith(".inputs"):
            hint = "pass the MotionInputs of fpr.model.inverse_dynamics.inverse_dynamics(robot, motion)"
        elif owner == "log":
            hint = "pass the SimulationLog of fpr.sim.closed_loop.simulate"
        else:
            hint = "a sampled plan needs label, t, motion, inputs (MotionInputs), knots, is_way and points"
        raise FigureError(owner, obj, f"{owner} has no attribute {attribute!r}: {hint}")
    a = np.asarray(getattr(obj, attribute), dtype=bool if attribute == "is_way" else float)
    if a.ndim != len(shape) or any(n is not None and n != m for n, m in zip(shape, a.shape, strict=True)):
        expected = ", ".join("?" if n is None else str(n) for n in shape)
        comma = "," if len(shape) == 1 else ""
        raise ShapeError(f"{owner}.{attribute}", a.shape, f"({expected}{comma}): {what}")
    if a.dtype != bool and not np.all(np.isfinite(a)):
        raise FigureError(f"{owner}.{attribute}", a, f"{owner}.{attribute} contains NaN or inf: the figures "
                                                     "need finite values")
    return a


def _trace(robot, plan, owner: str, is_reference: bool) -> _Trace:
    """The sampled plan ``plan`` (named ``owner`` in messages) checked against the robot's sizes.

    Raises:
        FigureError: an unknown robot, a missing or non-finite attribute, fewer than 2 samples or
            decreasing times.
        ShapeError: an attribute whose shape does not fit the robot.
    """
    n_s, n_d = _robot_sizes(robot)
    t = _field(owner, plan, "t", (None,), "sample times [s]")
    n = t.shape[0]
    if n < 2:
        raise FigureError(f"{owner}.t", t, f"{owner}.t has {n} sample(s): the figures need at least 2")
    if np.any(np.diff(t) < 0):
        raise FigureError(f"{owner}.t", t, f"{owner}.t decreases: sort the samples by time")
    motion = _field(owner, plan, "motion", (None, n, n_s), f"s and its derivatives at the N samples "
                                                           f"({robot.name}: n_s = {n_s})")
    if not hasattr(plan, "inputs"):
        raise FigureError(owner, plan, f"{owner} has no attribute 'inputs': pass the MotionInputs of "
                                       "fpr.model.inverse_dynamics.inverse_dynamics(robot, motion)")
    inputs = plan.inputs
    where = f"{owner}.inputs"
    knots = _field(owner, plan, "knots", (None,), "times of the points [s]")
    m1 = knots.shape[0]
    return _Trace(
        label=str(getattr(plan, "label", "reference" if is_reference else "plan")),
        t=t,
        s=motion[0],
        joints=_field(where, inputs, "joint_position", (n, n_d, len(robot.kind.force_axes)),
                      f"drone joints ({', '.join(robot.kind.force_axes)}) [m]"),
        thrust=_field(where, inputs, "thrust", (n, n_d), "thrust of each drone [N]"),
        roll=_field(where, inputs, "roll", (n, n_d), "roll of each drone [rad]"),
        roll_rate=_field(where, inputs, "roll_rate", (n, n_d), "roll rate of each drone [rad/s]"),
        rotor_speed=_field(where, inputs, "rotor_speed", (n, n_d, 4), "rotor speeds [rad/s]"),
        power=_field(where, inputs, "power", (n, n_d), "|F_i . v_i| of each drone [W]"),
        knots=knots,
        is_way=_field(owner, plan, "is_way", (m1,), "True for way points, False for via points"),
        point_positions=_field(owner, plan, "points", (m1, None, n_s), "the points of the polynomial")[:, 0],
        is_reference=is_reference,
    )


def _traces(robot, plan: SampledPlan, reference: SampledPlan | None) -> list[_Trace]:
    """The plan (first) and the reference (if given), validated against the robot."""
    out = [_trace(robot, plan, "plan", False)]
    if reference is not None:
        out.append(_trace(robot, reference, "reference", True))
    return out

