"""The NLP of a motion that crosses the prototype's Type-2 singularity (seed ch. 4): :class:`CrossingProblem`.

Motions here are two travels of 9th-degree segments, start -> crossing -> end, meeting at the
crossing point Xi_s = [xi_s, xi_s', xi_s'', xi_s''', xi_s''''] with xi_s = [q1_s, 0]; each travel
may hold via points (:func:`crossing_layout`). :class:`CrossingProblem` makes any of these groups of
unknowns free:

``"state"``
    q1_s, xi_s' and the one free parameter mu of xi_s'' on the criterion's line
    (:func:`fpr.robots.prototype_singularity.criterion_acceleration`): the criterion (4.7) then
    holds exactly for every x, it is never a constraint the solver could miss.
``"high"``
    xi_s''' and xi_s'''' (the thesis' step-1 unknowns).
``"vias"``
    every entry of every via point (the thesis' step-2 unknowns).
``"times"``
    the two travel times.

and solves min J = alpha J_e/J_e0 + (1 - alpha) J_phi/J_phi0 under the chapter's constraints
(ground, fixed point, |q1|, roll, rotor speeds; seed 4.2.1, with the rotor bound w_max - m_gr of
3.48), a least thrust (:func:`fpr.robots.prototype_singularity.min_thrust`), plus ``crossing_side``:
q2 > 0 before the crossing and < 0 after it (one crossing), with the crossing velocity bounded away
from 0 (a simple crossing), and (``smooth_crossing``) the 5th derivative continuous at the crossing:
there F is one derivative less smooth than the motion, and a C4 knot would step the roll acceleration.
The methods that solve it are in :mod:`planners.crossing.solve`.

Derivatives: the motion entries by dual numbers (:class:`planners.problem.motion.MotionProblem`), the
crossing acceleration's dependence on (q1_s, xi_s', mu) by complex step, the travel times by
central differences (each needs a new grid).
"""

from __future__ import annotations

import numpy as np

from fpr.model.errors import PlannerArgumentError, ShapeError
from fpr.robots.prototype_singularity import (
    criterion_acceleration,
    min_thrust,
    nearest_criterion_acceleration,
)
from planners.problem.motion import (
    CONSTRAINT_BACKOFF,
    Evaluation,
    MotionProblem,
    cached_evaluation,
    entry_scales,
    point_time_scales,
)
from planners.trajectory.polynomial import N_DERIVS, PiecewisePolynomial, Segment, with_via_points

#: Half-width of the band the 5th derivative's jump at the crossing is kept in, in Taylor units of the
#: local time scale (s^(5) T^5 / 5!), the optimiser's back-off (1e-3) included: the polynomials are
#: C4 at knots, and at the crossing a jump of the 5th derivative steps the roll acceleration.
JUMP_TOLERANCE = 2e-3

#: Groups of unknowns :class:`CrossingProblem` can free.
GROUPS = ("state", "high", "vias", "times")


def crossing_layout(n_via) -> tuple[int, np.ndarray]:
    """(index of the crossing point, travel index of each segment) for via counts (n1, n2)."""
    n1, n2 = (int(n) for n in n_via)
    return n1 + 1, np.repeat([0, 1], [n1 + 1, n2 + 1])


def segment_durations(times, n_via) -> np.ndarray:
    """Durations of the segments: each travel's time split evenly between its segments."""
    _, travel = crossing_layout(n_via)
    counts = np.bincount(travel, minlength=2)
    return np.asarray(times)[travel] / counts[travel]


def crossing_motion(start, end, crossing_point, times) -> PiecewisePolynomial:
    """The motion start (at rest) -> crossing point -> end (at rest), no via points.

    ``crossing_point``: (5, 2) xi_s and its derivatives 1..4; ``times``: the two travel times [s].
    """
    points = np.zeros((3, N_DERIVS, 2))
    points[0, 0], points[2, 0] = start, end
    points[1] = crossing_point
    return PiecewisePolynomial(points, np.asarray(times, dtype=float))


