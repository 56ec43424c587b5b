"""The rotor allocation timed as the control loop calls it (``python -m fpr.bench --section control``).

The allocator's inputs (attitude model, wanted thrusts, wanted attitude accelerations) are recorded at every
inner-loop tick of two real closed loops (:func:`fpr.sim.closed_loop.simulate`, default settings):

* ``square``: the built-in mission's two-step plan, 13 s simulated (6501 ticks; no rotor bound is reached);
* ``fast square``: the same square in 1 s per side stopping at every way point (the plan asks w^2 < 0 at some
  instants): rotors saturate, the robot loses tracking at about 0.55 s and the simulation stops there (the
  case of ``tests/test_simulate.py::test_saturation_is_reported_and_rotors_stay_within_limits``).

Each sequence is then replayed, in order, through a fresh :class:`controllers.allocation.Allocator` (so each
call is warm from the previous tick, as in the loop), timing every whole ``Allocator.solve`` call
(``time.perf_counter`` around it: the closed form or the QP's build, update and solve, and the result),
garbage collector off; ``passes`` replays, and each tick keeps its least time (the machine's noise only adds).
The ticks are split by the route the allocator took (closed form: no bound active; QP: a bound active, the
active-set method or ProxQP).
"""

from __future__ import annotations

import gc
import time

import numpy as np

from controllers.allocation import Allocator
from fpr.sim.closed_loop import SimulationSettings, simulate

#: the goal of the whole call, with or without an active bound [s]
ALLOCATION_GOAL_S = 20e-6


def record_allocations(result, settings: SimulationSettings) -> tuple[list[tuple], object]:
    """The (attitude, thrust, u_a) of every ``Allocator.solve`` call in ``simulate(result, settings)``.

    Returns:
        the calls in order, and the simulation's log.
    """
    calls = []
    original = Allocator.solve

    def recording(self, attitude, thrust, u_a):
        calls.append((attitude, np.array(thrust, dtype=float), np.array(u_a, dtype=float)))
        return original(self, attitude, thrust, u_a)

    Allocator.solve = recording
    try:
        log = simulate(result, settings)
    finally:
        Allocator.solve = original
    return calls, log


def replay(robot, calls: list[tuple], passes: int) -> dict:
    """Time every call of a recorded sequence through fresh allocators (module docstring).

    Returns:
        ticks, their routes, and per route (and over all ticks) the median, mean, 90th percentile and
        largest time per call [s].
    """
    best = np.full(len(calls), np.inf)
    routes = []
    for p in range(passes):
        allocator = Allocator(robot)
        counts = allocator.routes
        gc.disable()
        try:
            for k, (attitude, thrust, u_a) in enumerate(calls):
                before = counts["closed form"]
                start = time.perf_counter()
                allocator.solve(attitude, thrust, u_a)
                elapsed = time.perf_counter() - start
                best[k] = min(best[k], elapsed)
                if p == 0:
                    routes.append("closed form" if counts["closed form"] > before else "qp")
        finally:
            gc.enable()
    routes = np.array(routes)

    def stats(times):
        if times.size == 0:
            return None
        return dict(ticks=int(times.size), median_s=float(np.median(times)), mean_s=float(times.mean()),
                    p90_s=float(np.percentile(times, 90)), max_s=float(times.max()))

    return dict(ticks=len(calls), passes=passes, bound_active_ticks=int((routes == "qp").sum()),
                all=stats(best), closed_form=stats(best[routes == "closed form"]),
                qp=stats(best[routes == "qp"]))


def allocation_along_loops(square_plan, fast_plan, passes: int, say) -> dict:
    """Record both closed loops (module docstring) and replay them; the goal rows."""
    sequences = {}
    for label, result, settings in (("square", square_plan, SimulationSettings()),
                                    ("fast square", fast_plan, SimulationSettings(hold=0.0))):
        calls, log = record_allocations(result, settings)
        say(f"bench control: recorded {len(calls)} allocations along the {label} closed loop")
        sequences[label] = dict(replay(result.robot, calls, passes), failure=log.failure)
    targets = []
    for label, route, what in (("square", "closed_form", "no bound active"),
                               ("fast square", "qp", "bounds active")):
        figures = sequences[label][route]
        value = figures["median_s"] if figures else float("nan")
        targets.append(dict(target=f"allocation, whole Allocator.solve call, {what} (median over the {label} "
                                   f"closed loop's ticks) <= 20 us", value=value, goal=ALLOCATION_GOAL_S,
                            unit="s", met=bool(value <= ALLOCATION_GOAL_S)))
    return dict(sequences=sequences, targets=targets)


def allocation_lines(loops: dict, fmt) -> list[str]:
    """The replay as text lines."""
    lines = ["allocation along real closed loops (each tick's whole Allocator.solve call, replayed in order, "
             f"least of {next(iter(loops['sequences'].values()))['passes']} passes):"]
    for label, seq in loops["sequences"].items():
        lines.append(f"  {label}: {seq['ticks']} ticks, {seq['bound_active_ticks']} with a bound active"
                     + (f" (stopped: {seq['failure']})" if seq["failure"] else ""))
        for route in ("all", "closed_form", "qp"):
            s = seq[route]
            if s:
                name = route.replace("_", " ")
                lines.append(f"    {name:<12} {s['ticks']:5d} ticks: median {fmt(s['median_s'])}, "
                             f"mean {fmt(s['mean_s'])}, p90 {fmt(s['p90_s'])}, max {fmt(s['max_s'])}")
    return lines


__all__ = ["ALLOCATION_GOAL_S", "allocation_along_loops", "allocation_lines", "record_allocations", "replay"]
