"""Planning at scale (issue 13): the long missions' generator, the banded step-QP route against the dense
one and ProxQP, the scaling bench's fit and goals."""

from __future__ import annotations

import numpy as np
import pytest

from fpr.cli.bench.cli import parser
from fpr.cli.bench.scaling import EXPONENT_GOAL, _targets, growth_exponent, scaling_table
from planners.methods.way_points import WayPointTask
from fpr.bench.missions import LOOP_RADIUS, loop_mission, loop_way_points
from planners.problem.report import evaluate_motion


# ---------------------------------------------------------------------------------------------- generator
@pytest.mark.parametrize("count", [2, 5, 13])
def test_loop_missions_are_valid_and_alike_travel_by_travel(count):
    """Every way point on the circle, every travel a 0.5 m chord in 1.5 s (the square's 3 s per metre),
    the robot reaches every way point, and the stop-at-every-way-point motion holds every constraint."""
    mission = loop_mission(count, via_points=2)
    robot = mission.load_robot()
    s = mission.positions(robot)  # raises on an unreachable or singular way point
    assert s.shape == (count, 4)
    radius = np.hypot(s[:, 0] - 0.5, s[:, 1] - 0.5)
    np.testing.assert_allclose(radius, LOOP_RADIUS, atol=1e-12)
    chords = np.linalg.norm(np.diff(s[:, :2], axis=0), axis=1)
    np.testing.assert_allclose(chords, 2 * LOOP_RADIUS * np.sin(np.pi / 6), atol=1e-12)
    np.testing.assert_allclose(mission.times, 3.0 * chords, atol=1e-9)
    assert np.all(mission.via_points == 2) and mission.alpha == 0.5
    assert np.all((s[:, 2] > np.pi + 0.2) & (s[:, 2] < 2 * np.pi - 0.2))  # phi inside its bounds (3.28)
    task = WayPointTask.of(mission, robot)
    assert evaluate_motion(robot, task.stop).feasible


def test_loop_missions_are_deterministic_and_nested():
    """The same count gives the same mission; a longer one starts with a shorter one's way points."""
    assert loop_mission(9, 1) == loop_mission(9, 1)
    np.testing.assert_array_equal(loop_way_points(16)[:8], loop_way_points(8))


# ---------------------------------------------------------------------------------------------- the bench
def test_growth_exponent_is_the_log_log_slope_from_8_way_points():
    counts = [4, 8, 16, 32]
    times = [100.0, 2.0 * 8**1.3, 2.0 * 16**1.3, 2.0 * 32**1.3]  # 4 way points left out of the fit
    assert growth_exponent(counts, times) == pytest.approx(1.3, abs=1e-12)


def test_scaling_goals_and_table():
    rows = [dict(way_points=c, via_points=1, method=m, wall_time_s=t, J=0.5, feasible=True, iterations=9,
                 variables=10)
            for c in (4, 8, 16, 32) for m, t in (("two-step", 0.05 * c), ("one-step", 0.05 * c**2))]
    exponents = [dict(via_points=1, method="two-step", exponent=1.0), dict(via_points=1, method="one-step",
                                                                             exponent=2.0)]
    goals = {t["target"]: t for t in _targets(rows, exponents)}
    two_step = goals["32 way points, two-step <= 2 s"]
    assert two_step["met"] and two_step["value"] == 1.6
    assert not goals["32 way points, one-step <= 30 s"]["met"]  # 51.2 s
    assert goals[f"growth exponent in the way points, two-step <= {EXPONENT_GOAL:g}"]["met"]
    assert not goals[f"growth exponent in the way points, one-step <= {EXPONENT_GOAL:g}"]["met"]
    text = scaling_table(dict(rows=rows, exponents=exponents, targets=list(goals.values()),
                              load_average_before=(1.0,), load_average_after=(1.0,)))
    assert text.count("\n") >= 4 + 2 and "NOT met" in text


def test_bench_has_the_scaling_section():
    assert parser().parse_args(["--section", "scaling", "--quick"]).section == "scaling"
