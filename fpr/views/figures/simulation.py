"""Figures of a closed-loop simulation against its plan: seed Fig. 3.19-3.32 (FPR) and 3.42-3.51 (prototype)
(:func:`simulation_figures`).

The simulated motion is drawn solid in the plan colour, the plan dashed grey. Every ``_sim_<name>``
builder returns a :class:`matplotlib.figure.Figure` without writing it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fpr.model.errors import FigureError
from fpr.views.figures.planning import _path_axes
from fpr.views.figures.robot_info import (
    _applicable_bounds,
    _coordinate_axes,
    _drone_joint_velocities,
    _robot_sizes,
    _task_space_joints,
    _title,
    figure_context,
)
from fpr.views.figures.sampled import _field, _trace, cumulative_integral
from fpr.views.figures.style import ROTOR_STYLES, STYLE, _finish, _limit, _new_figure, _point_markers, _save, _styled
from planners.optimize import SampledPlan

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: File names written by :func:`simulation_figures`, in order (without the ".png" suffix).
SIMULATION_FIGURES = ("sim_path", "sim_coordinates", "sim_out_of_plane", "sim_roll", "sim_heights",
                      "sim_rotor_speeds", "sim_rotor_forces", "sim_energy")


# axis labels of out-of-plane coordinates, in the thesis' order of their panels (Fig. 3.20, 3.23, 3.24)
_OUT_OF_PLANE_LABELS = {"x": "x [m]", "theta": r"$\theta$ [rad]", "psi": r"$\psi$ [rad]"}


def _out_of_plane_panels(robot) -> list[tuple[str, str]]:
    """(coordinate, axis label) of each of the robot kind's ``out_of_plane`` coordinates: those with a label
    of :data:`_OUT_OF_PLANE_LABELS` in its order, then the others by their names.
    """
    names = robot.kind.out_of_plane
    known = [(c, label) for c, label in _OUT_OF_PLANE_LABELS.items() if c in names]
    return known + [(c, c) for c in names if c not in _OUT_OF_PLANE_LABELS]


def _drone_color(i: int) -> str:
    """Drone i's colour: the style's, then matplotlib's for a robot with more drones than the style names."""
    colors = STYLE["drone_colors"]
    return colors[i] if i < len(colors) else ("tab:brown", "tab:olive", "tab:cyan")[(i - len(colors)) % 3]


@dataclass(frozen=True)
class _Simulated:
    """A validated simulation log, in the arrays the figures draw (N inner-loop ticks)."""

    t: np.ndarray  # (N,) [s]
    planned: np.ndarray  # (N, n_s) planned planning coordinates
    simulated: np.ndarray  # (N, n_s) measured planning coordinates
    simulated_rate: np.ndarray  # (N, n_s) their rates
    planned_roll: np.ndarray  # (N, n_a) [rad]: the drones' attitude coordinates (a planar robot's rolls, n_a = n_d)
    desired_roll: np.ndarray  # (N, n_a) [rad], outer loop
    roll: np.ndarray  # (N, n_a) [rad], plant
    roll_rate: np.ndarray  # (N, n_a) [rad/s], plant
    thrust: np.ndarray  # (N, n_d) [N], allocated
    speed: np.ndarray  # (N, n_d, 4) [rad/s], plant rotors
    drone_height: np.ndarray  # (N, n_d) [m], drone centres of mass
    out_of_plane: dict  # name -> (N,) [m or rad]
    max_speed: float  # w_max [rad/s]


