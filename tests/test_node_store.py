"""NodeDerivatives: a problem whose segments another problem of the plan evaluated takes their derivatives."""

import numpy as np

from planners.methods.one_step import one_step_problem
from planners.methods.two_step import travel_problem
from planners.methods.way_points import WayPointTask
from planners.missions.mission import load_mission
from planners.optimisation.solving import Grid
from planners.problem.motion import MotionProblem, NodeDerivatives


def test_the_whole_problem_at_the_travels_points_takes_their_derivatives_and_they_are_its_own():
    mission = load_mission("square")
    task = WayPointTask.of(mission, mission.load_robot())
    grid = Grid()
    normalisation = task.normalisation(grid)
    points, durations, is_way = task.via_layout
    points = points.copy()
    shared = NodeDerivatives()
    rng = np.random.default_rng(7)
    way = np.flatnonzero(is_way)
    for a, b in zip(way[:-1], way[1:], strict=True):  # each travel moved somewhere, evaluated there with derivatives
        travel = travel_problem(task, points, durations, a, b, normalisation, grid)
        travel.share_node_derivatives(shared)
        x = travel.x_of(points[a:b + 1]) + 0.01 * rng.standard_normal(travel.n_x)
        travel.evaluate(x, True)
        points[a:b + 1] = travel.points_of(x)
    whole = one_step_problem(task, grid, normalisation)
    whole.share_node_derivatives(shared)
    x0 = whole.x_of(points)
    calls = []
    original = NodeDerivatives.get
    NodeDerivatives.get = lambda self, *args: calls.append(original(self, *args)) or calls[-1]
    try:
        stored = whole.evaluate(x0, True)
    finally:
        NodeDerivatives.get = original
    assert calls and calls[-1] is not None  # every segment came from the store
    fresh = MotionProblem(task.robot, whole.points, whole.durations, whole.free, whole.alpha, normalisation,
                          grid.samples_per_segment, grid.windows_per_segment, dips=True).evaluate(x0, True)
    assert abs(stored.J - fresh.J) <= 1e-14 * abs(fresh.J)
    for name in ("constraints", "gradient", "jacobian", "hessian"):
        a, b = np.asarray(getattr(stored, name)), np.asarray(getattr(fresh, name))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * max(1.0, np.abs(b).max()), err_msg=name)


def test_problems_share_only_when_given_a_store():
    mission = load_mission("square")
    task = WayPointTask.of(mission, mission.load_robot())
    problem = one_step_problem(task, Grid())
    assert problem.node_store is None
    x = problem.x_of(problem.points)
    first = problem.evaluate(x, True)
    again = one_step_problem(task, Grid())  # the same problem again, no store: computed again
    assert again.node_store is None and again.evaluate(x, True).gradient is not first.gradient


def test_an_owner_replaces_only_its_own_entries_and_far_points_miss():
    store = NodeDerivatives()
    first, second = store.owner(), store.owner()
    points = np.arange(30.0).reshape(3, 5, 2) + 1.0
    durations = np.array([1.5, 1.5])
    store.put(first, points, durations, 17, ["a0", "a1"])
    store.put(second, points + 1.0, durations, 17, ["b0", "b1"])
    assert store.get(points, durations, 17) == ["a0", "a1"]
    assert store.get(points + 1.0, durations, 17) == ["b0", "b1"]
    store.put(first, points + 2.0, durations, 17, ["c0", "c1"])  # first's earlier entries go, second's stay
    assert store.get(points, durations, 17) is None
    assert store.get(points + 1.0, durations, 17) == ["b0", "b1"]
    assert store.get(np.nextafter(points + 1.0, np.inf), durations, 17) == ["b0", "b1"]  # 1 ulp off
    assert store.get(points + 1.0 + 1e-9, durations, 17) is None
    assert store.get(points + 1.0, np.array([1.5, 1.25]), 17) is None
    assert store.get(points + 1.0, durations, 33) is None
