"""Missions made to measure the planner: seeded families of random way-point missions, and the loop.

**Random families** (:class:`MissionFamily`, :func:`random_mission`). A claim about the planner's speed or
quality holds on missions it was not tuned on, so the bench plans seeded random missions of every robot:

* the way points are a random walk inside the robot's *mission region* (``robot.kind.mission_region``, a
  box in task or joint coordinates that the robot's own module gives, e.g. the square mission's square for
  the FPR's end-effector): each next way point is the last one plus a step drawn uniformly in
  +-``step`` of the region's width per coordinate, kept when it lies in the region, passes the robot's
  workspace check (``kind.check_pose`` in the family's assembly mode) with ``clearance`` to spare on every
  geometric bound, the straight travel to it (the stop-at-way-points motion's path) keeps that clearance,
  and the robot can hover there;
* each travel's time is derived, not fitted: the least time T_min at which the stop-at-way-points motion of
  that travel holds every planning constraint (:func:`least_stop_times`: rotor speeds within w_max - m_gr,
  drone rolls, workspace; found by bisection, the constraints' margins only grow with the time), times a
  factor drawn uniformly in ``time_range`` (its lower end > 1: the stop motion is feasible with margin);
  the whole stop motion is then checked on the 500 Hz grid (a travel that fails gets 10 % more time);
* each travel gets a number of via points drawn uniformly in ``via_points`` (inclusive).

Everything is drawn from ``numpy.random.default_rng(seed)``: the same family and seed give the same
mission, on any machine. A robot of your own gets families once its kind has a ``mission_region`` (or give
``region=`` to :func:`random_mission`)::

    from fpr.bench.missions import MissionFamily
    family = MissionFamily("prototype", way_points=32, space="task", arm="up")
    missions = [family.mission(seed) for seed in range(20)]   # plan them, report median, p95, failures

**The loop** (:func:`loop_mission`): N way points on a closed curve in the square mission's workspace,
deterministically (no random numbers): the end-effector goes round the circle of centre (0.5, 0.5) m and
radius 0.5 m, starting at its lowest point and stepping :data:`LOOP_STEP` of arc per travel, lap after lap.
Every travel is the same chord, 2 r sin(step / 2) = 0.5 m, with the square's pace (3 s per metre: 1.5 s).
The link angle phi swings gently with the angle round the circle (phi = 5 pi/4 + 0.15 sin(theta)) and q21
stays at pi/2 as on the square. Every travel alike: one row of the bench beside the families.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fpr import robots
from fpr.model.errors import FprError, PlannerArgumentError, SingularityError, WorkspaceError
from fpr.model.inverse_dynamics import MOTION_ORDER, inverse_dynamics
from planners.missions.mission import Mission
from planners.problem.motion import constraint_rows
from planners.problem.report import evaluate_motion
from planners.trajectory.polynomial import PiecewisePolynomial, stop_points

#: Centre [y, z] [m] and radius [m] of the circle the end-effector goes round.
LOOP_CENTRE = (0.5, 0.5)
LOOP_RADIUS = 0.5
#: Arc between two way points [rad] (pi / 3: six travels a lap, 0.5 m chords).
LOOP_STEP = np.pi / 3
#: Travel time per metre of chord [s/m]: the square mission's (1 m sides in 3 s).
SECONDS_PER_METRE = 3.0
#: phi's centre [rad] (the square's s0: both drones above the end-effector) and its swing [rad].
PHI_CENTRE = 5 * np.pi / 4
PHI_SWING = 0.15
#: q21 [rad], held as on the square.
Q21 = np.pi / 2

#: Samples per travel of the stop motion in the travel-time search (:func:`least_stop_times`); the mission's
#: stop motion is then checked on the 500 Hz grid.
TIME_SEARCH_SAMPLES = 65
#: Draws of a next way point before the walk gives up (:class:`MissionRegionError`).
MAX_DRAWS = 2000


class MissionRegionError(FprError):
    """A random mission could not be drawn: the robot has no mission region, or its region holds too few
    feasible way points (every draw failed).
    """


@dataclass(frozen=True)
class MissionFamily:
    """A seeded family of random way-point missions of one robot (module docstring).

    Attributes:
        robot: a registered robot name (:func:`fpr.robots.names`).
        way_points: way points per mission, >= 2.
        space: "task" or "joint": the coordinates the way points are drawn and written in.
        arm: the assembly mode ("down" or "up"), kept by every way point of a robot with assembly modes.
        via_points: (least, most) via points per travel, drawn uniformly per travel.
        time_range: (least, most) factor on each travel's least feasible time T_min, drawn uniformly.
        step: largest step of the walk per coordinate, a share of the region's width.
        clearance: least margin of every way point and stop-motion path to the geometric bounds [m or rad].
        alpha: the objective's energy weight (3.26).
    """

    robot: str
    way_points: int
    space: str = "task"
    arm: str = "down"
    via_points: tuple[int, int] = (0, 2)
    time_range: tuple[float, float] = (1.1, 2.0)
    step: float = 0.5
    clearance: float = 0.01
    alpha: float = 0.5

    @property
    def label(self) -> str:
        """E.g. ``"prototype task up"``, ``"fpr task"`` (the arm only for a robot with assembly modes)."""
        modes = robots.get(self.robot).assembly_modes
        return f"{self.robot} {self.space}" + (f" {self.arm}" if modes else "")

    def mission(self, seed: int, robot=None) -> Mission:
        """The family's mission of ``seed`` (:func:`random_mission`); ``robot`` default ``fpr.robots.load``."""
        robot = robot if robot is not None else robots.load(self.robot)
        return random_mission(robot, self.way_points, seed, space=self.space, arm=self.arm,
                              via_points=self.via_points, time_range=self.time_range, step=self.step,
                              clearance=self.clearance, alpha=self.alpha)


