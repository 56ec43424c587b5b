"""One run of a campaign: the plan flown with one draw of the perturbations, and what came of it.

:class:`Flight` is what every worker receives once: the planned motion (its polynomial trajectory) and the
robot it was planned for (name and parameters; each worker builds the robot itself, once per set of
parameters). :func:`fly` simulates run ``index`` (:func:`fpr.sim.closed_loop.simulate`) and returns its row
(:func:`outcome_row`): a run that raises is a row with its error, never an exception.

Outcomes of a row (the columns after the sampled values):

========================== ==================================================================================
``success``                no error, the robot not lost and, with a tracking tolerance, every planning
                           coordinate within it
``lost``                   the simulator's watch stopped the run (:mod:`fpr.sim.watch`)
``failure``                what happened and when (the watch's line), "" when not lost
``failure_time_s``         when [s] (NaN when not lost)
``error``                  ``Type: message`` of an exception the run raised (a sampled value out of its range,
                           a bug), "" otherwise; the outcome columns are then NaN
``max_error_<c>``          largest |measured - planned| of each planning coordinate [m or rad]
``least_clearance_m``      least height of a drone's centre of mass above the ground [m]
``saturated_ticks``        inner-loop ticks with a rotor at a bound of the allocation
``peak_rotor_speed_rad_s`` the plant's highest rotor speed [rad/s] (w_max = 900)
``simulated_s``            simulated time [s] (shorter than the plan when lost)
========================== ==================================================================================

A campaign of an event family (:mod:`fpr.robustness.events`; :class:`EventSetup`) flies each run with its own
event (:func:`fly_event`), with the replanner when asked (``--replan``: the moves need it; a gust is not told to
it, which estimates the wind from the controller's observer), and adds the event and what came of it
(:data:`MOVE_COLUMNS`, :data:`GUST_COLUMNS`): for a move, how close the robot passed to the moved way point and,
for a miss, why; for a gust, whether it could be held at all (:mod:`fpr.robustness.holding`: at the poses of the
plan while it blows, or at the mission's way points with ``--replan``), the physical
limits broken and the share of saturated ticks; with ``without_observer`` the same run flown by the
controller without its observer, its outcomes beside (``no_observer_*``). A run's replans' wall times are
kept in its stored row (``replan_wall_s``, ``replan_cpu_s``: for the latency distribution of the summary), not
in the table.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from fpr.robots import load
from fpr.robustness.events import event_generator
from fpr.robustness.holding import hold_check
from fpr.robustness.spec import INITIAL_ERROR, SETTINGS
from fpr.sim.closed_loop import SimulationSettings, simulate
from fpr.sim.margins import broken, closed_loop_margins
from fpr.sim.plant import PlantDivergedError
from fpr.sim.replanning import InFlight, TriggerSettings
from planners.problem.disturbance import evaluate_in_gusts
from planners.replanning.replanner import Replanner, ReplanOptions

OUTCOMES = ("success", "lost", "failure", "failure_time_s", "error", "least_clearance_m", "saturated_ticks",
            "peak_rotor_speed_rad_s", "simulated_s")
"""Outcome columns every row has (``max_error_<coordinate>`` columns come after them)."""
MOVE_COLUMNS = ("event_way_point", "event_at_s", "event_lead_s", "event_distance_m", "pass_distance_m", "replans",
                "replans_used", "splice_delay_s", "executed_violates", "broken", "miss")
"""Columns of a move event's run: the way point, when it moved, how long before the robot got there [s], how
far [m]; how close the robot passed [m], the replans (and those used), the largest delay of a splice past
its deadline [s], the constraints the executed plan (the plan in force at each instant, checked on the
dense grid at 500 Hz) violates ("" when none), the physical limits the closed loop broke, and for a miss
why ("" when it passed)."""
GUST_COLUMNS = ("gust_body", "gust_at_s", "gust_duration_s", "gust_rise_s", "gust_force_n", "gust_force_y_n",
                "gust_force_z_n", "holdable", "hold_margin_rad_s", "replans", "broken", "saturated_share", "miss")
"""Columns of a gust's run: the gust; whether it can be held as a steady force within the rotor limits and with
what least margin [rad/s] (:func:`fpr.robustness.holding.hold_check`, before the flight); the replans, the
physical limits broken, the share of saturated ticks, and for a failure why."""
NO_OBSERVER_COLUMNS = ("no_observer_success", "no_observer_lost", "no_observer_broken",
                       "no_observer_saturated_share", "no_observer_worst_error", "no_observer_pass_distance_m")
"""The same run flown by the controller without its observer (``without_observer``)."""


@dataclass(frozen=True)
class EventSetup:
    """How the runs of an event family fly (:class:`fpr.robustness.spec.Campaign`).

    Attributes:
        family: ``"move"`` or ``"gust"`` (:data:`fpr.robustness.events.FAMILIES`).
        generator: the family's :class:`fpr.robustness.events.MoveFamily` or
            :class:`~fpr.robustness.events.GustFamily` (its options).
        seed: the campaign's seed: run i's event comes from :func:`fpr.robustness.events.event_generator`.
        replan: fly with the replanner (``python -m fpr.plan --replan``).
        latency: the replanner's :class:`planners.replanning.latency.LatencyModel` (resolved once for the
            campaign, so that every worker decides alike).
        without_observer: also fly each run with the controller without its observer.
        pass_tolerance: a move's run succeeds when the robot passes within this of the moved way point [m].
        max_saturation: a gust's run succeeds with at most this share of its ticks saturated.
    """

    family: str
    generator: object = None
    seed: int = 0
    replan: bool = False
    latency: object = None
    without_observer: bool = False
    pass_tolerance: float = 0.02
    max_saturation: float = 0.01

    def event(self, mission, robot, index: int):
        """Run ``index``'s event of ``mission`` (its robot ``robot``)."""
        return self.generator.draw(mission, robot, event_generator(self.seed, index))


