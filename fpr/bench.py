"""Benchmark of the dynamics models and the planner: ``python -m fpr.bench [--quick] [--json] [--section S]``.

All items run in one process, one after the other, so that their ratios mean something on a shared,
noisy machine. Each is a loop sized to last ~50 ms (20 ms with ``--quick``), repeated 7 times (3 with
``--quick``), garbage collector off; reported: median and min over repeats of the time per call
(``time.perf_counter``), the time per sample, and a ratio (per-sample time / a reference's):

1. The FPR :class:`~fpr.robots.Robot` in thesis coordinates (mass matrix, nonlinear effects, drone
   Jacobians, forward dynamics, attitude model) against the raw Pinocchio calls underneath (``crba``,
   ``nonLinearEffects``, ``computeJointJacobians`` + ``getFrameJacobian``, ``aba``): the ratio is the
   wrapper's overhead. Random states near ``phi = 5 pi / 4, q21 = pi / 2``.
2. The closed-form planar model (:mod:`fpr.planar`), batched over N = 1000, against Pinocchio per call.
3. :func:`fpr.inverse_dynamics.inverse_dynamics` along a sine motion of N = 2000 samples (FPR,
   prototype), against one minimal forward dynamics call.
4. The closed chain (:func:`fpr.constrained.build_closed_chain`): generalised input and constraint
   dynamics per call, against the minimal forward dynamics.

It also prints accuracy figures (not timings): the largest difference between the closed-chain and
the minimal accelerations over 100 random states and inputs, and the round-trip residual inverse
dynamics -> forward dynamics along a 50-sample motion, with d = 0 (exact) and with the default d
(roll rows exact, chain rows off by the p_i perturbation of seed eq. 2.7-2.8).

Timings depend on the machine and its load: no test asserts them. The accuracy figures are asserted,
with tolerances, in tests/test_constrained.py and tests/test_inverse_dynamics.py.

Planning section (``--section planning``), on the built-in ``square`` mission (n_vp = 1, alpha = 0.5),
side by side in one run:

a. ``plan(mission, "two-step")`` and b. ``plan(mission, "one-step")``: our exact-gradient Gauss-Newton
   SQP (median of 3 runs, 1 with ``--quick``);
c. ``plan(mission, "one-step", solver="slsqp")``: the same NLP, scipy SLSQP with our exact gradients;
d. a baseline mimicking the thesis' fmincon runs: scipy ``minimize(method="trust-constr")`` (interior
   point) on the same :class:`~planners.problem.MotionProblem`, with 2-point finite-difference gradients
   of J and of the constraints and BFGS Hessian approximations, stopped by a time cap (120 s, 15 s with
   ``--quick``). Its J is the dense-grid J of its last iterate, normalised by the same stop-at-way-points
   motion as ours; "time to our J" is when an iterate first held the grid constraints (1e-6) with a grid
   J at most ours (+1e-4 relative, the SQP's stopping tolerance);
e. re-optimising one segment: step 2 of the two-step method on travel 1, from the step-1 result
   (problem construction included; median of 11 runs, 5 with ``--quick``).

Speed-up = baseline time / our time, where the baseline time is its time to reach our J, or, when it
did not within the cap, its run time (the ratio is then a lower bound, marked ">="). The targets
(two-step < 2 s, one-step < 10 s, >= 50x the baseline at the same or lower J, segment < 50 ms) are
checked and printed (a speed-up lower bound below 50x is "undecided": ``met`` is None in the JSON). The load average is printed with the numbers: on a shared machine, OpenBLAS'
threads (numpy's matrix products in the inverse dynamics) slow these runs down several times; compare
with ``OPENBLAS_NUM_THREADS=1``.
"""

from __future__ import annotations

import argparse
import gc
import itertools
import json
import os
import platform
import sys
import time
import warnings

import numpy as np
import pinocchio as pin
from scipy.optimize import BFGS, NonlinearConstraint, minimize

import fpr
from fpr.constrained import build_closed_chain
from fpr.inverse_dynamics import inverse_dynamics
from fpr.planar import planar_configuration

SEED = 2024
REFERENCE = {  # the chain's reference pose: FPR (y, z, phi, q21), prototype (q1, q2)
    "fpr": (0.0, 0.0, 5 * np.pi / 4, np.pi / 2), "prototype": (0.3, 1.2)}


