"""Figures of the thesis' motion-planning chapter (seed 3.2.5-3.3.2), written as PNG files.

Three entry points:

* :func:`plan_figures` draws one planned motion (and optionally the stop-at-every-way-point
  reference it is compared with) in the figures of seed 3.11-3.18 (FPR) or 3.36-3.41 (prototype),
  plus the rotor speeds against the limits of eq. 3.48.
* :func:`via_point_study_figure` and :func:`alpha_study_figure` draw the parameter studies of
  seed 3.2.5 (Fig. 3.7-3.10).

A *sampled plan* is any object with the attributes

=========== ===================== =================================================================
``label``   str                   legend text, e.g. "optimised (two-step)"
``t``       (N,) [s]              sample times, non-decreasing
``motion``  (5, N, n_s)           s and its derivatives 0..4 (FPR s = [y z phi q21],
                                  prototype xi = [q1 q2])
``inputs``  MotionInputs          :class:`fpr.inverse_dynamics.MotionInputs` at the N samples
``knots``   (m+1,) [s]            times of all points of the piecewise polynomial
``is_way``  (m+1,) bool           True for a way point, False for a via point
``points``  (m+1, 5, n_s)         the points; ``points[:, 0]`` are positions in planning coordinates
=========== ===================== =================================================================

One style everywhere (:data:`STYLE`): the plan is drawn solid in one colour, the reference dashed
grey, limits as red dotted lines labelled "limit", way points as filled markers and via points as
open ones. Every axis label carries its unit.

matplotlib is imported lazily, inside the functions, and only through
:class:`matplotlib.figure.Figure` with an Agg canvas: pyplot is never imported, so the caller's
backend, open figures and rcParams are left alone (the style is applied in an
:func:`matplotlib.rc_context`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from fpr.errors import ShapeError

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from fpr.inverse_dynamics import MotionInputs

logger = logging.getLogger(__name__)

#: The figures' style: sizes [pt], line widths [pt], colours (matplotlib colour specs), dpi.
STYLE = MappingProxyType({
    "font_size": 9.0,
    "title_size": 10.0,
    "legend_size": 7.0,
    "line_width": 1.6,
    "thin_width": 0.8,
    "marker_size": 5.0,
    "plan_color": "tab:blue",
    "reference_color": "0.45",
    "reference_style": "--",
    "limit_color": "tab:red",
    "limit_style": ":",
    "limit_width": 1.3,
    "ground_color": "saddlebrown",
    "knot_color": "0.6",
    "knot_alpha": 0.5,
    "drone_colors": ("tab:green", "tab:purple"),
    "rotor_colors": ("tab:blue", "tab:orange", "tab:green", "tab:purple"),
    "width": 6.4,  # figure width [inch]
    "row_height": 2.1,  # height of one row of subplots [inch]
    "dpi": 120,
})

#: Legend label of every limit line (also its matplotlib gid, so that tests and users can find them).
LIMIT_LABEL = "limit"

#: File names written by :func:`plan_figures`, in order (without the ".png" suffix).
PLAN_FIGURES = ("path", "coordinates", "energy", "perturbation", "thrust", "roll", "rotor_speeds")

_TITLES = {
    "fpr": {
        "path": "Fig. 3.11 — path of the end-effector in the task space",
        "coordinates": "Fig. 3.12 — coordinates of the passive chain",
        "energy": "Fig. 3.13 — energy index $J_e$",
        "perturbation": r"Fig. 3.14 — perturbation index $J_\varphi$",
        "thrust": "Fig. 3.15-3.16 — thrust of each drone",
        "roll": "Fig. 3.17-3.18 — roll angle of each drone",
        "rotor_speeds": "Eq. 3.48 — rotor speeds of each drone",
    },
    "prototype": {
        "path": "Fig. 3.36 — path of the drone of the prototype",
        "coordinates": "Fig. 3.37 — joint angles of the prototype",
        "energy": "Fig. 3.38 — energy index $J_e$ of the prototype",
        "perturbation": r"Fig. 3.39 — perturbation index $J_\varphi$ of the prototype",
        "thrust": "Fig. 3.40 — thrust of the drone of the prototype",
        "roll": "Fig. 3.41 — roll angle of the drone of the prototype",
        "rotor_speeds": "Eq. 3.47-3.48 — rotor speeds of the drone of the prototype",
    },
}

# robot name -> (n_s planning coordinates, n_d drones)
_SIZES = {"fpr": (4, 2), "prototype": (2, 1)}


class SampledPlan(Protocol):
    """What the figures need from a planned motion (see the module docstring for shapes)."""

    label: str
    t: np.ndarray
    motion: np.ndarray
    inputs: MotionInputs
    knots: np.ndarray
    is_way: np.ndarray
    points: np.ndarray


# ------------------------------------------------------------------------------------------ numbers
def cumulative_integral(t, values) -> np.ndarray:
    """Cumulative trapezoidal integral of samples along the first axis, starting from 0.

    .. math:: I_0 = 0, \\quad I_k = I_{k-1} + \\tfrac{1}{2} (t_k - t_{k-1}) (v_k + v_{k-1})

    Its last entry is ``np.trapezoid(values, t, axis=0)``.

    Args:
        t: sample times, shape (N,) [s], non-decreasing.
        values: samples, shape (N, ...) [unit].

    Returns:
        The integral from t_0 to each t_k, shape of ``values`` [unit s].

    Raises:
        ShapeError: ``t`` is not 1-D or ``values`` does not have N rows.
        ValueError: ``t`` decreases somewhere or a value is not finite.
    """
    t = np.asarray(t, dtype=float)
    v = np.asarray(values, dtype=float)
    if t.ndim != 1:
        raise ShapeError("t", t.shape, "(N,): one time per sample [s]")
    if v.ndim == 0 or v.shape[0] != t.shape[0]:
        raise ShapeError("values", v.shape, f"({t.shape[0]}, ...): one row per time in t")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
        raise ValueError("t or values contain NaN or inf: integrate finite samples only")
    dt = np.diff(t)
    if np.any(dt < 0):
        k = int(np.flatnonzero(dt < 0)[0])
        raise ValueError(f"t decreases from t[{k}]={t[k]:.6g} s to t[{k + 1}]={t[k + 1]:.6g} s: "
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
    joints: np.ndarray  # (N, n_d, 2) drone joints [m]
    thrust: np.ndarray  # (N, n_d) [N]
    roll: np.ndarray  # (N, n_d) [rad]
    roll_rate: np.ndarray  # (N, n_d) [rad/s]
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


def _robot_sizes(robot) -> tuple[int, int]:
    name = getattr(robot, "name", None)
    if name not in _SIZES:
        raise ValueError(f"robot.name={name!r}: figures exist for 'fpr' and 'prototype' "
                         "(pass fpr.load('fpr') or fpr.load('prototype'))")
    return _SIZES[name]


def _field(owner: str, obj, attribute: str, shape: tuple, what: str) -> np.ndarray:
    """obj.attribute as a float array whose shape matches ``shape`` (None = any size)."""
    if not hasattr(obj, attribute):
        if owner.endswith(".inputs"):
            hint = "pass the MotionInputs of fpr.inverse_dynamics.inverse_dynamics(robot, motion)"
        else:
            hint = "a sampled plan needs label, t, motion, inputs (MotionInputs), knots, is_way and points"
        raise ValueError(f"{owner} has no attribute {attribute!r}: {hint}")
    a = np.asarray(getattr(obj, attribute), dtype=bool if attribute == "is_way" else float)
    if a.ndim != len(shape) or any(n is not None and n != m for n, m in zip(shape, a.shape, strict=True)):
        expected = ", ".join("?" if n is None else str(n) for n in shape)
        comma = "," if len(shape) == 1 else ""
        raise ShapeError(f"{owner}.{attribute}", a.shape, f"({expected}{comma}): {what}")
    if a.dtype != bool and not np.all(np.isfinite(a)):
        raise ValueError(f"{owner}.{attribute} contains NaN or inf: the figures need finite values")
    return a


def _trace(robot, plan, owner: str, is_reference: bool) -> _Trace:
    n_s, n_d = _robot_sizes(robot)
    t = _field(owner, plan, "t", (None,), "sample times [s]")
    n = t.shape[0]
    if n < 2:
        raise ValueError(f"{owner}.t has {n} sample(s): the figures need at least 2")
    if np.any(np.diff(t) < 0):
        raise ValueError(f"{owner}.t decreases: sort the samples by time")
    motion = _field(owner, plan, "motion", (None, n, n_s), f"s and its derivatives at the N samples "
                                                           f"({robot.name}: n_s = {n_s})")
    if not hasattr(plan, "inputs"):
        raise ValueError(f"{owner} has no attribute 'inputs': pass the MotionInputs of "
                         "fpr.inverse_dynamics.inverse_dynamics(robot, motion)")
    inputs = plan.inputs
    where = f"{owner}.inputs"
    knots = _field(owner, plan, "knots", (None,), "times of the points [s]")
    m1 = knots.shape[0]
    return _Trace(
        label=str(getattr(plan, "label", "reference" if is_reference else "plan")),
        t=t,
        s=motion[0],
        joints=_field(where, inputs, "joint_position", (n, n_d, 2), "drone joints (y, z) [m]"),
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


# --------------------------------------------------------------------------------------- matplotlib
def _rc() -> dict[str, Any]:
    return {
        "font.size": STYLE["font_size"],
        "axes.titlesize": STYLE["font_size"],
        "axes.labelsize": STYLE["font_size"],
        "figure.titlesize": STYLE["title_size"],
        "legend.fontsize": STYLE["legend_size"],
        "xtick.labelsize": STYLE["font_size"] - 1,
        "ytick.labelsize": STYLE["font_size"] - 1,
        "lines.linewidth": STYLE["line_width"],
        "lines.markersize": STYLE["marker_size"],
        "axes.grid": True,
        "grid.alpha": 0.3,
        "legend.framealpha": 0.8,
    }


@contextmanager
def _styled():
    """Apply the figures' rcParams for the duration of the block only."""
    import matplotlib

    with matplotlib.rc_context(_rc()):
        yield


