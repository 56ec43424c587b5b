"""The native jet products, solves and inverses (fpr._native's part ``jets``, fpr/_native/jets.c) against numpy's,
their reference (the part switched off).

Each kernel is compared on random real and complex batches, with the broadcasting the planner uses (a batch of
matrices against copies of it) and with the orders of constants; then the planner's node derivatives of a whole
mission, which go through all of them.
"""

import numpy as np
import pytest
from native_parts import native_module, needs_native

import fpr
from fpr import _native as native
from fpr.model import jets
from fpr.model.jets import Jet

pytestmark = needs_native


@pytest.fixture
def reference():
    """A function running ``f()`` under numpy's products (the reference), then under the native ones."""
    native_module("jets")

    def both(f):
        with native.switched(jets=False):
            want = f()
        with native.switched(jets=True):
            got = f()
        return want, got
    return both


def _random(rng, shape, complex_):
    x = rng.normal(size=shape)
    return x + 1j * rng.normal(size=shape) if complex_ else x


def _close(want, got, tol=1e-13):
    want, got = np.asarray(want), np.asarray(got)
    assert want.shape == got.shape and want.dtype == got.dtype
    assert np.abs(got - want).max() <= tol * max(1.0, np.abs(want).max())


@pytest.mark.parametrize("complex_", [False, True])
@pytest.mark.parametrize("shapes", [
    ((3, 7, 4, 4), (3, 7, 4, 1)),        # jets of one batch
    ((3, 7, 4, 4), (3, 5, 7, 4, 2)),     # a batch against copies of it (the complex-step copies)
    ((2, 5, 7, 3, 4), (2, 7, 4, 3)),     # and the other way round
    ((4, 1, 3, 3), (4, 6, 3, 3)),        # a leading 1
])
def test_jet_matmul_is_numpy_s(reference, complex_, shapes):
    """Jet @ Jet: every order of the Leibniz sum of matrix products, to round-off."""
    rng = np.random.default_rng(0)
    a, b = (Jet(_random(rng, s, complex_)) for s in shapes)
    want, got = reference(lambda: (a @ b).d)
    _close(want, got)


@pytest.mark.parametrize("complex_", [False, True])
def test_matmul_with_a_constant_is_numpy_s(reference, complex_):
    """A constant matrix (no derivatives) against a jet, on either side: the single-term Leibniz sums."""
    rng = np.random.default_rng(1)
    c = _random(rng, (6, 3, 3), complex_)
    j = Jet(_random(rng, (4, 6, 3, 2), complex_))
    _close(*reference(lambda: jets.matmul(c, j).d))
    k = Jet(_random(rng, (3, 6, 2, 3), complex_))
    _close(*reference(lambda: jets.matmul(k, c).d))


def test_batches_that_broadcast_otherwise_fall_back_to_numpy(reference):
    """(7, 1) against (1, 5) batches are not a suffix of each other: numpy computes them, the same result."""
    rng = np.random.default_rng(2)
    a, b = Jet(rng.normal(size=(2, 7, 1, 3, 3))), Jet(rng.normal(size=(2, 1, 5, 3, 1)))
    want, got = reference(lambda: (a @ b).d)
    assert got.shape == (2, 7, 5, 3, 1)
    np.testing.assert_array_equal(want, got)


@pytest.mark.parametrize("complex_", [False, True])
@pytest.mark.parametrize("order_a, order_b", [(2, 2), (4, 1), (1, 3), (None, 2), (2, None)])
def test_jet_solve_is_numpy_s(reference, complex_, order_a, order_b):
    """A x = b along a motion (either side possibly a constant): x's jet, to round-off; and it solves A x = b
    order by order (A x)^(n) = b^(n), an independent check of the recurrence.
    """
    rng = np.random.default_rng(3)
    n = 4
    a0 = _random(rng, (9, n, n), complex_) + 4 * np.eye(n)
    a = a0 if order_a is None else Jet(np.concatenate([a0[None], _random(rng, (order_a, 9, n, n), complex_)]))
    b = _random(rng, (9, n), complex_) if order_b is None else Jet(_random(rng, (order_b + 1, 9, n), complex_))
    want, got = reference(lambda: jets.solve(a, b).d)
    _close(want, got, 1e-12)
    x = Jet(got)
    residual = jets.matmul(a, x[..., None])[..., 0] - b
    assert np.abs(residual.d).max() < 1e-10


def test_inverse_is_numpy_s_and_singular_matrices_raise_as_numpy_does(reference):
    """Batches of small matrices: the inverse to round-off (relative to the condition number); a singular one
    raises numpy's LinAlgError; a matrix holding NaN gets NaN in its inverse (LAPACK leaves some entries finite, the
    C code none: no inverse exists either way) and leaves the others of its batch alone.
    """
    rng = np.random.default_rng(4)
    for n in (1, 2, 4, 7):
        a = rng.normal(size=(50, n, n))
        want, got = reference(lambda a=a: jets.inverse(a))
        scale = np.linalg.cond(a)[:, None, None] * np.abs(want).max(axis=(1, 2), keepdims=True)
        assert (np.abs(got - want) <= 1e-14 * scale).all()
    singular = rng.normal(size=(3, 4, 4))
    singular[1, 2] = 0.0
    for switch in (False, True):
        with native.switched(jets=switch), pytest.raises(np.linalg.LinAlgError):
            jets.inverse(singular)
    with_nan = rng.normal(size=(2, 3, 3))
    with_nan[0, 1, 1] = np.nan
    want, got = reference(lambda: jets.inverse(with_nan))
    assert np.isnan(got[0]).any() and np.isnan(want[0]).any() and np.isfinite(got[1]).all()
    _close(want[1], got[1], 1e-13)


def test_solve_matrices_is_numpy_s(reference):
    """Real batches A x = B (several right-hand sides): numpy's solve to round-off, and A x = B holds."""
    rng = np.random.default_rng(5)
    a = rng.normal(size=(40, 5, 5)) + 3 * np.eye(5)
    b = rng.normal(size=(40, 5, 3))
    want, got = reference(lambda: jets.solve_matrices(a, b))
    _close(want, got, 1e-12)
    assert np.abs(a @ got - b).max() < 1e-12


def test_node_derivatives_of_a_mission_are_numpy_s(reference):
    """The planner's exact derivatives of the square's 1-step NLP (complex-step copies of the inverse dynamics,
    through every kernel): values and sensitivities equal to round-off.
    """
    from planners.methods.one_step import one_step_problem
    from planners.methods.way_points import WayPointTask
    from planners.missions.mission import load_mission
    from planners.options import PlanOptions

    problem = one_step_problem(WayPointTask.of(load_mission("square"), fpr.load("fpr")), PlanOptions().grid)
    points = problem.points
    motion = problem.motion(points)
    want, got = reference(lambda: problem._node_derivatives(points, motion))
    for w, g in zip(want, got, strict=True):
        _close(w, g, 1e-10)
    assert np.abs(want[2]).max() > 0 and np.abs(want[3]).max() > 0  # the sensitivities are not trivially zero
