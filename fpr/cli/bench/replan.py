"""Replanning section of the benchmark (``python -m fpr.bench --section replan``): the latency of a replan.

First the section **calibrates this machine**: the replanner's latency model is measured for each robot
(:func:`planners.replanning.replanner.measure_latency`) and written to the machine's calibration file
(:func:`planners.replanning.latency.default_path`), which every later replanning run on this machine reads
(:mod:`planners.replanning.latency`: the same command gives the same bytes). Then each item is a series of
calls of :meth:`planners.replanning.replanner.Replanner.replan` (build the horizon's NLP, solve it, check the
result on the dense grid) from the offline two-step plan of a built-in mission, timed by the wall clock
and the process's CPU time:

a. ``moving-target``: the move event at 4 s (way point 2 to [1.2, 0.8]), repeated;
b. ``square`` at a fixed rate: a replan every 0.5 s (0.25 .. 11.25 s; 1 s with ``--quick``);
c. ``prototype-tour`` at a fixed rate: a replan every 2 s (4 s with ``--quick``);
d. ``gust``: solves from a robot pushed off the plan (5 cm along y, at rest relative to the plan), every
   0.5 s from 3.25 s (1 s with ``--quick``): timed only, such a plan is not spliced in (it is not C4 with the
   plan in force, :mod:`planners.replanning.replanner`).

Reported: per item and over all, the median, 95th percentile and worst wall time against the default
deadline (50 ms), on this machine's clock as it is (a shared machine's load, printed, slows it), and the
95th percentile of the CPU time (one core's work, which other jobs inflate less); the **latency
distribution** over all the replans (percentiles and a histogram in 5 ms bins); the modelled latency (the
new calibration) against the measured one (median and range of their ratio); the moving-target replan taken
apart into its phases (:mod:`fpr.cli.bench.replan_phases`). ``--json`` gives all of it as a document.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

from fpr.cli.bench.replan_phases import phases_table, replan_phases
from planners.missions.mission import load_mission
from planners.optimize import plan
from planners.replanning.latency import LatencyModel, default_path, write_calibration
from planners.replanning.replanner import Replanner, ReplanOptions, jet, measure_latency

DEADLINE = ReplanOptions().deadline
PERCENTILES = (50, 90, 95, 99)
BIN = 0.005  # histogram bin of the latency distribution [s]


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


def _latencies(result, times, options, *, move=False, offset=None):
    out = {key: [] for key in ("wall", "cpu", "model", "used", "delayed")}
    for t in times:
        record, cpu = _replan(result, t, move, offset, options)
        out["wall"].append(record.solve_wall_s)
        out["cpu"].append(cpu)
        out["model"].append(record.latency_s)
        out["used"].append(record.used)
        out["delayed"].append(record.delayed_s > 0)
    return out


def _stats(values) -> dict:
    v = np.asarray(values, dtype=float)
    return {"n": int(v.size), "median_s": float(np.median(v)), "p95_s": float(np.percentile(v, 95)),
            "worst_s": float(v.max())}


def distribution(values) -> dict:
    """The latency distribution of ``values`` [s]: count, percentiles, mean, worst, and a histogram in
    :data:`BIN` bins (``edges_s`` n + 1, ``counts`` n).
    """
    v = np.asarray(values, dtype=float)
    edges = np.arange(0.0, max(float(v.max()), BIN) + BIN, BIN)
    counts, edges = np.histogram(v, bins=edges)
    return {"n": int(v.size), **{f"p{p}_s": float(np.percentile(v, p)) for p in PERCENTILES},
            "mean_s": float(v.mean()), "worst_s": float(v.max()), "edges_s": edges.tolist(),
            "counts": counts.tolist()}


def calibrate(robots, say) -> dict:
    """Measure each robot's latency model on this machine and write the calibration file; their costs."""
    path = default_path()
    out = {"file": str(path), "robots": {}}
    for robot in robots:
        say(f"calibrating the latency model of the {robot.name} robot")
        model = measure_latency(robot)
        write_calibration(path, robot.name, model)
        out["robots"][robot.name] = model.to_dict()
    return out


