"""The chain itself in the plane, at a few instants and moving: :func:`strobe_figure`, :func:`chain_animation`.

Both draw a simulation log (:class:`fpr.sim.closed_loop.SimulationLog`): the links as a polyline through the
fixed point (if the robot has one), the passive joints and the main task point (the prototype: fixed point,
elbow, drone joint; the FPR: drone joint 1, end-effector, drone joint 2), and each drone as a bar through its
centre of mass, ``d`` above its joint along its thrust axis, tilted by its measured roll. The stroboscopic
figure overlays ``count`` instants, fading from light (early) to dark (late), with the path of the main point;
the animation writes a GIF (matplotlib's PillowWriter) or, for a ``.mp4`` path, an MP4 (needs ffmpeg).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fpr.model.errors import FigureError
from fpr.views.figures.style import STYLE, _new_figure, _styled


def _columns(robot, log):
    """(t, s, rolls) of ``log``, checked against ``robot`` (a planar one: its chain moves in the y-z plane)."""
    if len(robot.kind.force_axes) != 2:
        raise FigureError("robot", robot.name, f"the {robot.name} is not planar (force axes "
                                               f"{', '.join(robot.kind.force_axes)}): the chain's drawing in the "
                                               "plane does not apply; use the 3D scene (--meshcat)")
    if getattr(log, "robot_name", None) != robot.name:
        raise FigureError("log", getattr(log, "robot_name", log), f"draw a log of the {robot.name} with it")
    coords = list(log.coordinates)
    s = log.q[:, [coords.index(c) for c in robot.layout.chain]]
    rolls = log.q[:, [coords.index(c) for c in robot.layout.rolls]]
    if len(log.t) < 2:
        raise FigureError("log.t", log.t, "the log has fewer than 2 samples: nothing moves")
    return np.asarray(log.t), s, rolls


def chain_points(robot, s) -> np.ndarray:
    """The chain's polyline at poses ``s`` (N, n_s): shape (N, k, 2) [m] (y, z)."""
    main, joints = robot.kind.task_points(s)
    fixed = robot.kind.fixed_point
    if fixed is not None:  # fixed point -> joints -> main point (prototype)
        start = np.broadcast_to(np.asarray(fixed, dtype=float), main.shape)[:, None]
        return np.concatenate([start, joints, main[:, None]], axis=1)
    return np.concatenate([joints[:, :1], main[:, None], joints[:, 1:]], axis=1)  # r1 -> p -> r2 (FPR)


def drone_bars(robot, s, rolls) -> np.ndarray:
    """Each drone as a segment through its centre of mass, (N, n_d, 2, 2) [m]: joint + d u_z(roll) -+ arm u_y."""
    joints = robot.kind.drone_joints(s)
    d = float(np.mean(np.atleast_1d(robot.hinge_offset)))
    arm = float(robot.parameters.get("rotor_arm", 0.17))
    up = np.stack([-np.sin(rolls), np.cos(rolls)], axis=-1)
    side = np.stack([np.cos(rolls), np.sin(rolls)], axis=-1)
    centre = joints + d * up
    return np.stack([centre - arm * side, centre + arm * side], axis=-2)


def _indices(t: np.ndarray, count: int) -> np.ndarray:
    return np.unique(np.searchsorted(t, np.linspace(t[0], t[-1], count)).clip(0, len(t) - 1))


