"""The simulated plant: the closed-chain multibody model driven by rotor speeds through a motor lag.

The plant is the exact model of :mod:`fpr.model.constrained` (free-flying rigid drones, the passive chain,
loop closure by constraint dynamics with Baumgarte stabilisation), not the minimal model the planner
and the controller use: the controller only sees it through :meth:`Plant.measure` (the state in the
thesis' coordinates, by :meth:`~fpr.model.constrained.ClosedChainModel.to_minimal`), and acts on it through
rotor speed commands.

One :meth:`Plant.step` of length dt:

1. the command is saturated to [0, w_max] (``robot.rotor_constants.max_speed``);
2. the rotor speeds follow the first-order motor lag w' = (w_cmd - w) / T_m
   (``robot.rotor_constants.time_constant``), solved exactly: w(t) = w_cmd + (w_0 - w_cmd) exp(-t / T_m);
3. each drone's thrust and body torques are [f, tau] = R_f w^2 (seed 3.10, ``robot.rotors[i]``), their
   generalised force J_c^T w_i; an optional wind force (world axes) acts at each drone's centre of mass;
4. the state (q_c, v_c) advances by one step of the 4th-order Runge-Kutta-Munthe-Kaas method on the
   configuration Lie group (:func:`rkmk4_step`). The rotor speeds in the inputs are the exact lag
   solution w(t) at each stage's time, so the motor lag adds no integration error.

Why RKMK4: a plain RK4 that sums the stages' free-flyer twists as if they lived in one tangent space
is of low order in the drones' rotations (its drift grows about as dt^1.5). Measured on the passive
prototype (5 s, yaw rate 0.5 rad/s, hinge rate 2 rad/s): energy drift 8.6e-3 J at dt = 1 ms for the
plain RK4, 1.6e-5 J for RKMK4 (2.8e-3 J at dt = 5 ms), for 1.7 times the cost per step;
semi-implicit Euler gains 19 J.

The steps run native when built (:mod:`fpr._native`'s part ``plant``), with or without wind: the same method on
the same model, by the same Pinocchio algorithms called from C++ instead of Python.
"""

from __future__ import annotations

import math
import time as _time

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from fpr import _native as native
from fpr.model.constrained import ClosedChainModel, build_closed_chain, constraint_data
from fpr.model.errors import FprError, ModelArgumentError, check_shape
from fpr.robots import load
from fpr.sim.hover import hover_configuration, hover_speeds

_gesv = lapack.dgesv


class PlantDivergedError(FprError, FloatingPointError):
    """The simulated state is no longer finite (the step is too long, or the robot flew apart).

    Raised by :meth:`Plant.step`. The closed loop (:func:`fpr.sim.closed_loop.simulate`) catches it and
    returns the log simulated so far with ``failure`` set instead; the class stays for callers who step
    a plant themselves.

    Attributes:
        time: simulated time of the last finite state [s].
        what: what happened, e.g. "the plant state became non-finite".
    """

    def __init__(self, time: float, dt: float, what: str = "the plant state became non-finite"):
        self.time = float(time)
        self.what = what
        super().__init__(f"{what} in the step of {dt:g} s after t = {time:.6g} s: "
                         "reduce the time step, or check the inputs")


def rkmk4_step(model: pin.Model, q, v, dt: float, acceleration):
    """One 4th-order Runge-Kutta-Munthe-Kaas step of q' = v (on the Lie group), v' = a(q, v, t).

    The configuration of each stage is ``pin.integrate(model, q, theta)``; theta' is v pulled back
    through the differential of the exponential map, dexp^-1_theta(v) = ``dIntegrate(q, theta, ARG1)^-1 v``
    (identity on the revolute joints), which makes the method 4th order on SE(3).

    Args:
        model: the Pinocchio model.
        q: configuration, shape (model.nq,).
        v: velocity, shape (model.nv,).
        dt: step [s].
        acceleration: a(q, v, t) -> shape (model.nv,), t in [0, dt] the time within the step [s].

    Returns:
        (q, v) at the end of the step.
    """

    def theta_rate(theta, vel):
        jac = pin.dIntegrate(model, q, theta, pin.ArgumentPosition.ARG1)
        # LAPACK's gesv directly: the same LU solve as np.linalg.solve (identical results here), without
        # its Python-level checks at each call (3 calls per step)
        x, info = _gesv(jac, vel)[2:]
        if info != 0:  # singular (never for |theta| << pi): let numpy raise its usual error
            return np.linalg.solve(jac, vel)
        return x

    k1v, k1q = acceleration(q, v, 0.0).copy(), v
    theta = 0.5 * dt * k1q
    v2 = v + 0.5 * dt * k1v
    k2v, k2q = acceleration(pin.integrate(model, q, theta), v2, 0.5 * dt).copy(), theta_rate(theta, v2)
    theta = 0.5 * dt * k2q
    v3 = v + 0.5 * dt * k2v
    k3v, k3q = acceleration(pin.integrate(model, q, theta), v3, 0.5 * dt).copy(), theta_rate(theta, v3)
    theta = dt * k3q
    v4 = v + dt * k3v
    k4v, k4q = acceleration(pin.integrate(model, q, theta), v4, dt).copy(), theta_rate(theta, v4)
    q_next = pin.integrate(model, q, dt / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q))
    v_next = v + dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
    return q_next, v_next


