"""A robot of the toolkit as a Pinocchio model, in the coordinates of the seed thesis.

:class:`Robot` wraps the Pinocchio model of a URDF and speaks the thesis' coordinates. It is generic:
what is specific to one robot (its coordinate layout, kinematics, margins, closure...) is its *kind*,
an object of :mod:`fpr.robots` that the Robot holds as ``robot.kind`` and that generic code asks.
Build a Robot with :func:`fpr.robots.load` (``fpr.load``), which finds the kind by name in the
registry. The built-in layouts (seed 2.1, 3.3):

* FPR: ``q = [x y z psi theta phi q21 phi1 phi2]``: end-effector position, its yaw / pitch / roll
  (Z-Y-X Euler angles), the angle between the links, and the *absolute* roll of each drone.
  Pinocchio gets the end-effector's 6 coordinates from a composite root joint
  (PX, PY, PZ, RZ, RY, RX) so that its velocity is exactly ``qdot``.
* Prototype: ``q = [psi theta q1 q2 phi1]``: the chain's yaw and pitch about the fixed point,
  the two link angles and the drone's absolute roll.

Pinocchio's own coordinates differ only by the drone hinge angles, which are relative to the link
(``beta_1 = phi1 - phi``...): the map ``q_pin = T q`` is linear and constant (the :class:`Layout`),
so ``M = T^T M_pin T`` and ``c = T^T c_pin`` hold exactly.

The drones are actuated by a thrust along their body z axis and three body torques applied at the
drone's centre of mass (frame ``drone_<i>_center``); the generalised force is ``J^T w`` with
``w = [0, 0, f, tau_x, tau_y, tau_z]`` and ``J`` the drone's twist Jacobian in its own frame
(seed 2.10-2.11). Each drone ``<d>`` of the layout has a hinge joint ``<d>_hinge`` (its passive joint)
and frames ``<d>_center`` and ``<d>_rotor_1`` .. ``<d>_rotor_4``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from fpr import _native as native
from fpr.model.description import single_angle_urdf
from fpr.model.errors import ModelArgumentError, NotUniformError, RobotDefinitionError, check_shape
from fpr.model.parameters import Margins, RotorConstants, load_parameters, margins, rotor_constants
from fpr.model.planar import PlanarModel
from fpr.model.rotors import RotorModel

logger = logging.getLogger(__name__)

_posv = lapack.dposv

@dataclass(frozen=True)
class Layout:
    """How a robot's thesis coordinates map onto its Pinocchio joints.

    Attributes:
        coordinates: names of the thesis coordinates, in order.
        joints: for each Pinocchio joint name, ``{thesis coordinate: coefficient}`` giving its
            (one-dimensional) joint coordinate as a linear combination of thesis coordinates.
        drones: names of the drones (URDF prefixes).
        chain: the planar chain coordinates (the planning vector s, or xi for the prototype).
        attitude: the attitude coordinates q_a (seed 2.10).
        drone_attitude: per drone (in the order of ``drones``), the coordinates that hold its attitude,
            e.g. (("phi1",), ("phi2",)) for drones with one absolute roll each; each among ``attitude``.
        euler_root: whether Pinocchio gets a 6-dof Euler root joint (floating robot).
    """

    coordinates: tuple[str, ...]
    joints: dict
    drones: tuple[str, ...]
    chain: tuple[str, ...]
    attitude: tuple[str, ...]
    drone_attitude: tuple[tuple[str, ...], ...]
    euler_root: bool

    @property
    def rolls(self) -> tuple[str, ...]:
        """The drones' attitude coordinates in one tuple, drone after drone (``drone_attitude`` flattened):
        the absolute rolls (phi1, phi2...) of a planar robot's drones.
        """
        return tuple(c for coordinates in self.drone_attitude for c in coordinates)


EULER_ROOT_NAME = "end_effector_root"


def euler_root_joint() -> pin.JointModelComposite:
    """The FPR's root joint: translations x, y, z then yaw psi, pitch theta, roll phi (Z-Y-X)."""
    joint = pin.JointModelComposite()
    for j in (pin.JointModelPX(), pin.JointModelPY(), pin.JointModelPZ(),
              pin.JointModelRZ(), pin.JointModelRY(), pin.JointModelRX()):
        joint.addJoint(j)
    return joint


