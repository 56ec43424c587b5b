"""The planning section's families of random missions (``python -m fpr.bench --section planning``).

Per planar built-in robot (:data:`FAMILY_ROBOTS`), seeded random missions of :data:`WAY_POINTS` way points
(:mod:`fpr.bench.missions`: random walks in the robot's mission region, travel times derived from the stop motion's
feasibility, 0-2 via points a travel), every family of the robot (task and joint space, both assembly modes of the
prototype) with fixed seeds, :data:`SEEDS_PER_ROBOT` missions a robot in all (fewer with ``--quick``), each planned
once by both methods (:func:`fpr.bench.families.plan_family`). Beside them, in the same run: ``loop_mission(32)``
(the loop, :func:`fpr.bench.missions.loop_mission`, median of :data:`LOOP_REPEATS` plans) and the yardstick,
``pin.crba`` of the FPR (:func:`yardstick`), so that a run on another machine can be compared.

Goals, per robot and method over its missions: the 95th percentile of the plan times at most
:data:`P95_GOAL_S` and at most :data:`LOOP_RATIO_GOAL` times the loop's time (same method), no failure (every plan
feasible on the 500 Hz grid), and no J above the unpolished two-step motion's (:data:`fpr.bench.families.SAME_J_RTOL`).
"""

from __future__ import annotations

import sys
import time

import numpy as np
import pinocchio as pin

from fpr import robots
from fpr.bench.families import METHODS, FamilyRow, plan_family
from fpr.bench.missions import builtin_families, loop_mission
from fpr.bench.tables import family_label
from fpr.cli.bench.timing import Bench
from planners.optimize import plan

#: Way points of the section's missions.
WAY_POINTS = 32
#: The robots whose planning goals the families check: the planar ones, which the loop (a planar FPR mission)
#: measures the machine for. The spatial FPR's planning is timed on its tour, a row of the planning section.
FAMILY_ROBOTS = ("fpr", "prototype")
#: Missions per robot (shared among its families, seeds 0, 1, ... in each): full run / ``--quick``.
SEEDS_PER_ROBOT = {False: 20, True: 6}
#: Plans of the loop per method (the median is the ratio's reference): full run / ``--quick``.
LOOP_REPEATS = {False: 3, True: 1}
#: Goals (module docstring).
P95_GOAL_S = 3.0
LOOP_RATIO_GOAL = 3.0