def _rotor_force_map(closed: ClosedChainModel, mixing) -> np.ndarray | None:
    """G with J_c^T [0, 0, f_i, tau_i] summed over the drones = G w^2 (w^2 flattened drone by drone), or None.

    Each drone's centre frame is fixed on a free flyer whose parent is the world (build_closed_chain),
    so its LOCAL frame Jacobian does not depend on the configuration: on that free flyer's 6
    velocity columns it is the action matrix of the frame's placement inverse (the free flyer's
    velocity is its body twist), zero elsewhere; Pinocchio's, computed from world placements, equals
    it to round-off (2e-16). With the rotor maps R_f (``mixing``) the rotors' generalised force is
    then one constant matrix. None when a drone frame is placed otherwise (the Jacobian path is used).
    """
    model = closed.model
    g = np.zeros((model.nv, 4 * len(closed.drone_frame_ids)))
    for i, fid in enumerate(closed.drone_frame_ids):
        frame = model.frames[fid]
        joint = model.joints[frame.parentJoint]
        if model.parents[frame.parentJoint] != 0 or joint.shortname() != "JointModelFreeFlyer":
            return None
        jac = frame.placement.inverse().toActionMatrix()  # (6, 6): LOCAL Jacobian on the free flyer's columns
        g[joint.idx_v:joint.idx_v + 6, 4 * i:4 * i + 4] = jac[2:].T @ mixing[i]  # rows f, tau of the wrench
    return g