def add_via_points(trajectory: PiecewisePolynomial, n_via) -> PiecewisePolynomial:
    """The same motion (two travels) with n_via evenly spaced via points inserted in each travel."""
    points, durations, _ = with_via_points(trajectory, trajectory.durations, n_via)
    return PiecewisePolynomial(points, durations)


def jump_weights(durations, index: int) -> np.ndarray:
    """Weights W (3, 5) with s^(5)(t-) - s^(5)(t+) = sum_jk W[j, k] points[index - 1 + j, k] (each
    coordinate) at knot ``index``: the jump of the 5th derivative there, linear in the 3 points around it
    (the segments are C4 at their knots, not C5) [1/s^(5-k)].
    """
    def basis(duration, t):
        blank = np.zeros((N_DERIVS, 1))
        return Segment(blank, blank, float(duration)).basis(t, order=5)[5, 0]  # (2 sides, 5)

    w = np.zeros((3, N_DERIVS))
    w[0:2] += basis(durations[index - 1], float(durations[index - 1]))
    w[1:3] -= basis(durations[index], 0.0)
    return w


def fifth_derivative_jump(trajectory: PiecewisePolynomial, index: int) -> np.ndarray:
    """s^(5)(t-) - s^(5)(t+) at knot ``index`` [unit/s^5], one value per coordinate."""
    w = jump_weights(trajectory.durations, index)
    return np.einsum("jk,jkn->n", w, np.asarray(trajectory.points)[index - 1:index + 2])


def travel_times(trajectory: PiecewisePolynomial, n_via) -> np.ndarray:
    """The two travel times of a crossing motion laid out by :func:`crossing_layout`."""
    _, travel = crossing_layout(n_via)
    return np.bincount(travel, weights=trajectory.durations, minlength=2)


