"""The control section's machine yardstick and the native parts' worth (:mod:`fpr.cli.bench.control`).

* The yardstick: the raw Python calls ``pin.crba`` of the FPR's minimal model and ``pin.constraintDynamics``
  of its closed chain (the plant's model, closures and proximal settings) at hover, each timed as the model
  section times Pinocchio (:class:`fpr.cli.bench.timing.Bench`). A figure of the simulation divided by them
  compares across machines of different speed: the real-time factor normalised by the yardstick is
  RTF x (``pin.crba`` time / 2 us).
* The tick's Pinocchio calls: one closed-loop run of the square's plan on the Python paths (every native part
  off), with counters on Pinocchio's algorithms (``constraintDynamics``, ``integrate``, ``dIntegrate``, the
  kinematics, ``crba``, ``nonLinearEffects``, the Jacobians), gives how many of each a tick needs (the native
  parts make the same calls, from C++); each is then timed raw from Python on the arguments it was first
  called with. Their sum per tick is the time of the Pinocchio calls the tick needs, and the tick's overhead
  ratio is the tick's time (the whole ``simulate`` call's wall time over its ticks, every part native) over
  that sum.
* Each native part on and off: whole ``simulate`` calls of the square's plan with every part native, with one
  part switched off, and with none (the Python paths), alternating run by run so that the machine's load
  changes all alike; the median real-time factor of each (by wall clock and by CPU time) and its ratio to
  every part native. Each round also times the tick's Pinocchio calls and ``pin.crba`` again: the overhead
  ratio and the normalised real-time factor divide figures taken in the same rounds, under the same load.
"""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin

from fpr import _native as native
from fpr.sim.closed_loop import SimulationSettings, simulate
from fpr.sim.plant import Plant, hover_configuration, hover_speeds

#: the real-time factor is normalised to a machine where the raw pin.crba of the FPR takes this long
YARDSTICK_CRBA_S = 2e-6
#: Pinocchio's algorithms counted in the tick (the accessors and spatial algebra are not)
COUNTED = ("constraintDynamics", "integrate", "dIntegrate", "forwardKinematics", "framesForwardKinematics",
           "computeJointJacobians", "updateFramePlacements", "crba", "nonLinearEffects", "rnea",
           "getFrameJacobian", "getJointJacobian")
#: the parts of the closed loop (the jets are the planner's)
LOOP_PARTS = ("loop", "plant", "measure", "attitude", "allocation", "inner", "watch")


def yardstick(bench, robot) -> dict:
    """The raw ``pin.crba`` (minimal model) and ``pin.constraintDynamics`` (closed chain) of ``robot`` at
    hover.
    """
    q = hover_configuration(robot, robot.kind.reference_chain)
    plant = Plant.from_minimal(robot, q, v=0.01 * np.ones(robot.nq), w=hover_speeds(robot, q))
    closed = plant.closed
    qp = robot.to_pinocchio(q)
    tau = np.zeros(closed.model.nv)
    crba = bench.time(f"yardstick: pin.crba ({robot.name} minimal model, raw Python call)",
                      lambda: pin.crba(robot.model, robot.data, qp))
    dynamics = bench.time(f"yardstick: pin.constraintDynamics ({robot.name} closed chain, "
                          f"{len(closed.constraints)} closures, raw Python call)",
                          lambda: pin.constraintDynamics(closed.model, closed.data, plant.qc, plant.vc, tau,
                                                         closed.constraints, closed.constraint_datas,
                                                         closed.settings))
    return dict(crba_s=crba["median_s"], constraint_dynamics_s=dynamics["median_s"],
                normalised_to_crba_s=YARDSTICK_CRBA_S)


def _counted_run(result) -> tuple[dict, dict, int]:
    """One Python-path closed loop of ``result`` with counters on :data:`COUNTED`: (calls by name, the first
    arguments of each, ticks).
    """
    counts, first = dict.fromkeys(COUNTED, 0), {}
    originals = {name: getattr(pin, name) for name in COUNTED}

    def counter(name, function):
        def counted(*args):
            counts[name] += 1
            if name not in first:
                first[name] = tuple(a.copy() if isinstance(a, np.ndarray) else a for a in args)
            return function(*args)
        return counted

    for name, function in originals.items():
        setattr(pin, name, counter(name, function))
    try:
        with native.switched(**dict.fromkeys(native.PARTS, False)):
            log = simulate(result, SimulationSettings())
    finally:
        for name, function in originals.items():
            setattr(pin, name, function)
    return counts, first, int(log.t.size)


def _raw_time(function, args, target: float = 0.02, repeats: int = 5) -> float:
    """Median time per call of ``function(*args)`` over ``repeats`` loops of about ``target`` seconds each (as
    :class:`fpr.cli.bench.timing.Bench` times, shorter).
    """
    function(*args)
    loops, elapsed = 1, 0.0
    while True:
        start = time.perf_counter()
        for _ in range(loops):
            function(*args)
        elapsed = time.perf_counter() - start
        if elapsed >= target / 10:
            break
        loops *= 4
    loops = max(1, round(loops * target / elapsed))
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(loops):
            function(*args)
        times.append((time.perf_counter() - start) / loops)
    return float(np.median(times))


