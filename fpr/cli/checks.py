"""Checks of ``python -m fpr.plan``'s input before any work: every number, and the size of the work.

:func:`check_options` looks at the options alone (types are argparse's): finite numbers in physical ranges,
and no simulation option without ``--simulate`` (nor a replanning option without ``--replan``): an option
that would be silently ignored is refused. :func:`check_work` looks at the mission with the options: the
robot's coordinates for ``--initial-error``, each travel long enough for the robot (:func:`least_travel_times`),
the ranges that depend on the mission (sample and replanning rates, deadline), then the sizes of the grids
and files the run would make, estimated from the mission's duration and via points, against the limits below.
Each failure is a :class:`CommandLineError` naming the option or mission field and what to give.

Where the ranges come from (they exclude the absurd, not the unusual):

* a travel time: at least :data:`GRID_STEPS` steps of the planner's dense check grid (:data:`DENSE_RATE`), and
  at least the time below which even the gentlest rest-to-rest motion over the travel would need more thrust
  than the rotors give at full speed (:func:`least_travel_times`: it scales the stop-at-way-points motion's
  inverse dynamics to the time-optimal acceleration profile);
* ``--rate``: at least one sample per travel (1 / the shortest travel time);
* scales of the simulation (``--model-mass-scale``, ``--rotor-constant-scale``): within a factor
  :data:`MAX_SCALE` of 1, either way;
* forces (``--wind``, a gust's ``force``): :data:`MAX_WIND` per component, about the drag of a 100 m/s wind
  (beyond any measured gust) on a large multirotor (:data:`planners.missions.events.MAX_FORCE`);
* offsets and noise: :data:`MAX_OFFSET` [m or rad] (beyond it the robot starts outside any workspace of the
  built-in robots), :data:`MAX_RATE_NOISE` [m/s or rad/s] (faster than a drone ever moves);
* a gust (a mission's event): at least one step of the simulated plant, its onset 0 or at least one step;
* replanning: a deadline of at least one step of the simulated plant and at most the flight; a rate between
  one replan per flight and the controller's outer-loop rate; a tracking bound at most the error at which the
  simulation counts the robot lost;
* robot parameters: :data:`fpr.model.parameters.PARAMETER_RANGES` (broad physical ranges for a multirotor and
  its chain) and the lift of the drones' rotors.

The size limits keep the largest accepted work to minutes on a 2-core machine, from its cost per unit: a
fraction of a millisecond and about 3 kB of memory per sample of a motion (inverse dynamics, constraints,
CSV row), seconds per polynomial segment of an optimisation (it grows faster than linearly), about a
second and a half per simulated second.
"""

from __future__ import annotations

import math

import numpy as np

from controllers.ctc import ControllerSettings
from fpr.cli.output import size_text
from fpr.cli.plan_options import REPLAN_DEFAULTS, SIMULATION_DEFAULTS
from fpr.cli.text import number, short_list
from fpr.model.errors import FprError
from fpr.model.inverse_dynamics import thrust_vectors
from fpr.model.jets import Jet
from fpr.sim.closed_loop import SimulationSettings
from planners.missions.events import MAX_FORCE
from planners.trajectory.polynomial import PiecewisePolynomial, stop_points

MAX_SAMPLES = 200_000
"""Largest number of samples of the planner's dense check (500 Hz): a 400 s mission, about 20 s and 0.6 GB."""
MAX_ROWS = 100_000
"""Largest number of rows of a CSV file (``--rate`` times the duration): about 30 s and 0.3 GB a file."""
DENSE_RATE = 500.0
"""Rate of the planner's dense-grid check [Hz] (:class:`planners.options.PlanOptions`)."""
GRID_STEPS = 2
"""Least number of steps of the dense check grid in a travel (so that the middle of every travel is checked)."""
MAX_SEGMENTS = 64
"""Largest number of polynomial segments (travels + via points) of an optimised plan."""
MAX_SIMULATED = 300.0
"""Longest closed-loop simulation (plan and ``--hold``) [s]."""
BYTES_PER_SAMPLE = 3_000
SECONDS_PER_SEGMENT = 2.0
SECONDS_PER_SIMULATED_SECOND = 1.5
MAX_SCALE = 100.0
"""The simulation's scales are within [1 / MAX_SCALE, MAX_SCALE]."""
MAX_WIND = MAX_FORCE
"""Largest wind force component on a drone [N]."""
MAX_OFFSET = 10.0
"""Largest ``--initial-error`` and position/angle noise [m or rad]."""
MAX_RATE_NOISE = 100.0
"""Largest velocity noise [m/s or rad/s]."""
PROFILE_PEAK = 9.371976216962764
"""Peak of the second derivative of the stop-at-way-points profile (the 9th-degree rest-to-rest polynomial
with velocity, acceleration, jerk and snap zero at both ends) over a unit travel in unit time; the time-optimal
(bang-bang) profile's is 4: it needs 4 / 9.372 of the acceleration."""
_U = np.linspace(0.0, 1.0, 101)  # samples of each travel, in fractions of its time


