"""Checks of ``python -m fpr.plan``'s input before any work: every number, and the size of the work.

:func:`check_options` looks at the options alone (types are argparse's): finite numbers, positive rates
and scales, non-negative noise and hold, three wind components. :func:`check_work` looks at the mission
with the options: the robot's coordinates for ``--initial-error``, then the sizes of the grids and files
the run would make, estimated from the mission's duration and via points, against the limits below.
Each failure is a :class:`CommandLineError` naming the option or mission field and what to do.

The limits keep the largest accepted work to minutes on a 2-core machine, from its cost per unit: a
fraction of a millisecond and about 3 kB of memory per sample of a motion (inverse dynamics, constraints,
CSV row), seconds per polynomial segment of an optimisation (it grows faster than linearly), about a
second and a half per simulated second.
"""

from __future__ import annotations

import math

from fpr.model.errors import FprError

MAX_SAMPLES = 200_000
"""Largest number of samples of the planner's dense check (500 Hz): a 400 s mission, about 20 s and 0.6 GB."""
MAX_ROWS = 100_000
"""Largest number of rows of a CSV file (``--rate`` times the duration): about 30 s and 0.3 GB a file."""
DENSE_RATE = 500.0
"""Rate of the planner's dense-grid check [Hz] (:class:`planners.options.PlanOptions`)."""
MAX_SEGMENTS = 64
"""Largest number of polynomial segments (travels + via points) of an optimised plan."""
MAX_SIMULATED = 300.0
"""Longest closed-loop simulation (plan and ``--hold``) [s]."""
BYTES_PER_SAMPLE = 3_000
SECONDS_PER_SEGMENT = 2.0
SECONDS_PER_SIMULATED_SECOND = 1.5
MAX_SCALE = 100.0
MAX_WIND = 1_000.0
MAX_OFFSET = 10.0


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
        super().__init__(f"{option} {_shown(value)}: {reason}")


def _shown(value) -> str:
    if isinstance(value, (list, tuple)):
        return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def _bytes(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.3g} {unit}"
        n /= 1000
    return f"{n:.3g} TB"


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


def check_options(args) -> None:
    """Check the numbers of the options alone, before the mission is read.

    Raises:
        CommandLineError: the first option that is not a number the command can use.
    """
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
    _number("--model-mass-scale", args.model_mass_scale, low=0.0, low_open=True, high=MAX_SCALE,
            meaning="the controller's masses are the robot's times this")
    _number("--rotor-constant-scale", args.rotor_constant_scale, low=0.0, low_open=True, high=MAX_SCALE,
            meaning="the plant's rotor force and drag are the nominal ones times this")
    if args.wind is not None:
        if len(args.wind) != 3:
            raise CommandLineError("--wind", args.wind, f"{len(args.wind)} number(s): give three, FX,FY,FZ [N]")
        for f in args.wind:
            _number("--wind", f, low=-MAX_WIND, high=MAX_WIND, meaning="force on each drone [N]")
    if args.noise is not None:
        if len(args.noise) != 2:
            raise CommandLineError("--noise", args.noise, f"{len(args.noise)} number(s): give two, SQ,SV "
                                                          "(standard deviations on q and v)")
        for s in args.noise:
            _number("--noise", s, low=0.0, meaning="a standard deviation is >= 0")
    _number("--hold", args.hold, low=0.0, meaning="time simulated after the plan's end [s]")
    for name, offset in args.initial_error:
        _number("--initial-error", offset, low=-MAX_OFFSET, high=MAX_OFFSET, shown=f"{name}={offset:g}",
                meaning="offset of a coordinate at the start [m or rad]")


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
            raise CommandLineError(given, f"drone_mass={mass:g}" if by_option else f"{mass:g}", f"drone {i + 1} weighs {mass * gravity:.3g} N, more than its 4 "
                                                       f"rotors lift at full speed ({lift:.3g} N): give a drone of "
                                                       f"at most {lift / gravity:.3g} kg, or edit the rotor "
                                                       "constants in urdf/parameters.yaml")


def check_work(args, mission, robot, optimised: bool) -> None:
    """Check what needs the mission and the robot: ``--initial-error`` names, then the size of the work.

    Args:
        args: the parsed options.
        mission: the :class:`planners.missions.mission.Mission` as planned (overrides included).
        robot: its robot.
        optimised: a planning method that optimises via points (not ``none``).

    Raises:
        CommandLineError: an unknown coordinate, or a grid, file or optimisation larger than the limits
            (the message gives the estimate and the limit).
    """
    known = list(robot.index)
    for name, _ in args.initial_error:
        if name not in known:
            raise CommandLineError("--initial-error", f"{name}=...", f"unknown coordinate {name!r}: use one of "
                                                                     f"{', '.join(known)}")
    _check_lift(args, mission, robot)
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
    if args.simulate:
        simulated = duration + args.hold
        if simulated > MAX_SIMULATED:
            raise CommandLineError("--simulate", f"{simulated:g} s",
                                   f"the simulation would cover {simulated:g} s (the plan and --hold), about "
                                   f"{_duration(simulated * SECONDS_PER_SIMULATED_SECOND)}; the limit is "
                                   f"{MAX_SIMULATED:g} s: shorten the mission or --hold")
