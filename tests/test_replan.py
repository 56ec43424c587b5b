"""The replanner (planners/replanning/replanner.py): C4 splices, the deadline fallback, infeasible plans kept out."""

import numpy as np
import pytest

from fpr.model.inverse_dynamics import MOTION_ORDER, inverse_dynamics
from planners.missions.mission import load_mission
from planners.optimize import plan
from planners.replanning.latency import LatencyModel
from planners.replanning.replanner import Replanner, ReplanOptions, jet, splice
from planners.trajectory.polynomial import PiecewisePolynomial

S0 = [0.0, 0.0, 3.9269908169872414, 1.5707963267948966]


@pytest.fixture(scope="module")
def moving():
    """The moving-target mission and its offline two-step plan (the plan in force before the event)."""
    mission = load_mission("moving-target")
    return mission, plan(mission, "two-step")


#: A deadline the replans of this machine meet (the default 50 ms may be shorter than they take: guides/replanning)
DEADLINE = 0.3


def _replanned(result, **options):
    replanner = Replanner(result, ReplanOptions(**{"samples_per_segment": 9, "deadline": DEADLINE, **options}))
    replanner.move(0)
    return replanner, replanner.replan(4.0, "event")


def test_splice_keeps_the_plan_before_and_is_c4_at_the_splice(moving):
    mission, result = moving
    replanner, record = _replanned(result)
    assert record.used and record.feasible, record.why
    new, old, t_s = replanner.trajectory, result.trajectory, record.splice_time
    assert t_s == pytest.approx(4.0 + DEADLINE)
    before = np.linspace(0.0, t_s, 400)
    np.testing.assert_allclose(new.evaluate(before, 4), old.evaluate(before, 4), rtol=0, atol=1e-9)
    # C4: value and derivatives 0..4 agree on both sides of the splice (each segment evaluated at its own end)
    i = int(np.argmin(np.abs(new.knots - t_s)))
    assert abs(new.knots[i] - t_s) < 1e-12
    left_segment, right_segment = new.segments[i - 1], new.segments[i]
    left = left_segment.evaluate(np.array([left_segment.duration]), 5)[:, 0]
    right = right_segment.evaluate(np.array([0.0]), 5)[:, 0]
    old_jet = jet(old, t_s)
    scale = np.abs(old.evaluate(np.linspace(0, 12, 1201), 4)).max(axis=(1, 2))
    for k in range(5):
        assert np.abs(left[k] - right[k]).max() < 1e-9 * max(scale[k], 1.0), k
        assert np.abs(right[k] - old_jet[k]).max() < 1e-9 * max(scale[k], 1.0), k
    assert np.abs(left[5] - right[5]).max() > 1e-3  # the 5th derivative is free: the splice really is C4
    # the new plan goes through the moved way point at its time, and ends at rest where the mission ends
    np.testing.assert_allclose(new.evaluate(np.array([6.0]), 0)[0, 0], [1.2, 0.8, S0[2], S0[3]], atol=1e-9)
    np.testing.assert_allclose(new.evaluate(np.array([12.0]), 4)[1:, 0], 0.0, atol=1e-9)


def test_no_rotor_speed_jump_at_the_splice(moving):
    """The planned rotor speeds across the splice step by no more than between two normal 2 ms ticks."""
    mission, result = moving
    replanner, record = _replanned(result)
    robot, t_s = result.robot, record.splice_time
    ticks = np.arange(0.0, 12.0, 0.002)
    speeds = inverse_dynamics(robot, replanner.trajectory.evaluate(ticks, MOTION_ORDER)).rotor_speed
    steps = np.abs(np.diff(speeds, axis=0)).max(axis=(1, 2))
    k = int(np.searchsorted(ticks, t_s))
    across = np.abs(
        inverse_dynamics(
            robot, replanner.trajectory.evaluate(np.array([t_s - 1e-6, t_s + 1e-6]), MOTION_ORDER)
        ).rotor_speed[1]
        - inverse_dynamics(
            robot, replanner.trajectory.evaluate(np.array([t_s - 1e-6]), MOTION_ORDER)
        ).rotor_speed[0]
    ).max()
    assert across < 1e-3  # rad/s over 2 us: continuous
    assert steps[k - 1] <= 1.5 * np.median(
        steps[k - 50 : k + 50]
    )  # the tick over the splice is an ordinary one


