"""Tests for fpr.model.jets.

Inputs are random polynomials of time (seeded), whose derivatives are known exactly. Every
derivative of a composed result is checked against
  * closed forms (sin(t^2), log t, t^p, atan2 of a rotating vector, ...), to ~1e-12;
  * central finite differences of the *value* computed at shifted times: the k-th derivative of
    the degree-14 interpolation polynomial through 15 equispaced samples (step h = 0.015, exact
    rational weights; i.e. Richardson-extrapolated central differences). Measured errors on these
    functions, relative to the largest magnitude of that derivative over the samples, are
    <= 3e-11 (orders 1-2), 5e-10 (order 3) and 5e-8 (order 4, round-off dominated); the
    tolerances 1e-9, 1e-9, 1e-7, 1e-6 leave a margin of 20-300;
  * the complex step Im f(t + ih)/h, h = 1e-30, applied to the order-(k-1) jet's top
    derivative, which has no cancellation error (tolerance 1e-12) where the code is analytic.
"""
from fractions import Fraction
from functools import lru_cache
from math import factorial

import numpy as np
import pytest
from numpy.polynomial import polynomial as P

from fpr.model.jets import (
    Jet,
    atan2,
    concatenate,
    cos,
    dot,
    exp,
    hypot,
    log,
    matmul,
    matvec,
    norm,
    sin,
    sincos,
    solve,
    sqrt,
    square,
    stack,
)

K = 4
T = np.linspace(-1.0, 1.0, 201)
FD_STEP, FD_HALF = 0.015, 7
FD_RTOL = {1: 1e-9, 2: 1e-9, 3: 1e-7, 4: 1e-6}


def random_poly(rng, shape=(), deg=5):
    """Coefficients (deg+1, *shape) of a polynomial with O(1) Taylor-scaled coefficients."""
    scale = np.array([1.0 / factorial(i) for i in range(deg + 1)]) * 2.0
    return rng.normal(size=(deg + 1,) + shape) * scale.reshape((-1,) + (1,) * len(shape))


def poly_eval(c, t, k=0):
    """k-th derivative of the polynomial with coefficients c at times t -> (len(t), *shape)."""
    c = P.polyder(c, k, axis=0) if k else c
    tb = np.asarray(t).reshape((-1,) + (1,) * (c.ndim - 1))
    out = np.zeros(tb.shape[:1] + c.shape[1:], np.result_type(t, float))
    for coef in c[::-1]:
        out = out * tb + coef
    return out


def poly_jet(c, t, order=K):
    return Jet.from_derivatives([poly_eval(c, t, k) for k in range(order + 1)])


@lru_cache(maxsize=None)
def stencil(k, m):
    """Exact weights w_j, j = -m..m, with f^(k)(t) ~ h^-k sum_j w_j f(t + j h)."""
    n = 2 * m + 1
    rows = [[Fraction(j) ** i for j in range(-m, m + 1)] + [Fraction(factorial(k) * (i == k))]
            for i in range(n)]
    for c in range(n):  # Gauss-Jordan in exact arithmetic (Vandermonde system)
        p = next(r for r in range(c, n) if rows[r][c] != 0)
        rows[c], rows[p] = rows[p], rows[c]
        rows[c] = [v / rows[c][c] for v in rows[c]]
        for r in range(n):
            if r != c and rows[r][c] != 0:
                rows[r] = [a - rows[r][c] * b for a, b in zip(rows[r], rows[c], strict=True)]
    return np.array([float(r[n]) for r in rows])


def check_fd(func, jet, t=T, unwrap=False):
    """Compare jet.d[1..K] with finite differences of func(t_shifted) (value only)."""
    vals = np.array([func(t + j * FD_STEP) for j in range(-FD_HALF, FD_HALF + 1)])
    if unwrap:
        vals = np.unwrap(vals, axis=0)
    for k in range(1, jet.order + 1):
        fd = np.tensordot(stencil(k, FD_HALF), vals, axes=(0, 0)) / FD_STEP ** k
        scale = np.max(np.abs(jet.d[k]))
        np.testing.assert_allclose(jet.d[k], fd, rtol=0, atol=FD_RTOL[k] * scale,
                                   err_msg=f"derivative order {k}")


def check_complex_step(make, jet, t=T, h=1e-30):
    """d[k] of the order-K jet vs Im(d[k-1] of the order-(k-1) jet at t + ih) / h."""
    for k in range(1, jet.order + 1):
        cs = make(t + 1j * h, k - 1).d[k - 1].imag / h
        scale = max(1.0, np.max(np.abs(jet.d[k])))
        np.testing.assert_allclose(jet.d[k], cs, rtol=0, atol=1e-12 * scale)


