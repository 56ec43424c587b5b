"""Figures of the thesis' planning and simulation chapters (seed 3.2.5-3.3.2), written as PNG files.

Entry points:

* :func:`figure_set` writes every figure that applies to a planned motion (a
  :class:`planners.optimize.PlanResult` or a sampled plan), optionally against the
  stop-at-every-way-point reference and with a closed-loop :class:`fpr.sim.closed_loop.SimulationLog`,
  for the FPR (Fig. 3.11-3.32) or the prototype (Fig. 3.36-3.51). It calls the next two.
* :func:`plan_figures` draws one planned motion (and optionally the reference it is compared
  with) in the figures of seed 3.11-3.18 (FPR) or 3.36-3.41 (prototype), plus the rotor speeds
  and rotor forces against the limits of eq. 3.48 (:data:`PLAN_FIGURES`).
* :func:`simulation_figures` draws a simulation log against its plan (seed 3.19-3.32, 3.42-3.51;
  :data:`SIMULATION_FIGURES`).
* :func:`via_point_study_figure` and :func:`alpha_study_figure` draw the parameter studies of
  seed 3.2.5 (Fig. 3.7-3.10).

Every ``_<name>_figure`` / ``_sim_<name>`` builder returns a :class:`matplotlib.figure.Figure`
without writing it, so that tests (and users) can inspect the axes.

A *sampled plan* is any object with the attributes

=========== ===================== =================================================================
``label``   str                   legend text, e.g. "optimised (two-step)"
``t``       (N,) [s]              sample times, non-decreasing
``motion``  (5, N, n_s)           s and its derivatives 0..4 (FPR s = [y z phi q21],
                                  prototype xi = [q1 q2])
``inputs``  MotionInputs          :class:`fpr.model.inverse_dynamics.MotionInputs` at the N samples
``knots``   (m+1,) [s]            times of all points of the piecewise polynomial
``is_way``  (m+1,) bool           True for a way point, False for a via point
``points``  (m+1, 5, n_s)         the points; ``points[:, 0]`` are positions in planning coordinates
=========== ===================== =================================================================

One style everywhere (:data:`STYLE`): the plan is drawn solid in one colour, the reference dashed
grey, limits as red dotted lines labelled "limit", way points as filled markers and via points as
open ones. In the simulation figures the simulated motion is solid and the plan dashed grey.
Every axis label carries its unit.

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

from fpr.model.errors import ShapeError

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from fpr.model.inverse_dynamics import MotionInputs

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
PLAN_FIGURES = ("path", "coordinates", "energy", "perturbation", "thrust", "roll", "rotor_speeds",
                "rotor_forces")

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
            hint = "pass the MotionInputs of fpr.model.inverse_dynamics.inverse_dynamics(robot, motion)"
        elif owner == "log":
            hint = "pass the SimulationLog of fpr.sim.closed_loop.simulate"
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
                         "fpr.model.inverse_dynamics.inverse_dynamics(robot, motion)")
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
def _path_axes(robot) -> tuple[Figure, Axes]:
    """A task-space (y, z) figure with the ground z = -L and its margin z = -L + m_gd (3.27, 3.44).

    For the prototype also the fixed point and the margin y = m_gd (3.44). Call inside ``_styled()``.
    """
    length, margins = robot.link_length, robot.margins
    fig, (ax,) = _new_figure(1, height=6.0, sharex=False)
    ax.axhline(-length, color=STYLE["ground_color"], linewidth=STYLE["line_width"],
               label="ground z = -L", gid="ground", zorder=1)
    _limit(ax, -length + margins.ground)
    if robot.name == "prototype":
        ax.plot([0.0], [0.0], linestyle="none", marker="^", color="black", markersize=8,
                label="fixed point", gid="fixed point", zorder=5)
        _limit(ax, margins.ground, vertical=True)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("y [m]")
    ax.set_ylabel("z [m]")
    return fig, ax


def _task_space_joints(robot, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(main point, other joints) in the task space along s, shape (N, 2) and (N, k, 2) [m].

    FPR: the end-effector p and the drone joints r1, r2 (2.1); prototype: the drone joint (joint 3)
    and the elbow (joint 2) (3.35).
    """
    from fpr.model.kinematics import fpr_drone_joints, prototype_joints

    if robot.name == "fpr":
        return s[:, :2], fpr_drone_joints(s, robot.link_length)
    joints = prototype_joints(s, robot.link_length)
    return joints[:, 1], joints[:, :1]