def _new_figure(rows: int, cols: int = 1, height: float | None = None, width: float | None = None,
                sharex: bool = True) -> tuple[Figure, np.ndarray]:
    """A Figure on an Agg canvas (no pyplot) and its axes as a (rows * cols,) array."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    size = (width or STYLE["width"], height or (0.6 + STYLE["row_height"] * rows))
    fig = Figure(figsize=size, dpi=STYLE["dpi"])
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, sharex=sharex, squeeze=False)
    return fig, axes.reshape(-1)


def _finish(fig: Figure, title: str, axes: Sequence[Axes], legend_below: bool = False) -> Figure:
    """Title the figure, put a legend in every axes that has labelled artists, lay it out.

    Args:
        fig: the figure.
        title: its title, naming the thesis figure.
        axes: the axes that get a legend (one entry per distinct label).
        legend_below: put the legends under their axes instead of inside them.
    """
    fig.suptitle(title)
    for ax in axes:
        handles, labels = ax.get_legend_handles_labels()
        if not handles:
            continue
        unique = dict(zip(labels, handles, strict=True))
        ncol = 1 if len(unique) <= 4 else 2
        if legend_below:
            ax.legend(unique.values(), unique.keys(), loc="upper center", bbox_to_anchor=(0.5, -0.12),
                      ncol=ncol)
        else:
            ax.legend(unique.values(), unique.keys(), loc="best", ncol=ncol)
    fig.tight_layout()
    fig.set_layout_engine(None)  # laid out once here; savefig then draws only once
    return fig


def _save(fig: Figure, path: Path) -> Path:
    with _styled():
        fig.savefig(path, dpi=STYLE["dpi"], format="png")
    fig.clear()
    logger.debug("wrote %s", path)
    return path


def _limit(ax: Axes, value: float, vertical: bool = False) -> None:
    """A red dotted limit line (horizontal at y = value, or vertical at x = value), labelled "limit"."""
    kw = {"color": STYLE["limit_color"], "linestyle": STYLE["limit_style"], "linewidth": STYLE["limit_width"],
          "label": LIMIT_LABEL, "gid": LIMIT_LABEL, "zorder": 1}
    (ax.axvline if vertical else ax.axhline)(value, **kw)


def _knot_lines(ax: Axes, trace: _Trace, label: bool) -> None:
    """Faint vertical lines at the times of the way (solid) and via (dotted) points."""
    for time, way in zip(trace.knots, trace.is_way, strict=True):
        ax.axvline(time, color=STYLE["knot_color"], alpha=STYLE["knot_alpha"], linewidth=0.7,
                   linestyle="-" if way else ":", gid="knot",
                   label=("way point" if way else "via point") if label else None, zorder=0)


def _point_markers(ax: Axes, x: np.ndarray, y: np.ndarray, is_way: np.ndarray, label: bool = True) -> None:
    """Way points as filled markers, via points as open ones, in the plan's colour."""
    color = STYLE["plan_color"]
    if np.any(is_way):
        ax.plot(x[is_way], y[is_way], linestyle="none", marker="o", color=color, gid="way",
                label="way point" if label else None, zorder=4)
    if np.any(~is_way):
        ax.plot(x[~is_way], y[~is_way], linestyle="none", marker="o", markerfacecolor="none",
                markeredgecolor=color, gid="via", label="via point" if label else None, zorder=4)


