"""The SQP's step QP: banded matrices (planners.problem.banded), the active set (planners.optimisation.active_set)
and the interior-point route (planners.optimisation.interior_point), each against an independent solver.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import sparse

from fpr.bench.missions import loop_mission
from fpr.model.qp import proxsuite_module
from planners.methods.one_step import one_step_problem
from planners.methods.way_points import WayPointTask
from planners.optimisation.active_set import ActiveSet, solve_step_qp
from planners.optimisation.curvature import smoothed_hessian
from planners.optimisation.interior_point import solve_interior_point
from planners.optimisation.solving import Grid
from planners.optimisation.sqp import _qp_step, kkt_residual
from planners.problem.banded import Banded

proxqp = proxsuite_module().proxqp


def _banded_qp(n=240, block=20, seed=0, rows_count=60):
    """A random positive definite H coupling neighbouring blocks only, a g, rows touching 2 blocks, b <= 0."""
    rng = np.random.default_rng(seed)
    h = np.zeros((n, n))
    for a in range(0, n - block, block):
        f = rng.normal(size=(3 * block, 2 * block))
        h[a:a + 2 * block, a:a + 2 * block] += f.T @ f / (3 * block)
    h += 0.05 * np.eye(n)
    rows = np.zeros((rows_count, n))
    for i in range(rows_count):
        a = block * rng.integers(0, n // block - 1)
        rows[i, a:a + 2 * block] = rng.normal(size=2 * block)
    rows /= np.abs(rows).max(axis=1, keepdims=True)
    return h, rng.normal(size=n), rows, -0.05 * rng.random(rows_count)


def _objective(h, g, d, caps=None, rows=None, lower=None):
    value = 0.5 * d @ (h @ d) + g @ d
    if caps is not None:
        finite = np.isfinite(caps)
        value += float(np.sum(caps[finite] * np.maximum(0.0, lower[finite] - rows[finite] @ d)))
    return value


def _reference(h, g, rows, lower, radius, caps=None):
    """The QP by ProxQP (dense, tight), the elastic rows with explicit slacks: (d, objective)."""
    n, m = g.size, rows.shape[0]
    caps = np.full(m, np.inf) if caps is None else caps
    soft = np.flatnonzero(np.isfinite(caps))
    p = soft.size
    hh = np.zeros((n + p, n + p))
    hh[:n, :n] = h
    slack = np.zeros((m, p))
    slack[soft, np.arange(p)] = 1.0
    a = np.vstack([np.hstack([rows, slack]), np.eye(n + p)])
    low = np.concatenate([lower, np.full(n, -radius), np.zeros(p)])
    up = np.concatenate([np.full(m, np.inf), np.full(n, radius), np.full(p, np.inf)])
    res = proxqp.dense.solve(hh, np.concatenate([g, caps[soft]]), None, None, a, low, up, eps_abs=1e-12,
                             max_iter=100000)
    d = np.clip(np.asarray(res.x)[:n], -radius, radius)
    return d, _objective(h, g, d, caps, rows, lower)


# ---------------------------------------------------------------------------------------------- banded
def test_banded_matrix_is_its_dense_matrix():
    rng = np.random.default_rng(0)
    n, b = 50, 7
    a = rng.normal(size=(n, n))
    a = a + a.T
    i, j = np.indices((n, n))
    a[np.abs(i - j) > b] = 0.0
    m = Banded.from_dense(a)
    assert m.bandwidth == b and m.shape == (n, n)
    np.testing.assert_array_equal(np.asarray(m), a)
    x, xs = rng.normal(size=n), rng.normal(size=(n, 3))
    np.testing.assert_allclose(m @ x, a @ x, atol=1e-13)
    np.testing.assert_allclose(m @ xs, a @ xs, atol=1e-13)
    np.testing.assert_allclose(x @ m, x @ a, atol=1e-13)
    index = np.sort(rng.choice(n, 30, replace=False))
    np.testing.assert_array_equal(np.asarray(m.principal(index)), a[np.ix_(index, index)])
    s = rng.uniform(1.0, 2.0, n)
    np.testing.assert_allclose(np.asarray(m.scaled_both(s)), a * np.outer(s, s), atol=1e-13)
    np.testing.assert_array_equal(np.asarray(m.shifted(0.5)), a + 0.5 * np.eye(n))
    np.testing.assert_array_equal(m.to_sparse_upper().toarray(), np.triu(a))
    wide = Banded.from_dense(np.eye(n) * 3.0, bandwidth=12)
    np.testing.assert_array_equal(np.asarray(m + wide), a + 3.0 * np.eye(n))
    spd = Banded.from_dense(a + 30.0 * np.eye(n))
    np.testing.assert_allclose(spd.cholesky_solver(0.5)(x), np.linalg.solve(a + 30.5 * np.eye(n), x), atol=1e-14)
    assert m.abs_max() == np.abs(a).max() and m.trace() == pytest.approx(np.trace(a))


def test_banded_scatter_sums_at_the_flat_indices():
    n, b = 10, 3
    rows, cols = np.array([0, 0, 2, 2, 5]), np.array([0, 3, 4, 4, 5])
    values = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    m = np.asarray(Banded.scatter(values, Banded.flat_index(rows, cols, n, b), n, b))
    expected = np.zeros((n, n))
    for r, c, v in zip(rows, cols, values, strict=True):
        expected[r, c] += v
        if r != c:
            expected[c, r] += v
    np.testing.assert_array_equal(m, expected)


# ---------------------------------------------------------------------------------------------- the NLP's H
@pytest.fixture(scope="module")
def long_evaluation():
    """The 1-step NLP of 10 way points (1 via point a travel: 308 variables) and its evaluation with
    derivatives at a point near its start.
    """
    mission = loop_mission(10, 1)
    task = WayPointTask.of(mission, mission.load_robot())
    problem = one_step_problem(task, Grid())
    problem.power_model = True
    x = problem.x_of(problem.points) + 0.01 * np.sin(np.arange(problem.n_x))
    return problem, problem.evaluate(x, True)


def test_the_problems_band_holds_its_whole_hessian(long_evaluation):
    """The powers' Gauss-Newton sum assembled segment by segment into the band is the one from the powers'
    Jacobian (an independent product); the band's width does not depend on the mission's length.
    """
    problem, ev = long_evaluation
    assert isinstance(ev.hessian, Banded) and ev.hessian.bandwidth < 40  # two points' 20 entries
    weight = np.random.default_rng(2).random(ev.power.size)
    from_jacobian = ev.power_jacobian.T @ (weight[:, None] * ev.power_jacobian)
    np.testing.assert_allclose(np.asarray(ev.power_gram(weight)), from_jacobian, rtol=0,
                               atol=1e-12 * np.abs(from_jacobian).max())
    np.testing.assert_allclose(np.asarray(smoothed_hessian(ev)),
                               np.asarray(smoothed_hessian(dataclasses.replace(ev, power_gram=None))),
                               rtol=0, atol=1e-12 * np.abs(from_jacobian).max())
    assert ev.jacobian_sparse.nnz <= 40 * ev.constraints.size  # a row touches one segment's two points


# ---------------------------------------------------------------------------------------------- active set
@pytest.mark.parametrize("seed", range(4))
def test_active_set_banded_and_dense_routes_give_the_optimum(seed):
    """Banded H with CSR rows, and the arrays: the same step, multipliers and active set, at ProxQP's
    optimum; the step holds every row, and the multipliers satisfy the KKT conditions.
    """
    h, g, rows, lower = _banded_qp(seed=seed)
    radius = 0.5
    banded = solve_step_qp(Banded.from_dense(h), g, sparse.csr_matrix(rows), lower, radius)
    dense = solve_step_qp(h, g, rows, lower, radius)
    assert banded is not None and dense is not None
    np.testing.assert_allclose(banded[0], dense[0], rtol=0, atol=1e-10)
    np.testing.assert_allclose(banded[1], dense[1], rtol=0, atol=1e-9)
    assert sorted(banded[2].rows) == sorted(dense[2].rows)
    np.testing.assert_array_equal(banded[2].bounds, dense[2].bounds)
    d, lam, active = dense
    assert np.all(rows @ d >= lower - 1e-10) and np.abs(d).max() <= radius + 1e-12
    assert np.all(lam >= 0) and set(np.flatnonzero(lam > 0)) <= set(active.rows)
    residual = h @ d + g - rows.T @ lam  # = the box's multipliers: zero on the free variables
    free = active.bounds == 0
    np.testing.assert_allclose(residual[free], 0.0, atol=1e-9)
    assert np.all(-active.bounds[~free] * residual[~free] >= -1e-9)
    assert _objective(h, g, d) <= _reference(h, g, rows, lower, radius)[1] + 1e-9


def test_active_set_warm_start_and_shift():
    """Started from its own answer it returns it at once; a shift is H + shift I."""
    h, g, rows, lower = _banded_qp(seed=5)
    cold = solve_step_qp(h, g, rows, lower, 0.5)
    warm = solve_step_qp(h, g, rows, lower, 0.5, start=cold[2])
    np.testing.assert_allclose(warm[0], cold[0], rtol=0, atol=1e-12)
    shifted = solve_step_qp(h, g, rows, lower, 0.5, shift=0.3)
    reference = solve_step_qp(h + 0.3 * np.eye(h.shape[0]), g, rows, lower, 0.5)
    np.testing.assert_allclose(shifted[0], reference[0], rtol=0, atol=1e-13)
    assert np.abs(shifted[0] - cold[0]).max() > 1e-3  # the shift matters


@pytest.mark.parametrize("seed", range(12))
def test_elastic_rows_are_an_l1_penalty(seed):
    """Rows violated at d = 0 with a cap: the minimiser of the QP plus cap * violation (ProxQP with explicit
    slacks), by the active set or, where it gives up, the interior point; rows without a cap hold.
    """
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(3, 10)), int(rng.integers(2, 10))
    q = rng.normal(size=(n, n))
    h = q @ q.T * rng.uniform(0.01, 1.0) + rng.uniform(1e-3, 0.1) * np.eye(n)
    g = 3.0 * rng.normal(size=n)
    rows = rng.normal(size=(m, n))
    rows /= np.abs(rows).max(axis=1, keepdims=True)
    lower = -rng.uniform(0.05, 1.0, size=m)
    soft = rng.random(m) < 0.5
    soft[0] = True
    lower[soft] = rng.uniform(0.05, 2.0, size=soft.sum())
    caps = np.where(soft, rng.uniform(0.5, 5.0, m), np.inf)
    radius = float(rng.uniform(0.2, 1.5))
    out = solve_step_qp(h, g, rows, lower, radius, caps=caps)
    if out is None:
        out = solve_interior_point(h, g, rows, lower, radius, caps=caps)
    d = out[0]
    assert np.all((rows @ d - lower)[~soft] >= -1e-8) and np.abs(d).max() <= radius + 1e-12
    assert np.all(out[1] >= 0.0) and np.all(out[1] <= caps + 1e-9)
    assert _objective(h, g, d, caps, rows, lower) <= _reference(h, g, rows, lower, radius, caps)[1] + 1e-7


def test_active_set_solves_a_box_without_curvature_and_declines_a_cancelling_solve():
    # no curvature: every variable goes to the box, where the box's multipliers hold it: the exact answer
    rows, lower = np.array([[-1.0, 0.0]]), np.array([-1.0])
    d, lam, active = solve_step_qp(1e-21 * np.eye(2), np.ones(2), rows, lower, 1.0)
    assert np.array_equal(d, [-1.0, -1.0]) and np.array_equal(active.bounds, [-1, -1]) and lam[0] == 0.0
    # a row that holds a free variable of no curvature: its range-space step (H^-1 g ~ 1e21, cancelled by
    # H^-1 A^T lambda) would lose everything to cancellation: declined (the SQP takes another route)
    rows, lower = np.array([[1.4 / 2.4, 1.0]]), np.array([-0.03])
    assert solve_step_qp(1e-21 * np.eye(2), np.ones(2), rows, lower, 1.0) is None


# ---------------------------------------------------------------------------------------------- interior point
@pytest.mark.parametrize("seed", range(3))
def test_interior_point_banded_and_dense_routes_give_the_optimum(seed):
    h, g, rows, lower = _banded_qp(seed=seed)
    radius = 0.5
    banded = solve_interior_point(Banded.from_dense(h), g, sparse.csr_matrix(rows), lower, radius)
    dense = solve_interior_point(h, g, rows, lower, radius)
    assert banded is not None and dense is not None
    np.testing.assert_allclose(banded[0], dense[0], rtol=0, atol=1e-7)
    reference = _reference(h, g, rows, lower, radius)[1]
    for d in (banded[0], dense[0]):
        assert np.all(rows @ d >= lower - 1e-9)
        assert _objective(h, g, d) <= reference + 1e-9 * max(1.0, abs(reference))
    exact = solve_step_qp(h, g, rows, lower, radius)  # the active sets agree
    assert set(banded[3]) == set(exact[2].rows) and np.array_equal(banded[2], exact[2].bounds)


@pytest.fixture(scope="module")
def long_qp(long_evaluation):
    """The step QP of the 1-step NLP of 10 way points at a point near its start, as the SQP builds it (rows
    that can become active, scaled to unit infinity norm), its model's H banded.
    """
    _, ev = long_evaluation
    hess = smoothed_hessian(ev)
    radius = 0.5
    a = ev.jacobian_sparse
    keep = np.flatnonzero(ev.constraints - abs(a).sum(axis=1).A1 * radius <= 0.0)
    norms = np.maximum(abs(a[keep]).max(axis=1).toarray().ravel(), 1.0)
    rows = sparse.diags(1.0 / norms) @ a[keep]
    return hess, ev.gradient, sparse.csr_matrix(rows), -ev.constraints[keep] / norms, radius


def test_both_routes_on_a_long_missions_qp_reach_the_optimum(long_qp):
    """On a real long mission's QP (hundreds of bounds can bind) both routes answer, hold every row and end at
    ProxQP's optimum (dense backend, tight tolerance).
    """
    hess, g, rows, lower, radius = long_qp
    shift = 1e-9 * hess.trace() / hess.n
    dense = np.asarray(hess) + shift * np.eye(hess.n)
    reference = _reference(dense, g, rows.toarray(), lower, radius)[1]
    exact = solve_step_qp(hess, g, rows, lower, radius, shift=shift)
    inner = solve_interior_point(hess, g, rows, lower, radius, shift=shift)
    assert inner is not None
    for out in ([] if exact is None else [exact[0]]) + [inner[0]]:
        assert np.all(rows @ out >= lower - 1e-8) and np.abs(out).max() <= radius + 1e-12
        assert _objective(dense, g, out) <= reference + 1e-8 * max(1e-3, abs(reference))


@pytest.mark.parametrize("violated, radius", [(0, 0.5), (0, 3.0), (5, 0.5), (5, 3.0)])
def test_sqp_step_on_a_long_mission(long_evaluation, violated, radius):
    """The SQP's step QP on a long mission, at a feasible point and with ``violated`` constraints violated
    (their slacks elastic): a step, the multipliers >= 0, the violated rows' multipliers at most the penalty,
    the KKT residual of the QP's multipliers computable from the sparse Jacobian; the same from the start of
    its own active set.
    """
    _, ev = long_evaluation
    if violated:
        c = ev.constraints.copy()
        c[np.argsort(c)[:violated]] = -0.01
        ev = dataclasses.replace(ev, constraints=c)
    hess = smoothed_hessian(ev)
    d, predicted, linear, multipliers, active, _ = _qp_step(ev, radius, 10.0, hess)
    assert np.abs(d).max() > 0.05 * radius and predicted > 0.0 and np.abs(d).max() <= radius + 1e-12
    assert np.all(multipliers >= 0.0) and np.all(multipliers[ev.constraints < 0] <= 10.0 + 1e-9)
    after = ev.constraints + ev.jacobian_sparse @ d
    assert linear <= np.maximum(0.0, -ev.constraints).sum() + 1e-12  # the step does not add violation
    # the elastic rows: still violated only at their full penalty's multiplier
    still = np.flatnonzero((ev.constraints < 0) & (after < -1e-9))
    np.testing.assert_allclose(multipliers[still], 10.0, rtol=1e-9)
    assert np.isfinite(kkt_residual(ev.gradient, ev.constraints, ev.jacobian_sparse, multipliers).residual)
    again = _qp_step(ev, radius, 10.0, hess, start=active)
    np.testing.assert_allclose(again[0], d, rtol=0, atol=1e-9)
    # the interior point, to its tolerance: the same predicted decrease (the step itself may differ along the
    # model's flat directions, H's eigenvalues spanning 1e-7 to 1e2)
    inner = _qp_step(ev, radius, 10.0, hess, interior_first=True)
    assert inner[5] and inner[1] == pytest.approx(predicted, rel=1e-6)
    assert isinstance(active, ActiveSet)
