"""The robots as free-flying quadrotors closed by the passive chain: Pinocchio constraint dynamics.

This is the second, independent formulation of the dynamics and the plant of the simulator. It is
built from the same rigid bodies as the minimal model (inertias and joint placements are read from
the :class:`~fpr.model.robot.Robot`'s Pinocchio model), but with another tree and a loop closure.
Which tree and which closure is the robot kind's (``robot.kind.closed_chain``, e.g.
:mod:`fpr.robots.fpr`: drone 2 held on link 2 by two point constraints; :mod:`fpr.robots.prototype`: the
chain's end held at the fixed point by a ball joint); this module holds what every robot shares:
the free-flying drones (:func:`add_free_drone`), the joints reversed from the minimal model, the
state maps and the constraint dynamics.

Each free flyer's frame is the drone's hinge frame (drone axes, at the joint), so the free-flyer
velocity is the drone body twist there. Closure drift is held by Baumgarte stabilisation.

:meth:`ClosedChainModel.from_minimal` maps a state of the minimal model onto the closed chain;
:meth:`ClosedChainModel.to_minimal` is its inverse (how the simulator's controller "measures" the
plant). Angles read from rotations are only known modulo 2 pi: ``to_minimal`` takes a reference
configuration (e.g. the previous measurement) and returns every angle within pi of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from fpr import _native as native
from fpr.model.errors import check_shape

_posv = lapack.dposv


def wrap_angle(a):
    """Angle(s) mapped to [-pi, pi) [rad]."""
    return np.mod(np.asarray(a, dtype=float) + np.pi, 2 * np.pi) - np.pi


def euler_zyx(rotation, reference=None) -> np.ndarray:
    """Z-Y-X Euler angles [psi, theta, phi] of R = Rz(psi) Ry(theta) Rx(phi) [rad].

    Of the two solutions (theta in [-pi/2, pi/2] and (psi + pi, pi - theta, phi + pi)) the first is
    returned, or, given a ``reference`` [psi, theta, phi], the one closer to it modulo 2 pi.
    """
    phi, theta, psi = pin.rpy.matrixToRpy(rotation).tolist()
    if reference is None:
        return np.array([psi, theta, phi])
    # the two candidates' squared distances to the reference (angles wrapped), on floats: to_minimal runs
    # at every simulator tick, where each numpy call on three numbers costs microseconds
    r0, r1, r2 = reference.tolist() if isinstance(reference, np.ndarray) else reference
    pi, two_pi = math.pi, _TWO_PI
    first = ((psi - r0 + pi) % two_pi - pi) ** 2 + ((theta - r1 + pi) % two_pi - pi) ** 2 \
        + ((phi - r2 + pi) % two_pi - pi) ** 2
    second = ((psi + pi - r0 + pi) % two_pi - pi) ** 2 + ((pi - theta - r1 + pi) % two_pi - pi) ** 2 \
        + ((phi + pi - r2 + pi) % two_pi - pi) ** 2
    return np.array([psi + pi, pi - theta, phi + pi] if second < first else [psi, theta, phi])


_TWO_PI = 2 * math.pi


@dataclass
class ClosureTree:
    """What a robot kind adds to the closed-chain model (``kind.closed_chain``).

    Attributes:
        constraints: the loop-closure constraints (pin.StdVec_RigidConstraintModel).
        freeflyer_ids: joint of each drone's free flyer (:func:`add_free_drone`), in drone order.
        frame_ids: frame of each drone's centre of mass, in drone order.
        reversed_ids: ``{joint of the closed chain: (joint of the minimal model, sign)}``: the closed
            chain's joint angle is sign times the minimal model's.
        placed_freeflyers: ``(joint of the closed chain, joint of the minimal model)`` of each free flyer other
            than the drones' whose frame is that minimal joint's frame (e.g. a floating platform that carries
            the chain: its placement and body twist are the minimal joint's).
    """

    constraints: object
    freeflyer_ids: tuple
    frame_ids: tuple
    reversed_ids: dict
    placed_freeflyers: tuple = ()


@dataclass
class ClosedChainModel:
    """Pinocchio model of the robot as a tree of free-flying drones with loop-closure constraints.

    Attributes:
        robot: the minimal-coordinate robot it was built from.
        model: the Pinocchio tree.
        data: its data.
        constraints: the closure constraints (pin.StdVec_RigidConstraintModel).
        constraint_datas: their datas.
        drone_frame_ids: frames at the drones' centres of mass (where thrust and torques act).
        settings: proximal solver settings of pin.constraintDynamics.
        placed_freeflyers: the free flyers other than the drones' placed as a minimal joint's frame
            (:class:`ClosureTree`).
    """

    robot: object
    model: pin.Model
    data: pin.Data
    constraints: object
    constraint_datas: object
    drone_frame_ids: tuple
    freeflyer_ids: tuple
    reversed_ids: dict
    settings: pin.ProximalSettings
    placed_freeflyers: tuple = ()

    # ------------------------------------------------------------------ state conversion
    def from_minimal(self, q, v=None, a=None):
        """Closed-chain state from thesis coordinates of the minimal model.

        Returns (q_c, v_c[, a_c]); velocities/accelerations only when given.
        """
        r = self.robot
        qp = r.to_pinocchio(check_shape("q", q, (r.nq,)))
        vp = r.to_pinocchio(v) if v is not None else np.zeros(r.nq)
        ap = r.to_pinocchio(a) if a is not None else np.zeros(r.nq)
        pin.forwardKinematics(r.model, r.data, qp, vp, ap)
        qc = np.zeros(self.model.nq)
        vc = np.zeros(self.model.nv)
        ac = np.zeros(self.model.nv)
        pairs = tuple(zip(self.freeflyer_ids, r.hinge_joint_ids, strict=True)) + tuple(self.placed_freeflyers)
        for fly, hinge in pairs:
            jq, jv = self.model.joints[fly].idx_q, self.model.joints[fly].idx_v
            qc[jq:jq + 7] = pin.SE3ToXYZQUAT(r.data.oMi[hinge])
            vc[jv:jv + 6] = r.data.v[hinge].vector
            ac[jv:jv + 6] = r.data.a[hinge].vector
        for name, (source, sign) in self.reversed_ids.items():
            jid = self.model.getJointId(name)
            src = r.model.joints[r.model.getJointId(source)]
            qc[self.model.joints[jid].idx_q] = sign * qp[src.idx_q]
            vc[self.model.joints[jid].idx_v] = sign * vp[src.idx_v]
            ac[self.model.joints[jid].idx_v] = sign * ap[src.idx_v]
        out = (qc, vc) + ((ac,) if a is not None else ())
        return out if v is not None else qc

    def to_minimal(self, qc, vc=None, reference=None):
        """Thesis coordinates of the minimal model from a closed-chain state (inverse of from_minimal).

        Configuration, by extraction (exact on a closed loop; with closure drift, the loop is read
        from drone 1 along the tree, the closure only fixing what the tree cannot): the joints the
        closed chain shares with the minimal model (``reversed_ids``) are copied, the others are read
        from the placements by the robot kind's reader (``kind.closure_reader``; e.g. the FPR's root
        joint from the end-effector placement, the prototype's pivot from link 1's).

        Velocity: ``from_minimal`` is linear in v, vc = K(q) v with K the drone hinges' body
        Jacobians and the rows of the reversed joints; v is the least-squares solution of
        K v = vc (K has full column rank), exact when vc satisfies the closure.

        Angles: without ``reference``, psi and theta are in [-pi, pi) and [-pi/2, pi/2], the others as
        the kind's reader puts them (FPR: phi within pi of 5pi/4, the reference pose, and phi2 within
        pi of level; prototype: q1 in [-pi, pi)); the tree's joints (q21, q2, phi1) keep their
        continuous values. With ``reference``, every angle is returned within pi of it (the Euler
        solution closer to it is chosen), which keeps a sequence of measurements continuous when each
        is given the previous one.

        Args:
            qc: closed-chain configuration, shape (model.nq,).
            vc: closed-chain velocity, shape (model.nv,), or None.
            reference: thesis configuration the angles are unwrapped to, shape (n,), or None.

        Returns:
            q, shape (n,) [m, rad]; or (q, v) when ``vc`` is given, v = qdot [m/s, rad/s].
        """
        r = self.robot
        cache = _minimal_cache(self)
        qc = check_shape("qc", qc, (self.model.nq,))
        if reference is not None:
            reference = check_shape("reference", reference, (r.nq,))
            measure = None if vc is None else cache.native_measure(self)  # fpr._native's part "measure"
            if measure is not None:  # the same steps natively, the placements left in self.data as below
                out = measure.measure(qc, check_shape("vc", vc, (self.model.nv,)), reference)
                if out is not None:  # else (K^T K not positive definite: not these robots) the Python path
                    return out
        pin.forwardKinematics(self.model, self.data, qc)  # Plant.observe reads these placements after this call
        omi = self.data.oMi
        qp = np.zeros(r.nq)
        qp[cache.reversed_q_source] = cache.reversed_sign * qc[cache.reversed_q]
        cache.reader.read(qp, omi, reference)  # the robot's own: what the tree's joints do not give
        q = r.T_inv.dot(qp)  # r.from_pinocchio
        if reference is None:
            cache.reader.wrap(q)
        else:  # every angle within pi of the reference, on floats (a few numbers: cheaper than array calls)
            values, ref = q.tolist(), reference.tolist()
            for i in cache.angular_list:
                values[i] = ref[i] + ((values[i] - ref[i] + math.pi) % _TWO_PI - math.pi)
            q = np.array(values)
        if vc is None:
            return q
        vc = check_shape("vc", vc, (self.model.nv,))
        minimal = cache.native_minimal()  # fpr._native's part "measure", or None
        if minimal is not None:  # the same normal equations natively, K from Pinocchio's Jacobians there
            v = minimal.velocity(q, vc)
            if v is not None:  # else (K^T K not positive definite: not these robots) the Python path decides
                return q, v
        # Speed: least squares by the normal equations K^T K v = K^T vc (Cholesky, LAPACK's posv called
        # directly) instead of lstsq's SVD: K is well conditioned (cond(K) ~ 3 on both robots, so
        # cond(K^T K) ~ 10), which keeps v within 1e-15 (relative) of the SVD solution.
        k = self._velocity_map(q, cache)
        kt = k.T
        x, info = _posv(kt.dot(k), kt.dot(vc))[1:]
        v = x if info == 0 else np.linalg.lstsq(k, vc, rcond=None)[0]  # rank-deficient K: not these robots
        return q, v

    @property
    def _angular(self) -> np.ndarray:
        """Positions of the angular thesis coordinates (all but the end-effector position x, y, z)."""
        names = self.robot.layout.coordinates
        return np.array([i for i, c in enumerate(names) if c not in ("x", "y", "z")], dtype=int)

    def velocity_map(self, q) -> np.ndarray:
        """K(q): the closed-chain velocity of thesis velocities, vc = K v, shape (model.nv, n).

        Rows of the free flyers: the body Jacobians of the minimal model's drone hinges; rows of the
        reversed joints: +-1 on their source joint.
        """
        return self._velocity_map(check_shape("q", q, (self.robot.nq,)), _minimal_cache(self))

    def _velocity_map(self, q, cache) -> np.ndarray:
        """:meth:`velocity_map` without the shape check; the reversed joints' rows come from the cache."""
        r = self.robot
        pin.computeJointJacobians(r.model, r.data, r.T.dot(q))
        k = cache.velocity_rows.copy()
        for jv, hinge in cache.freeflyer_rows:
            k[jv:jv + 6] = pin.getJointJacobian(r.model, r.data, hinge, pin.LOCAL).dot(r.T)
        return k

    def generalized_input(self, qc, thrust, torque) -> np.ndarray:
        """J_c^T w: generalised force of the drones' thrusts and torques in the closed-chain model."""
        w = self.robot.input_wrenches(thrust, torque)
        pin.computeJointJacobians(self.model, self.data, qc)
        pin.updateFramePlacements(self.model, self.data)
        tau = np.zeros(self.model.nv)
        for i, f in enumerate(self.drone_frame_ids):
            tau += pin.getFrameJacobian(self.model, self.data, f, pin.LOCAL).T @ w[i]
        return tau

    def forward_dynamics(self, qc, vc, tau) -> np.ndarray:
        """Accelerations of the closed-chain model under the generalised force tau (constraint dynamics)."""
        return pin.constraintDynamics(self.model, self.data, qc, vc, tau, self.constraints, self.constraint_datas,
                                      self.settings)

    def closure_error(self, qc) -> float:
        """Norm of the loop-closure error (placement log for a weld, distance for a point) [m, rad]; NaN when
        a closure's is (a non-finite configuration).
        """
        pin.framesForwardKinematics(self.model, self.data, qc)
        err = 0.0
        for cm in self.constraints:
            m1 = self.data.oMi[cm.joint1_id] * cm.joint1_placement
            m2 = self.data.oMi[cm.joint2_id] * cm.joint2_placement
            if cm.type == pin.ContactType.CONTACT_6D:
                e = float(np.linalg.norm(pin.log6(m1.inverse() * m2).vector))
            else:
                e = float(np.linalg.norm(m1.translation - m2.translation))
            if e > err or e != e:  # not max(): max(0.0, nan) is 0.0
                err = e
        return err

    def energy(self, qc, vc) -> float:
        """Kinetic plus potential energy [J]."""
        return float(pin.computeKineticEnergy(self.model, self.data, qc, vc)
                     + pin.computePotentialEnergy(self.model, self.data, qc))

    def set_baumgarte(self, kp: float, kd: float) -> None:
        """Set the closure stabilisation gains of every constraint [1/s^2, 1/s]."""
        for cm in self.constraints:
            cm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(kp, kd))


