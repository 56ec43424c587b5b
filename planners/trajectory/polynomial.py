"""Ninth-degree polynomial motion segments (thesis eq. 3.18-3.19).

Each coordinate s_j(t) of a vector s (dimension n) is, on one segment t in [0, T], a polynomial
of degree 9 (eq. 3.18, s_j(t) = sum_c a_c t^c) fixed by its two boundary points
S = [s, s', s'', s''', s''''] at t = 0 and t = T (eq. 3.19): a C4 two-point Hermite interpolant.

Numerics. A segment is represented in normalised time tau = t / T in [0, 1] through the Hermite
basis h_{b,k}, h_{e,k} (begin / end side, derivative order k = 0..4)::

    s(tau) = sum_k T^k [S_b^(k) h_{b,k}(tau) + S_e^(k) h_{e,k}(tau)],

which is linear in the boundary points, so exact gradients are available (`Segment.basis`).
The basis is derived once in exact rational arithmetic (confluent Vandermonde system). It is
stored twice: expanded around tau = 0 (`HERMITE_BASIS`, used for tau <= 1/2) and around tau = 1
(used for tau > 1/2), so both boundaries are reproduced to rounding and ``|x| <= 1/2`` keeps the
power sums well conditioned. Evaluation is vectorised: one matrix product per (segment, half).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from math import perm

import numpy as np

from fpr.model.errors import TrajectoryError

N_COEFFS = 10  # coefficients of a degree-9 polynomial
N_DERIVS = 5  # derivative orders 0..4 held by a boundary point
MAX_ORDER = N_COEFFS - 1  # derivatives above 9 vanish identically
_REL_TOL = 1e-12  # relative tolerance on t outside [0, total]


def _hermite_fractions(x_begin: int, x_end: int) -> list[list[Fraction]]:
    """Exact basis coefficients: result[c][5 * side + k] multiplies x^c in h_{side,k}(x).

    Solves the 10x10 confluent Vandermonde system d^k/dx^k h_j(x_side) = delta by Gauss-Jordan
    elimination in `Fraction` arithmetic (the begin point sits at x_begin, the end at x_end).
    """
    rows = [[Fraction(perm(c, k)) * Fraction(x0) ** (c - k) if c >= k else Fraction(0)
             for c in range(N_COEFFS)] for x0 in (x_begin, x_end) for k in range(N_DERIVS)]
    aug = [row + [Fraction(int(i == j)) for j in range(N_COEFFS)] for i, row in enumerate(rows)]
    for col in range(N_COEFFS):
        pivot = next(r for r in range(col, N_COEFFS) if aug[r][col] != 0)
        aug[col], aug[pivot] = aug[pivot], aug[col]
        aug[col] = [v / aug[col][col] for v in aug[col]]
        for r in range(N_COEFFS):
            if r != col and aug[r][col] != 0:
                aug[r] = [a - aug[r][col] * b for a, b in zip(aug[r], aug[col], strict=True)]
    return [row[N_COEFFS:] for row in aug]  # inverse of the system matrix, rows = powers


def hermite_basis_exact() -> list[list[Fraction]]:
    """Exact monomial coefficients of the Hermite basis in tau (see `HERMITE_BASIS`)."""
    return _hermite_fractions(0, 1)


#: HERMITE_BASIS[c, 5 * side + k] is the coefficient of tau^c in h_{side,k}(tau), side 0 = begin.
HERMITE_BASIS = np.array(hermite_basis_exact(), dtype=float)
HERMITE_BASIS.setflags(write=False)
# Same basis expanded in sigma = tau - 1 (used for tau > 1/2); stacked with HERMITE_BASIS.
_EXPANSIONS = np.stack([HERMITE_BASIS, np.array(_hermite_fractions(-1, 0), dtype=float)])
# _DERIV[r, c, q]: coefficient q of a polynomial feeds coefficient c of its r-th derivative.
_DERIV = np.zeros((N_COEFFS, N_COEFFS, N_COEFFS))
for _r in range(N_COEFFS):
    for _c in range(N_COEFFS - _r):
        _DERIV[_r, _c, _c + _r] = perm(_c + _r, _r)
# _DERIV_BASIS[h, r, c, j]: x^c coefficient of the r-th x-derivative of basis j, expansion h.
_DERIV_BASIS = np.einsum("rcq,hqj->hrcj", _DERIV, _EXPANSIONS)
_K = np.arange(N_DERIVS)


def _check_order(order) -> int:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) \
            or not 0 <= order <= MAX_ORDER:
        raise TrajectoryError("order", order, f"order={order!r}: pass an integer in 0..{MAX_ORDER} (the highest "
                              "derivative wanted; derivatives above 9 are identically zero)")
    return int(order)


def _check_durations(durations, name: str, unit: str = "s") -> np.ndarray:
    d = np.array(durations, dtype=float)
    if d.size == 0:
        raise TrajectoryError(name, d, f"{name} is empty: give at least one value > 0 [{unit}]")
    bad = np.flatnonzero(~(np.isfinite(d) & (d > 0.0)))
    if bad.size:
        where = f"{name}[{bad[0]}]" if d.ndim else name
        raise TrajectoryError(name, d, f"{where}={float(d.flat[bad[0]])!r}: must be finite and > 0 [{unit}] "
                                       f"({bad.size} bad value(s))")
    return d


def _check_points(points, expected: str) -> np.ndarray:
    p = np.array(points, dtype=float)
    if p.ndim != 3 or p.shape[0] < 2 or p.shape[1] != N_DERIVS or p.shape[2] < 1:
        raise TrajectoryError("points", p, f"points.shape={p.shape}, expected {expected}: the value and "
                                           "derivatives 1..4 of every coordinate at each point")
    if not np.all(np.isfinite(p)):
        raise TrajectoryError("points", p, "points contain NaN or inf: give finite values and derivatives")
    p.setflags(write=False)
    return p


def _tau_coefficients(points: np.ndarray, durations: np.ndarray) -> np.ndarray:
    """Coefficients (m, 2, 10, n) of every segment in tau (expansion 0) and tau - 1 (1)."""
    m, _, n = points.shape[0] - 1, points.shape[1], points.shape[2]
    scale = durations[:, None] ** _K  # T^k, (m, 5)
    ends = np.stack([points[:-1], points[1:]], axis=1) * scale[:, None, :, None]
    return np.einsum("hcj,mjn->mhcn", _EXPANSIONS, ends.reshape(m, 2 * N_DERIVS, n))


def _powers(x: np.ndarray) -> np.ndarray:
    """Matrix (N, 10) of x^c, built row by row on a contiguous (10, N) buffer."""
    vt = np.empty((N_COEFFS, x.size))
    vt[0] = 1.0
    for c in range(1, N_COEFFS):
        np.multiply(vt[c - 1], x, out=vt[c])
    return vt.T


def _apply_groups(knots: np.ndarray, durations: np.ndarray, t, mats: np.ndarray):
    """Values (R, N, K) of x(t)^c @ mats[2 * segment + half], plus the segment of each t.

    mats has shape (2m, R, 10, K). Samples are grouped by (segment, half) with a stable sort
    (skipped for sorted t), so the work is one stacked matrix product per group actually hit.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    total = knots[-1]
    if t.ndim != 1:
        raise TrajectoryError("t", t, f"t.shape={t.shape}, expected a scalar or a 1-D array of times [s]")
    if not np.all(np.isfinite(t)):
        raise TrajectoryError("t", t, "t contains NaN or inf: pass finite times in [0, total_duration] [s]")
    if t.size and (t.min() < -_REL_TOL * total or t.max() > total * (1.0 + _REL_TOL)):
        raise TrajectoryError("t", t, f"t spans [{t.min():.17g}, {t.max():.17g}] s, outside the trajectory "
                                      f"time range [0, {total:.17g}] s: clip or rescale the query times")
    t = np.clip(t, 0.0, total)
    m = durations.size
    seg = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, m - 1)
    d = durations[seg]
    tau = (t - knots[seg]) / d
    half = tau > 0.5
    x = np.where(half, (t - knots[seg + 1]) / d, tau)  # |x| <= 1/2, exact 0 on knots
    key = 2 * seg + half
    order = None
    if np.any(key[1:] < key[:-1]):
        order = np.argsort(key, kind="stable")
        key, x = key[order], x[order]
    v = _powers(x)
    out = np.empty((mats.shape[1], t.size, mats.shape[3]))
    bounds = np.searchsorted(key, np.arange(2 * m + 1))
    for g in np.flatnonzero(bounds[1:] > bounds[:-1]):
        a, b = bounds[g], bounds[g + 1]
        np.matmul(v[a:b], mats[g], out=out[:, a:b])
    if order is not None:
        unsorted = np.empty_like(out)
        unsorted[:, order] = out
        out = unsorted
    return out, seg


