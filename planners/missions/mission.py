"""Missions: the user's input of the motion planner (way points, travel times, via points, weights).

A :class:`Mission` says *where* the robot must pass (way points, seed 3.2.1), *when* (the travel
time of each way-to-way travel), how many free via points the optimiser may place inside each
travel (n_vp, seed 3.2.4) and how it weighs energy against drone perturbation (alpha, seed 3.25).
It is validated when it is built: every error is a :class:`fpr.model.errors.MissionError` naming the
offending field as it is written in the file (``times[2]``, ``way_points[1]``...). Whether the way
points are reachable is a property of the robot as well; :meth:`Mission.positions` checks it and
raises :class:`fpr.model.errors.WorkspaceError` / :class:`fpr.model.errors.SingularityError`.

Missions are written in TOML files; the built-in ones (:data:`BUILTIN_MISSIONS`) live in
``planners/missions/`` and are meant to be copied and edited. Load one with :func:`load_mission`
(a built-in name or a path).

File format (every key at the top level, except the optional ``[robot_parameters]`` table):

``name`` (string, optional)
    The mission's name, used in messages and file names. Default: the file name without ``.toml``.
``description`` (string, optional)
    Free text. Default ``""``.
``robot`` (string, required)
    A registered robot (:mod:`fpr.robots`): ``"fpr"`` (two drones and the end-effector) or
    ``"prototype"`` (one drone, chain pinned at the origin), or one you registered.
``space`` (string, optional)
    In which coordinates the way points are written. Default ``"task"``.

    * FPR: task and joint space are the same, s = [y, z, phi, q21] [m, m, rad, rad]: the
      end-effector position p = (y, z), the absolute angle phi of link 1 (from the drone joint r1
      to p: r1 = p - L u(phi)) and the angle q21 between the links (DESIGN.md conventions).
    * prototype, ``"task"``: the drone joint position [y, z] [m] in the vertical plane, fixed point
      at the origin; the planner converts it to xi with the assembly mode ``arm``.
    * prototype, ``"joint"``: xi = [q1, q2] [rad], joint 2 = L u(q1), drone joint = L u(q1) + L u(q1 + q2).

    In general: ``"joint"`` is the robot's planning coordinates, ``"task"`` its ``task_coordinates``
    (the robot kind converts them, ``kind.planning_pose``).
``arm`` (string, optional)
    Assembly mode of the prototype: ``"down"`` (q2 > 0, the elbow below the line fixed point ->
    drone) or ``"up"`` (q2 < 0). Default ``"down"``. Must be one of the two for the FPR too, where
    it is ignored (a robot without ``assembly_modes``).
``way_points`` (array of arrays of numbers, required)
    k >= 2 way points, each with 4 numbers (FPR) or 2 (prototype), in the coordinates of ``space``.
    The robot starts at rest at the first and stops at rest at the last.
``times`` (array of numbers, required)
    k - 1 travel times [s], finite and > 0: ``times[i]`` is the time from way point i to i + 1.
``via_points`` (integer or array of integers, optional)
    0 <= n_vp <= 1000, the number of via points the optimiser places inside each travel; one integer is
    used for every travel, an array gives one per travel (k - 1 entries). Default 1.
``alpha`` (number, optional)
    Weight in [0, 1] of the energy term of the objective (seed 3.25)
    J = alpha Je / Je0 + (1 - alpha) Jphi / Jphi0: 1 minimises the energy only, 0 the drone
    perturbation (roll rates) only. Default 0.5.
``cross_singularity`` (boolean, optional)
    Prototype only (a robot whose kind ``crosses_singularity``): ``true`` asks for a motion that
    crosses the Type-2 singularity q2 = 0 exactly once (seed ch. 4, :mod:`planners.crossing.solve`). The
    mission then has 2 way points, the start in the assembly mode ``arm`` and the end in the other one, and
    2 travel times and via-point counts: start -> crossing and crossing -> end (the times are first guesses;
    the planner optimises them with the crossing state). Default ``false``.
``[robot_parameters]`` (table of numbers, optional)
    Overrides of the robot description's xacro arguments (keys of ``urdf/parameters.yaml`` that
    the URDF uses, e.g. ``link_length``), passed to ``fpr.load(robot, **robot_parameters)``.
    Default: none (the committed URDF).
``[[events]]`` (array of tables, optional)
    What happens during the flight: a way point that moves (``kind = "move"``), a gust
    (``kind = "gust"``); every key is documented in :mod:`planners.missions.events`. Default: none.

Full example (the built-in ``square`` mission, with a longer link)::

    description = "FPR square, seed 3.2.6"
    robot = "fpr"
    space = "task"
    arm = "down"
    way_points = [
        [0.0, 0.0, 3.9269908169872414, 1.5707963267948966],
        [1.0, 0.0, 3.9269908169872414, 1.5707963267948966],
        [1.0, 1.0, 3.9269908169872414, 1.5707963267948966],
        [0.0, 1.0, 3.9269908169872414, 1.5707963267948966],
        [0.0, 0.0, 3.9269908169872414, 1.5707963267948966],
    ]
    times = [3.0, 3.0, 3.0, 3.0]
    via_points = 1
    alpha = 0.5

    [robot_parameters]
    link_length = 1.0

In Python::

    from planners.missions.mission import load_mission
    mission = load_mission("square").replace(alpha=0.3, via_points=2)
    robot = mission.load_robot()
    s = mission.positions(robot)   # (k, 4) FPR s, or (k, 2) prototype xi, margins checked
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib.resources
import logging
import numbers
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from fpr import robots
from fpr.model import description
from fpr.model.errors import MissionError, ModelArgumentError
from fpr.model.parameters import check_parameters
from planners.missions import BUILTIN_MISSIONS
from planners.missions.events import events_toml, parse_events
from planners.missions.files import MAX_FILE_BYTES, parse_toml, read_mission_text

logger = logging.getLogger(__name__)

SPACES = ("task", "joint")
ARMS = ("down", "up")

MAX_VIA_POINTS = 1000
"""Most via points in one travel (``python -m fpr.plan`` optimises at most 64 polynomial segments in all)."""

_REQUIRED_KEYS = ("robot", "way_points", "times")
_FILE_KEYS = ("name", "description", "robot", "space", "arm", "way_points", "times", "via_points", "alpha",
              "cross_singularity", "robot_parameters", "events")


def _is_number(x) -> bool:
    """True for int and float scalars (numpy's too), False for bool and anything else."""
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_))


