"""Benchmark of the models, planner and controller: ``python -m fpr.bench [--quick] [--json] [--section S]``.

All items run in one process, one after the other, so that their ratios mean something on a shared,
noisy machine. Each is a loop sized to last ~50 ms (20 ms with ``--quick``), repeated 7 times (3 with
``--quick``), garbage collector off; reported: median and min over repeats of the time per call
(``time.perf_counter``), the time per sample, and a ratio (per-sample time / a reference's):

1. The FPR :class:`~fpr.model.robot.Robot` in thesis coordinates (mass matrix, nonlinear effects, drone
   Jacobians, forward dynamics, attitude model) against the raw Pinocchio calls underneath (``crba``,
   ``nonLinearEffects``, ``computeJointJacobians`` + ``getFrameJacobian``, ``aba``): the ratio is the
   wrapper's overhead. Random states near ``phi = 5 pi / 4, q21 = pi / 2``.
2. The closed-form planar model (:mod:`fpr.model.planar`), batched over N = 1000, against Pinocchio per call.
3. :func:`fpr.model.inverse_dynamics.inverse_dynamics` along a sine motion of N = 2000 samples (FPR,
   prototype), against one minimal forward dynamics call.
4. The closed chain (:func:`fpr.model.constrained.build_closed_chain`): generalised input and constraint
   dynamics per call, against the minimal forward dynamics.

It also prints accuracy figures (not timings): the largest difference between the closed-chain and
the minimal accelerations over 100 random states and inputs, and the round-trip residual inverse
dynamics -> forward dynamics along a 50-sample motion, with d = 0 (exact) and with the default d
(roll rows exact, chain rows off by the p_i perturbation of seed eq. 2.7-2.8).

Timings depend on the machine and its load: no test asserts them. The accuracy figures are asserted,
with tolerances, in tests/test_constrained.py and tests/test_inverse_dynamics.py.

Control section (``--section control``), side by side in one run for the FPR (8 rotor variables) and
the prototype (4), at states near hover (q and v perturbed by 0.01, small wanted attitude accelerations
u_a), in two cases: hover thrusts (no rotor bound active) and 3 times the hover thrusts (bounds active):

1. ProxQP warm-started: the full :meth:`controllers.allocation.Allocator.solve` call (building H and g,
   the solve, the result), and the QP solve alone (``allocator.qp.solve()`` after ``qp.update``, only
   the solve timed), with ``qp.update`` and the building of H, g on their own rows;
2. ProxQP cold: ``proxsuite.proxqp.dense.solve`` from scratch on the same scaled problem;
3. the closed-form pseudo-inverse law (:func:`controllers.allocation.pseudo_inverse_law`) and the rotor
   map, which ignores the bounds;
4. quadprog (Goldfarb-Idnani, cold) on the same scaled problem: the optional extra ``bench``
   (``pip install -e '.[bench]'``); the row is skipped with a note when it is not installed.

The largest difference of each solution's w^2 from the warm ProxQP's is printed (the pseudo-inverse
law differs when a bound is active, by design). Then the closed-loop simulation of the ``square``
mission's two-step plan (:func:`fpr.sim.closed_loop.simulate`, default settings: plant 1 kHz, inner loop
500 Hz, outer loop 100 Hz): simulated time, wall time and real-time factor (median of 3 runs, 1 with
``--quick``), and one more run with timers around the simulator's parts (measure, logged kinematics,
outer loop, attitude model, allocation, the rest of the inner loop, plant steps; the remainder is the
loop itself and the logging) for the per-tick breakdown. Targets: warm QP solve <= 20 us, RTF >= 20.

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
   (problem construction included; median of 11 runs, 5 with ``--quick``);
f. the singularity crossing: ``plan(load_mission("cross-singularity"))`` (:mod:`planners.crossing`,
   median of 3 runs, 1 with ``--quick``); not part of the speed-ups (no baseline).

Speed-up = baseline time / our time, where the baseline time is its time to reach our J, or, when it
did not within the cap, its run time (the ratio is then a lower bound, marked ">="). The targets
(two-step < 2 s, one-step < 10 s, >= 50x the baseline at the same or lower J, segment < 50 ms) are
checked and printed (a speed-up lower bound below 50x is "undecided": ``met`` is None in the JSON). The load average is printed with the numbers: on a shared machine, OpenBLAS'
threads (numpy's matrix products in the inverse dynamics) slow these runs down several times; compare
with ``OPENBLAS_NUM_THREADS=1``.
"""