def _evaluate(knots, durations, coef, t, order) -> np.ndarray:
    r_count = _check_order(order) + 1
    inv = (1.0 / durations)[:, None] ** np.arange(r_count)  # chain rule 1/T^r, (m, R)
    mats = np.einsum("rcq,mhqn->mhrcn", _DERIV[:r_count], coef) * inv[:, None, :, None, None]
    m, n = coef.shape[0], coef.shape[3]
    return _apply_groups(knots, durations, t, mats.reshape(2 * m, r_count, N_COEFFS, n))[0]


def _basis(knots, durations, t, order):
    r_count = _check_order(order) + 1
    power = _K[None, :] - np.arange(r_count)[:, None]  # k - r, (R, 5)
    scale = durations[:, None, None] ** power  # T^(k - r), (m, R, 5)
    mats = _DERIV_BASIS[None, :, :r_count].reshape(1, 2, r_count, N_COEFFS, 2, N_DERIVS) \
        * scale[:, None, :, None, None, :]
    m = durations.size
    out, seg = _apply_groups(knots, durations, t,
                             mats.reshape(2 * m, r_count, N_COEFFS, 2 * N_DERIVS))
    return out.reshape(r_count, -1, 2, N_DERIVS), seg


@dataclass(frozen=True, eq=False)
class Segment:
    """One degree-9 segment between two boundary points (eq. 3.18-3.19).

    Attributes:
        begin: boundary point at t = 0, shape (5, n): rows are s [unit], s' [unit/s], ...,
            s'''' [unit/s^4] for each of the n coordinates.
        end: boundary point at t = duration, shape (5, n), same layout.
        duration: segment time T [s], finite and > 0.
    """

    begin: np.ndarray
    end: np.ndarray
    duration: float
    _coef: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        begin, end = np.asarray(self.begin, dtype=float), np.asarray(self.end, dtype=float)
        if begin.ndim != 2 or begin.shape[0] != N_DERIVS or begin.shape != end.shape:
            raise TrajectoryError("begin", begin, f"begin.shape={begin.shape}, end.shape={end.shape}, expected "
                                                  "both (5, n): value and derivatives 1..4 of each coordinate")
        if np.ndim(self.duration) != 0:
            raise TrajectoryError("duration", self.duration,
                                  f"duration={self.duration!r}: pass one finite time > 0 [s]")
        duration = float(_check_durations(self.duration, "duration"))
        points = _check_points(np.stack([begin, end]), "(5, n) for begin and end")
        object.__setattr__(self, "begin", points[0])
        object.__setattr__(self, "end", points[1])
        object.__setattr__(self, "duration", duration)
        object.__setattr__(self, "_coef", _tau_coefficients(points, np.array([duration])))

    def evaluate(self, t, order: int = 4) -> np.ndarray:
        """Value and derivatives at times t.

        Args:
            t: scalar or 1-D array of times in [0, duration] [s], any order.
            order: highest derivative wanted, 0..9.

        Returns:
            Array (order+1, len(t), n); entry r is d^r s/dt^r [unit/s^r].
        """
        return _evaluate(np.array([0.0, self.duration]), np.array([self.duration]),
                         self._coef, t, order)

    @property
    def coefficients(self) -> np.ndarray:
        """Monomial coefficients a (10, n) in physical time: s(t) = sum_c a[c] t^c (eq. 3.18)."""
        return self._coef[0, 0] / self.duration ** np.arange(N_COEFFS)[:, None]

    def basis(self, t, order: int = 4) -> np.ndarray:
        """Weights w (order+1, len(t), 2, 5) of the boundary points, exact gradients.

        s^(r)(t_i) = sum_{side,k} w[r, i, side, k] * point[side][k, :] for every coordinate,
        with point[0] = begin, point[1] = end; hence d s^(r)(t_i) / d point[side][k] =
        w[r, i, side, k] (the segment is linear in its points). Units: [s^(k - r)].

        Args:
            t: scalar or 1-D array of times in [0, duration] [s].
            order: highest derivative r wanted, 0..9.
        """
        return _basis(np.array([0.0, self.duration]), np.array([self.duration]), t, order)[0]


