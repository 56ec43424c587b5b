"""The benchmark's JSON (``python -m fpr.bench --json``) as tables: pure Python, no Sphinx needed.

:func:`render` gives the tables of one part of a run (``PARTS``: run, goals, model, ..., replan-phases);
``bench_tables.py`` (the Sphinx extension) turns them into the page's tables. The benchmark's schema may grow or
lose fields: a part whose data
is absent or has another shape renders as a one-line "not measured in this run" note instead of failing the
build, so an older or partial JSON (e.g. ``--section planning`` alone) still builds. Every number shown is
read from the file; nothing is typed here.
"""

from __future__ import annotations

import logging
import math
import re
from typing import NamedTuple

LOG = logging.getLogger(__name__)


class Table(NamedTuple):
    """One table: its header and its rows, every cell a string."""

    header: list[str]
    rows: list[list[str]]


class NotMeasured(Exception):
    """The part asked for is absent from the run (or has a shape this renderer does not know)."""


# ---------------------------------------------------------------------------------------------- formatting
def fmt_time(seconds) -> str:
    """A duration in the unit that keeps 3-4 significant digits (ns, µs, ms, s)."""
    if seconds is None or not isinstance(seconds, (int, float)) or not math.isfinite(seconds):
        return "—"
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6), ("ns", 1e-9)):
        if abs(seconds) >= scale or unit == "ns":
            return f"{seconds / scale:.3g} {unit}"
    return f"{seconds:.3g} s"  # pragma: no cover


def fmt_num(value, digits: int = 4) -> str:
    """A number with ``digits`` significant digits; booleans as yes / no; None as a dash."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return f"{value:.{digits}g}" if math.isfinite(value) else str(value)
    return str(value)


def fmt_goal_value(value, unit, target: str = "") -> str:
    """A goal's value in its unit (seconds as a duration; without a unit, one read off the target's text)."""
    if unit is None and re.search(r"\d\s*(s|ms|us|µs)\b", target):
        unit = "s"
    return fmt_time(value) if unit == "s" else fmt_num(value)


def verdict(row: dict) -> str:
    """met / not met / undecided from a goal row (``verdict`` or ``met``)."""
    if "verdict" in row:
        return str(row["verdict"])
    met = row.get("met")
    return "undecided" if met is None else ("met" if met else "not met")


def fmt_load(load) -> str:
    """A load average triple (1, 5, 15 minutes)."""
    if not isinstance(load, (list, tuple)) or not load:
        return "—"
    return " / ".join(f"{x:.2f}" for x in load)


def list_table(header: list[str], rows: list[list]) -> list[Table]:
    """One table of strings (NotMeasured when it has no rows)."""
    if not rows:
        raise NotMeasured("no rows")
    return [Table([str(h) for h in header], [[str(c) for c in row] for row in rows])]


def need(doc: dict, *path):
    """doc[path[0]][path[1]]...; NotMeasured when a key is absent or None."""
    value = doc
    for key in path:
        if not isinstance(value, (dict, list)):
            raise NotMeasured("/".join(map(str, path)))
        try:
            value = value[key]
        except (KeyError, IndexError, TypeError) as exc:
            raise NotMeasured("/".join(map(str, path))) from exc
        if value is None:
            raise NotMeasured("/".join(map(str, path)))
    return value


# ------------------------------------------------------------------------------------------------ the parts
def part_run(doc: dict) -> list[Table]:
    """The machine and the load average of each section's run."""
    machine = need(doc, "machine")
    rows = [[key, machine[key]] for key in ("platform", "cpu_count", "python", "numpy", "pinocchio") if key in machine]
    rows.append(["repeats of each timing loop", fmt_num(doc.get("repeats"))])
    if isinstance(doc.get("loop_target_s"), (int, float)):
        rows.append(["length of each timing loop", fmt_time(doc["loop_target_s"])])
    for section in ("planning", "control", "scaling"):
        part = doc.get(section)
        if isinstance(part, dict) and "load_average_before" in part:
            rows.append([f"load average (1 / 5 / 15 min), {section}: before → after",
                         f"{fmt_load(part.get('load_average_before'))} → {fmt_load(part.get('load_average_after'))}"])
    replan = doc.get("replan")
    if isinstance(replan, dict) and "load_average" in replan:
        rows.append(["load average (1 / 5 / 15 min), replan", fmt_load(replan["load_average"])])
    return list_table(["property of the run", "value"], rows)