def builtin_families(way_points: int, names: tuple[str, ...] | None = None, **settings) -> list[MissionFamily]:
    """One family per robot, space and assembly mode: the FPR in task space (its task and joint coordinates are
    the same), the prototype in task and joint space, arm down and up. ``names``: the robots (default: the
    built-in ones, :data:`fpr.robots.BUILTIN`); ``settings`` are further :class:`MissionFamily` fields.
    """
    out = []
    for name in robots.BUILTIN if names is None else names:
        kind = robots.get(name)
        spaces = ("task",) if kind.task_coordinates is None else ("task", "joint")
        for space in spaces:
            for arm in kind.assembly_modes or ("down",):
                out.append(MissionFamily(name, way_points, space=space, arm=arm, **settings))
    return out


def _unit_step(order: int) -> np.ndarray:
    """sigma^(k)(tau), k = 0..order, of the stop motion's 0 -> 1 step of unit duration on the search grid,
    shape (order + 1, TIME_SEARCH_SAMPLES).
    """
    step = PiecewisePolynomial(stop_points([[0.0], [1.0]]), [1.0])
    return step.evaluate(np.linspace(0.0, 1.0, TIME_SEARCH_SAMPLES), order=order)[..., 0]


def _stop_feasible(robot, poses: np.ndarray, times: np.ndarray, clearance: float = 0.0) -> np.ndarray:
    """Whether the stop motion of each travel poses[i] -> poses[i + 1] in times[i] holds every planning
    constraint on the search grid (the geometric ones with ``clearance``), shape (m,).
    """
    sigma = _unit_step(MOTION_ORDER)  # (7, K)
    delta = np.diff(poses, axis=0)  # (m, n)
    k = np.arange(MOTION_ORDER + 1)[:, None, None, None]
    motion = sigma[:, None, :, None] * delta[None, :, None, :] / times[None, :, None, None] ** k  # (7, m, K, n)
    motion[0] += poses[:-1, None, :]
    motion = motion.reshape(MOTION_ORDER + 1, -1, poses.shape[1])
    rows, names, _ = constraint_rows(robot, motion, inverse_dynamics(robot, motion), scaled=False)
    geometric = np.array([name in robot.kind.workspace_margins(poses[0]) for name in names])
    rows = rows - np.where(geometric, clearance, 0.0)
    return rows.reshape(len(times), -1).min(axis=1) >= 0.0