class CommandLineError(FprError, ValueError):
    """A command-line option (or a mission field it stands for) that the command refuses.

    Attributes:
        option: the option or field, as the user wrote it (``--rate``, ``times``...).
        value: what was given.
        reason: what is wrong and what to do (the message).
    """

    def __init__(self, option: str, value, reason: str):
        self.option = option
        self.value = value
        self.reason = reason
        shown = _shown(value)
        super().__init__(f"{option} {shown}: {reason}" if shown != "" else f"{option}: {reason}")


def _shown(value) -> str:
    if isinstance(value, (list, tuple)):
        return short_list(value)
    return number(value)


def _bytes(n: float) -> str:
    return size_text(n)


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.3g} h"


def _number(option: str, value, *, low: float | None = None, low_open: bool = False,
            high: float | None = None, meaning: str, shown=None) -> None:
    """A finite number within [low, high] (``low_open``: > low); ``shown``: the value as the message shows it."""
    shown = value if shown is None else shown
    if not math.isfinite(value):
        raise CommandLineError(option, shown, f"give a finite number ({meaning})")
    if low is not None and (value < low or (low_open and value == low)):
        raise CommandLineError(option, shown, f"give a number {'>' if low_open else '>='} {low:g} ({meaning})")
    if high is not None and value > high:
        raise CommandLineError(option, shown, f"give a number <= {high:g} ({meaning})")


def _given(args, dest: str, default) -> bool:
    value = getattr(args, dest, None)
    return value is not None and value is not False and value != [] and value is not default


def check_options(args) -> None:
    """Check the numbers of the options alone, before the mission is read.

    Raises:
        CommandLineError: the first option that is not a number the command can use, or a simulation option
            without ``--simulate`` (a replanning option without ``--replan``).
    """
    if not getattr(args, "simulate", False):
        for dest, (option, _) in {**SIMULATION_DEFAULTS, **REPLAN_DEFAULTS}.items():
            if _given(args, dest, None):
                raise CommandLineError(option, "", "a simulation option: add --simulate (without it nothing is "
                                                   "simulated and the option would be ignored)")
    elif not getattr(args, "replan", False):
        for dest, (option, _) in REPLAN_DEFAULTS.items():
            if _given(args, dest, None):
                raise CommandLineError(option, "", "a replanning option: add --replan (without it nothing is "
                                                   "replanned and the option would be ignored)")
    _number("--rate", args.rate, low=0.0, low_open=True, meaning="samples per second of the CSV files [Hz]")
    if args.alpha is not None:
        _number("--alpha", args.alpha, low=0.0, high=1.0, meaning="1: energy only, 0: drone perturbation only")
    for i, t in enumerate(args.times or ()):
        if not (math.isfinite(t) and t > 0):
            raise CommandLineError("--times", args.times, f"times[{i}] = {t:g}: give finite travel times > 0 [s]")
    for i, n in enumerate(args.via_points or ()):
        if n < 0:
            raise CommandLineError("--via-points", args.via_points, f"via_points[{i}] = {n}: give integers >= 0 "
                                                                    "(via points inside each travel)")
    for key, value in args.robot_parameters:
        _number("--set", value, low=0.0, meaning=f"robot parameter {key} [SI units]", shown=f"{key}={value:g}")
    for option, dest in (("--model-mass-scale", "model_mass_scale"),
                         ("--rotor-constant-scale", "rotor_constant_scale")):
        value = getattr(args, dest, None)
        if value is not None:
            _number(option, value, low=1.0 / MAX_SCALE, high=MAX_SCALE,
                    meaning=f"a scale of the robot's masses or rotor constants, within a factor {MAX_SCALE:g} of 1")
    if getattr(args, "wind", None) is not None:
        if len(args.wind) != 3:
            raise CommandLineError("--wind", args.wind, f"{len(args.wind)} number(s): give three, FX,FY,FZ [N]")
        for f in args.wind:
            _number("--wind", f, low=-MAX_WIND, high=MAX_WIND, shown=args.wind,
                    meaning="force on each drone [N]; more than the drag of a 100 m/s wind on a large multirotor "
                            "is no wind")
    if getattr(args, "noise", None) is not None:
        if len(args.noise) != 2:
            raise CommandLineError("--noise", args.noise, f"{len(args.noise)} number(s): give two, SQ,SV "
                                                          "(standard deviations on q and v)")
        for s, high, unit in zip(args.noise, (MAX_OFFSET, MAX_RATE_NOISE), ("m or rad", "m/s or rad/s"), strict=True):
            _number("--noise", s, low=0.0, high=high, shown=args.noise,
                    meaning=f"a standard deviation [{unit}], >= 0; beyond {high:g} a sensor measures nothing")
    if getattr(args, "hold", None) is not None:
        _number("--hold", args.hold, low=0.0, high=MAX_SIMULATED, meaning="time simulated after the plan's end [s]")
    for name, offset in getattr(args, "initial_error", None) or ():
        _number("--initial-error", offset, low=-MAX_OFFSET, high=MAX_OFFSET, shown=f"{name}={offset:g}",
                meaning="offset of a coordinate at the start [m or rad]")
    for option, dest in (("--replan-deadline", "replan_deadline"), ("--replan-bound", "replan_bound"),
                         ("--replan-rate", "replan_rate")):
        value = getattr(args, dest, None)
        if value is not None:
            _number(option, value, low=0.0, low_open=True, meaning="a time [s], an error [m or rad] or a rate [Hz]")
    bound = getattr(args, "replan_bound", None)
    if bound is not None:
        lost = SimulationSettings().max_tracking_error
        _number("--replan-bound", bound, low=0.0, low_open=True, high=lost,
                meaning=f"a tracking error [m or rad]; past {lost:g} the simulation counts the robot lost")