def _simulated(robot, log) -> _Simulated:
    """Check ``log`` (a :class:`fpr.sim.closed_loop.SimulationLog`) against ``robot`` and pick its arrays.

    Raises:
        FigureError: not a log, a log of another robot, missing coordinates or attributes, fewer than 2
            samples, non-finite values.
        ShapeError: an array whose shape does not fit the robot.
    """
    n_s, n_d = _robot_sizes(robot)
    name = getattr(log, "robot_name", None)
    if name is None or not hasattr(log, "coordinates"):
        raise FigureError("log", log, "log has no attribute 'robot_name' or 'coordinates': pass the "
                                      "SimulationLog of fpr.sim.closed_loop.simulate")
    if name != robot.name:
        raise FigureError("log.robot_name", name, f"log.robot_name={name!r} but robot.name={robot.name!r}: "
                                                  "draw a log with the robot it simulated")
    coordinates = tuple(log.coordinates)
    missing = [c for c in (*robot.layout.chain, *robot.layout.rolls) if c not in coordinates]
    if missing:
        raise FigureError("log.coordinates", coordinates, f"log.coordinates={coordinates!r} lacks "
                                                          f"{missing!r}: pass a log of this robot")
    t = _field("log", log, "t", (None,), "tick times [s]")
    n = t.shape[0]
    if n < 2:
        raise FigureError("log.t", t, f"log.t has {n} sample(s): the figures need at least 2")
    q = _field("log", log, "q", (n, len(coordinates)), "plant state in thesis coordinates")
    v = _field("log", log, "v", (n, len(coordinates)), "plant velocities in thesis coordinates")
    chain = [coordinates.index(c) for c in robot.layout.chain]
    rolls = [coordinates.index(c) for c in robot.layout.rolls]
    return _Simulated(
        t=t,
        planned=_field("log", log, "reference", (None, n, n_s), "planned s, s', s''")[0],
        simulated=q[:, chain],
        simulated_rate=v[:, chain],
        planned_roll=_field("log", log, "planned_roll", (n, len(rolls)), "planned rolls [rad]"),
        desired_roll=_field("log", log, "roll_desired", (n, len(rolls)), "desired rolls [rad]"),
        roll=q[:, rolls],
        roll_rate=v[:, rolls],
        thrust=_field("log", log, "thrust", (n, n_d), "allocated thrusts [N]"),
        speed=_field("log", log, "speed", (n, n_d, 4), "plant rotor speeds [rad/s]"),
        drone_height=_field("log", log, "drone_height", (n, n_d), "drone heights [m]"),
        out_of_plane={c: q[:, coordinates.index(c)] for c, _ in _out_of_plane_panels(robot) if c in coordinates},
        max_speed=float(log.max_speed),
    )


#: Largest out-of-plane motion drawn as numerical noise rather than as a result [m or rad].
NOISE_LEVEL = 1e-5  # the closure numerics and round-off stay below it (tests/test_simulate.py)


def _physical_line(label: str = "physical limit") -> dict[str, Any]:
    """Keyword arguments of ``Axes.axhline`` for a physical limit (black dash-dot; the planning limit is red dotted)."""
    return {"color": "black", "linestyle": "-.", "linewidth": STYLE["thin_width"], "label": label,
            "gid": "physical limit", "zorder": 1}


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
    if len(robot.kind.force_axes) != 2:
        return _sim_path_spatial(robot, sim, plan)
    thin = STYLE["thin_width"]
    what, other = robot.kind.task_point_labels
    legends = robot.kind.joint_legends()
    with _styled():
        fig, ax = _path_axes(robot)
        planned_main, planned_joints = _task_space_joints(robot, sim.planned)
        main, joints = _task_space_joints(robot, sim.simulated)
        ax.plot(*planned_main.T, label=f"planned: {what}", gid="planned", **_planned_line())
        ax.plot(*main.T, label=f"simulated: {what}", gid="simulated", **_simulated_line())
        for k in range(joints.shape[1]):
            ax.plot(*planned_joints[:, k].T, label=f"planned: {other}", gid=f"planned joint {k + 1}",
                    **_planned_line(thin))
            label = f"simulated: {legends[k][0]}"
            ax.plot(*joints[:, k].T, label=label, gid=f"simulated joint {k + 1}",
                    **dict(_simulated_line(thin), color=_drone_color(k)))
        if plan is not None:
            tr = _trace(robot, plan, "plan", False)
            markers = _task_space_joints(robot, tr.point_positions)[0]
            _point_markers(ax, markers[:, 0], markers[:, 1], tr.is_way)
        return _finish(fig, _title(robot, "sim_path"), [ax], legend_below=True)