from __future__ import annotations

import argparse
import contextlib
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
from fpr.model.constrained import build_closed_chain
from fpr.model.inverse_dynamics import inverse_dynamics
from fpr.model.planar import planar_configuration

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
    crossing = load_mission("cross-singularity")
    runs, times = [], []
    for _ in range(settings["repeats"]):
        runs.append(plan(crossing))
        times.append(runs[-1].wall_time)
    items.append(_plan_item("(f) singularity crossing (cross-singularity mission)", runs, times))
    say(f"bench planning (f): {fmt(items[-1]['wall_time_s'])}, feasible {items[-1]['feasible']}")
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


# ----------------------------------------------------------------------------------------- control
CONTROL_MISSION = "square"
CONTROL_SETTINGS = {True: {"states": 32, "runs": 1}, False: {"states": 64, "runs": 3}}  # quick / full
CONTROL_TARGETS = {"warm_qp_solve_s": 20e-6, "real_time_factor": 20.0}
#: thrust of the "bounds active" allocation case, in hover thrusts
SATURATING_THRUST = 3.0


def _allocation_states(robot, rng, count: int):
    """Attitude models near hover (q, v perturbed by 0.01), the hover thrusts, small u_a (0.1 rad/s^2)."""
    from fpr.sim.plant import hover_configuration

    chain = REFERENCE[robot.name]
    q0 = hover_configuration(robot, chain)
    motion = np.zeros((5, 1, len(chain)))
    motion[0, 0] = chain
    hover = inverse_dynamics(robot, motion).thrust[0]
    n_a = len(robot.layout.attitude)
    states = [(robot.attitude_model(q0 + 0.01 * rng.normal(size=robot.nq), 0.01 * rng.normal(size=robot.nq)),
               0.1 * rng.normal(size=n_a)) for _ in range(count)]
    return states, hover


def _time_part(bench: Bench, name: str, prepare, part, n: int = 1) -> dict:
    """Like :meth:`Bench.time`, but only part() is timed; prepare() runs before each call, untimed.

    Each call's own time is summed (``time.perf_counter`` around it, ~50 ns of timer overhead included).
    """
    prepare()
    part()  # warm up
    gc.disable()
    try:
        def loop(count):
            total = 0.0
            for _ in range(count):
                prepare()
                start = time.perf_counter()
                part()
                total += time.perf_counter() - start
            return total

        loops, elapsed = 1, loop(1)
        while elapsed < bench.target / 10:
            loops *= 4
            elapsed = loop(loops)
        loops = max(1, round(loops * bench.target / elapsed))
        per_call = sorted(loop(loops) / loops for _ in range(bench.repeats))
    finally:
        gc.enable()
    median = float(np.median(per_call))
    result = dict(name=name, median_s=median, min_s=per_call[0], n=n, per_sample_s=median / n, loops=loops,
                  repeats=bench.repeats, ratio=None, ratio_to=None)
    bench.results.append(result)
    if bench.progress:
        print(f"bench [{len(bench.results):2d}] {name}: {fmt(median)} per call", file=sys.stderr, flush=True)
    return result