def random_states(robot, rng, count: int) -> list[tuple]:
    """Random (q, v, thrust, torque) near the reference pose (as in tests/test_constrained.py)."""
    centre = robot.configuration(**dict(zip(robot.layout.chain, REFERENCE[robot.name])))
    return [(centre + 0.3 * rng.normal(size=robot.nq), rng.normal(size=robot.nq),
             rng.uniform(3.0, 15.0, robot.n_drones), 0.3 * rng.normal(size=(robot.n_drones, 3)))
            for _ in range(count)]


def smooth_motion(name: str, samples: int, duration: float = 3.0) -> np.ndarray:
    """s(t) = s_0 + 0.2 sin(w t + p) and its derivatives 0..4, shape (5, N, n_s) (tests' smooth_motion)."""
    s0 = np.array(REFERENCE[name])
    omega, phase = np.linspace(1.0, 2.0, len(s0)), np.linspace(0.0, 1.0, len(s0))
    arg = omega * np.linspace(0.0, duration, samples)[:, None] + phase
    return np.array([s0 * (k == 0) + 0.2 * omega**k * np.sin(arg + k * np.pi / 2) for k in range(5)])


def cycling(fn, args: list[tuple]):
    """A no-argument callable that calls fn on the next argument tuple of args, round robin."""
    pool = itertools.cycle(args)
    return lambda: fn(*next(pool))


class Bench:
    """Times items one after the other and keeps the results.

    Attributes:
        repeats: repeats of each timed loop.
        target: duration of one timed loop [s].
        progress: whether to print one line per item on stderr.
        results: one dict per item (name, median_s, min_s, n, per_sample_s, loops, repeats, ratio, ratio_to).
    """

    def __init__(self, repeats: int, target: float, progress: bool):
        self.repeats, self.target, self.progress = repeats, target, progress
        self.results: list[dict] = []

    @staticmethod
    def _loop(fn, loops: int) -> float:
        start = time.perf_counter()
        for _ in range(loops):
            fn()
        return time.perf_counter() - start

    def time(self, name: str, fn, n: int = 1, ref: tuple[str, ...] = ()) -> dict:
        """Time fn (one call handles n samples); ratio = per-sample time / sum of the refs' per-sample times."""
        fn()  # warm up (caches, lazy imports)
        gc.disable()
        try:
            loops, elapsed = 1, self._loop(fn, 1)
            while elapsed < self.target / 10:
                loops *= 4
                elapsed = self._loop(fn, loops)
            loops = max(1, round(loops * self.target / elapsed))
            per_call = sorted(self._loop(fn, loops) / loops for _ in range(self.repeats))
        finally:
            gc.enable()
        median = float(np.median(per_call))
        known = {r["name"]: r["per_sample_s"] for r in self.results}
        ratio = median / n / sum(known[r] for r in ref) if ref else None
        result = dict(name=name, median_s=median, min_s=per_call[0], n=n, per_sample_s=median / n, loops=loops,
                      repeats=self.repeats, ratio=ratio, ratio_to=" + ".join(ref) or None)
        self.results.append(result)
        if self.progress:
            print(f"bench [{len(self.results):2d}] {name}: {fmt(median)} per call", file=sys.stderr, flush=True)
        return result