def family_seeds(families, total: int) -> list[list[int]]:
    """``total`` seeds shared among ``families`` as evenly as possible, 0, 1, ... in each (the first get one more)."""
    count = len(families)
    return [list(range(total // count + (i < total % count))) for i in range(count)]


def yardstick(quick: bool) -> dict:
    """The time of ``pin.crba`` on the FPR's model at its reference pose (median per call) [s]: the machine's pace."""
    robot = robots.load("fpr")
    q = pin.neutral(robot.model)
    data = robot.model.createData()
    bench = Bench(3 if quick else 7, 0.02 if quick else 0.05, False)
    row = bench.time("pin.crba (FPR)", lambda: pin.crba(robot.model, data, q))
    return dict(name=row["name"], median_s=row["median_s"], min_s=row["min_s"])


def loop_rows(quick: bool, way_points: int = WAY_POINTS) -> dict:
    """``loop_mission(way_points)`` planned by each method :data:`LOOP_REPEATS` times: {method: row}."""
    mission = loop_mission(way_points)
    robot = mission.load_robot()
    out = {}
    for method in METHODS:
        results = [plan(mission, method, robot=robot) for _ in range(LOOP_REPEATS[quick])]
        times = [float(r.wall_time) for r in results]
        out[method] = dict(mission=mission.name, method=method, times_s=times, median_s=float(np.median(times)),
                           J=float(results[-1].J), feasible=bool(results[-1].feasible),
                           iterations=int(sum(st.iterations for st in results[-1].stages)))
    return out


def _robot_rows(rows: list[FamilyRow]) -> list[dict]:
    """Each robot's missions of all its families together, per method (the goals' rows)."""
    out = []
    for name in dict.fromkeys(r.robot for r in rows):
        for method in METHODS:
            mine = [r for r in rows if r.robot == name and r.method == method]
            times = [t for r in mine for t in r.times_s]
            out.append(dict(robot=name, method=method, missions=len(times), median_s=float(np.median(times)),
                            p95_s=float(np.percentile(times, 95)), max_s=float(max(times)),
                            failures=sum(r.failures for r in mine),
                            worse_than_unpolished=sum(r.worse_than_unpolished for r in mine),
                            J_median=float(np.nanmedian([j for r in mine for j in r.J]))))
    return out


def run_families(quick: bool, progress: bool) -> dict:
    """The families part of the planning section (module docstring): rows, robots' rows, loop, yardstick, goals."""
    say = (lambda text: print(f"bench planning families: {text}", file=sys.stderr, flush=True)) if progress else None
    start = time.perf_counter()
    crba = yardstick(quick)
    loop = loop_rows(quick)
    rows = []
    by_robot: dict[str, list] = {}
    for family in builtin_families(WAY_POINTS, FAMILY_ROBOTS):
        by_robot.setdefault(family.robot, []).append(family)
    for name, families in by_robot.items():
        robot = robots.load(name)
        for family, seeds in zip(families, family_seeds(families, SEEDS_PER_ROBOT[quick]), strict=True):
            rows += plan_family(family, seeds, robot=robot, progress=say)
    robot_rows = _robot_rows(rows)
    targets = []
    for r in robot_rows:
        reference = loop[r["method"]]["median_s"]
        label = f"{r['robot']}, {WAY_POINTS} way points, {r['method']}"
        targets += [
            dict(target=f"{label}: p95 <= {P95_GOAL_S:g} s", value=r["p95_s"], goal=P95_GOAL_S, unit="s",
                 met=bool(r["p95_s"] <= P95_GOAL_S)),
            dict(target=f"{label}: p95 <= {LOOP_RATIO_GOAL:g} x the loop's {reference:.3g} s",
                 value=r["p95_s"] / reference, goal=LOOP_RATIO_GOAL, unit="x",
                 met=bool(r["p95_s"] <= LOOP_RATIO_GOAL * reference)),
            dict(target=f"{label}: every plan feasible", value=r["failures"], goal=0, unit="failures",
                 met=r["failures"] == 0),
            dict(target=f"{label}: J never above the unpolished two-step's", value=r["worse_than_unpolished"],
                 goal=0, unit="plans", met=r["worse_than_unpolished"] == 0)]
    return dict(way_points=WAY_POINTS, seeds_per_robot=SEEDS_PER_ROBOT[quick], yardstick=crba, loop=loop,
                rows=[r.summary() for r in rows], robots=robot_rows, targets=targets,
                wall_time_s=time.perf_counter() - start)


def families_table(families: dict) -> str:
    """The families part as text: one line per family and method, the robots' lines, the loop, the yardstick (the
    goals are the planning section's, printed with its other goals).
    """
    lines = [f"planning families: random missions of {families['way_points']} way points, "
             f"{families['seeds_per_robot']} a robot (fpr.bench.missions); yardstick {families['yardstick']['name']} "
             f"{families['yardstick']['median_s'] * 1e6:.2f} us",
             f"{'family':<22} {'method':<9} {'n':>3} {'median':>8} {'p95':>8} {'max':>8} {'fail':>4} {'worse':>5} "
             f"{'J med':>7}"]
    for r in families["rows"]:
        lines.append(f"{family_label(r):<22} {r['method']:<9} {len(r['seeds']):>3} {r['median_s']:8.3f} "
                     f"{r['p95_s']:8.3f} {r['max_s']:8.3f} {r['failures']:>4} {r['worse_than_unpolished']:>5} "
                     f"{r['J_median']:7.4f}")
    for r in families["robots"]:
        lines.append(f"{r['robot'] + ' (all)':<22} {r['method']:<9} {r['missions']:>3} {r['median_s']:8.3f} "
                     f"{r['p95_s']:8.3f} {r['max_s']:8.3f} {r['failures']:>4} {r['worse_than_unpolished']:>5} "
                     f"{r['J_median']:7.4f}")
    for method, r in families["loop"].items():
        lines.append(f"{r['mission']:<22} {method:<9} {len(r['times_s']):>3} {r['median_s']:8.3f}  (the loop: "
                     f"J {r['J']:.4f}, {r['iterations']} iterations)")
    return "\n".join(lines)
