"""Crossing the prototype's Type-2 singularity (seed ch. 4).

The prototype's chain obeys J_pr(xi)^T F = M_pt(xi) xi'' + c_pt(xi, xi') (seed 3.37, drone as a
point mass at its joint). At q2 = 0 the links are aligned and J_pr loses rank: its null vector
n = [-1, 2] (DESIGN.md) is the motion of the elbow across the straight chain with the drone still.
No drone force acts along it, so a motion can only pass q2 = 0 with a finite force if, there,

.. math:: n^T (M_{pt}(\\xi_s) \\ddot\\xi_s + c_{pt}(\\xi_s, \\dot\\xi_s)) = 0 \\qquad (4.7)

the *crossing criterion*. It is one linear equation in xi_s''. The force is then finite: across
the second link it is regular everywhere, along it (the link's tension) it is the 0/0 limit that
:func:`fpr.model.inverse_dynamics.prototype_thrust_vectors` computes exactly.

Motions here are two travels of 9th-degree segments, start -> crossing -> end, meeting at the
crossing point Xi_s = [xi_s, xi_s', xi_s'', xi_s''', xi_s''''] with xi_s = [q1_s, 0]; each travel
may hold via points. :class:`CrossingProblem` makes any of these groups of unknowns free:

``"state"``
    q1_s, xi_s' and the one free parameter mu of xi_s'' on the criterion's line
    (:func:`criterion_acceleration`): the criterion then holds exactly for every x, it is never
    a constraint the solver could miss.
``"high"``
    xi_s''' and xi_s'''' (the thesis' step-1 unknowns).
``"vias"``
    every entry of every via point (the thesis' step-2 unknowns).
``"times"``
    the two travel times.

and solves min J = alpha J_e/J_e0 + (1 - alpha) J_phi/J_phi0 under the chapter's constraints
(ground, fixed point, |q1|, roll, rotor speeds; seed 4.2.1, with the rotor bound w_max - m_gr of
3.48), a least thrust (:data:`MIN_THRUST_FRACTION` of the drone's weight), plus ``crossing_side``:
q2 > 0 before the crossing and < 0 after it (one crossing), with the crossing velocity bounded away
from 0 (a simple crossing), and (``smooth_crossing``) the 5th derivative continuous at the crossing:
there F is one derivative less smooth than the motion, and a C4 knot would step the roll acceleration.

* :func:`seed_approach` reproduces the seed's two approaches (4.2.1, 4.2.2) with this package's
  model and parameters: their fixed crossing state and travel times, their two steps, their
  constraints (C4 only at the crossing).
* :func:`optimise_crossing` frees everything together: the crossing state, the travel times and
  the via points, from a first guess in the drone's polar coordinates (:func:`first_guess`), which
  is what finds a motion within the limits. :func:`planners.optimize.plan` runs it for a mission
  with ``cross_singularity = true``.

Derivatives: the motion entries by complex step (:class:`planners.problem.MotionProblem`), the
crossing acceleration's dependence on (q1_s, xi_s', mu) by complex step too, the travel times by
central differences (each needs a new grid).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from fpr.model.jets import Jet
from planners.polynomial import N_DERIVS, PiecewisePolynomial
from planners.problem import CONSTRAINT_BACKOFF, Evaluation, MotionProblem, entry_scales, point_time_scales

#: Null vector of J_pr at q2 = 0 (any q1): J_pr n = 0 (seed 4.3; DESIGN.md).
NULL_VECTOR = np.array([-1.0, 2.0])

#: Least thrust of a crossing, as a fraction of the drone's weight. The controller steers the thrust's
#: direction (the roll); at a small thrust a small force error turns it far, and with the drone's
#: joint d below its centre of mass the roll error feeds back into the chain. Measured with the
#: built-in mission (fpr.sim.closed_loop, default controller): planned C4 only at the crossing, with this
#: bound at 0 (least thrust 1.9 N) or 0.5 (4.9 N), the closed loop lost the drone shortly before
#: the crossing; planned C5 there (the default), it tracks at 0 and 0.5 but the allocation saturates
#: (34 and 242 ticks); at 0.8 it saturates on none (tests/test_crossing.py).
MIN_THRUST_FRACTION = 0.8

#: The successive first guesses of :func:`optimise_crossing`: (drone polar angle at the crossing
#: [rad], fraction of the mission's total time). The chain nearly upright, where gravity acts least
#: across it; the travel times are optimised anyway, the fraction only changes where they start.
CROSSING_STARTS = ((1.2, 1.0), (1.3, 1.0), (1.1, 1.0), (1.2, 0.75), (1.3, 0.75))

#: Violations are compared between starts relative to these sizes (per unit of the report).
FEASIBILITY_SCALE = {"m": 0.1, "rad": 0.1, "rad/s": 100.0, "N": 1.0}

#: Half-width of the band the 5th derivative's jump at the crossing is kept in, in Taylor units of the
#: local time scale (s^(5) T^5 / 5!), the optimiser's back-off (1e-3) included: the polynomials are
#: C4 at knots, and at the crossing a jump of the 5th derivative steps the roll acceleration.
JUMP_TOLERANCE = 2e-3

#: Groups of unknowns :class:`CrossingProblem` can free.
GROUPS = ("state", "high", "vias", "times")

#: The seed's crossing task (4.1): start and end xi [rad] (the drone at the same point, both modes).
SEED_START = np.array([-0.9470, 1.8940])
SEED_END = np.array([0.9470, -1.8940])


def min_thrust(robot) -> float:
    """The least thrust of a crossing motion, :data:`MIN_THRUST_FRACTION` of m_d g [N]."""
    return MIN_THRUST_FRACTION * robot.drone_mass * robot.planar("point").gravity


# ---------------------------------------------------------------------------------------- the criterion
def _force_of(model, xi, xi_dot, xi_ddot) -> np.ndarray:
    """Generalised force M xi'' + c of a planar model at one state (complex-step safe), shape (2,)."""
    m = np.stack(np.broadcast_arrays(*(np.asarray(a) for a in (xi, xi_dot, xi_ddot))))[:, None, :]
    return model.inverse_dynamics_jet(Jet(m)).value[0]


def _affine_dynamics(model, xi, xi_dot) -> tuple[np.ndarray, np.ndarray]:
    """(M, c) of a planar model at (xi, xi'): M xi'' + c is the generalised force."""
    c = _force_of(model, xi, xi_dot, np.zeros(2))
    m = np.stack([_force_of(model, xi, xi_dot, e) - c for e in np.eye(2)], axis=-1)
    return m, c


def criterion(robot, xi, xi_dot, xi_ddot) -> float:
    """n^T (M_pt xi'' + c_pt) (seed 4.7) [N m]: 0 is what a finite force at q2 = 0 needs."""
    return float(np.real(NULL_VECTOR @ _force_of(robot.planar("point"), xi, xi_dot, xi_ddot)))


def _criterion_line(robot, q1, xi_dot):
    """The criterion's solutions xi'' = base + mu * direction at xi = [q1, 0] (direction unit)."""
    m, c = _affine_dynamics(robot.planar("point"), np.array([q1, 0.0 * q1]), xi_dot)
    p = m.T @ NULL_VECTOR  # criterion: p . xi'' + n . c = 0
    norm2 = p @ p
    base = -(NULL_VECTOR @ c) * p / norm2
    direction = np.array([-p[1], p[0]]) / np.sqrt(norm2)
    return base, direction


def criterion_acceleration(robot, q1, xi_dot, mu=0.0) -> np.ndarray:
    """The crossing acceleration xi_s'' at xi_s = [q1, 0] that satisfies the criterion (4.7).

    The criterion leaves a line of accelerations; ``mu`` [rad/s^2] is the signed distance along it
    from its point closest to 0. Complex-step safe in all arguments.
    """
    base, direction = _criterion_line(robot, q1, np.asarray(xi_dot))
    return base + mu * direction


def nearest_criterion_acceleration(robot, q1, xi_dot, xi_ddot) -> tuple[np.ndarray, float]:
    """``xi_ddot`` moved onto the criterion's line along the null vector n, and its ``mu``.

    Moving along n leaves the drone's acceleration J_pr xi'' unchanged (J_pr n = 0 at q2 = 0):
    only the elbow's acceleration across the straight chain changes, by what the criterion needs.
    """
    xi_dot = np.asarray(xi_dot, dtype=float)
    xi_ddot = np.asarray(xi_ddot, dtype=float)
    base, direction = _criterion_line(robot, q1, xi_dot)
    residual = criterion(robot, np.array([q1, 0.0]), xi_dot, xi_ddot)
    m, _ = _affine_dynamics(robot.planar("point"), np.array([q1, 0.0]), xi_dot)
    moved = xi_ddot - residual / (NULL_VECTOR @ m @ NULL_VECTOR) * NULL_VECTOR
    mu = float(direction @ (moved - base))
    return base + mu * direction, mu


def acceleration_from_chain_force(robot, xi, xi_dot, chain_force) -> np.ndarray:
    """xi'' of the passive chain when the drone pushes its joint with ``chain_force`` (seed 4.11).

    M_c xi'' + c_c = J_pr^T f_p, M_c, c_c the chain without the drone (regular at q2 = 0).
    """
    m, c = _affine_dynamics(robot.planar("none"), np.asarray(xi, float), np.asarray(xi_dot, float))
    jac = robot.planar("point").hinges[0].jacobian(np.asarray(xi, float))
    return np.linalg.solve(m, jac.T @ np.asarray(chain_force, float) - c)


def thrust_at(robot, xi, xi_dot, xi_ddot, chain_force) -> np.ndarray:
    """Thrust vector F = f_p + m_d (r'' + g e_z) of the (point-mass) drone for a chain force f_p."""
    point = robot.planar("point")
    m = np.stack([np.asarray(a, float) for a in (xi, xi_dot, xi_ddot)])[:, None, :]
    r_dd = point.hinges[0].position_jet(Jet(m)).d[2][0]
    return np.asarray(chain_force, float) + robot.drone_mass * (r_dd + np.array([0.0, point.gravity]))


# ---------------------------------------------------------------------------------------- motions
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
    from planners.optimize import _with_via_points

    points, durations, _ = _with_via_points(trajectory, trajectory.durations, n_via)
    return PiecewisePolynomial(points, durations)


def jump_weights(durations, index: int) -> np.ndarray:
    """Weights W (3, 5) with s^(5)(t-) - s^(5)(t+) = sum_jk W[j, k] points[index - 1 + j, k] (each
    coordinate) at knot ``index``: the jump of the 5th derivative there, linear in the 3 points around it
    (the segments are C4 at their knots, not C5) [1/s^(5-k)]."""
    from planners.polynomial import Segment

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
        alpha, normalisation: the objective (3.26), as in :class:`planners.problem.MotionProblem`.
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
            raise ValueError(f"free={sorted(free)}: unknown group(s) {sorted(unknown)}; use some of {GROUPS}")
        self.robot = robot
        self.points = np.array(points, dtype=float)
        self.times = np.asarray(times, dtype=float).copy()
        self.n_via = tuple(int(n) for n in n_via)
        self.index, self.travel = crossing_layout(self.n_via)
        if self.points.shape != (len(self.travel) + 1, N_DERIVS, 2):
            raise ValueError(f"points.shape={self.points.shape}, expected {(len(self.travel) + 1, N_DERIVS, 2)} "
                             f"for n_via={self.n_via}")
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
        for value, (kind, target, scale) in zip(x, self.variables):
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
                             min_thrust=min_thrust(self.robot))

    def _extra_rows(self, points, times) -> tuple[np.ndarray, list[str]]:
        """Rows beside the motion's (scaled, >= 0): travel-time bounds, the crossing speed, and the
        5th derivative continuous at the crossing (within +-:data:`JUMP_TOLERANCE` Taylor units)."""
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
    def evaluate(self, x, derivatives: bool = False) -> Evaluation:
        """J, the constraints and (optionally) their derivatives at x (cached)."""
        x = np.asarray(x, dtype=float)
        key = x.tobytes()
        if self._cache is not None and self._cache[0] == key and (self._cache[1] or not derivatives):
            return self._cache[2]
        points, times, _ = self._decode(x)
        inner = self._inner(points, times)
        ev = inner.evaluate(inner.x_of(points), derivatives)
        extra, _ = self._extra_rows(points, times)
        constraints = np.concatenate([ev.constraints, extra])
        if not derivatives:
            result = Evaluation(ev.J, ev.terms, constraints)
            self._cache = (key, False, result)
            return result
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
        result = Evaluation(ev.J, ev.terms, constraints, grad, np.vstack([jac, jac_extra]), hess)
        self._cache = (key, True, result)
        return result