def run_timings(bench: Bench) -> None:
    """The timed items 1-4 of the module docstring."""
    rng = np.random.default_rng(SEED)
    r = fpr.load("fpr")
    model, data, fids = r.model, r.data, r.drone_frame_ids
    states = []  # (q, v, thrust, torque, q_pin, v_pin, fext)
    for q, v, f, tau in random_states(r, rng, 64):
        fext = pin.StdVec_Force([pin.Force.Zero() for _ in range(model.njoints)])
        for w, fid in zip(r.input_wrenches(f, tau), fids):  # wrenches moved to the joints, as r.forward_dynamics
            fext[model.frames[fid].parentJoint] += model.frames[fid].placement.act(pin.Force(w))
        states.append((q, v, f, tau, r.to_pinocchio(q), r.to_pinocchio(v), fext))
    zero = np.zeros(model.nv)

    def raw_jacobians(qp):
        pin.computeJointJacobians(model, data, qp)
        return [pin.getFrameJacobian(model, data, f, pin.LOCAL) for f in fids]

    crba, nle, jac, aba = "pin.crba", "pin.nonLinearEffects", "pin.computeJointJacobians+getFrameJacobian", "pin.aba"
    for name, fn, ref in (
            (crba, lambda *s: pin.crba(model, data, s[4]), ()),
            ("fpr r.mass_matrix", lambda *s: r.mass_matrix(s[0]), (crba,)),
            (nle, lambda *s: pin.nonLinearEffects(model, data, s[4], s[5]), ()),
            ("fpr r.nonlinear_effects", lambda *s: r.nonlinear_effects(s[0], s[1]), (nle,)),
            (jac, lambda *s: raw_jacobians(s[4]), ()),
            ("fpr r.drone_jacobians", lambda *s: r.drone_jacobians(s[0]), (jac,)),
            (aba, lambda *s: pin.aba(model, data, s[4], s[5], zero, s[6]), ()),
            ("fpr r.forward_dynamics", lambda *s: r.forward_dynamics(*s[:4]), (aba,)),
            ("fpr r.attitude_model", lambda *s: r.attitude_model(s[0], s[1]), (crba, nle, jac))):
        bench.time(name, cycling(fn, states), ref=ref)

    planar = r.planar("rigid")
    big = random_states(r, rng, 1000)
    qs = planar_configuration(r, np.array([s[0] for s in big]))
    vs = planar_configuration(r, np.array([s[1] for s in big]))
    bench.time("planar rigid mass_matrix(Q), N=1000", lambda: planar.mass_matrix(qs), n=len(qs), ref=(crba,))
    bench.time("planar rigid bias(Q, V), N=1000", lambda: planar.bias(qs, vs), n=len(qs), ref=(nle,))

    proto = fpr.load("prototype")
    bench.time("prototype r.forward_dynamics", cycling(proto.forward_dynamics, random_states(proto, rng, 64)))
    for robot in (r, proto):
        motion = smooth_motion(robot.name, 2000)
        bench.time(f"{robot.name} inverse_dynamics, N=2000", lambda: inverse_dynamics(robot, motion), n=2000,
                   ref=(f"{robot.name} r.forward_dynamics",))
    for robot in (r, proto):
        closed = build_closed_chain(robot)
        args = []  # (q_c, v_c, thrust, torque, J_c^T w)
        for q, v, f, tau in random_states(robot, rng, 64):
            qc, vc = closed.from_minimal(q, v)
            args.append((qc, vc, f, tau, closed.generalized_input(qc, f, tau)))
        for name, fn in (("generalized_input", lambda qc, vc, f, tau, g: closed.generalized_input(qc, f, tau)),
                         ("forward_dynamics", lambda qc, vc, f, tau, g: closed.forward_dynamics(qc, vc, g)),
                         ("generalized_input+forward_dynamics", lambda qc, vc, f, tau, g: closed.forward_dynamics(
                             qc, vc, closed.generalized_input(qc, f, tau)))):
            bench.time(f"{robot.name} closed {name}", cycling(fn, args), ref=(f"{robot.name} r.forward_dynamics",))


def run_residuals() -> list[dict]:
    """Accuracy figures of item 5 of the module docstring (maximum absolute errors)."""
    rng = np.random.default_rng(SEED + 1)
    out = []
    for name in fpr.ROBOTS:
        robot = fpr.load(name)
        closed = build_closed_chain(robot)
        worst = scale = 0.0
        for q, v, f, tau in random_states(robot, rng, 100):
            a = robot.forward_dynamics(q, v, f, tau)
            qc, vc, expected = closed.from_minimal(q, v, a)
            ac = closed.forward_dynamics(qc, vc, closed.generalized_input(qc, f, tau))
            worst, scale = max(worst, np.abs(ac - expected).max()), max(scale, np.abs(expected).max())
        out.append(dict(name=f"{name} max |a_closed - a_minimal|", value=float(worst), samples=100,
                        max_abs_acceleration=float(scale)))
        for d in (0.0, robot.hinge_offset):
            model = fpr.load(name, hinge_offset=0.0) if d == 0.0 else robot
            inputs = inverse_dynamics(model, smooth_motion(name, 50))
            q, v, a = inputs.full_state(model)
            err = np.abs([model.forward_dynamics(q[k], v[k], inputs.thrust[k], inputs.torque[k]) - a[k]
                          for k in range(len(q))])
            rows = {"all rows": slice(None)} if d == 0.0 else {
                "roll rows": model.indices(model.layout.rolls),
                "chain rows": model.indices(model.layout.chain)}
            for label, idx in rows.items():
                out.append(dict(name=f"{name} round trip d={d:g}, {label}", value=float(err[:, idx].max()),
                                samples=len(q)))
    return out

