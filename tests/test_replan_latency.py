"""The replanner's latency work: the fused last evaluation and dense check, the iteration budget."""

import dataclasses

import numpy as np
import pytest

from fpr.model.dual import Dual
from planners.missions.events import GustEvent
from planners.missions.mission import load_mission
from planners.optimize import plan
from planners.problem.disturbance import dense_check
from planners.replanning.check import evaluate_and_check
from planners.replanning.latency import LatencyModel
from planners.replanning.replanner import Replanner, ReplanOptions
from planners.replanning.solver import solve_warm
from planners.trajectory.polynomial import PiecewisePolynomial


@pytest.fixture(scope="module")
def moving():
    """The moving-target mission's offline two-step plan."""
    return plan(load_mission("moving-target"), "two-step")


def _moved_problem(result, gusts=()):
    replanner = Replanner(result, ReplanOptions())
    replanner.move(0)
    replanner.gusts = list(gusts)
    return replanner.problem(4.05)


@pytest.mark.parametrize("gust", [False, True])
def test_the_fused_evaluation_is_the_problem_s_own_and_the_check_is_dense_check_s(moving, gust):
    """One inverse-dynamics call for both: MotionProblem.evaluate's values, dense_check's verdict."""
    gusts = (GustEvent(at=3.0, force=(0.0, -8.0, 0.0), duration=20.0, rise=1.0),) if gust else ()
    problem, x0, times, _ = _moved_problem(moving, gusts)
    assert (getattr(problem, "external", None) is not None) == gust  # the gust: in the NLP's inverse dynamics
    for x in (x0, x0 + 0.05 * np.sin(np.arange(x0.size))):  # the first guess, and a point off it
        evaluation, (feasible, violated, samples) = evaluate_and_check(problem, x, 100.0, 4.05, gusts)
        problem._cache = None
        alone = problem.evaluate(x)
        # the same code on batches of other shapes: to round-off (numpy's products of small matrices, on the
        # Python path of the jets, may sum otherwise in a larger batch; the native jets happen to give equal bits)
        assert evaluation.J == pytest.approx(alone.J, rel=1e-12)
        scale = np.abs(alone.constraints).max()
        np.testing.assert_allclose(evaluation.constraints, alone.constraints, rtol=1e-12, atol=1e-12 * scale)
        part = PiecewisePolynomial(problem.points_of(x), problem.durations)
        assert (feasible, violated, samples) == dense_check(problem.robot, part, 100.0, 4.05, gusts)
    # the gust makes the moved first guess break the rotor limits: the verdicts compared above differ
    assert gust == (not feasible)


def test_fusing_the_check_changes_nothing_but_the_calls(moving):
    """Same replan with the check fused or in a call of its own: same plan, same record (but the times)."""
    records, plans = [], []
    for fuse in (True, False):
        replanner = Replanner(moving, ReplanOptions(deadline=0.3, fuse_check=fuse, refine_margin=0.0))
        replanner.move(0)
        records.append(replanner.replan(4.0, "event"))
        plans.append(replanner.trajectory)
    fused, alone = records
    assert fused.used and alone.used
    assert (fused.J, fused.feasible, fused.violated, fused.iterations, fused.work) == (
        alone.J, alone.feasible, alone.violated, alone.iterations, alone.work)
    np.testing.assert_array_equal(plans[0].points, plans[1].points)
    np.testing.assert_array_equal(plans[0].durations, plans[1].durations)


def test_solve_warm_hands_back_the_fused_check_only_for_its_result(moving):
    """The check fused with the last trial is the result's check, or None when that trial was refused."""
    problem, x0, _, _ = _moved_problem(moving)
    asked = []

    def final(x):
        asked.append(np.array(x))
        return evaluate_and_check(problem, x, 100.0, 4.05)

    out = solve_warm(problem, x0, max_iterations=2, final=final)
    assert len(asked) == 1 and np.array_equal(asked[0], out.x)  # the last trial was the result
    part = PiecewisePolynomial(problem.points_of(out.x), problem.durations)
    assert out.check == dense_check(problem.robot, part, 100.0, 4.05)
    # a refused trial (here made to look worse than x0) is not the result: its check is not handed back
    worse = lambda x: (dataclasses.replace(problem.evaluate(x), J=1e9), "check of a refused point")  # noqa: E731
    refused = solve_warm(problem, x0, max_iterations=1, final=worse)
    assert np.array_equal(refused.x, x0) and refused.check is None

