"""Scaling section of the benchmark (``python -m fpr.bench --section scaling``): planning time by length.

Seeded families of random missions (:mod:`fpr.bench.missions`: random walks in each built-in robot's mission
region, travel times derived from the stop motion's feasibility, 0-2 via points a travel) of
:data:`WAY_POINTS` way points, each planned once by both methods in one process
(:func:`fpr.bench.families.plan_family`): per robot, length and method the median, 95th percentile and failures
of the plan times, and J. A robot's members of one length are its families' (task and joint space, both
assembly modes) with seeds 0, 1, ..., :data:`MEMBERS` in all (fewer with ``--quick``). The loop
(:func:`fpr.bench.missions.loop_mission`, 1 via point a travel) is one more row per length.

Per robot and method, the growth exponent: the least-squares slope of log(median time) over log(way points)
from :data:`FIT_FROM` way points on (4 way points are two interior ones only: too few to show the growth).
Goal: at most :data:`EXPONENT_GOAL`. Timings depend on the machine and its load: no test asserts them; the
yardstick ``pin.crba`` of the same run (:func:`fpr.cli.bench.families.yardstick`) says how fast the machine was.
"""

from __future__ import annotations

import os
import sys

import numpy as np

from fpr import robots
from fpr.bench.families import METHODS, plan_family
from fpr.bench.missions import builtin_families, loop_mission
from fpr.cli.bench.families import FAMILY_ROBOTS, family_seeds, yardstick
from fpr.cli.bench.timing import fmt
from planners.optimize import plan

WAY_POINTS = (4, 8, 16, 32, 64)
#: Missions per robot and length (shared among the robot's families): full run / ``--quick``.
MEMBERS = {False: 6, True: 2}
#: The way-point counts the growth exponent is fitted over (from this one on).
FIT_FROM = 8
#: Goal on the growth exponent of the median time, per robot and method.
EXPONENT_GOAL = 1.2


def growth_exponent(counts, times) -> float:
    """The least-squares slope of log(time) over log(count) for the counts >= :data:`FIT_FROM`."""
    counts, times = np.asarray(counts, dtype=float), np.asarray(times, dtype=float)
    keep = counts >= FIT_FROM
    return float(np.polyfit(np.log(counts[keep]), np.log(times[keep]), 1)[0])


def run_scaling(quick: bool, progress: bool, way_points=WAY_POINTS) -> dict:
    """Plan every (robot, length, member, method) once, and the loop; returns the rows, exponents and goals."""
    say = (lambda text: print(f"bench scaling: {text}", file=sys.stderr, flush=True)) if progress else None
    load_before = os.getloadavg()
    crba = yardstick(quick)
    rows, loop = [], []
    loop_robot = loop_mission(4).load_robot()
    plan(loop_mission(3, 0), "two-step", robot=loop_robot, max_iterations=2)  # warm up (imports, caches)
    for count in way_points:
        by_robot: dict[str, list] = {}
        for family in builtin_families(count, FAMILY_ROBOTS):
            by_robot.setdefault(family.robot, []).append(family)
        for name, families in by_robot.items():
            robot = robots.load(name)
            for family, seeds in zip(families, family_seeds(families, MEMBERS[quick]), strict=True):
                if seeds:
                    rows += [r.summary() for r in plan_family(family, seeds, robot=robot, progress=say)]
        mission = loop_mission(count)
        for method in METHODS:
            result = plan(mission, method, robot=loop_robot)
            loop.append(dict(way_points=count, method=method, wall_time_s=float(result.wall_time),
                             J=float(result.J), feasible=bool(result.feasible),
                             iterations=int(sum(st.iterations for st in result.stages))))
            if say:
                say(f"loop-{count}, {method}: {result.wall_time:.2f} s, J {result.J:.4f}")
    summary = _by_robot(rows)
    exponents = []
    for name in dict.fromkeys(r["robot"] for r in summary):
        for method in METHODS:
            mine = sorted((r for r in summary if r["robot"] == name and r["method"] == method),
                          key=lambda r: r["way_points"])
            counts = [r["way_points"] for r in mine]
            if sum(c >= FIT_FROM for c in counts) >= 2:
                exponents.append(dict(robot=name, method=method,
                                      exponent=growth_exponent(counts, [r["median_s"] for r in mine])))
    return dict(rows=rows, robots=summary, loop=loop, exponents=exponents, targets=_targets(exponents),
                yardstick=crba, members=MEMBERS[quick], load_average_before=load_before,
                load_average_after=os.getloadavg())