def part_goals(doc: dict) -> list[Table]:
    """Every goal the bench checks, its value and verdict."""
    rows = [[g.get("section", ""), g.get("target", ""),
             fmt_goal_value(g.get("value"), g.get("unit"), str(g.get("target", ""))), verdict(g)]
            for g in need(doc, "goals")]
    return list_table(["section", "goal", "value", "verdict"], rows)


def part_model(doc: dict) -> list[Table]:
    """The model's timings (median of the repeats) and their ratio to a reference call."""
    rows = [[t["name"], fmt_time(t.get("median_s")), fmt_time(t.get("min_s")),
             "" if t.get("ratio") is None else f"{t['ratio']:.2f} × {t.get('ratio_to')}"]
            for t in need(doc, "timings")]
    return list_table(["call", "median", "least", "ratio"], rows)


def part_residuals(doc: dict) -> list[Table]:
    """The model's consistency residuals."""
    rows = [[r["name"], fmt_num(r.get("value"), 3), fmt_num(r.get("samples"))] for r in need(doc, "residuals")]
    return list_table(["check", "largest residual", "samples"], rows)


def part_planning(doc: dict) -> list[Table]:
    """The planners on the bench's mission, and the speed-up over the finite-difference baseline."""
    planning = need(doc, "planning")
    rows = [[i["name"], fmt_time(i.get("wall_time_s")), fmt_num(i.get("J")), fmt_num(i.get("iterations")),
             fmt_num(i.get("feasible"))] for i in need(planning, "items")]
    lines = list_table(["planner (mission " + str(planning.get("mission", "?")) + ")", "time", "J", "iterations",
                        "feasible"], rows)
    speedups = planning.get("speedups")
    if isinstance(speedups, dict) and speedups:
        srows = [[key, ("≥ " if s.get("lower_bound") else "") + f"{s['ratio']:.1f} ×", fmt_time(s.get("ours_s")),
                  fmt_time(s.get("baseline_time_s")), fmt_num(s.get("baseline_reached_our_J"))]
                 for key, s in speedups.items() if isinstance(s, dict) and "ratio" in s]
        if srows:
            lines += list_table(["method", "speed-up over the baseline", "ours", "baseline", "baseline reached our J"],
                                srows)
    return lines


def part_optimality(doc: dict) -> list[Table]:
    """J against the best known, the KKT residuals, per mission and planner."""
    rows = [[r["mission"], r["planner"], fmt_num(r.get("J")), fmt_num(r.get("best_J")),
             "—" if r.get("gap") is None else f"{100 * r['gap']:+.2f} %", fmt_num(r.get("solver_kkt"), 2),
             fmt_num(r.get("one_step_kkt"), 2), fmt_num(r.get("iterations")), fmt_time(r.get("wall_time_s")),
             fmt_num(r.get("feasible"))]
            for r in need(doc, "planning", "optimality")]
    return list_table(["mission", "planner", "J", "best J known", "gap", "KKT (last stage)", "KKT (1-step NLP)",
                       "iterations", "time", "feasible"], rows)


def part_sensitivities(doc: dict) -> list[Table]:
    """One evaluation's node sensitivities: dual numbers against the complex step."""
    s = need(doc, "planning", "sensitivities")
    rows = [[fmt_num(s.get("nodes")), fmt_time(s.get("dual_s")), fmt_time(s.get("complex_s")),
             fmt_num(s.get("ratio"), 3)]]
    return list_table(["grid nodes", "dual numbers", "complex step", "ratio"], rows)


def _family_label(row: dict, arms: set) -> str:
    """A family's name: robot and space, and the assembly mode when the robot's families have more than one."""
    label = f"{row.get('robot', '?')} {row.get('space', '?')}"
    return label + (f" {row['arm']}" if len(arms) > 1 and row.get("arm") else "")


