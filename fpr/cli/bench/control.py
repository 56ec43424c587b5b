"""Control section of the benchmark (``python -m fpr.bench --section control``).

Side by side in one run for the FPR (8 rotor variables) and the prototype (4), at states near hover (q and v
perturbed by 0.01, small wanted attitude accelerations u_a), in two cases: hover thrusts (no rotor bound active)
and 3 times the hover thrusts (bounds active):

1. the full :meth:`controllers.allocation.Allocator.solve` call (its closed form when no bound is active,
   else its bounded route; the states cycled, so not warm from a neighbouring tick: the loop's figure is
   :mod:`fpr.cli.bench.loop_allocation`'s; the row names the path, the native tick when it is built, and the
   Python path has its own row then), and the allocator's ProxQP workspace warm-started: the QP solve
   alone (``allocator.qp.solve()`` after ``qp.update``, only the solve timed), with ``qp.update`` and the
   building of H, g on their own rows;
2. ProxQP cold: ``proxsuite.proxqp.dense.solve`` from scratch on the same scaled problem;
3. the closed-form pseudo-inverse law (:func:`controllers.allocation.pseudo_inverse_law`) and the rotor
   map, which ignores the bounds;
4. quadprog (Goldfarb-Idnani, cold) on the same scaled problem (a core dependency, the replanner's solver;
   the row is skipped with a note should it be missing).

The largest difference of each solution's w^2 from ``Allocator.solve``'s is printed (the pseudo-inverse
law differs when a bound is active, by design). Then the allocation as the control loop calls it
(:mod:`fpr.cli.bench.loop_allocation`: every tick's whole
``Allocator.solve`` call along two real closed loops, one with rotor bounds active), and the closed-loop
simulation of the ``square`` mission's two-step plan (:func:`fpr.sim.closed_loop.simulate`, default settings:
plant 1 kHz, inner loop 500 Hz, outer loop 100 Hz): simulated time, the wall time of the whole ``simulate``
call and the real-time factor (median of 3 runs, 1 with ``--quick``; the CPU time too, less sensitive to a
shared machine), and one more run with timers around the simulator's parts (observe: measure and logged
kinematics, outer loop, attitude model, allocation, the rest of the inner loop, plant steps, the watch; the
remainder is the loop itself and the logging) for the per-tick breakdown, with which parts of the tick run
natively (:mod:`fpr._native`; that run with the part ``loop`` off: the native loop has no timers
inside). Then :mod:`fpr.cli.bench.native_parts`: the machine yardstick (the raw
``pin.crba`` and ``pin.constraintDynamics`` of the FPR), the Pinocchio calls a tick needs, and each native part on
and off side by side. Goals, each a row of ``targets`` with its value, goal and verdict: the allocation's whole
call <= 20 us with and without an active bound; the square's whole-simulate RTF normalised by the yardstick (RTF
x raw ``pin.crba`` time / 2 us) >= 20; the tick's overhead ratio (its time over the time of the Pinocchio calls it
needs) <= 2.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import sys
import time
from importlib.metadata import PackageNotFoundError, version

import numpy as np

import fpr
from controllers.allocation import Allocator, pseudo_inverse_law
from controllers.ctc import CascadedController
from fpr import _native as native
from fpr.cli.bench.loop_allocation import allocation_along_loops, allocation_lines, path_name
from fpr.cli.bench.model import SEED
from fpr.cli.bench.native_parts import native_lines, parts_on_off, pinocchio_per_tick, yardstick
from fpr.cli.bench.timing import Bench, cycling, fmt, time_part
from fpr.model.inverse_dynamics import inverse_dynamics
from fpr.model.qp import proxsuite_module
from fpr.model.robot import Robot
from fpr.sim.closed_loop import SimulationSettings, simulate
from fpr.sim.plant import Plant, hover_configuration
from fpr.sim.watch import Watch
from planners.missions.mission import load_mission
from planners.optimize import plan

CONTROL_MISSION = "square"
CONTROL_SETTINGS = {True: {"states": 32, "runs": 1, "passes": 2},  # quick / full
                    False: {"states": 64, "runs": 3, "passes": 5}}
#: goals: the square's whole-simulate RTF normalised by the yardstick (native_parts), the tick's overhead ratio
CONTROL_TARGETS = {"normalised_real_time_factor": 20.0, "overhead_ratio": 2.0}
#: thrust of the "bounds active" allocation case, in hover thrusts
SATURATING_THRUST = 3.0


def _allocation_states(robot, rng, count: int):
    """Attitude models near hover (q, v perturbed by 0.01), the hover thrusts, small u_a (0.1 rad/s^2)."""
    chain = robot.kind.reference_chain
    q0 = hover_configuration(robot, chain)
    motion = np.zeros((5, 1, len(chain)))
    motion[0, 0] = chain
    hover = inverse_dynamics(robot, motion).thrust[0]
    n_a = len(robot.layout.attitude)
    states = [(robot.attitude_model(q0 + 0.01 * rng.normal(size=robot.nq), 0.01 * rng.normal(size=robot.nq)),
               0.1 * rng.normal(size=n_a)) for _ in range(count)]
    return states, hover



def _allocation_rows(bench: Bench, robot, case: str, states, thrust, quadprog) -> dict:
    """The timed allocation rows of one robot and case, and the agreement of the solvers' w^2."""
    label = f"{robot.name} {case}"
    allocator = Allocator(robot)
    scale, n = allocator.scale, allocator.n
    lower, upper = allocator.lower / scale, allocator.upper / scale
    problems = []  # the scaled QPs of the allocator (H w_max^4, g w_max^2), on zeta = w^2 / w_max^2
    for attitude, u_a in states:
        h, g = allocator.build(attitude, thrust, u_a)
        problems.append((h * scale**2, g * scale))
    # the allocator along the states, in order (its answers: the reference of the agreement figures)
    warm = np.array([allocator.solve(attitude, thrust, u_a).speeds_squared.reshape(-1)
                     for attitude, u_a in states])
    saturated = sum(bool(allocator.solve(attitude, thrust, u_a).any_saturated) for attitude, u_a in states)
    allocator._proxqp(*problems[0])  # its ProxQP workspace (the fallback route) initialised, warm-starting
    iterations = []
    for h, g in problems:
        allocator.qp.update(H=h, g=g, update_preconditioner=False)
        allocator.qp.solve()
        iterations.append(int(allocator.qp.results.info.iter))
    calls = [(a, thrust, u) for a, u in states]
    rows = [bench.time(f"{label}: (1) Allocator.solve, full call ({path_name(allocator)} path, states cycled)",
                       cycling(allocator.solve, calls))]
    if allocator.compiled:  # the Python path (the reference) on the same calls
        with native.switched(allocation=False):
            python = Allocator(robot)
        rows.append(bench.time(f"{label}:     Allocator.solve, full call (Python path, states cycled)",
                               cycling(python.solve, calls)))
    pool = itertools.cycle(problems)
    current = [None]

    def update():
        current[0] = next(pool)
        allocator.qp.update(H=current[0][0], g=current[0][1], update_preconditioner=False)

    rows.append(time_part(bench, f"{label}: (1) ProxQP warm, QP solve alone (qp.solve after update)", update,
                           allocator.qp.solve))
    rows.append(time_part(bench, f"{label}:     ProxQP warm, qp.update(H, g) alone", lambda: None, update))
    rows.append(bench.time(f"{label}:     building H, g (Allocator.build)",
                           cycling(allocator.build, [(a, thrust, u) for a, u in states])))

    proxsuite = proxsuite_module()  # the build the planner and the allocator use (fpr.model.qp), at its first use

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
        note = "quadprog not installed (pip install quadprog): row (4) skipped"
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
    patched = []
    for cls, method, key in ((Plant, "measure", "measure"),
                             (Plant, "drone_positions_and_closure_error", "logged kinematics"),
                             (Plant, "observe", "observe"),
                             (Plant, "advance", "plant steps"),  # the closed loop's steps of a tick
                             (CascadedController, "update", "controller"),
                             (CascadedController, "outer", "outer loop"),
                             (Robot, "attitude_model", "attitude model"),
                             (Allocator, "solve", "allocation"),
                             (Watch, "check", "watch")):
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



