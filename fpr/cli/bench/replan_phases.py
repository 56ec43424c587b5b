"""Where a replan's time goes: its phases timed one by one (part of ``python -m fpr.bench --section replan``).

The moving-target replan (the move event at 4 s, 28 grid nodes) is taken apart: the NLP's set-up
(:meth:`planners.replanning.replanner.Replanner.problem`), a derivative evaluation and its inverse dynamics
alone, a value evaluation, one step QP (:func:`planners.replanning.solver.qp_step`), the dense check
(:func:`planners.problem.disturbance.dense_check`) and the value evaluation fused with it
(:func:`planners.replanning.check.evaluate_and_check`). Each phase is repeated and its **minimum** CPU time
(``time.process_time``) kept: the least the phase takes on this machine, which the other jobs of a shared
machine inflate the least.
"""

from __future__ import annotations

import time

import numpy as np

from fpr.model.inverse_dynamics import inverse_dynamics
from planners.problem.disturbance import dense_check
from planners.problem.sensitivities import seeded_motion
from planners.replanning.check import evaluate_and_check
from planners.replanning.replanner import Replanner, ReplanOptions
from planners.replanning.solver import qp_step
from planners.trajectory.polynomial import PiecewisePolynomial


def _least(call, repeats: int) -> float:
    """The minimum CPU time of ``repeats`` calls [s] (after one call to warm up)."""
    call()
    best = np.inf
    for _ in range(repeats):
        begin = time.process_time()
        call()
        best = min(best, time.process_time() - begin)
    return float(best)


def replan_phases(result, repeats: int = 15) -> dict:
    """The phases of the moving-target replan of ``result`` (its offline plan), minimum CPU time each [s]."""
    replanner = Replanner(result, ReplanOptions())
    replanner.move(0)
    t_s = 4.0 + replanner.options.deadline
    problem, x0, _, _ = replanner.problem(t_s)
    rate = replanner.options.dense_rate

    def fresh(call):
        def run():
            problem._cache = None  # every call evaluates (the NLP keeps its last evaluation)
            return call()
        return run

    # what a derivative evaluation sends through the inverse dynamics (planners/problem/motion.py): the motion on
    # dual numbers, seeded with its 5 n directions
    motion = problem.motion(problem.points_of(x0))
    n_r, _, n = motion.shape
    seeded = seeded_motion(motion)
    first = problem.evaluate(x0, True)
    part = PiecewisePolynomial(problem.points_of(x0), problem.durations)
    phases = {
        "set-up of the NLP": _least(lambda: replanner.problem(t_s), repeats),
        "derivative evaluation": _least(fresh(lambda: problem.evaluate(x0, True)), repeats),
        "  its inverse dynamics": _least(lambda: inverse_dynamics(problem.robot, seeded), repeats),
        "value evaluation": _least(fresh(lambda: problem.evaluate(x0)), repeats),
        "step QP": _least(lambda: qp_step(first, replanner.options.radius, 10.0), repeats),
        "dense check": _least(lambda: dense_check(problem.robot, part, rate, t_s), repeats),
        "value evaluation + dense check, fused": _least(
            fresh(lambda: evaluate_and_check(problem, x0, rate, t_s)), repeats
        ),
    }
    return {"nodes": int(problem.t.size), "directions": int(n_r * n),
            "dense_samples": int(dense_check(problem.robot, part, rate, t_s)[2]), "repeats": repeats,
            "cpu_s": phases}


def phases_table(doc: dict) -> str:
    """The phases as text lines."""
    lines = [f"moving-target replan taken apart ({doc['nodes']} nodes, {doc['directions']} dual directions a node, "
             f"{doc['dense_samples']} dense samples; minimum CPU time of {doc['repeats']} runs):"]
    lines += [f"  {name:<40} {value * 1e3:7.2f} ms" for name, value in doc["cpu_s"].items()]
    return "\n".join(lines)


__all__ = ["phases_table", "replan_phases"]
