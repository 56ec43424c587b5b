"""Replanning section of the benchmark (``python -m fpr.bench --section replan``): the latency of a replan.

Each item is one call of :meth:`planners.replanning.replanner.Replanner.replan` (build the horizon's NLP, solve it by the
SQP with the replanner's own explicit options, check the result on the dense grid), timed by its wall
clock, from the offline two-step plan of a built-in mission:

a. ``moving-target``: the move event at 4 s (way point 2 to [1.2, 0.8]), start from the plan in force;
b. ``square`` at a fixed rate: a replan every 0.5 s (0.25 .. 11.25 s; 1 s with ``--quick``), start from the
   plan in force (the re-optimisation of the rest of the current travel);
c. ``gust``: solves from a robot pushed off the plan (5 cm along y, at rest relative to the plan), every
   0.5 s from 3.25 s (1 s with ``--quick``): timed only, such a plan is not spliced in (it is not C4 with the
   plan in force, :mod:`planners.replanning.replanner`).

Reported per item and over all of them: median, 95th percentile and worst **wall** time against the
default deadline (50 ms), on this machine's clock as it is (no scaling to a reference speed: on a shared
machine the times grow with the load, which is printed; run with ``OPENBLAS_NUM_THREADS=1``), and the 95th
percentile of the process's **CPU** time (``time.process_time``: one core's work, which the other jobs of a
shared machine inflate less than the wall clock). Each replan is also solved, right after, by the replanner
as it was before the latency work (:data:`BEFORE`: a dense check of its own, every SQP iteration up to the
cap whatever the deadline), and the ratios of today's times to those are printed: measured side by side in
one run, they hold on a loaded machine where the times themselves do not. The costs of the deterministic
``work`` latency (:data:`planners.replanning.replanner.WORK_COST`) are fitted (non-negative least squares) to today's wall
and CPU times and printed beside the costs in use, with the ratio of the modelled latency to the measured
one (median and range over the replans): how far the default, reproducible used / not-used decision may be
from the wall clock. Last, the moving-target replan taken apart into its phases
(:mod:`fpr.cli.bench.replan_phases`).
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np
from scipy.optimize import nnls

from fpr.cli.bench.replan_phases import phases_table, replan_phases
from planners.missions.mission import load_mission
from planners.optimize import plan
from planners.replanning.replanner import WORK_COST, Replanner, ReplanOptions, jet

DEADLINE = ReplanOptions().deadline
#: The replanner before the latency work, timed beside today's: the dense check in a call of its own, and
#: every SQP iteration up to the cap (2) whatever the deadline.
BEFORE = {"fuse_check": False, "refine_margin": 0.0}


def _replan(result, t, move, offset, options):
    """One replan at t [s]; returns (record, CPU time [s])."""
    replanner = Replanner(result, options)
    if move:
        replanner.move(0)
    start = None
    if offset is not None:
        start = jet(result.trajectory, t + replanner.options.deadline)
        start[0] = start[0] + offset
    cpu = time.process_time()
    record = replanner.replan(float(t), "bench", start=start)
    return record, time.process_time() - cpu


def _latencies(result, times, *, move=False, offset=None, options=None):
    out = {key: [] for key in ("wall", "cpu", "model", "used", "work", "J", "before_wall", "before_cpu",
                               "before_J", "before_work", "feasible")}
    for t in times:
        record, cpu = _replan(result, t, move, offset, options or ReplanOptions())
        before, before_cpu = _replan(result, t, move, offset, ReplanOptions(**BEFORE))
        out["wall"].append(record.solve_wall_s)
        out["cpu"].append(cpu)
        out["model"].append(record.latency_s)
        out["used"].append(record.used)
        out["work"].append(record.work)
        out["J"].append(record.J)
        out["before_wall"].append(before.solve_wall_s)
        out["before_cpu"].append(before_cpu)
        out["before_J"].append(before.J)
        out["before_work"].append(before.work)
        out["feasible"].append(record.feasible and before.feasible)
    return out


def _stats(values) -> dict:
    v = np.asarray(values, dtype=float)
    return {
        "n": int(v.size),
        "median_s": float(np.median(v)),
        "p95_s": float(np.percentile(v, 95)),
        "worst_s": float(v.max()),
    }


def _work_rows(works) -> np.ndarray:
    """The work model's columns (:meth:`planners.replanning.replanner.Replanner.latency`) of each replan's ``work``."""
    return np.array(
        [[w["nodes"] * w["derivative_evaluations"], w["nodes"] * w["value_evaluations"], w["horizon_s"]]
         for w in works],
        dtype=float,
    )


def _ratio(values, references, keep) -> dict:
    """Median and largest of values / references over the replans ``keep`` says (both feasible)."""
    keep = np.asarray(keep, dtype=bool)
    if not keep.any():  # no replan feasible in both versions: nothing to compare
        return {"median": None, "worst": None}
    r = np.asarray(values, dtype=float)[keep] / np.asarray(references, dtype=float)[keep]
    return {"median": float(np.median(r)), "worst": float(r.max())}


def run_replan(quick: bool, progress: bool = True) -> dict:
    """Time the replans of the module docstring; returns a JSON-friendly dict."""

    def say(text):
        if progress:
            print(f"  replan: {text}", file=sys.stderr, flush=True)

    step = 1.0 if quick else 0.5
    items = {}
    say("planning moving-target, square, gust offline (two-step)")
    moving = plan(load_mission("moving-target"), "two-step")
    square = plan(load_mission("square"), "two-step")
    gust = plan(load_mission("gust"), "two-step")
    cases = {
        "moving-target, move event at 4 s": (moving, [4.0] * (3 if quick else 7), {"move": True}),
        "square, fixed rate": (square, list(np.arange(0.25, 11.5, step)), {}),
        "gust, from a robot 5 cm off": (
            gust,
            list(np.arange(3.25, 11.0, step)),
            {"offset": np.array([0.05, 0.0, 0.0, 0.0])},
        ),
    }
    every = {}
    for name, (result, times, kw) in cases.items():
        say(name)
        got = _latencies(result, times, **kw)
        for key, values in got.items():
            every.setdefault(key, []).extend(values)
        items[name] = {
            "wall": _stats(got["wall"]),
            "cpu": _stats(got["cpu"]),
            "model": _stats(got["model"]),
            "before_wall": _stats(got["before_wall"]),
            "before_cpu": _stats(got["before_cpu"]),
            "J_over_before": _ratio(got["J"], got["before_J"], got["feasible"]),
            "used": int(sum(got["used"])),
            "runs": len(got["used"]),
        }
    rows, before_rows = _work_rows(every["work"]), _work_rows(every["before_work"])
    ratio = np.array(every["model"]) / np.array(every["wall"])
    return {
        "deadline_s": DEADLINE,
        "load_average": list(os.getloadavg()),
        "items": items,
        "square_two_step_s": square.wall_time,
        "all": {key: _stats(every[key]) for key in ("wall", "cpu", "model", "before_wall", "before_cpu")},
        "work_cost_fitted": nnls(rows, np.array(every["wall"]))[0].tolist(),
        "work_cost_fitted_cpu": nnls(rows, np.array(every["cpu"]))[0].tolist(),
        "work_cost_fitted_before": nnls(before_rows, np.array(every["before_wall"]))[0].tolist(),
        "work_cost_fitted_before_cpu": nnls(before_rows, np.array(every["before_cpu"]))[0].tolist(),
        "work_cost_in_use": list(WORK_COST),
        "model_over_wall": {
            "median": float(np.median(ratio)),
            "min": float(ratio.min()),
            "max": float(ratio.max()),
        },
        "openblas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "default"),
        "phases": replan_phases(moving, repeats=5 if quick else 15),
    }


def replan_table(doc: dict) -> str:
    """The replanning latencies as a text table."""
    ms = lambda v: f"{v * 1e3:7.1f}ms"  # noqa: E731
    lines = [
        f"replanning latency, wall clock (deadline {doc['deadline_s'] * 1e3:.0f} ms; load average "
        f"{', '.join(f'{x:.2f}' for x in doc['load_average'])}; "
        f"OPENBLAS_NUM_THREADS {doc['openblas_threads']}); "
        f"square two-step planned in {doc['square_two_step_s']:.2f} s in this run; "
        "'before': the replanner before the latency work, each replan timed right after today's",
        f"{'item':<34} {'runs':>4} {'used':>4}  {'wall median':>11} {'p95':>9} {'worst':>9}  {'model p95':>9}"
        f"  {'cpu p95':>9}  {'p95 / before':>12} {'cpu p95 / before':>16}",
    ]
    rows = list(doc["items"].items()) + [("all", {**doc["all"], "runs": doc["all"]["wall"]["n"], "used": ""})]
    for name, item in rows:
        w, m, c = item["wall"], item["model"], item["cpu"]
        bw, bc = item["before_wall"], item["before_cpu"]
        lines.append(
            f"{name:<34} {item['runs']:>4} {item['used']!s:>4}  {ms(w['median_s']):>11} {ms(w['p95_s'])} "
            f"{ms(w['worst_s'])}  {ms(m['p95_s'])}  {ms(c['p95_s'])}  {w['p95_s'] / bw['p95_s']:>12.2f} "
            f"{c['p95_s'] / bc['p95_s']:>16.2f}"
        )
    for name, item in doc["items"].items():
        j = item["J_over_before"]
        if j["median"] is None:
            lines.append(f"J / J before, {name}: no replan feasible in both versions")
            continue
        lines.append(f"J / J before (replans both feasible), {name}: median {j['median']:.3f}, "
                     f"worst {j['worst']:.3f}")
    raw = doc["all"]["wall"]["p95_s"]
    lines.append(
        f"target: 95th percentile <= {doc['deadline_s'] * 1e3:.0f} ms on the wall clock: "
        f"{'met' if raw <= doc['deadline_s'] else 'not met'} ({raw * 1e3:.1f} ms)"
    )
    cpu = doc["all"]["cpu"]["p95_s"]
    lines.append(
        f"on one core (CPU time of the process): 95th percentile {cpu * 1e3:.1f} ms: "
        f"{'met' if cpu <= doc['deadline_s'] else 'not met'}"
    )
    ratio = doc["model_over_wall"]
    lines.append(
        f"work model: fitted costs {', '.join(f'{v:.3g}' for v in doc['work_cost_fitted'])} "
        f"(to the CPU times: {', '.join(f'{v:.3g}' for v in doc['work_cost_fitted_cpu'])}; the replanner "
        f"before, wall: {', '.join(f'{v:.3g}' for v in doc['work_cost_fitted_before'])}, CPU: "
        f"{', '.join(f'{v:.3g}' for v in doc['work_cost_fitted_before_cpu'])}) "
        f"(planners.replanning.replanner.WORK_COST in use: {', '.join(f'{v:.3g}' for v in doc['work_cost_in_use'])}); "
        f"modelled / measured latency: median {ratio['median']:.2f}, range {ratio['min']:.2f} .. {ratio['max']:.2f}"
    )
    if "phases" in doc:
        lines.append(phases_table(doc["phases"]))
    return "\n".join(lines)


__all__ = ["replan_table", "run_replan"]