# ---------------------------------------------------------------------------------------- a first guess
def _smoothstep(x):
    """The 9th-degree step: 0 -> 1 on [0, 1] with derivatives 1..4 zero at both ends (works on Jets)."""
    return x**5 * (126.0 - 420.0 * x + 540.0 * x**2 - 315.0 * x**3 + 70.0 * x**4)


def designed_motion(start, end, duration: float, crossing_angle: float, t) -> np.ndarray:
    """A smooth crossing motion built in the drone's polar coordinates, derivatives 0..6 at times t.

    The drone joint's polar angle theta = q1 + q2/2 and the elbow angle q2 are prescribed:
    q2 = c (q2_a (1 + c)/2 - q2_b (1 - c)/2), c = cos(pi S(t/T)), S the 9th-degree step, so q2
    leaves q2_a at rest, passes 0 once at T/2 and stops at q2_b; theta goes from its start to its
    end value with S and bulges to ``crossing_angle`` at T/2 (a sin^6 bump). With the chain
    nearly vertical at the crossing, gravity barely acts across it (the criterion then asks for
    little), which is what makes this a good start. Not a solution: the criterion does not hold.

    Returns:
        shape (7, N, 2): xi and its derivatives 1..6.
    """
    from fpr.model import jets

    start, end = np.asarray(start, float), np.asarray(end, float)
    x = Jet.variable(np.atleast_1d(np.asarray(t, float)), 6) / duration
    step = _smoothstep(x)
    c = jets.cos(np.pi * step)
    q2 = c * (0.5 * start[1] * (1.0 + c) - 0.5 * end[1] * (1.0 - c))
    theta_a, theta_b = start[0] + 0.5 * start[1], end[0] + 0.5 * end[1]
    bump = jets.sin(np.pi * x) ** 6
    theta = theta_a + (theta_b - theta_a) * step + (crossing_angle - 0.5 * (theta_a + theta_b)) * bump
    q1 = theta - 0.5 * q2
    return np.stack([q1.d, q2.d], axis=-1)