def apply_defaults(args) -> None:
    """Give the simulation and replanning options that were not given their default values (in place)."""
    for dest, (_, default) in {**SIMULATION_DEFAULTS, **REPLAN_DEFAULTS}.items():
        if getattr(args, dest, None) is None:
            setattr(args, dest, list(default) if isinstance(default, list) else default)


def _field(args, option: str, field: str, mission) -> str:
    """How the user gave a mission field: the option if given, else the field of the mission file."""
    given = getattr(args, option[2:].replace("-", "_")) is not None
    return option if given else f"{mission.source}: field {field!r} ="


def _check_lift(args, mission, robot) -> None:
    """Each drone's rotors lift at least its own weight at full speed (4 c_T w_max^2 >= m_d g)."""
    rotors = robot.rotor_constants
    lift = 4 * rotors.thrust_coefficient * rotors.max_speed ** 2
    gravity = float(robot.parameters["gravity"])
    for i, mass in enumerate(robot.drone_masses):
        if mass * gravity > lift:
            by_option = any(k == "drone_mass" for k, _ in args.robot_parameters)
            given = "--set" if by_option else f"{mission.source}: field 'robot_parameters.drone_mass' ="
            raise CommandLineError(given, f"drone_mass={mass:g}" if by_option else f"{mass:g}",
                                   f"drone {i + 1} weighs {mass * gravity:.3g} N, more than its 4 rotors lift at "
                                   f"full speed ({lift:.3g} N): give a drone of at most {lift / gravity:.3g} kg, or "
                                   "edit the rotor constants in urdf/parameters.yaml")


def full_thrust(robot) -> np.ndarray:
    """The thrust of each drone's rotors all at full speed, sum of c_T w_max^2 over its rotors, shape (n_d,) [N]."""
    return np.array([len(rotor.positions) * rotor.constants.max_rotor_thrust for rotor in robot.rotors])


