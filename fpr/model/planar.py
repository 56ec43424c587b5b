r"""Closed-form, vectorised dynamics of the robots in their plane of motion.

The planner evaluates the dynamics at thousands of samples per iteration; this module gives the
in-plane model (x = psi = theta = 0) in closed form with numpy, batched over samples, and along a
motion with all its time derivatives (:mod:`fpr.model.jets`). Its numbers are not typed in: bodies,
masses, centres of mass, inertias and joint placements are read from the Pinocchio model of the
URDF (:class:`fpr.model.robot.Robot`), and the tests check it against Pinocchio's CRBA / RNEA.

Every point of the planar chain is written as

.. math:: p(q) = S q + \sum_k \mathrm{Rot}(a_k^T q + b_k)\, v_k,

with Rot the rotation of the (y, z) plane, S a selector of the end-effector position (FPR) and
a_k rows of joint-angle sums; each body is such a point (its centre of mass) with a mass, an
angle a^T q + b and a moment of inertia about x. Then

.. math::
    M = \sum_b m_b J_b^T J_b + I_b a_b a_b^T, \qquad
    c = \sum_b m_b J_b^T (\dot J_b \dot q - g),\qquad
    \dot J_b \dot q = -\sum_k \mathrm{Rot}(a_k^T q + b_k) v_k (a_k^T \dot q)^2.

The batched methods of :class:`PlanarModel` evaluate these sums as products of the features of the chain's
distinct angles (:mod:`fpr.model.stacked`, one sine-cosine table per batch); :class:`PlanarPoint` keeps the
per-point formulation, the reference the tests hold them to.

Coordinates: FPR ``[y z phi q21 phi1 phi2]`` (rigid drones) or ``[y z phi q21]`` (point-mass or
massless drones); prototype ``[q1 q2 phi1]`` or ``[q1 q2]``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from fpr.model import jets
from fpr.model.errors import RobotDefinitionError
from fpr.model.jets import Jet
from fpr.model.stacked import StackedDynamics


def _rotate(c, s, v):
    """Rot(theta) v for cos/sin arrays (..., K) and vectors (K, 2) -> components (..., K) each."""
    return v[:, 0] * c - v[:, 1] * s, v[:, 0] * s + v[:, 1] * c


@dataclass(frozen=True)
class PlanarPoint:
    """A point of the chain, p(q) = S q + sum_k Rot(a_k.q + b_k) v_k.

    Attributes:
        selector: S, shape (2, n).
        rows: a_k, shape (K, n).
        offsets: b_k, shape (K,) [rad].
        vectors: v_k, shape (K, 2) [m].
    """

    selector: np.ndarray
    rows: np.ndarray
    offsets: np.ndarray
    vectors: np.ndarray

    def _rotated(self, q):
        """Components (y, z) of each Rot(a_k.q + b_k) v_k, each of shape (..., K)."""
        th = jets.inexact(q) @ self.rows.T + self.offsets
        sin, cos = jets.sin_cos_value(th)
        return _rotate(cos, sin, self.vectors)

    def position(self, q) -> np.ndarray:
        """p(q), shape (..., 2) [m]."""
        y, z = self._rotated(q)
        return np.stack([y.sum(-1), z.sum(-1)], axis=-1) + jets.inexact(q) @ self.selector.T

    def jacobian(self, q) -> np.ndarray:
        """dp/dq, shape (..., 2, n)."""
        return self._jacobian_of(*self._rotated(q))

    def _jacobian_of(self, y, z):
        # d/dtheta Rot(theta) v = Rot(theta + pi/2) v = (-z, y)
        return np.stack([-z @ self.rows, y @ self.rows], axis=-2) + self.selector

    def bias(self, q, v) -> np.ndarray:
        """dJ/dt qdot = -sum_k Rot(theta_k) v_k (a_k . qdot)^2, shape (..., 2) [m/s^2]."""
        return self._bias_of(v, *self._rotated(q))

    def _bias_of(self, v, y, z):
        w2 = (jets.inexact(v) @ self.rows.T) ** 2
        return -np.stack([(y * w2).sum(-1), (z * w2).sum(-1)], axis=-1)

    def jacobian_and_bias(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`jacobian` and :meth:`bias` from one evaluation of the rotations."""
        y, z = self._rotated(q)
        return self._jacobian_of(y, z), self._bias_of(v, y, z)

    def _rotated_jet(self, q: Jet):
        # several points share their angles (a body's centre and the hinge on it): sin and cos once per motion
        cache, key = q.shared_cache(), ("sincos", self.rows.tobytes(), self.rows.shape, self.offsets.tobytes())
        hit = cache.get(key)
        if hit is None or hit[0].order < q.order:
            d = q.d @ self.rows.T
            d[0] = d[0] + self.offsets
            hit = cache[key] = jets.sincos(Jet(d))
        s, c = hit
        if s.order > q.order:
            s, c = s.truncate(q.order), c.truncate(q.order)
        return _rotate(c, s, self.vectors)

    def _position_from(self, q: Jet, y: Jet, z: Jet) -> Jet:
        return jets.stack([y.sum(-1), z.sum(-1)], axis=-1) + Jet(q.d @ self.selector.T)

    def _jacobian_from(self, y: Jet, z: Jet) -> Jet:
        return jets.matmul(jets.stack([-z, y], axis=-2), self.rows) + self.selector

    def position_jet(self, q: Jet) -> Jet:
        """p(q(t)) with its time derivatives, for a motion q given as a Jet of shape (..., n)."""
        return self._position_from(q, *self._rotated_jet(q))

    def jacobian_jet(self, q: Jet) -> Jet:
        """dp/dq along the motion, Jet of shape (..., 2, n)."""
        return self._jacobian_from(*self._rotated_jet(q))

    def position_and_jacobian_jet(self, q: Jet, jacobian_order: int) -> tuple[Jet, Jet]:
        """Both :meth:`position_jet` (order of q) and :meth:`jacobian_jet` (truncated to
        ``jacobian_order``) from one evaluation of the rotations.
        """
        y, z = self._rotated_jet(q)
        return self._position_from(q, y, z), self._jacobian_from(y.truncate(jacobian_order), z.truncate(jacobian_order))