class _MinimalCache:
    """Indices, constant rows and the kind's reader used by :meth:`ClosedChainModel.to_minimal` and ``velocity_map``.

    Built once per model (:func:`_minimal_cache`) rather than at every call: the joint-name lookups,
    SE3 inverses and constant rows cost more than the kinematics itself (the simulator measures
    the plant at every tick).
    """

    def __init__(self, closed: "ClosedChainModel"):
        r, model = closed.robot, closed.model
        src = r.model
        rev = [(model.joints[model.getJointId(name)], src.joints[src.getJointId(source)], sign)
               for name, (source, sign) in closed.reversed_ids.items()]
        self.reversed_q = np.array([j.idx_q for j, _, _ in rev], dtype=int)
        self.reversed_q_source = np.array([s.idx_q for _, s, _ in rev], dtype=int)
        self.reversed_sign = np.array([sign for _, _, sign in rev])
        # K's rows of the reversed joints are constant (+-1 on their source joint); the free flyers' are not
        self.velocity_rows = np.zeros((model.nv, r.nq))
        for j, source, sign in rev:
            self.velocity_rows[j.idx_v] = sign * r.T[source.idx_v]
        pairs = tuple(zip(closed.freeflyer_ids, r.hinge_joint_ids, strict=True)) + tuple(closed.placed_freeflyers)
        self.freeflyer_rows = tuple((model.joints[fly].idx_v, hinge) for fly, hinge in pairs)
        self.angular = closed._angular
        self.angular_list = self.angular.tolist()
        self.reader = r.kind.closure_reader(closed)
        self._robot = r
        self._native = None
        self._native_measure = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_native"] = state["_native_measure"] = None  # native objects: made again where they are used
        return state

    def native_measure(self, closed):
        """The native measurement (:mod:`fpr._native`'s part ``measure``: forward kinematics on ``closed.data``,
        the kind's reads, the unwrapping and the velocity), made at its first use; None when the part is off or
        not built, or the kind's reader gives no native reads.
        """
        if self.native_minimal() is None or not hasattr(self.reader, "native_reads"):
            return None
        if self._native_measure is None:
            r = self._robot
            eulers, angles = self.reader.native_reads()
            self._native_measure = native.use("measure").Measure(
                closed.model, closed.data, self._native, r.model.nq, self.reversed_q.tolist(),
                self.reversed_q_source.tolist(), self.reversed_sign, eulers, angles, r.T_inv, self.angular_list)
        return self._native_measure

    def native_minimal(self):
        """The native measured velocity (:mod:`fpr._native`'s part ``measure``: the minimal model, its own data,
        T, the constant rows of K and the hinges whose LOCAL Jacobians fill the free flyers' rows), made at its
        first use; None when the part is off or not built.
        """
        module = native.use("measure")
        if module is None:
            return None
        if self._native is None:
            r = self._robot
            self._native = module.Minimal(r.model, r.model.createData(), r.T, [], self.velocity_rows,
                                          [iv for iv, _ in self.freeflyer_rows],
                                          [hinge for _, hinge in self.freeflyer_rows])
        return self._native