def _path_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """Fig. 3.11 (FPR: end-effector and drone joint paths) or 3.36 (prototype: drone and elbow paths)."""
    traces = _traces(robot, plan, reference)
    thin = STYLE["thin_width"]
    with _styled():
        fig, ax = _path_axes(robot)
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
            else:
                elbow = _task_space_joints(robot, tr.s)[1][:, 0]
                ax.plot(tr.joints[:, 0, 0], tr.joints[:, 0, 1], label=f"{tr.label}: drone joint",
                        gid="main", **tr.line)
                kw = dict(tr.line, linewidth=thin)
                if not tr.is_reference:
                    kw["color"] = STYLE["drone_colors"][0]
                ax.plot(elbow[:, 0], elbow[:, 1], label=f"{tr.label}: elbow joint", gid="elbow", **kw)
            if not tr.is_reference:
                markers = _task_space_joints(robot, tr.point_positions)[0]
                _point_markers(ax, markers[:, 0], markers[:, 1], tr.is_way)
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


def _rotor_forces_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """Rotor forces f_ij = c_T w_ij^2 of each drone [N], 0 <= f_ij <= c_T (w_max - m_gr)^2 (3.48 as forces).

    A negative force is a negative w^2 (R_f^-1 asks for an impossible rotor speed, 3.31).
    """
    c_t = robot.rotor_constants.thrust_coefficient
    upper = c_t * (robot.rotor_constants.max_speed - robot.margins.rotor_speed) ** 2
    return _per_drone_figure(robot, _traces(robot, plan, reference), "rotor_forces",
                             lambda i: rf"$c_T \omega_{{{i + 1},j}}^2$ [N]",
                             lambda tr, i: c_t * tr.rotor_speed[:, i] * np.abs(tr.rotor_speed[:, i]),
                             (0.0, upper))


_BUILDERS: dict[str, Callable[..., Figure]] = {
    "path": _path_figure,
    "coordinates": _coordinates_figure,
    "energy": _energy_figure,
    "perturbation": _perturbation_figure,
    "thrust": _thrust_figure,
    "roll": _roll_figure,
    "rotor_speeds": _rotor_speeds_figure,
    "rotor_forces": _rotor_forces_figure,
}