# ------------------------------------------------------------------------------------------ figures
def _path_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """Fig. 3.11 (FPR: end-effector and drone joint paths) or 3.36 (prototype: drone and elbow paths)."""
    from fpr.kinematics import prototype_joints

    traces = _traces(robot, plan, reference)
    length, margins = robot.link_length, robot.margins
    with _styled():
        fig, (ax,) = _new_figure(1, height=6.0, sharex=False)
        ax.axhline(-length, color=STYLE["ground_color"], linewidth=STYLE["line_width"],
                   label="ground z = -L", gid="ground", zorder=1)
        _limit(ax, -length + margins.ground)
        thin = STYLE["thin_width"]
        for tr in traces:
            if robot.name == "fpr":
                ax.plot(tr.s[:, 0], tr.s[:, 1], label=f"{tr.label}: end-effector", gid="main", **tr.line)
                for i in range(tr.joints.shape[1]):
                    kw = dict(tr.line, linewidth=thin)
                    if not tr.is_reference:
                        kw["color"] = STYLE["drone_colors"][i]
                    label = (f"{tr.label}: drone joints" if tr.is_reference
                             else f"r{i + 1} (drone {i + 1} joint)")
                    ax.plot(tr.joints[:, i, 0], tr.joints[:, i, 1], label=label, gid=f"r{i + 1}", **kw)
                markers = tr.point_positions[:, :2]
            else:
                elbow = prototype_joints(tr.s, length)[:, 0]
                ax.plot(tr.joints[:, 0, 0], tr.joints[:, 0, 1], label=f"{tr.label}: drone joint",
                        gid="main", **tr.line)
                kw = dict(tr.line, linewidth=thin)
                if not tr.is_reference:
                    kw["color"] = STYLE["drone_colors"][0]
                ax.plot(elbow[:, 0], elbow[:, 1], label=f"{tr.label}: elbow joint", gid="elbow", **kw)
                markers = prototype_joints(tr.point_positions, length)[:, 1]
            if not tr.is_reference:
                _point_markers(ax, markers[:, 0], markers[:, 1], tr.is_way)
        if robot.name == "prototype":
            ax.plot([0.0], [0.0], linestyle="none", marker="^", color="black", markersize=8,
                    label="fixed point", gid="fixed point", zorder=5)
            _limit(ax, margins.ground, vertical=True)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("y [m]")
        ax.set_ylabel("z [m]")
        return _finish(fig, _TITLES[robot.name]["path"], [ax], legend_below=True)


