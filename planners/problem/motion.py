"""The motion-planning problem of the thesis' chapter 3, with exact derivatives.

A motion is a chain of degree-9 segments through points P (way points and via points, each
``[s, s', s'', s''', s'''']``, see :mod:`planners.trajectory.polynomial`). Given the segment durations, the
motion and its derivatives at any time are *linear* in P (the Hermite basis weights W), and
everything the planner looks at is a function of the motion at that instant only:

* the objective J = alpha J_e / J_e0 + (1 - alpha) J_phi / J_phi0 (seed 3.24-3.26), with
  J_e = integral of sum_i |F_i . r_i'| and J_phi = integral of sum_i phi_i'^2;
* the constraints, as signed margins >= 0: ground, end-effector orientation and Type-2
  singularity bounds (3.27-3.29; prototype 3.40-3.46), drone roll |phi_i| <= pi/2 - m_ga (3.33,
  3.45) and rotor speeds 0 <= w <= w_max - m_gr (3.48, applied to the FPR too).

The per-sample quantities come from :func:`fpr.model.inverse_dynamics.inverse_dynamics` (planning model:
point-mass drones for the thrusts and rolls, the exact rigid drones for the torques). Their
partial derivatives with respect to the 5 n entries of the local motion jet are exact, by forward-mode dual
numbers (:mod:`fpr.model.dual`: the value once and the 5 n directions as real tangents, each quantity carrying
only the directions it depends on). The chain rule through W then gives exact gradients with respect to P. The
complex step (Im(f(X + i h e)) / h, h = 1e-30: every function on that path is analytic) is the independent
reference the tests hold them to (:attr:`MotionProblem.derivatives`). Problems of one plan can share their nodes'
derivatives (:class:`NodeDerivatives`: the 2-step polish starts where its travels ended).

Integrals use Simpson's rule on K equally spaced nodes per segment (the optimisation grid).
Constraints are enforced on the same nodes, aggregated as the minimum over short windows
(a few nodes each) to keep the number of NLP constraints small, with a small back-off
(``CONSTRAINT_BACKOFF``) for what happens between nodes; :func:`planners.problem.report.evaluate_motion`
checks the result on a dense grid afterwards.

The absolute value in J_e is smoothed for the optimiser, |x| ~ sqrt(x^2 + eps^2) - eps with
eps = ``POWER_SMOOTHING`` (its effect on J_e is below eps times the duration per drone); every
reported J_e uses the exact absolute value.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from fpr import robots
from fpr.model.errors import PlannerArgumentError
from fpr.model.inverse_dynamics import MOTION_ORDER, MotionInputs, inverse_dynamics
from planners.problem.banded import Banded
from planners.problem.evaluation import Evaluation, NodeDerivatives, cached_evaluation
from planners.problem.sensitivities import by_complex_step, by_dual_numbers
from planners.trajectory.polynomial import N_DERIVS, PiecewisePolynomial

#: The step h of the complex step (:attr:`MotionProblem.derivatives` "complex", the reference).
COMPLEX_STEP = 1e-30
#: The settings of :attr:`MotionProblem.derivatives`.
DERIVATIVES = ("dual", "complex")
POWER_SMOOTHING = 1e-2  # [W]
POWER_CURVATURE_FLOOR = 1e-2  # [W]
# The optimiser asks every (scaled) margin to be at least this on its grid, so that what happens
# between grid nodes (a rotor-speed peak a few milliseconds off a node) stays within the limits:
# 1e-3 is 1 mm, 1 mrad, or about 0.4 rad/s at the rotor-speed limit.
CONSTRAINT_BACKOFF = 1e-3


@dataclass(frozen=True)
class Limits:
    """The bounds of the planning constraints, from the robot's margins (DESIGN.md).

    Attributes:
        roll: largest |phi_i|, pi/2 - m_ga [rad].
        speed: largest rotor speed, w_max - m_gr [rad/s].
    """

    roll: float
    speed: float

    @classmethod
    def from_robot(cls, robot) -> "Limits":
        """Limits of ``robot`` (``robot.margins``, ``robot.rotor_constants``)."""
        return cls(roll=np.pi / 2 - robot.margins.angle,
                   speed=robot.rotor_constants.max_speed - robot.margins.rotor_speed)


#: The constraint kinds every robot has: kind -> (unit, what it bounds).
GENERIC_CONSTRAINT_KINDS = {
    "rotor_speed_low": ("rad/s", "rotor speed w >= 0 (3.48)"),
    "rotor_speed_high": ("rad/s", "rotor speed w <= w_max - m_gr (3.48)"),
    "thrust_low": ("N", "thrust f_i >= f_min: the controller steers the thrust's direction, which a small "
                        "thrust makes ill-conditioned (singularity crossings, planners.crossing.solve)"),
}


class _ConstraintKinds(Mapping):
    """kind -> (unit, what it bounds): the generic kinds (:data:`GENERIC_CONSTRAINT_KINDS`) and those of every
    registered robot (``RobotKind.constraint_kinds``: its workspace's and its drones' attitude's), read from
    the registry when asked (a robot registered later adds its own).
    """

    def _table(self) -> dict:
        return {**robots.constraint_kinds(), **GENERIC_CONSTRAINT_KINDS}

    def __getitem__(self, kind):
        return self._table()[kind]

    def __iter__(self):
        return iter(self._table())

    def __len__(self):
        return len(self._table())


#: kind -> (unit, what it bounds) of every constraint a plan can have, the robots' included.
CONSTRAINT_KINDS: Mapping[str, tuple[str, str]] = _ConstraintKinds()


def workspace_kinds() -> frozenset[str]:
    """The constraint kinds of the robots' workspace margins (a function of the motion's positions alone): the
    registered robots' kinds but those of their drones' attitude.
    """
    return frozenset(robots.constraint_kinds()) - robots.attitude_kinds()


def constraint_kind(name: str) -> str:
    """The kind (key of :data:`CONSTRAINT_KINDS`) of a constraint name such as ``ground_2``."""
    table = robots.constraint_kinds()  # the same object while the registry does not change
    if _kind_of[0] is not table:
        _kind_of[:] = [table, {}]
    found = _kind_of[1].get(name)
    if found is None:
        found = next(k for k in sorted(CONSTRAINT_KINDS, key=len, reverse=True) if name.startswith(k))
        _kind_of[1][name] = found
    return found


# (the robots' constraint kinds it holds for, constraint name -> kind): constraint_kind's answers
_kind_of: list = [None, {}]


def _workspace(robot, s, crossing_sign=None) -> dict:
    """The robot kind's workspace margins of the motion's samples s (N, n_s): in the assembly mode the
    motion starts in (seed 3.46), or, with ``crossing_sign``, those of a single singularity crossing.
    """
    if crossing_sign is None:
        return robot.kind.workspace_margins(s)
    return robot.kind.crossing_margins(s, crossing_sign)


def constraint_rows(robot, motion, inputs: MotionInputs, *, scaled: bool, crossing_sign=None,
                    min_thrust: float | None = None, workspace: dict | None = None):
    """Every constraint margin at every sample (>= 0 where satisfied).

    Args:
        robot: the robot.
        motion: s and its derivatives, shape (5, N, n_s) (complex allowed).
        inputs: :func:`~fpr.model.inverse_dynamics.inverse_dynamics` of ``motion``.
        scaled: False gives natural units (m, rad, rad/s; rotor margins on the signed speed).
            True gives the smooth, O(1) rows the optimiser uses: rotor margins on w^2 / w_lim^2
            and 1 - w^2 / w_lim^2 (w^2 is smooth where the signed speed is not).
        crossing_sign: prototype crossing its Type-2 singularity once (:mod:`planners.crossing.solve`):
            per sample +1 before the crossing, -1 after it, 0 at it (N,). The assembly-mode bounds
            3.46 are then replaced by ``crossing_side`` (sign * q2 >= 0) and ``crossing_range``.
        min_thrust: f_min [N] of the ``thrust_low`` rows (scaled by m_d g), or None for none.
        workspace: the workspace margins {name: (N,)} if the caller has them (:meth:`MotionProblem._quantities`
            takes the lower of each node's and a point between nodes), or None: the robot kind's of ``motion[0]``.

    Returns:
        (rows (N, R), names (R,) of the constraint each row belongs to, details (R,) e.g. "rotor 3").
    """
    lim = Limits.from_robot(robot)
    cols, names, details = [], [], []
    if workspace is None:
        workspace = _workspace(robot, motion[0], crossing_sign)
    for name, value in workspace.items():
        cols.append(value)
        names.append(name)
        details.append("")
    attitude = robot.kind.attitude_margins(inputs, scaled)
    for i in range(robot.n_drones):
        for name, detail, margin in attitude[i]:
            cols.append(margin)
            names.append(name)
            details.append(detail)
        for m in range(4):
            if scaled:
                w2 = inputs.rotor_speed_squared[:, i, m] / lim.speed**2
                cols += [w2, 1.0 - w2]
            else:
                w = inputs.rotor_speed[:, i, m]
                cols += [w, lim.speed - w]
            names += [f"rotor_speed_low_{i + 1}", f"rotor_speed_high_{i + 1}"]
            details += [f"rotor {m + 1}"] * 2
        if min_thrust is not None:
            margin = inputs.thrust[:, i] - min_thrust
            cols.append(margin / (robot.drone_mass * float(-robot.model.gravity.linear[2])) if scaled else margin)
            names.append(f"thrust_low_{i + 1}")
            details.append("")
    return np.stack(cols, axis=-1), names, details


def between_node_minima(rows, per_segment: int, skip: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Each node's row values lowered to where they dip between the grid nodes, and where (in node spacings).

    A row (a constraint margin along the motion) may dip between two nodes below both: the rotor speeds of a
    fast travel peak a few milliseconds off a node. The parabola through a node's and its two neighbours'
    values (equally spaced, one segment) has its vertex at tau = -a1 / a2 spacings from the node
    (a1 = (c+ - c-) / 2, a2 = c- - 2 c + c+); where it curves upwards (a2 > 0) and its vertex is nearer this
    node than the neighbours (|tau| <= 1/2; up to 1 for the segment's second and second-last node, which
    cover the intervals at its ends), the node's value becomes the vertex's, c + a1 tau + a2 tau^2 / 2. The
    estimate is exact for quadratics, derived from the nodes alone; the rows' derivatives follow by the
    Lagrange weights at tau (:meth:`MotionProblem._row_derivatives`).

    Args:
        rows: the rows at the nodes, (m * per_segment, R), segment by segment.
        per_segment: nodes per segment (>= 3).
        skip: how many of the first columns are left as they are (rows with their own between-node rule).

    Returns:
        (the rows lowered (m * per_segment, R), tau (m * per_segment, R), 0 where not lowered).
    """
    n, r = rows.shape
    c = rows.reshape(-1, per_segment, r)
    before, node, after = c[:, :-2], c[:, 1:-1], c[:, 2:]
    a1, a2 = 0.5 * (after - before), before - 2.0 * node + after
    reach = np.full((per_segment - 2, 1), 0.5)
    low, high = -reach.copy(), reach.copy()
    low[0], high[-1] = -1.0, 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.where(a2 > 0.0, -a1 / np.where(a2 > 0.0, a2, 1.0), 0.0)
    tau = np.where((tau >= low) & (tau <= high), tau, 0.0)
    tau[..., :skip] = 0.0
    out, where = c.copy(), np.zeros_like(c)
    out[:, 1:-1] = node + tau * (a1 + 0.5 * a2 * tau)
    where[:, 1:-1] = tau
    return out.reshape(n, r), where.reshape(n, r)


def _chain_basis(sensitivities, basis_by_node) -> np.ndarray:
    """d q / d (the entries of a node's segment's two points) from d q / d (the node's motion jet).

    ``sensitivities`` (N, Q, r, j): d q_i / d X[r, i, j] (r the derivative order, j the coordinate);
    ``basis_by_node`` (N, r, 2 * 5): the Hermite weights. Returns (N, Q, 2, 5, j), the same sum over r as
    ``einsum("iqrj,risk->iqskj")``, as one batched matrix product (a few times faster than einsum's loop).
    """
    n, q, r, j = sensitivities.shape
    out = np.matmul(sensitivities.transpose(0, 1, 3, 2).reshape(n, q * j, r), basis_by_node)  # (N, Q j, 2 * 5)
    return out.reshape(n, q, j, 2, -1).transpose(0, 1, 3, 4, 2)


def _integrands(power, rate_squared, smoothing: float) -> np.ndarray:
    """[sum_i |P_i|, sum_i |w_i|^2] per sample from the drone powers F_i . r_i' and the squares of the drones'
    angular speeds (N, n_d) (phi_i'^2 for a planar robot's).
    """
    if smoothing > 0:
        power = np.sqrt(power * power + smoothing**2) - smoothing
    else:
        power = np.abs(power)
    return np.stack([power.sum(-1), rate_squared.sum(-1)], axis=-1)


def objective_rates(inputs: MotionInputs, smoothing: float = 0.0) -> np.ndarray:
    """Integrands of J_e and J_phi at every sample, shape (N, 2) [W, rad^2/s^2].

    ``smoothing`` > 0 replaces |x| by sqrt(x^2 + eps^2) - eps (analytic, complex-step safe).
    """
    power = np.sum(inputs.thrust_vector * inputs.joint_velocity, axis=-1)  # (N, n_d)
    return _integrands(power, inputs.attitude_rate_squared, smoothing)


def point_time_scales(durations) -> np.ndarray:
    """T_p of every point (m+1,): the mean duration of the segments that meet at it [s]."""
    d = np.asarray(durations, dtype=float)
    t_point = np.empty(d.size + 1)
    t_point[0], t_point[-1] = d[0], d[-1]
    t_point[1:-1] = 0.5 * (d[:-1] + d[1:])
    return t_point


def entry_scales(durations) -> np.ndarray:
    """k! / T_p^k for derivative order k of point p, shape (m+1, 5): one unit of a decision variable
    is one Taylor coefficient of s in units of the local time scale T_p (:func:`point_time_scales`).
    """
    orders = np.arange(N_DERIVS)
    factorial = np.cumprod(np.maximum(orders, 1))  # k!
    return factorial * point_time_scales(durations)[:, None] ** -orders


def simpson_weights(count: int, duration: float) -> np.ndarray:
    """Simpson's rule weights on ``count`` (odd, >= 3) equally spaced nodes over ``duration``."""
    if count < 3 or count % 2 == 0:
        raise PlannerArgumentError("count", count,
                                   f"count={count}: Simpson's rule needs an odd number of nodes >= 3")
    w = np.ones(count)
    w[1:-1:2], w[2:-1:2] = 4.0, 2.0
    return w * duration / (3.0 * (count - 1))


class MotionProblem:
    """J and the constraints of a piecewise motion as functions of its free point entries.

    The decision vector x holds the free entries of ``points`` (mask ``free``), each scaled by the
    local time scale: entry k (derivative order) of point p is x * k! / T_p^k, T_p the mean duration
    of the segments that meet at p (the Taylor coefficient of s in units of T_p), so that every entry
    of x moves the motion by about as much.

    Args:
        robot: the robot.
        points: template points (m+1, 5, n): fixed entries are kept, free ones replaced by x.
        durations: segment durations (m,) [s].
        free: boolean mask (m+1, 5, n) of the entries that x sets.
        alpha: energy weight in [0, 1].
        normalisation: (J_e0, J_phi0) [J, rad^2/s], the stop-at-every-way-point values (3.26).
        samples_per_segment: odd number of grid nodes per segment (ends included).
        windows_per_segment: constraint windows per segment (min over each window's nodes).
        crossing: index of the point where the prototype crosses its Type-2 singularity (q2 = 0
            there, :mod:`planners.crossing.solve`), or None. The motion is then evaluated with derivatives
            0..6 (:data:`fpr.model.inverse_dynamics.MOTION_ORDER`) and the assembly-mode bounds become the
            crossing's side constraints.
        min_thrust: a lower bound f_min [N] on every drone's thrust (``thrust_low``), or None.
        dips: the dynamic rows (rotor speeds, rolls, thrust) take their dips between the nodes
            (:func:`between_node_minima`): the way-point methods' and the crossing's NLPs, on grids fine enough
            for a parabola through three nodes to follow a row (the replanner's coarse grids keep the nodes'
            values). The workspace rows take their values half a spacing after each node either way.
    """

    #: How :meth:`_node_derivatives` differentiates: "dual" (forward-mode dual numbers, :mod:`fpr.model.dual`:
    #: the value once, the directions as real tangents; every plan) or "complex" (the complex step, the
    #: independent reference the tests hold the dual numbers to). Measured on seeded families of random missions
    #: of both robots (32 way points, whole plans), the complex step paid nowhere: dual numbers were as fast on the
    #: single travels of step 2 (tens of nodes) and faster on the whole missions (0.6x per evaluation of the FPR's,
    #: 0.85x of the prototype's; documentation: guides/planning-internals).
    derivatives = "dual"

    def __init__(self, robot, points, durations, free, alpha: float, normalisation,
                 samples_per_segment: int = 17, windows_per_segment: int = 4, crossing: int | None = None,
                 min_thrust: float | None = None, dips: bool = False):
        self.robot = robot
        self.node_store: NodeDerivatives | None = None  # (share_node_derivatives)
        self._store_owner = None
        self.points = np.array(points, dtype=float)
        self.durations = np.asarray(durations, dtype=float)
        self.free = np.asarray(free, dtype=bool)
        self.alpha = float(alpha)
        self.normalisation = tuple(float(v) for v in normalisation)
        if min(self.normalisation) <= 0:
            raise PlannerArgumentError("normalisation", self.normalisation,
                                       f"normalisation={self.normalisation}: J_e0 and J_phi0 must be > 0")
        m, _, n = self.points.shape
        m -= 1
        k = int(samples_per_segment)
        self.samples_per_segment = k
        tau = np.linspace(0.0, 1.0, k)
        knots = np.concatenate([[0.0], np.cumsum(self.durations)])
        self.t = (knots[:-1, None] + tau[None, :] * self.durations[:, None]).reshape(-1)
        self.t[k - 1::k] = knots[1:]  # segment ends exactly on the knots
        self.segment = np.repeat(np.arange(m), k)
        self.weights = np.concatenate([simpson_weights(k, d) for d in self.durations])
        # Hermite weights, evaluated segment by segment so every node uses its own segment
        shape = PiecewisePolynomial(np.zeros((m + 1, N_DERIVS, 1)), self.durations)
        self.order = N_DERIVS - 1 if crossing is None else MOTION_ORDER
        w = np.empty((self.order + 1, m * k, 2, N_DERIVS))
        for i, seg in enumerate(shape.segments):
            w[:, i * k:(i + 1) * k] = seg.basis(tau * seg.duration, order=self.order)
        self.basis = w
        self.crossing_sign = None
        self.min_thrust = min_thrust
        self.dips = bool(dips)
        if crossing is not None:
            if not 0 < int(crossing) < m:
                raise PlannerArgumentError("crossing", crossing,
                                           f"crossing={crossing}: must be an interior point index (1..{m - 1})")
            sign = np.where(self.segment < int(crossing), 1.0, -1.0)
            sign[int(crossing) * k - 1] = sign[int(crossing) * k] = 0.0  # both sides of the crossing knot
            self.crossing_sign = sign
        # windows: contiguous node ranges inside each segment
        bounds = np.linspace(0, k - 1, int(windows_per_segment) + 1).round().astype(int)
        self.windows = [(i * k + a, i * k + b + 1)
                        for i in range(m) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        # variable scaling by the local time scale
        scale = entry_scales(self.durations)[:, :, None] * np.ones((1, 1, n))
        self.scale = scale[self.free]
        self.n_x = int(self.free.sum())
        # the x index of every entry of the points (flat, in the order of points.reshape(-1)), -1 if fixed
        self._column = np.full(self.points.size, -1)
        self._column[np.flatnonzero(self.free.reshape(-1))] = np.arange(self.n_x)
        # the windows as one index array (W, L) when they have one length (the usual grids), else None
        lengths = {b - a for a, b in self.windows}
        self._window_index = (np.array([a for a, _ in self.windows])[:, None] + np.arange(lengths.pop())
                              if len(lengths) == 1 else None)
        self._cache: tuple[bytes, bool, Evaluation] | None = None
        #: set by the composite SQP (:mod:`planners.optimisation.sqp`): evaluations with derivatives then also give the
        #: powers, their derivatives and J_phi's Gauss-Newton matrix (``Evaluation.power``...)
        self.power_model = False
        self._rows_names: list[str] | None = None

    def share_node_derivatives(self, store: NodeDerivatives) -> None:
        """Share the nodes' derivatives with the other problems of ``store`` (:class:`NodeDerivatives`), which
        must be of the same robot and grid: an evaluation with derivatives keeps its nodes' numbers there, and
        takes a motion's from there when every segment is in it. Only this class's own evaluation shares
        (not a subclass's, whose quantities may depend on more than the motion), without a crossing or a
        thrust bound.
        """
        self.node_store, self._store_owner = store, store.owner()

    # ------------------------------------------------------------------ x <-> points
    def points_of(self, x) -> np.ndarray:
        """Points (m+1, 5, n) with the free entries set from x."""
        p = self.points.copy()
        p[self.free] = np.asarray(x, dtype=float) * self.scale
        return p

    def x_of(self, points) -> np.ndarray:
        """The decision vector of given points."""
        return np.asarray(points, dtype=float)[self.free] / self.scale

    def motion(self, points) -> np.ndarray:
        """s and its derivatives 0..4 at the grid nodes, shape (5, N, n)."""
        gathered = np.asarray(points)[self.segment[:, None] + np.arange(2)]  # (N, 2, 5, n)
        return np.einsum("risk,iskn->rin", self.basis, gathered)

    @property
    def constraint_names(self) -> list[str]:
        """Constraint name of each NLP constraint (windows are the slow index)."""
        if self._rows_names is None:
            self.evaluate(self.x_of(self.points))
        return [name for _ in self.windows for name in self._rows_names]

    # ------------------------------------------------------------------ evaluation
    def _inputs(self, motion) -> MotionInputs:
        """The inverse-dynamics inputs of ``motion`` (5, N, n): the hook a problem with external forces
        overrides (:class:`planners.problem.disturbance.DisturbedProblem`); here the free flight.
        """
        return inverse_dynamics(self.robot, motion)

    @property
    def _half_step_columns(self) -> int:
        """How many of the rows' first columns (the workspace margins) hold their value half a spacing after
        each node already (:meth:`_between_nodes`; none for a crossing).
        """
        if self.crossing_sign is not None:
            return 0
        if self._rows_names is None:
            self.evaluate(self.x_of(self.points))
        kinds = workspace_kinds()
        return sum(1 for name in self._rows_names if constraint_kind(name) in kinds)

    def _quantities(self, motion):
        """Raw integrand pieces (N, n_d + n_d k_w): [F_i . r_i' ..., the drones' angular velocity components ...]
        (a planar robot's roll rates phi_i', k_w = 1), and the rows.
        """
        inputs = self._inputs(motion)
        power = np.sum(inputs.thrust_vector * inputs.joint_velocity, axis=-1)
        sign = workspace = None
        if self.crossing_sign is not None:  # motion may hold several perturbed copies of the nodes
            sign = np.tile(self.crossing_sign, motion.shape[1] // self.crossing_sign.size)
        else:
            workspace = self._between_nodes(motion)
        rows, names, _ = constraint_rows(self.robot, motion, inputs, scaled=True, crossing_sign=sign,
                                         min_thrust=self.min_thrust, workspace=workspace)
        self._rows_names = names
        rates = inputs.angular_velocity
        return np.concatenate([power, rates.reshape(rates.shape[0], -1)], axis=-1), rows

    def _between_nodes(self, motion) -> dict:
        """The workspace margins of the nodes, each the lower of a node's and half a spacing after it.

        The workspace margins depend on s alone, which is cheap to evaluate: s half a spacing h after a
        node is its Taylor polynomial there, sum_k s^(k) (h/2)^k / k! (the motion is C4 across knots).
        Near the optimum a motion pushes against its workspace bounds, and a degree-9 motion dips
        between nodes by about h^2 |s''| / 8 (2 mrad on the square's phi bound, more than the back-off):
        the midpoints catch it on the optimisation grid instead of the dense check (and its grid refinement).
        Nodes and midpoints go through the robot kind's margins in one call.
        """
        powers = self._half_step_powers(motion.shape[1] // self.t.size)
        mid = motion[0] * powers[0]  # sum_k s^(k) (h/2)^k / k!, term by term in order (the bits of a plain sum)
        for k in range(1, N_DERIVS):
            term = motion[k] * powers[k]
            term /= math.factorial(k)
            mid += term
        margins = self.robot.kind.workspace_margins(np.concatenate([motion[0], mid]))
        n = motion.shape[1]
        # complex values (complex-step derivatives) compare by their real parts first
        return {name: np.where(col[n:].real < col[:n].real, col[n:], col[:n]) for name, col in margins.items()}

    def _half_step_powers(self, copies: int) -> list:
        """(h/2)^k, k = 0..4, of every node (h its segment's node spacing), tiled for ``copies`` copies of the
        nodes: (N copies, 1) each, computed once per copy count.
        """
        cache = self.__dict__.setdefault("_half_steps", {})
        if copies not in cache:
            step = np.tile(0.5 * self.durations[self.segment] / (self.samples_per_segment - 1), copies)[:, None]
            cache[copies] = [step**k for k in range(N_DERIVS)]
        return cache[copies]

    def _weights(self):
        return self.alpha / self.normalisation[0], (1.0 - self.alpha) / self.normalisation[1]

    @cached_evaluation
    def evaluate(self, x, derivatives: bool = False) -> Evaluation:
        """J, the constraints and (optionally) their exact derivatives at x (cached)."""
        points = self.points_of(x)
        motion = self.motion(points)
        n_r, n_s, n = motion.shape
        a_e, a_phi = self._weights()
        if not derivatives:
            raw, rows = self._quantities(motion)
            grad = hess = None
        else:
            raw, rows, sens_raw, sens_rows = self._node_derivatives(points, motion)
            local = _chain_basis(sens_raw, self._basis_by_node).reshape(n_s, raw.shape[1], -1)
            n_d = self.robot.n_drones  # raw holds [powers..., angular velocity components...]
            power, rate = raw[:, :n_d], raw[:, n_d:]
            smooth = np.sqrt(power * power + POWER_SMOOTHING**2)
            # J = sum_i w_i (a_e sum_d |P_id|_eps + a_phi sum_d rate_id^2)
            dj = self.weights[:, None] * np.concatenate([a_e * power / smooth, 2 * a_phi * rate], axis=1)
            # Gauss-Newton / reweighted least-squares curvature: 2 a_phi w grad(rate) grad(rate)^T, and
            # a_e w grad(P) grad(P)^T / |P|_eps (the curvature of the quadratic that majorises |P| at P)
            curv = self.weights[:, None] * np.concatenate([a_e / np.maximum(smooth, POWER_CURVATURE_FLOOR),
                                                          2 * a_phi * np.ones_like(rate)], axis=1)
            g_local = np.einsum("iq,iqv->iv", dj, local)  # (N, 2 * 5 * n)
            size = self.points.size
            index = (self.segment[:, None] * (N_DERIVS * n) + np.arange(2 * N_DERIVS * n)).reshape(n_s, -1)
            g_points = np.bincount(index.reshape(-1), g_local.reshape(-1), minlength=size)
            free = np.flatnonzero(self.free.reshape(-1))
            grad = g_points[free] * self.scale
            hess = self._assemble(curv, local)
            if self.power_model:
                # J_phi's part alone (the composite SQP models J_e's |P| piecewise linearly instead)
                rate_local = local[:, n_d:]
                rate_hess = self._assemble((2 * a_phi * self.weights)[:, None] * np.ones(rate_local.shape[1]),
                                           rate_local)
                # the powers' derivatives with respect to x: (N n_d, n_x)
                power_local = local[:, :n_d]
                p_sparse = self._scatter(np.repeat(index, n_d, axis=0), power_local.reshape(n_s * n_d, -1))
                p_weight = np.repeat(a_e * self.weights, n_d)

                def power_gram(weight, power_local=power_local):
                    return self._assemble(np.asarray(weight, dtype=float).reshape(n_s, n_d), power_local)
        n_d = self.robot.n_drones
        terms = self.weights @ _integrands(raw[:, :n_d], raw[:, n_d:] ** 2, POWER_SMOOTHING)
        value = float(a_e * terms[0] + a_phi * terms[1])
        if self.dips:
            rows, tau = between_node_minima(rows, self.samples_per_segment, self._half_step_columns)
        else:
            tau = np.zeros_like(rows)
        if self._window_index is not None:  # every window at once: the first node of each window's minimum
            arg = self._window_index[:, 0, None] + np.argmin(rows[self._window_index], axis=1)  # (W, R)
            constraints = np.take_along_axis(rows, arg, axis=0).reshape(-1) - CONSTRAINT_BACKOFF
            picks = list(arg)
        else:
            mins, picks = [], []
            for a, b in self.windows:
                arg = a + np.argmin(rows[a:b], axis=0)  # (R,)
                mins.append(rows[arg, np.arange(rows.shape[1])])
                picks.append(arg)
            constraints = np.concatenate(mins) - CONSTRAINT_BACKOFF
        if derivatives:
            sample = np.concatenate(picks)  # (W R,)
            column = np.tile(np.arange(rows.shape[1]), len(self.windows))
            row_local = self._row_derivatives(sens_rows, sample, column, tau[sample, column])
            width = 2 * N_DERIVS * n  # the entries of a segment's two points, in the points' flat order
            entries = self.segment[sample][:, None] * (N_DERIVS * n) + np.arange(width)
            jac_sparse = self._scatter(entries, row_local.reshape(sample.size, width))
        if not derivatives:
            return Evaluation(value, terms, constraints)
        if not self.power_model:
            return Evaluation(value, terms, constraints, grad, None, hess, jacobian_sparse=jac_sparse)
        return Evaluation(value, terms, constraints, grad, None, hess, power.reshape(-1), p_weight, None, rate_hess,
                          jac_sparse, p_sparse, power_gram)

    def _row_derivatives(self, sens_rows, sample, column, tau) -> np.ndarray:
        """d (row ``column`` at node ``sample``, its value between nodes :func:`between_node_minima`) / d (the
        entries of the node's segment's two points), (K, 2 * 5 * n): the Lagrange weights at tau of the node's
        and its neighbours' derivatives (the value is the interpolating parabola's, the weights its
        derivatives with respect to the three nodes' values).
        """
        basis = self._basis_by_node
        local = _chain_basis(sens_rows[sample, column][:, None], basis[sample])[:, 0]
        bent = np.flatnonzero(tau)
        if bent.size:
            t = tau[bent].reshape((-1,) + (1,) * (local.ndim - 1))
            local[bent] *= 1.0 - t * t
            for offset, weight in ((-1, 0.5 * t * (t - 1.0)), (1, 0.5 * t * (t + 1.0))):
                node = sample[bent] + offset  # the same segment: tau is 0 at a segment's first and last node
                local[bent] += weight * _chain_basis(sens_rows[node, column[bent]][:, None], basis[node])[:, 0]
        return local

    def _node_derivatives(self, points, motion):
        """Every node's quantities and their sensitivities to its motion jet (:attr:`derivatives`, module docstring):
        (raw (N, Q), rows (N, R), d raw / d X (N, Q, r, j), d rows / d X (N, R, r, j)), X[r, i, j] the r-th
        derivative of coordinate j at node i; from ``node_store`` when it holds every segment.
        """
        store = self.node_store if (type(self) is MotionProblem and self.crossing_sign is None
                                    and self.min_thrust is None) else None
        k = self.samples_per_segment
        if store is not None:
            found = store.get(points, self.durations, k)
            if found is not None:
                self._rows_names = found[0][4]
                return tuple(np.concatenate([f[a] for f in found]) for a in range(4))
        if self._dual_derivatives(motion):
            raw, rows, sens_raw, sens_rows = by_dual_numbers(self._quantities, motion)
        else:
            raw, rows, sens_raw, sens_rows = by_complex_step(self._quantities, motion, COMPLEX_STEP)
        if store is not None:
            names = self._rows_names
            store.put(self._store_owner, points, self.durations, k,
                      [(raw[a:a + k], rows[a:a + k], sens_raw[a:a + k], sens_rows[a:a + k], names)
                       for a in range(0, motion.shape[1], k)])
        return raw, rows, sens_raw, sens_rows

    def _dual_derivatives(self, motion) -> bool:
        """Whether :meth:`_node_derivatives` takes dual numbers (:attr:`derivatives`) at this motion: not with
        "complex", nor for a complex motion (a caller's own complex step through the problem).
        """
        if self.derivatives not in DERIVATIVES:
            raise PlannerArgumentError("derivatives", self.derivatives, f"derivatives = {self.derivatives!r}: "
                                       f"give {' or '.join(map(repr, DERIVATIVES))}")
        return self.derivatives == "dual" and not np.iscomplexobj(motion)

    def _scatter(self, entries, values) -> sparse.csr_matrix:
        """The (rows, n_x) derivatives with respect to x of rows whose derivatives with respect to the
        points' flat entries ``entries`` (rows, w) are ``values`` (rows, w): the free entries, scaled, as a CSR
        matrix (each row touches one segment's two points: its dense array would be mostly zeros).
        """
        cols = self._column[entries]
        hit = cols >= 0
        row, col = np.nonzero(hit)
        col = cols[row, col]
        value = values[hit] * self.scale[col]
        # row by row, columns increasing (a row's entries are its segment's, in the points' order): the CSR
        # arrays directly, without scipy's conversion from coordinates
        indptr = np.concatenate([[0], np.cumsum(hit.sum(axis=1))])
        return sparse.csr_matrix((value, col, indptr), shape=(entries.shape[0], self.n_x))

    def _assemble(self, curvature, local) -> Banded:
        """Sum over nodes i and quantities q of c_iq grad q_i grad q_i^T, for the free entries in x's scaling.

        ``curvature`` c (N, Q) >= 0 and ``local`` (N, Q, 10 n): the derivatives of node i's quantities
        with respect to the entries of the two points of its segment. A segment's nodes share those
        entries: each segment's block is one product (its nodes' rows weighted by sqrt(c)), added at
        its two points into the band (:class:`~planners.problem.banded.Banded`: x holds the points in order,
        so the sum couples neighbouring points only).
        """
        m = self.durations.size
        width = local.shape[-1]
        rows = (np.sqrt(curvature)[..., None] * local).reshape(m, -1, width)
        blocks = np.matmul(rows.transpose(0, 2, 1), rows)  # (m, 10 n, 10 n)
        hit, flat, scales, bandwidth = self._assembly_pattern
        return Banded.scatter(blocks[hit] * scales, flat, self.n_x, bandwidth)

    @functools.cached_property
    def _basis_by_node(self) -> np.ndarray:
        """The Hermite weights node by node, (N, r, 2 * 5) (r: the derivative orders of ``basis``):
        :func:`_chain_basis`'s layout of ``basis``.
        """
        b = self.basis
        return np.ascontiguousarray(b.transpose(1, 0, 2, 3).reshape(b.shape[1], b.shape[0], -1))

    @functools.cached_property
    def _assembly_pattern(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """What :meth:`_assemble` scatters by, the same at every evaluation: the entries of the segments'
        blocks (m, 10 n, 10 n) that are free in both indices and on or above the diagonal, their flat index in
        the band, their scales' products, and the band's width (the largest x-index distance of two entries of
        one segment).
        """
        cols = self._segment_columns  # (m, 10 n), -1 where fixed
        both = (cols[:, :, None] >= 0) & (cols[:, None, :] >= 0)
        bandwidth = int(np.max(np.abs(cols[:, :, None] - cols[:, None, :])[both], initial=0))
        hit = both & (cols[:, :, None] <= cols[:, None, :])
        rows = np.broadcast_to(cols[:, :, None], hit.shape)[hit]
        columns = np.broadcast_to(cols[:, None, :], hit.shape)[hit]
        flat = Banded.flat_index(rows, columns, self.n_x, bandwidth)
        return hit, flat, self.scale[rows] * self.scale[columns], bandwidth

    @functools.cached_property
    def _segment_columns(self) -> np.ndarray:
        """The x index of each entry of each segment's two points (m, 10 n), -1 where fixed."""
        half = N_DERIVS * self.points.shape[2]
        start = np.arange(self.durations.size)[:, None] * half
        return self._column[start + np.arange(2 * half)]

    def objective_terms(self, points) -> np.ndarray:
        """[J_e, J_phi] of given points on the grid (smoothed |.|, as the optimiser sees them)."""
        inputs = self._inputs(self.motion(points))
        return self.weights @ objective_rates(inputs, POWER_SMOOTHING)