def test_splice_reproduces_the_cut_segment_exactly():
    rng = np.random.default_rng(3)
    before = PiecewisePolynomial(rng.normal(size=(3, 5, 2)), np.array([1.0, 2.0]))
    t_s = 1.7
    part = PiecewisePolynomial(np.stack([jet(before, t_s), rng.normal(size=(5, 2))]), np.array([0.5]))
    joined = splice(before, t_s, part)
    t = np.linspace(0.0, t_s, 300)
    np.testing.assert_allclose(joined.evaluate(t, 4), before.evaluate(t, 4), atol=1e-9)
    np.testing.assert_allclose(joined.knots, [0.0, 1.0, 1.7, 2.2])


def test_a_solve_that_cannot_be_ready_by_the_deadline_is_spliced_when_it_can(moving):
    """The modelled first iteration does not fit the deadline: the splice moves to when it is ready (rounded up
    to the ms), the change is used, C4 there, and the record says why; nothing is late in the model.
    """
    mission, result = moving
    slow = LatencyModel((0.0, 0.0, 3e-3, 0.0, 0.0))  # 3 ms per node and derivative evaluation
    replanner, record = _replanned(result, latency=slow, deadline=0.05)
    assert record.used and record.feasible, record.why
    first = replanner.latency({**record.work, "derivative_evaluations": 1, "value_evaluations": 1})
    assert record.splice_time == pytest.approx(4.0 + np.ceil(first * 1e3 - 1e-9) / 1e3, abs=1e-12)
    assert record.delayed_s == pytest.approx(record.splice_time - 4.05) and record.delayed_s > 0
    assert record.latency_s <= record.splice_time - record.time + 1e-12
    assert "past the 50 ms deadline" in record.why
    before = np.linspace(0.0, record.splice_time, 300)
    np.testing.assert_allclose(replanner.trajectory.evaluate(before, 4), result.trajectory.evaluate(before, 4),
                               atol=1e-9)
    np.testing.assert_allclose(replanner.trajectory.evaluate(np.array([6.0]), 0)[0, 0], [1.2, 0.8, S0[2], S0[3]],
                               atol=1e-9)
    # a model that fits the deadline: spliced at t_0 + deadline, no delay
    replanner, record = _replanned(result, latency=LatencyModel((0.0, 0.0, 1e-4, 0.0, 0.0)), deadline=0.05)
    assert record.used and record.splice_time == pytest.approx(4.05) and record.delayed_s == 0.0


def test_a_late_wall_clock_solve_is_solved_again_after_its_end(moving):
    """Against an impossible wall-clock deadline (and a model that calls every solve instant, so the splice is
    not delayed) the first solve is late (not used: the plan in force stays then), and is solved again at
    once, triggered when it ended.
    """
    mission, result = moving
    instant = LatencyModel((0.0,) * 5)
    replanner, record = _replanned(result, timing="wall", deadline=1e-6, latency=instant)
    late, again = replanner.replans
    assert not late.used and "late" in late.why and late.latency_s == late.solve_wall_s
    assert again is record and "again" in again.trigger
    assert again.time == pytest.approx(late.time + late.latency_s)


def test_an_infeasible_plan_is_not_used(moving):
    mission, result = moving
    far = mission.replace(
        events=[{"at": 5.5, "kind": "move", "way_point": 2, "to": [-0.5, 1.0, S0[2], S0[3]]}]
    )
    replanner = Replanner(
        type(result)(**{**vars(result), "mission": far}), ReplanOptions(samples_per_segment=9, least_horizon=0.0)
    )
    replanner.move(0)
    record = replanner.replan(5.5, "event")  # 1.7 m in 0.45 s: beyond the rotors
    assert not record.feasible and not record.used
    assert "infeasible" in record.why and "rotor_speed" in " ".join(record.violated)
    assert replanner.trajectory is result.trajectory