def test_a_refinement_that_would_make_the_plan_late_is_not_started(moving):
    """Iteration 2 only when refine_margin x its modelled latency fits the deadline; late plans unused."""
    per_node = 0.028 / 21  # [s] per node and derivative evaluation: 21 nodes, 28 ms a derivative evaluation
    cost = LatencyModel((0.0, 0.0, per_node, 0.0, 0.0))

    def replanned(**options):
        replanner = Replanner(moving, ReplanOptions(latency=cost, least_horizon=0.0, **options))
        replanner.move(0)
        return replanner.replan(4.0, "event")

    # the second iteration would bring the modelled latency to 56 ms: margin x 56 ms against the deadline
    for deadline, margin, iterations in [(0.05, 1.0, 1), (0.06, 1.0, 2), (0.06, 1.7, 1), (0.1, 1.7, 2),
                                         (0.05, 0.0, 2)]:
        record = replanned(deadline=deadline, refine_margin=margin)
        assert record.iterations == iterations == record.work["derivative_evaluations"], (deadline, margin)
        if iterations == 1:
            assert record.solver.startswith("budget reached")
            assert record.latency_s == pytest.approx(0.028) and record.used, record.why
            one = record.J
        else:
            assert record.latency_s == pytest.approx(0.056) and record.J < one  # the refinement pays
    assert not record.used and "late" in record.why  # 56 ms against 50 ms: a late plan is never used
    assert ReplanOptions().refine_margin == 1.7


@pytest.mark.parametrize("value", [-1.0, float("nan"), float("inf"), "1.7", 0.8, True])
def test_refine_margin_refuses_absurd_values(value):
    """A negative, non-finite or non-numeric margin, or one in (0, 1) (a refinement could then make an
    on-time plan late), is refused with its name.
    """
    with pytest.raises(Exception, match="refine_margin"):
        ReplanOptions(refine_margin=value)


def test_fuse_check_must_be_a_boolean():
    with pytest.raises(Exception, match="fuse_check"):
        ReplanOptions(fuse_check="no")


def test_the_fused_check_leaves_a_callers_own_hook_in_place(moving):
    """evaluate_and_check answers the problem's _inputs hook for one evaluation, then restores the one set."""
    problem, x0, _, _ = _moved_problem(moving, ())
    original = problem._inputs
    seen = []
    problem._inputs = lambda motion: seen.append(1) or original(motion)
    instrument = problem._inputs
    evaluate_and_check(problem, x0, 100.0, 4.05)
    assert problem._inputs is instrument and not seen  # the fused call answered it, then gave it back
    problem._cache = None
    problem.evaluate(x0 + 1e-3)
    assert seen  # the instrument still sees the evaluations after it
    plain, _, _, _ = _moved_problem(moving, ())
    evaluate_and_check(plain, x0, 100.0, 4.05)
    assert "_inputs" not in plain.__dict__  # no hook of its own: the class's method again


def test_the_bench_times_the_copies_a_derivative_evaluation_sends(moving, monkeypatch):
    """fpr.bench's phase "its inverse dynamics" rebuilds the perturbed copies planners/problem/motion.py sends."""
    import fpr.cli.bench.replan_phases as phases

    sent = []
    monkeypatch.setattr(phases, "_least", lambda call, repeats: call() and 0.0)
    real = phases.inverse_dynamics
    monkeypatch.setattr(phases, "inverse_dynamics", lambda robot, m: sent.append(m) or real(robot, m))
    doc = phases.replan_phases(moving, repeats=1)
    problem, x0, _, _ = _moved_problem(moving)
    seen = []
    original = problem._inputs
    problem._inputs = lambda motion: seen.append(motion) or original(motion)
    problem.evaluate(x0, True)
    [seeded] = sent  # the motion on dual numbers (planners.problem.motion.MotionProblem.derivatives)
    assert isinstance(seeded, Dual)
    np.testing.assert_array_equal(seeded.value, seen[0].value)
    np.testing.assert_array_equal(seeded.tangents, seen[0].tangents)
    assert doc["directions"] == seeded.tangents.shape[0] == 20 and doc["nodes"] == seeded.shape[1] == 21