@dataclass(frozen=True, eq=False)
class PiecewisePolynomial:
    """Chain of m degree-9 segments through m+1 points, C4 at every junction by construction.

    Attributes:
        points: way and via points, shape (m+1, 5, n): value and derivatives 1..4 per point.
        durations: time of each segment, shape (m,) [s], finite and > 0.
        knots: cumulative times (m+1,) [s], knots[0] = 0, knots[-1] = total_duration.
    """

    points: np.ndarray
    durations: np.ndarray
    knots: np.ndarray = field(init=False)
    _coef: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        points = _check_points(self.points, "(m+1, 5, n) with m >= 1")
        durations = _check_durations(self.durations, "durations")
        if durations.shape != (points.shape[0] - 1,):
            raise TrajectoryError("durations", durations, f"durations.shape={durations.shape}, expected "
                                                          f"({points.shape[0] - 1},): one duration per segment "
                                                          f"between the {points.shape[0]} points")
        knots = np.concatenate([[0.0], np.cumsum(durations)])
        for a in (durations, knots):
            a.setflags(write=False)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "durations", durations)
        object.__setattr__(self, "knots", knots)
        object.__setattr__(self, "_coef", _tau_coefficients(points, durations))

    @property
    def total_duration(self) -> float:
        """Total time [s]."""
        return float(self.knots[-1])

    @property
    def segments(self) -> list[Segment]:
        """The m segments, each in its own local time [0, durations[i]]."""
        return [Segment(self.points[i], self.points[i + 1], float(d))
                for i, d in enumerate(self.durations)]

    def evaluate(self, t, order: int = 4) -> np.ndarray:
        """Value and derivatives (order+1, len(t), n); entry r is d^r s/dt^r [unit/s^r].

        Args:
            t: scalar or 1-D array of times in [0, total_duration] [s], any order. A time on a
                knot belongs to the segment starting there, t == total_duration to the last.
            order: highest derivative wanted, 0..9.
        """
        return _evaluate(self.knots, self.durations, self._coef, t, order)

    def evaluate_held(self, t, order: int = 4) -> np.ndarray:
        """:meth:`evaluate`, extended past the end: the motion rests at its last point there (its
        derivatives 1..order are 0). For tracking and animation beyond the plan; shape (order+1, N, n).
        """
        t = np.asarray(t, dtype=float)
        values = self.evaluate(np.minimum(t, self.total_duration), order)
        values[1:, t > self.total_duration] = 0.0
        return values

    def basis(self, t, order: int = 4) -> tuple[np.ndarray, np.ndarray]:
        """Exact point weights: (w (order+1, len(t), 2, 5), segment (len(t),) int).

        s^(r)(t_i) = sum_{side,k} w[r, i, side, k] * points[segment[i] + side, k, :], so w is
        also d s^(r)(t_i) / d points[segment[i] + side, k] (see `Segment.basis`).

        Args:
            t: scalar or 1-D array of times in [0, total_duration] [s].
            order: highest derivative r wanted, 0..9.
        """
        return _basis(self.knots, self.durations, t, order)

    def sample(self, rate_hz: float, order: int = 4) -> tuple[np.ndarray, np.ndarray]:
        """Evaluate on t_k = k / rate_hz, plus total_duration if it is not on the grid.

        Args:
            rate_hz: sampling rate [Hz], finite and > 0.
            order: highest derivative wanted, 0..9.

        Returns:
            (t (N,) [s], derivatives (order+1, N, n)); the last step may be shorter.
        """
        t = self.sample_times(rate_hz)
        return t, self.evaluate(t, order)

    def sample_times(self, rate_hz: float) -> np.ndarray:
        """The times of :meth:`sample`: t_k = k / rate_hz, then total_duration (the last step may be shorter)."""
        rate = float(_check_durations(rate_hz, "rate_hz", "Hz"))
        total = self.total_duration
        t = np.arange(int(np.floor(total * rate * (1.0 + _REL_TOL))) + 1) / rate
        if total - t[-1] > _REL_TOL * total:
            t = np.append(t, total)
        t[-1] = total
        return t


