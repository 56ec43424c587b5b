"""Seeded families of random missions (fpr.bench.missions): reproducible, inside the robot's region and
workspace, travel times derived from the stop motion's feasibility (checked on the 500 Hz grid), and open to a
robot of one's own.
"""

from __future__ import annotations

import numpy as np
import pytest
from robots.unequal_fpr.robot import UnequalFpr

import fpr.robots
from fpr.bench.missions import (
    MissionFamily,
    MissionRegionError,
    _stop_feasible,
    builtin_families,
    least_stop_times,
    random_mission,
)
from fpr.model.errors import PlannerArgumentError
from planners.missions.mission import Mission
from planners.problem.report import evaluate_motion
from planners.trajectory.polynomial import PiecewisePolynomial, stop_points


@pytest.fixture(scope="module")
def loaded():
    return {name: fpr.robots.load(name) for name in fpr.robots.BUILTIN}


def test_builtin_families_cover_each_robots_spaces_and_modes():
    labels = [f.label for f in builtin_families(8)]
    assert labels == ["fpr task", "prototype task down", "prototype task up", "prototype joint down",
                      "prototype joint up", "fpr3 task"]
    assert all(f.way_points == 8 and f.via_points == (0, 2) for f in builtin_families(8))


@pytest.mark.parametrize("index", range(6))
def test_a_familys_mission_is_reproducible_valid_and_feasible_to_stop(loaded, index):
    """Same seed, same mission; another seed, another; every way point in the region and the workspace (the
    mission's own check), via points in range, and the stop-at-way-points motion feasible on the 500 Hz grid with
    its travel times at least 1.1 times the least feasible ones.
    """
    family = builtin_families(7)[index]
    robot = loaded[family.robot]
    mission = family.mission(3, robot)
    assert mission == family.mission(3, robot) and mission != family.mission(4, robot)
    assert isinstance(mission, Mission) and mission.n_way_points == 7 and mission.space == family.space
    lower, upper = robot.kind.mission_region(family.space, family.arm if robot.kind.assembly_modes else None)
    assert np.all(mission.way_points >= lower) and np.all(mission.way_points <= upper)
    poses = mission.positions(robot)  # raises on a way point out of the workspace
    assert np.all((mission.via_points >= 0) & (mission.via_points <= 2))
    stop = PiecewisePolynomial(stop_points(poses), mission.times)
    assert evaluate_motion(robot, stop).feasible
    least = least_stop_times(robot, poses, clearance=family.clearance)
    assert np.all(mission.times >= 1.1 * least - 1e-9)


def test_least_stop_time_is_the_feasibility_border(loaded):
    """The least feasible time of each travel: its stop motion holds every constraint there (on the search grid)
    and not 2 % faster (the search's precision is 1 %).
    """
    robot = loaded["fpr"]
    poses = builtin_families(5)[0].mission(1, robot).positions(robot)
    least = least_stop_times(robot, poses)
    assert np.all(_stop_feasible(robot, poses, least))
    assert not np.any(_stop_feasible(robot, poses, least / 1.02))


def test_settings_are_checked_and_a_region_is_needed():
    robot = fpr.robots.load("fpr")
    with pytest.raises(PlannerArgumentError, match="time_range"):
        random_mission(robot, 5, 0, time_range=(1.0, 2.0))
    with pytest.raises(PlannerArgumentError, match="way_points"):
        random_mission(robot, 1, 0)

    class Boxless(type(robot.kind)):
        def mission_region(self, space, mode):
            return None

    robot.kind = Boxless(robot)  # this test's own robot
    with pytest.raises(MissionRegionError, match="mission_region"):
        random_mission(robot, 5, 0)
    mission = random_mission(robot, 4, 0, region=([0.0, 0.0, 3.8, 1.4], [0.5, 0.5, 4.0, 1.7]))
    assert np.all(mission.way_points[:, 2] >= 3.8) and np.all(mission.way_points[:, :2] <= 0.5)


def test_a_robot_of_ones_own_gets_families():
    """A registered robot kind with a mission region (here inherited from the FPR's) gets random missions of
    its own, feasible to stop at every way point with its own links.
    """
    fpr.robots.register(UnequalFpr)
    try:
        robot = fpr.robots.load("unequal_fpr")
        mission = MissionFamily("unequal_fpr", 5).mission(0, robot)
        assert mission.robot == "unequal_fpr"
        stop = PiecewisePolynomial(stop_points(mission.positions(robot)), mission.times)
        assert evaluate_motion(robot, stop).feasible
    finally:
        fpr.robots.unregister("unequal_fpr")