def run_replan(quick: bool, progress: bool = True) -> dict:
    """Calibrate this machine, time the replans of the module docstring; returns a JSON-friendly dict."""

    def say(text):
        if progress:
            print(f"  replan: {text}", file=sys.stderr, flush=True)

    step = 1.0 if quick else 0.5
    say("planning moving-target, square, prototype-tour, gust offline (two-step)")
    moving = plan(load_mission("moving-target"), "two-step")
    square = plan(load_mission("square"), "two-step")
    tour = plan(load_mission("prototype-tour"), "two-step")
    gust = plan(load_mission("gust"), "two-step")
    calibration = calibrate((square.robot, tour.robot), say)
    models = calibration["robots"]
    cases = {
        "moving-target, move event at 4 s": (moving, [4.0] * (3 if quick else 7), {"move": True}),
        "square, fixed rate": (square, list(np.arange(0.25, 11.5, step)), {}),
        "prototype-tour, fixed rate": (tour, list(np.arange(1.0, 49.0, 4 * step)), {}),
        "gust, from a robot 5 cm off": (gust, list(np.arange(3.25, 11.0, step)),
                                        {"offset": np.array([0.05, 0.0, 0.0, 0.0])}),
    }
    items, every = {}, {"wall": [], "cpu": [], "model": []}
    for name, (result, times, kw) in cases.items():
        say(name)
        options = ReplanOptions(latency=LatencyModel.from_dict(models[result.robot.name]))
        got = _latencies(result, times, options, **kw)
        for key in every:
            every[key].extend(got[key])
        items[name] = {"wall": _stats(got["wall"]), "cpu": _stats(got["cpu"]), "model": _stats(got["model"]),
                       "used": int(sum(got["used"])), "delayed": int(sum(got["delayed"])), "runs": len(got["used"])}
    ratio = np.array(every["model"]) / np.array(every["wall"])
    return {
        "deadline_s": DEADLINE,
        "load_average": list(os.getloadavg()),
        "openblas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "default"),
        "calibration": calibration,
        "items": items,
        "all": {key: _stats(every[key]) for key in ("wall", "cpu", "model")},
        "distribution": {"wall": distribution(every["wall"]), "cpu": distribution(every["cpu"])},
        "model_over_wall": {"median": float(np.median(ratio)), "min": float(ratio.min()), "max": float(ratio.max())},
        "phases": replan_phases(moving, repeats=5 if quick else 15),
    }


def replan_table(doc: dict) -> str:
    """The replanning latencies as a text table."""
    ms = lambda v: f"{v * 1e3:7.1f}ms"  # noqa: E731
    lines = [
        f"replanning latency, wall clock (deadline {doc['deadline_s'] * 1e3:.0f} ms; load average "
        f"{', '.join(f'{x:.2f}' for x in doc['load_average'])}; OPENBLAS_NUM_THREADS {doc['openblas_threads']})",
        f"this machine's calibration written to {doc['calibration']['file']}: "
        + "; ".join(f"{name} {', '.join(f'{c:.3g}' for c in entry['costs'])}"
                    for name, entry in doc["calibration"]["robots"].items()),
        f"{'item':<34} {'runs':>4} {'used':>4} {'later':>5}  {'wall median':>11} {'p95':>9} {'worst':>9}"
        f"  {'model p95':>9}  {'cpu p95':>9}",
    ]
    rows = list(doc["items"].items()) + [("all", {**doc["all"], "runs": doc["all"]["wall"]["n"], "used": "",
                                                  "delayed": ""})]
    for name, item in rows:
        w, m, c = item["wall"], item["model"], item["cpu"]
        lines.append(f"{name:<34} {item['runs']:>4} {item['used']!s:>4} {item['delayed']!s:>5}  "
                     f"{ms(w['median_s']):>11} {ms(w['p95_s'])} {ms(w['worst_s'])}  {ms(m['p95_s'])}  {ms(c['p95_s'])}")
    wall = doc["distribution"]["wall"]
    lines.append("latency distribution (wall): "
                 + ", ".join(f"p{p} {wall[f'p{p}_s'] * 1e3:.1f} ms" for p in PERCENTILES)
                 + f", worst {wall['worst_s'] * 1e3:.1f} ms over {wall['n']} replans")
    lines.append("  " + "  ".join(f"{a * 1e3:.0f}-{b * 1e3:.0f} ms: {n}"
                                  for a, b, n in zip(wall["edges_s"], wall["edges_s"][1:], wall["counts"], strict=False)
                                  if n))
    raw = doc["all"]["wall"]["p95_s"]
    lines.append(f"target: 95th percentile <= {doc['deadline_s'] * 1e3:.0f} ms on the wall clock: "
                 f"{'met' if raw <= doc['deadline_s'] else 'not met'} ({raw * 1e3:.1f} ms)")
    ratio = doc["model_over_wall"]
    lines.append(f"modelled / measured latency (the calibration just written): median {ratio['median']:.2f}, range "
                 f"{ratio['min']:.2f} .. {ratio['max']:.2f}")
    if "phases" in doc:
        lines.append(phases_table(doc["phases"]))
    return "\n".join(lines)


__all__ = ["distribution", "replan_table", "run_replan"]
