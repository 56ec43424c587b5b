"""The public API of the meshcat scenes: :func:`view`, :func:`write_scene`, :func:`serve` (see
:mod:`fpr.views.scene`), and the checks of what they are given.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fpr.model.errors import SceneError, check_shape
from fpr.model.robot import Robot
from fpr.views.scene.builder import (
    _PLANNED_COLOR,
    _TRACKED_COLOR,
    _default_configuration,
    _frame_times,
    _logged_reference,
    _planned_motion,
    _Scene,
    _tracked_motion,
)
from fpr.views.scene.geometry import deterministic_ids
from fpr.views.scene.page import SceneView

THRUST_SCALE = 0.03
"""Length of a thrust arrow per newton [m/N]: a hovering FPR drone (about 12 N) gets 0.36 m."""

DEFAULT_FPS = 30.0
"""Key frames per second of the animations [1/s]."""


def view(robot, plan=None, log=None, *, configuration=None, fps: float = DEFAULT_FPS,
         title: str | None = None, thrust_scale: float = THRUST_SCALE) -> SceneView:
    """Build the meshcat scene of a robot, a planned motion and / or a simulated one.

    Args:
        robot: the :class:`fpr.model.robot.Robot` (``plan.robot``, ``mission.load_robot()``).
        plan: a :class:`planners.optimize.PlanResult`. Alone: the robot follows it. With ``log``: the
            ghost follows it. Its way and via points are marked.
        log: a :class:`fpr.sim.closed_loop.SimulationLog`: the robot follows the simulated motion and a
            translucent ghost the plan.
        configuration: thesis coordinates q (n,) of a robot standing still (not with a plan or a
            log). With nothing given: FPR s0 = [0 0 5pi/4 pi/2], prototype xi = [0 pi/2].
        fps: key frames per second of the animation [1/s]; it plays in real time.
        title: the page's title (default: mission name, what is shown, duration).
        thrust_scale: length of the thrust arrows per newton [m/N].

    Returns:
        the :class:`SceneView` (``.html``, ``.write(path)``; Jupyter shows it inline).

    Raises:
        SceneError: a robot, plan or log of the wrong kind or for another robot, a configuration
            given with a plan or a log, a non-finite configuration, fps or thrust_scale not > 0.
        ShapeError: a configuration or log array of the wrong shape.
        ImportError: meshcat is not installed.
    """
    robot = _check_robot(robot)
    for name, value in (("fps", fps), ("thrust_scale", thrust_scale)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not (math.isfinite(value) and value > 0):
            raise SceneError(name, f"{value!r}: give a finite number > 0")
    if configuration is not None and (plan is not None or log is not None):
        raise SceneError("configuration", "it shows the robot standing still: give it alone, or a plan "
                                          "and / or a log instead")
    if plan is not None:
        _check_plan(robot, plan)
    if log is not None:
        _check_log(robot, log)

    with deterministic_ids():  # the same scene, the same bytes
        return _build(robot, plan, log, configuration, float(fps), title, float(thrust_scale))


def _build(robot, plan, log, configuration, fps: float, title: str | None, thrust_scale: float) -> SceneView:
    """:func:`view` once its arguments are checked."""
    scene = _Scene(robot, fps, thrust_scale)
    if plan is None and log is None:
        q = _default_configuration(robot) if configuration is None else \
            check_shape("configuration", configuration, (robot.nq,))
        if not np.all(np.isfinite(q)):
            raise SceneError("configuration", f"{np.array2string(q, precision=4)} is not finite")
        poses = scene.poses(q[None])
        scene.draw_robot("robot", poses, None, ghost=False)
        scene.environment([(poses, None)])
        return scene.view(title or f"{robot.name}: configuration", None, ())

    duration = max(([plan.trajectory.total_duration] if plan is not None else [])
                   + ([float(log.t[-1])] if log is not None else []))
    times = scene.frame_times = _frame_times(duration, scene.fps)
    planned = _planned_motion(robot, plan, times) if plan is not None \
        else _logged_reference(robot, log, times)
    planned_poses = scene.poses(planned.q)
    scale = f"{thrust_scale:g} m/N"
    if log is None:
        scene.draw_robot("robot", planned_poses, planned, ghost=False)
        scene.paths("planned", planned_poses, _PLANNED_COLOR)
        legend = ["robot: planned motion", f"red arrows: planned thrusts ({scale})",
                  "blue lines: planned paths of the end-effector and the drones"]
        everything = [(planned_poses, planned)]
    else:
        tracked = _tracked_motion(log, times)
        tracked_poses = scene.poses(tracked.q)
        scene.draw_robot("robot", tracked_poses, tracked, ghost=False)
        scene.draw_robot("ghost", planned_poses, planned, ghost=True)
        scene.paths("planned", planned_poses, _PLANNED_COLOR)
        scene.paths("tracked", tracked_poses, _TRACKED_COLOR)
        legend = ["solid robot: simulation; translucent: plan", f"red arrows: controller thrusts ({scale})",
                  "paths: planned (blue), simulated (orange)"]
        everything = [(planned_poses, planned), (tracked_poses, tracked)]
    if plan is not None:
        legend.append(scene.markers(plan))
    scene.environment(everything)
    name = getattr(getattr(plan, "mission", None), "name", None) or robot.name
    shown = "simulation" if log is not None else f"plan ({plan.method})"
    return scene.view(title or f"{name}: {shown}, {duration:g} s", duration, tuple(legend))


def write_scene(path, robot, plan=None, log=None, **kw) -> Path:
    """Write the page of :func:`view` to ``path`` (a folder gets ``scene.html``); returns the file written."""
    return view(robot, plan, log, **kw).write(path)


def serve(robot, plan=None, log=None, *, zmq_url: str | None = None, **kw):
    """Send the scene of :func:`view` to a live meshcat server; returns the ``meshcat.Visualizer``.

    Args:
        robot: as :func:`view`.
        plan: as :func:`view`.
        log: as :func:`view`.
        zmq_url: a running server (``meshcat-server``); default: start one.
        **kw: the keyword arguments of :func:`view`.

    Returns:
        the Visualizer (:meth:`SceneView.serve`); ``visualizer.url()`` is the page to open.
    """
    return view(robot, plan, log, **kw).serve(zmq_url)


def _check_robot(robot):
    """``robot`` if it is a :class:`fpr.model.robot.Robot` (SceneError otherwise)."""
    if not isinstance(robot, Robot):
        raise SceneError("robot", f"got a {type(robot).__name__}; give fpr.load('fpr'), "
                                  "fpr.load('prototype') or plan.robot")
    return robot


def _check_plan(robot, plan) -> None:
    """SceneError unless ``plan`` is a PlanResult of ``robot`` with one way/via flag per point."""
    if not all(hasattr(plan, a) for a in ("trajectory", "is_way", "method")):
        raise SceneError("plan", f"got a {type(plan).__name__}; give the PlanResult of "
                                 "planners.optimize.plan")
    other = getattr(plan, "robot", None)
    if other is not None and (other.name != robot.name or other.urdf != robot.urdf):
        raise SceneError("plan", f"it was planned for another robot ({other.name}, "
                                 f"L = {other.link_length:g} m) than the one given ({robot.name}, "
                                 f"L = {robot.link_length:g} m): give plan.robot")
    if len(plan.is_way) != len(plan.trajectory.points):
        raise SceneError("plan", f"{len(plan.is_way)} way/via flags for {len(plan.trajectory.points)} points")


def _check_log(robot, log) -> None:
    """SceneError (ShapeError) unless ``log`` is a SimulationLog of ``robot`` with increasing times."""
    if not all(hasattr(log, a) for a in ("robot_name", "coordinates", "t", "q", "thrust", "reference",
                                         "planned_roll")):
        raise SceneError("log", f"got a {type(log).__name__}; give the SimulationLog of "
                                "fpr.sim.closed_loop.simulate")
    if log.robot_name != robot.name or tuple(log.coordinates) != tuple(robot.layout.coordinates):
        raise SceneError("log", f"it is a simulation of the {log.robot_name!r} (coordinates "
                                f"{', '.join(log.coordinates)}), not of the {robot.name!r} given")
    t = np.asarray(log.t, dtype=float)
    check_shape("log.q", log.q, (t.size, robot.nq))
    check_shape("log.thrust", log.thrust, (t.size, robot.n_drones))
    if t.size < 2 or not np.all(np.diff(t) > 0) or not np.all(np.isfinite(log.q)):
        raise SceneError("log", "it needs at least two samples, increasing times and finite states")

