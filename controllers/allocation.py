r"""Rotor allocation of the drones as a box-constrained QP solved by ProxQP (seed 2.13, 2.24, 3.10, 3.31).

The inner loop wants the attitude accelerations u_a (psi'', theta'', roll'' of each drone for the
FPR; psi'', theta'', phi1'' for the prototype) and the outer loop wants the thrusts f_d. With the
attitude model (2.13)

.. math:: \ddot q_a = A_\tau \tau + M_{inv,a} (J_f^T f - c)

and each drone's rotor map [f_i; tau_i] = R_f,i w_i^2 (3.10), the allocation chooses the squared
rotor speeds z = w^2 of all drones:

.. math:: \min_z \tfrac12 \|W_a (A_\tau S_\tau z + M_{inv,a} J_f^T S_f z - M_{inv,a} c - u_a)\|^2
          + \tfrac12 \|W_f (S_f z - f_d)\|^2 + \tfrac{\varepsilon}2 \|S_\tau z\|^2
          \quad \text{s.t.}\; 0 \le z \le w_{max}^2.

N_tau = I - A_tau^+ A_tau projects on the torques that do not change the attitude accelerations
(the FPR's A_tau is 4 x 6: two such directions; the prototype's is square and N_tau = 0). Without
active bounds the first two terms vanish at the thesis' law (2.24), f = f_d and
tau = A_tau^+ (u_a + M_inv,a c - M_inv,a J_f^T f_d), whose torque has no component along N_tau:
that law is then *the* minimiser, to the solver's accuracy. Penalising only the null-space
component (rather than all of tau with a tiny weight) keeps the QP well conditioned. With bounds active the QP
returns the closest command the rotors can produce in the weighted sense (W_a = 1 per rad/s^2 and W_f = 1 per N by
default, so that one rotor's full range weighs about 30 times more on the attitude rows: a drone that cannot hold
its attitude loses its thrust direction anyway), and says which rotors are at a bound. ProxQP solves for
z / w_max^2 in [0, 1], which keeps the problem well scaled.

:func:`allocation_qp` builds the QP matrices (testable without a solver); :class:`Allocator`
holds one ProxQP workspace, built once and warm-started at every call.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import lapack

from controllers.box_qp import AT_LOWER, AT_UPPER, FREE, solve_box_qp_state
from fpr import _native as native
from fpr.model.qp import proxsuite_module

_posv = lapack.dposv


#: the routes of the compiled tick's answer, by its route number
_ROUTE_NAMES = ("closed form", "active set")


@dataclass(frozen=True)
class AllocationResult:
    """One allocation.

    Attributes:
        speeds_squared: w^2 of every rotor, shape (n_d, 4) [(rad/s)^2], within the bounds.
        thrust: f of each drone, shape (n_d,) [N].
        torque: body torques, shape (n_d, 3) [N m].
        saturated: rotors at a bound (within 1e-6 of it), shape (n_d, 4) bool.
        iterations: linear solves of the active-set route (or ProxQP iterations), 0 when the closed form (no
            bound active) was used.
        attitude_error: achieved minus wanted attitude accelerations, shape (n_a,) [rad/s^2] (computed when
            first read: the control loop does not read it).
        thrust_error: achieved minus wanted thrusts, shape (n_d,) [N] (same).
    """

    speeds_squared: np.ndarray
    thrust: np.ndarray
    torque: np.ndarray
    saturated: np.ndarray
    iterations: int
    attitude: object = field(default=None, repr=False, compare=False)
    thrust_desired: np.ndarray | None = field(default=None, repr=False, compare=False)
    attitude_desired: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def any_saturated(self) -> bool:
        """Whether a rotor bound is active."""
        return bool(self.saturated.any())

    @property
    def attitude_error(self) -> np.ndarray:
        """Achieved minus wanted attitude accelerations, shape (n_a,) [rad/s^2] (seed 2.13)."""
        achieved = self.attitude.attitude_acceleration(self.thrust, self.torque)
        return achieved - np.asarray(self.attitude_desired, dtype=float)

    @property
    def thrust_error(self) -> np.ndarray:
        """Achieved minus wanted thrusts, shape (n_d,) [N]."""
        return self.thrust - np.asarray(self.thrust_desired, dtype=float)


def _result(speeds_squared, thrust, torque, saturated, iterations, attitude, attitude_desired,
            thrust_desired=None) -> AllocationResult:
    """An :class:`AllocationResult` without the frozen dataclass' ``__init__`` (one ``object.__setattr__``
    per field, about twice the cost on the control loop's path); the same object, fields filled directly.
    ``thrust_desired`` defaults to ``thrust`` (the closed form reaches it).
    """
    result = object.__new__(AllocationResult)
    result.__dict__.update(speeds_squared=speeds_squared, thrust=thrust, torque=torque, saturated=saturated,
                           iterations=iterations, attitude=attitude,
                           thrust_desired=thrust if thrust_desired is None else thrust_desired,
                           attitude_desired=attitude_desired)
    return result


def selectors(robot) -> tuple[np.ndarray, np.ndarray]:
    """S_f (n_d, 4 n_d) and S_tau (3 n_d, 4 n_d): thrusts and torques from all w^2 (R_f of each drone)."""
    n_d = robot.n_drones
    s_f = np.zeros((n_d, 4 * n_d))
    s_tau = np.zeros((3 * n_d, 4 * n_d))
    for i, rotor in enumerate(robot.rotors):
        mix = rotor.mixing_matrix  # [f, tau_x, tau_y, tau_z] = mix @ w^2
        s_f[i, 4 * i:4 * i + 4] = mix[0]
        s_tau[3 * i:3 * i + 3, 4 * i:4 * i + 4] = mix[1:]
    return s_f, s_tau


def allocation_qp(attitude, s_f, s_tau, thrust_desired, attitude_desired, attitude_weight, thrust_weight,
                  regularisation):
    """H and g of the allocation QP (module docstring) for one state.

    Args:
        attitude: the :class:`fpr.model.robot.AttitudeModel` at the measured state.
        s_f: S_f, the thrusts from all w^2, shape (n_d, 4 n_d) [N/(rad/s)^2] (:func:`selectors`).
        s_tau: S_tau, the torques from all w^2, shape (3 n_d, 4 n_d) [N m/(rad/s)^2] (:func:`selectors`).
        thrust_desired: f_d, shape (n_d,) [N].
        attitude_desired: u_a, shape (n_a,) [rad/s^2].
        attitude_weight: W_a diagonal, shape (n_a,) or scalar [1/(rad/s^2)].
        thrust_weight: W_f diagonal, shape (n_d,) or scalar [1/N].
        regularisation: epsilon, weight of the torque component along N_tau [1/(N m)^2].

    Returns:
        (H, g): the objective 0.5 z^T H z + g^T z (+ const).
    """
    r = np.asarray(attitude_desired, dtype=float)
    w_a = np.broadcast_to(np.asarray(attitude_weight, dtype=float), r.shape)
    w_f = np.broadcast_to(np.asarray(thrust_weight, dtype=float), (s_f.shape[0],))
    w_s_f = w_f[:, None] * s_f
    return _allocation_qp(attitude, s_f, s_tau, np.asarray(thrust_desired, dtype=float), r, w_a, w_f, w_s_f,
                          w_s_f.T @ w_s_f, regularisation)


def _allocation_qp(attitude, s_f, s_tau, thrust_desired, attitude_desired, w_a, w_f, w_s_f, thrust_gram,
                   regularisation):
    """:func:`allocation_qp` without its argument conversions, its constant terms given (per-tick path).

    W_a, W_f as vectors (w_a, w_f), w_s_f = W_f S_f and thrust_gram = (W_f S_f)^T (W_f S_f).
    """
    a_tau = attitude.a_tau
    a = a_tau @ s_tau + attitude.m_inv_a @ attitude.j_f.T @ s_f  # d qdd_a / d z
    # N_tau = I - A^+ A. With A = A_tau of full row rank, A^+ = A^T (A A^T)^-1: a Cholesky solve of the
    # (n_a, n_a) A A^T instead of pinv's SVD (the same projector to round-off, several times cheaper).
    x, info = _posv(a_tau @ a_tau.T, a_tau)[1:]
    row_space = a_tau.T @ x if info == 0 else np.linalg.pinv(a_tau) @ a_tau  # A^+ A (rank deficient: pinv)
    reg = (_identity(s_tau.shape[0]) - row_space) @ s_tau
    r = attitude_desired + attitude.m_inv_a @ attitude.c
    wa = w_a[:, None] * a
    ra = w_a * r
    h = wa.T @ wa + thrust_gram + regularisation * reg.T @ reg
    g = -(wa.T @ ra + w_s_f.T @ (w_f * thrust_desired))
    return 0.5 * (h + h.T), g


@functools.lru_cache(maxsize=8)
def _identity(n: int) -> np.ndarray:
    """np.eye(n), built once per size (read only)."""
    eye = np.eye(n)
    eye.flags.writeable = False
    return eye


def pseudo_inverse_law(attitude, thrust_desired, attitude_desired) -> np.ndarray:
    """The thesis' torques (2.24): tau = A_tau^+ (u_a + M_inv,a c - M_inv,a J_f^T f), shape (n_d, 3)."""
    rhs = np.asarray(attitude_desired, dtype=float) + attitude.m_inv_a @ (
        attitude.c - attitude.j_f.T @ np.asarray(thrust_desired, dtype=float))
    return (np.linalg.pinv(attitude.a_tau) @ rhs).reshape(-1, 3)