def part_families(doc: dict) -> list[Table]:
    """The planning section's families of random missions: per family and method, per robot, and the loop."""
    families = need(doc, "planning", "families")
    rows = need(families, "rows")
    arms = {robot: {r.get("arm") for r in rows if r.get("robot") == robot} for robot in {r.get("robot") for r in rows}}
    table = [[_family_label(r, arms[r.get("robot")]), r.get("method", ""), fmt_num(len(r.get("seeds", []))),
              fmt_time(r.get("median_s")), fmt_time(r.get("p95_s")), fmt_time(r.get("max_s")),
              fmt_num(r.get("failures")), fmt_num(r.get("worse_than_unpolished")), fmt_num(r.get("J_median"))]
             for r in rows]
    table += [[f"{r.get('robot', '?')}, all families", r.get("method", ""), fmt_num(r.get("missions")),
               fmt_time(r.get("median_s")), fmt_time(r.get("p95_s")), fmt_time(r.get("max_s")),
               fmt_num(r.get("failures")), fmt_num(r.get("worse_than_unpolished")), fmt_num(r.get("J_median"))]
              for r in need(families, "robots")]
    loop = families.get("loop")
    if isinstance(loop, dict):
        table += [[f"{r.get('mission', 'the loop')} (the loop)", method, fmt_num(len(r.get("times_s", []))),
                   fmt_time(r.get("median_s")), "", "", fmt_num(0 if r.get("feasible") else 1), "", fmt_num(r.get("J"))]
                  for method, r in loop.items() if isinstance(r, dict)]
    header = [f"family ({fmt_num(families.get('way_points'))} way points)", "method", "missions", "median", "p95",
              "largest", "failures", "J above the unpolished two-step's", "J (median)"]
    lines = list_table(header, table)
    stick = families.get("yardstick")
    if isinstance(stick, dict):
        lines += list_table(["the machine's pace (yardstick, same run)", "median per call"],
                            [[stick.get("name", "?"), fmt_time(stick.get("median_s"))]])
    return lines


def part_scaling(doc: dict) -> list[Table]:
    """Planning time against the mission's length: per robot (its families' missions together), length and
    method, and the loop; the growth exponents.
    """
    scaling = need(doc, "scaling")
    robots = need(scaling, "robots")
    methods = list(dict.fromkeys(r["method"] for r in robots))
    rows = []
    for robot, count in dict.fromkeys((r["robot"], r["way_points"]) for r in robots):
        mine = {r["method"]: r for r in robots if (r["robot"], r["way_points"]) == (robot, count)}
        if not set(methods) <= set(mine):
            raise NotMeasured(f"scaling: {robot}, {count} way points lacks a method")
        cells = [c for m in methods for c in (fmt_time(mine[m].get("median_s")), fmt_time(mine[m].get("p95_s")))]
        rows.append([robot, fmt_num(count), fmt_num(mine[methods[0]].get("missions")), *cells,
                     fmt_num(sum(r.get("failures", 0) for r in mine.values())),
                     " / ".join(fmt_num(mine[m].get("J_median")) for m in methods)])
    loop = scaling.get("loop")
    for count in dict.fromkeys(r["way_points"] for r in loop) if isinstance(loop, list) else ():
        mine = {r["method"]: r for r in loop if r["way_points"] == count}
        if set(methods) <= set(mine):
            rows.append(["the loop", fmt_num(count), "1",
                         *(c for m in methods for c in (fmt_time(mine[m].get("wall_time_s")), "")),
                         fmt_num(sum(not r.get("feasible") for r in mine.values())),
                         " / ".join(fmt_num(mine[m].get("J")) for m in methods)])
    header = ["robot", "way points", "missions", *(c for m in methods for c in (f"{m} median", f"{m} p95")),
              "failures", "J (median), " + " / ".join(methods)]
    lines = list_table(header, rows)
    exponents = scaling.get("exponents")
    if isinstance(exponents, list) and exponents:
        lines += list_table(["robot", "method", "growth exponent of the median time in the way points"],
                            [[e.get("robot", ""), e.get("method", ""), fmt_num(e.get("exponent"), 3)]
                             for e in exponents])
    return lines


