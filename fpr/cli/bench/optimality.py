"""How close the planners get to the optimum, part of ``python -m fpr.bench --section planning``.

For each built-in mission of :data:`MISSIONS` and each planner of :data:`PLANNERS`, one run: the dense-grid
J, the best J known for that mission (:data:`BEST_J`) and the gap to it, the KKT residual the solver
reports for its last stage (:mod:`planners.optimisation.sqp`), the KKT residual of the result as a point of the
whole 1-step NLP (the same for every method: multipliers by non-negative least squares on the
constraints within 1e-6 of their bound, :func:`planners.optimisation.solving.kkt_with_best_multipliers`), the
iterations, the time, and whether the plan holds every constraint on the dense grid.
"""

from __future__ import annotations

import sys
import time

from planners.methods import METHODS
from planners.methods.one_step import one_step_problem
from planners.methods.way_points import WayPointTask
from planners.missions.mission import load_mission
from planners.optimisation.solving import Grid, kkt_with_best_multipliers
from planners.options import PlanOptions

#: The best J known per mission: peer solvers (scipy's SLSQP with the planner's exact derivatives, tight
#: tolerances, several starts; IPOPT confirming a KKT point), every result feasible on the 500 Hz
#: grid.
BEST_J = {"square": 0.5037, "prototype-tour": 0.6895, "study, n_vp = 3": 0.6654}

#: (name in the table, mission name, mission changes).
MISSIONS = (("square", "square", {}), ("prototype-tour", "prototype-tour", {}),
            ("study, n_vp = 3", "study", {"via_points": 3}))

#: (name in the table, method, PlanOptions fields, also with --quick).
PLANNERS = (
    ("one-step (default)", "one-step", {}, True),
    ("one-step, thesis (GN, stop)", "one-step", {"curvature": "gauss-newton", "one_step_start": "stop"},
     True),
    ("two-step (thesis, no polish)", "two-step", {"polish": False}, True),
    ("two-step (polished, default)", "two-step", {}, True),
    ("one-step, composite, KKT stop", "one-step",
     {"curvature": "composite", "stop": "kkt", "max_iterations": 60}, False),
)


def run_optimality(quick: bool, progress: bool) -> list[dict]:
    """One row per mission and planner (the module docstring); ``quick`` leaves the slow planners out."""
    rows = []
    for label, name, changes in MISSIONS:
        mission = load_mission(name).replace(**changes) if changes else load_mission(name)
        robot = mission.load_robot()
        whole = one_step_problem(WayPointTask.of(mission, robot), Grid())
        for planner, method, fields, in_quick in PLANNERS:
            if quick and not in_quick:
                continue
            start = time.perf_counter()
            result = METHODS[method](mission, robot, PlanOptions(**fields))
            elapsed = time.perf_counter() - start
            ev = whole.evaluate(whole.x_of(result.trajectory.points), True)
            best = BEST_J[label]
            rows.append(dict(mission=label, planner=planner, J=float(result.J), best_J=best,
                             gap=float(result.J / best - 1.0), solver_kkt=float(result.stages[-1].kkt),
                             one_step_kkt=float(kkt_with_best_multipliers(ev).residual),
                             iterations=int(sum(st.iterations for st in result.stages)), wall_time_s=elapsed,
                             feasible=bool(result.feasible)))
            if progress:
                r = rows[-1]
                print(f"bench planning optimality: {label}, {planner}: J {r['J']:.4f} ({r['gap']:+.2%}), "
                      f"{elapsed:.1f} s", file=sys.stderr, flush=True)
    return rows


def optimality_table(rows: list[dict]) -> str:
    """The rows as text."""
    lines = ["optimality: J against the best known, KKT residuals (solver's last stage; the "
             "result as a point of the 1-step NLP)",
             f"{'mission':<16} {'planner':<30} {'J':>7} {'best J':>7} {'gap':>7} {'KKT stage':>9} "
             f"{'KKT 1-step':>10} {'iter':>5} {'time':>8}  feasible"]
    for r in rows:
        lines.append(f"{r['mission']:<16} {r['planner']:<30} {r['J']:7.4f} {r['best_J']:7.4f} "
                     f"{r['gap']:+7.2%} "
                     f"{r['solver_kkt']:9.2g} {r['one_step_kkt']:10.2g} {r['iterations']:5d} "
                     f"{r['wall_time_s']:7.2f}s  {'yes' if r['feasible'] else 'NO'}")
    return "\n".join(lines)