@dataclass(frozen=True)
class Flight:
    """The plan shipped to the workers: small, picklable, the same for every run.

    Attributes:
        robot_name: the registered robot (``robot.name``).
        robot_parameters: the robot's parameters the plan was made with (xacro overrides).
        chain: the planning coordinates (``robot.layout.chain``), for the tracking columns.
        trajectory: the planned motion (:class:`planners.trajectory.polynomial.PiecewisePolynomial`).
        hold: time simulated after the plan's end [s].
        tracking_tolerance: see :class:`fpr.robustness.spec.Campaign`.
        mission: the mission as planned (an event family adds each run's event to it), or None.
        constraints: the plan's constraints (``report.constraints``: the closed loop's physical limits), or None.
        setup: the :class:`EventSetup` of an event family, or None.
    """

    robot_name: str
    robot_parameters: tuple
    chain: tuple
    trajectory: object
    hold: float
    tracking_tolerance: float | None = None
    mission: object = None
    constraints: object = None
    setup: EventSetup | None = None

    @property
    def columns(self) -> tuple[str, ...]:
        """The outcome columns of a row, in order."""
        out = OUTCOMES + tuple(f"max_error_{c}" for c in self.chain)
        if self.setup is not None:
            out += MOVE_COLUMNS if self.setup.family == "move" else GUST_COLUMNS
            out += NO_OBSERVER_COLUMNS if self.setup.without_observer else ()
        return out


@dataclass(frozen=True)
class _Plan:
    """What :func:`fpr.sim.closed_loop.simulate` (and with events the replanner and the margins) ask of a
    plan.
    """

    robot: object
    trajectory: object
    mission: object = None
    report: object = None
    crossing: object = None


@functools.lru_cache(maxsize=8)
def _robot(name: str, parameters: tuple):
    return load(name, **dict(parameters))


def settings_of(flight: Flight, values: dict, noise_seed: int) -> tuple[SimulationSettings, dict]:
    """The simulation settings of one run and the robot parameters it changes (from its sampled ``values``)."""
    fields = {"hold": flight.hold, "seed": noise_seed}
    wind, noise, initial, parameters = [0.0, 0.0, 0.0], [0.0, 0.0], {}, {}
    for name, value in values.items():
        if name in ("model_mass_scale", "rotor_constant_scale"):
            fields[name] = value
        elif name.startswith("wind_"):
            wind["xyz".index(name[-1])] = value
        elif name.startswith("noise_"):
            noise["qv".index(name[-1])] = value
        elif name.startswith(INITIAL_ERROR):
            initial[name[len(INITIAL_ERROR):]] = value
        elif name not in SETTINGS:
            parameters[name] = value
    return SimulationSettings(initial_error=initial, measurement_noise=tuple(noise), wind=tuple(wind),
                              **fields), parameters