class Plant:
    """The simulated robot: closed-chain constraint dynamics, rotor model and motor lag.

    Build it with :meth:`from_minimal` (a state in the thesis' coordinates) or from a closed-chain
    state. The rotor speeds are part of the state (the motor lag), not an input.

    Attributes:
        closed: the :class:`~fpr.model.constrained.ClosedChainModel` (its ``data`` is used as scratch).
        qc: closed-chain configuration, shape (closed.model.nq,).
        vc: closed-chain velocity, shape (closed.model.nv,).
        time: simulated time [s].
    """

    def __init__(self, closed: ClosedChainModel, qc, vc=None, w=None, time: float = 0.0, reference=None,
                 rotor_constant_scale: float = 1.0):
        """Args:
            closed: the closed-chain model (:func:`~fpr.model.constrained.build_closed_chain`).
            qc: its configuration, shape (model.nq,).
            vc: its velocity, shape (model.nv,); zero by default.
            w: rotor speeds, shape (n_d, 4) [rad/s]; stopped (zero) by default.
            time: initial time [s].
            reference: thesis configuration for the first :meth:`measure` to unwrap its angles to.
            rotor_constant_scale: the rotors produce this times the nominal force and drag torque (c_T and
                c_Q both scaled; 0: no thrust at all), >= 0.

        Raises:
            ModelArgumentError: a negative or non-finite rotor_constant_scale.
        """
        if not (np.isfinite(rotor_constant_scale) and rotor_constant_scale >= 0):
            raise ModelArgumentError("rotor_constant_scale", rotor_constant_scale,
                                     f"rotor_constant_scale = {rotor_constant_scale!r}: give a finite "
                                     "number >= 0 (1: the nominal rotors)")
        self.closed = closed
        model = closed.model
        self.qc = check_shape("qc", qc, (model.nq,)).copy()
        self.vc = np.zeros(model.nv) if vc is None else check_shape("vc", vc, (model.nv,)).copy()
        n_d = closed.robot.n_drones
        self._w = np.zeros((n_d, 4)) if w is None else check_shape("w", w, (n_d, 4)).copy()
        self.time = float(time)
        self._reference = (None if reference is None
                           else check_shape("reference", reference, (closed.robot.nq,)).copy())
        self._mixing = np.array([rotor.mixing_matrix for rotor in closed.robot.rotors])  # (n_d, 4, 4)
        if rotor_constant_scale != 1.0:
            self._mixing = self._mixing * rotor_constant_scale
        self._rotor_map = _rotor_force_map(closed, self._mixing)
        self._max_speed = closed.robot.rotor_constants.max_speed
        self._step_constants = {}  # dt -> (lag decay at 0, dt/2, dt; dt/2; RK4 weights), see _python_steps
        self._native_plant = None  # the native part's plant (fpr._native, "plant"), made at its first use
        # constraint and frame data read by drone_positions_and_closure_error (looked up once)
        self._closure_terms = tuple((cm.joint1_id, cm.joint1_placement.translation.copy(), cm.joint2_id,
                                     cm.joint2_placement.translation.copy()) for cm in closed.constraints)
        self._closure_is_3d = all(cm.type == pin.ContactType.CONTACT_3D for cm in closed.constraints)
        self._drone_frames = tuple((model.frames[f].parentJoint, model.frames[f].placement.translation.copy())
                                   for f in closed.drone_frame_ids)
        self._drone_points = tuple((joint, p.tolist()) for joint, p in self._drone_frames)  # as floats
        self._closure_points = tuple((j1, p1.tolist(), j2, p2.tolist())
                                     for j1, p1, j2, p2 in self._closure_terms)
        self._point_joints = tuple(sorted({j for j, _ in self._drone_points}
                                         | {j for j1, _, j2, _ in self._closure_points for j in (j1, j2)}))
        # each drone's free flyer (its hinge frame, build_closed_chain): where its q and v sit, and its thrust
        # axis (the centre frame's z) in the free flyer's frame, read by drone_joint_positions / drone_tilts
        self._freeflyers = tuple((model.joints[j].idx_q, model.joints[j].idx_v,
                                  model.frames[f].placement.rotation[:, 2].copy())
                                 for j, f in zip(closed.freeflyer_ids, closed.drone_frame_ids, strict=True))

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_native_plant"] = None  # a native object: made again at the next step
        return state

    @classmethod
    def from_minimal(cls, robot, q, v=None, w=None, baumgarte: tuple[float, float] = (400.0, 40.0),
                     max_iter: int = 3, closed: ClosedChainModel | None = None,
                     rotor_constant_scale: float = 1.0) -> "Plant":
        """A plant at a state given in thesis coordinates.

        Args:
            robot: the :class:`~fpr.model.robot.Robot`.
            q: configuration, shape (n,) [m, rad].
            v: velocity, shape (n,) [m/s, rad/s]; zero by default.
            w: rotor speeds, shape (n_d, 4) [rad/s]; stopped by default (see :func:`hover_speeds`).
            baumgarte: closure stabilisation gains (Kp [1/s^2], Kd [1/s]), when ``closed`` is not given.
            max_iter: proximal iterations of the constraint solve, when ``closed`` is not given. The
                FPR's closure has 6 rows of rank 5, so the solver's stopping test (on the multipliers,
                undetermined along the redundant row) never passes and it always runs max_iter
                iterations; the accelerations agree to 1e-15 with a 200-iteration solve from the 2nd
                iteration on. 3 instead of build_closed_chain's 50 makes a plant step about 1.6 times faster.
            closed: a closed-chain model of ``robot`` to reuse (it is then shared: one plant at a time).
            rotor_constant_scale: the rotors' force and drag times this (see :class:`Plant`).
        """
        closed = closed or build_closed_chain(robot, baumgarte=baumgarte, max_iter=max_iter)
        q = check_shape("q", q, (robot.nq,))
        v = np.zeros(robot.nq) if v is None else check_shape("v", v, (robot.nq,))
        qc, vc = closed.from_minimal(q, v)
        return cls(closed, qc, vc, w, reference=q, rotor_constant_scale=rotor_constant_scale)

    # ------------------------------------------------------------------ state
    @property
    def robot(self):
        """The minimal-coordinate :class:`~fpr.model.robot.Robot`."""
        return self.closed.robot

    @property
    def rotor_speeds(self) -> np.ndarray:
        """The actual rotor speeds w (a copy), shape (n_d, 4) [rad/s]."""
        return self._w.copy()

    def measure(self, reference=None) -> tuple[np.ndarray, np.ndarray]:
        """The state in thesis coordinates, (q, v) [m, rad; m/s, rad/s] (:meth:`ClosedChainModel.to_minimal`).

        Args:
            reference: configuration the angles are unwrapped to (within pi); by default the
                previous measurement (or the initial q of :meth:`from_minimal`), which keeps
                successive measurements continuous.
        """
        ref = self._reference if reference is None else reference
        q, v = self.closed.to_minimal(self.qc, self.vc, reference=ref)
        self._reference = q.copy()
        return q, v

    def energy(self) -> float:
        """Kinetic plus gravitational potential energy [J] (rotors not included)."""
        return self.closed.energy(self.qc, self.vc)

    def closure_error(self) -> float:
        """Loop-closure error of the current configuration [m]."""
        return self.closed.closure_error(self.qc)

    def drone_positions(self) -> np.ndarray:
        """World positions of the drones' centres of mass, shape (n_d, 3) [m]."""
        pin.framesForwardKinematics(self.closed.model, self.closed.data, self.qc)
        return np.array([self.closed.data.oMf[f].translation.copy() for f in self.closed.drone_frame_ids])

    def drone_positions_and_closure_error(self) -> tuple[np.ndarray, float]:
        """:meth:`drone_positions` and :meth:`closure_error` together, from one forward kinematics pass.

        The simulator logs both at every tick: this reads the joint placements once and moves the few
        points itself (x = R p + t, what Pinocchio's SE3 products compute), instead of the two methods'
        two kinematics passes and their SE3 objects (about 4 times faster). Same values to round-off.

        Returns:
            positions, shape (n_d, 3) [m]; closure error [m].
        """
        if not self._closure_is_3d:  # a 6D weld's error is a placement log: the general code
            return self.drone_positions(), self.closure_error()
        pin.forwardKinematics(self.closed.model, self.closed.data, self.qc)
        return self._positions_and_closure()

    def _positions_and_closure(self) -> tuple[np.ndarray, float]:
        """:meth:`drone_positions_and_closure_error` from the joint placements in ``closed.data`` (forward
        kinematics at ``qc`` already done), 3D closures only: x = R p + t for each point, on floats.

        Each joint's placement is read once, as one 4x4 matrix (``SE3.homogeneous``: one conversion instead
        of the rotation's and the translation's, each costing more than the arithmetic), for all the points
        on it.
        """
        omi = self.closed.data.oMi
        placements = {joint: omi[joint].homogeneous.tolist() for joint in self._point_joints}

        def point(joint, p):  # world position of the point p (a list) of a joint's frame
            (r00, r01, r02, t0), (r10, r11, r12, t1), (r20, r21, r22, t2), _ = placements[joint]
            return (r00 * p[0] + r01 * p[1] + r02 * p[2] + t0,
                    r10 * p[0] + r11 * p[1] + r12 * p[2] + t1,
                    r20 * p[0] + r21 * p[1] + r22 * p[2] + t2)

        positions = np.array([point(joint, p) for joint, p in self._drone_points])
        error = 0.0
        for j1, p1, j2, p2 in self._closure_points:
            a, b = point(j1, p1), point(j2, p2)
            e = math.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)
            if e > error or e != e:  # NaN stays NaN, as in the native points() (max(0.0, nan) is 0.0)
                error = e
        return positions, error

    def observe(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """What the closed loop reads at every tick, from one forward kinematics pass: :meth:`measure` (q, v)
        and :meth:`drone_positions_and_closure_error` (positions, closure error), the same values (the
        positions and the closure error from the native plant's kinematics when it steps the plant: equal to
        round-off, a NaN state giving a NaN closure error).

        Returns:
            q, v (thesis coordinates, shape (n,)); the drones' centres of mass, shape (n_d, 3) [m]; the
            loop-closure error [m].
        """
        q, v = self.measure()
        if not self._closure_is_3d:
            return (q, v) + self.drone_positions_and_closure_error()
        kernel = self._step_kernel()
        if kernel is not None:  # the native plant's kinematics (the same points, to round-off)
            return (q, v) + kernel.points(self.qc)
        # ClosedChainModel.to_minimal (in measure) left the placements at qc in closed.data
        return (q, v) + self._positions_and_closure()

    def drone_joint_positions(self) -> np.ndarray:
        """World positions of the drones' passive joints (hinges), shape (n_d, 3) [m].

        Read from the state: each drone's free flyer is placed at its hinge (:func:`build_closed_chain`).
        """
        return np.array([self.qc[iq:iq + 3] for iq, _, _ in self._freeflyers])

    def drone_tilts(self) -> np.ndarray:
        """Angle between each drone's thrust axis and the world's upward z, shape (n_d,) [rad].

        0: level; pi/2: the thrust is horizontal; beyond pi/2 it pushes the drone down. Read from the free
        flyers' quaternions, no kinematics pass.
        """
        cosines = []
        for iq, _, axis in self._freeflyers:
            x, y, z, w = self.qc[iq + 3:iq + 7] / np.linalg.norm(self.qc[iq + 3:iq + 7])
            third_row = (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))  # of the rotation
            cosines.append(float(np.dot(third_row, axis)))
        return np.arccos(np.clip(cosines, -1.0, 1.0))

    def drone_speeds(self) -> tuple[np.ndarray, np.ndarray]:
        """Speed of each drone's hinge [m/s] and its angular speed [rad/s], each shape (n_d,) (norms of the
        free flyers' twists).
        """
        linear = np.array([np.linalg.norm(self.vc[iv:iv + 3]) for _, iv, _ in self._freeflyers])
        angular = np.array([np.linalg.norm(self.vc[iv + 3:iv + 6]) for _, iv, _ in self._freeflyers])
        return linear, angular

    def center_of_mass(self) -> tuple[np.ndarray, np.ndarray]:
        """Position [m] and velocity [m/s] of the whole robot's centre of mass, each shape (3,)."""
        com = pin.centerOfMass(self.closed.model, self.closed.data, self.qc, self.vc)
        return com.copy(), self.closed.data.vcom[0].copy()

    # ------------------------------------------------------------------ dynamics
    def rotor_inputs(self, w=None) -> tuple[np.ndarray, np.ndarray]:
        """Thrusts and body torques [f_i, tau_i] = R_f w_i^2 (seed 3.10) of rotor speeds.

        Args:
            w: rotor speeds, shape (n_d, 4) [rad/s]; the plant's by default.

        Returns:
            thrust, shape (n_d,) [N]; torque, shape (n_d, 3) [N m].
        """
        w = self._w if w is None else check_shape("w", w, (self.robot.n_drones, 4))
        wrench = np.einsum("dij,dj->di", self._mixing, w * w)
        return wrench[:, 0], wrench[:, 1:]

    def _wind_forces(self, wind) -> np.ndarray | None:
        if wind is None:
            return None
        n_d = self.robot.n_drones
        f = np.asarray(wind, dtype=float)
        if f.shape == (3,):
            return np.tile(f, (n_d, 1))
        return check_shape("wind", f, (n_d, 3))

    def generalized_force(self, qc, w, wind_forces=None) -> np.ndarray:
        """Generalised force of the rotors (and wind) on the closed chain at qc, shape (model.nv,).

        Same as ``closed.generalized_input(qc, *rotor_inputs(w))`` (thrust along body z and body
        torques at each drone's centre, through its LOCAL frame Jacobian), plus J_lin^T F for the
        wind, J_lin the WORLD-aligned linear rows of each drone centre's Jacobian.

        Args:
            qc: closed-chain configuration.
            w: rotor speeds, shape (n_d, 4) [rad/s].
            wind_forces: force on each drone's centre of mass in world axes, shape (n_d, 3) [N], or None.
        """
        model, data = self.closed.model, self.closed.data
        wrench = np.einsum("dij,dj->di", self._mixing, w * w)  # [f, tau_x, tau_y, tau_z] per drone
        pin.computeJointJacobians(model, data, qc)
        pin.updateFramePlacements(model, data)
        tau = np.zeros(model.nv)
        for i, fid in enumerate(self.closed.drone_frame_ids):
            jac = pin.getFrameJacobian(model, data, fid, pin.LOCAL)
            tau += wrench[i] @ jac[2:]
            if wind_forces is not None:
                jac = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
                tau += wind_forces[i] @ jac[:3]
        return tau

    def acceleration(self, w=None, wind=None) -> np.ndarray:
        """Closed-chain acceleration at the current state under rotor speeds w, shape (model.nv,).

        Args:
            w: rotor speeds, shape (n_d, 4) [rad/s]; the plant's by default.
            wind: see :meth:`step`.
        """
        w = self._w if w is None else check_shape("w", w, (self.robot.n_drones, 4))
        tau = self.generalized_force(self.qc, w, self._wind_forces(wind))
        return self.closed.forward_dynamics(self.qc, self.vc, tau).copy()

    def saturate(self, w_command) -> np.ndarray:
        """Rotor speed commands clipped to [0, w_max], shape (n_d, 4) [rad/s]."""
        return np.minimum(np.maximum(self._checked_command(w_command), 0.0), self._max_speed)  # np.clip, cheaper

    def step(self, w_command, dt: float, wind=None) -> None:
        """Advance the plant by dt under a rotor speed command held over the step.

        Args:
            w_command: commanded rotor speeds, shape (n_d, 4) [rad/s]; saturated to [0, w_max].
            dt: time step [s], > 0 (1 ms is accurate: see the module notes).
            wind: constant force on each drone's centre of mass in world axes [N]: shape (3,) (the
                same on every drone) or (n_d, 3); None for no wind.

        Raises:
            ModelArgumentError: dt <= 0.
            PlantDivergedError: the state became non-finite (or so fast that the integrator failed).
        """
        if not dt > 0:
            raise ModelArgumentError("dt", dt, f"dt = {dt!r}: the time step must be positive [s]")
        kernel = self._step_kernel() if self._compiles_forces() else None
        if kernel is not None:  # the native steps saturate the command themselves (the same clip)
            self._native_steps(kernel, self._checked_command(w_command), dt, 1, self._wind_forces(wind))
            return
        w_cmd = self.saturate(w_command)
        if wind is None and self._rotor_map is not None:
            self._python_steps(w_cmd, dt, 1)
            return
        self._python_wind_step(w_cmd, dt, self._wind_forces(wind))

    def _python_wind_step(self, w_cmd, dt: float, wind_forces) -> None:
        """One :func:`rkmk4_step` on :meth:`generalized_force` (w_cmd saturated, wind_forces (n_d, 3) or None)."""
        w0 = self._w
        lag = self.robot.rotor_constants.time_constant

        def speeds(t):
            return w_cmd + (w0 - w_cmd) * np.exp(-t / lag) if lag > 0 else w_cmd

        closed = self.closed

        def acceleration(qc, vc, t):
            return closed.forward_dynamics(qc, vc, self.generalized_force(qc, speeds(t), wind_forces))

        self._advance(lambda: rkmk4_step(closed.model, self.qc, self.vc, dt, acceleration), dt, speeds(dt))

    def _advance(self, integrate, dt: float, w_end) -> None:
        """Run ``integrate() -> (qc, vc)``, check the result, and take it with the rotor speeds w_end."""
        try:
            qc, vc = integrate()
        except np.linalg.LinAlgError as error:  # a rotation of ~2 pi within one step: the state blew up
            raise PlantDivergedError(self.time, dt, f"the plant's integrator failed ({error})") from error
        if not math.isfinite(qc.sum() + vc.sum()):  # NaN or inf if any entry is
            raise PlantDivergedError(self.time, dt)
        self.qc, self.vc, self._w = qc, vc, w_end
        self.time += dt

    def advance(self, w_command, dt: float, steps: int, wind=None) -> None:
        """``steps`` calls of :meth:`step` with one command held (the closed loop's plant steps of one tick).

        A subclass that overrides :meth:`step` (e.g. :class:`fpr.sim.replanning.ForcedPlant`) gets its own
        :meth:`step` called ``steps`` times; the base plant runs the steps in one call of the native steps, or
        of :meth:`_python_steps` without wind (the same steps bit for bit, set up once).

        Args:
            w_command: commanded rotor speeds, shape (n_d, 4) [rad/s], held over the steps (as :meth:`step`).
            dt: time step [s], > 0.
            steps: number of steps, >= 1.
            wind: as :meth:`step`.

        Raises:
            ModelArgumentError: dt <= 0.
            PlantDivergedError: the state became non-finite; the plant keeps its last finite state, and
                the error's ``time`` says after which step.
        """
        if type(self).step is Plant.step and self._compiles_forces():
            if not dt > 0:
                raise ModelArgumentError("dt", dt, f"dt = {dt!r}: the time step must be positive [s]")
            kernel = self._step_kernel()
            if kernel is not None:  # the native steps saturate the command themselves (the same clip)
                self._native_steps(kernel, self._checked_command(w_command), dt, steps, self._wind_forces(wind))
                return
            if wind is None:
                self._python_steps(self.saturate(w_command), dt, steps)
                return
        for _ in range(steps):
            self.step(w_command, dt, wind)

    def _lean_constants(self, dt: float) -> tuple:
        """What :meth:`_python_steps` and :meth:`_native_steps` read, looked up once per dt: the lag's decay at
        (0, dt/2, dt), dt/2, the RK4 weights (dt/6, dt/3, dt/3, dt/6), G^T, the Pinocchio objects and functions,
        two stage buffers, G^T in C order.
        """
        constants = self._step_constants.get(dt)
        if constants is None:
            lag = self.robot.rotor_constants.time_constant
            decay = np.array([1.0, math.exp(-0.5 * dt / lag), math.exp(-dt / lag)] if lag > 0
                             else [0.0, 0.0, 0.0])
            closed = self.closed
            nv = closed.model.nv
            constants = self._step_constants[dt] = (
                decay[:, None], 0.5 * dt, np.array([dt / 6.0, dt / 3.0, dt / 3.0, dt / 6.0]),
                self._rotor_map.T,
                closed.model, closed.data, closed.settings, closed.constraints, closed.constraint_datas,
                np.empty((4, nv)), np.empty((4, nv)), np.ascontiguousarray(self._rotor_map.T))
        return constants

    def _compiles_forces(self) -> bool:
        """Whether the native steps compute this plant's forces: the rotors' as one constant map, and no
        subclass adds its own through :meth:`generalized_force` (a subclass that does says when it does not).
        """
        return self._rotor_map is not None and type(self).generalized_force is Plant.generalized_force

    def _checked_command(self, w) -> np.ndarray:
        """The command as :meth:`saturate` takes it, not yet clipped (shape checked)."""
        ok = type(w) is np.ndarray and w.shape == self._w.shape and w.dtype == float
        return w if ok else check_shape("w_command", w, (self.robot.n_drones, 4))

    def _step_kernel(self):
        """The native plant (:mod:`fpr._native`'s part ``plant``), made at its first use, or None for the Python
        steps (the part switched off or not built, or the rotors' force not one constant map).

        It steps the closed chain's own model, constraints and proximal settings (the same objects, not a copy),
        on a data and constraint datas of its own (``closed.data`` is left to the Python side).
        """
        module = native.use("plant")
        if module is None or self._rotor_map is None:
            return None
        if self._native_plant is None:
            closed = self.closed
            data, datas = constraint_data(closed.model, closed.constraints)
            self._native_plant = module.Plant(closed.model, data, closed.constraints, datas, closed.settings,
                                              np.ascontiguousarray(self._rotor_map.T), list(closed.drone_frame_ids))
        return self._native_plant

    def _native_steps(self, kernel, w_cmd, dt: float, steps: int, wind_forces=None) -> None:
        """:meth:`_python_steps` natively (``fpr/_native/cpp/plant.cpp``): the same RKMK4 steps on the same
        Pinocchio calls (``constraintDynamics``, ``integrate``, ``dIntegrate``), with the wind's J^T F of each
        drone's centre at every stage when ``wind_forces`` (n_d, 3) is given. The native steps saturate w_cmd to
        [0, w_max] as :meth:`saturate` does (a saturated command is unchanged).
        """
        decay = self._lean_constants(dt)[0]
        q, v, w, done, status = kernel.steps(self.qc, self.vc, self._w, w_cmd, self._max_speed, decay, dt, steps,
                                             wind_forces)
        if done:
            self.qc, self.vc, self._w = q, v, w
            for _ in range(done):
                self.time += dt
        if status == 1:
            raise PlantDivergedError(self.time, dt)
        if status == 2:
            raise PlantDivergedError(self.time, dt, "the plant's integrator failed (dexp^-1 singular: a turn of "
                                                    "about 2 pi within one step)")

    def _python_steps(self, w_cmd, dt: float, steps: int) -> None:
        """``steps`` RKMK4 steps without wind, w_cmd saturated: the same steps as :func:`rkmk4_step` (equal to
        round-off; tested), in fewer array calls.

        The rotors' generalised force does not depend on the configuration (:func:`_rotor_force_map`), only
        on the stage's time: the exact lag solution w(t) at the 3 distinct times (0, dt/2, dt) gives the 3
        forces in one product. The step's constants (dt/2, the RK4 weights, the lag's decay, the Pinocchio
        objects) are looked up once per dt; the stages go into two buffers (k_v the accelerations, k_q the
        rates of theta) and the weighted sums are one product each. dexp^-1_theta(v) is LAPACK's gesv on
        ``dIntegrate(q, theta, ARG1)`` (as :func:`rkmk4_step`). After each step the state is checked finite
        (:class:`PlantDivergedError` with the time of the last finite state otherwise).
        """
        constants = self._lean_constants(dt)
        decay, half, weights, force_map_t, model, data, settings, cms, cds, k_v, k_q, _ = constants
        dynamics, integrate, d_integrate = pin.constraintDynamics, pin.integrate, pin.dIntegrate
        arg1, gesv, isfinite = pin.ArgumentPosition.ARG1, _gesv, math.isfinite
        w_cmd = w_cmd.reshape(-1)
        w, q, v = self._w.reshape(-1), self.qc, self.vc
        for _ in range(steps):
            speeds = w_cmd + (w - w_cmd) * decay  # (3, 4 n_d): w at 0, dt/2, dt
            forces = (speeds * speeds).dot(force_map_t)  # (3, nv)
            try:
                k_v[0] = a = dynamics(model, data, q, v, forces[0], cms, cds, settings)
                k_q[0] = x = v
                # stages 2-4: from the previous stage's rates, at dt/2, dt/2, dt (forces at those times)
                for stage, h, force in ((1, half, forces[1]), (2, half, forces[1]), (3, dt, forces[2])):
                    v_stage, theta = v + h * a, h * x
                    q_stage = integrate(model, q, theta)
                    k_v[stage] = a = dynamics(model, data, q_stage, v_stage, force, cms, cds, settings)
                    x, info = gesv(d_integrate(model, q, theta, arg1), v_stage)[2:]
                    if info != 0:
                        raise np.linalg.LinAlgError("Singular matrix")
                    k_q[stage] = x
                q_next = integrate(model, q, weights.dot(k_q))
                v_next = v + weights.dot(k_v)
            except np.linalg.LinAlgError as error:  # a rotation of ~2 pi within one step: the state blew up
                raise PlantDivergedError(self.time, dt, f"the plant's integrator failed ({error})") from error
            if not isfinite(q_next.sum() + v_next.sum()):  # NaN or inf if any entry is
                raise PlantDivergedError(self.time, dt)
            q, v, w = q_next, v_next, speeds[2]
            self.qc, self.vc, self._w = q, v, w.reshape(-1, 4)
            self.time += dt


def plant_step_time(robot, steps: int = 1000, dt: float = 1e-3) -> float:
    """Mean wall time of one :meth:`Plant.step` [s], hovering at the robot's reference pose
    (``robot.kind.reference_chain``).

    Args:
        robot: a :class:`~fpr.model.robot.Robot` or a registered robot name ("fpr", "prototype"...).
        steps: number of steps timed.
        dt: simulated step [s].
    """
    if isinstance(robot, str):
        robot = load(robot)
    q = hover_configuration(robot, robot.kind.reference_chain)
    w = hover_speeds(robot, q)
    plant = Plant.from_minimal(robot, q, w=w)
    plant.step(w, dt)  # warm up
    start = _time.perf_counter()
    for _ in range(steps):
        plant.step(w, dt)
    return (_time.perf_counter() - start) / steps


__all__ = ["Plant", "PlantDivergedError", "hover_configuration", "hover_speeds",
           "plant_step_time", "rkmk4_step"]