def _minimal_cache(closed: "ClosedChainModel") -> _MinimalCache:
    """The :class:`_MinimalCache` of a closed-chain model, built at its first use."""
    cache = closed.__dict__.get("_minimal_cache")
    if cache is None:
        cache = closed.__dict__["_minimal_cache"] = _MinimalCache(closed)
    return cache


def add_free_drone(model: pin.Model, robot, index: int) -> tuple[int, int]:
    """Add drone ``index`` of ``robot`` to ``model`` as a free flyer whose joint frame is its hinge frame.

    The drone's body (inertia of the minimal model's hinge joint) hangs on the free flyer, and the
    frame ``<drone>_center`` marks its centre of mass (where thrust and torques act).

    Args:
        model: the closed-chain model being built.
        robot: the minimal-coordinate :class:`~fpr.model.robot.Robot`.
        index: the drone's position in ``robot.layout.drones``.

    Returns:
        (free-flyer joint id, centre frame id).
    """
    name = robot.layout.drones[index]
    hinge = robot.hinge_joint_ids[index]
    jid = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), f"{name}_freeflyer")
    model.appendBodyToJoint(jid, robot.model.inertias[hinge], pin.SE3.Identity())
    centre = robot.model.frames[robot.drone_frame_ids[index]]
    fid = model.addFrame(pin.Frame(f"{name}_center", jid, centre.placement, pin.FrameType.OP_FRAME))
    return jid, fid