# ----------------------------------------------------------------------------------------- planning
PLANNING_MISSION = "square"
PLANNING_SETTINGS = {  # quick / full
    True: {"repeats": 1, "segment_repeats": 5, "baseline_cap_s": 15.0},
    False: {"repeats": 3, "segment_repeats": 11, "baseline_cap_s": 120.0},
}
SAME_J_RTOL = 1e-4  # "same J": the SQP's stopping tolerance on J (about 1)
GRID_FEASIBILITY = 1e-6  # largest scaled grid-constraint violation counted as feasible
TARGETS = {"two-step_s": 2.0, "one-step_s": 10.0, "speedup": 50.0, "segment_s": 0.05}


def one_step_problem(mission, robot, samples_per_segment: int = 17, windows_per_segment: int = 4):
    """The 1-step NLP of ``planners.optimize.plan`` (first attempt, no grid refinement), built the same way.

    A local copy of the code inside ``plan`` (which has no public helper for it).

    Returns:
        (problem, x0, durations, is_way, stop): the :class:`~planners.problem.MotionProblem`, its start
        (the stop-at-way-points motion split at the via times), the segment durations, the way-point
        mask and the stop-at-way-points :class:`~planners.polynomial.PiecewisePolynomial`.
    """
    from planners.optimize import _with_via_points
    from planners.polynomial import PiecewisePolynomial, stop_points
    from planners.problem import MotionProblem

    way_times = np.asarray(mission.times, dtype=float)
    n_via = np.broadcast_to(np.asarray(mission.via_points, dtype=int), way_times.shape)
    stop = PiecewisePolynomial(stop_points(mission.positions(robot)), way_times)
    options = {"samples_per_segment": samples_per_segment, "windows_per_segment": windows_per_segment}
    free_way = np.zeros(stop.points.shape, dtype=bool)
    free_way[1:-1, 1:] = True
    normalisation = tuple(MotionProblem(robot, stop.points, way_times, free_way, mission.alpha, (1.0, 1.0),
                                        **options).objective_terms(stop.points))
    points, durations, is_way = _with_via_points(stop, way_times, n_via)
    free = np.zeros(points.shape, dtype=bool)
    free[~is_way] = True
    free[np.flatnonzero(is_way)[1:-1], 1:] = True
    problem = MotionProblem(robot, points, durations, free, mission.alpha, normalisation, **options)
    return problem, problem.x_of(points), durations, is_way, stop


def _plan_item(name: str, results: list, times: list[float]) -> dict:
    """Row of a plan() run: median / min wall time over repeats, numbers of the last result."""
    r = results[-1]
    stages = r.stages
    return dict(name=name, wall_time_s=float(np.median(times)), min_s=float(min(times)), repeats=len(times),
                J=float(r.J), J_e=float(r.report.J_e), J_phi=float(r.report.J_phi),
                iterations=int(sum(st.iterations for st in stages)),
                evaluations=int(sum(st.evaluations for st in stages)),
                gradient_evaluations=int(sum(st.gradient_evaluations for st in stages)),
                feasible=bool(r.feasible), solver_success=bool(r.solver_success),
                message="; ".join(f"{st.name}: {st.message}" for st in stages))