def part_allocation(doc: dict) -> list[Table]:
    """The rotor allocation's calls, one table per robot and case."""
    lines = []
    for block in need(doc, "control", "allocation"):
        title = f"{block.get('robot', '?')}, {block.get('case', '?')}"
        lines += list_table(["call (" + title + ")", "median", "least"],
                            [[r["name"].split(": ", 1)[-1].strip(), fmt_time(r.get("median_s")),
                              fmt_time(r.get("min_s"))] for r in block.get("rows", [])])
    return lines


def part_allocation_loops(doc: dict) -> list[Table]:
    """Every tick's whole allocation call along two closed loops, by route and path."""
    sequences = need(doc, "control", "allocation_along_loops", "sequences")
    rows = []
    for loop, seq in sequences.items():
        for variant in (seq, seq.get("python")):
            if not isinstance(variant, dict):
                continue
            for route in ("all", "closed_form", "qp"):
                stats = variant.get(route)
                if isinstance(stats, dict):
                    rows.append([loop, variant.get("path", "?"), route.replace("_", " "), fmt_num(stats.get("ticks")),
                                 fmt_time(stats.get("median_s")), fmt_time(stats.get("p90_s")),
                                 fmt_time(stats.get("max_s"))])
    return list_table(["closed loop", "path", "route", "ticks", "median", "90 %", "worst"], rows)


def part_simulation(doc: dict) -> list[Table]:
    """The closed-loop simulation's real-time factor and its per-tick breakdown."""
    sim = need(doc, "control", "simulation")
    rows = [["mission, method", f"{sim.get('mission', '?')}, {sim.get('method', '?')}"],
            ["rates: plant / inner loop / outer loop",
             " / ".join(fmt_num(sim.get(k)) + " Hz" for k in ("plant_rate_hz", "inner_rate_hz", "outer_rate_hz"))],
            ["simulated time", fmt_time(sim.get("simulated_s"))],
            ["wall time of the whole simulate call", fmt_time(sim.get("wall_s"))],
            ["real-time factor (wall clock)", fmt_num(sim.get("real_time_factor"), 3)],
            ["real-time factor (CPU time)", fmt_num(sim.get("cpu_real_time_factor"), 3)],
            ["control ticks / plant steps", f"{fmt_num(sim.get('ticks'))} / {fmt_num(sim.get('plant_steps'))}"]]
    lines = list_table(["closed-loop simulation", "value"], rows)
    per_tick, fraction = sim.get("breakdown_per_tick_s"), sim.get("breakdown_fraction") or {}
    if isinstance(per_tick, dict) and per_tick:
        lines += list_table(["part of a control tick", "time per tick", "share"],
                            [[name, fmt_time(t), "—" if fraction.get(name) is None else f"{100 * fraction[name]:.0f} %"]
                             for name, t in per_tick.items()])
    return lines


def part_native(doc: dict) -> list[Table]:
    """The machine yardstick, the Pinocchio calls a tick needs, and the native parts switched on and off."""
    control = need(doc, "control")
    stick, pinocchio = need(control, "yardstick"), need(control, "pinocchio_per_tick")
    parts = need(control, "native_parts")
    crba, reference = need(stick, "crba_s"), need(stick, "normalised_to_crba_s")
    tables = list_table(["machine yardstick (raw Python calls)", "time"],
                        [["pin.crba (FPR minimal model)", fmt_time(crba)],
                         ["pin.constraintDynamics (FPR closed chain)", fmt_time(stick.get("constraint_dynamics_s"))]])
    per_tick = need(pinocchio, "per_tick_s")
    tables += list_table([f"Pinocchio calls a tick needs ({fmt_num(pinocchio.get('ticks'))} ticks counted)", "per tick",
                          "raw time of one call"],
                         [[f"pin.{name}", fmt_num(c.get("per_tick"), 3), fmt_time(c.get("raw_s"))]
                          for name, c in need(pinocchio, "calls").items()]
                         + [["all, per tick", "", fmt_time(per_tick)]])
    tables += list_table(["whole simulate call of the square", "wall (median)", "real-time factor",
                          f"normalised to pin.crba = {fmt_time(reference)}", "time per tick",
                          "overhead ratio (tick / its Pinocchio calls)", "slowdown"],
                         [[r["label"], fmt_time(r.get("wall_s")), fmt_num(r.get("real_time_factor"), 3),
                           fmt_num(r["real_time_factor"] * crba / reference, 3), fmt_time(r.get("tick_s")),
                           fmt_num(r["tick_s"] / per_tick, 3), f"{r.get('slowdown', float('nan')):.2f} ×"]
                          for r in need(parts, "rows")])
    return tables