def _simulation(result, runs: int, say) -> dict:
    """RTF of the closed-loop simulation of the square mission (two-step plan ``result``), and its per-tick
    breakdown.

    The wall time is the whole ``simulate`` call's (the plan sampled, its inverse dynamics, the plant and
    controller built, the loop, the log assembled), not only the loop's.
    """
    settings = SimulationSettings()
    logs, cpu, walls = [], [], []
    for k in range(runs):
        start, wall = time.process_time(), time.perf_counter()  # CPU time: less sensitive to the load
        logs.append(simulate(result, settings))
        walls.append(time.perf_counter() - wall)
        cpu.append(time.process_time() - start)
        say(f"bench control: simulation {k + 1}/{runs}: {walls[-1]:.2f} s wall (whole call), "
            f"RTF {(logs[-1].t[-1] - logs[-1].t[0]) / walls[-1]:.2f}")
    acc = {}
    with _tick_timers(acc), native.switched(loop=False):  # the tick part by part (the native loop has no timers)
        timed = simulate(result, settings)
    ticks = timed.t.size
    steps = ticks - 1
    controller = acc.get("controller", 0.0)
    inner = controller - sum(acc.get(k, 0.0) for k in ("outer loop", "attitude model", "allocation"))
    parts = {
        "measure (Plant.measure: to_minimal)": acc.get("measure", 0.0),
        "logged kinematics (drone heights, closure error)": acc.get("logged kinematics", 0.0)
        + acc.get("observe", 0.0) - acc.get("measure", 0.0),  # observe = measure + the kinematics
        "controller: outer loop (100 Hz)": acc.get("outer loop", 0.0),
        "controller: inner loop (attitude model)": acc.get("attitude model", 0.0),
        "controller: inner loop (the rest)": inner,
        "controller: allocation (Allocator.solve)": acc.get("allocation", 0.0),
        "plant steps (2 per tick, RKMK4)": acc.get("plant steps", 0.0),
        "watch (Watch.check)": acc.get("watch", 0.0),
    }
    parts["loop, reference, logging, the rest"] = timed.wall_time - sum(parts.values())
    simulated = float(logs[0].t[-1] - logs[0].t[0])
    st = settings.controller
    running = native.parts()
    running["loop"] = False  # the breakdown's run
    return dict(mission=CONTROL_MISSION, method="two-step", plant_rate_hz=settings.plant_rate,
                inner_rate_hz=st.inner_rate, outer_rate_hz=st.outer_rate, runs=runs, simulated_s=simulated,
                wall_s=float(np.median(walls)), wall_min_s=float(min(walls)), wall_runs_s=walls,
                real_time_factor=simulated / float(np.median(walls)), cpu_s=float(np.median(cpu)),
                loop_wall_s=float(np.median([log.wall_time for log in logs])),
                cpu_real_time_factor=simulated / float(np.median(cpu)), ticks=ticks, plant_steps=steps * 2,
                breakdown_wall_s=timed.wall_time, breakdown_real_time_factor=timed.real_time_factor,
                breakdown_per_tick_s={k: v / ticks for k, v in parts.items()},
                breakdown_fraction={k: v / timed.wall_time for k, v in parts.items()},
                per_plant_step_s=acc.get("plant steps", 0.0) / max(1, 2 * steps), native=running)



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
    say = (lambda text: print(text, file=sys.stderr, flush=True)) if progress else (lambda text: None)
    square = plan(load_mission(CONTROL_MISSION), "two-step")
    fast = plan(load_mission(CONTROL_MISSION).replace(times=[1.0] * 4), "none")  # saturates (loop_allocation)
    loops = allocation_along_loops(square, fast, settings["passes"], say)
    simulation = _simulation(square, settings["runs"], say)
    stick = yardstick(bench, square.robot)
    pinocchio = pinocchio_per_tick(bench, square)
    parts = parts_on_off(square, settings["runs"], say, pinocchio, square.robot)
    pinocchio.pop("arguments")
    every = parts["rows"][0]  # every part native, the same rounds as the others' (and as the yardstick's)
    normalised, overhead = every["normalised_real_time_factor"], every["overhead_ratio"]
    simulation.update(normalised_real_time_factor=normalised, overhead_ratio=overhead)
    targets = loops["targets"] + [
        dict(target="closed-loop simulation of the square, plant 1 kHz: real-time factor (whole simulate call, "
                    "every native part on) x raw pin.crba time / 2 us >= 20", value=normalised,
             goal=CONTROL_TARGETS["normalised_real_time_factor"], unit="x",
             met=bool(normalised >= CONTROL_TARGETS["normalised_real_time_factor"])),
        dict(target="the tick's overhead ratio (tick time / the time of the Pinocchio calls it needs) <= 2",
             value=overhead, goal=CONTROL_TARGETS["overhead_ratio"], unit="x",
             met=bool(overhead <= CONTROL_TARGETS["overhead_ratio"])),
    ]
    return dict(settings=settings, allocation=cases, allocation_along_loops=loops, simulation=simulation,
                yardstick=stick, pinocchio_per_tick=pinocchio, native_parts=parts, targets=targets,
                quadprog=_version("quadprog") if quadprog is not None else None,
                proxsuite=_version("proxsuite"), load_average_before=load_before,
                load_average_after=os.getloadavg())