def _is_integer(x) -> bool:
    """True for int scalars (numpy's too), False for bool, float and anything else."""
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))


def _is_sequence(x) -> bool:
    return isinstance(x, (list, tuple)) or (isinstance(x, np.ndarray) and x.ndim >= 1)


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Mission:
    """A motion-planning task: way points, travel times, via points and objective weight.

    Built and validated from keyword arguments or from a file (:func:`load_mission`); the arrays
    are stored read-only. Two missions are equal when every field but ``source`` is equal.

    Attributes:
        name: the mission's name.
        robot: a registered robot name (:func:`fpr.robots.names`), e.g. "fpr" or "prototype".
        way_points: shape (k, n), k >= 2, in the coordinates of ``space``: FPR n = 4,
            s = [y z phi q21] [m, m, rad, rad]; prototype n = 2, task [y z] of the drone joint [m]
            or joint xi = [q1 q2] [rad].
        times: shape (k - 1,), travel time from way point i to i + 1 [s], finite and > 0.
        via_points: shape (k - 1,), int >= 0, number n_vp of via points inside each travel
            (a single integer is broadcast; default 1).
        alpha: weight of the energy term in J = alpha Je/Je0 + (1 - alpha) Jphi/Jphi0, in [0, 1].
        space: "task" or "joint", the coordinates of ``way_points``.
        arm: prototype assembly mode, "down" (q2 > 0) or "up" (q2 < 0); ignored for the FPR.
        description: free text.
        robot_parameters: xacro overrides for ``fpr.load(robot, **robot_parameters)``, e.g.
            ``{"link_length": 1.0}`` [SI units]; stored as a read-only mapping.
        events: what happens in flight, a tuple of :class:`planners.missions.events.MoveEvent` /
            :class:`planners.missions.events.GustEvent` sorted by time (:mod:`planners.missions.events`).
        source: where the mission came from (file path or ``"built-in <name>"``), for messages.

    Raises:
        MissionError: on construction, for any missing, malformed or inconsistent field.
    """

    name: str
    robot: str
    way_points: np.ndarray
    times: np.ndarray
    via_points: np.ndarray = 1  # type: ignore[assignment]  (broadcast to an array)
    alpha: float = 0.5
    space: str = "task"
    arm: str = "down"
    description: str = ""
    robot_parameters: Mapping[str, float] = field(default_factory=dict)
    cross_singularity: bool = False
    events: tuple = ()
    source: str = ""

    # ------------------------------------------------------------------ validation
    def __post_init__(self):
        self._set("source", str(self.source))
        self._set("name", self._text("name", self.name, allow_empty=False))
        self._set("description", self._text("description", self.description))
        self._set("robot", self._choice("robot", self.robot, robots.names(), "the robot to plan for"))
        self._set("space", self._choice("space", self.space, SPACES, "the coordinates of way_points"))
        self._set("arm", self._choice("arm", self.arm, ARMS, "the prototype's assembly mode, down: q2 > 0"))
        way_points = self._way_points(self.way_points)
        self._set("way_points", way_points)
        k = way_points.shape[0]
        self._set("cross_singularity", self._crossing(self.cross_singularity, k))
        travels = k if self.cross_singularity else k - 1
        self._set("times", self._times(self.times, k, travels))
        self._set("via_points", self._via_points(self.via_points, k, travels))
        self._set("alpha", self._alpha(self.alpha))
        self._set("robot_parameters", self._robot_parameters(self.robot_parameters))
        self._check_arm_signs()
        self._set("events", parse_events(self.events, self))  # [[events]]: planners/missions/events.py

    def _set(self, name: str, value) -> None:
        object.__setattr__(self, name, value)

    def _error(self, field_name: str, reason: str) -> MissionError:
        return MissionError(field_name, reason, self.source)

    def _text(self, field_name: str, value, allow_empty: bool = True) -> str:
        if not isinstance(value, str):
            raise self._error(field_name, f"{_short(value)} is a {type(value).__name__}: write a string in quotes")
        if not allow_empty and not value.strip():
            raise self._error(field_name, "is empty: give the mission a name")
        return value

    def _choice(self, field_name: str, value, choices: tuple[str, ...], meaning: str) -> str:
        if not isinstance(value, str) or value not in choices:
            raise self._error(field_name, f"{_short(value)} is not known ({meaning}): use one of "
                                          f"{', '.join(map(repr, choices))}")
        return value

    @property
    def kind(self):
        """The robot kind (class) of ``robot``, from the registry (:func:`fpr.robots.get`)."""
        return robots.get(self.robot)

    def _way_points(self, value) -> np.ndarray:
        coords = self.kind.mission_coordinates(self.space)
        n, listed = len(coords), ", ".join(coords)
        shape_hint = f"a list of way points, each a list of {n} numbers [{listed}]"
        if not _is_sequence(value):
            raise self._error("way_points", f"{_short(value)} is not a list: give {shape_hint}")
        rows = list(value)
        if len(rows) < 2:
            reason = f"{len(rows)} way point(s): give at least 2 (a start and an end), as {shape_hint}"
            raise self._error("way_points", reason)
        for i, row in enumerate(rows):
            name = f"way_points[{i}]"
            if not _is_sequence(row) or np.ndim(row) != 1:
                raise self._error(name, f"{_short(row)} is not a list of numbers: give {n} numbers [{listed}]")
            if len(row) != n:
                reason = f"has {len(row)} entries; a {self.robot} way point in {self.space} space has {n}: " \
                         f"[{listed}]"
                raise self._error(name, reason)
            for j, x in enumerate(row):
                if not _is_number(x):
                    raise self._error(name, f"entry {j} ({coords[j]}) is {_short(x)}, not a number")
                if not np.isfinite(x):
                    raise self._error(name, f"entry {j} ({coords[j]}) is {x}: give a finite number")
        return _read_only(np.array([[float(x) for x in row] for row in rows], dtype=float))

    def _crossing(self, value, k: int) -> bool:
        if not isinstance(value, (bool, np.bool_)):
            raise self._error("cross_singularity", f"{_short(value)}: write true or false")
        if value and (not self.kind.crosses_singularity or k != 2):
            able = [name for name in robots.names() if robots.get(name).crosses_singularity]
            reason = (f"true needs a robot that can cross its singularity ({', '.join(map(repr, able))}) and "
                      "exactly 2 way points (the start, in the assembly mode `arm`, and the end, in the other "
                      f"one); this mission has robot = {self.robot!r} and {k} way points")
            raise self._error("cross_singularity", reason)
        return bool(value)

    def _travels_text(self, k: int, travels: int) -> str:
        if self.cross_singularity:
            return "a singularity crossing has 2 travels (start -> crossing -> end)"
        return f"{k} way points make {travels} travel{'' if travels == 1 else 's'}"

    def _times(self, value, k: int, travels: int) -> np.ndarray:
        count = f"{self._travels_text(k, travels)}: give {travels} travel time(s) [s]"
        if not _is_sequence(value) or np.ndim(value) != 1:
            raise self._error("times", f"{_short(value)} is not a list: {count}, "
                                       f"e.g. times = {_short([3.0] * travels)}")
        if len(value) != travels:
            raise self._error("times", f"has {len(value)} entries; {count}, one per travel")
        for i, t in enumerate(value):
            if not _is_number(t):
                raise self._error(f"times[{i}]", f"{_short(t)} is not a number: give a travel time in seconds")
            if not (np.isfinite(t) and t > 0):
                raise self._error(f"times[{i}]", f"{t} s: a travel time must be finite and > 0 [s]")
        return _read_only(np.array([float(t) for t in value], dtype=float))

    def _via_points(self, value, k: int, travels: int) -> np.ndarray:
        if not _is_sequence(value):
            self._check_via_point("via_points", value)
            return _read_only(np.full(travels, int(value), dtype=int))
        if np.ndim(value) != 1 or len(value) != travels:
            reason = (f"has {len(value)} entries; {self._travels_text(k, travels)}: give one integer "
                      "per travel, or a single integer for all of them")
            raise self._error("via_points", reason)
        for i, n_vp in enumerate(value):
            self._check_via_point(f"via_points[{i}]", n_vp)
        return _read_only(np.array([int(n_vp) for n_vp in value], dtype=int))

    def _check_via_point(self, field_name: str, value) -> None:
        if not _is_integer(value):
            reason = (f"{_short(value)} is not an integer: give the number of via points of a travel as an integer "
                      ">= 0 (e.g. 1, not 1.0)")
            raise self._error(field_name, reason)
        if value < 0:
            raise self._error(field_name, f"{value}: the number of via points must be >= 0")
        if value > MAX_VIA_POINTS:
            raise self._error(field_name, f"{_short(value)}: give at most {MAX_VIA_POINTS} via points a travel (no "
                                          "planner optimises more)")

    def _alpha(self, value) -> float:
        if not _is_number(value) or not np.isfinite(value) or not 0.0 <= value <= 1.0:
            reason = f"{_short(value)}: give a number in [0, 1] (1: energy only, 0: drone perturbation only)"
            raise self._error("alpha", reason)
        return float(value)

    def _robot_parameters(self, value) -> Mapping[str, float]:
        if not isinstance(value, Mapping):
            reason = f"{_short(value)} is not a table: write [robot_parameters] then lines like link_length = 1.0"
            raise self._error("robot_parameters", reason)
        known = description.xacro_arguments(self.kind.xacro)
        checked = {}
        for key, x in value.items():
            name = f"robot_parameters.{key}"
            if key not in known:
                reason = (f"unknown robot parameter{_did_you_mean(key, known)}: use some of "
                          f"{', '.join(known)} (rotor constants, margins: edit urdf/parameters.yaml instead)")
                raise self._error(name, reason)
            if not _is_number(x) or not np.isfinite(x) or x < 0 or (key == "link_length" and x == 0):
                raise self._error(name, f"{_short(x)}: give a finite number >= 0 (> 0 for link_length) [SI units]")
            try:
                check_parameters({key: float(x)}, {})
            except ModelArgumentError as error:
                raise self._error(name, error.reason) from None
            checked[key] = float(x)
        return MappingProxyType(checked)

    def _check_arm_signs(self) -> None:
        """Joint space: each way point must be in the assembly mode ``arm_of`` it (a pose on a mode's
        border, such as the prototype's q2 = 0, is left to the singularity check).
        """
        kind = self.kind
        if not kind.assembly_modes or self.space != "joint":
            return
        k = self.way_points.shape[0]
        expected = [self.arm_of(i) for i in range(k)]
        actual = [kind.assembly_mode(point) for point in self.way_points]
        wrong = [i for i in range(k) if actual[i] is not None and actual[i] != expected[i]]
        if not wrong:
            return
        i = wrong[0]
        where = f"{_text_of(self.way_points[i])} is in the assembly mode {kind.describe_mode(actual[i])}"
        if self.cross_singularity:
            reason = (f"{where}: a singularity crossing starts in the mode `arm` = {self.arm!r} and ends in the "
                      f"other, so this way point needs the mode {kind.describe_mode(expected[i])}")
            raise self._error(f"way_points[{i}]", reason)
        if len(wrong) == k and len(set(actual)) == 1:
            reason = (f"{self.arm!r}, but every way point is in the assembly mode {kind.describe_mode(actual[0])}: "
                      f"set arm = {actual[0]!r} or change the way points")
            raise self._error("arm", reason)
        reason = (f"{where}, arm = {self.arm!r}: change the way point (the assembly mode cannot change at a way "
                  "point; the modes meet at a singularity)")
        raise self._error(f"way_points[{i}]", reason)

    # ------------------------------------------------------------------ comparisons and copies
    def __eq__(self, other) -> bool:
        if not isinstance(other, Mission):
            return NotImplemented
        return all(_field_equal(getattr(self, f.name), getattr(other, f.name))
                   for f in dataclasses.fields(self) if f.name != "source")

    __hash__ = None  # type: ignore[assignment]  (holds arrays)

    def replace(self, **changes) -> Mission:
        """A validated copy with some fields changed, e.g. ``replace(alpha=0.3, via_points=2)``.

        A scalar ``via_points`` is broadcast to every travel. When ``way_points`` change (and with
        them the number of travels) and ``via_points`` is not given, a uniform ``via_points`` stays
        uniform; ``times`` must then be given too.

        Raises:
            MissionError: an unknown field, or a changed value that is not valid.
        """
        names = [f.name for f in dataclasses.fields(self)]
        for key in changes:
            if key not in names:
                reason = f"not a mission field{_did_you_mean(key, names)}: use some of {', '.join(names)}"
                raise self._error(key, reason)
        if "way_points" in changes and "via_points" not in changes and np.unique(self.via_points).size == 1:
            changes["via_points"] = int(self.via_points[0])
        return dataclasses.replace(self, **changes)

    # ------------------------------------------------------------------ derived quantities
    @property
    def n_way_points(self) -> int:
        """k, the number of way points."""
        return int(self.way_points.shape[0])

    @property
    def duration(self) -> float:
        """Total time of the mission, sum of ``times`` [s]."""
        return float(np.sum(self.times))

    def load_robot(self):
        """The robot to plan for: ``fpr.load(robot, **robot_parameters)`` (a :class:`fpr.model.robot.Robot`).

        Raises:
            MissionError: a robot parameter that the description does not accept, or out of its physical
                range (:func:`fpr.robots.check_parameters`) (field ``robot_parameters.<key>``).
        """
        try:
            return robots.load(self.robot, **self.robot_parameters)
        except (ValueError, TypeError) as error:
            known = description.xacro_arguments(self.kind.xacro)
            bad = next((k for k in self.robot_parameters if k not in known), getattr(error, "argument", None))
            if bad not in self.robot_parameters:
                raise
            raise self._error(f"robot_parameters.{bad}", f"rejected by fpr.load: {error}") from error

    def positions(self, robot=None) -> np.ndarray:
        """The way points in planning coordinates, each checked against the workspace margins.

        Args:
            robot: the :class:`fpr.model.robot.Robot` to plan for (its ``kind`` converts and checks the
                way points); default :meth:`load_robot`.

        Returns:
            shape (k, n_s), the robot's planning coordinates: FPR s = [y z phi q21] [m, m, rad, rad]
            (both spaces), prototype xi = [q1 q2] [rad] (task-space way points converted with the
            assembly mode ``arm``).

        Raises:
            MissionError: ``robot`` is not the mission's robot, or was built with another link length.
            WorkspaceError: a way point out of reach or violating a geometric margin (ground,
                fixed point, link angles); the message names the way point and the bound.
            SingularityError: a way point closer than m_ga to a Type-2 singularity.
        """
        robot = robot if robot is not None else self.load_robot()
        self._check_robot(robot)
        poses = []
        for i, point in enumerate(self.way_points):
            pose = self._planning_pose(i, point, robot)
            self._check_way_point(i, point, pose, robot)
            poses.append(pose)
        return np.array(poses, dtype=float)

    def _check_robot(self, robot) -> None:
        if robot.name != self.robot:
            reason = f"the mission is for the {self.robot!r} but a {robot.name!r} model was given: use " \
                     "mission.load_robot()"
            raise self._error("robot", reason)
        wanted = self.robot_parameters.get("link_length")
        if wanted is not None and not np.isclose(robot.link_length, wanted, rtol=1e-12, atol=0.0):
            raise self._error("robot_parameters.link_length",
                              f"{wanted} m, but the robot given has L = {robot.link_length} m: build it with "
                              "mission.load_robot()")

    def _where(self, i: int, point: np.ndarray) -> str:
        return f"way_points[{i}] = {_text_of(point)} of mission {self.name!r}"

    def arm_of(self, i: int) -> str:
        """Assembly mode of way point i: ``arm``, except the end of a singularity crossing."""
        if self.cross_singularity and i == self.way_points.shape[0] - 1:
            return "up" if self.arm == "down" else "down"
        return self.arm

    def _planning_pose(self, i: int, point: np.ndarray, robot) -> np.ndarray:
        return robot.kind.planning_pose(point, self.space, self._mode_of(i), self._where(i, point))

    def _mode_of(self, i: int) -> str | None:
        """The assembly mode of way point i for the robot kind (None: the robot has no modes to keep)."""
        return self.arm_of(i) if self.kind.assembly_modes else None

    def _check_way_point(self, i: int, point: np.ndarray, pose: np.ndarray, robot) -> None:
        names = ", ".join(robot.layout.chain)
        what = self._where(i, point) + ("" if np.array_equal(point, pose) else f" ({names} = {_text_of(pose)})")
        robot.kind.check_pose(pose, self._mode_of(i), what)

    # ------------------------------------------------------------------ output
    def to_dict(self) -> dict[str, Any]:
        """The mission as plain Python types (lists, floats, ints, str), ready for JSON or TOML.

        ``source`` is left out: it is where the mission was read from, not part of it, and
        ``mission_from_dict(m.to_dict()) == m``.
        """
        return {
            "name": self.name,
            "description": self.description,
            "robot": self.robot,
            "space": self.space,
            "arm": self.arm,
            "way_points": self.way_points.tolist(),
            "times": self.times.tolist(),
            "via_points": [int(n) for n in self.via_points],
            "alpha": float(self.alpha),
            "cross_singularity": bool(self.cross_singularity),
            "robot_parameters": dict(self.robot_parameters),
            **({"events": [e.to_dict() for e in self.events]} if self.events else {}),
        }

    def to_toml(self) -> str:
        """The mission as a TOML document that :func:`mission_from_toml` reads back equal.

        Floats are written with ``repr`` (shortest text that reads back to the same double).
        """
        d = self.to_dict()
        rows = "".join(f"    {_toml_value(row)},\n" for row in d["way_points"])
        lines = [
            "# Mission written by planners.missions.mission.Mission.to_toml (format: see planners/missions/mission.py)",
            f"name = {_toml_value(d['name'])}",
            f"description = {_toml_value(d['description'])}",
            f"robot = {_toml_value(d['robot'])}  # {' or '.join(_toml_value(n) for n in robots.names())}",
            f"space = {_toml_value(d['space'])}  # coordinates of way_points: \"task\" or \"joint\"",
            f"arm = {_toml_value(d['arm'])}  # prototype assembly mode: \"down\" (q2 > 0) or \"up\" (q2 < 0)",
            f"# {', '.join(self.kind.mission_coordinates(self.space))} per way point",
            f"way_points = [\n{rows}]",
            f"times = {_toml_value(d['times'])}  # travel time of each way-to-way travel [s]",
            f"via_points = {_toml_value(d['via_points'])}  # via points inside each travel",
            f"alpha = {_toml_value(d['alpha'])}  # weight of the energy term, in [0, 1]",
            *(["cross_singularity = true  # prototype: cross q2 = 0 once (planners.crossing.solve)"]
              if d["cross_singularity"] else []),
            "",
            "[robot_parameters]  # overrides of urdf/parameters.yaml for the URDF [SI units]",
            *(f"{key} = {_toml_value(value)}" for key, value in d["robot_parameters"].items()),
        ]
        return "\n".join(lines) + "\n" + events_toml(self.events)