def _coordinate_axes(robot) -> list[tuple[str, tuple[float, float] | None]]:
    """(y label, (lower, upper) bounds or None) of each planning coordinate (seed 3.28-3.29, 3.44-3.46)."""
    m = robot.margins.angle
    if robot.name == "fpr":
        return [("y [m]", None), ("z [m]", None), (r"$\varphi$ [rad]", (np.pi + m, 2 * np.pi - m)),
                (r"$q_{21}$ [rad]", (m, np.pi - m))]
    return [(r"$q_1$ [rad]", (-(np.pi / 2 - m), np.pi / 2 - m)), (r"$q_2$ [rad]", (m, np.pi - m))]


def _coordinates_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """Fig. 3.12 (y, z, phi, q21) or 3.37 (q1, q2) against time, with their bounds."""
    traces = _traces(robot, plan, reference)
    specs = _coordinate_axes(robot)
    with _styled():
        fig, axes = _new_figure(len(specs))
        for j, (ax, (ylabel, bounds)) in enumerate(zip(axes, specs, strict=True)):
            _knot_lines(ax, traces[0], label=j == 0)
            for tr in traces:
                ax.plot(tr.t, tr.s[:, j], label=tr.label, **tr.line)
            first = traces[0]
            _point_markers(ax, first.knots, first.point_positions[:, j], first.is_way, label=False)
            if bounds is not None:
                for b in bounds:
                    _limit(ax, b)
            ax.set_ylabel(ylabel)
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _TITLES[robot.name]["coordinates"], axes)