@pytest.fixture
def rng():
    return np.random.default_rng(20240531)


# --- construction, indexing, shapes --------------------------------------------------------------
def test_constructors_and_indexing():
    v = Jet.variable(T, 3)
    assert v.order == 3 and v.shape == T.shape
    np.testing.assert_array_equal(v.d[1], 1.0)
    np.testing.assert_array_equal(v.d[2:], 0.0)
    c = Jet.constant(np.ones((5, 2)), 2)
    assert c.d.shape == (3, 5, 2) and not c.d[1:].any()
    j = Jet.from_derivatives([np.zeros((5, 3)), 1.0, np.arange(3.0)])
    assert j.d.shape == (3, 5, 3) and j.value.shape == (5, 3)
    assert j[..., 0].shape == (5,) and j[:, 1:].shape == (5, 2) and j[2].shape == (3,)
    np.testing.assert_array_equal(j[..., 2].d[2], 2.0)
    assert j.truncate(1).order == 1 and j.derivative().order == 1
    with pytest.raises(ValueError):
        j.truncate(5)
    assert j.reshape(15).shape == (15,) and j.sum(axis=-1).shape == (5,) and j.sum().shape == ()
    assert Jet(np.arange(3)).d.dtype == float


def test_order_mixing_and_broadcasting(rng):
    a4 = poly_jet(random_poly(rng, (1,)), T)               # (N, 1), order 4
    v2 = poly_jet(random_poly(rng, (3,)), T, order=2)      # (N, 3), order 2
    s = Jet.constant(2.0, 4)                                # shape (), order 4
    for r in (a4 * v2, a4 + v2, v2 - a4, v2 / (a4 * a4 + 1)):
        assert r.order == 2 and r.shape == (len(T), 3)
    prod = a4 * v2
    for i in range(3):
        np.testing.assert_allclose((a4[:, 0] * v2[:, i]).d, prod[:, i].d, rtol=1e-14)
    assert (a4 * s).order == 4 and (s * a4).shape == (len(T), 1)
    arr = np.array([1.0, 2.0, 3.0])
    for r in (a4 + arr, arr + a4, arr * a4, a4 / arr, arr / (a4 * a4 + 1), arr - a4):
        assert isinstance(r, Jet) and r.order == 4 and r.shape == (len(T), 3)
    for r in (2 - a4, a4 - 2, 2 * a4, a4 / 2, 2 / (a4 * a4 + 1), -a4, a4 ** 2):
        assert isinstance(r, Jet) and r.order == 4 and r.shape == (len(T), 1)
    np.testing.assert_allclose((arr - a4).d[1:], -np.broadcast_to(a4.d[1:], (K, len(T), 3)))
    np.testing.assert_allclose((a4 + arr).d[0], a4.d[0] + arr)
    st = stack([a4[:, 0], 0.0, a4[:, 0] * 2], axis=-1)
    assert st.shape == (len(T), 3) and st.order == 4 and not st.d[:, :, 1].any()
    assert stack([a4, a4], axis=0).shape == (2, len(T), 1)
    cat = concatenate([v2, a4, np.zeros((len(T), 2))], axis=1)
    assert cat.shape == (len(T), 6) and cat.order == 2