def least_stop_times(robot, poses, precision: float = 0.01, clearance: float = 0.0) -> np.ndarray:
    """The least time of each travel at which its stop-at-way-points motion holds every planning constraint.

    The motion of travel i is poses[i] + (poses[i+1] - poses[i]) sigma(t / T) (sigma the degree-9 step with
    zero derivatives 1..4 at both ends); its rates and accelerations scale as 1 / T and 1 / T^2, so the
    rotor-speed and roll margins grow with T. The search doubles T from sqrt(L / g) until the motion holds
    (on :data:`TIME_SEARCH_SAMPLES` samples), then bisects (in log T) to ``precision`` (relative).

    Args:
        robot: the robot.
        poses: way points in planning coordinates, shape (k, n_s).
        precision: relative precision of the result.
        clearance: margin the geometric constraints must keep [m or rad].

    Returns:
        T_min of each travel, shape (k - 1,) [s] (an upper bound within ``precision``).

    Raises:
        MissionRegionError: a travel that no time makes feasible (its path leaves the workspace, or a pose
            the robot cannot hold at rest).
    """
    poses = np.asarray(poses, dtype=float)
    length = robot.link_length or max(robot.kind.link_lengths)  # (a robot whose drones sit on no link: its links')
    high = np.full(len(poses) - 1, math.sqrt(length / float(-robot.model.gravity.linear[2])))
    ok = _stop_feasible(robot, poses, high, clearance)
    for _ in range(16):
        if ok.all():
            break
        high = np.where(ok, high, 2.0 * high)
        ok = _stop_feasible(robot, poses, high, clearance)
    if not ok.all():
        raise MissionRegionError(f"travel {int(np.argmin(ok))} of the stop motion holds its constraints at no "
                                 "travel time: its path or one of its poses is infeasible")
    low = high / 2.0
    for _ in range(math.ceil(math.log2(math.log(2.0) / math.log1p(precision)))):
        middle = np.sqrt(low * high)
        ok = _stop_feasible(robot, poses, middle, clearance)
        high, low = np.where(ok, middle, high), np.where(ok, low, middle)
    return high


def _planning_pose(robot, point, space: str, mode, clearance: float):
    """The planning pose of a drawn way point, or None when it is out of the workspace (with ``clearance``)."""
    kind = robot.kind
    try:
        pose = kind.planning_pose(point, space, mode, "a random way point")
        kind.check_pose(pose, mode, "a random way point")
    except (WorkspaceError, SingularityError):
        return None
    margins = kind.workspace_margins(pose, mode)
    return pose if min(float(v) for v in margins.values()) >= clearance else None


def _path_clear(robot, start, end, mode, clearance: float) -> bool:
    """Whether the straight path start -> end (planning coordinates) keeps ``clearance`` to every geometric
    bound, on the search grid.
    """
    tau = np.linspace(0.0, 1.0, TIME_SEARCH_SAMPLES)[:, None]
    margins = robot.kind.workspace_margins(start + tau * (end - start), mode)
    return min(float(np.min(v)) for v in margins.values()) >= clearance


def _can_hover(robot, pose) -> bool:
    """Whether the robot can hold ``pose`` at rest within its rotor and roll limits."""
    motion = np.zeros((5, 1, pose.size))
    motion[0, 0] = pose
    rows, _, _ = constraint_rows(robot, motion, inverse_dynamics(robot, motion), scaled=False)
    return bool(rows.min() >= 0.0)