def first_guess(robot, start, end, duration: float, n_via, crossing_angle: float = 1.2) -> PiecewisePolynomial:
    """The :func:`designed_motion` as a crossing motion (travels of ``duration``/2, ``n_via`` via
    points each), its crossing acceleration moved onto the criterion's line (along n: the drone's
    acceleration is kept)."""
    half = 0.5 * float(duration)
    d = designed_motion(start, end, duration, crossing_angle, [half])[:, 0]
    point = np.array(d[:N_DERIVS])
    point[0, 1] = 0.0
    point[2], _ = nearest_criterion_acceleration(robot, point[0, 0], point[1], point[2])
    motion = add_via_points(crossing_motion(start, end, point, [half, half]), n_via)
    points = np.array(motion.points)
    index, _ = crossing_layout(n_via)
    for i in range(1, len(points) - 1):
        if i != index:
            points[i] = designed_motion(start, end, duration, crossing_angle, [motion.knots[i]])[:N_DERIVS, 0]
    return PiecewisePolynomial(points, motion.durations)


def count_crossings(trajectory: PiecewisePolynomial, rate: float = 2000.0) -> int:
    """How many times q2 changes sign along ``trajectory`` (sampled at ``rate`` [Hz])."""
    t = trajectory.sample_times(rate)
    q2 = trajectory.evaluate(t, order=0)[0][:, 1]
    signs = np.sign(q2[np.abs(q2) > 1e-9])
    return int(np.count_nonzero(np.diff(signs)))


