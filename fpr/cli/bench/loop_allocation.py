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
active-set method or ProxQP). The default path is measured (the native tick, ``fpr/_native/alloc.c``, when
it is built; the lines say which) and, when it is the native one, the Python path too, interleaved pass by
pass (their ratio: an A/B in one run); the goals are the default path's.
"""

from __future__ import annotations

import gc
import time

import numpy as np

from controllers.allocation import Allocator
from fpr import _native as native
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
        with native.switched(loop=False):  # every tick's call through Allocator.solve (the native loop: its kernel)
            log = simulate(result, settings)
    finally:
        Allocator.solve = original
    return calls, log


def path_name(allocator) -> str:
    """Which path an allocator's ``solve`` runs."""
    return "native (C)" if allocator.compiled else "Python"


def replay(robot, calls: list[tuple], passes: int, compiled: bool | None = None) -> dict:
    """Time every call of a recorded sequence through fresh allocators (module docstring).

    Args:
        robot: the robot the calls were recorded on (each pass builds fresh allocators for it).
        calls: the recorded (attitude model, wanted thrusts [N], wanted attitude accelerations u_a) of every
            ``Allocator.solve`` call, in order (:func:`record_allocations`).
        passes: how many times the sequence is replayed; each call keeps its least time.
        compiled: :mod:`fpr._native`'s part ``allocation`` switched on (True) or off (False) for the replay's
            allocators; None: as the switch is.

    Returns:
        the path measured ("native (C)" or "Python"), ticks, their routes, and per route (and over all
        ticks) the median, mean, 90th percentile and largest time per call [s].
    """
    return replay_paths(robot, calls, passes, (compiled,))[0]


def replay_paths(robot, calls: list[tuple], passes: int, paths) -> list[dict]:
    """:func:`replay` for several ``compiled`` settings, interleaved pass by pass (an A/B on a shared machine:
    the load changes both alike); one :func:`replay` dict per setting.
    """
    best = [np.full(len(calls), np.inf) for _ in paths]
    routes = [[] for _ in paths]
    names = []
    for p in range(passes):
        for m, compiled in enumerate(paths):
            with native.switched(**({} if compiled is None else {"allocation": compiled})):
                allocator = Allocator(robot)
            if p == 0:
                names.append(path_name(allocator))
            counts = allocator.routes
            gc.disable()
            try:
                for k, (attitude, thrust, u_a) in enumerate(calls):
                    before = counts["closed form"]
                    start = time.perf_counter()
                    allocator.solve(attitude, thrust, u_a)
                    elapsed = time.perf_counter() - start
                    best[m][k] = min(best[m][k], elapsed)
                    if p == 0:
                        routes[m].append("closed form" if counts["closed form"] > before else "qp")
            finally:
                gc.enable()

    def stats(times):
        if times.size == 0:
            return None
        return dict(ticks=int(times.size), median_s=float(np.median(times)), mean_s=float(times.mean()),
                    p90_s=float(np.percentile(times, 90)), max_s=float(times.max()))

    out = []
    for name, times, route in zip(names, best, routes, strict=True):
        route = np.array(route)
        out.append(dict(path=name, ticks=len(calls), passes=passes,
                        bound_active_ticks=int((route == "qp").sum()), all=stats(times),
                        closed_form=stats(times[route == "closed form"]), qp=stats(times[route == "qp"])))
    return out


def allocation_along_loops(square_plan, fast_plan, passes: int, say) -> dict:
    """Record both closed loops (module docstring) and replay them; the goal rows."""
    sequences = {}
    for label, result, settings in (("square", square_plan, SimulationSettings()),
                                    ("fast square", fast_plan, SimulationSettings(hold=0.0))):
        calls, log = record_allocations(result, settings)
        say(f"bench control: recorded {len(calls)} allocations along the {label} closed loop")
        measured = replay_paths(result.robot, calls, passes, (None, False))  # the default path, Python's
        default = measured[0]
        python = measured[1] if default["path"] != "Python" else None
        sequences[label] = dict(default, failure=log.failure, python=python)
    targets = []
    for label, route, what in (("square", "closed_form", "no bound active"),
                               ("fast square", "qp", "bounds active")):
        figures = sequences[label][route]
        value = figures["median_s"] if figures else float("nan")
        path = sequences[label]["path"]
        targets.append(dict(target=f"allocation, whole Allocator.solve call ({path} path), {what} (median "
                                   f"over the {label} closed loop's ticks) <= 20 us", value=value,
                            goal=ALLOCATION_GOAL_S, unit="s", met=bool(value <= ALLOCATION_GOAL_S)))
    return dict(sequences=sequences, targets=targets)


def allocation_lines(loops: dict, fmt) -> list[str]:
    """The replay as text lines."""
    lines = ["allocation along real closed loops (each tick's whole Allocator.solve call, replayed in order, "
             f"least of {next(iter(loops['sequences'].values()))['passes']} passes):"]
    for label, seq in loops["sequences"].items():
        lines.append(f"  {label}: {seq['ticks']} ticks, {seq['bound_active_ticks']} with a bound active"
                     + (f" (stopped: {seq['failure']})" if seq["failure"] else ""))
        measured = [seq] + ([seq["python"]] if seq.get("python") else [])
        for route in ("all", "closed_form", "qp"):
            for path in measured:
                s = path[route]
                if s:
                    name = route.replace("_", " ")
                    ratio = (f", Python / native {s['median_s'] / seq[route]['median_s']:.2f}"
                             if path is not seq else "")
                    lines.append(f"    {name:<12} {path['path']:<12} {s['ticks']:5d} ticks: median "
                                 f"{fmt(s['median_s'])}, mean {fmt(s['mean_s'])}, p90 {fmt(s['p90_s'])}, "
                                 f"max {fmt(s['max_s'])}{ratio}")
    return lines


__all__ = ["ALLOCATION_GOAL_S", "allocation_along_loops", "allocation_lines", "record_allocations", "replay",
           "replay_paths"]