def _index_figure(robot, plan: SampledPlan, reference: SampledPlan | None, which: str) -> Figure:
    traces = _traces(robot, plan, reference)
    if which == "energy":
        ylabel, unit, symbol = "$J_e$ [J]", "J", "$J_e$"
    else:
        ylabel, unit, symbol = r"$J_\varphi$ [rad$^2$/s]", r"rad$^2$/s", r"$J_\varphi$"
    with _styled():
        fig, (ax,) = _new_figure(1, height=3.2)
        _knot_lines(ax, traces[0], label=False)
        for tr in traces:
            curve = getattr(tr, which)
            label = f"{tr.label} ({symbol} = {curve[-1]:.4g} {unit})"
            ax.plot(tr.t, curve, label=label, gid=tr.label, **tr.line)
        ax.set_xlabel("t [s]")
        ax.set_ylabel(ylabel)
        return _finish(fig, _TITLES[robot.name][which], [ax])


def _energy_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """Fig. 3.13 / 3.38: cumulative J_e(t) = int sum_i |F_i . v_i| dt [J] (seed 3.24)."""
    return _index_figure(robot, plan, reference, "energy")


def _perturbation_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """Fig. 3.14 / 3.39: cumulative J_phi(t) = int sum_i phidot_i^2 dt [rad^2/s] (seed 3.25)."""
    return _index_figure(robot, plan, reference, "perturbation")


def _per_drone_figure(robot, traces: list[_Trace], which: str, ylabel: Callable[[int], str],
                      values: Callable[[_Trace, int], np.ndarray], limits: Sequence[float]) -> Figure:
    """One subplot per drone; for rotor speeds ``values`` returns (N, 4) and each rotor gets a colour."""
    _, n_d = _robot_sizes(robot)
    with _styled():
        fig, axes = _new_figure(n_d)
        for i, ax in enumerate(axes):
            _knot_lines(ax, traces[0], label=False)
            for tr in traces:
                v = values(tr, i)
                if v.ndim == 1:
                    ax.plot(tr.t, v, label=tr.label, **tr.line)
                    continue
                for k in range(v.shape[1]):
                    kw = dict(tr.line)
                    if tr.is_reference:
                        kw["linewidth"] = STYLE["thin_width"]
                    else:
                        kw["color"] = STYLE["rotor_colors"][k % len(STYLE["rotor_colors"])]
                    label = tr.label if tr.is_reference else f"rotor {k + 1}"
                    ax.plot(tr.t, v[:, k], label=label, **kw)
            for b in limits:
                _limit(ax, b)
            ax.set_ylabel(ylabel(i))
            if n_d > 1:
                ax.set_title(f"drone {i + 1}")
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _TITLES[robot.name][which], axes)


def _thrust_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """Fig. 3.15-3.16 / 3.40: thrust norm |F_i| of each drone [N]."""
    return _per_drone_figure(robot, _traces(robot, plan, reference), "thrust",
                             lambda i: f"$|F_{i + 1}|$ [N]", lambda tr, i: tr.thrust[:, i], ())


def _roll_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """Fig. 3.17-3.18 / 3.41: roll phi_i of each drone [rad], with |phi_i| <= pi/2 - m_ga (3.33, 3.45)."""
    bound = np.pi / 2 - robot.margins.angle
    return _per_drone_figure(robot, _traces(robot, plan, reference), "roll",
                             lambda i: rf"$\varphi_{i + 1}$ [rad]", lambda tr, i: tr.roll[:, i],
                             (-bound, bound))


def _rotor_speeds_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """Rotor speeds of each drone [rad/s] with 0 <= w_ij <= w_max - m_gr (seed 3.48)."""
    upper = robot.rotor_constants.max_speed - robot.margins.rotor_speed
    return _per_drone_figure(robot, _traces(robot, plan, reference), "rotor_speeds",
                             lambda i: rf"$\omega_{{{i + 1},j}}$ [rad/s]", lambda tr, i: tr.rotor_speed[:, i],
                             (0.0, upper))


_BUILDERS: dict[str, Callable[..., Figure]] = {
    "path": _path_figure,
    "coordinates": _coordinates_figure,
    "energy": _energy_figure,
    "perturbation": _perturbation_figure,
    "thrust": _thrust_figure,
    "roll": _roll_figure,
    "rotor_speeds": _rotor_speeds_figure,
}