# ---------------------------------------------------------------------------------------- solving
@dataclass
class CrossingOutcome:
    """A crossing motion and what it takes.

    Attributes:
        name: what produced it.
        trajectory: the motion (points laid out by :func:`crossing_layout` with ``n_via``).
        n_via: via points per travel.
        report: dense-grid :class:`planners.optimize.MotionReport` (crossing-side constraints).
        initial: the same for the motion the optimisation started from.
        stages: the NLP solves (:class:`planners.optimize.StageReport`).
        wall_time: [s].
    """

    name: str
    trajectory: PiecewisePolynomial
    n_via: tuple
    report: object
    initial: object
    stages: list = field(default_factory=list)
    wall_time: float = 0.0

    @property
    def index(self) -> int:
        """Index of the crossing point."""
        return crossing_layout(self.n_via)[0]

    @property
    def crossing_time(self) -> float:
        """When q2 = 0 [s]."""
        return float(self.trajectory.knots[self.index])

    @property
    def crossing_point(self) -> np.ndarray:
        """xi_s and its derivatives 1..4 at the crossing, (5, 2)."""
        return np.array(self.trajectory.points[self.index])

    @property
    def times(self) -> np.ndarray:
        """The two travel times [s]."""
        return travel_times(self.trajectory, self.n_via)

    def criterion_residual(self, robot) -> float:
        """n^T (M xi_s'' + c) at the crossing [N m] (4.7; 0 for a finite force)."""
        p = self.crossing_point
        return criterion(robot, p[0], p[1], p[2])

    @property
    def crossings(self) -> int:
        """Sign changes of q2 along the motion (1 wanted)."""
        return count_crossings(self.trajectory)

    @property
    def feasible(self) -> bool:
        """Every constraint holds on the dense grid, and q2 changes sign exactly once."""
        return self.report.feasible and self.crossings == 1

    def summary(self, robot) -> dict:
        """JSON-friendly numbers: peaks, crossing, constraints, stages."""
        peaks = self.report.peaks(robot)
        peaks.pop("least_singularity_margin_rad", None)
        return {
            "name": self.name,
            "feasible": self.feasible,
            "crossings": self.crossings,
            "crossing_time_s": self.crossing_time,
            "crossing_point": self.crossing_point.tolist(),
            "travel_times_s": self.times.tolist(),
            "criterion_residual_Nm": self.criterion_residual(robot),
            **peaks,
            "J_e": self.report.J_e,
            "J_phi": self.report.J_phi,
            "violated": [c.name for c in self.report.violations],
            "wall_time_s": self.wall_time,
            "stages": [vars(st) for st in self.stages],
        }


