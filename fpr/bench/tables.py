"""The documentation's tables of planning speed, made from the bench's JSON (``python -m fpr.bench --json``).

``python -m fpr.bench.tables bench.json`` prints Markdown: the planning section's families of random missions
(per family and per robot: median, p95, failures, J) and the scaling section's table (per robot and length,
both methods, the loop, the growth exponents), with the yardstick and the load of the run they came from.
Numbers in the documentation are these, not typed.
"""

from __future__ import annotations

import json
import sys

from fpr import robots


def family_label(row: dict) -> str:
    """A family row's name: robot and space, and the assembly mode for a robot that has more than one."""
    return f"{row['robot']} {row['space']}" + (f" {row['arm']}" if robots.get(row["robot"]).assembly_modes else "")


def _seconds(value: float) -> str:
    return f"{value:.2f} s" if value >= 0.995 else f"{value * 1e3:.0f} ms"


def families_markdown(families: dict) -> str:
    """The planning section's families (``doc["planning"]["families"]``) as a Markdown table."""
    lines = [f"Random missions of {families['way_points']} way points, {families['seeds_per_robot']} a robot; "
             f"yardstick {families['yardstick']['name']} {families['yardstick']['median_s'] * 1e6:.2f} us.", "",
             "| family | method | missions | median | p95 | failures | J above the unpolished two-step's | "
             "J (median) |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in families["rows"]:
        lines.append(f"| {family_label(r)} | {r['method']} | {len(r['seeds'])} | {_seconds(r['median_s'])} | "
                     f"{_seconds(r['p95_s'])} | {r['failures']} | {r['worse_than_unpolished']} | {r['J_median']:.4f} |")
    for r in families["robots"]:
        lines.append(f"| **{r['robot']}, all** | {r['method']} | {r['missions']} | {_seconds(r['median_s'])} | "
                     f"{_seconds(r['p95_s'])} | {r['failures']} | {r['worse_than_unpolished']} | {r['J_median']:.4f} |")
    for method, r in families["loop"].items():
        lines.append(f"| {r['mission']} (the loop) | {method} | {len(r['times_s'])} | {_seconds(r['median_s'])} | "
                     f"| {0 if r['feasible'] else 1} | | {r['J']:.4f} |")
    return "\n".join(lines)


def scaling_markdown(scaling: dict) -> str:
    """The scaling section (``doc["scaling"]``) as a Markdown table: median (p95) per robot, length and method."""
    methods = list(dict.fromkeys(r["method"] for r in scaling["robots"]))
    lines = [f"{scaling['members']} random missions a robot and length; yardstick {scaling['yardstick']['name']} "
             f"{scaling['yardstick']['median_s'] * 1e6:.2f} us; load average "
             f"{scaling['load_average_before'][0]:.1f} -> {scaling['load_average_after'][0]:.1f}.", "",
             "| robot | way points | " + " | ".join(f"{m} median (p95)" for m in methods) + " | failures |",
             "| --- | --- | " + " | ".join("---" for _ in methods) + " | --- |"]
    for robot, count in dict.fromkeys((r["robot"], r["way_points"]) for r in scaling["robots"]):
        mine = {r["method"]: r for r in scaling["robots"] if (r["robot"], r["way_points"]) == (robot, count)}
        cells = [f"{_seconds(mine[m]['median_s'])} ({_seconds(mine[m]['p95_s'])})" for m in methods]
        failures = sum(r["failures"] for r in mine.values())
        lines.append(f"| {robot} | {count} | " + " | ".join(cells) + f" | {failures} |")
    for count in dict.fromkeys(r["way_points"] for r in scaling["loop"]):
        mine = {r["method"]: r for r in scaling["loop"] if r["way_points"] == count}
        cells = [_seconds(mine[m]["wall_time_s"]) for m in methods]
        failures = sum(not r["feasible"] for r in mine.values())
        lines.append(f"| loop | {count} | " + " | ".join(cells) + f" | {failures} |")
    lines.append("")
    lines += [f"Growth exponent of the median time (8..64 way points), {e['robot']}, {e['method']}: "
              f"{e['exponent']:.2f}" for e in scaling["exponents"]]
    return "\n".join(lines)


def main(argv=None) -> int:
    """Print the tables of the bench JSON file given (its planning families and scaling sections, when there)."""
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python -m fpr.bench.tables BENCH.json (from python -m fpr.bench --json)", file=sys.stderr)
        return 2
    try:
        with open(argv[0], encoding="utf-8") as f:
            doc = json.load(f)
    except (OSError, ValueError) as error:
        print(f"{argv[0]}: {error}: give the JSON that python -m fpr.bench --json wrote", file=sys.stderr)
        return 2
    parts = []
    if (doc.get("planning") or {}).get("families"):
        parts.append(families_markdown(doc["planning"]["families"]))
    if doc.get("scaling"):
        parts.append(scaling_markdown(doc["scaling"]))
    print("\n\n".join(parts) if parts else "no planning families or scaling section in this file")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
