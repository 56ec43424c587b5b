"""Tests of planners.trajectory.polynomial (degree-9 segments, thesis eq. 3.18-3.19).

All random data come from seeded generators; tolerances are stated at each assertion.
"""
import dataclasses
import time
from fractions import Fraction
from math import factorial, perm

import numpy as np
import pytest
from numpy.polynomial import polynomial as npoly

from planners.trajectory.polynomial import (
    HERMITE_BASIS,
    MAX_ORDER,
    PiecewisePolynomial,
    Segment,
    hermite_basis_exact,
    split_evenly,
    stop_points,
)

N = 4  # coordinates (x, y, z, yaw)


def random_points(rng, count, n=N):
    """Points (count, 5, n) with O(1) values and derivatives of mixed sign."""
    return rng.normal(size=(count, 5, n)) * rng.uniform(0.5, 2.0, size=(count, 5, 1))


def random_chain(seed, m=5, n=N):
    """Chain of m random segments with durations in [0.2, 3] s."""
    rng = np.random.default_rng(seed)
    return PiecewisePolynomial(random_points(rng, m + 1, n), rng.uniform(0.2, 3.0, size=m))


# --------------------------------------------------------------------------- Hermite basis
def test_basis_constant_equals_exact_derivation():
    """The float constant is the correctly rounded exact basis."""
    exact = hermite_basis_exact()
    assert HERMITE_BASIS.shape == (10, 10)
    # Fraction -> float is correctly rounded: equality is exact.
    assert np.array_equal(HERMITE_BASIS, np.array(exact, dtype=float))


def test_exact_basis_satisfies_boundary_conditions_exactly():
    """d^k h_j / dtau^k at tau = 0, 1 is exactly the Kronecker delta (eq. 3.19)."""
    exact = hermite_basis_exact()
    for j in range(10):
        for side, x in enumerate((Fraction(0), Fraction(1))):
            for k in range(5):
                value = sum(exact[c][j] * perm(c, k) * x ** (c - k) for c in range(k, 10))
                assert value == (1 if j == 5 * side + k else 0), (j, side, k)


def test_basis_matches_closed_form_smoothstep():
    """The position basis is the known degree-9 smoothstep."""
    # h_b0 = 1 - (126 t^5 - 420 t^6 + 540 t^7 - 315 t^8 + 70 t^9), h_e0 = the smoothstep.
    smooth = [0, 0, 0, 0, 0, 126, -420, 540, -315, 70]
    assert [c[5] for c in hermite_basis_exact()] == smooth
    assert [c[0] for c in hermite_basis_exact()] == [1] + [-v for v in smooth[1:]]


