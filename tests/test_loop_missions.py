"""The loop missions (fpr.bench.missions.loop_mission): valid, deterministic, every travel alike."""

from __future__ import annotations

import numpy as np
import pytest

from fpr.bench.missions import LOOP_RADIUS, loop_mission, loop_way_points
from planners.methods.way_points import WayPointTask
from planners.problem.report import evaluate_motion


# ---------------------------------------------------------------------------------------------- generator
@pytest.mark.parametrize("count", [2, 5, 13])
def test_loop_missions_are_valid_and_alike_travel_by_travel(count):
    """Every way point on the circle, every travel a 0.5 m chord in 1.5 s (the square's 3 s per metre),
    the robot reaches every way point, and the stop-at-every-way-point motion holds every constraint.
    """
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