def plan_figures(out_dir: str | Path, robot, plan: SampledPlan,
                 reference: SampledPlan | None = None) -> list[Path]:
    """Write the figures of one planned motion (seed Fig. 3.11-3.18 for the FPR, 3.36-3.41 for the prototype).

    Files, in ``out_dir`` (created if needed), in this order: ``path.png``, ``coordinates.png``,
    ``energy.png``, ``perturbation.png``, ``thrust.png``, ``roll.png``, ``rotor_speeds.png``,
    ``rotor_forces.png`` (:data:`PLAN_FIGURES`). The plan is drawn solid, the reference (typically the
    trajectory that stops at every way point) dashed grey; the planning bounds are red dotted lines:

    * path: ground z = -L and the margin z = -L + m_gd (3.27; 3.44), for the prototype also the
      fixed point and y = m_gd (3.44);
    * coordinates: pi + m_ga <= phi <= 2 pi - m_ga, m_ga <= q21 <= pi - m_ga (3.28-3.29), or
      |q1| <= pi/2 - m_ga, m_ga <= q2 <= pi - m_ga (3.44, 3.46);
    * roll: |phi_i| <= pi/2 - m_ga (3.33, 3.45); rotor speeds: 0 <= w_ij <= w_max - m_gr (3.48);
      rotor forces: 0 <= c_T w_ij^2 <= c_T (w_max - m_gr)^2.

    Args:
        out_dir: output folder.
        robot: the :class:`~fpr.model.robot.Robot` the plan is for (``robot.name`` "fpr" or "prototype").
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


def _crossing_comparison(robot, outcomes: Sequence, rate: float) -> Figure:
    from fpr.model.inverse_dynamics import MOTION_ORDER, inverse_dynamics

    if not outcomes:
        raise ValueError("outcomes is empty: give at least one planners.crossing.CrossingOutcome")
    colors = [STYLE["plan_color"], "tab:orange", "tab:green", "tab:purple"]
    limit = robot.rotor_constants.max_speed - robot.margins.rotor_speed
    max_thrust = 4 * robot.rotor_constants.thrust_coefficient * limit**2
    with _styled():
        fig, axes = _new_figure(3, 1, height=7.5, sharex=False)
        for k, out in enumerate(outcomes):
            trajectory = out.trajectory
            t = trajectory.sample_times(rate)
            m = trajectory.evaluate(t, order=MOTION_ORDER)
            inputs = inverse_dynamics(robot, m)
            tau = t - out.crossing_time  # time from the crossing
            color = colors[k % len(colors)]
            label = out.name + ("" if out.feasible else " (limits violated)")
            axes[0].plot(tau, m[0][:, 1], color=color, label=label)
            axes[1].plot(tau, inputs.thrust[:, 0], color=color, label=label)
            w = inputs.rotor_speed[:, 0]
            axes[2].plot(tau, w.max(axis=-1), color=color, label=label)
            axes[2].plot(tau, w.min(axis=-1), color=color, linestyle="--", linewidth=STYLE["thin_width"])
        axes[0].axhline(0.0, color=STYLE["reference_color"], linewidth=STYLE["thin_width"], zorder=1)
        axes[0].set_ylabel(r"$q_2$ [rad]")
        _limit(axes[1], max_thrust)
        axes[1].set_ylabel(r"thrust $|F|$ [N]")
        _limit(axes[2], limit)
        _limit(axes[2], 0.0)
        axes[2].set_ylabel(r"rotor speeds, max / min [rad/s]")
        for ax in axes[1:]:
            low, high = ax.get_ylim()  # the seed's approaches reach 1e3..1e6: keep the limits readable
            span = 4 * (limit if ax is axes[2] else max_thrust)
            ax.set_ylim(0.0 if ax is axes[1] else max(low, -span), min(high, span))
        for ax in axes:
            ax.axvline(0.0, color=STYLE["reference_color"], linestyle=STYLE["reference_style"],
                       linewidth=STYLE["thin_width"], zorder=1)
            ax.set_xlabel("time from the crossing [s]")
        return _finish(fig, "Fig. 4.2-4.9 — crossing the prototype's Type-2 singularity", axes[:2])


def crossing_comparison_figure(path: str | Path, robot, outcomes: Sequence, rate: float = 500.0) -> Path:
    """Write the crossing approaches side by side (seed Fig. 4.2-4.9): q2, the thrust and the extreme
    rotor speeds against time from the crossing, with the thrust limit 4 c_T (w_max - m_gr)^2 and the
    rotor limits [0, w_max - m_gr] (the vertical axes are clipped at 4x the limit).

    Args:
        path: the PNG file to write.
        robot: the prototype.
        outcomes: :class:`planners.crossing.CrossingOutcome` s (the seed's approaches, ours).
        rate: sampling rate [Hz].

    Returns:
        ``path`` as a :class:`~pathlib.Path`.
    """
    target = _png_path(path)
    return _save_to_file(_crossing_comparison(robot, outcomes, rate), target)


# ------------------------------------------------------------------------------------ simulation
#: File names written by :func:`simulation_figures`, in order (without the ".png" suffix).
SIMULATION_FIGURES = ("sim_path", "sim_coordinates", "sim_out_of_plane", "sim_roll", "sim_heights",
                      "sim_rotor_speeds", "sim_rotor_forces", "sim_energy")

#: File names written by :func:`figure_set` with a simulation log, in order.
FIGURE_SET = PLAN_FIGURES + SIMULATION_FIGURES

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

# thesis order of the out-of-plane coordinates (Fig. 3.20, 3.23, 3.24) and their axis labels
_OUT_OF_PLANE = (("x", "x [m]"), ("theta", r"$\theta$ [rad]"), ("psi", r"$\psi$ [rad]"))


@dataclass(frozen=True)
class _Simulated:
    """A validated simulation log, in the arrays the figures draw (N inner-loop ticks)."""

    t: np.ndarray  # (N,) [s]
    planned: np.ndarray  # (N, n_s) planned planning coordinates
    simulated: np.ndarray  # (N, n_s) measured planning coordinates
    simulated_rate: np.ndarray  # (N, n_s) their rates
    planned_roll: np.ndarray  # (N, n_d) [rad]
    desired_roll: np.ndarray  # (N, n_d) [rad], outer loop
    roll: np.ndarray  # (N, n_d) [rad], plant
    roll_rate: np.ndarray  # (N, n_d) [rad/s], plant
    thrust: np.ndarray  # (N, n_d) [N], allocated
    speed: np.ndarray  # (N, n_d, 4) [rad/s], plant rotors
    drone_height: np.ndarray  # (N, n_d) [m], drone centres of mass
    out_of_plane: dict  # name -> (N,) [m or rad]
    max_speed: float  # w_max [rad/s]


def _simulated(robot, log) -> _Simulated:
    """Check ``log`` (a :class:`fpr.sim.closed_loop.SimulationLog`) against ``robot`` and pick its arrays."""
    n_s, n_d = _robot_sizes(robot)
    name = getattr(log, "robot_name", None)
    if name is None or not hasattr(log, "coordinates"):
        raise ValueError("log has no attribute 'robot_name' or 'coordinates': pass the SimulationLog of "
                         "fpr.sim.closed_loop.simulate")
    if name != robot.name:
        raise ValueError(f"log.robot_name={name!r} but robot.name={robot.name!r}: draw a log with the robot "
                         "it simulated")
    coordinates = tuple(log.coordinates)
    missing = [c for c in (*robot.layout.chain, *robot.layout.rolls) if c not in coordinates]
    if missing:
        raise ValueError(f"log.coordinates={coordinates!r} lacks {missing!r}: pass a log of this robot")
    t = _field("log", log, "t", (None,), "tick times [s]")
    n = t.shape[0]
    if n < 2:
        raise ValueError(f"log.t has {n} sample(s): the figures need at least 2")
    q = _field("log", log, "q", (n, len(coordinates)), "plant state in thesis coordinates")
    v = _field("log", log, "v", (n, len(coordinates)), "plant velocities in thesis coordinates")
    chain = [coordinates.index(c) for c in robot.layout.chain]
    rolls = [coordinates.index(c) for c in robot.layout.rolls]
    return _Simulated(
        t=t,
        planned=_field("log", log, "reference", (None, n, n_s), "planned s, s', s''")[0],
        simulated=q[:, chain],
        simulated_rate=v[:, chain],
        planned_roll=_field("log", log, "planned_roll", (n, n_d), "planned rolls [rad]"),
        desired_roll=_field("log", log, "roll_desired", (n, n_d), "desired rolls [rad]"),
        roll=q[:, rolls],
        roll_rate=v[:, rolls],
        thrust=_field("log", log, "thrust", (n, n_d), "allocated thrusts [N]"),
        speed=_field("log", log, "speed", (n, n_d, 4), "plant rotor speeds [rad/s]"),
        drone_height=_field("log", log, "drone_height", (n, n_d), "drone heights [m]"),
        out_of_plane={c: q[:, coordinates.index(c)] for c, _ in _OUT_OF_PLANE if c in coordinates},
        max_speed=float(log.max_speed),
    )


def _planned_line(width: float | None = None) -> dict[str, Any]:
    """Keyword arguments of ``Axes.plot`` for the plan in a simulation figure (dashed grey)."""
    return {"color": STYLE["reference_color"], "linestyle": STYLE["reference_style"],
            "linewidth": width or STYLE["line_width"], "zorder": 2}


def _simulated_line(width: float | None = None) -> dict[str, Any]:
    """Keyword arguments of ``Axes.plot`` for the simulated motion (solid, the plan colour)."""
    return {"color": STYLE["plan_color"], "linestyle": "-", "linewidth": width or STYLE["line_width"],
            "zorder": 3}


def _sim_path(robot, log, plan: SampledPlan | None = None) -> Figure:
    """Fig. 3.19 / 3.42: the task-space path, planned and simulated, with the way / via points of ``plan``."""
    sim = _simulated(robot, log)
    thin = STYLE["thin_width"]
    what, other = ("end-effector", "drone joints") if robot.name == "fpr" else ("drone joint", "elbow joint")
    with _styled():
        fig, ax = _path_axes(robot)
        planned_main, planned_joints = _task_space_joints(robot, sim.planned)
        main, joints = _task_space_joints(robot, sim.simulated)
        ax.plot(*planned_main.T, label=f"planned: {what}", gid="planned", **_planned_line())
        ax.plot(*main.T, label=f"simulated: {what}", gid="simulated", **_simulated_line())
        for k in range(joints.shape[1]):
            ax.plot(*planned_joints[:, k].T, label=f"planned: {other}", gid=f"planned joint {k + 1}",
                    **_planned_line(thin))
            label = (f"simulated: r{k + 1} (drone {k + 1} joint)" if robot.name == "fpr"
                     else f"simulated: {other}")
            ax.plot(*joints[:, k].T, label=label, gid=f"simulated joint {k + 1}",
                    **dict(_simulated_line(thin), color=STYLE["drone_colors"][k]))
        if plan is not None:
            tr = _trace(robot, plan, "plan", False)
            markers = _task_space_joints(robot, tr.point_positions)[0]
            _point_markers(ax, markers[:, 0], markers[:, 1], tr.is_way)
        return _finish(fig, _SIM_TITLES[robot.name]["sim_path"], [ax], legend_below=True)


def _sim_coordinates(robot, log, plan: SampledPlan | None = None) -> Figure:
    """Planned vs simulated planning coordinates with their bounds (left) and the error (right).

    Fig. 3.21-3.22, 3.25-3.26 (FPR y, z, phi, q21), 3.43-3.45 (prototype q1, q2 and their errors).
    """
    sim = _simulated(robot, log)
    specs = _coordinate_axes(robot)
    with _styled():
        fig, axes = _new_figure(len(specs), 2, width=STYLE["width"] * 1.5)
        for j, (ylabel, bounds) in enumerate(specs):
            ax, ax_err = axes[2 * j], axes[2 * j + 1]
            ax.plot(sim.t, sim.planned[:, j], label="planned" if j == 0 else None, gid="planned",
                    **_planned_line())
            ax.plot(sim.t, sim.simulated[:, j], label="simulated" if j == 0 else None, gid="simulated",
                    **_simulated_line())
            for b in bounds or ():
                _limit(ax, b)
            ax.set_ylabel(ylabel)
            symbol, unit = ylabel.rsplit(" [", 1)
            ax_err.plot(sim.t, sim.simulated[:, j] - sim.planned[:, j], gid="error", **_simulated_line())
            ax_err.set_ylabel(f"{symbol} error [{unit}")
        for ax in axes[-2:]:
            ax.set_xlabel("t [s]")
        return _finish(fig, _SIM_TITLES[robot.name]["sim_coordinates"], axes)


def _sim_out_of_plane(robot, log, plan: SampledPlan | None = None) -> Figure:
    """Out of the plane: x (FPR), pitch theta, yaw psi of the simulated robot (Fig. 3.20, 3.23-3.24).

    The plan keeps them at 0.
    """
    sim = _simulated(robot, log)
    specs = [(c, label) for c, label in _OUT_OF_PLANE if c in sim.out_of_plane]
    with _styled():
        fig, axes = _new_figure(len(specs))
        for ax, (name, ylabel) in zip(axes, specs, strict=True):
            ax.axhline(0.0, label="planned", gid="planned", **_planned_line())
            ax.plot(sim.t, sim.out_of_plane[name], label="simulated", gid="simulated", **_simulated_line())
            ax.set_ylabel(ylabel)
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _SIM_TITLES[robot.name]["sim_out_of_plane"], axes)


def _sim_roll(robot, log, plan: SampledPlan | None = None) -> Figure:
    """Drone rolls planned, desired by the outer loop and simulated (Fig. 3.27-3.28, 3.48).

    Limits: |phi_i| <= pi/2 - m_ga (3.33, 3.45).
    """
    sim = _simulated(robot, log)
    bound = np.pi / 2 - robot.margins.angle
    n_d = sim.roll.shape[1]
    with _styled():
        fig, axes = _new_figure(n_d)
        for i, ax in enumerate(axes):
            ax.plot(sim.t, sim.planned_roll[:, i], label="planned", gid="planned", **_planned_line())
            ax.plot(sim.t, sim.desired_roll[:, i], color="tab:orange", linewidth=STYLE["thin_width"],
                    label="desired (outer loop)", gid="desired", zorder=2)
            ax.plot(sim.t, sim.roll[:, i], label="simulated", gid="simulated", **_simulated_line())
            _limit(ax, -bound)
            _limit(ax, bound)
            ax.set_ylabel(rf"$\varphi_{i + 1}$ [rad]")
            if n_d > 1:
                ax.set_title(f"drone {i + 1}")
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _SIM_TITLES[robot.name]["sim_roll"], axes)


def _sim_heights(robot, log, plan: SampledPlan | None = None) -> Figure:
    """Heights planned and simulated, with z >= -L + m_gd (3.27, 3.44).

    FPR (Fig. 3.29-3.30): the drone joints r_i and the drones' centres of mass. Prototype
    (Fig. 3.46-3.47): joint 2 (elbow) and joint 3 (drone joint), and the drone's centre of mass.
    """
    sim = _simulated(robot, log)
    planned_main, planned_joints = _task_space_joints(robot, sim.planned)
    main, joints = _task_space_joints(robot, sim.simulated)
    if robot.name == "fpr":
        panels = [(rf"$z_{i + 1}$ [m]", f"drone {i + 1} joint", planned_joints[:, i, 1], joints[:, i, 1], i)
                  for i in range(joints.shape[1])]
    else:
        panels = [(r"$z_{j2}$ [m]", "joint 2", planned_joints[:, 0, 1], joints[:, 0, 1], None),
                  (r"$z_{j3}$ [m]", "joint 3 (drone joint)", planned_main[:, 1], main[:, 1], 0)]
    ground = -robot.link_length + robot.margins.ground
    with _styled():
        fig, axes = _new_figure(len(panels))
        for ax, (ylabel, what, planned, simulated, drone) in zip(axes, panels, strict=True):
            ax.plot(sim.t, planned, label=f"planned: {what}", gid="planned", **_planned_line())
            ax.plot(sim.t, simulated, label=f"simulated: {what}", gid="simulated", **_simulated_line())
            if drone is not None:
                ax.plot(sim.t, sim.drone_height[:, drone], label="simulated: drone centre of mass", gid="com",
                        **dict(_simulated_line(STYLE["thin_width"]), color=STYLE["drone_colors"][drone]))
            _limit(ax, ground)
            ax.set_ylabel(ylabel)
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _SIM_TITLES[robot.name]["sim_heights"], axes)


def _sim_rotors(robot, log, plan: SampledPlan | None, which: str) -> Figure:
    """Rotor speeds [rad/s] or forces c_T w^2 [N] in the plant, one colour per rotor, the plan's dashed grey.

    Limits (3.48): 0 and w_max - m_gr (speeds) or c_T (w_max - m_gr)^2 (forces), red dotted; the
    rotors' saturation w_max (or c_T w_max^2) is a thin grey line.
    """
    sim = _simulated(robot, log)
    c_t = robot.rotor_constants.thrust_coefficient
    upper = robot.rotor_constants.max_speed - robot.margins.rotor_speed
    if which == "sim_rotor_forces":
        def value(w):
            return c_t * w * np.abs(w)

        def ylabel(i):
            return rf"$c_T \omega_{{{i + 1},j}}^2$ [N]"
        saturation_label = r"saturation $c_T \omega_{max}^2$"
    else:
        def value(w):
            return w

        def ylabel(i):
            return rf"$\omega_{{{i + 1},j}}$ [rad/s]"
        saturation_label = r"saturation $\omega_{max}$"
    trace = None if plan is None else _trace(robot, plan, "plan", True)
    n_d = sim.speed.shape[1]
    with _styled():
        fig, axes = _new_figure(n_d)
        for i, ax in enumerate(axes):
            if trace is not None:
                for k in range(4):
                    ax.plot(trace.t, value(trace.rotor_speed[:, i, k]), label="planned", gid="planned",
                            **_planned_line(STYLE["thin_width"]))
            for k in range(4):
                ax.plot(sim.t, value(sim.speed[:, i, k]), label=f"rotor {k + 1}", gid="simulated",
                        color=STYLE["rotor_colors"][k], linewidth=STYLE["thin_width"] * 1.25, zorder=3)
            _limit(ax, 0.0)
            _limit(ax, float(value(upper)))
            ax.axhline(float(value(sim.max_speed)), color=STYLE["reference_color"], linestyle="-",
                       linewidth=STYLE["thin_width"], label=saturation_label, gid="saturation", zorder=1)
            ax.set_ylabel(ylabel(i))
            if n_d > 1:
                ax.set_title(f"drone {i + 1}")
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _SIM_TITLES[robot.name][which], axes)


def _sim_rotor_speeds(robot, log, plan: SampledPlan | None = None) -> Figure:
    """Rotor speeds in the plant with 0 <= w <= w_max - m_gr (3.48) and the saturation w_max."""
    return _sim_rotors(robot, log, plan, "sim_rotor_speeds")


def _sim_rotor_forces(robot, log, plan: SampledPlan | None = None) -> Figure:
    """Rotor forces c_T w^2 in the plant [N] (Fig. 3.31-3.32, 3.49), with 0 and c_T (w_max - m_gr)^2.

    c_T is the robot's nominal constant (a simulation with ``rotor_constant_scale`` != 1 has rotors
    that really produce that factor times these forces).
    """
    return _sim_rotors(robot, log, plan, "sim_rotor_forces")


def simulated_indices(robot, log) -> tuple[np.ndarray, np.ndarray]:
    r"""J_e(t) and J_phi(t) of a simulation (seed 3.24-3.25, Fig. 3.50-3.51), shape (N,) each [J, rad^2/s].

    .. math:: J_e(t) = \int_0^t \sum_i |F_i \cdot \dot r_i| \, dt, \quad
              J_\varphi(t) = \int_0^t \sum_i \dot\varphi_i^2 \, dt

    with the allocated thrust along the plant drone's thrust axis, F_i = f_i (-sin phi_i, cos phi_i),
    the drone joint velocities r_i' of the measured chain motion and the plant's roll rates.

    Args:
        robot: the robot the log simulated.
        log: a :class:`fpr.sim.closed_loop.SimulationLog`.
    """
    from fpr.model.kinematics import fpr_drone_joint_velocities, prototype_jacobian

    sim = _simulated(robot, log)
    if robot.name == "fpr":
        velocity = fpr_drone_joint_velocities(sim.simulated, sim.simulated_rate, robot.link_length)
    else:
        jac = prototype_jacobian(sim.simulated, robot.link_length)
        velocity = np.einsum("nij,nj->ni", jac, sim.simulated_rate)[:, None]
    force = sim.thrust[..., None] * np.stack([-np.sin(sim.roll), np.cos(sim.roll)], axis=-1)
    power = np.abs(np.sum(force * velocity, axis=-1)).sum(axis=1)
    return cumulative_integral(sim.t, power), cumulative_integral(sim.t, np.sum(sim.roll_rate**2, axis=1))


def _sim_energy(robot, log, plan: SampledPlan | None = None) -> Figure:
    """J_e(t), J_phi(t) simulated (:func:`simulated_indices`) and, with ``plan``, planned (Fig. 3.50-3.51)."""
    sim = _simulated(robot, log)
    energy, perturbation = simulated_indices(robot, log)
    trace = None if plan is None else _trace(robot, plan, "plan", True)
    specs = (("$J_e$ [J]", "$J_e$", "J", energy, "energy"),
             (r"$J_\varphi$ [rad$^2$/s]", r"$J_\varphi$", r"rad$^2$/s", perturbation, "perturbation"))
    with _styled():
        fig, axes = _new_figure(2)
        for ax, (ylabel, symbol, unit, simulated, which) in zip(axes, specs, strict=True):
            if trace is not None:
                planned = getattr(trace, which)
                ax.plot(trace.t, planned, label=f"planned ({symbol} = {planned[-1]:.4g} {unit})",
                        gid="planned", **_planned_line())
            ax.plot(sim.t, simulated, label=f"simulated ({symbol} = {simulated[-1]:.4g} {unit})",
                    gid="simulated", **_simulated_line())
            ax.set_ylabel(ylabel)
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _SIM_TITLES[robot.name]["sim_energy"], axes)


_SIM_BUILDERS: dict[str, Callable[..., Figure]] = {
    "sim_path": _sim_path,
    "sim_coordinates": _sim_coordinates,
    "sim_out_of_plane": _sim_out_of_plane,
    "sim_roll": _sim_roll,
    "sim_heights": _sim_heights,
    "sim_rotor_speeds": _sim_rotor_speeds,
    "sim_rotor_forces": _sim_rotor_forces,
    "sim_energy": _sim_energy,
}


def simulation_figures(out_dir: str | Path, robot, log, plan: SampledPlan | None = None) -> list[Path]:
    """Write the thesis' simulation figures of a :class:`fpr.sim.closed_loop.SimulationLog` as PNG files.

    Files, in ``out_dir`` (created if needed), in the order of :data:`SIMULATION_FIGURES`:

    * ``sim_path.png``: task-space path, planned and simulated (Fig. 3.19 / 3.42);
    * ``sim_coordinates.png``: planning coordinates with their bounds, and the tracking errors
      (Fig. 3.21-3.22, 3.25-3.26 / 3.43-3.45);
    * ``sim_out_of_plane.png``: x (FPR), pitch, yaw (Fig. 3.20, 3.23-3.24);
    * ``sim_roll.png``: rolls planned, desired, simulated, |phi_i| <= pi/2 - m_ga (Fig. 3.27-3.28 / 3.48);
    * ``sim_heights.png``: drone joint / joint 2 and 3 heights and the drones' centres of mass, with
      z >= -L + m_gd (Fig. 3.29-3.30 / 3.46-3.47);
    * ``sim_rotor_speeds.png`` and ``sim_rotor_forces.png``: the plant's rotors against 0 and
      w_max - m_gr, resp. c_T (w_max - m_gr)^2, and the saturation (eq. 3.48, Fig. 3.31-3.32 / 3.49);
    * ``sim_energy.png``: J_e(t), J_phi(t) simulated (Fig. 3.50-3.51).

    Args:
        out_dir: output folder.
        robot: the :class:`~fpr.model.robot.Robot` that was simulated.
        log: the :class:`fpr.sim.closed_loop.SimulationLog`.
        plan: the sampled plan that was tracked (optional): adds its rotor speeds, rotor forces,
            J_e(t), J_phi(t) and way/via points to the figures.

    Returns:
        The paths of the written PNG files.

    Raises:
        ValueError: the log is of another robot or has arrays of the wrong shape, or the plan is
            not a sampled plan of the robot (nothing is written then).
    """
    _simulated(robot, log)  # fail before writing anything
    if plan is not None:
        _trace(robot, plan, "plan", False)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [_save(_SIM_BUILDERS[name](robot, log, plan), out / f"{name}.png") for name in SIMULATION_FIGURES]


# ------------------------------------------------------------------------------------ the whole set
def _as_sampled(what: str, plan, robot, rate: float) -> SampledPlan:
    """A :class:`planners.optimize.PlanResult` sampled at ``rate``, or a sampled plan as it is."""
    if hasattr(plan, "trajectory") and callable(getattr(plan, "sampled", None)):
        return plan.sampled(rate, robot=robot)
    if hasattr(plan, "motion"):
        return plan
    raise ValueError(f"{what} is a {type(plan).__name__}: pass a planners.optimize.PlanResult or a sampled "
                     "plan (PlanResult.sampled(rate))")


def figure_set(out_dir: str | Path, plan, log=None, reference=None, *, robot=None,
               rate: float = 200.0) -> dict[str, Path]:
    """Write every figure of the thesis that applies to a planned (and possibly simulated) motion.

    FPR: Fig. 3.11-3.18 and the rotor limits of eq. 3.48 (:data:`PLAN_FIGURES`), and with ``log``
    Fig. 3.19-3.32 (:data:`SIMULATION_FIGURES`). Prototype: Fig. 3.36-3.41, and with ``log``
    Fig. 3.42-3.51. Calls :func:`plan_figures`, then :func:`simulation_figures` with the plan.

    Example::

        result = plan(load_mission("square"), "two-step")
        paths = figure_set("out", result, simulate(result), reference=plan(load_mission("square"), "none"))
        paths["sim_rotor_forces"]  # Path("out/sim_rotor_forces.png")

    Args:
        out_dir: output folder (created if needed).
        plan: a :class:`planners.optimize.PlanResult` (sampled at ``rate``) or a sampled plan.
        log: a :class:`fpr.sim.closed_loop.SimulationLog` of ``plan``, or None for the planning figures only.
        reference: the motion to compare with, typically ``plan(mission, "none")`` (stop at every
            way point): a PlanResult or a sampled plan, or None.
        robot: the robot; default ``plan.robot`` (required for a sampled plan).
        rate: sampling rate of PlanResults [Hz].

    Returns:
        name -> path of every written PNG file, in the order of :data:`FIGURE_SET` (the ``sim_``
        ones only with a log).

    Raises:
        ValueError: no robot, a rate that is not positive, or inputs that do not fit the robot
            (nothing is written then).
    """
    robot = robot if robot is not None else getattr(plan, "robot", None)
    if robot is None:
        raise ValueError("no robot: pass robot=fpr.load(...) with a sampled plan (a PlanResult carries "
                         "its own)")
    if not (np.isfinite(rate) and rate > 0):
        raise ValueError(f"rate={rate!r}: give a positive sampling rate [Hz]")
    sampled = _as_sampled("plan", plan, robot, rate)
    sampled_reference = None if reference is None else _as_sampled("reference", reference, robot, rate)
    _traces(robot, sampled, sampled_reference)  # check everything before writing anything
    if log is not None:
        _simulated(robot, log)
    paths = dict(zip(PLAN_FIGURES, plan_figures(out_dir, robot, sampled, sampled_reference), strict=True))
    if log is not None:
        paths.update(zip(SIMULATION_FIGURES, simulation_figures(out_dir, robot, log, sampled), strict=True))
    return paths