def _allocation_rows(bench: Bench, robot, case: str, states, thrust, quadprog) -> dict:
    """The timed allocation rows of one robot and case, and the agreement of the solvers' w^2."""
    import proxsuite

    from controllers.allocation import Allocator, pseudo_inverse_law

    label = f"{robot.name} {case}"
    allocator = Allocator(robot)
    scale, n = allocator.scale, allocator.n
    lower, upper = allocator.lower / scale, allocator.upper / scale
    problems = []  # the scaled QPs of the allocator (H w_max^4, g w_max^2), on zeta = w^2 / w_max^2
    for attitude, u_a in states:
        h, g = allocator.build(attitude, thrust, u_a)
        problems.append((h * scale**2, g * scale))
    # warm: the allocator along the states, in order (each warm-started from the previous one's result)
    warm = np.array([allocator.solve(attitude, thrust, u_a).speeds_squared.reshape(-1)
                     for attitude, u_a in states])
    saturated = sum(bool(allocator.solve(attitude, thrust, u_a).any_saturated) for attitude, u_a in states)
    iterations = []
    for h, g in problems:
        allocator.qp.update(H=h, g=g, update_preconditioner=False)
        allocator.qp.solve()
        iterations.append(int(allocator.qp.results.info.iter))
    rows = [bench.time(f"{label}: (1) ProxQP warm, full call (Allocator.solve)",
                       cycling(allocator.solve, [(a, thrust, u) for a, u in states]))]
    pool = itertools.cycle(problems)
    current = [None]

    def update():
        current[0] = next(pool)
        allocator.qp.update(H=current[0][0], g=current[0][1], update_preconditioner=False)

    rows.append(_time_part(bench, f"{label}: (1) ProxQP warm, QP solve alone (qp.solve after update)", update,
                           allocator.qp.solve))
    rows.append(_time_part(bench, f"{label}:     ProxQP warm, qp.update(H, g) alone", lambda: None, update))
    rows.append(bench.time(f"{label}:     building H, g (Allocator.build)",
                           cycling(allocator.build, [(a, thrust, u) for a, u in states])))

    def cold(h, g):
        return proxsuite.proxqp.dense.solve(h, g, l_box=lower, u_box=upper, eps_abs=1e-9, eps_rel=0.0,
                                            verbose=False)

    rows.append(bench.time(f"{label}: (2) ProxQP cold (proxqp.dense.solve)", cycling(cold, problems)))

    def law(attitude, u_a):
        tau = pseudo_inverse_law(attitude, thrust, u_a)
        rotors = zip(thrust, tau, robot.rotors, strict=True)
        return np.concatenate([rotor.speeds_squared(f, t) for f, t, rotor in rotors])

    rows.append(bench.time(f"{label}: (3) pseudo-inverse law + rotor map (no bounds)", cycling(law, states)))
    solutions = {"ProxQP cold": np.array([np.asarray(cold(h, g).x) * scale for h, g in problems]),
                 "pseudo-inverse law": np.array([law(a, u) for a, u in states])}
    note = None
    if quadprog is None:
        note = "quadprog not installed (pip install -e '.[bench]'): row (4) skipped"
    else:
        box = np.hstack([np.eye(n), -np.eye(n)])  # C^T zeta >= b: zeta >= 0 and -zeta >= -1
        bound = np.concatenate([lower, -upper])

        def other(h, g):
            return quadprog.solve_qp(h, -g, box, bound, 0)

        try:
            solutions["quadprog"] = np.array([other(h, g)[0] * scale for h, g in problems])
            rows.append(bench.time(f"{label}: (4) quadprog.solve_qp (Goldfarb-Idnani, cold)",
                                   cycling(other, problems)))
        except ValueError as error:  # quadprog needs H positive definite
            note = f"quadprog failed: {error}"
    agreement = {k: float(np.abs(s - warm).max()) for k, s in solutions.items()}
    return dict(robot=robot.name, case=case, rows=rows, thrust=thrust.tolist(), states=len(states),
                states_with_a_bound_active=saturated, warm_iterations_mean=float(np.mean(iterations)),
                max_abs_w2_difference_to_warm=agreement, w_max2=float(scale), note=note)


@contextlib.contextmanager
def _tick_timers(acc: dict):
    """Adds the time spent in the simulator's parts to ``acc`` (seconds by part) while active."""
    from controllers.allocation import Allocator
    from controllers.ctc import CascadedController
    from fpr.sim.plant import Plant
    from fpr.model.robot import Robot

    patched = []
    for cls, method, key in ((Plant, "measure", "measure"),
                             (Plant, "drone_positions_and_closure_error", "logged kinematics"),
                             (Plant, "step", "plant steps"),
                             (CascadedController, "update", "controller"),
                             (CascadedController, "outer", "outer loop"),
                             (Robot, "attitude_model", "attitude model"),
                             (Allocator, "solve", "allocation")):
        original = cls.__dict__[method]

        def timed(*args, _f=original, _key=key, **kwargs):
            start = time.perf_counter()
            try:
                return _f(*args, **kwargs)
            finally:
                acc[_key] = acc.get(_key, 0.0) + time.perf_counter() - start

        setattr(cls, method, timed)
        patched.append((cls, method, original))
    try:
        yield acc
    finally:
        for cls, method, original in patched:
            setattr(cls, method, original)