def _sim_path_spatial(robot, sim: _Simulated, plan: SampledPlan | None) -> Figure:
    """:func:`_sim_path` of a robot whose task points are in space (``force_axes`` x, y, z): the paths seen from
    above (x, y) and from the side (x, z), with the ground and its margin in the side view.
    """
    thin = STYLE["thin_width"]
    what, other = robot.kind.task_point_labels
    legends = robot.kind.joint_legends()
    planned_main, planned_joints = _task_space_joints(robot, sim.planned)
    main, joints = _task_space_joints(robot, sim.simulated)
    markers = None
    if plan is not None:
        tr = _trace(robot, plan, "plan", False)
        markers = (_task_space_joints(robot, tr.point_positions)[0], tr.is_way)
    with _styled():
        fig, axes = _new_figure(2, height=9.0, sharex=False)
        for ax, (a, b) in zip(axes, ((0, 1), (0, 2)), strict=True):
            ax.plot(planned_main[:, a], planned_main[:, b], label=f"planned: {what}", gid="planned",
                    **_planned_line())
            ax.plot(main[:, a], main[:, b], label=f"simulated: {what}", gid="simulated", **_simulated_line())
            for k in range(joints.shape[1]):
                ax.plot(planned_joints[:, k, a], planned_joints[:, k, b], label=f"planned: {other}" if k == 0 else None,
                        gid=f"planned joint {k + 1}", **_planned_line(thin))
                ax.plot(joints[:, k, a], joints[:, k, b], label=f"simulated: {legends[k][0]}",
                        gid=f"simulated joint {k + 1}", **dict(_simulated_line(thin), color=_drone_color(k)))
            if markers is not None:
                _point_markers(ax, markers[0][:, a], markers[0][:, b], markers[1])
            ax.set_aspect("equal", adjustable="datalim")
            ax.set_xlabel("x [m]")
            ax.set_ylabel("xyz"[b] + " [m]")
        ground = robot.kind.ground_height
        axes[1].axhline(ground, color=STYLE["ground_color"], linewidth=STYLE["line_width"], label="ground",
                        gid="ground", zorder=1)
        _limit(axes[1], ground + robot.margins.ground)
        axes[0].set_title("from above")
        axes[1].set_title("from the side")
        return _finish(fig, _title(robot, "sim_path"), axes, legend_below=True)


def _drone_kinematics(robot, q, v) -> tuple[np.ndarray, np.ndarray]:
    """Each drone's thrust axis in world axes and its angular velocity in its own axes along logged states q, v
    (N, n) (Pinocchio's kinematics of the robot's model), shapes (N, n_d, 3).
    """
    import pinocchio as pin

    model, data = robot.model, robot.model.createData()
    n = len(q)
    axes, rates = np.empty((n, robot.n_drones, 3)), np.empty((n, robot.n_drones, 3))
    for k in range(n):
        pin.forwardKinematics(model, data, robot.to_pinocchio(q[k]), robot.to_pinocchio(v[k]))
        pin.updateFramePlacements(model, data)
        for i, frame in enumerate(robot.drone_frame_ids):
            axes[k, i] = data.oMf[frame].rotation[:, 2]
            rates[k, i] = pin.getFrameVelocity(model, data, frame, pin.LOCAL).angular
    return axes, rates