def _baseline(mission, robot, reference, cap: float, targets: dict, progress: bool) -> dict:
    """Item d: trust-constr, 2-point finite differences, BFGS, time cap; see the module docstring."""
    from planners.optimize import PlanResult, evaluate_motion
    from planners.polynomial import PiecewisePolynomial

    problem, x0, durations, is_way, _ = one_step_problem(mission, robot)
    calls = {"J": 0, "c": 0, "it": 0}
    reached = {name: None for name in targets}  # name -> time to reach that grid J
    trace = []

    def objective(x):
        calls["J"] += 1
        return problem.evaluate(x).J

    def constraints(x):
        calls["c"] += 1
        return problem.evaluate(x).constraints

    start = time.perf_counter()

    def callback(xk, state):
        calls["it"] += 1
        ev = problem.evaluate(xk)
        elapsed = time.perf_counter() - start
        violation = float(max(0.0, -ev.constraints.min()))
        trace.append((elapsed, ev.J, violation))
        for name, j in targets.items():
            if reached[name] is None and violation <= GRID_FEASIBILITY and ev.J <= j * (1 + SAME_J_RTOL):
                reached[name] = elapsed
        if progress and calls["it"] % 5 == 0:
            print(f"bench planning (d) trust-constr: iteration {calls['it']}, {elapsed:.0f} s, "
                  f"grid J {ev.J:.4f}, violation {violation:.2g}", file=sys.stderr, flush=True)
        return elapsed > cap

    nonlinear = NonlinearConstraint(constraints, 0.0, np.inf, jac="2-point", hess=BFGS())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = minimize(objective, x0, method="trust-constr", jac="2-point", hess=BFGS(),
                       constraints=[nonlinear], options={"maxiter": 100000},
                       callback=callback)  # stopped by the time cap
    wall = time.perf_counter() - start
    trajectory = PiecewisePolynomial(problem.points_of(res.x), durations)
    report = evaluate_motion(robot, trajectory)
    result = PlanResult(mission, "one-step", float(mission.alpha), trajectory, is_way, report, reference, [],
                        wall, robot)
    ev = problem.evaluate(res.x)
    return dict(name="(d) baseline: trust-constr, 2-point FD, BFGS", wall_time_s=wall, min_s=wall, repeats=1,
                J=float(result.J), J_e=float(report.J_e), J_phi=float(report.J_phi), iterations=int(res.nit),
                evaluations=calls["J"] + calls["c"], gradient_evaluations=0, feasible=bool(result.feasible),
                solver_success=bool(res.success), message=f"status {res.status}: {res.message}",
                cap_s=cap, grid_J=float(ev.J), grid_violation=float(max(0.0, -ev.constraints.min())),
                objective_evaluations=calls["J"], constraint_evaluations=calls["c"],
                time_to_J_s=reached, trace=trace)


def _segment(mission, robot, two_step, repeats: int) -> dict:
    """Item e: step 2 on travel 1 from the step-1 result of ``two_step`` (construction + solve)."""
    from planners.optimize import _with_via_points, evaluate_motion
    from planners.polynomial import PiecewisePolynomial
    from planners.problem import MotionProblem
    from planners.sqp import SqpOptions, solve_sqp

    problem, _, _, _, stop = one_step_problem(mission, robot)
    way_times = np.asarray(mission.times, dtype=float)
    n_via = np.broadcast_to(np.asarray(mission.via_points, dtype=int), way_times.shape)
    first = PiecewisePolynomial(two_step.trajectory.points[two_step.is_way], way_times)  # step 1's motion
    points, durations, is_way = _with_via_points(first, way_times, n_via)
    a, b = np.flatnonzero(is_way)[:2]
    free = np.zeros(points[a:b + 1].shape, dtype=bool)
    free[1:-1] = True

    def once():
        travel = MotionProblem(robot, points[a:b + 1], durations[a:b], free, mission.alpha,
                               problem.normalisation)
        out = solve_sqp(travel, travel.x_of(points[a:b + 1]), SqpOptions())
        return travel, out

    once()  # warm up
    times, outs = [], []
    for _ in range(repeats):
        t = time.perf_counter()
        outs.append(once())
        times.append(time.perf_counter() - t)
    travel, out = outs[-1]
    spliced = two_step.trajectory.points.copy()
    spliced[a:b + 1] = travel.points_of(out.x)
    report = evaluate_motion(robot, PiecewisePolynomial(spliced, durations))
    alpha = float(mission.alpha)
    J = alpha * report.J_e / two_step.reference.J_e + (1 - alpha) * report.J_phi / two_step.reference.J_phi
    return dict(name="(e) re-optimise one segment (step 2, travel 1)", wall_time_s=float(np.median(times)),
                min_s=float(min(times)), repeats=repeats, J=float(J), J_e=float(report.J_e),
                J_phi=float(report.J_phi), iterations=int(out.iterations),
                evaluations=int(out.evaluations + out.gradient_evaluations),
                gradient_evaluations=int(out.gradient_evaluations), feasible=bool(report.feasible),
                solver_success=bool(out.success), message=out.message, segment_grid_J=float(out.J),
                note="J: the two-step motion with travel 1 re-optimised (dense grid)")