def _by_robot(rows: list[dict]) -> list[dict]:
    """Per robot, length and method, its families' missions together: median, p95, failures, J."""
    out = []
    keys = dict.fromkeys((r["robot"], r["way_points"], r["method"]) for r in rows)
    for name, count, method in keys:
        mine = [r for r in rows if (r["robot"], r["way_points"], r["method"]) == (name, count, method)]
        times = [t for r in mine for t in r["times_s"]]
        out.append(dict(robot=name, way_points=count, method=method, missions=len(times),
                        median_s=float(np.median(times)), p95_s=float(np.percentile(times, 95)),
                        failures=sum(r["failures"] for r in mine),
                        J_median=float(np.nanmedian([j for r in mine for j in r["J"]]))))
    return out


def _targets(exponents) -> list[dict]:
    """The goal of the module docstring per robot and method (value, goal, unit, met)."""
    return [dict(target=f"growth exponent of the median time, {FIT_FROM}..{max(WAY_POINTS)} way points, "
                        f"{e['robot']}, {e['method']} <= {EXPONENT_GOAL:g}",
                 value=e["exponent"], goal=EXPONENT_GOAL, unit="", met=bool(e["exponent"] <= EXPONENT_GOAL))
            for e in exponents]


def scaling_table(scaling: dict) -> str:
    """The scaling section as text: one line per (robot, way points), both methods side by side; the loop."""
    lines = [f"planning scaling: random mission families, {scaling['members']} missions a robot and length "
             f"(fpr.bench.missions; load average {scaling['load_average_before'][0]:.2f} -> "
             f"{scaling['load_average_after'][0]:.2f}; yardstick {scaling['yardstick']['name']} "
             f"{scaling['yardstick']['median_s'] * 1e6:.2f} us)",
             f"{'robot':<10} {'way points':>10}  " + "  ".join(
                 f"{m + ' median':>16} {'p95':>10} {'fail':>4} {'J':>7}" for m in METHODS)]
    keys = dict.fromkeys((r["robot"], r["way_points"]) for r in scaling["robots"])
    for name, count in keys:
        cells = []
        for method in METHODS:
            r = next(r for r in scaling["robots"] if (r["robot"], r["way_points"], r["method"]) ==
                     (name, count, method))
            cells.append(f"{fmt(r['median_s']):>16} {fmt(r['p95_s']):>10} {r['failures']:>4} {r['J_median']:7.4f}")
        lines.append(f"{name:<10} {count:>10}  " + "  ".join(cells))
    for count in dict.fromkeys(r["way_points"] for r in scaling["loop"]):
        cells = []
        for method in METHODS:
            r = next(r for r in scaling["loop"] if (r["way_points"], r["method"]) == (count, method))
            cells.append(f"{fmt(r['wall_time_s']):>16} {'':>10} {0 if r['feasible'] else 1:>4} {r['J']:7.4f}")
        lines.append(f"{'loop':<10} {count:>10}  " + "  ".join(cells))
    for e in scaling["exponents"]:
        lines.append(f"growth exponent ({FIT_FROM}..{max(WAY_POINTS)} way points), {e['robot']}, {e['method']}: "
                     f"{e['exponent']:.2f}")
    for t in scaling["targets"]:
        lines.append(f"target {t['target']}: {t['value']:.4g} -> {'met' if t['met'] else 'NOT met'}")
    return "\n".join(lines)