def _text_of(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{x:.6g}" for x in np.asarray(values, dtype=float).reshape(-1)) + "]"


def _short(value, limit: int = 80) -> str:
    """``repr(value)`` for a message, cut to ``limit`` characters (a list of 20,000 numbers is not echoed)."""
    text = repr(value.tolist() if isinstance(value, np.ndarray) else value)
    return text if len(text) <= limit else f"{text[:limit - 20]}... ({len(text)} characters)"


def _field_equal(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.shape(a) == np.shape(b) and bool(np.array_equal(a, b))
    return a == b


def _did_you_mean(key, known) -> str:
    close = difflib.get_close_matches(str(key), list(known), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


_TOML_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}


def _toml_value(value) -> str:
    """TOML text of a str, bool, int, finite float or list of them."""
    if isinstance(value, str):
        body = "".join(_TOML_ESCAPES.get(c, f"\\u{ord(c):04X}" if ord(c) < 0x20 or ord(c) == 0x7F else c)
                       for c in value)
        return f'"{body}"'
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write a {type(value).__name__} as TOML")


# ---------------------------------------------------------------------------------------- readers
def mission_from_dict(data: Mapping[str, Any], source: str = "", *,
                      default_name: str | None = None) -> Mission:
    """Build a :class:`Mission` from a dictionary with the keys of the file format.

    Args:
        data: the keys of the file format (module docstring); ``robot``, ``way_points`` and ``times``
            are required.
        source: where the data came from, for messages (file path).
        default_name: the name when ``data`` has none; default: the stem of ``source`` (file name
            without ``.toml``), else ``"unnamed"``.

    Raises:
        MissionError: unknown or missing keys, or invalid values.
    """
    source = str(source)
    if not isinstance(data, Mapping):
        raise MissionError("<toml>", f"expected a table of keys, got a {type(data).__name__}", source)
    for key in data:
        if key not in _FILE_KEYS:
            reason = f"unknown key{_did_you_mean(key, _FILE_KEYS)}: the keys of a mission are " \
                     f"{', '.join(_FILE_KEYS)}"
            raise MissionError(_short(str(key), 60).strip("'\""), reason, source)
    missing = [key for key in _REQUIRED_KEYS if key not in data]
    if missing:
        raise MissionError(missing[0], f"missing: a mission needs {', '.join(_REQUIRED_KEYS)} (missing: "
                                       f"{', '.join(missing)}); see the built-in missions "
                                       f"({', '.join(BUILTIN_MISSIONS)}) for examples", source)
    if default_name is None:
        default_name = Path(source).stem if source else "unnamed"
    values = dict(data)
    values.setdefault("name", default_name)
    return Mission(**values, source=source)


def mission_from_toml(text: str, source: str = "", *, default_name: str | None = None) -> Mission:
    """Build a :class:`Mission` from the text of a TOML mission file.

    Args:
        text: the TOML document (module docstring).
        source: where the text came from, for messages and the default name (file path).
        default_name: see :func:`mission_from_dict`.

    Raises:
        MissionError: a TOML syntax error (field ``"<toml>"``, the reason gives line and column),
            or any error of :func:`mission_from_dict`.
    """
    data = parse_toml(text, source)
    return mission_from_dict(data, source, default_name=default_name)


def builtin_mission_text(name: str) -> str:
    """The TOML text of a built-in mission (a starting point for your own file).

    Raises:
        MissionError: ``name`` is not in :data:`BUILTIN_MISSIONS`.
    """
    if name not in BUILTIN_MISSIONS:
        reason = f"no built-in mission {name!r}: use one of {', '.join(BUILTIN_MISSIONS)}"
        raise MissionError("<file>", reason, name)
    folder = importlib.resources.files(__package__ or "planners.missions")
    return folder.joinpath(f"{name}.toml").read_text(encoding="utf-8")


def load_mission(name_or_path: str | os.PathLike) -> Mission:
    """Load a built-in mission by name, or a mission file.

    Args:
        name_or_path: one of :data:`BUILTIN_MISSIONS` (e.g. ``"square"``), or the path of a
            ``.toml`` file (a built-in name wins over a file of the same name without suffix).

    Raises:
        MissionError: no such built-in mission or readable file (field ``"<file>"``, the message
            lists the built-in missions), a file larger than :data:`MAX_FILE_BYTES` or not UTF-8
            (:func:`read_mission_text`), or an invalid file.
    """
    if isinstance(name_or_path, str) and name_or_path in BUILTIN_MISSIONS:
        logger.debug("loading the built-in mission %s", name_or_path)
        return mission_from_toml(builtin_mission_text(name_or_path), f"built-in {name_or_path}",
                                 default_name=name_or_path)
    text = read_mission_text(name_or_path)
    logger.debug("loading the mission file %s", name_or_path)
    return mission_from_toml(text, str(name_or_path))


__all__ = [
    "ARMS",
    "BUILTIN_MISSIONS",
    "Mission",
    "SPACES",
    "builtin_mission_text",
    "MAX_FILE_BYTES",
    "load_mission",
    "mission_from_dict",
    "mission_from_toml",
    "read_mission_text",
]