def _report(robot, trajectory, n_via, rate):
    from planners.optimize import evaluate_motion

    index, _ = crossing_layout(n_via)
    return evaluate_motion(robot, trajectory, rate, crossing_time=float(trajectory.knots[index]),
                           min_thrust=min_thrust(robot))


def _normalisation(robot, trajectory, n_via, samples, windows) -> tuple[float, float]:
    problem = CrossingProblem(robot, trajectory.points, travel_times(trajectory, n_via), n_via, (), 0.5,
                              (1.0, 1.0), samples_per_segment=samples, windows_per_segment=windows)
    terms = problem.evaluate(problem.x0()).terms
    return float(max(terms[0], 1e-9)), float(max(terms[1], 1e-9))


def _stage(robot, trajectory, n_via, free, alpha, normalisation, name, progress, samples, windows,
           max_iterations, smooth_crossing=True):
    from planners.optimize import _solve

    problem = CrossingProblem(robot, trajectory.points, travel_times(trajectory, n_via), n_via, free, alpha,
                              normalisation, samples_per_segment=samples, windows_per_segment=windows,
                              smooth_crossing=smooth_crossing)
    x, stage = _solve(problem, problem.x0(), name, progress, max_iterations, 1e-4)
    return problem.trajectory(x), stage


#: The seed's two approaches (4.2.1, 4.2.2): crossing point q1_s, velocity, how the acceleration is
#: set, and the travel times of their initial guesses.
SEED_APPROACHES = {
    1: {"q1": 1e-4, "velocity": (-1.0, 2.0), "acceleration": (-10.7243, 24.6296), "times": (0.4, 1.5)},
    2: {"q1": 1e-4, "velocity": (-3.0, 3.0), "chain_force": (0.0, 5.0), "times": (1.25, 1.2)},
}