def test_basis_mirror_symmetry():
    """End basis is the mirrored begin basis."""
    # h_{e,k}(tau) = (-1)^k h_{b,k}(1 - tau), to 1e-12 absolute on [0, 1].
    tau = np.linspace(0.0, 1.0, 101)
    for k in range(5):
        begin = npoly.polyval(1.0 - tau, HERMITE_BASIS[:, k])
        end = npoly.polyval(tau, HERMITE_BASIS[:, 5 + k])
        np.testing.assert_allclose(end, (-1) ** k * begin, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------- boundary values
@pytest.mark.parametrize("duration", [0.01, 0.1, 1.0, 10.0, 100.0])
def test_boundary_conditions_segment(duration):
    """Derivatives 0..4 at both ends equal the given points."""
    rng = np.random.default_rng(int(duration * 100))
    begin, end = random_points(rng, 2)
    seg = Segment(begin, end, duration)
    out = seg.evaluate([0.0, duration], order=4)  # (5, 2, n)
    # all derivatives 0..4 at both ends, 1e-9 relative (every entry is nonzero)
    np.testing.assert_allclose(out[:, 0], begin, rtol=1e-9, atol=0)
    np.testing.assert_allclose(out[:, 1], end, rtol=1e-9, atol=0)


@pytest.mark.parametrize("scale", [0.01, 1.0, 100.0])
def test_boundary_conditions_piecewise(scale):
    """A chain passes through all its points with all derivatives 0..4."""
    rng = np.random.default_rng(7)
    points = random_points(rng, 6)
    pp = PiecewisePolynomial(points, scale * rng.uniform(0.5, 2.0, size=5))
    out = pp.evaluate(pp.knots, order=4)  # every knot, the last one included
    np.testing.assert_allclose(out.transpose(1, 0, 2), points, rtol=1e-9, atol=0)


def test_c4_continuity_at_junctions():
    """Derivatives 0..4 are continuous at every junction."""
    pp = random_chain(11, m=6)
    segs = pp.segments
    for left, right in zip(segs[:-1], segs[1:], strict=True):
        a = left.evaluate([left.duration], order=4)[:, 0]
        b = right.evaluate([0.0], order=4)[:, 0]
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)  # 1e-9 rel, 1e-9 abs
    # just left / right of each interior knot (h = 1e-9 s): derivatives 0..4 are continuous,
    # the 5th (not imposed) is not.
    h = 1e-9
    inner = pp.knots[1:-1]
    lo, hi = pp.evaluate(inner - h, order=5), pp.evaluate(inner + h, order=5)
    peak = np.abs(pp.evaluate(np.linspace(0, pp.total_duration, 2001), 5)).max(axis=(1, 2))
    for r in range(5):  # Taylor bound 2 h max|s^(r+1)| (x1.5) plus 1e-10 relative rounding
        assert np.abs(hi[r] - lo[r]).max() <= 3 * h * peak[r + 1] + 1e-10 * peak[r]
    assert np.abs(hi[5] - lo[5]).max() > 1e-3 * peak[5]  # crackle does jump: test not vacuous


def test_matches_segments_and_last_time_belongs_to_last_segment():
    """The chain agrees with its segments; t == total lies on the last one."""
    pp = random_chain(3)
    t = np.linspace(0.0, pp.total_duration, 777)
    out = pp.evaluate(t, order=4)
    for i, seg in enumerate(pp.segments):
        mask = (t >= pp.knots[i]) & ((t < pp.knots[i + 1]) | (i == len(pp.segments) - 1))
        local = seg.evaluate(np.clip(t[mask] - pp.knots[i], 0.0, seg.duration), order=4)
        np.testing.assert_allclose(out[:, mask], local, rtol=1e-9, atol=1e-9 * np.abs(out).max())
    np.testing.assert_allclose(pp.evaluate(pp.total_duration)[:, 0], pp.points[-1], rtol=1e-12)