def split_evenly(way_times, n_via) -> np.ndarray:
    """Segment durations when each way-to-way travel is cut evenly by n_via via points (3.2.1).

    Args:
        way_times: travel time between consecutive way points, shape (k,) [s].
        n_via: via points per travel (int >= 0, or one int per travel).

    Returns:
        Durations [s] of the sum(n_via + 1) segments, in order.
    """
    times = _check_durations(way_times, "way_times").reshape(-1)
    counts = np.asarray(n_via)
    if counts.shape not in ((), times.shape) or not np.issubdtype(counts.dtype, np.integer) \
            or np.any(counts < 0):
        raise TrajectoryError("n_via", n_via, f"n_via={n_via!r}: pass a non-negative integer, or {times.size} of "
                                              "them (one per travel)")
    counts = np.broadcast_to(counts, times.shape)
    return np.repeat(times / (counts + 1), counts + 1)


def stop_points(positions) -> np.ndarray:
    """Points (k, 5, n) at positions (k, n) with zero velocity, acceleration, jerk and snap."""
    pos = np.asarray(positions, dtype=float)
    if pos.ndim != 2:
        raise TrajectoryError("positions", pos, f"positions.shape={pos.shape}, expected (k, n)")
    points = np.zeros((pos.shape[0], N_DERIVS, pos.shape[1]))
    points[:, 0] = pos
    return points


