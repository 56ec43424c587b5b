"""Planning families of missions (fpr.bench.families) and the bench's planning and scaling sections built on
them (fpr.cli.bench.families, fpr.cli.bench.scaling): statistics, the comparison with the unpolished two-step,
the goals and the tables.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from fpr.bench.families import FamilyRow, plan_family, unpolished_comparison
from fpr.bench.missions import MissionFamily
from fpr.bench.tables import families_markdown, main, scaling_markdown
from fpr.cli.bench.cli import parser
from fpr.cli.bench.families import families_table, family_seeds
from fpr.cli.bench.scaling import EXPONENT_GOAL, _by_robot, _targets, growth_exponent, scaling_table
from planners.optimize import plan


@pytest.fixture(scope="module")
def rows():
    return plan_family(MissionFamily("prototype", 4, arm="up"), seeds=[0, 1])


def test_a_family_is_planned_seed_by_seed_by_both_methods(rows):
    """One row per method, one entry per seed; feasible plans, J below the stop motion's (1), the statistics
    from the times, and a J no worse than the unpolished two-step's on its grid (the polish keeps the better).
    """
    assert [r.method for r in rows] == ["two-step", "one-step"]
    for r in rows:
        assert r.seeds == [0, 1] and len(r.times_s) == len(r.J) == len(r.J_grid) == 2
        assert r.failures == 0 and all(0.0 < j < 1.0 for j in r.J)
        assert r.median_s == pytest.approx(np.median(r.times_s)) and r.p95_s <= max(r.times_s)
    two_step = rows[0]
    assert all(j <= u * (1 + 1e-12) for j, u in zip(two_step.J_grid, two_step.J_unpolished_grid, strict=True))
    summary = json.loads(json.dumps(rows[1].summary()))  # plain types
    assert summary["failures"] == 0 and summary["via_points"] == [0, 2] and "p95_s" in summary


def test_unpolished_comparison_reads_the_polish_start():
    """The unpolished two-step J is the polish's J_start; the polished plan's grid J is no higher."""
    mission = MissionFamily("fpr", 4, via_points=(1, 1)).mission(2)
    robot = mission.load_robot()
    two = plan(mission, "two-step", robot=robot)
    polish = [st for st in two.stages if st.name == "polish (one-step)"]
    mine, reference = unpolished_comparison(mission, robot, two, two)
    assert reference == polish[0].J_start and mine <= reference * (1 + 1e-12)


def test_worse_than_unpolished_counts_beyond_the_tolerance():
    row = FamilyRow("fpr", "task", "down", 4, (0, 2), "one-step", J_grid=[0.50, 0.5001, 0.6, np.nan],
                    J_unpolished_grid=[0.51, 0.50, 0.50, 0.5])
    assert row.worse_than_unpolished == 2  # 0.5001 vs 0.50 is above 1e-4 relative, and 0.6


def test_seeds_are_shared_among_a_robots_families():
    assert family_seeds([1, 2, 3, 4], 20) == [list(range(5))] * 4
    assert family_seeds([1, 2, 3, 4], 6) == [[0, 1], [0, 1], [0], [0]]
    assert family_seeds([1], 6) == [list(range(6))]


def test_growth_exponent_is_the_log_log_slope_from_8_way_points():
    counts = [4, 8, 16, 32, 64]
    times = [100.0] + [2.0 * c**1.1 for c in counts[1:]]  # 4 way points left out of the fit
    assert growth_exponent(counts, times) == pytest.approx(1.1, abs=1e-12)


def test_scaling_rows_goals_and_table():
    """Per robot, length and method, the families' missions together; the exponent's goal per robot and method."""
    rows = []
    for count in (4, 8, 16):
        for method, power in (("two-step", 1.0), ("one-step", 1.5)):
            for _space in ("task", "joint"):
                rows.append(dict(robot="prototype", way_points=count, method=method, times_s=[0.01 * count**power],
                                 J=[0.5], failures=0))
    summary = _by_robot(rows)
    assert len(summary) == 6 and all(r["missions"] == 2 for r in summary)
    exponents = [dict(robot="prototype", method="two-step", exponent=1.0),
                 dict(robot="prototype", method="one-step", exponent=1.5)]
    goals = _targets(exponents)
    assert [g["met"] for g in goals] == [True, False] and goals[0]["goal"] == EXPONENT_GOAL
    loop = [dict(way_points=c, method=m, wall_time_s=0.1, J=0.5, feasible=True, iterations=3)
            for c in (4, 8, 16) for m in ("two-step", "one-step")]
    text = scaling_table(dict(rows=rows, robots=summary, loop=loop, exponents=exponents, targets=goals,
                              yardstick=dict(name="pin.crba (FPR)", median_s=1e-6), members=2,
                              load_average_before=(1.0,), load_average_after=(1.0,)))
    assert text.count("\n") >= 3 + 3 + 2 and "NOT met" in text


def test_families_table_lists_families_robots_and_the_loop(rows):
    robots = [dict(robot="prototype", method=r.method, missions=2, median_s=r.median_s, p95_s=r.p95_s,
                   max_s=max(r.times_s), failures=r.failures, worse_than_unpolished=0, J_median=0.5) for r in rows]
    text = families_table(dict(way_points=4, seeds_per_robot=2, yardstick=dict(name="pin.crba (FPR)", median_s=1e-6),
                               rows=[r.summary() for r in rows], robots=robots,
                               loop={"two-step": dict(mission="loop-4", times_s=[0.1], median_s=0.1, J=0.5,
                                                      iterations=3)}))
    assert "prototype task up" in text and "prototype (all)" in text and "loop-4" in text


def test_bench_has_the_sections():
    assert parser().parse_args(["--section", "scaling", "--quick"]).section == "scaling"
    assert parser().parse_args(["--section", "planning"]).section == "planning"


def test_documentation_tables_come_from_the_json(rows, tmp_path, capsys):
    """The Markdown tables from a bench JSON: the families' rows, the robots' and the loop's; the scaling rows."""
    robots = [dict(robot="prototype", method=r.method, missions=2, median_s=r.median_s, p95_s=r.p95_s,
                   max_s=max(r.times_s), failures=0, worse_than_unpolished=0, J_median=0.5) for r in rows]
    families = dict(way_points=4, seeds_per_robot=2, yardstick=dict(name="pin.crba (FPR)", median_s=1e-6),
                    rows=[r.summary() for r in rows], robots=robots,
                    loop={"two-step": dict(mission="loop-4", times_s=[0.1], median_s=0.1, J=0.5, feasible=True)})
    text = families_markdown(families)
    assert "| prototype task up | two-step | 2 |" in text and "**prototype, all**" in text and "loop-4" in text
    scaling = dict(members=2, yardstick=families["yardstick"], load_average_before=[1.0], load_average_after=[1.0],
                   robots=[dict(robot="fpr", way_points=8, method=m, median_s=0.5, p95_s=0.7, failures=0)
                           for m in ("two-step", "one-step")],
                   loop=[dict(way_points=8, method=m, wall_time_s=0.2, feasible=True)
                         for m in ("two-step", "one-step")],
                   exponents=[dict(robot="fpr", method="two-step", exponent=1.01)])
    assert "| fpr | 8 | 500 ms (700 ms) | 500 ms (700 ms) | 0 |" in scaling_markdown(scaling)
    path = tmp_path / "bench.json"
    path.write_text(json.dumps(dict(planning=dict(families=families), scaling=scaling)))
    assert main([str(path)]) == 0 and "Growth exponent" in capsys.readouterr().out
    assert main([str(tmp_path / "missing.json")]) == 2