def _version(package: str) -> str | None:
    """Installed version of a distribution, or None."""
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
                     f"{case['warm_iterations_mean']:.1f} iterations on average; "
                     f"max |w^2 - w^2 Allocator.solve| [(rad/s)^2, w_max^2 = {case['w_max2']:.3g}]: {diffs}")
        if case["note"]:
            lines.append(f"  note: {case['note']}")
    sim = control["simulation"]
    lines.append(f"\nclosed-loop simulation, mission {sim['mission']!r} ({sim['method']} plan), plant "
                 f"{sim['plant_rate_hz']:g} Hz, inner {sim['inner_rate_hz']:g} Hz, outer "
                 f"{sim['outer_rate_hz']:g} Hz: simulated {sim['simulated_s']:.2f} s, wall "
                 f"{sim['wall_s']:.2f} s, whole simulate call (median of {sim['runs']}; min "
                 f"{sim['wall_min_s']:.2f} s; the loop alone {sim['loop_wall_s']:.2f} s) -> RTF "
                 f"{sim['real_time_factor']:.2f} (by CPU time: {sim['cpu_s']:.2f} s, RTF "
                 f"{sim['cpu_real_time_factor']:.2f})")
    lines.append(f"per-tick breakdown ({sim['ticks']} ticks; timed run: wall "
                 f"{sim['breakdown_wall_s']:.2f} s, RTF {sim['breakdown_real_time_factor']:.2f}, timers "
                 f"included; {fmt(sim['per_plant_step_s'])} per plant step; native: "
                 f"{', '.join(k for k, v in sim.get('native', {}).items() if v) or 'nothing'})")
    for k, v in sim["breakdown_per_tick_s"].items():
        lines.append(f"  {k:<50}  {fmt(v)}  {100 * sim['breakdown_fraction'][k]:5.1f} %")
    lines += native_lines(control["native_parts"], control["yardstick"], control["pinocchio_per_tick"], fmt)
    lines += allocation_lines(control["allocation_along_loops"], fmt)
    for t in control["targets"]:
        lines.append(f"target {t['target']}: {t['value']:.4g} -> {'met' if t['met'] else 'NOT met'}")
    return "\n".join(lines)