def least_travel_times(mission, robot, chunk: int = 500) -> np.ndarray:
    """The least time of each travel of a way-point mission that the robot's rotors can fly [s], shape (k,).

    The stop-at-way-points motion of a travel takes its s along the straight line from one way point to the
    next with the rest-to-rest profile; over a time T its thrusts (planning model, seed 2.6-2.7) are
    exactly F(u) = G(u) + H(u) / T^2 at each fraction u of the travel, G the static thrust at that pose and
    H the part of the motion (accelerations and velocities, scaled to a unit time). The time-optimal
    profile needs 4 / :data:`PROFILE_PEAK` of that motion's acceleration, and at best the gravity G helps,
    so no rest-to-rest motion along the travel has a peak thrust below (4 / PROFILE_PEAK) max|H| / T^2 -
    max|G|: the least time makes that equal to the rotors' full thrust (:func:`full_thrust`). A travel with
    no motion (two equal way points) can last any time (0 here; the grid's floor applies).

    Returns:
        the least time of each travel [s] (0 for a travel without motion).
    """
    poses = mission.positions(robot)
    count = poses.shape[0] - 1
    out = np.zeros(count)
    f_max = full_thrust(robot)
    for begin in range(0, count, chunk):
        end = min(begin + chunk, count)
        stop = PiecewisePolynomial(stop_points(poses[begin:end + 1]), np.ones(end - begin))
        t = (np.arange(end - begin)[:, None] + _U[None, :]).reshape(-1)
        motion = stop.evaluate(np.minimum(t, end - begin), order=4)
        still = motion.copy()
        still[1:] = 0.0
        moving = thrust_vectors(robot, Jet(motion), order=0).d[0]  # (N, n_d, 2)
        static = thrust_vectors(robot, Jet(still), order=0).d[0]
        inertial = np.linalg.norm(moving - static, axis=-1).reshape(end - begin, _U.size, -1).max(axis=1)
        weight = np.linalg.norm(static, axis=-1).reshape(end - begin, _U.size, -1).max(axis=1)
        need = (4.0 / PROFILE_PEAK) * inertial / (f_max[None, :] + weight)  # T^2 of each drone, (travels, n_d)
        out[begin:end] = np.sqrt(need.max(axis=1))
    return out


def _check_grid_times(args, mission) -> None:
    """Each travel at least :data:`GRID_STEPS` steps of the dense check grid."""
    times = [float(t) for t in mission.times]
    grid = GRID_STEPS / DENSE_RATE
    for i, t in enumerate(times):
        if t < grid:
            raise CommandLineError(_field(args, "--times", "times", mission), times,
                                   f"times[{i}] = {t:g} s is shorter than {GRID_STEPS} steps of the planner's "
                                   f"{DENSE_RATE:g} Hz check grid: give at least {grid:g} s")


def _check_travel_times(args, mission, robot) -> None:
    """Each travel long enough for the rotors (:func:`least_travel_times`; not for a singularity crossing, whose
    times are first guesses the planner optimises).
    """
    if mission.cross_singularity:
        return
    times = [float(t) for t in mission.times]
    least = least_travel_times(mission, robot)
    short = np.flatnonzero(np.asarray(times) < least)
    if short.size:
        i = int(short[0])
        need = _round_up(least[i])
        raise CommandLineError(_field(args, "--times", "times", mission), times,
                               f"times[{i}] = {times[i]:g} s is too short for the robot's rotors: over the travel "
                               f"from way point {i} to {i + 1}, even the time-optimal rest-to-rest motion needs "
                               f"more than their full thrust ({full_thrust(robot).max():.3g} N a drone) in less "
                               f"than {need:g} s: give at least {need:g} s")


def _round_up(seconds: float) -> float:
    """``seconds`` rounded up to 3 significant digits."""
    if seconds <= 0:
        return 0.0
    step = 10.0 ** (math.floor(math.log10(seconds)) - 2)
    return math.ceil(seconds / step) * step