def outcome_row(flight: Flight, log, ground: float) -> dict:
    """The outcomes of a simulation log (see the module docstring); ``ground``: the ground's height [m]."""
    error = np.abs(log.tracking_error)
    lost = log.failure is not None
    row = {
        "lost": lost,
        "failure": log.failure or "",
        "failure_time_s": math.nan if log.failure_time is None else float(log.failure_time),
        "error": "",
        "least_clearance_m": float(log.drone_height.min() - ground) if log.t.size else math.nan,
        "saturated_ticks": int(log.saturated.any(axis=(1, 2)).sum()),
        "peak_rotor_speed_rad_s": float(log.speed.max()) if log.t.size else math.nan,
        "simulated_s": float(log.t[-1] - log.t[0]) if log.t.size else 0.0,
    }
    for j, c in enumerate(flight.chain):
        row[f"max_error_{c}"] = float(error[:, j].max()) if log.t.size else math.nan
    worst = max((row[f"max_error_{c}"] for c in flight.chain), default=0.0)
    row["success"] = not lost and (flight.tracking_tolerance is None or worst <= flight.tracking_tolerance)
    return row


def error_row(flight: Flight, error: BaseException) -> dict:
    """The row of a run that raised ``error``: not a success, outcomes NaN, the error's type and message."""
    message = " ".join(str(error).split())
    row = {"success": False, "lost": False, "failure": "", "failure_time_s": math.nan,
           "error": f"{type(error).__name__}: {message}"[:500], "least_clearance_m": math.nan,
           "saturated_ticks": -1, "peak_rotor_speed_rad_s": math.nan, "simulated_s": 0.0}
    row.update({f"max_error_{c}": math.nan for c in flight.chain})
    if flight.setup is not None:
        row.update({c: None for c in flight.columns if c not in row})
        row["miss"] = f"error: {row['error']}"
    return row


def fly(flight: Flight, index: int, values: dict, noise_seed: int) -> dict:
    """Simulate run ``index`` with its sampled ``values`` (and its event in an event family's campaign:
    :meth:`EventSetup.event`); returns its row (index, values, outcomes).

    Never raises for the run's own sake (an ``Exception`` becomes the row's ``error``); an interruption or a
    dying process does propagate (the engine redoes the run).
    """
    row = {"index": int(index), **values}
    try:
        settings, changed = settings_of(flight, values, noise_seed)
        parameters = {**dict(flight.robot_parameters), **changed}
        robot = _robot(flight.robot_name, tuple(sorted(parameters.items())))
        if flight.setup is not None:
            row.update(fly_event(flight, robot, settings, flight.setup.event(flight.mission, robot, index)))
            return row
        log = simulate(_Plan(robot, flight.trajectory), settings)
        row.update(outcome_row(flight, log, float(robot.kind.ground_height)))
    except PlantDivergedError as error:  # diverged before a log could be made: lost at once
        row.update(error_row(flight, error), lost=True, error="", failure=" ".join(str(error).split()))
    except Exception as error:  # noqa: BLE001 - a failed run is a row with its error
        row.update(error_row(flight, error))
    return row


def _flown(flight: Flight, robot, settings: SimulationSettings, event, observer: bool):
    """One flight of ``event``: (log, the InFlight hooks, the plan) with the controller's observer or not."""
    setup = flight.setup
    mission = flight.mission.replace(events=(event,))
    report = SimpleNamespace(constraints=flight.constraints, t=None, inputs=None)
    plan = _Plan(robot, flight.trajectory, mission, report)
    controller = settings.controller
    if not observer:
        controller = dataclasses.replace(controller, observer_bandwidth=0.0)
    settings = dataclasses.replace(settings, controller=controller)
    replanner = Replanner(plan, ReplanOptions(latency=setup.latency)) if setup.replan else None
    # a gust is not told: with a replanner, it plans against the wind estimated in flight
    triggers = TriggerSettings(known_gusts=False, estimate_wind=True)
    chain = [robot.index[c] for c in robot.layout.chain]
    hooks = InFlight(mission, replanner, triggers, controller, chain, robot)
    return simulate(plan, settings, in_flight=hooks), hooks, plan


def _executed_violations(hooks) -> str:
    """The constraints the executed plan violates on its dense grid, in the gusts it was made for ("": none,
    or nothing replanned).
    """
    replanner = hooks.replanner
    if replanner is None or not replanner.revisions:
        return ""
    report = evaluate_in_gusts(replanner.robot, replanner.trajectory, tuple(replanner.gusts), 500.0)
    return ", ".join(c.name for c in report.violations)