def plan_figures(out_dir: str | Path, robot, plan: SampledPlan,
                 reference: SampledPlan | None = None) -> list[Path]:
    """Write the figures of one planned motion (seed Fig. 3.11-3.18 for the FPR, 3.36-3.41 for the prototype).

    Files, in ``out_dir`` (created if needed), in this order: ``path.png``, ``coordinates.png``,
    ``energy.png``, ``perturbation.png``, ``thrust.png``, ``roll.png``, ``rotor_speeds.png``
    (:data:`PLAN_FIGURES`). The plan is drawn solid, the reference (typically the trajectory that
    stops at every way point) dashed grey; the planning bounds are red dotted lines:

    * path: ground z = -L and the margin z = -L + m_gd (3.27; 3.44), for the prototype also the
      fixed point and y = m_gd (3.44);
    * coordinates: pi + m_ga <= phi <= 2 pi - m_ga, m_ga <= q21 <= pi - m_ga (3.28-3.29), or
      |q1| <= pi/2 - m_ga, m_ga <= q2 <= pi - m_ga (3.44, 3.46);
    * roll: |phi_i| <= pi/2 - m_ga (3.33, 3.45); rotor speeds: 0 <= w_ij <= w_max - m_gr (3.48).

    Args:
        out_dir: output folder.
        robot: the :class:`~fpr.robots.Robot` the plan is for (``robot.name`` "fpr" or "prototype").
        plan: the sampled plan to show (see the module docstring).
        reference: an optional sampled plan to compare with.

    Returns:
        The paths of the written PNG files.

    Raises:
        ValueError: the robot is unknown, or a plan misses an attribute or has a shape that does
            not fit the robot (ShapeError, a ValueError).
    """
    _traces(robot, plan, reference)  # fail before writing anything
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [_save(_BUILDERS[name](robot, plan, reference), out / f"{name}.png") for name in PLAN_FIGURES]


# ----------------------------------------------------------------------------------- parameter studies
def _png_path(path: str | Path) -> Path:
    p = Path(path)
    if p.suffix.lower() != ".png":
        raise ValueError(f"path={str(path)!r}: the figures are PNG files, give a name ending in '.png'")
    return p


def _save_to_file(fig: Figure, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    return _save(fig, path)


def _study_arrays(x_name: str, x, energy_ratio, perturbation_ratio) -> tuple[np.ndarray, ...]:
    arrays = [np.asarray(a, dtype=float) for a in (x, energy_ratio, perturbation_ratio)]
    names = (x_name, "energy_ratio", "perturbation_ratio")
    for name, a in zip(names, arrays, strict=True):
        if a.ndim != 1 or a.size == 0:
            raise ShapeError(name, a.shape, "(k,) with k >= 1: one value per case of the study")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} contains NaN or inf: give finite values")
    sizes = {name: a.size for name, a in zip(names, arrays, strict=True)}
    if len(set(sizes.values())) != 1:
        raise ValueError(f"mismatched lengths {sizes}: give one energy and one perturbation ratio per "
                         f"value of {x_name}")
    return tuple(arrays)


def _via_point_study(n_via: Sequence[int], energy_ratio, perturbation_ratio) -> Figure:
    counts, e, p = _study_arrays("n_via", n_via, energy_ratio, perturbation_ratio)
    if np.any(counts < 0) or np.any(counts != np.round(counts)):
        raise ValueError(f"n_via={list(n_via)!r}: numbers of via points are integers >= 0")
    if np.unique(counts).size != counts.size:
        raise ValueError(f"n_via={list(n_via)!r}: each number of via points may appear once")
    with _styled():
        fig, axes = _new_figure(1, 2, height=3.2, width=STYLE["width"] * 1.25, sharex=False)
        ylabels = (r"$J_e / J_{e0}$ [-]", r"$J_\varphi / J_{\varphi 0}$ [-]")
        for ax, ratio, ylabel in zip(axes, (e, p), ylabels, strict=True):
            ax.axhline(1.0, color=STYLE["reference_color"], linestyle=STYLE["reference_style"],
                       linewidth=STYLE["thin_width"], label="no via point (ratio 1)", zorder=1)
            bars = ax.bar(counts, ratio, width=0.6, color=STYLE["plan_color"], zorder=2)
            ax.bar_label(bars, fmt="%.3g", fontsize=STYLE["legend_size"])
            ax.set_xticks(counts)
            ax.set_xlabel(r"number of via points per segment $n_{vp}$ [-]")
            ax.set_ylabel(ylabel)
            ax.set_ylim(0.0, 1.15 * max(1.0, float(ratio.max())))
        return _finish(fig, "Fig. 3.7-3.8 — energy and perturbation against the number of via points", axes)