def strobe_figure(path: str | Path, robot, log, count: int = 12, title: str | None = None) -> Path:
    """The chain at ``count`` evenly spaced instants of ``log``, light (early) to dark (late), as a PNG file.

    Args:
        path: the PNG file to write.
        robot: the simulated robot.
        log: its :class:`fpr.sim.closed_loop.SimulationLog`.
        count: instants drawn (>= 2).
        title: the figure's title (default: "Stroboscopic view of the simulated motion").

    Returns:
        ``path``.
    """
    if count < 2:
        raise FigureError("count", count, "draw at least 2 instants")
    t, s, rolls = _columns(robot, log)
    chain, bars = chain_points(robot, s), drone_bars(robot, s, rolls)
    main, _ = robot.kind.task_points(s)
    picks = _indices(t, count)
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    with _styled():
        fig, axes = _new_figure(1, 1, height=5.0, width=6.4)
        ax = axes[0]
        ax.axhline(robot.kind.ground_height, color=STYLE["ground_color"], linewidth=2.0, label="ground")
        ax.plot(*main.T, color="0.6", linewidth=STYLE["thin_width"],
                label=robot.kind.task_point_labels[0] + " path")
        for n, k in enumerate(picks):
            color = cmap(0.1 + 0.85 * n / max(len(picks) - 1, 1))
            ax.plot(*chain[k].T, "-o", color=color, markersize=3, linewidth=1.6, gid="chain")
            for bar in bars[k]:
                ax.plot(*bar.T, color=color, linewidth=3.0, solid_capstyle="round", gid="drone")
            ax.annotate(f"{t[k]:.1f} s", main[k], textcoords="offset points", xytext=(4, 4), fontsize=6,
                        color=color)
        if robot.kind.fixed_point is not None:
            ax.plot(*robot.kind.fixed_point, "ks", markersize=6, label="fixed point")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("y [m]")
        ax.set_ylabel("z [m]")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))
        fig.suptitle(title or "Stroboscopic view of the simulated motion (colour: time)")
        fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    with _styled():
        fig.savefig(out, dpi=STYLE["dpi"])
    return out


def chain_animation(path: str | Path, robot, log, fps: float = 20.0, speed: float = 1.0,
                    title: str | None = None) -> Path:
    """Animate the chain and the drones of ``log`` and write a GIF (PillowWriter) or an MP4 (``.mp4``, ffmpeg).

    Args:
        path: the ``.gif`` (or ``.mp4``) file to write.
        robot: the simulated robot.
        log: its :class:`fpr.sim.closed_loop.SimulationLog` (of that robot, at least 2 samples).
        fps: frames per second of the file.
        speed: simulated seconds per second of the file.
        title: shown above the chain (default: the robot's name), with the time.

    Returns:
        ``path``.

    Raises:
        FigureError: a suffix other than .gif or .mp4, an MP4 without ffmpeg, fps or speed <= 0.
    """
    from matplotlib import animation

    out = Path(path)
    suffix = out.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise FigureError("path", path, "give a .gif (or .mp4) file name")
    if not (fps > 0 and speed > 0):
        raise FigureError("fps", (fps, speed), "fps and speed must be > 0")
    if suffix == ".mp4" and not animation.FFMpegWriter.isAvailable():
        raise FigureError("path", path, "ffmpeg is not installed: write a .gif instead")
    t, s, rolls = _columns(robot, log)
    chain, bars = chain_points(robot, s), drone_bars(robot, s, rolls)
    frames = np.searchsorted(t, np.arange(t[0], t[-1], speed / fps)).clip(0, len(t) - 1)
    everything = np.concatenate([chain.reshape(-1, 2), bars.reshape(-1, 2)])
    low, high = everything.min(axis=0) - 0.1, everything.max(axis=0) + 0.1
    with _styled():
        fig, axes = _new_figure(1, 1, height=4.0, width=4.8)
        ax = axes[0]
        ax.set_xlim(low[0], high[0])
        ax.set_ylim(min(low[1], robot.kind.ground_height - 0.05), high[1])
        ax.set_aspect("equal")
        ax.axhline(robot.kind.ground_height, color=STYLE["ground_color"], linewidth=2.0)
        main, _ = robot.kind.task_points(s)
        ax.plot(*main.T, color="0.75", linewidth=STYLE["thin_width"])
        (links,) = ax.plot([], [], "-o", color=STYLE["plan_color"], linewidth=2.0, markersize=4)
        drones = [ax.plot([], [], color=STYLE["drone_colors"][i % 2], linewidth=4.0)[0]
                  for i in range(bars.shape[1])]
        label = ax.set_title("")
        ax.set_xlabel("y [m]")
        ax.set_ylabel("z [m]")
        fig.tight_layout()
        name = title or f"the {robot.name}"

        def draw(k):
            links.set_data(*chain[k].T)
            for line, bar in zip(drones, bars[k], strict=True):
                line.set_data(*bar.T)
            label.set_text(f"{name}, t = {t[k]:.2f} s")
            return [links, *drones, label]

        anim = animation.FuncAnimation(fig, draw, frames=frames, blit=False)
        writer = animation.PillowWriter(fps=fps) if suffix == ".gif" else animation.FFMpegWriter(fps=fps)
        out.parent.mkdir(parents=True, exist_ok=True)
        anim.save(out, writer=writer, dpi=80)
    return out
