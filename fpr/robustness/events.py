"""Event families for campaigns: seeded random ``move`` events and random gusts of a mission.

A campaign that flies a family (:class:`fpr.robustness.spec.Campaign` ``events``) gives each run one event
drawn from the run's own generator (``SeedSequence(seed, spawn_key=(i, 2))``): the same run gets the same
event whatever the number of workers.

**Moves** (:class:`MoveFamily`): a way point that has not been reached moves while the robot flies.

* which: one of the way points after the start (1..k-1), uniformly;
* when: uniformly during the travel towards it, at least ``warning`` [s] before the robot gets there
  (from the previous way point's time, or from 0);
* where: the first two mission coordinates (the task point's y and z in task space: the FPR's
  end-effector, the prototype's drone joint) move by a distance uniform in ``distance`` [m] in a
  direction uniform on the circle, the other coordinates kept; a target out of the workspace (the
  margins of :meth:`fpr.robots.base.RobotKind.check_pose`) is drawn again: the target is within reach.

**Gusts** (:class:`GustFamily`): a force that blows for a while, not told to the controller or the replanner.

* strength uniform in ``force`` [N] (0 to 8 N by default), direction uniform in the plane (world y, z);
* rise (onset and decay) uniform in ``rise`` [s] (0: a step), duration uniform in ``duration`` [s]
  (at least twice the rise), start uniform in the motion (it may blow past the end);
* on the end-effector (the robot kind's task point) or on a drone, uniformly among those bodies.

:func:`fpr.robustness.holding.hold_verdict` says before the flight whether the robot can hold a gust at all
as a steady force within its rotor limits; a campaign counts the gusts it cannot hold apart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fpr.model.errors import CampaignError, FprError
from planners.missions.events import END_EFFECTOR, GustEvent, MoveEvent, moved_positions

FAMILIES = ("move", "gust")
"""The event families a campaign can fly."""


def _range(name: str, value, least: float = 0.0) -> tuple[float, float]:
    try:
        low, high = (float(v) for v in value)
    except (TypeError, ValueError):
        raise CampaignError(f"{name} = {value!r}", "give [low, high]") from None
    if not (math.isfinite(low) and math.isfinite(high) and least <= low <= high):
        raise CampaignError(f"{name} = {value!r}", f"give finite [low, high] with {least:g} <= low <= high")
    return low, high


@dataclass(frozen=True)
class MoveFamily:
    """Random ``move`` events of a mission (module docstring).

    Attributes:
        distance: [least, largest] displacement of the task point [m].
        warning: least time between the event and the robot's arrival at the way point [s].
        tries: targets drawn before giving up on a way point that has no room around it.
    """

    distance: tuple = (0.05, 0.3)
    warning: float = 1.0
    tries: int = 100

    def __post_init__(self):
        object.__setattr__(self, "distance", _range("distance", self.distance))
        if not (isinstance(self.warning, (int, float)) and math.isfinite(self.warning) and self.warning > 0):
            raise CampaignError(f"warning = {self.warning!r}", "give a time > 0 [s]")

    def draw(self, mission, robot, rng: np.random.Generator) -> MoveEvent:
        """One move event of ``mission`` (its robot ``robot``) from ``rng``.

        Raises:
            CampaignError: no way point has room for a move (every draw out of the workspace), or no travel
                is longer than ``warning``.
        """
        ends = np.concatenate([[0.0], np.cumsum(mission.times)])
        candidates = [j for j in range(1, mission.way_points.shape[0])
                      if ends[j] - self.warning > ends[j - 1]]
        if not candidates:
            raise CampaignError("move events", f"no travel of mission {mission.name!r} is longer than the "
                                               f"warning {self.warning:g} s: give a shorter warning")
        for _ in range(self.tries):
            j = int(candidates[int(rng.integers(len(candidates)))])
            at = float(rng.uniform(ends[j - 1], ends[j] - self.warning))
            radius = float(rng.uniform(*self.distance))
            angle = float(rng.uniform(0.0, 2.0 * math.pi))
            to = np.array(mission.way_points[j], dtype=float)
            to[:2] += radius * np.array([math.cos(angle), math.sin(angle)])
            event = MoveEvent(round(at, 6), j, tuple(float(v) for v in to))
            try:
                moved_positions(mission, robot, (event,))
            except FprError:  # out of the workspace or too near a singularity: within reach only
                continue
            return event
        raise CampaignError("move events", f"no target within reach found in {self.tries} draws around the "
                                           f"way points of mission {mission.name!r}: give a smaller distance")


@dataclass(frozen=True)
class GustFamily:
    """Random gusts (module docstring).

    Attributes:
        force: [least, largest] strength [N].
        rise: [least, largest] onset and decay time [s].
        duration: [least, largest] time it blows [s] (raised to twice the rise when shorter).
        bodies: "all" (the end-effector and every drone), "end_effector" or "drones".
    """

    force: tuple = (0.0, 8.0)
    rise: tuple = (0.0, 1.0)
    duration: tuple = (1.0, 6.0)
    bodies: str = "all"

    def __post_init__(self):
        for name in ("force", "rise", "duration"):
            object.__setattr__(self, name, _range(name, getattr(self, name)))
        if self.duration[1] <= 0:
            raise CampaignError(f"duration = {self.duration!r}", "give a duration > 0 [s]")
        if self.bodies not in ("all", END_EFFECTOR, "drones"):
            raise CampaignError(f"bodies = {self.bodies!r}", 'give "all", "end_effector" or "drones"')

    def draw(self, mission, robot, rng: np.random.Generator) -> GustEvent:
        """One gust during ``mission`` (its robot ``robot``) from ``rng``."""
        names = [END_EFFECTOR] if self.bodies != "drones" else []
        if self.bodies != END_EFFECTOR:
            names += [f"drone_{i + 1}" for i in range(robot.n_drones)]
        strength = float(rng.uniform(*self.force))
        angle = float(rng.uniform(0.0, 2.0 * math.pi))
        rise = float(rng.uniform(*self.rise))
        duration = max(float(rng.uniform(*self.duration)), 2.0 * rise, 1e-3)
        at = float(rng.uniform(0.0, mission.duration))
        body = names[int(rng.integers(len(names)))]
        force = (0.0, round(strength * math.cos(angle), 6), round(strength * math.sin(angle), 6))
        duration = round(duration, 6)
        # rounded, the rise stays within half the rounded duration (a rise of exactly half of it, rounded up,
        # would not: GustEvent refuses it)
        return GustEvent(round(at, 6), force, duration, body, min(round(rise, 6), math.floor(duration * 5e5) / 1e6))


def family(name: str, **options):
    """The family ``name`` (:data:`FAMILIES`) with its options.

    Raises:
        CampaignError: an unknown family or option.
    """
    kinds = {"move": MoveFamily, "gust": GustFamily}
    if name not in kinds:
        raise CampaignError(f"events = {name!r}", f"unknown event family: use {', '.join(FAMILIES)}")
    try:
        return kinds[name](**options)
    except TypeError as error:
        raise CampaignError(f"events = {name!r}", f"an option it does not take ({error})") from None


def event_generator(seed: int, index: int) -> np.random.Generator:
    """The generator of run ``index``'s event: ``SeedSequence(seed, spawn_key=(index, 2))``."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(index, 2)))


__all__ = ["FAMILIES", "GustFamily", "MoveFamily", "event_generator", "family"]
