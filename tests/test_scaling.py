"""Planning at scale: the long missions' generator, the banded step-QP route against the dense
one and ProxQP, the scaling bench's fit and goals."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import sparse

import planners.optimisation.active_set as active_set
import planners.optimisation.curvature as curvature
from fpr.cli.bench.cli import parser
from fpr.cli.bench.scaling import EXPONENT_GOAL, _targets, growth_exponent, scaling_table
from fpr.model.qp import proxsuite_module
from planners.optimisation.active_set import banded_solver, bandwidth, solve_step_qp
from planners.optimisation.curvature import smoothed_hessian
from planners.methods.one_step import one_step_problem
from planners.methods.way_points import WayPointTask
from fpr.bench.missions import LOOP_RADIUS, loop_mission, loop_way_points
from planners.problem.report import evaluate_motion
from planners.optimisation.solving import Grid
from planners.optimisation.sqp import _proxqp, _qp_step, kkt_residual

proxqp = proxsuite_module().proxqp


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


# ---------------------------------------------------------------------------------------------- banded QP
def _banded_qp(n=240, block=20, seed=0):
    """A random positive definite H coupling neighbouring blocks only, a g, and rows touching 2 blocks."""
    rng = np.random.default_rng(seed)
    h = np.zeros((n, n))
    for a in range(0, n - block, block):
        f = rng.normal(size=(3 * block, 2 * block))
        h[a:a + 2 * block, a:a + 2 * block] += f.T @ f / (3 * block)
    h += 0.05 * np.eye(n)
    rows = np.zeros((60, n))
    for i in range(60):
        a = rng.integers(0, n - 2 * block)
        rows[i, a:a + 2 * block] = rng.normal(size=2 * block)
    rows /= np.abs(rows).max(axis=1, keepdims=True)
    return h, rng.normal(size=n), rows, -0.05 * rng.random(60)


def test_banded_solver_inverts_h():
    h, g, _, _ = _banded_qp()
    assert bandwidth(h) == 39
    solve = banded_solver(h)
    assert solve is not None
    np.testing.assert_allclose(h @ solve(g), g, atol=1e-10)
    assert banded_solver(h[:100, :100]) is None  # small: the dense route
    assert banded_solver(np.ones((300, 300)) + np.eye(300)) is None  # dense H


def test_bandwidth_is_the_largest_offset_of_a_non_zero():
    """bandwidth (from each row's first and last non-zero) against the definition on the non-zeros' indices:
    random banded, lopsided and mostly empty matrices."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        n = int(rng.integers(1, 60))
        m = rng.normal(size=(n, n)) * (rng.random((n, n)) < 0.05)
        m[rng.random(n) < 0.3] = 0.0  # empty rows
        i, j = np.nonzero(m)
        assert bandwidth(m) == (int(np.abs(i - j).max()) if i.size else 0)
    assert bandwidth(np.zeros((5, 5))) == 0 and bandwidth(np.eye(4)) == 0


@pytest.mark.parametrize("banded", [True, False])
def test_shift_is_h_plus_shift_times_identity(banded, monkeypatch):
    """solve_step_qp(H, ..., shift=s) is solve_step_qp(H + s I, ...) bit for bit, banded and dense routes."""
    h, g, rows, lower = _banded_qp()
    if not banded:
        monkeypatch.setattr(active_set, "BANDED_MIN_SIZE", 10**9)
    shift = 0.3
    shifted = h.copy()
    shifted[np.diag_indices_from(shifted)] += shift
    mine, reference = solve_step_qp(h, g, rows, lower, 0.5, shift=shift), solve_step_qp(shifted, g, rows, lower, 0.5)
    assert mine is not None and reference is not None
    np.testing.assert_array_equal(mine[0], reference[0])
    np.testing.assert_array_equal(mine[1], reference[1])
    assert not np.array_equal(mine[0], solve_step_qp(h, g, rows, lower, 0.5)[0])  # the shift matters


def test_banded_route_equals_the_dense_route(monkeypatch):
    """The same active set and step, whether H^-1 comes from a banded Cholesky factor or the eigenvectors."""
    h, g, rows, lower = _banded_qp()
    banded = solve_step_qp(h, g, rows, lower, 0.5)
    monkeypatch.setattr(active_set, "BANDED_MIN_SIZE", 10**9)
    dense = solve_step_qp(h, g, rows, lower, 0.5)
    assert banded is not None and dense is not None
    assert sorted(banded[2]) == sorted(dense[2]) and len(banded[2]) > 0  # some rows active
    np.testing.assert_allclose(banded[0], dense[0], atol=1e-9)
    np.testing.assert_allclose(banded[1], dense[1], atol=1e-9)


@pytest.fixture(scope="module")
def long_evaluation():
    """The 1-step NLP of 10 way points (1 via point a travel: 308 variables) and its evaluation with
    derivatives at its start."""
    mission = loop_mission(10, 1)
    task = WayPointTask.of(mission, mission.load_robot())
    problem = one_step_problem(task, Grid())
    problem.power_model = True
    return problem, problem.evaluate(problem.x_of(problem.points), True)


def test_long_problems_sparse_jacobian_is_the_dense_one(long_evaluation, monkeypatch):
    """The sparse copy holds the same numbers; the KKT residual and the smoothed model's H are the same
    from it as from the dense arrays."""
    problem, ev = long_evaluation
    assert problem.n_x >= 200 and ev.jacobian_sparse is not None
    np.testing.assert_array_equal(ev.jacobian_sparse.toarray(), ev.jacobian)
    # a row touches one segment's two points: at most 2 x 20 entries (fewer at the fixed way points)
    assert ev.jacobian_sparse.nnz <= 40 * ev.jacobian.shape[0]
    lam = np.random.default_rng(1).random(ev.constraints.size)
    dense, sparse_kkt = (kkt_residual(ev.gradient, ev.constraints, a, lam)
                         for a in (ev.jacobian, ev.jacobian_sparse))
    assert sparse_kkt.stationarity == pytest.approx(dense.stationarity, rel=1e-12)
    assert sparse_kkt.complementarity == pytest.approx(dense.complementarity, rel=1e-12)
    h_sparse = smoothed_hessian(ev)
    monkeypatch.setattr(curvature, "SPARSE_FROM", 10**9)
    np.testing.assert_allclose(h_sparse, smoothed_hessian(ev), rtol=0, atol=1e-12 * np.abs(h_sparse).max())


def test_long_problems_sparse_power_jacobian_is_the_dense_one(long_evaluation):
    """The evaluation's CSR copy of the powers' Jacobian holds the same numbers as the dense one, and the
    smoothed model's H from it is the one from converting the dense array (bit for bit)."""
    _, ev = long_evaluation
    assert ev.power_jacobian_sparse is not None
    np.testing.assert_array_equal(ev.power_jacobian_sparse.toarray(), ev.power_jacobian)
    from_dense = smoothed_hessian(dataclasses.replace(ev, power_jacobian_sparse=None))
    np.testing.assert_array_equal(smoothed_hessian(ev), from_dense)
    assert np.abs(from_dense - ev.rate_hessian).max() > 0  # the powers' part is there


@pytest.fixture(scope="module")
def long_qp(long_evaluation):
    """The step QP of the 1-step NLP of 10 way points (1 via point a travel) at its start, as the SQP
    builds it at a feasible point (rows that can become active, scaled to unit infinity norm)."""
    _, ev = long_evaluation
    hess = smoothed_hessian(ev)
    radius = 0.5
    keep = np.flatnonzero(ev.constraints - np.abs(ev.jacobian).sum(axis=1) * radius <= 0.0)
    norms = np.maximum(np.abs(ev.jacobian[keep]).max(axis=1), 1.0)
    hess = hess + 1e-9 * np.trace(hess) / hess.shape[0] * np.eye(hess.shape[0])
    return hess, ev.gradient, ev.jacobian[keep] / norms[:, None], -ev.constraints[keep] / norms, radius


def test_banded_step_on_a_long_mission_is_proxqps_optimum(long_qp):
    """On a real long mission's QP the banded route answers, its step holds every row, and its objective is
    no higher than ProxQP's (dense backend, tight tolerance): the optimum."""
    hess, g, rows, lower, radius = long_qp
    n = g.size
    assert n >= active_set.BANDED_MIN_SIZE and bandwidth(hess) <= 40  # two points' 20 entries
    out = solve_step_qp(hess, g, rows, lower, radius)
    assert out is not None
    d = out[0]
    assert np.all(rows @ d >= lower - 1e-9) and np.abs(d).max() <= radius + 1e-12
    ref = proxqp.dense.solve(hess, g, None, None, np.vstack([rows, np.eye(n)]),
                             np.concatenate([lower, np.full(n, -radius)]),
                             np.concatenate([np.full(lower.size, np.inf), np.full(n, radius)]),
                             eps_abs=1e-11, max_iter=20000)
    x = np.asarray(ref.x)

    def q(v):
        return 0.5 * v @ hess @ v + g @ v
    assert q(d) <= q(x) + 1e-9 * max(1.0, abs(q(x)))


def test_sparse_proxqp_gives_the_dense_answer(long_qp):
    """The fallback's sparse backend (large QPs) solves the same QP as the dense one."""
    hess, g, rows, lower, radius = long_qp
    n = g.size
    scale = 1.0 / np.abs(hess).max()
    args = (hess * scale, g * scale, np.vstack([rows, np.eye(n)]),
            np.concatenate([lower, np.full(n, -radius)]),
            np.concatenate([np.full(lower.size, np.inf), np.full(n, radius)]))
    assert n >= active_set.BANDED_MIN_SIZE
    ours = _proxqp(*args)
    ref = proxqp.dense.solve(args[0], args[1], None, None, *args[2:], eps_abs=1e-9, max_iter=300)
    assert isinstance(args[0], np.ndarray) and not sparse.issparse(args[0])

    def q(v):
        return 0.5 * v @ args[0] @ v + args[1] @ v
    x, y = np.asarray(ours.x), np.asarray(ref.x)
    assert abs(q(x) - q(y)) <= 1e-6 * max(1e-3, abs(q(y)))
    assert np.all(args[2] @ x >= args[3] - 1e-6) and np.all(args[2] @ x <= args[4] + 1e-6)


# ---------------------------------------------------------------------------------------------- the bench
def test_active_set_on_sparse_rows_is_the_dense_one():
    """solve_step_qp with its rows as a CSR matrix (a long mission's step QP) returns the dense rows' step,
    multipliers and working set: the same numbers, the rows are only stored differently."""
    h, g, rows, lower = _banded_qp()
    dense = solve_step_qp(h, g, rows, lower, 0.5)
    on_sparse = solve_step_qp(h, g, sparse.csr_matrix(rows), lower, 0.5)
    assert dense is not None and on_sparse is not None and len(dense[2]) > 0  # some rows active
    assert on_sparse[2] == dense[2]
    np.testing.assert_allclose(on_sparse[0], dense[0], rtol=0, atol=1e-14)
    np.testing.assert_allclose(on_sparse[1], dense[1], rtol=0, atol=1e-12 * np.abs(dense[1]).max())


@pytest.mark.parametrize("violated, radius", [(0, 0.5), (0, 3.0), (5, 0.5), (5, 3.0)])
def test_step_qp_from_the_sparse_jacobian_is_the_dense_ones(long_evaluation, violated, radius):
    """The SQP's step QP on a long mission from the Jacobian's sparse copy (rows kept sparse, scaled in
    place; ProxQP gets them sparse) gives the dense Jacobian's step, predicted decrease and multipliers:
    at the feasible start (the active set) and with ``violated`` rows made violated (the elastic QP,
    ProxQP)."""
    _, ev = long_evaluation
    if violated:
        c = ev.constraints.copy()
        c[np.argsort(c)[:violated]] = -0.01
        ev = dataclasses.replace(ev, constraints=c)
    hess = smoothed_hessian(ev)
    from_sparse = _qp_step(ev, radius, 10.0, hess)
    from_dense = _qp_step(dataclasses.replace(ev, jacobian_sparse=None), radius, 10.0, hess)
    assert np.abs(from_sparse[0]).max() > 0.1 * radius  # a real step
    np.testing.assert_allclose(from_sparse[0], from_dense[0], rtol=0, atol=1e-12)
    assert from_sparse[1] == pytest.approx(from_dense[1], rel=1e-12)
    assert from_sparse[2] == pytest.approx(from_dense[2], abs=1e-15)
    np.testing.assert_allclose(from_sparse[3], from_dense[3], rtol=0, atol=1e-12)
    assert (np.count_nonzero(from_sparse[3]) > 0) == (violated > 0)  # violated rows carry multipliers


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