def _miss(flight: Flight, log, hooks, distance, broken_names, share, executed="") -> str:
    """Why a run failed, in a line ("" when it succeeded)."""
    setup = flight.setup
    if log.failure is not None:
        return f"lost: {log.failure}"
    if executed:
        return f"the executed plan violates {executed}"
    if setup.family == "move":
        if distance is not None and distance <= setup.pass_tolerance:
            return ""
        replans = hooks.replans
        if not replans:
            return "not replanned: fly it with --replan"
        if not any(r.used for r in replans):
            last = replans[-1]
            moved = next(e.way_point for e in hooks.events if e.kind == "move")
            ahead = float(np.sum(flight.mission.times[:moved])) - last.splice_time
            return (f"no replan used: {last.why.removeprefix('not used: ')} (the last from the splice at "
                    f"{last.splice_time:.3f} s, {ahead:.2f} s before the moved way point {moved})")
        return f"replanned, but the robot passed {distance * 100:.1f} cm away (the closed loop's tracking)"
    if broken_names:
        return f"physical limit broken: {broken_names}"
    if share > setup.max_saturation:
        return f"saturated on {share:.1%} of the ticks (> {setup.max_saturation:.0%})"
    return ""


def _judged(flight: Flight, robot, log, hooks, plan) -> dict:
    """A flight's outcomes: the base ones, how close a move was passed, limits broken, saturation, success."""
    out = outcome_row(flight, log, float(robot.kind.ground_height))
    passed = hooks.passes(log)
    distance = passed[0]["distance_m"] if passed else None
    broken_names = ", ".join(m.name for m in broken(closed_loop_margins(plan, log))) if log.t.size else ""
    share = out["saturated_ticks"] / max(int(log.t.size), 1)
    executed = _executed_violations(hooks)
    miss = _miss(flight, log, hooks, distance, broken_names, share, executed)
    out.update(success=not miss, pass_distance_m=math.nan if distance is None else distance, broken=broken_names,
               saturated_share=share, executed_violates=executed, miss=miss)
    return out


def fly_event(flight: Flight, robot, settings: SimulationSettings, event) -> dict:
    """The outcomes of one run of an event family (module docstring): the event's columns, the flight's, and
    with ``without_observer`` the same flight by the controller without its observer.
    """
    setup = flight.setup
    row = {}
    if setup.family == "gust":
        # flown as planned, the robot passes the plan's poses; a replanner may move them (the way points stay)
        planned = None if setup.replan else flight.trajectory
        verdict = hold_check(robot, flight.mission, event, planned, flight.trajectory.total_duration + flight.hold)
        force = np.asarray(event.force, dtype=float)
        row.update(gust_body=event.body, gust_at_s=event.at, gust_duration_s=event.duration, gust_rise_s=event.rise,
                   gust_force_n=float(np.linalg.norm(force[1:])), gust_force_y_n=float(force[1]),
                   gust_force_z_n=float(force[2]), holdable=bool(verdict.holdable),
                   hold_margin_rad_s=float(verdict.margin))
    else:
        ends = np.concatenate([[0.0], np.cumsum(flight.mission.times)])
        start = np.asarray(flight.mission.way_points[event.way_point], dtype=float)
        row.update(event_way_point=int(event.way_point), event_at_s=event.at,
                   event_lead_s=float(ends[event.way_point] - event.at),
                   event_distance_m=float(np.linalg.norm(np.asarray(event.to)[:2] - start[:2])))
    log, hooks, plan = _flown(flight, robot, settings, event, observer=True)
    judged = _judged(flight, robot, log, hooks, plan)
    replans = hooks.replans
    judged.update(replans=len(replans), replans_used=sum(r.used for r in replans),
                  splice_delay_s=max((r.delayed_s for r in replans), default=0.0))
    row.update({k: v for k, v in judged.items() if k in flight.columns})
    row["replan_wall_s"] = [float(r.solve_wall_s) for r in replans]
    row["replan_cpu_s"] = [float(r.solve_cpu_s) for r in replans]
    row["replan_latency_s"] = [float(r.latency_s) for r in replans]
    if setup.without_observer:
        log, hooks, plan = _flown(flight, robot, settings, event, observer=False)
        other = _judged(flight, robot, log, hooks, plan)
        row.update(no_observer_success=other["success"], no_observer_lost=other["lost"],
                   no_observer_broken=other["broken"], no_observer_saturated_share=other["saturated_share"],
                   no_observer_worst_error=max(other[f"max_error_{c}"] for c in flight.chain),
                   no_observer_pass_distance_m=other["pass_distance_m"])
    return row
