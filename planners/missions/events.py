"""Events of a mission: what happens while the robot flies (a way point that moves, a gust).

A mission file may list ``[[events]]`` tables (TOML array of tables), each with ``at`` and ``kind``:

``at`` (number, required)
    When it happens [s from the start of the motion], finite, >= 0 and before the end of the motion
    (the sum of ``times``).
``kind = "move"``: a way point moves; the robot learns it at ``at``.
    ``way_point`` (integer, required): the index of the way point that moves, 1..k-1 (the start cannot
    move, the robot is there), and the robot must not have reached it yet: ``at`` < its time (the sum
    of the travel times before it).
    ``to`` (array of numbers, required): the new way point, in the mission's ``space`` and coordinates
    (4 numbers for the FPR, 2 for the prototype), finite; it is checked against the workspace margins
    like the way points (:func:`moved_positions`).
``kind = "gust"``: an external force for a while.
    ``force`` (array of 3 numbers, required): [x, y, z] in world axes [N], finite, each at most
    :data:`MAX_FORCE` in size.
    ``duration`` (number, required): how long it pushes [s], finite and > 0; the force is constant
    from ``at`` to ``at + duration`` (a step on and off) unless ``rise`` is given.
    ``rise`` (number, optional, default 0): onset and decay time [s], finite, >= 0 and at most half the
    duration: the force grows from 0 to ``force`` over ``rise`` from ``at`` with the C2 ramp
    10u^3 - 15u^4 + 6u^5 (u = (t - at) / rise; within 4.4 % of the force of the aviation standard 1 - cosine
    discrete gust, and its rate and slope start and end at 0), holds, and falls back the same way over
    the last ``rise`` of ``duration``. 0: today's step (a blast the controller can only fight); > 0: a
    wind that builds up, which the controller's integral term and a replanner can follow.
    ``body`` (string, optional): where it pushes: ``"end_effector"`` (default; the robot kind's task
    point: the FPR's end-effector, the prototype's drone joint) or ``"drone_<i>"`` (the centre of mass
    of drone i, 1-based, i at most the robot's number of drones).

Events are validated when the mission is built (:class:`planners.missions.mission.Mission` calls
:func:`parse_events`); an error is a :class:`fpr.model.errors.MissionError` naming the field as
``events[i].<key>``. A simulation applies gusts always and ``move`` events only when it replans
(:mod:`fpr.sim.replanning`): without replanning the robot flies the plan made before the flight.

Example (the built-in ``moving-target``)::

    [[events]]
    at = 3.5
    kind = "move"
    way_point = 2
    to = [1.3, 0.8, 3.9269908169872414, 1.5707963267948966]
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from fpr.model.errors import MissionError

MAX_FORCE = 1000.0
"""Largest component of a gust's force [N]: about the drag of a 100 m/s wind (beyond any measured gust) on a
large multirotor (0.5 rho v^2 C_d A with rho = 1.2 kg/m^3, C_d A = 0.2 m^2: 1200 N). A larger force is no wind."""

#: The kinds of event and the keys each takes (besides ``at`` and ``kind``), required first.
EVENT_KEYS = {"move": (("way_point", "to"), ()), "gust": (("force", "duration"), ("body", "rise"))}
END_EFFECTOR = "end_effector"


@dataclass(frozen=True)
class MoveEvent:
    """Way point ``way_point`` moves to ``to`` (mission space) at time ``at`` [s]."""

    at: float
    way_point: int
    to: tuple

    kind = "move"

    def to_dict(self) -> dict:
        """Plain types, the keys of the file format."""
        return {"at": self.at, "kind": self.kind, "way_point": self.way_point, "to": list(self.to)}


@dataclass(frozen=True)
class GustEvent:
    """A force ``force`` [N] (world x, y, z) on ``body`` from ``at`` for ``duration`` [s].

    It is ramped on and off over ``rise`` [s] (0: a step; module docstring).
    """

    at: float
    force: tuple
    duration: float
    body: str = END_EFFECTOR
    rise: float = 0.0

    kind = "gust"

    def to_dict(self) -> dict:
        """Plain types, the keys of the file format."""
        out = {
            "at": self.at,
            "kind": self.kind,
            "force": list(self.force),
            "duration": self.duration,
            "body": self.body,
        }
        if self.rise > 0.0:  # a step (the default) is written as before
            out["rise"] = self.rise
        return out

    def active(self, t: float) -> bool:
        """The gust pushes at time t [s] (at <= t < at + duration)."""
        return self.at <= t < self.at + self.duration

    def strength(self, t) -> np.ndarray:
        """The share (0..1) of ``force`` that pushes at times t [s], and its two time derivatives.

        Returns:
            [share, d/dt [1/s], d2/dt2 [1/s^2]], shape (3,) + shape of t: the ramp of ``rise`` at both
            ends (a box for rise 0).
        """
        t = np.asarray(t, dtype=float)
        if self.rise <= 0.0:
            box = ((self.at <= t) & (t < self.at + self.duration)).astype(float)
            return np.stack([box, 0.0 * box, 0.0 * box])
        end = self.at + self.duration
        return smooth_ramp((t - self.at) / self.rise, self.rise) - smooth_ramp(
            (t - end) / self.rise + 1.0, self.rise
        )

    def drone_index(self) -> int | None:
        """0-based drone index of ``body``, or None for the end-effector."""
        return None if self.body == END_EFFECTOR else int(self.body.split("_")[1]) - 1


def smooth_ramp(u, rise: float) -> np.ndarray:
    """The C2 ramp 10u^3 - 15u^4 + 6u^5 of u = (t - t_0) / rise, u clipped to [0, 1].

    Returns:
        [value, d/dt [1/s], d2/dt2 [1/s^2]], shape (3,) + shape of u.
    """
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    value = u**3 * (10.0 + u * (-15.0 + 6.0 * u))
    rate = 30.0 * u**2 * (1.0 - u) ** 2 / rise
    curvature = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / rise**2
    return np.stack([value, rate, curvature])


def _number(x) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_))


def _finite_list(error, name: str, value, n: int, meaning: str, largest: float | None = None) -> tuple:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        shown = f"a list of {len(value)}" if isinstance(value, (list, tuple)) else _short(value)
        raise error(name, f"{shown}: give a list of {n} numbers ({meaning})")
    for j, x in enumerate(value):
        if not _number(x) or not np.isfinite(x):
            raise error(name, f"entry {j} is {_short(x)}: give {n} finite numbers ({meaning})")
        if largest is not None and abs(x) > largest:
            raise error(name, f"entry {j} is {x:g}: give numbers within +-{largest:g} ({meaning})")
    return tuple(float(x) for x in value)


def _short(value, limit: int = 60) -> str:
    """``repr(value)``, cut to ``limit`` characters."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def parse_events(value, mission) -> tuple:
    """The events of ``mission`` (its ``events`` field as read from the file), validated.

    Args:
        value: a list of tables (dicts) with the keys of the module docstring, or of events already
            built (:class:`MoveEvent`, :class:`GustEvent`), or empty.
        mission: the :class:`planners.missions.mission.Mission` being built (way points, times, space, robot).

    Returns:
        a tuple of events, sorted by ``at`` (stable: events at the same time keep their order).

    Raises:
        MissionError: a field named ``events[i].<key>`` that is missing, unknown or out of range.
    """

    def error(name: str, reason: str) -> MissionError:
        return MissionError(name, reason, mission.source)

    if value is None:
        return ()
    if not isinstance(value, (list, tuple)):
        raise error("events", f"{_short(value)}: write events as [[events]] tables (a list of tables)")
    k = mission.way_points.shape[0]
    ends = np.concatenate([[0.0], np.cumsum(mission.times)])
    coords = mission.kind.mission_coordinates(mission.space)
    events = []
    for i, item in enumerate(value):
        if isinstance(item, (MoveEvent, GustEvent)):
            item = item.to_dict()
        where = f"events[{i}]"
        if not isinstance(item, dict):
            raise error(where, f"{_short(item)}: each event is a table with at, kind and the kind's keys")
        kind = item.get("kind")
        if kind not in EVENT_KEYS:
            raise error(f"{where}.kind", f"{_short(kind)}: use one of {', '.join(map(repr, EVENT_KEYS))}")
        required, optional = EVENT_KEYS[kind]
        allowed = ("at", "kind", *required, *optional)
        for key in item:
            if key not in allowed:
                raise error(
                    f"{where}.{key}", f"unknown key for a {kind!r} event: its keys are {', '.join(allowed)}"
                )
        for key in ("at", *required):
            if key not in item:
                raise error(
                    f"{where}.{key}", f"missing: a {kind!r} event needs {', '.join(('at', *required))}"
                )
        at = item["at"]
        if not _number(at) or not (np.isfinite(at) and 0.0 <= at < ends[-1]):
            raise error(
                f"{where}.at", f"{_short(at)}: give a time [s] in [0, {ends[-1]:g}) (the motion's duration)"
            )
        at = float(at)
        if kind == "move":
            wp = item["way_point"]
            if not isinstance(wp, (int, np.integer)) or isinstance(wp, bool) or not 1 <= wp <= k - 1:
                raise error(
                    f"{where}.way_point",
                    f"{_short(wp)}: give the index of a way point, 1..{k - 1} (the start cannot move)",
                )
            if at >= ends[wp]:
                raise error(
                    f"{where}.at",
                    f"{at:g} s: way point {wp} is reached at {ends[wp]:g} s; a move must "
                    "happen before the robot gets there",
                )
            to = _finite_list(
                error,
                f"{where}.to",
                item["to"],
                len(coords),
                f"[{', '.join(coords)}] in {mission.space} space",
            )
            events.append(MoveEvent(at, int(wp), to))
        else:
            force = _finite_list(error, f"{where}.force", item["force"], 3,
                                 f"[x, y, z] in N, world axes; more than {MAX_FORCE:g} N is no wind", MAX_FORCE)
            duration = item["duration"]
            if not _number(duration) or not (np.isfinite(duration) and duration > 0):
                raise error(f"{where}.duration", f"{_short(duration)}: give a finite duration > 0 [s]")
            body = item.get("body", END_EFFECTOR)
            drones = len(mission.kind.layout.drones)
            names = ", ".join(f'"drone_{j}"' for j in range(1, drones + 1))
            if not isinstance(body, str) or not (body == END_EFFECTOR or _drone_name(body)):
                raise error(f"{where}.body", f'{_short(body)}: use "end_effector" or {names}')
            if body != END_EFFECTOR and int(body.split("_")[1]) > drones:
                raise error(f"{where}.body", f'{body!r}: the {mission.robot} robot has {drones} drone(s): use '
                                             f'"end_effector" or {names}')
            rise = item.get("rise", 0.0)
            if not _number(rise) or not (np.isfinite(rise) and 0.0 <= 2.0 * rise <= duration):
                raise error(
                    f"{where}.rise",
                    f"{_short(rise)}: give an onset time [s] >= 0 and at most half the duration ({duration:g} s)",
                )
            events.append(GustEvent(at, force, float(duration), body, float(rise)))
    return tuple(sorted(events, key=lambda e: e.at))


