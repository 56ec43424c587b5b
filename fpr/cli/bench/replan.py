"""Replanning section of the benchmark (``python -m fpr.bench --section replan``): the latency of a replan.

Each item is one call of :meth:`planners.replan.Replanner.replan` (build the horizon's NLP, solve it by the
SQP with the replanner's own explicit options, check the result on the dense grid), timed by its wall
clock, from the offline two-step plan of a built-in mission:

a. ``moving-target``: the move event at 4 s (way point 2 to [1.2, 0.8]), start from the plan in force;
b. ``square`` at a fixed rate: a replan every 0.5 s (0.25 .. 11.25 s; 1 s with ``--quick``), start from the
   plan in force (the re-optimisation of the rest of the current travel);
c. ``gust``: replans from a robot pushed off the plan (5 cm along y, at rest relative to the plan, the start a
   tracking-error replan builds), every 0.5 s from 3.25 s (1 s with ``--quick``).

Reported per item and over all of them: median, 95th percentile and worst wall time, against the default
deadline (50 ms), and the deterministic latency of the ``work`` model (:data:`planners.replan.WORK_COST`)
with the ratio wall / model (how well the model matches this machine). The load average is printed with
the numbers: on a shared machine the wall times grow several times (run with ``OPENBLAS_NUM_THREADS=1``).
"""

from __future__ import annotations

import os
import sys

import numpy as np

from planners.mission import load_mission
from planners.optimize import plan
from planners.replan import ReplanOptions, Replanner, jet

DEADLINE = ReplanOptions().deadline


def _latencies(result, times, *, move=False, offset=None, options=None):
    walls, models, used = [], [], []
    for t in times:
        replanner = Replanner(result, options or ReplanOptions(samples_per_segment=9))
        if move:
            replanner.move(0)
        start = None
        if offset is not None:
            start = jet(result.trajectory, t + replanner.options.deadline)
            start[0] = start[0] + offset
        record = replanner.replan(float(t), "bench", start=start)
        walls.append(record.solve_wall_s)
        models.append(record.latency_s)
        used.append(record.used)
    return walls, models, used


def _stats(values) -> dict:
    v = np.asarray(values, dtype=float)
    return {"n": int(v.size), "median_s": float(np.median(v)), "p95_s": float(np.percentile(v, 95)),
            "worst_s": float(v.max())}


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
        "gust, from a robot 5 cm off": (gust, list(np.arange(3.25, 11.0, step)),
                                        {"offset": np.array([0.05, 0.0, 0.0, 0.0])}),
    }
    every_wall, every_model = [], []
    for name, (result, times, kw) in cases.items():
        say(name)
        walls, models, used = _latencies(result, times, **kw)
        every_wall += walls
        every_model += models
        items[name] = {"wall": _stats(walls), "model": _stats(models), "used": int(sum(used)), "runs": len(used),
                       "wall_over_model": float(np.median(np.array(walls) / np.array(models)))}
    return {"deadline_s": DEADLINE, "load_average": list(os.getloadavg()), "items": items,
            "all": {"wall": _stats(every_wall), "model": _stats(every_model),
                    "wall_over_model": float(np.median(np.array(every_wall) / np.array(every_model)))},
            "openblas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "default")}


def replan_table(doc: dict) -> str:
    """The replanning latencies as a text table."""
    lines = [f"replanning latency (deadline {doc['deadline_s'] * 1e3:.0f} ms; load average "
             f"{', '.join(f'{x:.2f}' for x in doc['load_average'])}; OPENBLAS_NUM_THREADS {doc['openblas_threads']})",
             f"{'item':<36} {'runs':>4} {'used':>4}  {'median':>8} {'p95':>8} {'worst':>8}  "
             f"{'model p95':>9}  wall/model"]
    rows = list(doc["items"].items()) + [("all", {**doc["all"], "runs": doc["all"]["wall"]["n"], "used": ""})]
    for name, item in rows:
        w, m = item["wall"], item["model"]
        lines.append(f"{name:<36} {item['runs']:>4} {item['used']!s:>4}  {w['median_s'] * 1e3:6.1f}ms "
                     f"{w['p95_s'] * 1e3:6.1f}ms {w['worst_s'] * 1e3:6.1f}ms  {m['p95_s'] * 1e3:7.1f}ms  "
                     f"{item['wall_over_model']:.2f}")
    p95 = doc["all"]["wall"]["p95_s"]
    lines.append(f"target: 95th percentile <= {doc['deadline_s'] * 1e3:.0f} ms: "
                 f"{'met' if p95 <= doc['deadline_s'] else 'not met'} ({p95 * 1e3:.1f} ms here)")
    return "\n".join(lines)


__all__ = ["replan_table", "run_replan"]