@dataclass(frozen=True)
class AttitudeModel:
    r"""Attitude dynamics of the drones (seed 2.12-2.13) at one state.

    .. math:: \ddot q_a = M_{inv,a} (J_\tau^T \tau + J_f^T f - c) = A_\tau \tau + M_{inv,a}(J_f^T f - c)

    Attributes:
        m_inv_a: rows of M^-1 of the attitude coordinates, shape (n_a, n).
        j_tau: torque rows of the drone Jacobians, shape (3 n_d, n); tau = [tau_1; tau_2].
        j_f: thrust rows of the drone Jacobians, shape (n_d, n).
        a_tau: M_inv_a J_tau^T, shape (n_a, 3 n_d).
        c: nonlinear effects (Coriolis, centrifugal, gravity), shape (n,).
    """

    m_inv_a: np.ndarray
    j_tau: np.ndarray
    j_f: np.ndarray
    a_tau: np.ndarray
    c: np.ndarray

    def attitude_acceleration(self, thrust, torque) -> np.ndarray:
        """qddot_a for thrusts f (n_d,) [N] and torques tau (n_d, 3) [N m] (seed 2.12)."""
        tau = np.asarray(torque, dtype=float).reshape(-1)
        return self.m_inv_a.dot(self.j_tau.T.dot(tau) + self.j_f.T.dot(np.asarray(thrust, dtype=float)) - self.c)


_ATTITUDE_FIELDS = ("m_inv_a", "j_tau", "j_f", "a_tau", "c")  # AttitudeModel's fields, in order


