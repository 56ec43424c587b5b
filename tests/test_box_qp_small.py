"""The box QP's plain-Python linear solve for one or two free variables (controllers/box_qp.py, _small_solve)
against LAPACK's posv, which the method uses for more.
"""

import numpy as np
from scipy.linalg import lapack

from controllers.box_qp import _small_solve, solve_box_qp


def test_small_solve_is_posv():
    """Random positive definite 1 x 1 and 2 x 2 systems: the same x as LAPACK's Cholesky solve, to round-off."""
    rng = np.random.default_rng(11)
    for k in (1, 2):
        for _ in range(300):
            a = rng.normal(size=(k, k))
            h = a @ a.T + 1e-3 * np.eye(k)
            b = rng.normal(size=k)
            x = np.array(_small_solve(h.tolist(), b.tolist()))
            reference, info = lapack.dposv(h, b)[1:]
            assert info == 0
            np.testing.assert_allclose(x, reference, rtol=1e-10, atol=1e-12 * np.abs(reference).max())
            np.testing.assert_allclose(h @ x, b, rtol=0, atol=1e-9 * np.abs(h).max() * np.abs(x).max())


def test_small_solve_refuses_what_posv_refuses():
    """Not positive definite (as posv's info > 0): None, and the box QP then gives up (None: ProxQP's turn)."""
    for h in ([[-1.0]], [[0.0]], [[1.0, 2.0], [2.0, 1.0]], [[1.0, 1.0], [1.0, 1.0]]):
        assert _small_solve(h, [1.0] * len(h)) is None
        assert lapack.dposv(np.array(h), np.ones(len(h)))[2] > 0
    # the free set is the two variables of an indefinite H: the method cannot solve it
    h = np.diag([1.0, 1.0, 1.0])
    h[:2, :2] = [[1.0, 2.0], [2.0, 1.0]]
    assert solve_box_qp(h, np.zeros(3), [False, False, True], [False, False, False]) is None
