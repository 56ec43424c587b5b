"""The SQP's step length by the model with J_e's kinks (planners.optimisation.curvature.along_step)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import sparse
from scipy.optimize import minimize_scalar

from planners.optimisation.curvature import along_step
from planners.problem.motion import POWER_SMOOTHING


def _smooth(p):
    return np.sqrt(p * p + POWER_SMOOTHING**2)


def _evaluation(rng, n=6, k=9, m=4):
    """A random point of J = x^T R x / 2 + sum_k pw_k |P_k(x)|_eps, P affine, with constraints c(x) = c0 + A x."""
    root = rng.normal(size=(n, n))
    rate = root @ root.T / n
    pj = rng.normal(size=(k, n))
    pv = rng.normal(size=k)
    pw = rng.uniform(0.5, 2.0, size=k)
    g_phi = rng.normal(size=n)
    gradient = g_phi + pj.T @ (pw * pv / _smooth(pv))
    c = rng.uniform(-0.2, 1.0, size=m)
    a = rng.normal(size=(m, n))
    ev = SimpleNamespace(power=pv, power_weight=pw, power_jacobian_sparse=sparse.csr_matrix(pj), gradient=gradient,
                         rate_hessian=rate, constraints=c, jacobian=a, jacobian_sparse=sparse.csr_matrix(a))
    return ev, g_phi


def _model(ev, g_phi, d, penalty):
    """The kink model along d, written out directly (an independent evaluation of m(t))."""
    def m(t):
        p = ev.power + t * (ev.power_jacobian_sparse @ d)
        viol = np.maximum(0.0, -(ev.constraints + t * (ev.jacobian @ d))).sum()
        kinks = ev.power_weight @ (_smooth(p) - _smooth(ev.power))
        return (t * g_phi @ d + 0.5 * t * t * d @ ev.rate_hessian @ d + kinks
                + penalty * (viol - np.maximum(0.0, -ev.constraints).sum()))
    return m


@pytest.mark.parametrize("seed", range(8))
def test_along_step_minimises_the_kink_model_along_the_step(seed):
    rng = np.random.default_rng(seed)
    ev, g_phi = _evaluation(rng)
    penalty = 10.0
    # a descent direction of the model (minus its slope at 0), long enough to pass the kinks
    slope = np.array([_model(ev, g_phi, e, penalty)(1e-7) / 1e-7 for e in np.eye(g_phi.size)])
    d = -3.0 * slope / np.abs(slope).max()
    m = _model(ev, g_phi, d, penalty)
    step, predicted = along_step(ev, d, penalty, predicted=-1.0)
    t = float(step @ d / (d @ d))
    np.testing.assert_allclose(step, t * d, rtol=0, atol=1e-12)
    best = minimize_scalar(m, bounds=(0.0, 1.0), method="bounded", options={"xatol": 1e-10})
    assert m(t) <= best.fun + 1e-9  # the minimiser on [0, 1] (the model is convex)
    np.testing.assert_allclose(predicted, -m(t), rtol=1e-9, atol=1e-12)
    assert predicted > 0.0


def test_along_step_cuts_a_step_that_takes_a_power_across_zero():
    # J = |1 - x|_eps, one variable: the QP's step to x = 3 overshoots the kink at x = 1
    ev = SimpleNamespace(power=np.array([1.0]), power_weight=np.array([1.0]),
                         power_jacobian_sparse=sparse.csr_matrix([[-1.0]]), gradient=np.array([-1.0 / _smooth(1.0)]),
                         rate_hessian=np.zeros((1, 1)), constraints=np.zeros(0), jacobian=np.zeros((0, 1)),
                         jacobian_sparse=None)
    step, predicted = along_step(ev, np.array([3.0]), 10.0, predicted=2.0)
    np.testing.assert_allclose(step, [1.0], atol=1e-9)
    np.testing.assert_allclose(predicted, _smooth(1.0) - POWER_SMOOTHING, rtol=1e-9)


def test_along_step_keeps_a_step_the_model_does_not_decrease_along():
    ev = SimpleNamespace(power=np.array([1.0]), power_weight=np.array([1.0]),
                         power_jacobian_sparse=sparse.csr_matrix([[1.0]]), gradient=np.array([1.0 / _smooth(1.0)]),
                         rate_hessian=np.zeros((1, 1)), constraints=np.zeros(0), jacobian=np.zeros((0, 1)),
                         jacobian_sparse=None)
    step, predicted = along_step(ev, np.array([0.5]), 10.0, predicted=0.125)
    assert step.tolist() == [0.5] and predicted == 0.125