def test_unsorted_and_scalar_times():
    """Unsorted, scalar and empty time arguments."""
    pp = random_chain(4)
    rng = np.random.default_rng(5)
    t = rng.uniform(0.0, pp.total_duration, size=500)
    order = np.argsort(t)
    # the same values to round-off: the segments' sums may be vectorised differently for the two orders
    ref = pp.evaluate(t[order])
    np.testing.assert_allclose(pp.evaluate(t)[:, order], ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    assert pp.evaluate(0.3).shape == (5, 1, N)
    assert pp.evaluate(np.array([]), order=2).shape == (3, 0, N)


# --------------------------------------------------------------------------- derivatives
@pytest.mark.parametrize("seed", [0, 1])
def test_derivatives_match_central_differences(seed):
    """Derivative r is the central difference of derivative r-1."""
    pp = random_chain(seed)
    h = 1e-5  # [s]
    t = np.linspace(h, pp.total_duration - h, 997)
    t = t[np.min(np.abs(t[:, None] - pp.knots[None, 1:-1]), axis=1) > 2 * h]  # stay in a segment
    out = pp.evaluate(t, order=MAX_ORDER)
    plus, minus = pp.evaluate(t + h, order=MAX_ORDER), pp.evaluate(t - h, order=MAX_ORDER)
    for r in range(1, MAX_ORDER + 1):
        fd = (plus[r - 1] - minus[r - 1]) / (2 * h)
        scale = np.abs(out[r]).max() + np.abs(out[r - 1]).max()
        # truncation h^2/6 |s^(r+2)| + rounding eps |s^(r-1)| / h; measured <= 5e-8 of scale
        np.testing.assert_allclose(fd, out[r], rtol=0, atol=1e-6 * scale, err_msg=f"r={r}")


def test_high_derivatives_of_degree_nine():
    """Orders up to 9 are available; the 9th derivative is constant."""
    pp = random_chain(9)
    out = pp.evaluate(np.linspace(0, pp.total_duration, 50), order=MAX_ORDER)
    assert out.shape == (10, 50, N)
    seg = pp.segments[0]
    const = seg.evaluate(np.linspace(0, seg.duration, 7), order=9)[9]  # 9th derivative
    np.testing.assert_allclose(const, const[[0]].repeat(7, axis=0), rtol=1e-9)


# --------------------------------------------------------------------------- linear basis
def test_segment_basis_reproduces_evaluate_and_gradient():
    """Basis weights give evaluate() and the exact gradient w.r.t. each point entry."""
    rng = np.random.default_rng(21)
    begin, end = random_points(rng, 2)
    seg = Segment(begin, end, 1.7)
    t = np.linspace(0.0, 1.7, 301)
    w = seg.basis(t, order=4)  # (5, N_t, 2, 5)
    assert w.shape == (5, t.size, 2, 5)
    out = seg.evaluate(t, order=4)
    recon = np.einsum("risk,skn->rin", w, np.stack([begin, end]))
    np.testing.assert_allclose(recon, out, rtol=0, atol=1e-12 * np.abs(out).max())
    # the segment is linear in its points: a finite difference with any step is exact
    delta = 0.5
    for side in (0, 1):
        for k in range(5):
            pts = np.stack([begin, end])
            pts[side, k, 2] += delta
            fd = (Segment(pts[0], pts[1], 1.7).evaluate(t) - out) / delta
            np.testing.assert_allclose(fd[:, :, 2], w[:, :, side, k], rtol=0,
                                       atol=1e-9 * np.abs(w[:, :, side, k]).max())
            np.testing.assert_array_equal(fd[:, :, [0, 1, 3]], 0.0)  # other coordinates


def test_piecewise_basis_gradient_of_shared_point():
    """Gradient w.r.t. a point shared by two segments (chain basis)."""
    pp = random_chain(22, m=4)
    t = np.linspace(0.0, pp.total_duration, 400)
    w, seg = pp.basis(t, order=4)
    out = pp.evaluate(t)
    recon = np.einsum("risk,iskn->rin", w, np.stack([pp.points[seg], pp.points[seg + 1]], 1))
    np.testing.assert_allclose(recon, out, rtol=0, atol=1e-12 * np.abs(out).max())
    p, k, j, delta = 2, 3, 1, 0.25  # interior point: used by segments 1 and 2
    pts = np.array(pp.points)
    pts[p, k, j] += delta
    fd = (PiecewisePolynomial(pts, pp.durations).evaluate(t) - out)[:, :, j] / delta
    grad = np.where(seg == p, w[:, :, 0, k], 0.0) + np.where(seg + 1 == p, w[:, :, 1, k], 0.0)
    np.testing.assert_allclose(fd, grad, rtol=0, atol=1e-9 * np.abs(grad).max())


# --------------------------------------------------------------------------- monomial form
@pytest.mark.parametrize("duration", [0.7, 3.0])
def test_coefficients_reproduce_evaluate(duration):
    """Physical-time monomial coefficients (eq. 3.18) give evaluate()."""
    rng = np.random.default_rng(31)
    seg = Segment(*random_points(rng, 2), duration)
    coef = seg.coefficients
    assert coef.shape == (10, N)
    t = np.linspace(0.0, duration, 101)
    out = seg.evaluate(t, order=4)
    for r in range(5):
        ref = npoly.polyval(t, npoly.polyder(coef, r)).T
        np.testing.assert_allclose(ref, out[r], rtol=0, atol=1e-9 * np.abs(out[r]).max())


@pytest.mark.parametrize("degree", [3, 9])
def test_polynomial_reproduced_exactly(degree):
    """A polynomial of degree <= 9 is recovered from its own boundary derivatives."""
    rng = np.random.default_rng(41 + degree)
    duration = 2.5
    true = np.zeros((10, N))
    true[:degree + 1] = rng.normal(size=(degree + 1, N)) / duration ** np.arange(degree + 1)[:, None]
    def point(t):
        return np.stack([npoly.polyval(t, npoly.polyder(true, k)) for k in range(5)])

    seg = Segment(point(0.0), point(duration), duration)
    # coefficients in units scaled by T^c, 1e-10 of the O(1) scale
    np.testing.assert_allclose((seg.coefficients - true) * duration ** np.arange(10)[:, None],
                               0.0, atol=1e-10)
    t = rng.uniform(0.0, duration, size=200)
    out = seg.evaluate(t, order=MAX_ORDER)
    for r in range(10):
        ref = npoly.polyval(t, npoly.polyder(true, r)).T if r <= degree else np.zeros((200, N))
        scale = factorial(r) / duration ** r
        np.testing.assert_allclose(out[r], ref, rtol=0, atol=1e-9 * scale, err_msg=f"r={r}")


# --------------------------------------------------------------------------- helpers
def test_stop_points_give_rest_at_junctions():
    """Stop points: rest (zero derivatives 1..4) at every way point."""
    rng = np.random.default_rng(51)
    positions = rng.normal(size=(5, N))
    points = stop_points(positions)
    assert points.shape == (5, 5, N)
    np.testing.assert_array_equal(points[:, 1:], 0.0)
    pp = PiecewisePolynomial(points, [1.0, 0.5, 2.0, 1.5])
    out = pp.evaluate(pp.knots, order=4)
    np.testing.assert_allclose(out[0], positions, rtol=1e-12)
    np.testing.assert_allclose(out[1:], 0.0, atol=1e-12)  # velocity, acc, jerk, snap


def test_split_evenly():
    """Even split of way-to-way times by via points."""
    way = np.array([2.0, 3.0, 0.9])
    d = split_evenly(way, 2)
    assert d.shape == (9,)
    np.testing.assert_allclose(d.reshape(3, 3).sum(axis=1), way, rtol=1e-15)
    np.testing.assert_allclose(d.sum(), way.sum(), rtol=1e-15)
    np.testing.assert_array_equal(split_evenly(way, 0), way)
    mixed = split_evenly(way, [0, 1, 3])
    np.testing.assert_allclose(mixed, [2.0, 1.5, 1.5, 0.225, 0.225, 0.225, 0.225])


def test_sample_grid():
    """Uniform 1/rate grid that ends exactly at the total time."""
    pp = PiecewisePolynomial(stop_points(np.eye(3, N)), [0.5, 0.25])
    t, derivs = pp.sample(100.0, order=3)
    assert t.shape == (76,) and derivs.shape == (4, 76, N)
    np.testing.assert_allclose(np.diff(t), 0.01, rtol=1e-9)
    assert t[0] == 0.0 and t[-1] == pp.total_duration
    np.testing.assert_array_equal(derivs, pp.evaluate(t, order=3))
    t2, _ = PiecewisePolynomial(stop_points(np.eye(2, N)), [0.333]).sample(100.0)
    assert t2.size == 35 and t2[-1] == 0.333 and abs(t2[-2] - 0.33) < 1e-15


def test_frozen_and_read_only():
    """Fields cannot be reassigned and arrays are read-only."""
    pp = random_chain(61)
    with pytest.raises(dataclasses.FrozenInstanceError):
        pp.durations = np.ones(5)
    with pytest.raises(ValueError):
        pp.points[0, 0, 0] = 1.0


# --------------------------------------------------------------------------- errors
@pytest.mark.parametrize("duration", [0.0, -1.0, np.nan, np.inf])
def test_bad_segment_duration(duration):
    """Non-positive or non-finite duration is refused."""
    with pytest.raises(ValueError, match=r"duration=.*finite and > 0 \[s\]"):
        Segment(np.zeros((5, 2)), np.zeros((5, 2)), duration)


@pytest.mark.parametrize("build, message", [
    (lambda: Segment(np.zeros((4, 2)), np.zeros((5, 2)), 1.0), r"begin.shape=\(4, 2\)"),
    (lambda: Segment(np.zeros((5, 2)), np.zeros((5, 3)), 1.0), r"end.shape=\(5, 3\)"),
    (lambda: PiecewisePolynomial(np.zeros((3, 4, 2)), [1.0, 1.0]),
     r"points.shape=\(3, 4, 2\), expected \(m\+1, 5, n\)"),
    (lambda: PiecewisePolynomial(np.zeros((1, 5, 2)), []), r"points.shape=\(1, 5, 2\)"),
    (lambda: PiecewisePolynomial(np.zeros((4, 5, 2)), [1.0, 1.0]),
     r"durations.shape=\(2,\), expected \(3,\)"),
    (lambda: PiecewisePolynomial(np.zeros((3, 5, 2)), [1.0, 0.0]), r"durations\[1\]=0.0"),
    (lambda: PiecewisePolynomial(np.full((3, 5, 2), np.nan), [1.0, 1.0]), r"NaN or inf"),
    (lambda: split_evenly([1.0, 2.0], -1), r"n_via=-1"),
    (lambda: split_evenly([1.0, 2.0], 1.5), r"n_via=1.5"),
    (lambda: split_evenly([1.0, 2.0], [1, 2, 3]), r"n_via=\[1, 2, 3\].*2 of them"),
    (lambda: split_evenly([1.0, -2.0], 1), r"way_times\[1\]=-2.0"),
    (lambda: stop_points(np.zeros(3)), r"positions.shape=\(3,\), expected \(k, n\)"),
])
def test_shape_and_value_errors(build, message):
    """Wrong shapes and values are refused with a message naming them."""
    with pytest.raises(ValueError, match=message):
        build()


def test_time_and_order_errors():
    """Out-of-range times, bad orders and rates are refused."""
    pp = random_chain(71)
    total = pp.total_duration
    for t in ([-1e-3], [total * (1 + 1e-9)], [0.1, total + 1.0]):
        with pytest.raises(ValueError, match=r"outside the trajectory time range"):
            pp.evaluate(t)
    with pytest.raises(ValueError, match=r"NaN or inf"):
        pp.evaluate([0.1, np.nan])
    with pytest.raises(ValueError, match=r"t.shape=\(2, 2\)"):
        pp.evaluate(np.zeros((2, 2)))
    for order in (-1, 10, 2.0, True):
        with pytest.raises(ValueError, match=r"order=.*integer in 0..9"):
            pp.evaluate([0.1], order=order)
    with pytest.raises(ValueError, match=r"rate_hz=0.0"):
        pp.sample(0.0)
    with pytest.raises(ValueError, match=r"outside"):
        pp.segments[0].evaluate([pp.durations[0] * 1.01])
    # within the 1e-12 relative tolerance: accepted and clamped to the end
    inside = pp.evaluate([-1e-14 * total, total * (1 + 1e-13)])
    np.testing.assert_array_equal(inside, pp.evaluate([0.0, total]))


# --------------------------------------------------------------------------- speed
def test_evaluation_is_vectorised():
    """4 coordinates x 2000 samples evaluate in well under the 5 ms guard."""
    # Guard against a per-sample Python loop (which costs >> 5 ms for 2000 samples); the
    # measured cost is ~0.15-0.4 ms. Best of 20 runs, generous bound for loaded CI machines.
    pp = random_chain(81, m=8)
    t = np.linspace(0.0, pp.total_duration, 2000)
    best = np.inf
    for _ in range(20):
        start = time.perf_counter()
        pp.evaluate(t, order=4)
        best = min(best, time.perf_counter() - start)
    assert best < 5e-3