def via_point_study_figure(path: str | Path, n_via: Sequence[int], energy_ratio, perturbation_ratio) -> Path:
    """Write Fig. 3.7-3.8: J_e / J_e0 and J_phi / J_phi0 against the number of via points (bars).

    J_e0, J_phi0 are the indices without via points (seed 3.2.5); the ratios are dimensionless.

    Args:
        path: the PNG file to write (its folder is created if needed).
        n_via: numbers of via points per segment, distinct integers >= 0, shape (k,).
        energy_ratio: J_e / J_e0 of each case, shape (k,) [-].
        perturbation_ratio: J_phi / J_phi0 of each case, shape (k,) [-].

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        ValueError: mismatched lengths, empty or non-finite inputs, bad counts, a suffix other than .png.
    """
    target = _png_path(path)
    return _save_to_file(_via_point_study(n_via, energy_ratio, perturbation_ratio), target)


def _alpha_study(alphas, energy_ratio, perturbation_ratio) -> Figure:
    a, e, p = _study_arrays("alphas", alphas, energy_ratio, perturbation_ratio)
    if np.any((a < 0) | (a > 1)):
        raise ValueError(f"alphas={a.tolist()!r}: the weight alpha of seed 3.26 lies in [0, 1]")
    order = np.argsort(a, kind="stable")
    with _styled():
        fig, axes = _new_figure(1, 2, height=3.2, width=STYLE["width"] * 1.25, sharex=False)
        specs = ((e, r"$J_e / J_e|_{\alpha=0}$ [-]"), (p, r"$J_\varphi / J_\varphi|_{\alpha=1}$ [-]"))
        for ax, (ratio, ylabel) in zip(axes, specs, strict=True):
            ax.plot(a[order], ratio[order], marker="o", color=STYLE["plan_color"],
                    linewidth=STYLE["line_width"], label="optimised")
            ax.set_xlabel(r"weight $\alpha$ [-]")
            ax.set_ylabel(ylabel)
            ax.set_xlim(-0.05, 1.05)
        return _finish(fig, r"Fig. 3.9-3.10 — energy and perturbation against the weight $\alpha$", axes)


def alpha_study_figure(path: str | Path, alphas, energy_ratio, perturbation_ratio) -> Path:
    """Write Fig. 3.9-3.10: J_e / J_e|alpha=0 and J_phi / J_phi|alpha=1 against alpha (markers + lines).

    Args:
        path: the PNG file to write (its folder is created if needed).
        alphas: weights alpha of the objective (seed 3.26), each in [0, 1], shape (k,) [-].
        energy_ratio: J_e / J_e|alpha=0 of each case, shape (k,) [-].
        perturbation_ratio: J_phi / J_phi|alpha=1 of each case, shape (k,) [-].

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        ValueError: mismatched lengths, empty or non-finite inputs, alpha outside [0, 1], a suffix
            other than .png.
    """
    target = _png_path(path)
    return _save_to_file(_alpha_study(alphas, energy_ratio, perturbation_ratio), target)


# ------------------------------------------------------------------------------------ simulation
SIMULATION_FIGURES = ("sim_coordinates", "sim_out_of_plane", "sim_roll", "sim_heights", "sim_rotor_speeds")


def _sim_coordinates(log) -> Figure:
    """Planned vs simulated planning coordinates, and the tracking error (Fig 3.19, 3.21-3.22, 3.25-3.26, 3.43)."""
    units = {"y": "m", "z": "m", "phi": "rad", "q21": "rad", "q1": "rad", "q2": "rad"}
    fig, axes = _new_figure(2 * len(log.chain))
    err = log.tracking_error
    for i, name in enumerate(log.chain):
        ax, ax_err = axes[2 * i], axes[2 * i + 1]
        ax.plot(log.t, log.reference[0][:, i], color=STYLE["reference_color"], linestyle="--", label="planned")
        ax.plot(log.t, log.column(name), color=STYLE["plan_color"], label="simulated")
        ax.set_ylabel(f"{name} [{units[name]}]")
        ax_err.plot(log.t, err[:, i], color=STYLE["plan_color"], label="error")
        ax_err.set_ylabel(f"{name} error [{units[name]}]")
    axes[-1].set_xlabel("t [s]")
    return _finish(fig, "Fig. 3.19-3.26 / 3.43 — tracking of the planned motion", axes)