# ---------------------------------------------------------------------------------------- the NLP
class CrossingProblem:
    """J and the constraints of a crossing motion as functions of the free groups (:data:`GROUPS`).

    Args:
        robot: the prototype.
        points: template points (m+1, 5, 2) laid out by :func:`crossing_layout` (start, vias of
            travel 1, crossing, vias of travel 2, end); entries not freed are kept.
        times: the two travel times [s] (kept unless ``"times"`` is free).
        n_via: via points in each travel.
        free: the groups of unknowns (subset of :data:`GROUPS`).
        alpha, normalisation: the objective (3.26), as in :class:`planners.problem.motion.MotionProblem`.
        samples_per_segment, windows_per_segment: the grid.
        min_crossing_speed: |q2'| at the crossing is kept above this [rad/s] (a simple crossing).
        time_bounds: (least, largest) travel time [s]; default (0.3 s, twice the two given times together).
        smooth_crossing: also keep the 5th derivative continuous at the crossing (rows
            ``crossing_c5``), so that the roll acceleration and the rotor speeds do not step there.
    """

    def __init__(self, robot, points, times, n_via, free, alpha: float, normalisation, *,
                 samples_per_segment: int = 17, windows_per_segment: int = 4, min_crossing_speed: float = 0.2,
                 time_bounds: tuple[float, float] | None = None, smooth_crossing: bool = True):
        unknown = set(free) - set(GROUPS)
        if unknown:
            raise PlannerArgumentError("free", tuple(free), f"free={sorted(free)}: unknown group(s) "
                                                            f"{sorted(unknown)}; use some of {GROUPS}")
        self.robot = robot
        self.points = np.array(points, dtype=float)
        self.times = np.asarray(times, dtype=float).copy()
        self.n_via = tuple(int(n) for n in n_via)
        self.index, self.travel = crossing_layout(self.n_via)
        if self.points.shape != (len(self.travel) + 1, N_DERIVS, 2):
            raise ShapeError("points", self.points.shape,
                             f"{(len(self.travel) + 1, N_DERIVS, 2)} for n_via={self.n_via}")
        self.free_groups = tuple(g for g in GROUPS if g in free)
        self.alpha, self.normalisation = float(alpha), tuple(normalisation)
        self.samples, self.windows = int(samples_per_segment), int(windows_per_segment)
        self.min_crossing_speed = float(min_crossing_speed)
        if time_bounds is None:
            time_bounds = (0.3, 2.0 * float(np.sum(self.times)))
        self.time_bounds = tuple(float(t) for t in time_bounds)
        self.smooth_crossing = bool(smooth_crossing)
        self.before = 1.0 if self.points[0, 0, 1] > 0 else -1.0  # sign of q2 before the crossing
        c = self.index
        # the template's crossing point must be on q2 = 0 and (if its state is free) on the criterion
        self.points[c, 0, 1] = 0.0
        mu = 0.0
        if "state" in self.free_groups:
            acc, mu = nearest_criterion_acceleration(robot, self.points[c, 0, 0], self.points[c, 1],
                                                     self.points[c, 2])
            self.points[c, 2] = acc
        # decision variables: (kind, target, scale)
        durations = segment_durations(self.times, self.n_via)
        entry_scale = entry_scales(durations)
        var: list[tuple[str, tuple, float]] = []
        if "state" in self.free_groups:
            var.append(("entry", (c, 0, 0), 1.0))
            var += [("entry", (c, 1, j), entry_scale[c, 1]) for j in range(2)]
            var.append(("mu", (), entry_scale[c, 2]))
        if "high" in self.free_groups:
            var += [("entry", (c, k, j), entry_scale[c, k]) for k in (3, 4) for j in range(2)]
        if "vias" in self.free_groups:
            vias = [p for p in range(1, len(self.points) - 1) if p != c]
            var += [("entry", (p, k, j), entry_scale[p, k]) for p in vias for k in range(N_DERIVS)
                    for j in range(2)]
        if "times" in self.free_groups:
            var += [("time", (i,), 1.0) for i in range(2)]
        self.variables = var
        self.scale = np.array([v[2] for v in var])
        self.n_x = len(var)
        self._mu0 = mu
        # the point entries that x moves (the inner problem's free mask)
        mask = np.zeros(self.points.shape, dtype=bool)
        for kind, target, _ in var:
            if kind == "entry":
                mask[target] = True
        if "state" in self.free_groups:
            mask[c, 2] = True
        self.mask = mask
        # the 5th-derivative jump at the crossing in Taylor units of the local time scale, T^5 / 5!
        self._jump_scale = point_time_scales(durations)[c] ** 5 / 120.0
        self._cache: tuple[bytes, bool, Evaluation] | None = None

    # ------------------------------------------------------------------ x <-> motion
    def _decode(self, x):
        """(points, times, mu) of x (complex x allowed for the crossing state)."""
        x = np.asarray(x)
        points = self.points.astype(x.dtype)
        times = self.times.astype(float).copy()
        mu = self._mu0
        for value, (kind, target, scale) in zip(x, self.variables, strict=True):
            if kind == "entry":
                points[target] = value * scale
            elif kind == "mu":
                mu = value * scale
            else:
                times[target[0]] = float(np.real(value)) * scale
        if "state" in self.free_groups:
            c = self.index
            points[c, 2] = criterion_acceleration(self.robot, points[c, 0, 0], points[c, 1], mu)
        return points, times, mu

    def x0(self) -> np.ndarray:
        """The decision vector of the template."""
        x = []
        for kind, target, scale in self.variables:
            value = self.points[target] if kind == "entry" else self._mu0 if kind == "mu" else self.times[target[0]]
            x.append(value / scale)
        return np.array(x, dtype=float)

    def trajectory(self, x) -> PiecewisePolynomial:
        """The motion of x."""
        points, times, _ = self._decode(x)
        return PiecewisePolynomial(np.real(points), segment_durations(times, self.n_via))

    def _inner(self, points, times) -> MotionProblem:
        return MotionProblem(self.robot, points, segment_durations(times, self.n_via), self.mask, self.alpha,
                             self.normalisation, samples_per_segment=self.samples,
                             windows_per_segment=self.windows, crossing=self.index,
                             min_thrust=min_thrust(self.robot), dips=True)

    def _extra_rows(self, points, times) -> tuple[np.ndarray, list[str]]:
        """Rows beside the motion's (scaled, >= 0): travel-time bounds, the crossing speed, and the
        5th derivative continuous at the crossing (within +-:data:`JUMP_TOLERANCE` Taylor units).
        """
        lo, hi = self.time_bounds
        c = self.index
        jump = self._jump_scale * np.einsum("jk,jkn->n", jump_weights(segment_durations(times, self.n_via), c),
                                            np.real(points[c - 1:c + 2]))
        rows = [times[0] - lo, times[1] - lo, hi - times[0], hi - times[1],
                (-self.before * np.real(points[c, 1, 1]) - self.min_crossing_speed)]
        names = ["travel_time"] * 4 + ["crossing_speed"]
        if self.smooth_crossing:
            rows += [*(JUMP_TOLERANCE + jump), *(JUMP_TOLERANCE - jump)]
            names += ["crossing_c5"] * 4
        return np.array(rows) - CONSTRAINT_BACKOFF, names

    @property
    def constraint_names(self) -> list[str]:
        """Name of each constraint row."""
        points, times, _ = self._decode(self.x0())
        return self._inner(points, times).constraint_names + self._extra_rows(points, times)[1]

    # ------------------------------------------------------------------ evaluation
    @cached_evaluation
    def evaluate(self, x, derivatives: bool = False) -> Evaluation:
        """J, the constraints and (optionally) their derivatives at x (cached)."""
        points, times, _ = self._decode(x)
        inner = self._inner(points, times)
        ev = inner.evaluate(inner.x_of(points), derivatives)
        extra, _ = self._extra_rows(points, times)
        constraints = np.concatenate([ev.constraints, extra])
        if not derivatives:
            return Evaluation(ev.J, ev.terms, constraints)
        # d(inner free entries)/dx
        flat = np.flatnonzero(self.mask.reshape(-1))
        position = {int(f): i for i, f in enumerate(flat)}
        shape = self.points.shape
        jp = np.zeros((flat.size, self.n_x))
        for col, (kind, target, scale) in enumerate(self.variables):
            if kind == "entry":
                jp[position[int(np.ravel_multi_index(target, shape))], col] = scale
        if "state" in self.free_groups:
            c = self.index
            rows = [position[int(np.ravel_multi_index((c, 2, j), shape))] for j in range(2)]
            for col, (kind, target, _) in enumerate(self.variables):
                if kind == "mu" or (kind == "entry" and target[0] == c and target[1] in (0, 1)):
                    h = 1e-30
                    xc = x.astype(complex)
                    xc[col] += 1j * h
                    pc, _, _ = self._decode(xc)
                    jp[rows, col] = pc[c, 2].imag / h
        inv = 1.0 / inner.scale
        grad = jp.T @ (ev.gradient * inv)
        jac = (ev.jacobian * inv[None, :]) @ jp
        hess = jp.T @ (ev.hessian * np.outer(inv, inv)) @ jp
        # extra rows: the speed row and the jump rows are linear in the point entries
        c = self.index
        d_points = np.zeros((extra.size,) + shape)
        d_points[4, c, 1, 1] = -self.before
        if self.smooth_crossing:
            w = self._jump_scale * jump_weights(segment_durations(times, self.n_via), c)  # (3, 5)
            for j in range(2):
                d_points[5 + j, c - 1:c + 2, :, j] = w
                d_points[7 + j, c - 1:c + 2, :, j] = -w
        jac_extra = d_points.reshape(extra.size, -1)[:, flat] @ jp
        for col, (kind, target, scale) in enumerate(self.variables):
            if kind != "time":
                continue
            step = 1e-5  # central differences: each side needs a new grid
            values = []
            for sign in (1.0, -1.0):
                t = times.copy()
                t[target[0]] += sign * step
                other = self._inner(points, t)
                values.append((other.evaluate(other.x_of(points)), self._extra_rows(points, t)[0]))
            grad[col] = (values[0][0].J - values[1][0].J) / (2 * step) * scale
            jac[:, col] = (values[0][0].constraints - values[1][0].constraints) / (2 * step) * scale
            jac_extra[:, col] = (values[0][1] - values[1][1]) / (2 * step) * scale
            hess[col, col] += 1e-3 * max(1.0, np.abs(np.diag(hess)).max())
        return Evaluation(ev.J, ev.terms, constraints, grad, np.vstack([jac, jac_extra]), hess)