def run_planning(quick: bool, progress: bool) -> dict:
    """The planning items a-e of the module docstring; returns the items, speed-ups and targets."""
    from planners.mission import load_mission
    from planners.optimize import plan

    settings = PLANNING_SETTINGS[quick]
    say = (lambda text: print(text, file=sys.stderr, flush=True)) if progress else (lambda text: None)
    load_before = os.getloadavg()
    mission = load_mission(PLANNING_MISSION)
    robot = mission.load_robot()
    plan(load_mission("study"), "two-step", robot=robot, max_iterations=2)  # warm up (imports, caches)
    items, results = [], {}
    for key, label, kwargs, repeats in (
            ("two-step", "(a) two-step, SQP (exact gradients, Gauss-Newton)", {"method": "two-step"},
             settings["repeats"]),
            ("one-step", "(b) one-step, SQP (exact gradients, Gauss-Newton)", {"method": "one-step"},
             settings["repeats"]),
            ("slsqp", "(c) one-step, scipy SLSQP (exact gradients)",
             {"method": "one-step", "solver": "slsqp"}, 1)):
        runs, times = [], []
        for _ in range(repeats):
            r = plan(mission, robot=robot, **kwargs)
            runs.append(r)
            times.append(r.wall_time)
        results[key] = runs[-1]
        items.append(_plan_item(label, runs, times))
        say(f"bench planning {label}: {fmt(items[-1]['wall_time_s'])}, J {items[-1]['J']:.4f}")
    # our results' J on the 1-step grid (same points layout: the via times are the same)
    problem, x0, *_ = one_step_problem(mission, robot)
    grid_J = {k: float(problem.evaluate(problem.x_of(r.trajectory.points)).J) for k, r in results.items()}
    start_J = results["one-step"].stages[0].J_start
    consistent = bool(np.isclose(problem.evaluate(x0).J, start_J, rtol=1e-12, atol=0.0))
    cap = settings["baseline_cap_s"]
    say(f"bench planning (d) baseline: trust-constr with finite differences, capped at {cap:g} s")
    base = _baseline(mission, robot, results["one-step"].reference, cap, grid_J, progress)
    items.append(base)
    say(f"bench planning (d): {fmt(base['wall_time_s'])}, J {base['J']:.4f}")
    items.append(_segment(mission, robot, results["two-step"], settings["segment_repeats"]))
    say(f"bench planning (e): {fmt(items[-1]['wall_time_s'])}")
    speedups = {}
    for key, item in zip(("two-step", "one-step", "slsqp"), items[:3]):
        reached = base["time_to_J_s"][key]
        baseline_time = reached if reached is not None else base["wall_time_s"]
        speedups[key] = dict(ratio=baseline_time / item["wall_time_s"], lower_bound=reached is None,
                             baseline_time_s=baseline_time, ours_s=item["wall_time_s"],
                             ours_grid_J=grid_J[key],
                             baseline_reached_our_J=reached is not None,
                             baseline_final_J_at_most_ours=base["J"] <= item["J"] * (1 + SAME_J_RTOL))
    seg = items[4]
    targets = [
        dict(target="two-step < 2 s", value=items[0]["wall_time_s"],
             met=items[0]["wall_time_s"] < TARGETS["two-step_s"]),
        dict(target="one-step < 10 s", value=items[1]["wall_time_s"],
             met=items[1]["wall_time_s"] < TARGETS["one-step_s"]),
        *(dict(target=f">= 50x faster than the baseline at the same or lower J ({key})",
               value=speedups[key]["ratio"], lower_bound=speedups[key]["lower_bound"],
               # a lower bound below the target says nothing: the baseline was stopped too early
               met=True if speedups[key]["ratio"] >= TARGETS["speedup"] else
               None if speedups[key]["lower_bound"] else False)
          for key in ("one-step", "two-step")),
        dict(target="segment re-optimisation < 50 ms", value=seg["wall_time_s"],
             met=seg["wall_time_s"] < TARGETS["segment_s"]),
    ]
    return dict(mission=PLANNING_MISSION, settings=settings, items=items, speedups=speedups, targets=targets,
                one_step_problem_matches_plan=consistent, load_average_before=load_before,
                load_average_after=os.getloadavg(),
                blas_threads_env={k: os.environ.get(k) for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")})


def planning_table(planning: dict) -> str:
    """The planning section as text: one line per item, then speed-ups and targets."""
    rows = planning["items"]
    width = max(len(r["name"]) for r in rows)
    lines = [f"planning, mission {planning['mission']!r} (load average "
             f"{planning['load_average_before'][0]:.2f} -> {planning['load_average_after'][0]:.2f}; "
             f"OPENBLAS_NUM_THREADS {planning['blas_threads_env']['OPENBLAS_NUM_THREADS'] or 'unset'})",
             f"{'name':<{width}}  {'time':>10}  {'min':>10}  {'J':>7}  {'J_e [J]':>8}  {'J_phi':>8}  "
             f"{'iter':>5}  {'evals':>6}  feasible"]
    for r in rows:
        lines.append(f"{r['name']:<{width}}  {fmt(r['wall_time_s'])}  {fmt(r['min_s'])}  {r['J']:7.4f}  "
                     f"{r['J_e']:8.3f}  {r['J_phi']:8.5f}  {r['iterations']:5d}  {r['evaluations']:6d}  "
                     f"{'yes' if r['feasible'] else 'no'}")
    base = rows[3]
    reach = ", ".join(f"{k} {f'{v:.1f} s' if v is not None else 'not reached'}"
                      for k, v in base["time_to_J_s"].items())
    lines.append(f"baseline: stopped after {base['wall_time_s']:.1f} s (cap {base['cap_s']:g} s), "
                 f"{base['message']}; time to our J: {reach}")
    for key, s in planning["speedups"].items():
        lines.append(f"speed-up vs baseline, {key}: {'>= ' if s['lower_bound'] else ''}{s['ratio']:.0f}x "
                     f"({s['baseline_time_s']:.1f} s / {s['ours_s']:.3f} s)")
    for t in planning["targets"]:
        bound = " (lower bound)" if t.get("lower_bound") else ""
        verdict = {True: "met", False: "NOT met", None: "undecided (the baseline stopped at its time cap "
                   "before reaching our J: raise the cap)"}[t["met"]]
        lines.append(f"target {t['target']}: {t['value']:.4g}{bound} -> {verdict}")
    return "\n".join(lines)


def fmt(seconds: float) -> str:
    """A duration with a readable unit."""
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6)):
        if seconds >= scale:
            return f"{seconds / scale:7.3f} {unit}"
    return f"{seconds / 1e-9:7.1f} ns"