class Robot:
    """A robot's Pinocchio model, used in the thesis' coordinates.

    Build it with :func:`fpr.robots.load` (``fpr.load``). All methods take and return thesis
    coordinates; the Pinocchio model (``model``, ``data``) is available for anything else, with
    ``to_pinocchio`` / ``from_pinocchio`` to convert. What is specific to the robot is asked of
    ``kind`` (:class:`fpr.robots.base.RobotKind`), never of its name.

    Attributes:
        kind: the robot kind bound to this robot (its coordinates, kinematics, margins, closure...).
        name: the kind's registry name (e.g. "fpr", "prototype"), for messages and files.
        layout: the coordinate layout, ``kind.layout``.
        model: the Pinocchio model.
        data: its data.
        rotor_constants: c_T, c_Q, w_max, spin senses.
        margins: planning margins.
        urdf: the URDF text the model was built from.
        parameters: the parameter dictionary (``urdf/parameters.yaml`` and the xacro overrides).
    """

    def __init__(self, kind, urdf: str, params: dict | None = None):
        """Build the model of ``urdf`` for a robot kind.

        Args:
            kind: a robot kind *class* (:class:`fpr.robots.base.RobotKind` subclass); the robot holds
                ``kind(self)``, an instance bound to it.
            urdf: the URDF text.
            params: the parameter dictionary; default ``urdf/parameters.yaml``.

        Raises:
            RobotDefinitionError: the URDF lacks a joint or frame of the layout, or its coordinates are
                not the layout's.
        """
        self.name = kind.name
        self.layout = kind.layout
        self.urdf = urdf
        self.parameters = params or load_parameters()
        text = single_angle_urdf(urdf)  # continuous hinges: one angle each
        if self.layout.euler_root:
            self.model = pin.buildModelFromXML(text, euler_root_joint(), EULER_ROOT_NAME)
        else:
            self.model = pin.buildModelFromXML(text)
        self.model.gravity.linear = np.array([0.0, 0.0, -float(self.parameters["gravity"])])
        self.data = self.model.createData()
        self.rotor_constants: RotorConstants = rotor_constants(self.parameters)
        self.margins: Margins = margins(self.parameters)
        self._build_coordinate_map()
        self._check_drone_attitude()
        self.drone_frame_ids = tuple(self.model.getFrameId(f"{d}_center") for d in self.layout.drones)
        self.hinge_joint_ids = tuple(self.model.getJointId(f"{d}_hinge") for d in self.layout.drones)
        for fid, jid, d in zip(self.drone_frame_ids, self.hinge_joint_ids, self.layout.drones, strict=True):
            if fid >= self.model.nframes or jid >= self.model.njoints:
                raise RobotDefinitionError(self.name, f"the URDF has no frame '{d}_center' or no joint "
                                                      f"'{d}_hinge': make each drone with the quadrotor macro of "
                                                      "urdf/quadrotor.xacro")
        self.kind = kind(self)

    # ------------------------------------------------------------------ coordinates
    def _build_coordinate_map(self):
        names = self.layout.coordinates
        n = len(names)
        if self.model.nq != n or self.model.nv != n:
            raise RobotDefinitionError(self.name, f"the Pinocchio model has nq={self.model.nq}, "
                                                  f"nv={self.model.nv}; the layout expects {n} coordinates {names}")
        t = np.zeros((n, n))
        if self.layout.euler_root:
            jid = self.model.getJointId(EULER_ROOT_NAME)
            i0 = self.model.joints[jid].idx_q
            t[i0:i0 + 6, :6] = np.eye(6)
        for joint, combination in self.layout.joints.items():
            jid = self.model.getJointId(joint)
            if jid >= self.model.njoints:
                raise RobotDefinitionError(self.name, f"the URDF has no joint {joint!r} (named in the layout)")
            for coordinate, coefficient in combination.items():
                t[self.model.joints[jid].idx_q, names.index(coordinate)] = coefficient
        self.T = t
        self.T_inv = np.linalg.inv(t)
        self.index = {c: i for i, c in enumerate(names)}

    def _check_drone_attitude(self):
        layout = self.layout
        if len(layout.drone_attitude) != len(layout.drones):
            raise RobotDefinitionError(self.name, f"the layout's drone_attitude has {len(layout.drone_attitude)} "
                                                  f"entries for {len(layout.drones)} drones: give one tuple of "
                                                  "attitude coordinates per drone")
        stray = [c for c in layout.rolls if c not in layout.attitude]
        if stray:
            raise RobotDefinitionError(self.name, f"the layout's drone_attitude names {stray}, which are not "
                                                  f"among its attitude coordinates {layout.attitude}")

    @property
    def nq(self) -> int:
        """Number of coordinates."""
        return len(self.layout.coordinates)

    @property
    def n_drones(self) -> int:
        """Number of drones."""
        return len(self.layout.drones)

    def indices(self, coordinates) -> np.ndarray:
        """Positions of named coordinates in q."""
        return np.array([self.index[c] for c in coordinates], dtype=int)

    def planar_indices(self, rolls: bool = True) -> np.ndarray:
        """Positions in q of the in-plane coordinates: the chain, then (if ``rolls``) the drone rolls."""
        return self.indices(self.layout.chain + (self.layout.rolls if rolls else ()))

    def to_pinocchio(self, q) -> np.ndarray:
        """Thesis coordinates (or velocities, accelerations) to Pinocchio's."""
        return self.T.dot(np.asarray(q, dtype=float))  # .dot: about 5 times cheaper than @ on a vector here

    def from_pinocchio(self, q_pin) -> np.ndarray:
        """Pinocchio coordinates (or velocities, accelerations) to the thesis'."""
        return self.T_inv.dot(np.asarray(q_pin, dtype=float))

    def _q(self, q, name="q") -> np.ndarray:
        return self.to_pinocchio(check_shape(name, q, (self.nq,)))

    def configuration(self, **values) -> np.ndarray:
        """A configuration vector from named coordinates (the others zero), e.g. ``configuration(phi=3.9)``."""
        q = np.zeros(self.nq)
        for k, v in values.items():
            if k not in self.index:
                raise KeyError(f"{k!r} is not a coordinate of the {self.name}: {', '.join(self.layout.coordinates)}")
            q[self.index[k]] = v
        return q

    # ------------------------------------------------------------------ geometry read from the URDF
    @cached_property
    def link_length(self) -> float:
        """L, read from drone 1's hinge position in the frame of the link that carries it [m].

        The length of every link of the built-in robots, and the ground's depth below the origin
        (z = -L). A robot with links of different lengths: ask its kind (``kind.link_lengths``,
        ``kind.ground_height``).
        """
        return float(np.linalg.norm(self.model.jointPlacements[self.hinge_joint_ids[0]].translation))

    @cached_property
    def hinge_offsets(self) -> np.ndarray:
        """d_i, distance from each drone's hinge to its centre of mass, shape (n_d,) [m]."""
        return np.array([np.linalg.norm(self.model.frames[f].placement.translation) for f in self.drone_frame_ids])

    @cached_property
    def drone_masses(self) -> np.ndarray:
        """m_i, mass of each drone, shape (n_d,) [kg]."""
        return np.array([self.model.inertias[j].mass for j in self.hinge_joint_ids], dtype=float)

    def _uniform(self, quantity: str, values: np.ndarray, plural: str) -> float:
        if np.ptp(values) > 1e-12 * max(1.0, float(np.abs(values).max())):
            raise NotUniformError(quantity, values, f"use robot.{plural}, one value per drone")
        return float(values[0])

    @property
    def hinge_offset(self) -> float:
        """d, distance from the drone hinge to the drone's centre of mass, the same for every drone [m].

        Raises:
            NotUniformError: the drones' offsets differ (use :attr:`hinge_offsets`).
        """
        return self._uniform("hinge_offset", self.hinge_offsets, "hinge_offsets")

    @property
    def drone_mass(self) -> float:
        """m_d, mass of one drone, the same for every drone [kg].

        Raises:
            NotUniformError: the drones' masses differ (use :attr:`drone_masses`).
        """
        return self._uniform("drone_mass", self.drone_masses, "drone_masses")

    @cached_property
    def total_mass(self) -> float:
        """Mass of the whole robot [kg]."""
        return float(sum(inertia.mass for inertia in self.model.inertias))

    @cached_property
    def rotors(self) -> tuple[RotorModel, ...]:
        """Rotor model of each drone, with rotor positions read from the URDF frames."""
        models = []
        for drone, fid in zip(self.layout.drones, self.drone_frame_ids, strict=True):
            centre = self.model.frames[fid].placement
            positions = []
            for m in range(1, 5):
                rid = self.model.getFrameId(f"{drone}_rotor_{m}")
                if rid >= self.model.nframes:
                    raise RobotDefinitionError(self.name, f"the URDF has no frame '{drone}_rotor_{m}'")
                positions.append((centre.inverse() * self.model.frames[rid].placement).translation)
            models.append(RotorModel(np.array(positions), self.rotor_constants))
        return tuple(models)

    # ------------------------------------------------------------------ kinematics
    def frame_placements(self, q) -> list[pin.SE3]:
        """World placement of every drone centre-of-mass frame."""
        pin.framesForwardKinematics(self.model, self.data, self._q(q))
        return [self.data.oMf[f].copy() for f in self.drone_frame_ids]

    def drone_positions(self, q) -> np.ndarray:
        """World positions of the drones' centres of mass, shape (n_d, 3) [m]."""
        return np.array([m.translation for m in self.frame_placements(q)])

    def hinge_positions(self, q) -> np.ndarray:
        """World positions of the drone hinges (the drone joints r_i), shape (n_d, 3) [m]."""
        pin.forwardKinematics(self.model, self.data, self._q(q))
        return np.array([self.data.oMi[j].translation.copy() for j in self.hinge_joint_ids])

    # ------------------------------------------------------------------ dynamics
    def mass_matrix(self, q) -> np.ndarray:
        """M(q), generalised inertia matrix, shape (n, n) (seed 2.11)."""
        # M = T^T M_p T. Pinocchio's Python crba returns M_p whole (its binding mirrors the upper triangle that
        # the algorithm fills: tests/test_fast_paths.py holds this), so the call is CRBA and two 9 x 9 products,
        # one numpy call fewer than a map on the triangle (take, product, reshape) and cheaper on this size.
        t = self.T
        m = pin.crba(self.model, self.data, t.dot(check_shape("q", q, (self.nq,))))
        return self._t_transposed.dot(m).dot(t)

    @cached_property
    def _t_transposed(self) -> np.ndarray:
        """T^T, C-contiguous (the left factor of :meth:`mass_matrix`)."""
        return np.ascontiguousarray(self.T.T)

    def nonlinear_effects(self, q, v) -> np.ndarray:
        """c(q, qdot): Coriolis, centrifugal and gravity terms, shape (n,) (seed 2.11)."""
        return self.T.T @ pin.nonLinearEffects(self.model, self.data, self._q(q), self._q(v, "v"))

    def gravity_terms(self, q) -> np.ndarray:
        """g(q), the gravity part of c, shape (n,)."""
        return self.T.T @ pin.computeGeneralizedGravity(self.model, self.data, self._q(q))

    def drone_jacobians(self, q) -> np.ndarray:
        """J: twists of the drones' centre frames in their own axes, shape (n_d, 6, n) (seed 2.10-2.11).

        ``J[i] @ qdot`` is [linear velocity; angular velocity] of drone i expressed in drone i's frame.
        """
        qp = self._q(q)
        pin.computeJointJacobians(self.model, self.data, qp)
        pin.updateFramePlacements(self.model, self.data)
        return np.array([pin.getFrameJacobian(self.model, self.data, f, pin.LOCAL) @ self.T
                         for f in self.drone_frame_ids])

    def input_wrenches(self, thrust, torque) -> np.ndarray:
        """Drone wrenches w_i = [0, 0, f_i, tau_ix, tau_iy, tau_iz] (seed 2.1-2.2), shape (n_d, 6)."""
        f = check_shape("thrust", np.atleast_1d(thrust), (self.n_drones,))
        tau = check_shape("torque", np.reshape(torque, (self.n_drones, 3)), (self.n_drones, 3))
        w = np.zeros((self.n_drones, 6))
        w[:, 2] = f
        w[:, 3:] = tau
        return w

    def generalized_input(self, q, thrust, torque) -> np.ndarray:
        """Generalised force of the drones, J^T [w_1; w_2], shape (n,)."""
        jac = self.drone_jacobians(q)
        w = self.input_wrenches(thrust, torque)
        return np.einsum("kij,ki->j", jac, w)

    def forward_dynamics(self, q, v, thrust, torque) -> np.ndarray:
        """qddot = M^-1 (J^T w - c) (seed 2.11), computed by Pinocchio's ABA.

        Args:
            q: configuration (n,).
            v: velocity (n,).
            thrust: f_i of each drone, shape (n_d,) [N].
            torque: body torques of each drone, shape (n_d, 3) [N m].
        """
        qp, vp = self._q(q), self._q(v, "v")
        pin.framesForwardKinematics(self.model, self.data, qp)
        w = self.input_wrenches(thrust, torque)
        fext = pin.StdVec_Force()
        for _ in range(self.model.njoints):
            fext.append(pin.Force.Zero())
        for i, f in enumerate(self.drone_frame_ids):
            frame = self.model.frames[f]
            # the frame's wrench, moved to its parent joint's frame (ABA takes forces in joint frames)
            fext[frame.parentJoint] += frame.placement.act(pin.Force(w[i]))
        a = pin.aba(self.model, self.data, qp, vp, np.zeros(self.model.nv), fext)
        return self.from_pinocchio(a)

    def kinetic_energy(self, q, v) -> float:
        """Kinetic energy [J]."""
        return float(pin.computeKineticEnergy(self.model, self.data, self._q(q), self._q(v, "v")))

    def potential_energy(self, q) -> float:
        """Gravitational potential energy, zero at z = 0 [J]."""
        return float(pin.computePotentialEnergy(self.model, self.data, self._q(q)))

    def attitude_model(self, q, v) -> AttitudeModel:
        """The attitude model of seed 2.12-2.13 at (q, qdot)."""
        # Speed (the controller calls this at every inner-loop tick; each numpy call costs a microsecond or
        # more on these small arrays): the same quantities as mass_matrix, nonlinear_effects and
        # drone_jacobians with fewer calls, from one Pinocchio pass (CRBA, RNEA, the joint Jacobians), or with
        # the native part (fpr._native's "attitude") from one call of the same algorithms in C++ (equal to
        # round-off: tests/test_attitude_compiled.py), on a data of its own. The rest, natively in C
        # (fpr/_native/attitude.c, about 3 times cheaper than the numpy calls of _attitude_python, its reference,
        # equal to round-off: tests/test_fast_paths.py).
        constants = self.__dict__.get("_attitude_constants") or self._build_attitude_constants()
        q, v = check_shape("q", q, (self.nq,)), check_shape("v", v, (self.nq,))
        kernel = native.use("attitude")
        post = None if kernel is None or constants[-1] is None else kernel.post
        terms = None if post is None else self._native_terms()
        if terms is not None:  # M_p, nle and the Jacobians by Pinocchio's C++ algorithms
            m, nle, jacobians = terms.frame_terms(q, v)
        else:
            t, model, data = self.T, self.model, self.data
            qp, vp = t.dot(q), t.dot(v)
            m = pin.crba(model, data, qp)
            nle = pin.nonLinearEffects(model, data, qp, vp)
            pin.computeJointJacobians(model, data, qp)
            pin.updateFramePlacements(model, data)
            jacobians = tuple([pin.getFrameJacobian(model, data, f, pin.LOCAL) for f in self.drone_frame_ids])
        if post is not None:
            out = post(m, nle, jacobians, constants[-1])
            if out is not None:  # else (M_p not positive definite: never) the Python path decides
                # the frozen dataclass without its __init__ (one object.__setattr__ per field): the same
                # object, about half the cost
                result = object.__new__(AttitudeModel)
                result.__dict__.update(zip(_ATTITUDE_FIELDS, out, strict=True))
                return result
        return self._attitude_python(m, nle, jacobians)

    def _build_attitude_constants(self) -> tuple:
        """What :meth:`attitude_model` needs besides the state, built once: (T^-1)[a]^T, the Jacobian rows of
        f and tau, and the native part's constants vector (``fpr/_native/attitude.c``: n, n_d, n_a, the
        attitude indices, T, T^-1; None when the robot does not fit it).
        """
        n, n_d = self.nq, self.n_drones
        attitude = self.indices(self.layout.attitude)
        rows = np.arange(6 * n_d).reshape(n_d, 6)
        vector = None
        kernel = native.module("_attitude")
        if kernel is not None and n <= kernel.MAX_COORDINATES and n_d <= kernel.MAX_DRONES:
            vector = np.concatenate([[n, n_d, attitude.size], attitude, self.T.reshape(-1),
                                     self.T_inv.reshape(-1)]).astype(float)
        constants = self.__dict__["_attitude_constants"] = (
            np.ascontiguousarray(self.T_inv[attitude].T), rows[:, 2].copy(), rows[:, 3:].reshape(-1).copy(), vector)
        return constants

    def __getstate__(self):
        state = self.__dict__.copy()
        state.pop("_native_minimal", None)  # a native object: made again where it is next used
        return state

    def _native_terms(self):
        """The minimal model's native terms (``fpr._native._pinocchio.Minimal``: M_p, nle and the drones' LOCAL frame
        Jacobians at (T q, T v), on a data of its own), made at its first use; None when the model's nq != nv.
        """
        terms = self.__dict__.get("_native_minimal", False)
        if terms is False:
            module = native.module("_pinocchio")
            terms = None
            if module is not None and self.model.nq == self.model.nv:
                terms = module.Minimal(self.model, self.model.createData(), self.T, list(self.drone_frame_ids),
                                       np.zeros((0, self.nq)), [], [])
            self.__dict__["_native_minimal"] = terms
        return terms

    def _attitude_python(self, m, nle, jacobians) -> AttitudeModel:
        """:meth:`attitude_model` from Pinocchio's M_p (upper triangle read), its nonlinear effects and the
        drones' frame Jacobians (LOCAL), with numpy and LAPACK: the reference of the native part.

        Only the n_a needed rows of M^-1, from M_p (upper triangle, as CRBA fills it and as LAPACK's posv
        reads it) without forming M = T^T M_p T: M^-1 = T^-1 M_p^-1 T^-T, so the rows a of M^-1 are
        (T^-1 X)^T with M_p X = (T^-1)[a]^T. Same values to round-off (4e-16 relative on m_inv_a).
        """
        rhs, f_rows, tau_rows = (self.__dict__.get("_attitude_constants") or self._build_attitude_constants())[:3]
        t = self.T
        c = t.T.dot(nle)
        jac = np.vstack(jacobians).dot(t)
        x, info = _posv(m, rhs)[1:]
        if info != 0:  # (not positive definite: never) the full symmetric M and a general solve
            x = np.linalg.solve(np.where(self._upper_mask, m, m.T), rhs)
        m_inv_a = self.T_inv.dot(x).T
        j_tau = jac[tau_rows]
        return AttitudeModel(m_inv_a=m_inv_a, j_tau=j_tau, j_f=jac[f_rows], a_tau=m_inv_a.dot(j_tau.T), c=c)

    @cached_property
    def _upper_mask(self) -> np.ndarray:
        """True on and above the diagonal of an (n, n) matrix (where CRBA writes M)."""
        return np.triu(np.ones((self.nq, self.nq), dtype=bool))

    # ------------------------------------------------------------------ variants
    def planar(self, drones: str = "rigid"):
        """The closed-form in-plane model (:class:`fpr.model.planar.PlanarModel`), built once and cached.

        Args:
            drones: "rigid", "point" (the seed's planning model) or "none" (the passive chain alone).
        """
        cache = self.__dict__.setdefault("_planar_cache", {})
        if drones not in cache:
            cache[drones] = PlanarModel.from_robot(self, drones)
        return cache[drones]

    def with_drones_as(self, kind: str) -> "Robot":
        """A copy whose drones are rigid bodies ("rigid"), point masses at their hinges ("point"),
        or massless ("none").

        The "point" variant is the seed's planning model (drone = point mass at its joint,
        eq. 2.6-2.7); "none" leaves the passive chain alone (M_p, c_p of eq. 2.6).
        """
        if kind not in ("rigid", "point", "none"):
            raise ModelArgumentError("kind", kind, f"kind={kind!r}: use 'rigid', 'point' or 'none'")
        other = Robot(type(self.kind), self.urdf, self.parameters)
        for j in other.hinge_joint_ids:
            inertia = other.model.inertias[j]
            if kind == "point":
                other.model.inertias[j] = pin.Inertia(inertia.mass, np.zeros(3), np.zeros((3, 3)))
            elif kind == "none":
                other.model.inertias[j] = pin.Inertia.Zero()
        other.data = other.model.createData()
        return other


__all__ = ["AttitudeModel", "EULER_ROOT_NAME", "Layout", "Robot", "euler_root_joint"]
