"""Figures of one planned motion against the limits: seed Fig. 3.11-3.18 (FPR) and 3.36-3.41 (prototype),
plus the rotor speeds and rotor forces against the limits of eq. 3.48 (:func:`plan_figures`).

The plan is drawn solid in the plan colour, the reference (typically the trajectory that stops at every
way point) dashed grey. Every ``_<name>_figure`` builder returns a :class:`matplotlib.figure.Figure`
without writing it, so that tests (and users) can inspect the axes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fpr.views.figures.robot_info import (
    _applicable_bounds,
    _context,
    _coordinate_axes,
    _robot_sizes,
    _task_space_joints,
    _title,
    figure_context,
)
from fpr.views.figures.sampled import _Trace, _traces
from fpr.views.figures.style import ROTOR_STYLES, STYLE, _finish, _limit, _new_figure, _point_markers, _save, _styled
from planners.optimize import SampledPlan

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: File names written by :func:`plan_figures`, in order (without the ".png" suffix).
PLAN_FIGURES = ("path", "coordinates", "energy", "perturbation", "thrust", "roll", "rotor_speeds",
                "rotor_forces")


def _knot_lines(ax: Axes, trace: _Trace, label: bool) -> None:
    """Faint vertical lines at the times of the way (solid) and via (dotted) points."""
    for time, way in zip(trace.knots, trace.is_way, strict=True):
        ax.axvline(time, color=STYLE["knot_color"], alpha=STYLE["knot_alpha"], linewidth=0.7,
                   linestyle="-" if way else ":", gid="knot",
                   label=("way point" if way else "via point") if label else None, zorder=0)


def _path_axes(robot) -> tuple[Figure, Axes]:
    """A task-space (y, z) figure with the ground z = -L and its margin z = -L + m_gd (3.27, 3.44).

    For the prototype also the fixed point and the margin y = m_gd (3.44). Call inside ``_styled()``.
    """
    ground, margins = robot.kind.ground_height, robot.margins
    fig, (ax,) = _new_figure(1, height=6.0, sharex=False)
    ax.axhline(ground, color=STYLE["ground_color"], linewidth=STYLE["line_width"],
               label="ground z = -L", gid="ground", zorder=1)
    _limit(ax, ground + margins.ground)
    fixed = robot.kind.fixed_point
    if fixed is not None:
        ax.plot([fixed[0]], [fixed[1]], linestyle="none", marker="^", color="black", markersize=8,
                label="fixed point", gid="fixed point", zorder=5)
        _limit(ax, fixed[0] + margins.ground, vertical=True)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("y [m]")
    ax.set_ylabel("z [m]")
    return fig, ax


def _path_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """Fig. 3.11 (FPR: end-effector and drone joint paths) or 3.36 (prototype: drone and elbow paths); a robot
    with three force axes gets two projections (:func:`_projections_figure`).
    """
    if len(robot.kind.force_axes) == 3:
        return _projections_figure(robot, plan, reference)
    traces = _traces(robot, plan, reference)
    thin = STYLE["thin_width"]
    with _styled():
        fig, ax = _path_axes(robot)
        what, other = robot.kind.task_point_labels
        legends = robot.kind.joint_legends()
        for tr in traces:
            main, joints = _task_space_joints(robot, tr.s)
            ax.plot(main[:, 0], main[:, 1], label=f"{tr.label}: {what}", gid="main", **tr.line)
            for i, (legend, gid) in enumerate(legends):
                kw = dict(tr.line, linewidth=thin)
                if not tr.is_reference:
                    kw["color"] = STYLE["drone_colors"][i % len(STYLE["drone_colors"])]
                label = f"{tr.label}: {other if tr.is_reference else legend}"
                ax.plot(joints[:, i, 0], joints[:, i, 1], label=label, gid=gid, **kw)
            if not tr.is_reference:
                markers = _task_space_joints(robot, tr.point_positions)[0]
                _point_markers(ax, markers[:, 0], markers[:, 1], tr.is_way)
                _direction_marks(ax, tr.t, main, markers[tr.is_way], tr.knots[tr.is_way])
        return _finish(fig, _title(robot, "path"), [ax], legend_below=True)


def _projections_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """The paths of a spatial robot's main point and joints (``task_points``, world x, y, z) seen from above (x-y)
    and from the side (x-z, with the ground and its margin m_gd).
    """
    traces = _traces(robot, plan, reference)
    thin = STYLE["thin_width"]
    views = ((0, 1, "x [m]", "y [m]", "from above"), (0, 2, "x [m]", "z [m]", "from the side"))
    with _styled():
        fig, axes = _new_figure(2, height=9.0, sharex=False)
        what, other = robot.kind.task_point_labels
        legends = robot.kind.joint_legends()
        ground = robot.kind.ground_height
        axes[1].axhline(ground, color=STYLE["ground_color"], linewidth=STYLE["line_width"], label="ground",
                        gid="ground", zorder=1)
        _limit(axes[1], ground + robot.margins.ground)
        for ax, (a, b, xlabel, ylabel, view) in zip(axes, views, strict=True):
            for tr in traces:
                main, joints = _task_space_joints(robot, tr.s)
                ax.plot(main[:, a], main[:, b], label=f"{tr.label}: {what}", gid="main", **tr.line)
                for i, (legend, gid) in enumerate(legends):
                    kw = dict(tr.line, linewidth=thin)
                    if not tr.is_reference:
                        kw["color"] = STYLE["drone_colors"][i % len(STYLE["drone_colors"])]
                    label = f"{tr.label}: {other if tr.is_reference else legend}"
                    ax.plot(joints[:, i, a], joints[:, i, b], label=label, gid=gid, **kw)
                if not tr.is_reference:
                    markers = _task_space_joints(robot, tr.point_positions)[0]
                    _point_markers(ax, markers[:, a], markers[:, b], tr.is_way, label=a == 0 and b == 1)
            ax.set_aspect("equal", adjustable="datalim")
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabel)
            ax.set_title(view)
        return _finish(fig, _title(robot, "path"), [axes[0]], legend_below=True)


def _direction_marks(ax, t: np.ndarray, path: np.ndarray, way: np.ndarray, way_times: np.ndarray) -> None:
    """Arrows along ``path`` (N, 2) showing the direction of motion, and each way point's time."""
    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    if length[-1] <= 0:
        return
    for s in np.linspace(0.0, length[-1], 14)[1:-1]:
        k = min(int(np.searchsorted(length, s)), len(path) - 2)
        ax.annotate("", xy=path[k + 1], xytext=path[k], gid="direction",
                    arrowprops={"arrowstyle": "-|>", "color": STYLE["plan_color"], "lw": 0.8, "mutation_scale": 9})
    seen = {}
    for (y, z), time in zip(way, way_times, strict=True):
        key = (round(float(y), 3), round(float(z), 3))
        seen[key] = seen.get(key, ()) + (time,)
    centre = np.mean(list(seen), axis=0) if seen else np.zeros(2)
    for (y, z), times in seen.items():
        # outside the way points' polygon, away from the reference's lines between them: on the side of the
        # point away from the way points' centre, the text extending away from it
        away = np.array([y, z]) - centre
        sy, sz = (1.0 if away[0] >= 0 else -1.0), (1.0 if away[1] >= 0 else -1.0)
        ax.annotate(", ".join(f"{x:g} s" for x in times), (y, z), textcoords="offset points",
                    xytext=(6 * sy, 6 * sz), ha="left" if sy > 0 else "right", va="bottom" if sz > 0 else "top",
                    fontsize=STYLE["legend_size"], color="0.25", gid="time mark")


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
            for b in _applicable_bounds(bounds, traces[0].s[:, j]):
                _limit(ax, b)
            ax.set_ylabel(ylabel)
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _title(robot, "coordinates"), axes)


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
        return _finish(fig, _title(robot, which), [ax])


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
                    kw = dict(tr.line, color=STYLE["rotor_colors"][k % len(STYLE["rotor_colors"])])
                    if tr.is_reference:  # thin, dashed and faded, in its rotor's colour: each finds its rotor
                        kw.update(linewidth=STYLE["thin_width"], alpha=STYLE["reference_alpha"])
                        ax.plot(tr.t, v[:, k], gid=f"{tr.label}: rotor {k + 1}", **kw)
                    else:
                        kw["linestyle"] = ROTOR_STYLES[k % len(ROTOR_STYLES)]  # visible where rotors coincide
                        ax.plot(tr.t, v[:, k], label=f"rotor {k + 1}", gid=f"rotor {k + 1}", **kw)
                if tr.is_reference:  # one legend entry for the four
                    ax.plot([], [], color=STYLE["reference_color"], linestyle=STYLE["reference_style"],
                            linewidth=STYLE["thin_width"], label=tr.label)
            for b in limits:
                _limit(ax, b)
            ax.set_ylabel(ylabel(i))
            if n_d > 1:
                ax.set_title(f"drone {i + 1}")
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _title(robot, which), axes)


