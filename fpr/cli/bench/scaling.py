"""Scaling section of the benchmark (``python -m fpr.bench --section scaling``): planning time by length.

Missions of 4, 8, 16 and 32 way points round a circle (:func:`fpr.bench.missions.loop_mission`:
every travel a 0.5 m chord in 1.5 s), with 0 to 4 via points per travel (``--quick``: 1 only), each
planned once by ``plan(mission, method)`` with the planner's defaults, both methods, one after the other
in one process. Per (way points, via points, method): the wall time of the whole call (reference and
dense check included), J, the dense-grid feasibility and the SQP iterations of all stages. Per method
and via-point count, the growth exponent: the least-squares slope of log(time) over log(way points),
8 to 32 (4 way points are two interior ones only: too few to show the growth).

Goals, at 1 via point: 32 way points planned in at most 2 s (two-step) and 30 s (one-step),
growth exponents at most 1.5. Timings depend on the machine and its load: no test asserts them.
"""

from __future__ import annotations

import os
import sys

import numpy as np

from fpr.cli.bench.timing import fmt
from fpr.bench.missions import loop_mission
from planners.optimize import plan

WAY_POINTS = (4, 8, 16, 32)
VIA_POINTS = {True: (1,), False: (0, 1, 2, 3, 4)}  # quick / full
METHODS = ("two-step", "one-step")
#: The way-point counts the growth exponent is fitted over.
FIT_FROM = 8
#: Goals at 1 via point per travel: time at 32 way points [s] per method, and the exponent.
TIME_GOALS = {"two-step": 2.0, "one-step": 30.0}
EXPONENT_GOAL = 1.5
GOAL_VIA_POINTS = 1


def growth_exponent(counts, times) -> float:
    """The least-squares slope of log(time) over log(count) for the counts >= :data:`FIT_FROM`."""
    counts, times = np.asarray(counts, dtype=float), np.asarray(times, dtype=float)
    keep = counts >= FIT_FROM
    return float(np.polyfit(np.log(counts[keep]), np.log(times[keep]), 1)[0])


def run_scaling(quick: bool, progress: bool, way_points=WAY_POINTS, via_points=None) -> dict:
    """Plan every (way points, via points, method) once; returns the rows, exponents and goals."""
    via_points = VIA_POINTS[quick] if via_points is None else tuple(via_points)
    say = (lambda text: print(text, file=sys.stderr, flush=True)) if progress else (lambda text: None)
    load_before = os.getloadavg()
    robot = loop_mission(4).load_robot()
    plan(loop_mission(3, 0), "two-step", robot=robot, max_iterations=2)  # warm up (imports, caches)
    rows = []
    for n_vp in via_points:
        for count in way_points:
            for method in METHODS:
                result = plan(loop_mission(count, n_vp), method, robot=robot)
                rows.append(dict(way_points=count, via_points=n_vp, method=method,
                                 wall_time_s=float(result.wall_time), J=float(result.J),
                                 feasible=bool(result.feasible),
                                 iterations=int(sum(st.iterations for st in result.stages)),
                                 variables=int(max(st.n_variables for st in result.stages))))
                say(f"bench scaling: {count} way points, {n_vp} via points, {method}: "
                    f"{result.wall_time:.2f} s, J {result.J:.4f}")
    exponents = []
    for n_vp in via_points:
        for method in METHODS:
            mine = [r for r in rows if r["via_points"] == n_vp and r["method"] == method]
            counts = [r["way_points"] for r in mine]
            if sum(c >= FIT_FROM for c in counts) >= 2:
                exponents.append(dict(via_points=n_vp, method=method,
                                      exponent=growth_exponent(counts, [r["wall_time_s"] for r in mine])))
    return dict(rows=rows, exponents=exponents, targets=_targets(rows, exponents),
                load_average_before=load_before, load_average_after=os.getloadavg())


def _targets(rows, exponents) -> list[dict]:
    """The goals of the module docstring that the rows measured (value, goal, unit, met)."""
    out = []
    for method, goal in TIME_GOALS.items():
        row = next((r for r in rows if r["way_points"] == 32 and r["via_points"] == GOAL_VIA_POINTS
                    and r["method"] == method), None)
        if row is not None:
            out.append(dict(target=f"32 way points, {method} <= {goal:g} s", value=row["wall_time_s"],
                            goal=goal, unit="s", met=bool(row["wall_time_s"] <= goal)))
    for e in exponents:
        if e["via_points"] == GOAL_VIA_POINTS:
            out.append(dict(target=f"growth exponent in the way points, {e['method']} <= {EXPONENT_GOAL:g}",
                            value=e["exponent"], goal=EXPONENT_GOAL, unit="",
                            met=bool(e["exponent"] <= EXPONENT_GOAL)))
    return out


def scaling_table(scaling: dict) -> str:
    """The scaling section as text: one line per (way points, via points), both methods side by side."""
    lines = [f"planning scaling, loop missions (fpr.bench.missions; load average "
             f"{scaling['load_average_before'][0]:.2f} -> {scaling['load_average_after'][0]:.2f})",
             f"{'way points':>10}  {'via':>3}  " + "  ".join(
                 f"{m + ' time':>15}  {'J':>7}  {'iter':>4}  {'feas':>4}" for m in METHODS)]
    keys = dict.fromkeys((r["way_points"], r["via_points"]) for r in scaling["rows"])
    for count, n_vp in sorted(keys, key=lambda k: (k[1], k[0])):
        cells = []
        for method in METHODS:
            r = next(r for r in scaling["rows"] if (r["way_points"], r["via_points"], r["method"]) ==
                     (count, n_vp, method))
            cells.append(f"{fmt(r['wall_time_s']):>15}  {r['J']:7.4f}  {r['iterations']:4d}  "
                         f"{'yes' if r['feasible'] else 'no':>4}")
        lines.append(f"{count:>10}  {n_vp:>3}  " + "  ".join(cells))
    for e in scaling["exponents"]:
        lines.append(f"growth exponent ({FIT_FROM}..32 way points), {e['via_points']} via points, "
                     f"{e['method']}: {e['exponent']:.2f}")
    for t in scaling["targets"]:
        lines.append(f"target {t['target']}: {t['value']:.4g} -> {'met' if t['met'] else 'NOT met'}")
    return "\n".join(lines)