def random_mission(robot, way_points: int, seed: int, *, space: str = "task", arm: str = "down",
                   via_points: tuple[int, int] = (0, 2), time_range: tuple[float, float] = (1.1, 2.0),
                   step: float = 0.5, clearance: float = 0.01, alpha: float = 0.5, region=None,
                   name: str | None = None) -> Mission:
    """A random way-point mission of ``robot`` (module docstring), the same for the same arguments.

    Args:
        robot: the :class:`~fpr.model.robot.Robot` (a built-in one or your own registered kind).
        way_points: number of way points, >= 2.
        seed: the seed of ``numpy.random.default_rng``.
        space: "task" or "joint", the coordinates of the way points.
        arm: the assembly mode every way point keeps (robots with ``assembly_modes``).
        via_points: (least, most) via points per travel (inclusive).
        time_range: (least, most) factor on each travel's least feasible time; the least must be > 1.
        step: largest step of the walk per coordinate, a share of the region's width, in (0, 1].
        clearance: least margin to every geometric bound of the way points and the travels' straight paths.
        alpha: the objective's energy weight.
        region: (lower, upper) of the way points in ``space`` coordinates; default
            ``robot.kind.mission_region(space, mode)``.
        name: the mission's name; default "<robot>-<space>[-<arm>]-<way points>-seed<seed>".

    Raises:
        PlannerArgumentError: a setting out of its range.
        MissionRegionError: no region, or too few feasible way points in it.
    """
    kind = robot.kind
    mode = arm if kind.assembly_modes else None
    count = int(way_points)
    low_vp, high_vp = (int(v) for v in via_points)
    if count < 2:
        raise PlannerArgumentError("way_points", way_points, f"way_points={way_points!r}: give at least 2")
    if not 0 <= low_vp <= high_vp:
        raise PlannerArgumentError("via_points", via_points, f"via_points={via_points!r}: give (least, most), "
                                   "0 <= least <= most")
    if not 1.0 < time_range[0] <= time_range[1]:
        raise PlannerArgumentError("time_range", time_range, f"time_range={time_range!r}: give (least, most) "
                                   "with 1 < least <= most (factors on the least feasible travel time)")
    if not 0.0 < step <= 1.0:
        raise PlannerArgumentError("step", step, f"step={step!r}: give a share of the region's width in (0, 1]")
    if region is None:
        region = kind.mission_region(space, mode)
        if region is None:
            raise MissionRegionError(f"the robot kind {kind.name!r} defines no mission_region: give "
                                     "region=(lower, upper) in its {space} coordinates")
    lower, upper = (np.asarray(r, dtype=float) for r in region)
    width = upper - lower
    rng = np.random.default_rng(seed)
    points, poses = [], []
    draws = 0
    while len(points) < count:
        draws += 1
        if draws > MAX_DRAWS * count:
            raise MissionRegionError(f"{draws - 1} draws gave {len(points)} of {count} way points: the region "
                                     f"{lower.tolist()} .. {upper.tolist()} holds too few feasible ones")
        if points:
            point = points[-1] + width * rng.uniform(-step, step, size=width.size)
            if np.any(point < lower) or np.any(point > upper):
                continue
        else:
            point = lower + width * rng.uniform(size=width.size)
        pose = _planning_pose(robot, point, space, mode, clearance)
        if pose is None or not _can_hover(robot, pose):
            continue
        if poses and not _path_clear(robot, poses[-1], pose, mode, clearance):
            continue
        points.append(point)
        poses.append(pose)
    poses = np.array(poses)
    times = least_stop_times(robot, poses, clearance=clearance) * rng.uniform(*time_range, size=count - 1)
    times = np.ceil(times * 1000.0) / 1000.0  # whole milliseconds, never below the drawn time
    n_vp = rng.integers(low_vp, high_vp + 1, size=count - 1)
    for _ in range(50):  # the search grid is coarser than the 500 Hz check: a travel may need a little more
        report = evaluate_motion(robot, PiecewisePolynomial(stop_points(poses), times))
        if report.feasible:
            break
        worst = report.violations[0].time
        travel = min(int(np.searchsorted(np.cumsum(times), worst)), count - 2)
        times[travel] = np.ceil(times[travel] * 1100.0) / 1000.0
    else:
        raise MissionRegionError("the stop motion of the drawn way points stays infeasible")
    label = f"{kind.name}-{space}" + (f"-{arm}" if mode is not None else "")
    return Mission(name=name or f"{label}-{count}-seed{seed}", robot=kind.name, way_points=np.array(points),
                   times=times, via_points=[int(v) for v in n_vp], alpha=alpha, space=space, arm=arm,
                   description=f"random walk of {count} way points, seed {seed} (fpr.bench.missions)",
                   source="fpr.bench.missions")


def loop_way_points(count: int) -> np.ndarray:
    """The ``count`` way points s = [y, z, phi, q21] of :func:`loop_mission` (count, 4) [m, m, rad, rad]."""
    theta = -np.pi / 2 + LOOP_STEP * np.arange(count)  # start at the circle's lowest point
    y = LOOP_CENTRE[0] + LOOP_RADIUS * np.cos(theta)
    z = LOOP_CENTRE[1] + LOOP_RADIUS * np.sin(theta)
    phi = PHI_CENTRE + PHI_SWING * np.sin(theta + np.pi / 2)  # theta + pi/2: phi starts at its centre
    return np.stack([y, z, phi, np.full(count, Q21)], axis=-1)


def loop_mission(count: int, via_points: int = 1, alpha: float = 0.5) -> Mission:
    """A mission of ``count`` way points round the circle (module docstring), ``via_points`` per travel.

    Args:
        count: number of way points, >= 2.
        via_points: n_vp of every travel, >= 0.
        alpha: the energy weight of the objective (3.26).

    Raises:
        MissionError: count < 2, a negative via_points or alpha outside [0, 1] (the mission's own checks).
    """
    points = loop_way_points(int(count)) if int(count) >= 1 else np.zeros((0, 4))
    chords = np.linalg.norm(np.diff(points[:, :2], axis=0), axis=1)
    return Mission(name=f"loop-{int(count)}", robot="fpr", way_points=points,
                   times=np.round(SECONDS_PER_METRE * chords, 12), via_points=via_points, alpha=alpha,
                   description=f"{int(count)} way points round a 0.5 m circle, {via_points} via points a "
                               "travel (fpr.bench.missions)",
                   source="fpr.bench.missions")