def seed_approach(robot, approach: int, *, alpha: float = 0.5, progress=None, samples_per_segment: int = 17,
                  windows_per_segment: int = 4, max_iterations: int = 60, dense_rate: float = 500.0,
                  start=SEED_START, end=SEED_END) -> CrossingOutcome:
    """One of the seed's approaches, with this package's model, parameters and solver.

    Approach 1 (4.2.1): xi_s' = [-1, 2]; the seed's xi_s'' (4.9) does not satisfy the criterion
    with our parameters, so it is moved onto the criterion's line along n (the drone's
    acceleration kept). Approach 2 (4.2.2): xi_s' = [-3, 3] and the chain force f_p1 = [0, 5] N at
    the crossing give xi_s'' by the chain's direct dynamics (4.11). Both: q1_s = 1e-4 (4.1, q2_s = 0
    exactly here), the seed's travel times; step 1 optimises xi_s''', xi_s'''' (from 0), step 2 one
    via point per travel, J normalised by the initial guess (as the seed does).
    """
    if approach not in SEED_APPROACHES:
        raise ValueError(f"approach={approach!r}: the seed has approaches 1 and 2")
    spec = SEED_APPROACHES[approach]
    start_time = time.perf_counter()
    q1 = spec["q1"]
    velocity = np.array(spec["velocity"])
    if approach == 1:
        acceleration, _ = nearest_criterion_acceleration(robot, q1, velocity, spec["acceleration"])
    else:
        acceleration = acceleration_from_chain_force(robot, [q1, 0.0], velocity, spec["chain_force"])
    point = np.zeros((N_DERIVS, 2))
    point[0] = [q1, 0.0]
    point[1], point[2] = velocity, acceleration
    guess = crossing_motion(start, end, point, spec["times"])
    args = dict(samples=samples_per_segment, windows=windows_per_segment, max_iterations=max_iterations,
                smooth_crossing=False)  # the seed's constraints: C4 only
    normalisation = _normalisation(robot, guess, (0, 0), samples_per_segment, windows_per_segment)
    step1, stage1 = _stage(robot, guess, (0, 0), ("high",), alpha, normalisation, f"seed approach {approach}, step 1",
                           progress, **args)
    with_via = add_via_points(step1, (1, 1))
    step2, stage2 = _stage(robot, with_via, (1, 1), ("vias",), alpha, normalisation,
                           f"seed approach {approach}, step 2", progress, **args)
    return CrossingOutcome(f"seed approach {approach}", step2, (1, 1), _report(robot, step2, (1, 1), dense_rate),
                           _report(robot, guess, (0, 0), dense_rate), [stage1, stage2],
                           time.perf_counter() - start_time)


def optimise_crossing(robot, start, end, duration: float, n_via=(2, 2), *, alpha: float = 0.5,
                      starts=CROSSING_STARTS, progress=None, samples_per_segment: int = 17,
                      windows_per_segment: int = 4, max_iterations: int = 100, dense_rate: float = 500.0,
                      max_refinements: int = 2) -> CrossingOutcome:
    """Our method: everything the seed held fixed is free.

    From :func:`first_guess` (total ``duration`` [s] times ``starts[0][1]``, crossing with the drone at
    polar angle ``starts[0][0]``), one NLP frees the crossing state (q1_s, xi_s', xi_s'' on the criterion's
    line, xi_s''', xi_s''''), the via points and both travel times. As in
    :func:`planners.optimize.plan`, a result that holds on the optimisation grid but not on the
    dense grid is solved again on a grid twice as fine (at most ``max_refinements`` times). A start
    that ends infeasible is followed by the next of ``starts``; the first feasible result is
    returned, else the one with the least (relative) violation. Every solve is in ``stages``.
    """
    start_time = time.perf_counter()
    n_via = tuple(int(n) for n in n_via)
    best, best_worst, all_stages = None, -np.inf, []
    for attempt, (angle, fraction) in enumerate(starts):
        guess = first_guess(robot, start, end, fraction * duration, n_via, angle)
        normalisation = _normalisation(robot, guess, n_via, samples_per_segment, windows_per_segment)
        label = "crossing" if attempt == 0 else \
            f"crossing, start {attempt + 1} (crossing angle {angle:g} rad, {fraction * duration:g} s)"
        samples, windows = samples_per_segment, windows_per_segment
        trajectory = guess
        for refinement in range(max_refinements + 1):
            suffix = "" if refinement == 0 else f" (grid refined x{2 ** refinement})"
            trajectory, stage = _stage(robot, trajectory, n_via, GROUPS, alpha, normalisation, label + suffix,
                                       progress, samples, windows, max_iterations)
            all_stages.append(stage)
            report = _report(robot, trajectory, n_via, dense_rate)
            if report.feasible or stage.violation_end > 1e-6:
                break
            samples, windows = 2 * samples - 1, 2 * windows
        outcome = CrossingOutcome("optimised crossing", trajectory, n_via, report,
                                  _report(robot, guess, n_via, dense_rate))
        if outcome.feasible:
            best = outcome
            break
        worst = min((c.margin / FEASIBILITY_SCALE[c.unit] for c in report.violations), default=0.0)
        if best is None or worst > best_worst:
            best, best_worst = outcome, worst
    best.stages = all_stages
    best.wall_time = time.perf_counter() - start_time
    return best