def check_work(args, mission, robot, optimised: bool) -> None:
    """Check what needs the mission and the robot: ``--initial-error`` names, the lift, the sizes of the work,
    each travel's time, and the ranges that depend on the mission.

    Args:
        args: the parsed options (their defaults applied, :func:`apply_defaults`).
        mission: the :class:`planners.missions.mission.Mission` as planned (overrides included).
        robot: its robot.
        optimised: a planning method that optimises via points (not ``none``).

    Raises:
        CommandLineError: an unknown coordinate, a drone its rotors cannot lift, a travel too short, a rate
            or deadline out of its range, or a grid, file or optimisation larger than the limits (the
            message gives the estimate and the limit).
    """
    known = list(robot.index)
    for name, _ in getattr(args, "initial_error", None) or ():
        if name not in known:
            raise CommandLineError("--initial-error", f"{name}=...", f"unknown coordinate {name!r}: use one of "
                                                                     f"{', '.join(known)}")
    _check_lift(args, mission, robot)
    _check_grid_times(args, mission)
    _check_events(mission)
    duration = mission.duration
    dense = duration * DENSE_RATE + 1
    if dense > MAX_SAMPLES:
        where = _field(args, "--times", "times", mission)
        raise CommandLineError(where, [float(t) for t in mission.times],
                               f"the mission lasts {duration:.6g} s; the planner checks it on a {DENSE_RATE:g} Hz grid "
                               f"of {dense:.3g} samples (about {_bytes(dense * BYTES_PER_SAMPLE)} of memory); the "
                               f"limit is {MAX_SAMPLES:,} samples ({MAX_SAMPLES / DENSE_RATE:g} s): give shorter "
                               "travel times")
    rows = math.floor(duration * args.rate) + 1
    if rows > MAX_ROWS:
        raise CommandLineError("--rate", args.rate,
                               f"trajectory.csv would have {rows:.3g} rows ({duration:g} s at {args.rate:g} Hz, about "
                               f"{_bytes(rows * BYTES_PER_SAMPLE)} of memory); the limit is {MAX_ROWS:,} rows: "
                               f"give --rate {math.floor((MAX_ROWS - 1) / duration):d} or less")
    segments = int(sum(int(n) + 1 for n in mission.via_points))
    if optimised and segments > MAX_SEGMENTS:
        where = _field(args, "--via-points", "via_points", mission)
        raise CommandLineError(where, [int(n) for n in mission.via_points],
                               f"the optimisation would have {segments} polynomial segments ({len(mission.times)} "
                               f"travel(s) and {segments - len(mission.times)} via points), about "
                               f"{_duration(segments * SECONDS_PER_SEGMENT)} or more to solve; the limit is "
                               f"{MAX_SEGMENTS} segments: give fewer via points, or --method none")
    if getattr(args, "simulate", False):
        simulated = duration + args.hold
        if simulated > MAX_SIMULATED:
            raise CommandLineError("--simulate", f"{simulated:g} s",
                                   f"the simulation would cover {simulated:g} s (the plan and --hold), about "
                                   f"{_duration(simulated * SECONDS_PER_SIMULATED_SECOND)}; the limit is "
                                   f"{MAX_SIMULATED:g} s: shorten the mission or --hold")
        _check_replanning(args, simulated)
    _check_travel_times(args, mission, robot)
    least_rate = 1.0 / float(np.min(mission.times))
    if args.rate < least_rate:
        raise CommandLineError("--rate", args.rate, f"fewer samples than travels: give at least {least_rate:.3g} Hz "
                                                    f"(a sample per travel; the shortest lasts {1 / least_rate:g} s)")


def _check_events(mission) -> None:
    """A gust lasts at least one step of the simulated plant, and its onset is 0 (a step) or at least one step."""
    step = 1.0 / SimulationSettings().plant_rate
    for i, event in enumerate(mission.events):
        if event.kind != "gust":
            continue
        where = f"{mission.source}: field 'events[{i}].{{}}' ="
        if event.duration < step:
            raise CommandLineError(where.format("duration"), event.duration,
                                   f"a gust shorter than one step of the simulation ({step:g} s) does not push: give "
                                   f"at least {step:g} s")
        if 0.0 < event.rise < step:
            raise CommandLineError(where.format("rise"), event.rise,
                                   f"give 0 (a step) or an onset of at least one step of the simulation ({step:g} s)")


def _check_replanning(args, simulated: float) -> None:
    """The replanning deadline and rate within what the controller and the flight make meaningful."""
    if not getattr(args, "replan", False):
        return
    outer, step = ControllerSettings().outer_rate, 1.0 / SimulationSettings().plant_rate
    _number("--replan-deadline", args.replan_deadline, low=step, high=simulated,
            meaning=f"at least one step of the simulation ({step:g} s) and at most the flight ({simulated:g} s) "
                    "[s]")
    if args.replan_rate is not None:
        _number("--replan-rate", args.replan_rate, low=1.0 / simulated, high=outer,
                meaning=f"at least one replan in the {simulated:g} s flight and at most the controller's "
                        f"{outer:g} Hz outer-loop rate [Hz]")


def output_size(args, mission, robot) -> float:
    """About how many bytes the run writes into ``--out`` (an upper estimate) [bytes].

    CSV files of about 12 bytes a value, a simulation log of 8 bytes a value (before compression), figures
    of at most 300 kB each.
    """
    rows = math.floor(mission.duration * args.rate) + 1
    columns = 1 + 3 * len(robot.layout.chain) + 12 * robot.n_drones
    csv = 12 * rows * columns * (1 if args.method == "none" else 2)
    size = csv + 100_000 + (0 if args.no_plots else 12 * 300_000)
    if getattr(args, "simulate", False):
        ticks = (mission.duration + (args.hold or 0.0)) * ControllerSettings().inner_rate
        values = 2 * robot.nq + 3 * len(robot.layout.chain) + 20 * robot.n_drones + 2
        size += 12 * rows * (2 * robot.nq + 12 * robot.n_drones) + 8 * ticks * values
        size += 0 if args.no_plots else 12 * 300_000
    return float(size)