def main(argv=None) -> int:
    """Run the benchmark and print the tables (or JSON with ``--json``).

    Args:
        argv: command-line arguments (default: sys.argv[1:]).

    Returns:
        the exit status, 0.
    """
    parser = argparse.ArgumentParser(prog="python -m fpr.bench", description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print a JSON document instead of the table")
    parser.add_argument("--quick", action="store_true",
                        help="3 repeats of ~20 ms loops instead of 7 of ~50 ms; planning: 1 run per item, "
                             "baseline capped at 15 s instead of 120 s")
    parser.add_argument("--section", choices=("all", "model", "planning"), default="all",
                        help="which part to run (default all)")
    args = parser.parse_args(argv)
    bench = Bench(repeats=3 if args.quick else 7, target=0.02 if args.quick else 0.05, progress=not args.json)
    info = dict(python=platform.python_version(), numpy=np.__version__, pinocchio=pin.__version__,
                cpu_count=os.cpu_count(), platform=platform.platform())
    residuals, planning = [], None
    if args.section in ("all", "model"):
        run_timings(bench)
        residuals = run_residuals()
    if args.section in ("all", "planning"):
        planning = run_planning(args.quick, progress=not args.json)
    if args.json:
        doc = dict(machine=info, repeats=bench.repeats, loop_target_s=bench.target, timings=bench.results,
                   residuals=residuals)
        if planning is not None:
            doc["planning"] = planning
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
