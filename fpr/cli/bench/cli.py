"""Benchmark of the models, planner and controller: ``python -m fpr.bench [--quick] [--json] [--section S]``.

All items run in one process, one after the other, so that their ratios mean something on a shared,
noisy machine. Each is a loop sized to last ~50 ms (20 ms with ``--quick``), repeated 7 times (3 with
``--quick``), garbage collector off (:class:`fpr.cli.bench.timing.Bench`); reported: median and min over
repeats of the time per call (``time.perf_counter``), the time per sample, and a ratio (per-sample time /
a reference's). The sections, each in its own module:

* ``model`` (:mod:`fpr.cli.bench.model`): the robot model, the planar model, the inverse dynamics and the
  closed chain against the raw Pinocchio calls, and accuracy figures;
* ``planning`` (:mod:`fpr.cli.bench.planning`): the planning methods on the square mission against a
  baseline in the manner of the thesis' fmincon runs (:mod:`fpr.bench.baseline`), re-optimising one
  segment, the singularity crossing, and seeded families of random missions of every built-in robot
  (:mod:`fpr.cli.bench.families`);
* ``control`` (:mod:`fpr.cli.bench.control`): the rotor allocation's QP solvers side by side, and the
  closed-loop simulation's real-time factor;
* ``replan`` (:mod:`fpr.cli.bench.replan`): the latency of a replan in flight (median, 95th percentile,
  worst) on the built-in missions;
* ``scaling`` (:mod:`fpr.cli.bench.scaling`): planning time against the mission's length (4 to 64 way
  points, seeded families of random missions of every built-in robot, both methods) and its growth exponent.

Timings depend on the machine and its load: no test asserts them.
"""

from __future__ import annotations

import json
import os
import platform

import numpy as np
import pinocchio as pin

from fpr.cli import contract
from fpr.cli.bench.control import control_table, run_control
from fpr.cli.bench.model import model_targets, run_residuals, run_timings
from fpr.cli.bench.planning import planning_table, run_planning
from fpr.cli.bench.replan import replan_table, run_replan
from fpr.cli.bench.scaling import run_scaling, scaling_table
from fpr.cli.bench.timing import Bench, fmt
from fpr.tuning import tune_process


def parser() -> contract.Parser:
    """The argument parser of ``python -m fpr.bench``."""
    p = contract.Parser(prog="python -m fpr.bench", description=__doc__.splitlines()[0],
                        formatter_class=contract.HelpFormatter,
                        epilog="exit codes: 0 done (a goal not met is reported, not a failure), 2 bad option, "
                               "3 internal error (a bug: --debug shows the traceback), 130 interrupted")
    p.add_argument("--json", action="store_true", help="print a JSON document instead of the table")
    p.add_argument("--quick", action="store_true",
                   help="3 repeats of ~20 ms loops instead of 7 of ~50 ms; planning: 1 run per item, "
                        "baseline capped at 15 s instead of 120 s; control: 32 states instead of 64, "
                        "1 simulation run instead of 3; planning: 6 random missions a robot instead of 20; "
                        "scaling: 2 a robot and length instead of 6")
    p.add_argument("--section", choices=("all", "model", "planning", "control", "replan", "scaling"),
                   default="all", help="which part to run")
    contract.add_debug(p)
    return p


def main(argv=None) -> int:
    """Run the benchmark and print the tables (or JSON with ``--json``).

    Args:
        argv: command-line arguments (default: sys.argv[1:]).

    Returns:
        The exit code: 0, or 2 (a bad option), 3 (a bug), 130 (Ctrl-C).
    """
    tune_process()  # one BLAS thread, freed memory kept in glibc's heap (fpr.tuning)
    return contract.command(parser(), argv, _run)


def _run(args, argv) -> int:
    bench = Bench(repeats=3 if args.quick else 7, target=0.02 if args.quick else 0.05, progress=not args.json)
    info = dict(python=platform.python_version(), numpy=np.__version__, pinocchio=pin.__version__,
                cpu_count=os.cpu_count(), platform=platform.platform())
    residuals, planning, control, replan = [], None, None, None
    if args.section in ("all", "model"):
        run_timings(bench)
        residuals = run_residuals()
    if args.section in ("all", "planning"):
        planning = run_planning(args.quick, progress=not args.json)
    if args.section in ("all", "control"):  # its own Bench: its rows are not the model table's
        control = run_control(Bench(bench.repeats, bench.target, bench.progress), args.quick,
                              progress=not args.json)
    if args.section in ("all", "replan"):  # replanning latency (fpr/cli/bench/replan.py)
        replan = run_replan(args.quick, progress=not args.json)
    scaling = run_scaling(args.quick, progress=not args.json) if args.section in ("all", "scaling") else None
    goals = _goals(bench, planning, control, scaling)
    if args.json:
        doc = dict(machine=info, repeats=bench.repeats, loop_target_s=bench.target, timings=bench.results,
                   residuals=residuals, goals=goals)
        if planning is not None:
            doc["planning"] = planning
        if control is not None:
            doc["control"] = control
        if replan is not None:
            doc["replan"] = replan
        if scaling is not None:
            doc["scaling"] = scaling
        print(json.dumps(doc, indent=2))
        return 0
    print(" ".join(f"{k} {v}" for k, v in info.items()))
    if bench.results:
        print(f"{bench.repeats} repeats of ~{bench.target * 1e3:.0f} ms loops; times per call, "
              "per-sample = median / n")
        width = max(len(r["name"]) for r in bench.results)
        print(f"{'name':<{width}}  {'median':>10}  {'min':>10}  {'per-sample':>10}  ratio (per-sample / ref)")
        for r in bench.results:
            ratio = f"{r['ratio']:8.3f} x {r['ratio_to']}" if r["ratio"] is not None else ""
            print(f"{r['name']:<{width}}  {fmt(r['median_s'])}  {fmt(r['min_s'])}  {fmt(r['per_sample_s'])}  "
                  f"{ratio}")
        print("\naccuracy (max abs acceleration error)")
        for r in residuals:
            print(f"  {r['name']:<{width}}  {r['value']:.3e}")
    if planning is not None:
        print()
        print(planning_table(planning))
    if control is not None:
        print()
        print(control_table(control))
    if replan is not None:
        print()
        print(replan_table(replan))
    if scaling is not None:
        print()
        print(scaling_table(scaling))
    if goals:
        print("\ngoals")
        for g in goals:
            print(f"  [{g['section']}] {g['target']}: {g['value']:.4g} -> {g['verdict']}")
    return 0


def _goals(bench, planning, control, scaling=None) -> list[dict]:
    """Every section's goals in one list: target, value, (goal, unit when given), met and its verdict."""
    rows = [("model", t) for t in model_targets(bench.results)]
    sections = (("planning", planning), ("control", control), ("scaling", scaling))
    rows += [(name, t) for name, section in sections if section for t in section.get("targets", [])]
    return [dict(section=name, **t, verdict="met" if t["met"] else "not met") for name, t in rows]