def test_work_latency_is_deterministic(moving):
    mission, result = moving
    first = _replanned(result)[1]
    second = _replanned(result)[1]
    assert (
        first.latency_s == second.latency_s and first.J == second.J and first.iterations == second.iterations
    )


def test_a_start_off_the_plan_is_solved_but_not_spliced(moving):
    """A splice must be C4: a start from the robot's state (off the plan in force) makes the plan jump."""
    mission, result = moving
    replanner = Replanner(result, ReplanOptions())
    start = jet(result.trajectory, 2.05)
    start[0, 0] += 0.05  # 5 cm off along y
    record = replanner.replan(2.0, "tracking error", start=start)
    assert record.start == "robot" and record.iterations >= 1 and not record.used
    assert "off the plan" in record.why and replanner.trajectory is result.trajectory


def test_a_travel_cut_by_the_splice_keeps_segments_as_long_as_the_offline_plans(moving):
    """The cut travel's via points leave segments no shorter than the offline ones (at least one when the
    travel is the whole horizon); the travels after it keep all their via points.
    """
    mission, result = moving
    replanner = Replanner(result, ReplanOptions())
    way = replanner.way_times
    for t_s, j0, j_end in [(4.05, 2, 3), (3.2, 2, 3), (5.9, 2, 2), (4.05, 2, 2), (6.0 + 1e-3, 3, 4)]:
        times, is_way = replanner._layout(t_s, j0, j_end)
        assert times[0] == t_s and is_way[-1] and np.all(np.diff(times) > 0)
        assert np.array_equal(times[is_way], way[j0 : j_end + 1])
        for j in range(j0, j_end + 1):
            inside = times[(times > max(way[j - 1], t_s) - 1e-12) & (times <= way[j] + 1e-12)]
            if way[j - 1] < t_s:  # the travel the splice cuts
                segments = np.diff(np.concatenate([[t_s], inside]) if inside[0] > t_s else inside)
                offline = (way[j] - way[j - 1]) / (replanner.n_via[j - 1] + 1)
                if j0 < j_end or segments.size > 2:
                    assert segments.min() >= offline - 1e-9, (t_s, j, segments, offline)
                assert segments.size >= (2 if j0 == j_end else 1)  # at least one via point alone
                assert np.allclose(segments, segments[0])
            else:  # a whole travel keeps the offline via points
                assert inside.size == replanner.n_via[j - 1] + 2


def test_an_infeasible_replan_is_solved_again_with_more_iterations():
    """A way point moved 0.49 m 0.85 s before the robot gets there (square, way point 3 to [0.14, 1.46]): two
    SQP iterations leave the part infeasible; it is solved again when that solve ends, with up to
    ``persist_iterations`` iterations and its splice as far as they take on this machine (the model), and
    that part is used. With persist_iterations 0 it is not.
    """
    mission = load_mission("square").replace(
        events=[{"at": 8.150262, "kind": "move", "way_point": 3, "to": [0.1404476745649267, 1.4574497310551306,
                                                                          S0[2], S0[3]]}])
    result = plan(mission, "two-step")
    model = LatencyModel((0.002, 0.001, 2e-4, 0.0, 0.0))
    for persist in (8, 0):
        replanner = Replanner(result, ReplanOptions(latency=model, persist_iterations=persist))
        replanner.move(0)
        record = replanner.replan(8.150262, "event")
        first = replanner.replans[0]
        assert not first.feasible and "infeasible" in first.why
        if persist:
            assert len(replanner.replans) == 2 and record.used and record.feasible, record.why
            assert record.time == pytest.approx(first.time + first.latency_s)
            assert 2 < record.iterations <= 8 and record.latency_s <= record.splice_time - record.time + 1e-12
        else:
            assert replanner.replans == [first] and not record.used