def _tilts(robot, log, sim: _Simulated) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each drone's tilt from the vertical (N, n_d) [rad]: planned (the plan's chain and attitude), desired (the
    measured chain, the controller's attitude targets) and simulated.
    """
    coordinates = tuple(log.coordinates)
    chain = [coordinates.index(c) for c in robot.layout.chain]
    rolls = [coordinates.index(c) for c in robot.layout.rolls]
    q = np.asarray(log.q, dtype=float)
    zero = np.zeros_like(q)
    planned = np.zeros_like(q)
    planned[:, chain], planned[:, rolls] = sim.planned, sim.planned_roll
    desired = q.copy()
    desired[:, rolls] = sim.desired_roll
    return tuple(np.arccos(np.clip(_drone_kinematics(robot, x, zero)[0][..., 2], -1.0, 1.0))
                 for x in (planned, desired, q))


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
            for b in _applicable_bounds(bounds, sim.planned[:, j]):
                _limit(ax, b)
            ax.set_ylabel(ylabel)
            symbol, unit = ylabel.rsplit(" [", 1)
            ax_err.plot(sim.t, sim.simulated[:, j] - sim.planned[:, j], gid="error", **_simulated_line())
            ax_err.set_ylabel(f"{symbol} error [{unit}")
        for ax in axes[-2:]:
            ax.set_xlabel("t [s]")
        return _finish(fig, _title(robot, "sim_coordinates"), axes)


def _sim_out_of_plane(robot, log, plan: SampledPlan | None = None) -> Figure:
    """Out of the plane: the robot kind's ``out_of_plane`` coordinates (x (FPR), pitch theta, yaw psi) of the
    simulated robot (Fig. 3.20, 3.23-3.24).

    The plan keeps them at 0.
    """
    sim = _simulated(robot, log)
    specs = [(c, label) for c, label in _out_of_plane_panels(robot) if c in sim.out_of_plane]
    with _styled():
        fig, axes = _new_figure(len(specs))
        for ax, (name, ylabel) in zip(axes, specs, strict=True):
            ax.axhline(0.0, label="planned", gid="planned", **_planned_line())
            values = sim.out_of_plane[name]
            ax.plot(sim.t, values, label="simulated", gid="simulated", **_simulated_line())
            ax.set_ylabel(ylabel)
            largest = float(np.abs(values).max())
            if largest < NOISE_LEVEL:  # round-off only: do not blow it up into a result
                ax.set_ylim(-10 * NOISE_LEVEL, 10 * NOISE_LEVEL)
                ax.text(0.02, 0.85, f"numerical noise only: |{name}| <= {largest:.1e} (nothing pushes the robot out "
                                    "of its plane)", transform=ax.transAxes, fontsize=STYLE["legend_size"], gid="noise")
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _title(robot, "sim_out_of_plane"), axes)


def _sim_roll(robot, log, plan: SampledPlan | None = None) -> Figure:
    """Drone rolls planned, desired by the outer loop and simulated (Fig. 3.27-3.28, 3.48).

    Limits: |phi_i| <= pi/2 - m_ga (3.33, 3.45).
    """
    sim = _simulated(robot, log)
    bound = np.pi / 2 - robot.margins.angle
    spatial = len(robot.kind.force_axes) != 2  # each drone's tilt from the vertical instead of its roll
    planned, desired, simulated = _tilts(robot, log, sim) if spatial else (sim.planned_roll, sim.desired_roll,
                                                                           sim.roll)
    n_d = simulated.shape[1]
    with _styled():
        fig, axes = _new_figure(n_d)
        for i, ax in enumerate(axes):
            ax.plot(sim.t, planned[:, i], label="planned", gid="planned", **_planned_line())
            ax.plot(sim.t, desired[:, i], color="tab:orange", linewidth=STYLE["thin_width"],
                    label="desired (outer loop)", gid="desired", zorder=2)
            ax.plot(sim.t, simulated[:, i], label="simulated", gid="simulated", **_simulated_line())
            for side in (1.0,) if spatial else (-1.0, 1.0):
                _limit(ax, side * bound)
                ax.axhline(side * np.pi / 2, **_physical_line())  # the physical limit: a drone on its side
            ax.set_ylabel(rf"tilt of drone {i + 1} [rad]" if spatial else rf"$\varphi_{i + 1}$ [rad]")
            if n_d > 1:
                ax.set_title(f"drone {i + 1}")
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _title(robot, "sim_roll"), axes)


def _sim_heights(robot, log, plan: SampledPlan | None = None) -> Figure:
    """Heights planned and simulated, with z >= -L + m_gd (3.27, 3.44).

    FPR (Fig. 3.29-3.30): the drone joints r_i and the drones' centres of mass. Prototype
    (Fig. 3.46-3.47): joint 2 (elbow) and joint 3 (drone joint), and the drone's centre of mass.
    """
    sim = _simulated(robot, log)
    planned_main, planned_joints = _task_space_joints(robot, sim.planned)
    main, joints = _task_space_joints(robot, sim.simulated)
    points = {"main": (planned_main[:, None], main[:, None]), "joint": (planned_joints, joints)}
    panels = [(ylabel, what, points[which][0][:, k, -1], points[which][1][:, k, -1], drone)  # z: the last axis
              for ylabel, what, which, k, drone in robot.kind.height_panels()]
    ground = robot.kind.ground_height + robot.margins.ground
    with _styled():
        fig, axes = _new_figure(len(panels))
        for ax, (ylabel, what, planned, simulated, drone) in zip(axes, panels, strict=True):
            ax.plot(sim.t, planned, label=f"planned: {what}", gid="planned", **_planned_line())
            ax.plot(sim.t, simulated, label=f"simulated: {what}", gid="simulated", **_simulated_line())
            if drone is not None:
                ax.plot(sim.t, sim.drone_height[:, drone], label="simulated: drone centre of mass", gid="com",
                        **dict(_simulated_line(STYLE["thin_width"]), color=_drone_color(drone)))
            _limit(ax, ground)
            ax.axhline(robot.kind.ground_height, **_physical_line("ground (physical limit)"))
            ax.set_ylabel(ylabel)
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _title(robot, "sim_heights"), axes)


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
            if trace is not None:  # each rotor's plan thin, dashed and faded in its colour; one legend entry
                for k in range(4):
                    ax.plot(trace.t, value(trace.rotor_speed[:, i, k]), gid="planned",
                            **dict(_planned_line(STYLE["thin_width"]), color=STYLE["rotor_colors"][k],
                                   alpha=STYLE["reference_alpha"]))
                ax.plot([], [], label="planned", **_planned_line(STYLE["thin_width"]))
            for k in range(4):
                ax.plot(sim.t, value(sim.speed[:, i, k]), label=f"rotor {k + 1}", gid="simulated",
                        color=STYLE["rotor_colors"][k], linestyle=ROTOR_STYLES[k], linewidth=STYLE["thin_width"] * 1.25,
                        zorder=3)
            _limit(ax, 0.0)
            _limit(ax, float(value(upper)))
            ax.axhline(float(value(sim.max_speed)), color=STYLE["reference_color"], linestyle="-",
                       linewidth=STYLE["thin_width"], label=saturation_label, gid="saturation", zorder=1)
            ax.set_ylabel(ylabel(i))
            if n_d > 1:
                ax.set_title(f"drone {i + 1}")
        axes[-1].set_xlabel("t [s]")
        return _finish(fig, _title(robot, which), axes)


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
    sim = _simulated(robot, log)
    velocity = _drone_joint_velocities(robot, sim.simulated, sim.simulated_rate)
    if len(robot.kind.force_axes) != 2:  # in space: the thrust axes and the drones' angular velocities (J_w)
        axes, rates = _drone_kinematics(robot, np.asarray(log.q, dtype=float), np.asarray(log.v, dtype=float))
        rows = ["xyz".index(a) for a in robot.kind.force_axes]
        power = np.abs(np.sum(sim.thrust[..., None] * axes[..., rows] * velocity, axis=-1)).sum(axis=1)
        return cumulative_integral(sim.t, power), cumulative_integral(sim.t, np.sum(rates**2, axis=(1, 2)))
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
        return _finish(fig, _title(robot, "sim_energy"), axes)


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


def simulation_figures(out_dir: str | Path, robot, log, plan: SampledPlan | None = None, *, figure_numbers=None,
                       crossing: bool = False) -> list[Path]:
    """Write the thesis' simulation figures of a :class:`fpr.sim.closed_loop.SimulationLog` as PNG files.

    Files, in ``out_dir`` (created if needed), in the order of :data:`SIMULATION_FIGURES`:

    * ``sim_path.png``: task-space path, planned and simulated (Fig. 3.19 / 3.42);
    * ``sim_coordinates.png``: planning coordinates with their bounds, and the tracking errors
      (Fig. 3.21-3.22, 3.25-3.26 / 3.43-3.45);
    * ``sim_out_of_plane.png``: x (FPR), pitch, yaw (Fig. 3.20, 3.23-3.24): the kind's ``out_of_plane``
      coordinates, not written for a kind without any (the spatial FPR);
    * ``sim_roll.png``: rolls planned, desired, simulated, ``|phi_i| <= pi/2 - m_ga`` (Fig. 3.27-3.28 / 3.48); for
      a robot whose thrust vectors are in space (``force_axes`` x, y, z), each drone's tilt from the vertical,
      <= pi/2 - m_ga;
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
        figure_numbers: the thesis figure number(s) the motion reproduces, written in the titles instead of the
            robot's default ones: one text for every figure, or figure name -> text, or None
            (:func:`fpr.views.figures.robot_info.figure_context`).
        crossing: the motion crosses the Type-2 singularity on purpose: the assembly-mode bounds it crosses are
            not drawn.

    Returns:
        The paths of the written PNG files.

    Raises:
        FigureError: the log is of another robot or misses an attribute, or the plan is not a
            sampled plan of the robot (nothing is written then).
        ShapeError: a log or plan array of the wrong shape.
    """
    _simulated(robot, log)  # fail before writing anything
    if plan is not None:
        _trace(robot, plan, "plan", False)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    names = [n for n in SIMULATION_FIGURES if n != "sim_out_of_plane" or robot.kind.out_of_plane]  # none to draw
    with figure_context(figure_numbers, crossing):
        return [_save(_SIM_BUILDERS[name](robot, log, plan), out / f"{name}.png") for name in names]