def _simulation(runs: int, progress: bool) -> dict:
    """RTF of the closed-loop simulation of the square mission (two-step plan), and its per-tick breakdown."""
    from fpr.sim.closed_loop import SimulationSettings, simulate
    from planners.mission import load_mission
    from planners.optimize import plan

    say = (lambda text: print(text, file=sys.stderr, flush=True)) if progress else (lambda text: None)
    result = plan(load_mission(CONTROL_MISSION), "two-step")
    settings = SimulationSettings()
    logs, cpu = [], []
    for k in range(runs):
        start = time.process_time()  # CPU time: less sensitive than the wall time to other processes' load
        logs.append(simulate(result, settings))
        cpu.append(time.process_time() - start)
        say(f"bench control: simulation {k + 1}/{runs}: {logs[-1].wall_time:.2f} s wall, "
            f"RTF {logs[-1].real_time_factor:.2f}")
    acc = {}
    with _tick_timers(acc):
        timed = simulate(result, settings)
    ticks = timed.t.size
    steps = ticks - 1
    controller = acc.get("controller", 0.0)
    inner = controller - sum(acc.get(k, 0.0) for k in ("outer loop", "attitude model", "allocation"))
    parts = {
        "measure (Plant.measure: to_minimal)": acc.get("measure", 0.0),
        "logged kinematics (drone heights, closure error)": acc.get("logged kinematics", 0.0),
        "controller: outer loop (100 Hz)": acc.get("outer loop", 0.0),
        "controller: inner loop (attitude model)": acc.get("attitude model", 0.0),
        "controller: inner loop (the rest)": inner,
        "controller: allocation (Allocator.solve)": acc.get("allocation", 0.0),
        "plant steps (2 per tick, RKMK4)": acc.get("plant steps", 0.0),
    }
    parts["loop, reference, logging, the rest"] = timed.wall_time - sum(parts.values())
    walls = [log.wall_time for log in logs]
    simulated = float(logs[0].t[-1] - logs[0].t[0])
    st = settings.controller
    return dict(mission=CONTROL_MISSION, method="two-step", plant_rate_hz=settings.plant_rate,
                inner_rate_hz=st.inner_rate, outer_rate_hz=st.outer_rate, runs=runs, simulated_s=simulated,
                wall_s=float(np.median(walls)), wall_min_s=float(min(walls)), wall_runs_s=walls,
                real_time_factor=simulated / float(np.median(walls)), cpu_s=float(np.median(cpu)),
                cpu_real_time_factor=simulated / float(np.median(cpu)), ticks=ticks, plant_steps=steps * 2,
                breakdown_wall_s=timed.wall_time, breakdown_real_time_factor=timed.real_time_factor,
                breakdown_per_tick_s={k: v / ticks for k, v in parts.items()},
                breakdown_fraction={k: v / timed.wall_time for k, v in parts.items()},
                per_plant_step_s=acc.get("plant steps", 0.0) / max(1, 2 * steps))


def run_control(bench: Bench, quick: bool, progress: bool) -> dict:
    """The control section: allocation solvers side by side, then the closed-loop simulation's RTF."""
    try:
        import quadprog
    except ImportError:
        quadprog = None
    settings = CONTROL_SETTINGS[quick]
    load_before = os.getloadavg()
    rng = np.random.default_rng(SEED + 2)
    cases = []
    for name in fpr.ROBOTS:
        robot = fpr.load(name)
        states, hover = _allocation_states(robot, rng, settings["states"])
        for case, thrust in (("no bound active", hover), ("bounds active", SATURATING_THRUST * hover)):
            cases.append(_allocation_rows(bench, robot, case, states, thrust, quadprog))
    simulation = _simulation(settings["runs"], progress)
    targets = []
    for case in cases:
        solve = next(r for r in case["rows"] if "QP solve alone" in r["name"])
        value = solve["median_s"]
        targets.append(dict(target=f"warm ProxQP solve <= 20 us ({case['robot']}, {case['case']})",
                            value=value, met=value <= CONTROL_TARGETS["warm_qp_solve_s"]))
    targets += [
        dict(target="closed-loop simulation RTF >= 20", value=simulation["real_time_factor"],
             met=simulation["real_time_factor"] >= CONTROL_TARGETS["real_time_factor"]),
    ]
    return dict(settings=settings, allocation=cases, simulation=simulation, targets=targets,
                quadprog=_version("quadprog") if quadprog is not None else None,
                proxsuite=_version("proxsuite"), load_average_before=load_before,
                load_average_after=os.getloadavg())