def pinocchio_per_tick(bench, result) -> dict:
    """How many calls of each Pinocchio algorithm a tick of ``result``'s closed loop needs, each one's raw
    time, and their sum per tick (module docstring); ``arguments`` keeps each one's first arguments for
    :func:`parts_on_off`, which times them again round by round.
    """
    counts, first, ticks = _counted_run(result)
    calls = {}
    for name in COUNTED:
        if counts[name]:
            args, function = first[name], getattr(pin, name)
            row = bench.time(f"tick's Pinocchio: pin.{name} (raw Python call)", lambda f=function, a=args: f(*a))
            calls[name] = dict(per_tick=counts[name] / ticks, raw_s=row["median_s"])
    total = sum(c["per_tick"] * c["raw_s"] for c in calls.values())
    return dict(ticks=ticks, calls=calls, per_tick_s=total, arguments={n: first[n] for n in calls})


def _round_figures(pinocchio: dict, crba) -> tuple[float, float]:
    """(the tick's Pinocchio time, the raw pin.crba time) timed now (one round of :func:`parts_on_off`)."""
    total = sum(c["per_tick"] * _raw_time(getattr(pin, name), pinocchio["arguments"][name])
                for name, c in pinocchio["calls"].items())
    return total, _raw_time(*crba)


def parts_on_off(result, runs: int, say, pinocchio: dict, robot) -> dict:
    """Whole ``simulate`` calls with every part native, one part off, none; alternating (module docstring).
    Each round also times the tick's Pinocchio calls and the raw ``pin.crba`` again, so that the overhead
    ratio and the normalised real-time factor compare figures taken under the same load.
    """
    configs = [("every part native", {})] + [(f"{part} off", {part: False}) for part in LOOP_PARTS] \
        + [("no part native (Python paths)", dict.fromkeys(native.PARTS, False))]
    configs = [(label, switches) for label, switches in configs
               if not switches or any(native.parts()[p] for p in switches)]  # a part that is not native: no row
    walls, cpus = {label: [] for label, _ in configs}, {label: [] for label, _ in configs}
    crba = (pin.crba, (robot.model, robot.data, robot.to_pinocchio(hover_configuration(robot,
                                                                                        robot.kind.reference_chain))))
    per_tick, crba_times = [], []
    simulated, ticks = 0.0, 0
    for r in range(runs):
        figures = _round_figures(pinocchio, crba)
        per_tick.append(figures[0])
        crba_times.append(figures[1])
        for label, switches in configs:
            with native.switched(**switches):
                start, cpu = time.perf_counter(), time.process_time()
                log = simulate(result, SimulationSettings())
                walls[label].append(time.perf_counter() - start)
                cpus[label].append(time.process_time() - cpu)
            simulated, ticks = float(log.t[-1] - log.t[0]), int(log.t.size)
        say(f"bench control: parts on and off, round {r + 1}/{runs}")
    pinocchio_s, crba_s = float(np.median(per_tick)), float(np.median(crba_times))
    rows = []
    base = float(np.median(walls[configs[0][0]]))
    for label, switches in configs:
        wall, cpu = float(np.median(walls[label])), float(np.median(cpus[label]))
        rtf = simulated / wall
        rows.append(dict(label=label, off=sorted(switches), wall_s=wall, wall_runs_s=walls[label], cpu_s=cpu,
                         real_time_factor=rtf, cpu_real_time_factor=simulated / cpu,
                         normalised_real_time_factor=rtf * crba_s / YARDSTICK_CRBA_S, tick_s=wall / ticks,
                         overhead_ratio=wall / ticks / pinocchio_s, slowdown=wall / base))
    return dict(runs=runs, simulated_s=simulated, ticks=ticks, pinocchio_per_tick_s=pinocchio_s,
                pinocchio_per_tick_runs_s=per_tick, crba_s=crba_s, crba_runs_s=crba_times, rows=rows)


def native_lines(parts: dict, stick: dict, pinocchio: dict, fmt) -> list[str]:
    """The yardstick, the tick's Pinocchio calls and the parts on and off as text lines."""
    lines = [f"machine yardstick: pin.crba (FPR) {fmt(stick['crba_s'])}, pin.constraintDynamics (FPR closed "
             f"chain) {fmt(stick['constraint_dynamics_s'])} (raw Python calls)",
             f"the tick's Pinocchio calls ({pinocchio['ticks']} ticks of the Python paths counted; raw time of "
             f"each): {fmt(pinocchio['per_tick_s'])} per tick"]
    for name, c in pinocchio["calls"].items():
        lines.append(f"  pin.{name:<24} {c['per_tick']:6.2f} per tick x {fmt(c['raw_s'])}")
    lines.append(f"native parts on and off: whole simulate calls of the square, {parts['simulated_s']:.2f} s "
                 f"simulated, {parts['ticks']} ticks, median of {parts['runs']} alternating rounds; each round "
                 f"also timed the tick's Pinocchio calls (median {fmt(parts['pinocchio_per_tick_s'])} per tick) "
                 f"and pin.crba (median {fmt(parts['crba_s'])}):")
    lines.append(f"  {'':<32} {'wall':>8} {'RTF':>7} {'RTF (CPU)':>10} {'normalised':>11} {'tick':>11} "
                 f"{'overhead':>9} {'slower':>7}")
    for row in parts["rows"]:
        lines.append(f"  {row['label']:<32} {row['wall_s']:7.3f}s {row['real_time_factor']:7.2f} "
                     f"{row['cpu_real_time_factor']:10.2f} {row['normalised_real_time_factor']:11.2f} "
                     f"{fmt(row['tick_s']):>11} {row['overhead_ratio']:9.2f} {row['slowdown']:6.2f}x")
    return lines