def _stats_row(name: str, item: dict) -> list:
    wall, cpu, model = item.get("wall") or {}, item.get("cpu") or {}, item.get("model") or {}
    return [name, fmt_num(wall.get("n")), fmt_time(wall.get("median_s")), fmt_time(wall.get("p95_s")),
            fmt_time(wall.get("worst_s")), fmt_time(cpu.get("p95_s")), fmt_time(model.get("median_s"))]


def part_replan(doc: dict) -> list[Table]:
    """The replanning latency on the built-in missions, against the deadline."""
    replan = need(doc, "replan")
    rows = [_stats_row(name, item) for name, item in need(replan, "items").items() if isinstance(item, dict)]
    if isinstance(replan.get("all"), dict):
        rows.append(_stats_row("all", replan["all"]))
    return list_table(["replans (deadline " + fmt_time(replan.get("deadline_s")) + ")", "count", "wall median",
                       "wall 95 %", "wall worst", "CPU 95 %", "modelled (work model)"], rows)


def part_replan_phases(doc: dict) -> list[Table]:
    """One replan taken apart into its phases (least CPU time of the repeats)."""
    phases = need(doc, "replan", "phases")
    cpu = need(phases, "cpu_s")
    # "directions": the dual directions per node (a run of the dual-number planner); "copies": the complex step's
    # perturbed copies (an older run)
    sizes = (f"{fmt_num(phases['directions'])} dual directions a node" if "directions" in phases
             else f"{fmt_num(phases.get('copies'))} perturbed copies")
    title = f"phase ({fmt_num(phases.get('nodes'))} grid nodes, {sizes}, " \
            f"{fmt_num(phases.get('dense_samples'))} dense samples)"
    return list_table([title, "CPU time"], [[name.strip(), fmt_time(t)] for name, t in cpu.items()])


def part_latency_model(doc: dict) -> list[Table]:
    """The replanner's latency model: each robot's costs as measured on the run's machine, and the modelled over
    the measured latency of the run's replans.
    """
    replan = need(doc, "replan")
    robots = need(replan, "calibration")["robots"]
    features = next(iter(robots.values()))["features"]
    rows = [[name, *(fmt_time(x) for x in robot["costs"])] for name, robot in robots.items()]
    lines = list_table(["robot", *features], rows)
    ratio = replan.get("model_over_wall")
    if isinstance(ratio, dict):
        lines += list_table(["modelled / measured latency", "median", "least", "largest"],
                            [["ratio", fmt_num(ratio.get("median"), 3), fmt_num(ratio.get("min"), 3),
                              fmt_num(ratio.get("max"), 3)]])
    return lines


PARTS = {
    "run": part_run, "goals": part_goals, "model": part_model, "residuals": part_residuals,
    "planning": part_planning, "optimality": part_optimality, "sensitivities": part_sensitivities,
    "families": part_families, "scaling": part_scaling, "allocation": part_allocation,
    "allocation-loops": part_allocation_loops,
    "simulation": part_simulation, "native": part_native, "replan": part_replan, "replan-phases": part_replan_phases,
    "latency-model": part_latency_model,
}


def render(doc: dict | None, part: str) -> list[Table | str]:
    """The tables of ``part`` of the run ``doc``, or one "not measured" note (a string) when it cannot be."""
    try:
        if doc is None:
            raise NotMeasured("no benchmark file")
        return PARTS[part](doc)
    except (NotMeasured, KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        LOG.debug("bench-table %s: not measured (%s)", part, exc)
        return [f"Not measured in this run (the benchmark file has no usable {part!r} data)."]