def _sim_out_of_plane(log) -> Figure:
    """x, psi, theta of the simulated robot (Fig 3.20, 3.23-3.24), which the plan keeps at zero."""
    names = [c for c in ("x", "psi", "theta") if c in log.coordinates]
    fig, axes = _new_figure(len(names))
    for ax, name in zip(axes, names):
        ax.plot(log.t, log.column(name), color=STYLE["plan_color"], label="simulated")
        ax.set_ylabel(f"{name} [{'m' if name == 'x' else 'rad'}]")
    axes[-1].set_xlabel("t [s]")
    return _finish(fig, "Fig. 3.20, 3.23-3.24 — motion out of the plane", axes)


def _sim_roll(log, robot) -> Figure:
    """Drone rolls: planned, desired by the outer loop, simulated (Fig 3.27-3.28)."""
    n_d = log.planned_roll.shape[1]
    fig, axes = _new_figure(n_d)
    bound = np.pi / 2 - robot.margins.angle
    for i, ax in enumerate(axes):
        ax.plot(log.t, log.planned_roll[:, i], color=STYLE["reference_color"], linestyle="--", label="planned")
        ax.plot(log.t, log.roll_desired[:, i], color="tab:orange", linewidth=0.8, label="desired (outer loop)")
        ax.plot(log.t, log.column(f"phi{i + 1}"), color=STYLE["plan_color"], label="simulated")
        ax.set_ylabel(f"phi{i + 1} [rad]")
        _limit(ax, bound)
        _limit(ax, -bound)
    axes[-1].set_xlabel("t [s]")
    return _finish(fig, "Fig. 3.27-3.28 — roll angle of each drone", axes)


def _sim_heights(log, robot) -> Figure:
    """Height of each drone's centre of mass in the plant, with the ground margin (Fig 3.29-3.30)."""
    n_d = log.drone_height.shape[1]
    fig, axes = _new_figure(n_d)
    for i, ax in enumerate(axes):
        ax.plot(log.t, log.drone_height[:, i], color=STYLE["plan_color"], label="simulated")
        ax.set_ylabel(f"z of drone {i + 1} [m]")
        _limit(ax, -robot.link_length + robot.margins.ground)
    axes[-1].set_xlabel("t [s]")
    return _finish(fig, "Fig. 3.29-3.30 — height of each drone", axes)


def _sim_rotor_speeds(log) -> Figure:
    """Rotor speeds in the plant against w_max and the planning limit (Fig 3.31-3.32, 3.48-3.49)."""
    n_d = log.speed.shape[1]
    fig, axes = _new_figure(n_d)
    for i, ax in enumerate(axes):
        for m in range(4):
            ax.plot(log.t, log.speed[:, i, m], linewidth=1.0, label=f"rotor {m + 1}")
        ax.set_ylabel(f"drone {i + 1} rotor speed [rad/s]")
        _limit(ax, log.max_speed)
        _limit(ax, 0.0)
        ax.axhline(log.speed_limit, color="grey", linestyle=":", linewidth=0.8, label="planning limit")
    axes[-1].set_xlabel("t [s]")
    return _finish(fig, "Fig. 3.31-3.32 — rotor speeds in the simulation", axes)


def simulation_figures(out_dir: str | Path, robot, log) -> list[Path]:
    """Write the thesis' simulation figures of a :class:`fpr.simulate.SimulationLog` as PNG files.

    Returns:
        the paths of ``sim_coordinates.png``, ``sim_out_of_plane.png`` (FPR and prototype: psi,
        theta; FPR also x), ``sim_roll.png``, ``sim_heights.png``, ``sim_rotor_speeds.png``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    builders = {"sim_coordinates": lambda: _sim_coordinates(log), "sim_out_of_plane": lambda: _sim_out_of_plane(log),
                "sim_roll": lambda: _sim_roll(log, robot), "sim_heights": lambda: _sim_heights(log, robot),
                "sim_rotor_speeds": lambda: _sim_rotor_speeds(log)}
    paths = []
    with _styled():
        for name in SIMULATION_FIGURES:
            paths.append(_save(builders[name](), out / f"{name}.png"))
    return paths