def via_point_times(trajectory: PiecewisePolynomial, begin: float, duration: float, count: int) -> np.ndarray:
    """Value and derivatives 0..4 of ``trajectory`` at ``count`` evenly spaced times inside
    [begin, begin + duration] [s], shape (count, 5, n).
    """
    if count == 0:
        return np.zeros((0,) + trajectory.points.shape[1:])
    t = begin + duration * np.arange(1, count + 1) / (count + 1)
    return np.moveaxis(trajectory.evaluate(t, order=4), 1, 0)


def with_via_points(trajectory: PiecewisePolynomial, way_times,
                    n_via) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The same motion cut at evenly spaced via times (3.2.1): the new points are the motion's own
    value and derivatives there, so the motion does not change.

    Args:
        trajectory: a motion whose knots are the way points (one segment per travel).
        way_times: travel times (k,) [s], the durations of ``trajectory``.
        n_via: via points to insert in each travel (k,) (integers >= 0).

    Returns:
        (points (m+1, 5, n), durations (m,) [s], is_way (m+1,) True at the way points): each travel
        split evenly (:func:`split_evenly`).
    """
    knots = np.concatenate([[0.0], np.cumsum(way_times)])
    points, durations, is_way = [trajectory.points[0]], [], [True]
    for j, (duration, count) in enumerate(zip(way_times, n_via, strict=True)):
        for via in via_point_times(trajectory, knots[j], duration, int(count)):
            points.append(via)
            is_way.append(False)
        points.append(trajectory.points[j + 1])
        is_way.append(True)
        durations += [duration / (count + 1)] * (int(count) + 1)
    return np.array(points), np.array(durations), np.array(is_way)