def constraint_data(model: pin.Model, constraints) -> tuple[pin.Data, pin.StdVec_RigidConstraintData]:
    """A data of ``model`` and one data per constraint of ``constraints``, initialised for
    ``pin.constraintDynamics``.
    """
    data, datas = model.createData(), pin.StdVec_RigidConstraintData()
    for cm in constraints:
        datas.append(cm.createData())
    pin.initConstraintDynamics(model, data, constraints, datas)
    return data, datas


def build_closed_chain(robot, baumgarte: tuple[float, float] = (400.0, 40.0),
                       accuracy: float = 1e-12, mu: float = 1e-9, max_iter: int = 50,
                       axis_offset: float = 0.1) -> ClosedChainModel:
    """Build the closed-chain formulation of a :class:`~fpr.model.robot.Robot`.

    The tree and the closure are the robot kind's (``robot.kind.closed_chain``).

    Args:
        robot: the minimal-coordinate robot (its bodies are reused).
        baumgarte: (Kp, Kd) closure stabilisation gains [1/s^2, 1/s].
        accuracy: proximal solver accuracy.
        mu: proximal regularisation (a closure may have redundant rows, e.g. the FPR's: 6 of rank 5).
        max_iter: proximal solver iterations.
        axis_offset: distance between two closure points on a hinge's axis, for a revolute closure made
            of two point constraints (FPR) [m].
    """
    model = pin.Model()
    model.gravity = robot.model.gravity
    tree = robot.kind.closed_chain(model, axis_offset)
    data, datas = constraint_data(model, tree.constraints)
    settings = pin.ProximalSettings(accuracy, mu, max_iter)
    closed = ClosedChainModel(robot, model, data, tree.constraints, datas, tree.frame_ids, tree.freeflyer_ids,
                              tree.reversed_ids, settings, tuple(tree.placed_freeflyers))
    closed.set_baumgarte(*baumgarte)
    return closed


__all__ = ["ClosedChainModel", "ClosureTree", "add_free_drone", "build_closed_chain", "euler_zyx", "wrap_angle"]
