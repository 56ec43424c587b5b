"""Replanning in flight: the plan revisions over the executed path, and the rotor speeds with and without.

:func:`replanning_figure` draws, for a simulation that replanned (:mod:`fpr.sim.replanning`):

* top: the task-space path (the robot kind's main task point, e.g. the FPR's end-effector): the offline plan
  (dashed grey), each revision from its splice on (thin, one colour each), the simulated path (solid), the
  way points (filled) and where moved way points went (stars);
* bottom: the largest rotor speed of the plant over time, with replanning and, when given, without it,
  against the planning limit w_max - m_gr and w_max (red dotted), the splices as vertical lines.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fpr.views.figures.robot_info import _task_space_joints
from fpr.views.figures.style import STYLE, _finish, _limit, _new_figure, _save, _styled


def replanning_figure(robot, offline, revisions, log, log_without=None, moved=()):
    """The figure (a :class:`matplotlib.figure.Figure`, not written).

    Args:
        robot: the robot.
        offline: the offline plan's trajectory (:class:`planners.trajectory.polynomial.PiecewisePolynomial`).
        revisions: (splice time [s], plan in force from then on) of each replan used
            (:attr:`planners.replanning.replanner.Replanner.revisions`).
        log: the :class:`fpr.sim.closed_loop.SimulationLog` with replanning.
        log_without: the same simulation without replanning, or None.
        moved: the moved way points, in planning coordinates (n_s,) each.
    """
    with _styled():
        fig, (path, speed) = _new_figure(2, height=7.5, sharex=False)
        t = np.linspace(0.0, offline.total_duration, 600)
        main = _task_space_joints(robot, offline.evaluate(t, 0)[0])[0]
        path.plot(*main.T, color="0.6", linestyle="--", label="offline plan", gid="offline")
        way = _task_space_joints(robot, offline.points[:, 0])[0]
        colors = list(STYLE["drone_colors"]) + ["tab:purple", "tab:brown", "tab:olive", "tab:cyan"]
        for i, (t_s, plan) in enumerate(revisions):
            tt = np.linspace(t_s, plan.total_duration, 300)
            p = _task_space_joints(robot, plan.evaluate(tt, 0)[0])[0]
            path.plot(
                *p.T,
                linewidth=STYLE["thin_width"],
                color=colors[i % len(colors)],
                label=f"revision {i + 1} (from {t_s:.2f} s)" if i < 6 else None,
                gid=f"revision {i + 1}",
            )
        chain = [log.coordinates.index(c) for c in log.chain]
        sim = _task_space_joints(robot, log.q[:, chain])[0]
        path.plot(*sim.T, color="k", label="simulated", gid="simulated")
        if log_without is not None:
            other = _task_space_joints(robot, log_without.q[:, chain])[0]
            path.plot(
                *other.T,
                color="tab:red",
                linewidth=STYLE["thin_width"],
                label="simulated without replanning",
                gid="without",
            )
        path.plot(*way.T, "o", color="k", markersize=4, label="way and via points of the offline plan")
        for point in moved:
            p = _task_space_joints(robot, np.asarray(point)[None])[0][0]
            path.plot(*p, "*", color="tab:green", markersize=12, label="moved way point")
        path.set_xlabel("y [m]")
        path.set_ylabel("z [m]")
        path.set_aspect("equal", adjustable="datalim")
        speed.plot(log.t, log.speed.max(axis=(1, 2)), color="k", label="largest rotor speed, replanning")
        if log_without is not None:
            speed.plot(
                log_without.t,
                log_without.speed.max(axis=(1, 2)),
                color="tab:red",
                linewidth=STYLE["thin_width"],
                label="largest rotor speed, without replanning",
            )
        _limit(speed, log.speed_limit)
        _limit(speed, log.max_speed)
        for i, (t_s, _) in enumerate(revisions):
            speed.axvline(t_s, color="0.7", linewidth=0.8, label="splice" if i == 0 else None)
        speed.set_xlabel("t [s]")
        speed.set_ylabel("rotor speed [rad/s]")
        return _finish(
            fig, "Replanning in flight: plan revisions and rotor speeds", [path, speed], legend_below=True
        )


def write_replanning_figure(path: str | Path, *args, **kwargs) -> Path:
    """:func:`replanning_figure` written as a PNG file at ``path``."""
    return _save(replanning_figure(*args, **kwargs), Path(path))


__all__ = ["replanning_figure", "write_replanning_figure"]