@dataclass(frozen=True)
class PlanarBody:
    """A rigid body moving in the plane.

    Attributes:
        name: the Pinocchio joint that carries it.
        mass: [kg].
        inertia: moment of inertia about the x axis through its centre of mass [kg m^2].
        com: its centre of mass.
        angle_row: a, its angle is a.q + angle_offset.
        angle_offset: [rad].
    """

    name: str
    mass: float
    inertia: float
    com: PlanarPoint
    angle_row: np.ndarray
    angle_offset: float


class PlanarModel:
    """In-plane dynamics of a :class:`~fpr.model.robot.Robot`, closed form and batched.

    Build it with :meth:`from_robot`. Arrays take a trailing coordinate axis and any batch shape.

    Attributes:
        coordinates: names of the planar coordinates.
        bodies: the rigid bodies with mass.
        hinges: the drone joints r_i (where the drones hold the chain).
        drone_centres: the drones' centres of mass (same as hinges for point-mass drones).
        drone_angles: angle row of each drone's roll (zero rows for point-mass / massless drones).
        gravity: g [m/s^2], along -z.
    """

    def __init__(self, coordinates, bodies, hinges, drone_centres, drone_angles, gravity):
        self.coordinates = tuple(coordinates)
        self.bodies = tuple(bodies)
        self.hinges = tuple(hinges)
        self.drone_centres = tuple(drone_centres)
        self.drone_angles = tuple(drone_angles)
        self.gravity = float(gravity)
        self._g = np.array([0.0, -self.gravity])

    @property
    def n(self) -> int:
        """Number of planar coordinates."""
        return len(self.coordinates)

    @classmethod
    def from_robot(cls, robot, drones: str = "rigid") -> "PlanarModel":
        """Read the planar model off a robot's Pinocchio model.

        Args:
            robot: a :class:`~fpr.model.robot.Robot`.
            drones: "rigid" (drones are rigid bodies; their rolls are coordinates), "point"
                (point masses at their joints: the seed's planning model) or "none" (massless).
        """
        source = robot if drones == "rigid" else robot.with_drones_as(drones)
        model = source.model
        n_pin = model.nq
        frames = {0: (np.zeros((2, n_pin)), [], np.zeros(n_pin), 0.0)}  # selector, terms, angle row, offset
        for j in range(1, model.njoints):
            sel, terms, row, off = frames[model.parents[j]]
            placement = model.jointPlacements[j]
            rot = placement.rotation
            t = placement.translation
            if abs(t[0]) > 1e-12 or not np.allclose(rot[0], [1, 0, 0], atol=1e-12):
                raise RobotDefinitionError(robot.name, f"joint {model.names[j]} is not placed in the plane x = 0 "
                                                       "about x: the planar model needs the chain in the (y, z) plane")
            terms = list(terms)
            if np.any(np.abs(t[1:]) > 0):
                terms.append((row.copy(), off, t[1:].copy()))
            off = off + np.arctan2(rot[2, 1], rot[1, 1])
            row = row.copy()
            sel = sel.copy()
            kind = model.joints[j].shortname()
            iq = model.joints[j].idx_q
            if kind == "JointModelComposite":  # the Euler root: x y z psi theta phi
                sel[0, iq + 1] = sel[1, iq + 2] = 1.0
                row[iq + 5] = 1.0
            elif kind == "JointModelRX":
                row[iq] = 1.0
            elif kind not in ("JointModelRY", "JointModelRZ", "JointModelPX"):
                raise RobotDefinitionError(robot.name, f"joint {model.names[j]} of kind {kind} is not handled by the "
                                                       "planar model: use revolute joints about x (and the Euler root)")
            frames[j] = (sel, terms, row, off)

        keep = robot.planar_indices(rolls=drones == "rigid")
        names = [robot.layout.coordinates[i] for i in keep]
        to_planar = robot.T[:, keep]  # q_pin = T q, restricted to the planar coordinates
        others = np.setdiff1d(np.arange(robot.nq), keep)

        def point(sel, terms, extra=None):
            items = list(terms) + ([extra] if extra is not None else [])
            rows = np.array([r for r, _, _ in items]).reshape(-1, n_pin)
            for a in (sel, rows):
                if np.any(np.abs(a @ robot.T[:, others]) > 1e-12):
                    raise RobotDefinitionError(robot.name, "the planar model depends on a coordinate outside the "
                                                           "plane: check the layout's chain and rolls")
            return PlanarPoint(
                selector=sel @ to_planar,
                rows=rows @ to_planar,
                offsets=np.array([o for _, o, _ in items], dtype=float),
                vectors=np.array([v for _, _, v in items], dtype=float).reshape(-1, 2),
            )

        bodies = []
        for j in range(1, model.njoints):
            inertia = model.inertias[j]
            if inertia.mass <= 0:
                continue
            sel, terms, row, off = frames[j]
            lever = inertia.lever
            com_term = (row, off, lever[1:].copy()) if np.any(np.abs(lever[1:]) > 0) else None
            bodies.append(PlanarBody(model.names[j], float(inertia.mass), float(inertia.inertia[0, 0]),
                                     point(sel, terms, com_term), row @ to_planar, float(off)))
        hinges, centres, angles = [], [], []
        for jid, fid in zip(robot.hinge_joint_ids, robot.drone_frame_ids, strict=True):
            sel, terms, row, off = frames[jid]
            hinges.append(point(sel, terms))
            centre = model.frames[fid].placement.translation
            centres.append(point(sel, terms, (row, off, centre[1:].copy())) if drones == "rigid" else hinges[-1])
            angles.append(row @ to_planar if drones == "rigid" else np.zeros(len(keep)))
        return cls(names, bodies, hinges, centres, angles, float(-model.gravity.linear[2]))

    # ------------------------------------------------------------------ pointwise (batched) model
    @functools.cached_property
    def stacked(self) -> StackedDynamics:
        """The bodies, drone centres and hinges as one :class:`~fpr.model.stacked.StackedDynamics` (one table
        of sines and cosines per batch, M and c as matrix products): what the methods below evaluate.
        """
        return StackedDynamics(self)

    def mass_matrix(self, q) -> np.ndarray:
        """M(q), shape (..., n, n)."""
        return self.stacked.mass_matrix_from(self.stacked.points.features(q))

    def bias(self, q, v) -> np.ndarray:
        """c(q, qdot): Coriolis, centrifugal and gravity terms, shape (..., n)."""
        return self.stacked.bias_from(self.stacked.points.features(q), v)

    def mass_matrix_and_bias(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        """M(q) and c(q, qdot) together, from one table of sines and cosines."""
        features = self.stacked.points.features(q)
        return self.stacked.mass_matrix_from(features), self.stacked.bias_from(features, v)

    def dynamics_and_centre_jacobians(self, q, v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """M(q), c(q, qdot) and the Jacobians of the :attr:`drone_centres` as one array (..., n_d, 2, n), from
        one table of sines and cosines.
        """
        st = self.stacked
        features = st.points.features(q)
        return (st.mass_matrix_from(features), st.bias_from(features, v),
                st.points.jacobians_from(features, "centres"))

    def inverse_dynamics(self, q, v, a) -> np.ndarray:
        """Generalised force M a + c, shape (..., n)."""
        m, c = self.mass_matrix_and_bias(q, v)
        return np.einsum("...ij,...j->...i", m, jets.inexact(a)) + c

    def hinge_jacobian(self, q) -> np.ndarray:
        """d[r_1; ...; r_nd]/dq, shape (..., 2 n_d, n) (J_p of seed 2.6, J_pr of 3.35)."""
        return np.concatenate([h.jacobian(q) for h in self.hinges], axis=-2)

    def energy(self, q, v) -> np.ndarray:
        """Kinetic plus potential energy (zero at z = 0), shape (...) [J]."""
        q = jets.inexact(q)
        kinetic = 0.5 * np.einsum("...i,...ij,...j->...", v, self.mass_matrix(q), v)
        potential = sum(b.mass * self.gravity * b.com.position(q)[..., 1] for b in self.bodies)
        return kinetic + potential

    # ------------------------------------------------------------------ along a motion
    def inverse_dynamics_jet(self, q: Jet) -> Jet:
        """Generalised force M(q) qddot + c(q, qdot) along a motion, with its time derivatives.

        Args:
            q: the motion, a Jet of order K >= 2 and shape (..., n).

        Returns:
            a Jet of order K - 2 and shape (..., n).
        """
        k = q.order - 2
        st = self.stacked
        features = st.points.features_jet(q.truncate(k))
        inertial = jets.matmul(st.mass_matrix_from(features), Jet(q.d[2:, ..., None]))[..., 0]
        return inertial + st.bias_from(features, Jet(q.d[1:k + 2]))

    def hinge_jacobian_jet(self, q: Jet) -> Jet:
        """The hinge Jacobian along a motion, Jet of shape (..., 2 n_d, n)."""
        st = self.stacked
        jac = st.points.jacobians_from(st.points.features_jet(q), "hinges")
        return jac.reshape(jac.shape[:-3] + (-1, self.n))

    def hinge_positions_jet(self, q: Jet) -> Jet:
        """The hinges' positions along a motion, Jet of shape (..., n_d, 2) (same order as q)."""
        st = self.stacked
        return st.points.positions_from(q, st.points.features_jet(q), "hinges")


def planar_configuration(robot, q) -> np.ndarray:
    """Planar coordinates [chain..., drone rolls...] taken out of a full configuration (..., n)."""
    return np.asarray(q, dtype=float)[..., robot.planar_indices()]


__all__ = ["PlanarBody", "PlanarModel", "PlanarPoint", "planar_configuration"]