def _drone_name(body: str) -> bool:
    head, _, index = body.partition("_")
    return head == "drone" and index.isdigit() and int(index) >= 1


def _toml(value) -> str:
    """TOML text of an event's value: a float (repr), an int, a checked name (kind, body) or a list."""
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, str):
        return f'"{value}"'
    return repr(value)


def events_toml(events) -> str:
    """The ``[[events]]`` tables of ``events``, TOML text ("" for none)."""
    blocks = []
    for event in events:
        lines = ["", "[[events]]"] + [f"{key} = {_toml(v)}" for key, v in event.to_dict().items()]
        blocks.append("\n".join(lines))
    return "\n".join(blocks) + ("\n" if blocks else "")


def moved_positions(mission, robot, events=None) -> dict:
    """The new way points of the ``move`` events, in planning coordinates, each checked like a way point.

    Returns:
        {event index in ``mission.events``: planning pose (n_s,)}.

    Raises:
        WorkspaceError, SingularityError: a ``to`` out of reach or within a margin (the message names it).
    """
    out = {}
    for i, event in enumerate(mission.events if events is None else events):
        if event.kind != "move":
            continue
        point = np.array(event.to)
        mode = mission.arm_of(event.way_point) if mission.kind.assembly_modes else None
        what = f"events[{i}].to = [{', '.join(f'{x:.6g}' for x in event.to)}] of mission {mission.name!r}"
        pose = robot.kind.planning_pose(point, mission.space, mode, what)
        robot.kind.check_pose(pose, mode, what)
        out[i] = np.asarray(pose, dtype=float)
    return out


def gust_force(events, t: float, n_drones: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Forces of the gusts active at t [s]: (on the end-effector (3,), on the drones (n_d, 3)), or None."""
    tip, drones = None, None
    for event in events:
        if event.kind != "gust" or not event.active(t):
            continue
        force = float(event.strength(t)[0]) * np.array(event.force)
        index = event.drone_index()
        if index is None:
            tip = (np.zeros(3) if tip is None else tip) + force
        elif index < n_drones:
            drones = np.zeros((n_drones, 3)) if drones is None else drones
            drones[index] += force
    return tip, drones


__all__ = [
    "END_EFFECTOR",
    "EVENT_KEYS",
    "MAX_FORCE",
    "GustEvent",
    "MoveEvent",
    "events_toml",
    "gust_force",
    "moved_positions",
    "parse_events",
    "smooth_ramp",
]