def _thrust_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """Fig. 3.15-3.16 / 3.40: thrust norm |F_i| of each drone [N]."""
    floor = _context("min_thrust")
    return _per_drone_figure(robot, _traces(robot, plan, reference), "thrust",
                             lambda i: f"$|F_{i + 1}|$ [N]", lambda tr, i: tr.thrust[:, i],
                             () if floor is None else (floor,))


def _roll_figure(robot, plan: SampledPlan, reference: SampledPlan | None = None) -> Figure:
    """Fig. 3.17-3.18 / 3.41: roll phi_i of each drone [rad], with |phi_i| <= pi/2 - m_ga (3.33, 3.45); for a robot
    whose drones' angle is another (``kind.drone_angle_column``, e.g. the spatial FPR's tilt from the vertical,
    >= 0), that angle with its bound pi/2 - m_ga.
    """
    bound = np.pi / 2 - robot.margins.angle
    column = robot.kind.drone_angle_column
    if column == "phi":
        return _per_drone_figure(robot, _traces(robot, plan, reference), "roll",
                                 lambda i: rf"$\varphi_{i + 1}$ [rad]", lambda tr, i: tr.roll[:, i],
                                 (-bound, bound))
    return _per_drone_figure(robot, _traces(robot, plan, reference), "roll",
                             lambda i: f"{column} {i + 1} [rad]", lambda tr, i: tr.roll[:, i], (bound,))


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
                 reference: SampledPlan | None = None, *, figure_numbers=None, crossing: bool = False,
                 min_thrust: float | None = None) -> list[Path]:
    """Write the figures of one planned motion (seed Fig. 3.11-3.18 for the FPR, 3.36-3.41 for the prototype).

    Files, in ``out_dir`` (created if needed), in this order: ``path.png``, ``coordinates.png``,
    ``energy.png``, ``perturbation.png``, ``thrust.png``, ``roll.png``, ``rotor_speeds.png``,
    ``rotor_forces.png`` (:data:`PLAN_FIGURES`). The plan is drawn solid, the reference (typically the
    trajectory that stops at every way point) dashed grey; the planning bounds are red dotted lines:

    * path: ground z = -L and the margin z = -L + m_gd (3.27; 3.44), for the prototype also the
      fixed point and y = m_gd (3.44);
    * coordinates: pi + m_ga <= phi <= 2 pi - m_ga, m_ga <= q21 <= pi - m_ga (3.28-3.29), or
      ``|q1| <= pi/2 - m_ga``, m_ga <= q2 <= pi - m_ga (3.44, 3.46);
    * roll: ``|phi_i| <= pi/2 - m_ga`` (3.33, 3.45); rotor speeds: 0 <= w_ij <= w_max - m_gr (3.48);
      rotor forces: 0 <= c_T w_ij^2 <= c_T (w_max - m_gr)^2.

    Args:
        out_dir: output folder.
        robot: the :class:`~fpr.model.robot.Robot` the plan is for (``robot.name`` "fpr" or "prototype").
        plan: the sampled plan to show (see :mod:`fpr.views.figures`).
        reference: an optional sampled plan to compare with.
        figure_numbers: the thesis figure number(s) the motion reproduces, written in the titles instead of the
            robot's default ones: one text for every figure, or figure name -> text, or None
            (:func:`figure_context`).
        crossing: the motion crosses the Type-2 singularity on purpose: the assembly-mode bounds it crosses are
            not drawn.
        min_thrust: the thrust floor the motion was planned with [N], drawn on the thrust figure, or None.

    Returns:
        The paths of the written PNG files.

    Raises:
        FigureError: the robot is unknown, or a plan misses an attribute or has non-finite values
            (nothing is written then).
        ShapeError: a plan has an attribute whose shape does not fit the robot.
    """
    _traces(robot, plan, reference)  # fail before writing anything
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with figure_context(figure_numbers, crossing, min_thrust):
        return [_save(_BUILDERS[name](robot, plan, reference), out / f"{name}.png") for name in PLAN_FIGURES]