# --- closed forms and exact polynomial identities ------------------------------------------------
def test_closed_forms():
    t = np.linspace(0.2, 2.0, 101)
    u = Jet.variable(t, K)
    s, c = sincos(u * u)
    q = t * t
    ds = [np.sin(q), 2 * t * np.cos(q), 2 * np.cos(q) - 4 * q * np.sin(q),
          -12 * t * np.sin(q) - 8 * t ** 3 * np.cos(q),
          -12 * np.sin(q) - 48 * q * np.cos(q) + 16 * q * q * np.sin(q)]
    np.testing.assert_allclose(s.d, ds, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(sin(u * u).d, s.d)
    np.testing.assert_allclose(cos(u * u).d[1], -2 * t * np.sin(q), rtol=1e-12, atol=1e-12)
    for k in range(K + 1):
        np.testing.assert_allclose(exp(2 * u).d[k], 2.0 ** k * np.exp(2 * t), rtol=1e-13)
        np.testing.assert_allclose((1 / u).d[k], (-1) ** k * factorial(k) / t ** (k + 1),
                                   rtol=1e-12)
        if k:
            np.testing.assert_allclose(log(u).d[k], (-1) ** (k - 1) * factorial(k - 1) / t ** k,
                                       rtol=1e-12)
        for p, jet in ((0.5, sqrt(u)), (2.5, u ** 2.5), (-1.5, u ** -1.5)):
            coef = np.prod([p - i for i in range(k)])
            np.testing.assert_allclose(jet.d[k], coef * t ** (p - k), rtol=1e-12)
    np.testing.assert_allclose(hypot(3 * u, 4 * u).d[:2], [5 * t, 5 + 0 * t], rtol=1e-13)


def test_polynomial_identities(rng):
    ca, cb = random_poly(rng), random_poly(rng)
    a, b = poly_jet(ca, T), poly_jet(cb, T)
    ab = a * b
    exact = P.polymul(ca, cb)
    for k in range(K + 1):
        np.testing.assert_allclose(ab.d[k], poly_eval(exact, T, k), rtol=1e-12, atol=1e-12)
    den = b * b + 1.0
    np.testing.assert_allclose(((a / den) * den).d, a.d, rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose((a ** 3).d, (a * a * a).d, rtol=1e-12, atol=1e-11)
    np.testing.assert_allclose(square(a).d, (a * a).d)
    np.testing.assert_allclose((den ** -2 * den * den).d, Jet.constant(np.ones_like(T), K).d,
                               atol=1e-10)
    np.testing.assert_allclose((a ** 0).d, Jet.constant(np.ones_like(T), K).d)
    np.testing.assert_allclose((-(a - b)).d, (b - a).d)


# --- finite-difference and complex-step checks of compositions -----------------------------------
def _scalar_comp(a, b, c):
    return (a * b / (2 + c * c) + sin(a + b) * cos(c) - sqrt(1 + a * a + b * b) + exp(0.3 * c)
            + log(3 + sin(a)) + a ** 3 - 1.5 / (2 + b * b))


def test_scalar_compositions(rng):
    cs = [random_poly(rng) for _ in range(3)]
    def make(t, order):
        return _scalar_comp(*(poly_jet(c, t, order) for c in cs))
    jet = make(T, K)
    check_fd(lambda t: make(t, 0).value, jet)
    check_complex_step(make, jet)
    def with_atan(t, o):
        return atan2(poly_jet(cs[1], t, o), 2 + poly_jet(cs[0], t, o) ** 2)
    check_fd(lambda t: with_atan(t, 0).value, with_atan(T, K))


def test_vector_compositions(rng):
    cv, cw = random_poly(rng, (3,)), random_poly(rng, (3,))
    off = np.array([3.0, -2.0, 1.0])

    def make(t, order):
        v, w = poly_jet(cv, t, order) + off, poly_jet(cw, t, order)
        r = stack([norm(v), dot(v, w), hypot(v[:, 0], v[:, 1] + 5.0)], axis=-1)
        return r / norm(v)[:, None]

    jet = make(T, K)
    assert jet.shape == (len(T), 3)
    check_fd(lambda t: make(t, 0).value, jet)
    check_complex_step(make, jet)


def test_matmul(rng):
    c2a, c2b = random_poly(rng, (2, 2)), random_poly(rng, (2, 2))
    c4a, c4b, cx = random_poly(rng, (4, 4)), random_poly(rng, (4, 4)), random_poly(rng, (4,))
    M = rng.normal(size=(4, 4))

    def make(t, order):
        A2, B2 = poly_jet(c2a, t, order), poly_jet(c2b, t, order)
        A4, B4, x = (poly_jet(c, t, order) for c in (c4a, c4b, cx))
        r2 = (A2 @ B2).reshape(-1, 4)
        r4 = matvec(matmul(A4, B4.mT) @ M, x) + matvec(M, x) + M[0] @ A4.T + A4 @ M[1]
        return concatenate([r2, r4], axis=-1)

    jet = make(T, K)
    check_fd(lambda t: make(t, 0).value, jet)
    check_complex_step(make, jet)
    A2, B2 = poly_jet(c2a, T), poly_jet(c2b, T)     # entrywise Leibniz vs matrix Leibniz
    prod = matmul(A2, B2)
    for i in range(2):
        for j in range(2):
            ref = A2[:, i, 0] * B2[:, 0, j] + A2[:, i, 1] * B2[:, 1, j]
            np.testing.assert_allclose(prod[:, i, j].d, ref.d, rtol=1e-13, atol=1e-13)
    assert isinstance(M @ poly_jet(c4a, T), Jet) and (M[0] @ poly_jet(c4a, T)).shape == (len(T), 4)
    np.testing.assert_allclose(matmul(M, M), M @ M)


def _well_conditioned(rng, t, order, n=4):
    return poly_jet(random_poly(rng, (n, n)) * 0.15, t, order) + 3.0 * np.eye(n)


def test_solve_residual_every_order(rng):
    """A x - b vanishes for every derivative order (1e-10 relative to the size of b^(k))."""
    A = _well_conditioned(rng, T, K)
    assert np.max(np.linalg.cond(A.value)) < 10
    b = poly_jet(random_poly(rng, (4,)), T)
    Bm = poly_jet(random_poly(rng, (4, 3)), T, order=3)
    A0 = A.value[0]
    cases = [(solve(A, b), lambda x: matvec(A, x) - b, 4),
             (solve(A, Bm), lambda x: matmul(A, x) - Bm, 3),             # order mixing
             (solve(A0, b), lambda x: matvec(A0, x) - b, 4),              # constant matrix
             (solve(A, b.value), lambda x: matvec(A, x) - b.value, 4),    # constant rhs
             (solve(A, b.truncate(2)[0]), lambda x: matvec(A, x) - b.truncate(2)[0], 2)]
    for x, residual, order in cases:
        assert isinstance(x, Jet) and x.order == order
        scale = max(1.0, np.max(np.abs(b.d)), np.max(np.abs(Bm.d)))
        assert np.max(np.abs(residual(x).d)) <= 1e-10 * scale
    x_np = solve(A.value, b.value)
    assert isinstance(x_np, np.ndarray)
    np.testing.assert_allclose(x_np, np.linalg.solve(A.value, b.value[..., None])[..., 0])


def test_solve_finite_differences(rng):
    ca, cb = random_poly(rng, (4, 4)) * 0.15, random_poly(rng, (4,))
    def make(t, o):
        return solve(poly_jet(ca, t, o) + 3.0 * np.eye(4), poly_jet(cb, t, o))
    jet = make(T, K)
    check_fd(lambda t: make(t, 0).value, jet)
    check_complex_step(make, jet)


# --- atan2 across the branch cut -----------------------------------------------------------------
def test_atan2_rotating_vector_is_time():
    t = np.linspace(0.0, 2 * np.pi, 400)        # crosses the cut at t = pi
    s, c = sincos(Jet.variable(t, K))
    ang = atan2(3 * s, 3 * c)
    np.testing.assert_allclose(ang.d[1], 1.0, rtol=1e-13)
    np.testing.assert_allclose(ang.d[2:], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.unwrap(ang.value), t, atol=1e-12)


def test_atan2_branch_cut_continuous(rng):
    cy, cx = random_poly(rng), random_poly(rng) * 0.2
    cy[:2], cx[0] = [0.05, 1.0], -2.0              # y crosses 0 near t = -0.05 while x < 0
    def make(t, o):
        return atan2(poly_jet(cy, t, o), poly_jet(cx, t, o))
    jet = make(T, K)
    y, x = poly_eval(cy, T), poly_eval(cx, T)
    assert np.all(x < 0) and y.min() < 0 < y.max()
    assert np.ptp(jet.value) > np.pi                   # the value jumps by 2 pi ...
    for k in range(1, K + 1):                          # ... its derivatives do not
        assert np.max(np.abs(np.diff(jet.d[k]))) < 0.2 * np.max(np.abs(jet.d[k])) + 1e-9
    dy, dx = poly_eval(cy, T, 1), poly_eval(cx, T, 1)
    np.testing.assert_allclose(jet.d[1], (x * dy - y * dx) / (x * x + y * y), rtol=1e-13)
    check_fd(lambda t: make(t, 0).value, jet, unwrap=True)


def test_thrust_roll_angle(rng):
    """Roll angle of a planar drone thrust F = m (s'' + g e_z) from s, s', ..., s''''."""
    cp, m, g = random_poly(rng, (3,)), 1.2, 9.81

    def make(t, order):
        acc = poly_jet(cp, t, order + 2).derivative().derivative()
        F = m * (acc + np.array([0.0, 0.0, g]))
        return atan2(-F[..., 1], F[..., 2])

    phi = make(T, 2)
    assert phi.order == 2
    check_fd(lambda t: make(t, 0).value, phi)
