"""The options of ``python -m fpr.plan``: its argument parser, importable without the planner and the simulator.

``python -m fpr.plan --help`` and a mistyped option need only this module (and argparse): the choices read
from registries (robots, planning methods) are read when a value is checked (:class:`fpr.cli.contract.LazyChoices`).
The numbers are checked for physical sense by :mod:`fpr.cli.checks` before any work.

The simulation options default to None here, so that :func:`fpr.cli.checks.check_options` can tell that one
was given without ``--simulate`` (refused: it would be silently ignored); :data:`SIMULATION_DEFAULTS` holds
the values they stand for.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from fpr.cli import contract

#: The built-in missions (files ``planners/missions/<name>.toml``; :data:`planners.missions.BUILTIN_MISSIONS`).
from planners.missions import BUILTIN_MISSIONS

#: What the simulation options stand for when not given: option dest -> (option, default value).
SIMULATION_DEFAULTS = {
    "initial_error": ("--initial-error", []),
    "model_mass_scale": ("--model-mass-scale", 1.0),
    "rotor_constant_scale": ("--rotor-constant-scale", 1.0),
    "wind": ("--wind", None),
    "noise": ("--noise", None),
    "hold": ("--hold", 1.0),
    "takeoff": ("--takeoff", False),
    "replan": ("--replan", False),
    "replan_wind": ("--replan-wind", "known"),
    "no_observer": ("--no-observer", False),
}
#: The options that only mean something with ``--replan``: option dest -> (option, default value).
REPLAN_DEFAULTS = {
    "replan_deadline": ("--replan-deadline", 0.05),
    "replan_bound": ("--replan-bound", 0.05),
    "replan_rate": ("--replan-rate", None),
    "replan_timing": ("--replan-timing", "work"),
    "replan_calibration": ("--replan-calibration", None),
}
#: The values of ``--replan-timing`` (:data:`planners.replanning.replanner.TIMINGS`).
REPLAN_TIMINGS = ("work", "wall")
DESCRIPTION = ("``python -m fpr.plan``: plan a mission of the FPR or the prototype, and write what the drones "
               "must do.")
"""The first line of ``--help`` (the first paragraph of :mod:`fpr.cli.plan`'s docstring)."""
#: The built-in planning methods, for the help (the registry, :data:`planners.methods.METHODS`, checks the value).
HELP_METHODS = ("two-step", "one-step", "none", "crossing")


def floats(text: str, option: str) -> list[float]:
    """The numbers of ``text``, separated by commas (argparse type)."""
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{option} {text!r}: give numbers separated by commas") from None
    if not values:
        raise argparse.ArgumentTypeError(f"{option} {text!r}: give at least one number")
    return values


def integers(text: str) -> list[int]:
    """The integers of ``--via-points``, separated by commas (argparse type)."""
    try:
        return [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--via-points {text!r}: give integers >= 0 separated by commas") from None


def assignment(text: str, option: str = "--set") -> tuple[str, float]:
    """``NAME=VALUE`` as (name, number) (argparse type)."""
    key, sep, value = text.partition("=")
    try:
        if not sep or not key.strip():
            raise ValueError
        return key.strip(), float(value)
    except ValueError:
        example = "--set link_length=1.0" if option == "--set" else f"{option} y=0.05"
        raise argparse.ArgumentTypeError(f"{option} {text!r}: write NAME=VALUE, e.g. {example}") from None


def _robot_names():
    from fpr import robots

    return robots.names()


def _method_names():
    from planners.methods import METHODS

    return tuple(METHODS)


def parser() -> argparse.ArgumentParser:
    """The command-line parser of ``python -m fpr.plan``."""
    p = contract.Parser(prog="python -m fpr.plan", description=DESCRIPTION,
                        formatter_class=contract.HelpFormatter, epilog=contract.EXIT_CODES)
    p.add_argument("--mission", default="square",
                   help=f"built-in mission ({', '.join(BUILTIN_MISSIONS)}) or a mission TOML file")
    p.add_argument("--robot", choices=contract.LazyChoices(_robot_names), default=None, metavar="ROBOT",
                   help="robot the mission must be for, e.g. fpr or prototype (checked; the mission file names "
                        "its robot)")
    p.add_argument("--set", dest="robot_parameters", type=assignment, action="append", default=[],
                   metavar="NAME=VALUE", help="override a robot parameter (xacro argument), e.g. link_length=1.0")
    p.add_argument("--alpha", type=float, default=None, help="energy weight in [0, 1] (default: the mission's)")
    p.add_argument("--via-points", type=integers, default=None, metavar="N[,N...]",
                   help="via points per travel, one number for all or one per travel (default: the mission's)")
    p.add_argument("--times", type=lambda t: floats(t, "--times"), default=None, metavar="T[,T...]",
                   help="travel times [s], one for all or one per travel (default: the mission's)")
    p.add_argument("--method", default="two-step", choices=contract.LazyChoices(_method_names), metavar="METHOD",
                   help=f"planning method ({', '.join(HELP_METHODS)}; registry planners.methods.METHODS): "
                        "two-step / one-step optimisation (seed 3.2.4), none (stop at every way point), crossing "
                        "(seed ch. 4; a singularity-crossing mission gets it whatever is asked, and its first "
                        "guess with none)")
    p.add_argument("--solver", default="sqp", choices=["sqp", "slsqp"],
                   help="NLP solver: our trust-region SQP (smoothed curvature, active-set QP steps, interior-point and "
                        "ProxQP fallbacks) or scipy SLSQP, both with exact gradients")
    p.add_argument("--optimal", action="store_true",
                   help="the SQP with the composite curvature and the KKT stopping rule: a KKT point to 1e-5, "
                        "2-20x slower (the default ends within 0.3 %% of the best J known on the built-in "
                        "missions too; see the documentation, guides/planning-methods)")
    p.add_argument("--no-polish", action="store_true",
                   help="two-step: the thesis' method as it is, without the final one-step solve from its result")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: fpr-out/<mission>)")
    p.add_argument("--rate", type=float, default=200.0, help="sample rate of the CSV files [Hz]")
    p.add_argument("--no-plots", action="store_true", help="do not write the PNG figures")
    sim = p.add_argument_group("closed-loop simulation (--simulate; every option below needs it)")
    sim.add_argument("--simulate", action="store_true",
                     help="track the plan with the cascaded CTC on the closed-chain plant")
    sim.add_argument("--initial-error", type=lambda t: assignment(t, "--initial-error"), action="append",
                     default=None, metavar="NAME=VALUE",
                     help="offset of a coordinate at the start, e.g. y=0.05 [m or rad] (default: none)")
    sim.add_argument("--model-mass-scale", type=float, default=None,
                     help="the controller's model has every mass times this (1.1: believes 10 %% heavier; "
                          "default 1)")
    sim.add_argument("--rotor-constant-scale", type=float, default=None,
                     help="the plant's rotors give this times the nominal force and drag (default 1)")
    sim.add_argument("--wind", type=lambda t: floats(t, "--wind"), default=None, metavar="FX,FY,FZ",
                     help="constant wind force on each drone, world frame [N] (default: none)")
    sim.add_argument("--noise", type=lambda t: floats(t, "--noise"), default=None, metavar="SQ,SV",
                     help="standard deviations of the measurement noise on q and v (default: none)")
    sim.add_argument("--hold", type=float, default=None, help="time simulated after the plan's end [s] (default 1)")
    sim.add_argument("--takeoff", action="store_true",
                     help="start at rest on the take-off pose, drones level (as the thesis' drones did), "
                          "instead of on the plan")
    sim.add_argument("--no-observer", action="store_true",
                     help="the controller without its external-force observer (the thesis' law with the integral "
                          "term): an unknown wind is held by the feedback alone, and --replan-wind estimated reads "
                          "it from the tracking error")
    add_replanning(sim)
    scene = p.add_argument_group("3D scene (meshcat)")
    scene.add_argument("--meshcat", action="store_true",
                       help="write scene.html: the robot following the plan (with --simulate: the simulated "
                            "robot and the plan as a ghost), thrust arrows, paths, way and via points")
    scene.add_argument("--serve", action="store_true",
                       help="also show the scene on a live meshcat server, print its URL and wait for Ctrl-C "
                            "(implies --meshcat)")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    contract.add_debug(p)
    return p


def add_replanning(group) -> None:
    """The replanning options (:mod:`fpr.cli.replanning`), in the simulation's argument group."""
    group.add_argument(
        "--replan", action="store_true",
        help="replan in flight (with --simulate): on a move event, a tracking error past --replan-bound, and "
             "optionally at --replan-rate; see the documentation, guides/replanning")
    group.add_argument(
        "--replan-deadline", type=float, default=None,
        help="simulated time between a trigger and the splice [s]; a solve the latency model says cannot be ready "
             "by then is spliced when it can be (default 0.05)")
    group.add_argument(
        "--replan-bound", type=float, default=None,
        help="tracking error of a chain coordinate that triggers a replan [m or rad] (default 0.05)")
    group.add_argument("--replan-rate", type=float, default=None,
                       help="also replan at this fixed rate [Hz] (default: only on triggers)")
    group.add_argument(
        "--replan-wind", choices=["known", "estimated", "blind"], default=None,
        help="known (the default): the replanner is told the force of each gust with a rise as it starts (a "
             "forecast, a wind sensor; a step gust stays unknown); estimated: it plans against the wind the "
             "controller's observer estimates once it has held 0.3 s (with --no-observer: a steady force on the "
             "end-effector estimated from the tracking error, once it has held 1 s); blind: it sees a gust only "
             "through the tracking error. The controller is told the same wind (fed forward), also without "
             "--replan in known mode")
    group.add_argument(
        "--replan-timing", choices=list(REPLAN_TIMINGS), default=None,
        help="what is compared with the deadline: the solver's work times this machine's measured costs (work, "
             "the default: --replan-calibration; the same bytes on this machine) or the measured wall time (wall: "
             "not reproducible)")
    group.add_argument(
        "--replan-calibration", default=None, metavar="FILE|measure",
        help="the replanner's latency model: a calibration file or a run's replans.json (the run is then pinned "
             "to it: the same bytes on any machine); 'measure': timed at start, this run only; default: this "
             "machine's calibration file (measured and written once, on first use; python -m fpr.bench --section "
             "replan rewrites it)")