def _version(package: str) -> str | None:
    """Installed version of a distribution, or None."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(package)
    except PackageNotFoundError:
        return None


def control_table(control: dict) -> str:
    """The control section as text: allocation rows by robot and case, agreement, the simulation's RTF."""
    rows = [r for c in control["allocation"] for r in c["rows"]]
    width = max(len(r["name"]) for r in rows)
    lines = [f"control (load average {control['load_average_before'][0]:.2f} -> "
             f"{control['load_average_after'][0]:.2f}; proxsuite {control['proxsuite']}, "
             f"quadprog {control['quadprog'] or 'not installed'})",
             f"allocation: {control['settings']['states']} states near hover (q, v + 0.01 N(0, 1), "
             f"u_a 0.1 N(0, 1) rad/s^2), cycled; bounds active: thrust {SATURATING_THRUST:g} x hover",
             f"{'name':<{width}}  {'median':>10}  {'min':>10}"]
    for case in control["allocation"]:
        for r in case["rows"]:
            lines.append(f"{r['name']:<{width}}  {fmt(r['median_s'])}  {fmt(r['min_s'])}")
        diffs = ", ".join(f"{k} {v:.2e}" for k, v in case["max_abs_w2_difference_to_warm"].items())
        lines.append(f"  {case['robot']} {case['case']}: {case['states_with_a_bound_active']}/"
                     f"{case['states']} states with a rotor at a bound; warm ProxQP "
                     f"{case['warm_iterations_mean']:.1f} iterations on average; max |w^2 - w^2 warm ProxQP| "
                     f"[(rad/s)^2, w_max^2 = {case['w_max2']:.3g}]: {diffs}")
        if case["note"]:
            lines.append(f"  note: {case['note']}")
    sim = control["simulation"]
    lines.append(f"\nclosed-loop simulation, mission {sim['mission']!r} ({sim['method']} plan), plant "
                 f"{sim['plant_rate_hz']:g} Hz, inner {sim['inner_rate_hz']:g} Hz, outer "
                 f"{sim['outer_rate_hz']:g} Hz: simulated {sim['simulated_s']:.2f} s, wall "
                 f"{sim['wall_s']:.2f} s (median of {sim['runs']}; min {sim['wall_min_s']:.2f} s) -> RTF "
                 f"{sim['real_time_factor']:.2f} (by CPU time: {sim['cpu_s']:.2f} s, RTF "
                 f"{sim['cpu_real_time_factor']:.2f})")
    lines.append(f"per-tick breakdown ({sim['ticks']} ticks; timed run: wall "
                 f"{sim['breakdown_wall_s']:.2f} s, RTF {sim['breakdown_real_time_factor']:.2f}, timers "
                 f"included; {fmt(sim['per_plant_step_s'])} per plant step)")
    for k, v in sim["breakdown_per_tick_s"].items():
        lines.append(f"  {k:<50}  {fmt(v)}  {100 * sim['breakdown_fraction'][k]:5.1f} %")
    for t in control["targets"]:
        lines.append(f"target {t['target']}: {t['value']:.4g} -> {'met' if t['met'] else 'NOT met'}")
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
                             "baseline capped at 15 s instead of 120 s; control: 32 states instead of 64, "
                             "1 simulation run instead of 3")
    parser.add_argument("--section", choices=("all", "model", "planning", "control"), default="all",
                        help="which part to run (default all)")
    args = parser.parse_args(argv)
    bench = Bench(repeats=3 if args.quick else 7, target=0.02 if args.quick else 0.05, progress=not args.json)
    info = dict(python=platform.python_version(), numpy=np.__version__, pinocchio=pin.__version__,
                cpu_count=os.cpu_count(), platform=platform.platform())
    residuals, planning, control = [], None, None
    if args.section in ("all", "model"):
        run_timings(bench)
        residuals = run_residuals()
    if args.section in ("all", "planning"):
        planning = run_planning(args.quick, progress=not args.json)
    if args.section in ("all", "control"):  # its own Bench: its rows are not the model table's
        control = run_control(Bench(bench.repeats, bench.target, bench.progress), args.quick,
                              progress=not args.json)
    if args.json:
        doc = dict(machine=info, repeats=bench.repeats, loop_target_s=bench.target, timings=bench.results,
                   residuals=residuals)
        if planning is not None:
            doc["planning"] = planning
        if control is not None:
            doc["control"] = control
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