class Allocator:
    """The allocation QP of one controller, solved at every control tick.

    :meth:`solve` takes one of two routes:

    1. **No bound active** (the usual tick): the minimiser is the thesis' law (2.24), f = f_d and
       tau = A_tau^+ (u_a + M_inv,a (c - J_f^T f_d)) (module docstring), mapped to w^2 by each drone's
       R_f^-1; A_tau^+ = A_tau^T (A_tau A_tau^T)^-1 by one Cholesky solve. When every w^2 lies within
       [0, w_max^2] this is the QP's solution exactly (the objective is 0 there, its least value, and H is
       positive definite), so no QP is built or solved.
    2. **A bound active**: H and g are built (:meth:`_lean_qp`, the constant terms computed once) and the box
       QP is solved exactly by an active-set method (:func:`controllers.box_qp.solve_box_qp_state`),
       warm-started from the previous tick's active bounds (or, after a tick without, from the bounds the law
       crosses): usually one solve, in plain Python for up to two free rotors. Thrusts and torques come from
       one product, the saturation mask is one read-only array per pattern met. A tick after one with a bound
       active comes here directly, without trying the closed form: the method releases the bounds that no longer
       bind (its minimiser is then the law's).
    3. Should the active-set method cycle (not seen on the reference missions), ProxQP: one dense workspace,
       initialised at its first use, then updated (H, g only) and solved warm from its previous result.

    Small arrays: each numpy call costs about a microsecond or more, ``a.dot(b)`` about half of ``a @ b``;
    the code counts its calls. Routes 1 and 2 also exist natively (``fpr/_native/alloc.c``, :mod:`fpr._native`'s
    part ``allocation``, the same computation in C, a few microseconds per call): used when the part is on
    when the allocator is made. When it declines (A_tau A_tau^T singular, the active-set method
    cycled, an input not finite) the Python path decides that tick, ProxQP included.

    Args:
        robot: the robot (rotor maps and limits).
        attitude_weight: W_a (module docstring), scalar or (n_a,).
        thrust_weight: W_f, scalar or (n_d,).
        regularisation: epsilon, picks the least-norm torque (the pseudo-inverse's) [1/(N m)^2].
        max_speed: upper rotor speed bound [rad/s] (default: the robot's w_max).

    Attributes:
        qp: the ProxQP workspace of route 3 (``proxsuite.proxqp.dense.QP``), built and initialised at its
            first use (None before: proxsuite is imported only then).
        compiled: whether the native tick is used (read only).
        routes: how many calls took each route, {"closed form": n, "active set": n, "proxqp": n}.
    """

    def __init__(self, robot, attitude_weight=1.0, thrust_weight=1.0, regularisation: float = 100.0,
                 max_speed: float | None = None):
        self.robot = robot
        self.s_f, self.s_tau = selectors(robot)
        self.n = self.s_f.shape[1]
        n_d = robot.n_drones
        self._weights = (attitude_weight, thrust_weight)
        self._regularisation = float(regularisation)
        speed = robot.rotor_constants.max_speed if max_speed is None else float(max_speed)
        self.upper = np.full(self.n, speed**2)
        self.lower = np.zeros(self.n)
        self.scale = speed**2  # the bounded routes solve for zeta = z / w_max^2 in [0, 1]: well scaled
        self._tol = 1e-6 * self.scale  # a rotor within this of a bound is reported saturated
        self._constants()  # also inv_f, inv_tau: z = inv_f f + inv_tau tau, w^2 of every drone's (f, tau)
        self._unsaturated = np.zeros((n_d, 4), dtype=bool)
        self._unsaturated.flags.writeable = False
        self._n_d = n_d
        self._saturation_arrays = {}  # read-only (n_d, 4) masks of the bounded route, by pattern
        self.qp = None  # route 3's ProxQP workspace, built at its first use (:meth:`_proxqp`)
        self.routes = {"closed form": 0, "active set": 0, "proxqp": 0}
        self._active = None  # the active bounds of the previous tick (a box_qp state), when it had some
        # the same for the compiled tick (which updates it in place): FREE everywhere when none
        self._state = np.zeros(self.n, dtype=np.int8)
        self._bit_masks = {}  # the compiled tick's saturation masks, by its bit pattern
        self._kernel = self._resolve_kernel()

    def _resolve_kernel(self):
        """The native tick for this allocator (:mod:`fpr._native`'s part ``allocation``), or None for the Python
        path (the part off or not built, or the robot larger than the tick's fixed sizes).
        """
        module = native.use("allocation")
        fits = module is not None and self.n <= module.MAX_ROTORS and self._w_a.size <= module.MAX_ATTITUDE \
            and self.robot.nq <= module.MAX_COORDINATES
        return module.tick if fits else None

    @property
    def compiled(self) -> bool:
        """Whether :meth:`solve` uses the native tick (``fpr/_native/alloc.c``)."""
        return self._kernel is not None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_kernel"] = None  # an extension's function: resolved again where it is unpickled
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._kernel = self._resolve_kernel()
        self._handover(to_compiled=self._kernel is not None)

    def _handover(self, to_compiled: bool) -> None:
        """Move the previous tick's active bounds to the representation of the path that runs next (the Python
        path's tuple ``_active`` or the compiled tick's array ``_state``).
        """
        if to_compiled:
            if self._active is not None:
                self._state[:] = self._active
            self._active = None
        else:
            if self._state.any():
                self._active = tuple(self._state.tolist())
            self._state[:] = 0

    @property
    def regularisation(self) -> float:
        """epsilon [1/(N m)^2]."""
        return self._regularisation

    @regularisation.setter
    def regularisation(self, value):
        self._regularisation = float(value)
        self._constants()

    @property
    def attitude_weight(self):
        """W_a, scalar or (n_a,)."""
        return self._weights[0]

    @attitude_weight.setter
    def attitude_weight(self, value):
        self._weights = (value, self._weights[1])
        self._constants()

    @property
    def thrust_weight(self):
        """W_f, scalar or (n_d,)."""
        return self._weights[1]

    @thrust_weight.setter
    def thrust_weight(self, value):
        self._weights = (self._weights[0], value)
        self._constants()

    def _constants(self) -> None:
        """The QP terms that do not change between calls: the weights as vectors, W_f S_f, its Gram matrix."""
        attitude_weight, thrust_weight = self._weights
        n_a = len(self.robot.layout.attitude)
        self._w_a = np.broadcast_to(np.asarray(attitude_weight, dtype=float), (n_a,))
        self._w_f = np.broadcast_to(np.asarray(thrust_weight, dtype=float), (self.s_f.shape[0],))
        self._w_s_f = self._w_f[:, None] * self.s_f
        self._thrust_gram = self._w_s_f.T @ self._w_s_f
        # the constant part of H, and W_f^2 S_f^T (g's thrust term), for the bounded path (_lean_qp)
        # all scaled to zeta = z / w_max^2 once here: S_f and S_tau times w_max^2 (so are A and B), H's constant
        # part times w_max^4 and g's thrust term's matrix times -w_max^2
        scale = self.scale
        self._h_constant = (self._thrust_gram + self.regularisation * self.s_tau.T @ self.s_tau) * scale**2
        self._thrust_g = -scale * (self._w_s_f.T * self._w_f)
        self._scaled_s_f, self._scaled_s_tau = scale * self.s_f, scale * self.s_tau
        self._unit_attitude_weight = bool(np.all(self._w_a == 1.0))
        # [f; tau] of all drones from zeta in one product (the bounded route's result)
        self._scaled_wrench = np.vstack([self._scaled_s_f, self._scaled_s_tau])
        # the compiled tick's constants, one vector (the layout of fpr/_native/alloc.c's header comment)
        n_d = self.s_f.shape[0]
        inverse = np.zeros((self.n, 4 * n_d))
        for i, rotor in enumerate(self.robot.rotors):
            inverse[4 * i:4 * i + 4, 4 * i:4 * i + 4] = rotor.inverse_mixing_matrix
        self._inv_f = np.ascontiguousarray(inverse[:, 0::4])
        self._inv_tau = np.ascontiguousarray(np.delete(inverse, np.s_[0::4], axis=1))
        header = [n_d, n_a, scale, self._tol, self._regularisation, float(self._unit_attitude_weight)]
        self._kernel_constants = np.concatenate(
            [header] + [np.ravel(x) for x in (self._w_a, self._inv_f, self._inv_tau, self._scaled_s_f,
                                              self._scaled_s_tau, self._h_constant, self._thrust_g)])

    def build(self, attitude, thrust_desired, attitude_desired):
        """(H, g) at this state (see :func:`allocation_qp`)."""
        return _allocation_qp(attitude, self.s_f, self.s_tau, np.asarray(thrust_desired, dtype=float),
                              np.asarray(attitude_desired, dtype=float), self._w_a, self._w_f, self._w_s_f,
                              self._thrust_gram, self.regularisation)

    def solve(self, attitude, thrust_desired, attitude_desired) -> AllocationResult:
        """Allocate the rotor speeds for wanted thrusts f_d (n_d,) [N] and attitude accelerations u_a (n_a,)
        [rad/s^2] at the state of ``attitude`` (:class:`fpr.model.robot.AttitudeModel`).
        """
        tick = self._kernel
        if tick is None:
            return self._solve_python(attitude, thrust_desired, attitude_desired)
        found = tick(attitude.m_inv_a, attitude.j_f, attitude.a_tau, attitude.c, thrust_desired,
                     attitude_desired, self._kernel_constants, self._state)
        if found is None:  # declined (class docstring): the Python path decides this tick
            self._handover(to_compiled=False)
            try:
                return self._solve_python(attitude, thrust_desired, attitude_desired)
            finally:
                self._handover(to_compiled=True)
        route, iterations, z, thrust, torque, bits = found
        self.routes[_ROUTE_NAMES[route]] += 1
        if bits:
            saturated = self._bit_masks.get(bits)
            if saturated is None:
                saturated = np.array([bool(bits >> i & 1) for i in range(self.n)]).reshape(-1, 4)
                saturated.flags.writeable = False
                self._bit_masks[bits] = saturated
        else:
            saturated = self._unsaturated
        return _result(z, thrust, torque, saturated, iterations, attitude, attitude_desired, thrust_desired)

    def _solve_python(self, attitude, thrust_desired, attitude_desired) -> AllocationResult:
        """:meth:`solve` in Python (numpy, LAPACK, ProxQP): the reference of the compiled tick."""
        f_d = np.asarray(thrust_desired, dtype=float)
        u_a = np.asarray(attitude_desired, dtype=float)
        a_tau = attitude.a_tau
        gram = a_tau.dot(a_tau.T)
        if self._active is not None:  # the previous tick had a bound active: most likely this one too
            return self._bounded(attitude, f_d, u_a, gram, None)
        x, info = _posv(gram, u_a + attitude.m_inv_a.dot(attitude.c - attitude.j_f.T.dot(f_d)))[1:]
        if info != 0:  # A_tau rank deficient (never on these robots): the QP decides
            return self._bounded(attitude, f_d, u_a, None, None)
        tau = a_tau.T.dot(x)
        z = self._inv_f.dot(f_d) + self._inv_tau.dot(tau)
        values = z.tolist()
        lowest, highest = min(values), max(values)
        if lowest >= 0.0 and highest <= self.scale:  # the law is feasible: it is the QP's minimiser
            self.routes["closed form"] += 1
            saturated = (self._unsaturated if lowest > self._tol and highest < self.scale - self._tol
                         else self._saturation(z))
            return _result(z.reshape(-1, 4), f_d, tau.reshape(-1, 3), saturated, 0, attitude, u_a)
        return self._bounded(attitude, f_d, u_a, gram, values)

    def _saturation(self, z) -> np.ndarray:
        """Rotors within 1e-6 w_max^2 of a bound, shape (n_d, 4)."""
        return ((z <= self.lower + self._tol) | (z >= self.upper - self._tol)).reshape(-1, 4)

    def _lean_qp(self, attitude, f_d, u_a, gram):
        """(H, g) of :meth:`build`, scaled to zeta = z / w_max^2 (H w_max^4, g w_max^2), in fewer array calls.

        With B = A_tau S_tau, the regularisation's
        S_tau^T N_tau S_tau = S_tau^T S_tau - B^T (A_tau A_tau^T)^-1 B
        (N_tau = I - A_tau^T (A_tau A_tau^T)^-1 A_tau, symmetric and idempotent); the constant terms are
        computed once (:meth:`_constants`). Equal to :meth:`build` to round-off (tested); symmetric to round-off
        (the Cholesky solves read its upper triangle; ProxQP gets 0.5 (H + H^T)).
        """
        m_inv_a = attitude.m_inv_a
        b = attitude.a_tau.dot(self._scaled_s_tau)  # B w_max^2 (the constants are scaled: _constants)
        a = b + m_inv_a.dot(attitude.j_f.T).dot(self._scaled_s_f)  # d qdd_a / d zeta
        _, x, info = _posv(gram, b)
        if info != 0:  # A_tau rank deficient: the general builder (pinv)
            h, g = self.build(attitude, f_d, u_a)
            return h * self.scale**2, g * self.scale
        r = u_a + m_inv_a.dot(attitude.c)
        if not self._unit_attitude_weight:
            a, r = a * self._w_a[:, None], self._w_a * r
        a_t = a.T
        h = a_t.dot(a)
        h += self._h_constant
        h -= self._regularisation * b.T.dot(x)
        return h, self._thrust_g.dot(f_d) - a_t.dot(r)

    def _bounded(self, attitude, f_d, u_a, gram, law) -> AllocationResult:
        """Routes 2 and 3 (class docstring).

        ``gram``: A_tau A_tau^T, or None when it is singular; ``law``: the law's w^2 as a list, or None.
        """
        if gram is None:
            h, g = self.build(attitude, f_d, u_a)
            h, g = h * self.scale**2, g * self.scale
        else:
            h, g = self._lean_qp(attitude, f_d, u_a, gram)
        if self._active is not None:
            state = self._active
        elif law is not None:
            scale = self.scale
            state = tuple([AT_LOWER if w < 0.0 else AT_UPPER if w > scale else FREE for w in law])
        else:
            state = (FREE,) * self.n
        found = solve_box_qp_state(h, g, state)
        if found is not None:
            values, state, iterations = found
            self._active = state if AT_LOWER in state or AT_UPPER in state else None
            self.routes["active set"] += 1
            zeta = np.array(values)  # within [0, 1] (solve_box_qp_state): z within the bounds
        else:
            zeta, iterations = self._proxqp(0.5 * (h + h.T), g)
            self._active = None
            self.routes["proxqp"] += 1
            zeta = np.minimum(np.maximum(zeta, 0.0), 1.0)  # np.clip, cheaper
            values = zeta.tolist()
        wrench = self._scaled_wrench.dot(zeta)  # [f; tau] of every drone
        n_d = self._n_d
        return _result((zeta * self.scale).reshape(-1, 4), wrench[:n_d], wrench[n_d:].reshape(-1, 3),
                       self._saturated(values), iterations, attitude, u_a, f_d)

    def _saturated(self, zeta) -> np.ndarray:
        """Rotors within 1e-6 w_max^2 of a bound (as :meth:`_saturation`), from zeta = z / w_max^2 (n floats), shape
        (n_d, 4): one read-only array per pattern, built at its first use.
        """
        low, high = self._tol / self.scale, 1.0 - self._tol / self.scale
        key = tuple([w <= low or w >= high for w in zeta])
        mask = self._saturation_arrays.get(key)
        if mask is None:
            mask = self._saturation_arrays[key] = np.array(key).reshape(-1, 4)
            mask.flags.writeable = False
        return mask

    def _proxqp(self, h, g):
        """Route 3: the scaled QP by the warm-started ProxQP workspace; (zeta, iterations)."""
        if self.qp is None:
            proxqp = proxsuite_module().proxqp  # the portable build (fpr.model.qp), loaded at the first use
            self.qp = proxqp.dense.QP(self.n, 0, 0, True)
            self.qp.settings.eps_abs = 1e-9
            self.qp.settings.eps_rel = 0.0
            self.qp.settings.verbose = False
            self.qp.init(h, g, None, None, None, None, None, self.lower / self.scale, self.upper / self.scale)
            self.qp.solve()
            # only once a result exists (ProxQP 0.8 crashes warm-starting from nothing)
            self.qp.settings.initial_guess = proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
        else:
            self.qp.update(H=h, g=g, update_preconditioner=False)
            self.qp.solve()
        return np.asarray(self.qp.results.x), int(self.qp.results.info.iter)
