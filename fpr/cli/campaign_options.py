"""The options of ``python -m fpr.campaign``: its argument parser, importable without the planner, the
simulator and Dask (``--help`` and a mistyped option need nothing else).

The numbers are checked before any work by :mod:`fpr.cli.campaign` (with :mod:`fpr.cli.checks`); the number
of worker processes is bounded by the machine (:mod:`fpr.cli.workers`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from fpr.cli import contract
from fpr.cli.plan_options import HELP_METHODS, assignment, floats

DESCRIPTION = ("``python -m fpr.campaign``: a robustness campaign, many closed-loop flights of one plan under "
               "sampled perturbations, run on Dask.")
"""The first line of ``--help`` (the first paragraph of :mod:`fpr.cli.campaign`'s docstring)."""

MAX_RUNS = 1_000_000
"""Most runs of one campaign."""

EXIT_CODES = """exit codes:
  0    the campaign is complete (lost robots are results)
  1    complete, but a limit is broken: the plan violates a constraint, or the success rate's 95 % Wilson
       lower bound is below --min-success
  2    bad input: an option, a distribution, a quantity, a campaign or mission file, an --out that holds
       something else than this campaign
  3    internal error: a bug in fpr (one line says so; --debug shows the traceback)
  130  interrupted (Ctrl-C, SIGTERM): the finished runs stay in --out; the same command resumes"""


EVENT_FAMILIES = ("move", "gust")
"""The values of ``--events`` (:data:`fpr.robustness.events.FAMILIES`, written here so that ``--help`` imports
nothing heavy)."""


def vary(text: str) -> tuple[str, str]:
    """``NAME=DISTRIBUTION`` as (name, text) (argparse type)."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip() or not value.strip():
        raise argparse.ArgumentTypeError(f"--vary {text!r}: write NAME=DISTRIBUTION, e.g. "
                                         "model_mass_scale=uniform(0.9,1.1)")
    return name.strip(), value.strip()


def _method_names():
    from planners.methods import METHODS

    return tuple(METHODS)


def parser() -> argparse.ArgumentParser:
    """The command-line parser of ``python -m fpr.campaign``."""
    p = contract.Parser(prog="python -m fpr.campaign", description=DESCRIPTION,
                        formatter_class=contract.HelpFormatter, epilog=EXIT_CODES)
    p.add_argument("--campaign", type=Path, default=None,
                   help="a campaign TOML file (see the documentation, guides/campaigns); the options below "
                        "override its fields")
    p.add_argument("--mission", default=None, help="built-in mission or mission TOML file (default: square)")
    p.add_argument("--method", default=None, choices=contract.LazyChoices(_method_names), metavar="METHOD",
                   help=f"planning method ({', '.join(HELP_METHODS)}; default: two-step)")
    p.add_argument("--runs", type=int, default=None,
                   help=f"number of closed-loop runs, 1 to {MAX_RUNS:,} (default: 100)")
    p.add_argument("--seed", type=int, default=None, help="campaign seed, an integer >= 0 (default: 0)")
    p.add_argument("--vary", type=vary, action="append", default=[], metavar="NAME=DIST",
                   help="a quantity and its distribution: uniform(lo,hi), normal(mean,sd), truncnormal(mean,sd,"
                        "lo,hi), lognormal(median,sigma), loguniform(lo,hi), choice(a,b,...), linspace(lo,hi) "
                        "or a number; NAME: model_mass_scale, rotor_constant_scale, wind (each axis; or "
                        "wind_x/_y/_z), noise (or noise_q/_v), initial_error.<coordinate>, a robot parameter")
    p.add_argument("--set", dest="robot_parameters", type=assignment, action="append", default=[],
                   metavar="NAME=VALUE", help="fixed robot parameter for the plan and every run, e.g. link_length=1.0")
    p.add_argument("--hold", type=float, default=None, help="time simulated after the plan's end [s] (default: 1)")
    p.add_argument("--tracking-tolerance", type=float, default=None,
                   help="a run succeeds only if every planning coordinate stays within this of the plan [m, rad]")
    p.add_argument("--events", choices=list(EVENT_FAMILIES), default=None,
                   help="one random event per run: a way point that moves, or a gust (fpr.robustness.events; "
                        "options in a campaign file's [event_options])")
    p.add_argument("--replan", action="store_true", default=None, help="fly with the replanner (moves need it)")
    p.add_argument("--without-observer", action="store_true", default=None,
                   help="also fly each run with the controller without its observer, its outcomes beside")
    fixed = p.add_argument_group("fixed perturbations (as python -m fpr.plan --simulate; --vary wins)")
    fixed.add_argument("--model-mass-scale", type=float, default=None, help="the controller's masses times this")
    fixed.add_argument("--rotor-constant-scale", type=float, default=None, help="the plant's rotor force times this")
    fixed.add_argument("--wind", type=lambda t: floats(t, "--wind"), default=None, metavar="FX,FY,FZ",
                       help="constant wind force on each drone [N]")
    fixed.add_argument("--noise", type=lambda t: floats(t, "--noise"), default=None, metavar="SQ,SV",
                       help="measurement-noise standard deviations on q and v")
    fixed.add_argument("--initial-error", type=lambda t: assignment(t, "--initial-error"), action="append",
                       default=[], metavar="NAME=VALUE", help="offset of a coordinate at the start [m or rad]")
    engine = p.add_argument_group("engine (Dask)")
    engine.add_argument("--workers", type=int, default=None,
                        help="worker processes of the local cluster (default: one per usable core; more than the "
                             "cores, or than the memory holds, are capped with a warning)")
    engine.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="an existing Dask scheduler (tcp://host:8786) instead of a local cluster")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: fpr-out/campaign-<mission>)")
    p.add_argument("--min-success", type=float, default=None,
                   help="exit 1 when the success rate's 95 %% Wilson lower bound is below this, in [0, 1]")
    p.add_argument("--no-plots", action="store_true", help="do not write the figures")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors (no progress bar)")
    contract.add_debug(p)
    return p
