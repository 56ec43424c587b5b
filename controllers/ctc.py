r"""The cascaded computed-torque controller of the thesis (seed 2.2), for any robot of the registry.

**Outer loop** (passive chain, eq. 2.14-2.16, 2.20): from the planned s_d and its derivatives and
the measured chain state,

.. math:: u_p = \ddot s_d - K_{pp} (s - s_d) - K_{dp} (\dot s - \dot s_d), \qquad
          J_h(s)^T F = M_s(s) u_p + c_s(s, \dot s)

gives the force F_i each drone must apply at its joint (point-mass drones, the planning model);
the desired roll is its direction, phi_d,i = atan2(-F_iy, F_iz) (2.20). The thrust is its
component on the drone's measured thrust axis b_z(phi_i) = (-sin phi_i, cos phi_i) (2.15),
corrected for the drone's offset d_i (each drone its own m_i, d_i): the exact multibody model gives,
along the thrust axis, f_i = b_z . F_i - m_i d_i phi_i'^2 (the thesis' 2.21 adds m_i d_i phi_i'' instead: in the exact
model that term lies across the thrust axis, where a thrust cannot cancel it; DESIGN.md).

An integral term K_ip int(s - s_d) dt (not in the thesis) removes the steady error a wrong model
leaves (mass or rotor-constant mismatch, a small wind).

**What the feedback measures** (``momentum_feedback``, on by default; not in the thesis). A drone's joint sits
d_i below its centre of mass, so the torque that rolls a drone pushes its joint, and the chain, the other way
before the tilted thrust pulls it along: from the roll torque to the chain there is a right-half-plane zero
near sqrt(f_i / (m_i d_i)) rad/s (the planar VTOL's coupling, Hauser, Sastry and Meyer 1992), sqrt(g / d_i)
at hover and lower when a push takes thrust off a drone. Fed back through s and s', it closes a loop with the
attitude loop that rings and, at low thrust, diverges. The drones' torques act on their absolute rolls only
(the chain rows of J_tau are zero), so the chain's rows of the full model's momentum M(q) q' do not feel them
at once: the outer loop feeds back the chain velocity that momentum stands for, and its position analogue,

.. math:: \dot s_m - \dot s_d = (\dot s - \dot s_d) + K (\dot q_o - \dot q_{o,d}), \qquad
          s_m - s_d = (s - s_d) + K (q_o - q_{o,d}), \qquad K = M_{ss}^{-1} M_{so},

q_o the coordinates outside the chain (the rolls, and x, psi, theta), q_o,d their references (the rolls of
the reference's thrust vectors and the planned roll rates; 0 for the others). On the reference both equal
the thesis' errors; the integral keeps integrating s - s_d, so a roll held off its plan (a steady wind)
leaves no steady error in s.

**An unknown external force** is estimated by a generalized-momentum observer (:mod:`controllers.observer`,
bandwidth ``observer_bandwidth``, K_O = 20 rad/s by default) on the robot's full model in the thesis'
coordinates q (seed 2.11: rigid drones on their offset joints, the model of the inner loop's attitude
dynamics 2.12), from the measured (q, q') and the thrusts and torques the allocation commands. Its estimate
r (n,) is fed forward in both loops: its chain rows in the outer loop, J_h^T F = M_s u_p + c_s - Q_known -
r_s (a force at the task point or at a drone's centre of mass acts on the chain rows as on the point-drone
model's, whose drones sit at their joints), and all of it in the attitude model (c - r, as a known wind).
``observer_bandwidth = 0`` is the controller without it (the thesis' law with the integral term); then the
feedback alone holds an unknown wind. :meth:`CascadedController.estimated_forces` reads r_s as forces on
the task point and the drones (for a replanner that plans against the wind).

**A known external force** (a wind the controller is told of, or estimates: ``Reference.task_force`` on
the robot kind's task point, ``Reference.drone_forces`` on the drones) is fed forward in the outer loop:
the chain's equation of motion with it is M_s s'' + c_s = J_h^T F + Q_ext, Q_ext = J_p(s)^T f_p +
sum_i J_h,i(s)^T f_i (the same generalised force as the planner's :mod:`planners.problem.disturbance`, J_p the
task point's Jacobian, J_h,i drone i's joint's: the planning model puts the drone's mass there), so the
drones must give J_h^T F = M_s u_p + c_s - Q_ext. Without it the feedback alone holds the wind: the
integral is clamped (``integral_limit``), so a strong wind is balanced by the proportional term, the
robot blown off the plan. With no force given the outer loop is the one above, to the bit.

The solve J_h^T F = b is the robot kind's (``robot.kind.outer_loop_forces``). **Through the
prototype's Type-2 singularity** (q2 = 0, seed ch. 4) it cannot be inverted: the prototype solves the
tension's row in the least-squares sense, regularised towards the planned tension
(:func:`fpr.robots.prototype_thrust.regularised_force`, the same split of F along and across the link
as the planner's inverse dynamics; ``singular_band`` sets the regularisation), so that near q2 = 0 the
elbow's motion across the straight chain, which no drone force can act on, follows the plan open loop.

**Out of the plane** (a robot kind with a ``lateral_loop``: the FPR, whose ``out_of_plane`` coordinates
include x): the pitch theta tilts every thrust out of the plane, so the lateral position x is held by a
desired pitch theta_d = (-k_px x - k_dx x') / (d x'' / d theta), the sensitivity taken from the model at the
hover pose ``kind.reference_chain``; psi_d = 0. A pinned chain (the prototype) has no x: psi_d = theta_d = 0.

**Inner loop** (attitude, eq. 2.23): the robot kind's ``attitude_targets`` turns F_i into the thrusts and the
targets q_a,d with their feed-forward (the planar robots': the roll and thrust above, the lateral loop's
pitch, the planned roll rates and accelerations; :mod:`fpr.robots.planar_control`), then
u_a = q_a,d'' - K_pa (q_a - q_a,d) - K_da (q_a' - q_a,d') for q_a = ``layout.attitude`` ([psi, theta, phi_1,
(phi_2)]); the compiled part (``fpr/_native/alloc.c``) runs both where the kind says it fits;
then the rotor allocation QP (:mod:`controllers.allocation`) turns u_a and the thrusts into rotor
speeds under 0 <= w <= w_max, equal to the thesis' pseudo-inverse law (2.24) when no rotor is at
a bound.

The two loops run at their own rates (:class:`ControllerSettings`); :meth:`CascadedController.update`
is called by the simulator at every inner-loop tick and recomputes the outer loop when it is due.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from controllers.allocation import AllocationResult, Allocator
from controllers.observer import MomentumObserver
from controllers.saturation import ForceLimiter
from fpr import _native as native


@dataclass
class ControllerSettings:
    """Gains and rates.

    Attributes:
        outer_rate, inner_rate: loop rates [Hz].
        chain_frequency, chain_damping: natural frequency [rad/s] and damping ratio of the
            chain's error dynamics (K_pp = w^2, K_dp = 2 zeta w).
        chain_integral: integral gain K_ip on the chain error [1/s^3] (0: the thesis' PD law).
            Without it a model error (masses off by 10 %) leaves a steady error of about
            0.1 g / w^2 = 11 cm in z; with the defaults the error polynomial is
            (s + 1)^2 (s + 4), stable and free of steady error.
        integral_limit: bound on each component of the integrated error (anti wind-up) [m s or rad s].
        attitude_frequency, attitude_damping: same for the drone rolls in the attitude loop.
        orientation_frequency, orientation_damping: same for psi and theta, the orientation of the
            whole robot out of the plane: its inertia is large and the drones move it with weak
            torques, so this loop is slower.
        lateral_frequency, lateral_damping: same for x (FPR only).
        max_pitch: bound on theta_d [rad].
        attitude_weight, thrust_weight: allocation weights (:class:`controllers.allocation.Allocator`).
        singular_band: the angle [rad] that sets the regularisation near a Type-2 singularity (the
            prototype's eps = L sin(band) of the tension near q2 = 0, used when the reference carries
            the planned force; ``robot.kind.outer_loop_forces``).
        observer_bandwidth: K_O [rad/s] of the external-force observer (:mod:`controllers.observer`), whose
            estimate is fed forward in both loops; 0: no observer (the thesis' law with the integral term).
            Above the chain loop's and the attitude loop's frequencies, below the motor lag's 1 / T_m, a fifth of
            the outer rate (:mod:`controllers.observer` says why).
        momentum_feedback: the outer loop feeds back the chain state that the full model's momentum stands for
            (module docstring), free of the drones' roll torques; False: the measured s and s' (the thesis).
        force_limits: a new F whose first attitude tick the rotors cannot give (the allocation's law beyond a rotor
            bound) is turned so that the attitude loop asks what a slower loop would, within the bounds, the chain
            integral held meanwhile (:mod:`controllers.saturation`); before that, the drones' forces are kept where
            each drone's rotors can hold its tilt and turn it back (:mod:`controllers.authority`); False: F as the
            chain loop computes it.
    """

    outer_rate: float = 100.0
    inner_rate: float = 500.0
    chain_frequency: float = 3.0
    chain_damping: float = 1.0
    chain_integral: float = 4.0
    integral_limit: float = 0.5
    attitude_frequency: float = 15.0
    attitude_damping: float = 1.0
    orientation_frequency: float = 5.0
    orientation_damping: float = 1.0
    lateral_frequency: float = 1.5
    lateral_damping: float = 1.0
    max_pitch: float = 0.3
    attitude_weight: float = 1.0
    thrust_weight: float = 1.0
    singular_band: float = 0.03
    observer_bandwidth: float = 20.0
    momentum_feedback: bool = True
    force_limits: bool = True

    @property
    def chain_gains(self) -> tuple[float, float]:
        """(K_p [1/s^2], K_d [1/s]) of the chain loop: omega^2 and 2 zeta omega of its frequency and damping."""
        return self.chain_frequency**2, 2 * self.chain_damping * self.chain_frequency


@dataclass
class Reference:
    """What the controller tracks at one instant (from the plan).

    Attributes:
        motion: s_d and its derivatives 0..4, shape (5, n_s).
        attitude_rate, attitude_acceleration: the planned rates and accelerations of the drones' attitude
            coordinates (``layout.drone_attitude`` flattened; the rolls phi_i', phi_i'' of a planar robot, shape
            (n_d,)), the attitude loop's feed-forward. ``roll_rate`` and ``roll_acceleration`` are their
            former names (read-only aliases).
        force: planned thrust vectors F_i, shape (n_d, len(force_axes)) [N], or None. The robot kind's
            outer-loop solve may use it (the prototype's near q2 = 0, module docstring).
        task_force: a known external force on the robot kind's task point (the FPR's end-effector), world
            [x, y, z] [N], fed forward (module docstring), or None. x does not act on the planar chain.
        drone_forces: known external forces on each drone, world [x, y, z], shape (n_d, 3) [N], or None: at
            its joint in the outer loop (as in the planning model), at its centre of mass in the attitude model.
    """

    motion: np.ndarray
    attitude_rate: np.ndarray
    attitude_acceleration: np.ndarray
    force: np.ndarray | None = None
    task_force: np.ndarray | None = None
    drone_forces: np.ndarray | None = None

    @property
    def roll_rate(self) -> np.ndarray:
        """``attitude_rate`` under its former name (a planar robot's planned roll rates)."""
        return self.attitude_rate

    @property
    def roll_acceleration(self) -> np.ndarray:
        """``attitude_acceleration`` under its former name (a planar robot's planned roll accelerations)."""
        return self.attitude_acceleration


@dataclass
class ControlOutput:
    """One inner-loop tick.

    Attributes:
        speeds: commanded rotor speeds, shape (n_d, 4) [rad/s].
        allocation: the :class:`~controllers.allocation.AllocationResult`.
        force: F_i of the outer loop, shape (n_d, len(force_axes)) [N].
        attitude_target: the targets of the drones' attitude coordinates (``layout.drone_attitude``
            flattened; phi_d,i of a planar robot, shape (n_d,)) [rad]; ``roll_desired`` is its former name
            (a read-only alias).
        thrust_desired: f_i wanted from the allocation, shape (n_d,) [N].
        attitude_desired: u_a, the attitude loop's commanded accelerations, shape (n_a,) [rad/s^2] (the
            allocation's name; the desired attitudes are ``attitude_target``).
        pitch_desired: theta_d of the lateral loop [rad] (0 without one).
    """

    speeds: np.ndarray
    allocation: AllocationResult
    force: np.ndarray
    attitude_target: np.ndarray
    thrust_desired: np.ndarray
    attitude_desired: np.ndarray
    pitch_desired: float

    @property
    def roll_desired(self) -> np.ndarray:
        """``attitude_target`` under its former name (a planar robot's desired rolls)."""
        return self.attitude_target


@dataclass
class CascadedController:
    """The thesis' cascaded CTC for one robot (the controller's own model of it).

    Args:
        robot: the model the controller uses (it may differ from the plant: mass mismatch tests).
        settings: :class:`ControllerSettings`.
    """

    robot: object
    settings: ControllerSettings = field(default_factory=ControllerSettings)

    def __post_init__(self):
        r, st = self.robot, self.settings
        # The outer loop's model at one sample, through Pinocchio: the robot with point-mass drones (the
        # seed's planning model, whose closed form is r.planar("point")) restricted to the chain
        # coordinates of an in-plane state. Equal to the closed form to 1e-15 (relative), about 8 times
        # cheaper for a single sample (the closed form is vectorised for the planner's batches).
        self._point_robot = r.with_drones_as("point")
        self._chain_map = self._point_robot.T[:, r.indices(r.layout.chain)]  # Pinocchio q of the chain s
        self._task_frame = self._point_robot.model.getFrameId(r.kind.task_frame)
        self._full_task_frame = r.model.getFrameId(r.kind.task_frame)
        self._upper = np.triu(np.ones((r.nq, r.nq), dtype=bool))
        self._axes = _force_rows(r.kind.force_axes)  # the rows of world (x, y, z) along the kind's force axes
        self._gains = None  # (key, kp, kd, their lists) of the attitude loop, see _attitude_gains
        self.chain = r.indices(r.layout.chain)
        self.rolls = r.indices(r.layout.rolls)
        self._others = np.setdiff1d(np.arange(r.nq), self.chain)  # q_o: the coordinates outside the chain
        self._other_rolls = np.searchsorted(self._others, self.rolls)  # the rolls' places in q_o
        self.attitude = r.indices(r.layout.attitude)
        drone_attitude = set(r.layout.rolls)  # drone_attitude flattened
        self._wrap = [c in drone_attitude for c in r.layout.attitude]  # errors taken as the shortest angle
        self._drone_places = [k for k, wrap in enumerate(self._wrap) if wrap]  # their places in q_a
        self.allocator = Allocator(r, st.attitude_weight, st.thrust_weight)
        self.offset = np.array(r.hinge_offsets)  # d_i, (n_d,) [m]
        self.mass = np.array(r.drone_masses)  # m_i, (n_d,) [kg]
        self.lateral = r.kind.lateral_loop is not None  # an out-of-plane position held with the pitch
        self._force = None
        self._last_outer = -np.inf
        self._integral = np.zeros(len(self.chain))
        self._attitude_list = self.attitude.tolist()  # as Python numbers (the inner loop works on floats)
        self.observer = None  # the external-force observer (controllers/observer.py), made by _observe
        self._applied = np.zeros(r.nq)  # sum of the inputs' generalised forces since the last observer update
        self._ticks = 0
        self._seen = None  # (J_p, J_h) of the last outer update, for estimated_forces
        self.limiter = ForceLimiter(self)  # F within what the rotors can give (controllers/saturation.py)

    def reset(self) -> None:
        """Forget the held outer-loop output, the integrated error and the observer (a new run)."""
        self._force, self._last_outer = None, -np.inf
        self._integral = np.zeros(len(self.chain))
        self.observer, self._seen = None, None
        self._applied, self._ticks = np.zeros(self.robot.nq), 0
        self.limiter = ForceLimiter(self)

    @property
    def disturbance(self) -> np.ndarray:
        """The observer's estimate r_s of the external generalised force on the chain s [N or N m], shape (n_s,)
        (zeros without an observer or before its second update).
        """
        return np.zeros(len(self.chain)) if self.observer is None else self.observer.estimate[self.chain]

    def estimated_forces(self) -> tuple[np.ndarray, np.ndarray]:
        """The observer's estimate as forces, world [x, y, z] [N]: (on the task point (3,), on the drones'
        joints (n_d, 3)), equal to r_s in generalised force on the chain at the configuration of the last
        outer update.

        The task point takes what a force on it can explain (least squares of J_p^T f_p = r_s: all of r_s when
        it comes from a force there), the drones the rest (J_h^T F = r_s - J_p^T f_p, least squares). The
        estimate's roll rows could tell a force at a drone's centre from one at the task point in a steady
        state, but in transients they carry the motor lag's torque errors, which turned such a split into
        opposite forces of 10 N and more: the chain's rows alone are used, so an estimate cannot tell a force
        on the end-effector from one on a drone when both give the same r_s.
        """
        n_d = self.robot.n_drones
        task, drones = np.zeros(3), np.zeros((n_d, 3))
        if self.observer is None or self._seen is None:
            return task, drones
        jac_task, jac_hinges = self._seen
        r = self.disturbance
        axes = self._axes
        task[axes] = np.linalg.lstsq(jac_task.T, r, rcond=None)[0]
        rest = r - jac_task.T.dot(task[axes])
        drones[:, axes] = np.linalg.lstsq(jac_hinges.T, rest, rcond=None)[0].reshape(n_d, -1)
        return task, drones

    # ------------------------------------------------------------------ loops
    def outer(self, q, v, reference: Reference, mass=None) -> np.ndarray:
        """F_i (along the kind's ``force_axes``) each drone must apply at its joint, shape (n_d, len(force_axes))
        [N] (2.14-2.16). ``mass``: the full model's M(q) when the caller has it (the momentum feedback's), else
        computed here.
        """
        st = self.settings
        kp, kd = st.chain_gains
        s, ds = q[self.chain], v[self.chain]
        sd = reference.motion
        error, rate_error = s - sd[0], ds - sd[1]
        if st.momentum_feedback:
            mass = self.robot.mass_matrix(q) if mass is None else mass
            error, rate_error = self._momentum_errors(q, v, reference, error, rate_error, mass)
        u = sd[2] - kp * error - kd * rate_error - st.chain_integral * self._integral
        m, c, jac = self._point_dynamics(s, ds)
        b = m.dot(u) + c
        if reference.task_force is not None or reference.drone_forces is not None:
            b = b - self.external_force(reference.task_force, reference.drone_forces, jac)
        if self.observer is None:
            return self.robot.kind.outer_loop_forces(s, b, jac, reference.force, st.singular_band)
        jac_task = pin.getFrameJacobian(self._point_robot.model, self._point_robot.data, self._task_frame,
                                        pin.LOCAL_WORLD_ALIGNED)[self._axes].dot(self._chain_map)
        self._seen = (jac_task, jac)
        return self.robot.kind.outer_loop_forces(s, b - self.observer.estimate[self.chain], jac, reference.force,
                                                 st.singular_band)

    def _momentum_errors(self, q, v, reference: Reference, error, rate_error, mass):
        """The chain's errors of the state its momentum stands for (module docstring): (s_m - s_d, s_m' - s_d'),
        each (n_s,), from the thesis' ``error`` = s - s_d and ``rate_error`` = s' - s_d'.

        K = M_ss^-1 M_so from the full model's M(q) (``mass``, Pinocchio's CRBA). The rolls' references: the attitude of
        the reference's thrust vectors (the robot kind's ``force_attitude``, 2.20), or of the held outer-loop
        force without them, or the measured rolls (no position term) before either exists; their rates: the
        reference's attitude rates.
        """
        chain, others = self.chain, self._others
        gain = np.linalg.solve(mass[np.ix_(chain, chain)], mass[np.ix_(chain, others)])
        position, rate = q[others].copy(), v[others].copy()
        force = reference.force if reference.force is not None else self._force
        if force is not None:
            force = np.asarray(force, dtype=float)
            planned = self.robot.kind.force_attitude(force, q)  # (2.20)
            position[self._other_rolls] = np.remainder(position[self._other_rolls] - planned + np.pi,
                                                       2 * np.pi) - np.pi
        else:
            position[self._other_rolls] = 0.0
        rate[self._other_rolls] -= reference.attitude_rate
        return error + gain.dot(position), rate_error + gain.dot(rate)

    def _observe(self, dt: float, q, v, mass) -> None:
        """One update of the observer (:mod:`controllers.observer`) at the measured (q, q'), dt [s] after the
        last: the full model's M(q) (``mass``) and nonlinear effects (Pinocchio's CRBA and RNEA), and the mean over the
        inner-loop ticks since the last update of the generalised force the drones were commanded to apply
        (J_f^T f + J_tau^T tau of the attitude model) plus the known wind's.
        """
        st = self.settings
        if self.observer is None or self.observer.bandwidth != st.observer_bandwidth:
            self.observer = MomentumObserver(st.observer_bandwidth, self.robot.nq)
        r = self.robot
        applied = self._applied / self._ticks if self._ticks else np.zeros(r.nq)
        self._applied, self._ticks = np.zeros(r.nq), 0
        self.observer.update(dt, mass, v, r.nonlinear_effects(q, v), applied)

    def external_force(self, task_force=None, drone_forces=None, hinge_jacobian=None) -> np.ndarray:
        """Q_ext = J_p^T f_p + sum_i J_h,i^T f_i on the chain coordinates [N or N m], shape (n_s,).

        At the configuration of the last :meth:`_point_dynamics` call (the Jacobians of its Pinocchio
        pass; ``hinge_jacobian`` is its J_h), only the forces' components along the kind's ``force_axes``
        (world y, z of a planar robot).

        Args:
            task_force: world force on the task point [x, y, z] [N], or None.
            drone_forces: world forces on the drones' joints (n_d, 3) [N], or None.
            hinge_jacobian: J_h (n_d len(force_axes), n_s) of that configuration (needed with ``drone_forces``).
        """
        q_ext = np.zeros(len(self.chain))
        if task_force is not None:
            r = self._point_robot
            jac = pin.getFrameJacobian(r.model, r.data, self._task_frame, pin.LOCAL_WORLD_ALIGNED)
            jac = jac[self._axes].dot(self._chain_map)
            q_ext += np.asarray(task_force, dtype=float)[self._axes].dot(jac)
        if drone_forces is not None:
            q_ext += np.asarray(drone_forces, dtype=float)[:, self._axes].reshape(-1).dot(hinge_jacobian)
        return q_ext

    def _point_dynamics(self, s, ds):
        """M_s(s), c_s(s, s') and the hinge Jacobian J_h(s) (n_d len(force_axes), n_s) of the point-drone planning
        model.

        The same as ``robot.planar("point").mass_matrix_and_bias(s, ds)`` and ``.hinge_jacobian(s)`` to
        round-off, from Pinocchio's CRBA, RNEA and joint Jacobians at q = (s, out-of-plane
        coordinates and rolls 0): the point drones' rolls carry no inertia.
        """
        r, t = self._point_robot, self._chain_map
        model, data = r.model, r.data
        qp = t.dot(s)
        m = pin.crba(model, data, qp)
        m = t.T.dot(np.where(self._upper, m, m.T)).dot(t)  # CRBA fills the upper triangle only
        c = t.T.dot(pin.nonLinearEffects(model, data, qp, t.dot(ds)))
        pin.computeJointJacobians(model, data, qp)
        jac = np.concatenate([pin.getJointJacobian(model, data, h, pin.LOCAL_WORLD_ALIGNED)[self._axes]
                              for h in r.hinge_joint_ids]).dot(t)  # the force axes (world y, z) of each hinge
        return m, c, jac

    def _attitude_in_wind(self, q, attitude, task_force, drone_forces):
        """The attitude model (2.12) with the known external forces: c - Q_ext, Q_ext on the full coordinates.

        Q_ext = J_p^T f_p + sum_i J_c,i^T f_i (J_p: the task point's, J_c,i: drone i's centre of mass's, world
        aligned, 3D), from a Pinocchio kinematics pass at q: the wind's push on the chain moves the rolls
        through the coupled dynamics, which the inner loop's torques must then not fight.
        """
        r = self.robot
        model, data = r.model, r.data
        pin.computeJointJacobians(model, data, r.T.dot(q))
        pin.updateFramePlacements(model, data)
        q_ext = np.zeros(r.nq)
        if task_force is not None:
            jac = pin.getFrameJacobian(model, data, self._full_task_frame, pin.LOCAL_WORLD_ALIGNED)[:3]
            jac = jac.dot(r.T)
            q_ext += np.asarray(task_force, dtype=float).dot(jac)
        if drone_forces is not None:
            for frame, f in zip(r.drone_frame_ids, np.asarray(drone_forces, dtype=float), strict=True):
                q_ext += f.dot(pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[:3].dot(r.T))
        return dataclasses.replace(attitude, c=attitude.c - q_ext)

    def _attitude_gains(self) -> tuple[np.ndarray, np.ndarray]:
        """K_pa, K_da of q_a = ``layout.attitude`` (the orientation gains for the coordinates that are not a
        drone's attitude, psi and theta, the attitude gains for the drones'), rebuilt only when the settings
        change; with them the compiled inner loop's constants (``fpr/_native/alloc.c``'s ``inner``: the robot
        kind's ``compiled_inner_constants``, then K_pa, K_da; None when the kind says it does not fit), as
        ``self._gains = (key, kp, kd, kp list, kd list, constants)``.
        """
        st = self.settings
        key = (st.orientation_frequency, st.orientation_damping, st.attitude_frequency, st.attitude_damping,
               st.lateral_frequency, st.lateral_damping, st.max_pitch)
        if self._gains is None or self._gains[0] != key:
            kp = np.array([st.attitude_frequency**2 if wrap else st.orientation_frequency**2 for wrap in self._wrap])
            kd = np.array([2 * st.attitude_damping * st.attitude_frequency if wrap
                           else 2 * st.orientation_damping * st.orientation_frequency for wrap in self._wrap])
            robot_part = self.robot.kind.compiled_inner_constants(st)
            constants = None if robot_part is None else np.array(robot_part + kp.tolist() + kd.tolist(), dtype=float)
            self._gains = (key, kp, kd, kp.tolist(), kd.tolist(), constants)  # lists: _inner_python's loop
        return self._gains[1], self._gains[2]

    def _inner_python(self, q, v, reference: Reference):
        """The inner loop's float part in Python: (thrust f_i (n_d,), u_a (n_a,), the drones' attitude targets
        (n_d,), pitch reference) from the measured state, the held outer-loop force and the reference's
        feed-forward: the robot kind's ``attitude_targets``, then the attitude loop (2.23) on them, the drones'
        attitude errors taken as the shortest angle. The reference of the native part (the same operations in
        the same order; the tests hold the two equal to round-off).
        """
        targets = self.robot.kind.attitude_targets(q, v, self._force, reference, self.settings)
        ql, vl = q.tolist(), v.tolist()  # on floats: a few numbers each
        self._attitude_gains()  # K_pa, K_da up to date, their lists in self._gains
        kp, kd = self._gains[3], self._gains[4]
        u_a = []
        for i, goal, kp_k, kd_k, rate_k, acc_k, wrap in zip(self._attitude_list, targets.target, kp, kd, targets.rate,
                                                            targets.acceleration, self._wrap, strict=True):
            error = ql[i] - goal
            if wrap:  # a drone's attitude: the shortest angle
                error = math.remainder(error, _TWO_PI)
            u_a.append(acc_k - kp_k * error - kd_k * (vl[i] - rate_k))
        drone_targets = [targets.target[k] for k in self._drone_places]
        return np.array(targets.thrust), np.array(u_a), np.array(drone_targets), targets.pitch

    def _inner_kernel(self):
        """The native inner loop's function (:mod:`fpr._native`'s part ``inner``, ``fpr/_native/alloc.c``), or None
        for :meth:`_inner_python`.
        """
        module = native.use("inner")
        if module is None or len(self.attitude) > module.MAX_ATTITUDE:
            return None
        self._attitude_gains()
        return module.inner if self._gains[5] is not None else None  # the kind's word: the compiled part fits

    def native_outer(self):
        """What the native closed loop's outer-loop updates need (``fpr/_native/cpp/outer.cpp``: :meth:`update`'s
        outer part, the same operations in the same order): (the point-drone model's native terms, the constants
        vector), or None when the robot kind's outer loop has no compiled form (its ``compiled_outer_constants``) or
        the native part is not built (the updates then run in Python).

        The constants: n, n_s, n_d, the kind's solve and its parameter, K_p, K_d, K_i, the integral's bound, the
        observer's bandwidth, momentum feedback, the singular band, the number of force axes and their world rows,
        then the chain's indices, the other coordinates', the rolls' places among those, the point model's hinge joints.
        """
        r, st = self.robot, self.settings
        kind_part = r.kind.compiled_outer_constants(st)
        module = native.module("_pinocchio")
        point = self._point_robot
        if kind_part is None or module is None or point.model.nq != point.model.nv:
            return None
        n_s = len(self.chain)
        terms = module.Minimal(point.model, point.model.createData(), self._chain_map, [], np.zeros((0, n_s)), [], [])
        kp, kd = st.chain_gains
        axes = ["xyz".index(a) for a in r.kind.force_axes]
        header = [r.nq, n_s, r.n_drones, kind_part[0], kp, kd, st.chain_integral, st.integral_limit,
                  st.observer_bandwidth, float(st.momentum_feedback), st.singular_band, kind_part[1], len(axes), *axes]
        indices = self.chain.tolist() + self._others.tolist() + self._other_rolls.tolist() + list(point.hinge_joint_ids)
        return terms, np.array(header + indices, dtype=float)

    def _inner_tick(self, q, v, reference: Reference):
        """The inner loop's float part on the held force: (thrust, u_a, attitude targets, pitch), natively where
        it fits (:meth:`_inner_python`'s operations, in its order), else in Python.
        """
        kernel = self.__dict__.get("_inner")
        if kernel is None or kernel[0] is not native.use("inner"):  # the switch read again when it changed
            kernel = self._inner = (native.use("inner"), self._inner_kernel())
        inner = None
        if kernel[1] is not None:  # in C: _inner_python's operations, in its order (None: a result not finite)
            self._attitude_gains()  # its constants up to date, in self._gains
            inner = kernel[1](q, v, self._force, reference.attitude_rate, reference.attitude_acceleration,
                              self._gains[5])
        return self._inner_python(q, v, reference) if inner is None else inner

    def update(self, t: float, q, v, reference: Reference) -> ControlOutput:
        """One inner-loop tick at time t [s] with the measured (q, v); the outer loop when due."""
        st = self.settings
        updated = self._force is None or t - self._last_outer >= 1.0 / st.outer_rate - 1e-9
        if updated:
            if np.isfinite(self._last_outer) and not self.limiter.limited:  # held while F is limited
                error = q[self.chain] - reference.motion[0]
                self._integral = np.minimum(np.maximum(self._integral + error * (t - self._last_outer),
                                                    -st.integral_limit), st.integral_limit)  # np.clip
            self.limiter.limited = False
            # M(q) once for the observer and the momentum feedback
            mass = self.robot.mass_matrix(q) if st.observer_bandwidth > 0 or st.momentum_feedback else None
            if st.observer_bandwidth > 0:
                self._observe(t - self._last_outer if np.isfinite(self._last_outer) else 0.0, q, v, mass)
            self._force = self.outer(q, v, reference, mass)
            if st.force_limits:  # every drone's F with the authority to turn (controllers/authority.py)
                self._force = self.limiter.hold(q, v, self._force)
            self._last_outer = t
        thrust, u_a, attitude_target, pitch = self._inner_tick(q, v, reference)
        attitude = self.robot.attitude_model(q, v)
        own = attitude.c
        if reference.task_force is not None or reference.drone_forces is not None:  # the known wind (2.12)
            attitude = self._attitude_in_wind(q, attitude, reference.task_force, reference.drone_forces)
        if self.observer is not None:  # the estimated one
            attitude = dataclasses.replace(attitude, c=attitude.c - self.observer.estimate)
        allocation = self.allocator.solve(attitude, thrust, u_a)
        if updated and st.force_limits and allocation.any_saturated:  # a new F the rotors cannot follow
            force = self.limiter.limit(q, v, reference, self._force, attitude)
            if force is not self._force:  # F within what they can give (controllers/saturation.py)
                self._force = force
                thrust, u_a, attitude_target, pitch = self._inner_tick(q, v, reference)
                allocation = self.allocator.solve(attitude, thrust, u_a)
        speeds = np.sqrt(np.maximum(allocation.speeds_squared, 0.0))
        if st.observer_bandwidth > 0:  # the inputs' generalised force until the next tick, and the known wind's
            known = own - attitude.c if self.observer is None else own - attitude.c - self.observer.estimate
            self._applied += (attitude.j_f.T.dot(allocation.thrust)
                              + attitude.j_tau.T.dot(allocation.torque.reshape(-1)) + known)
            self._ticks += 1
        return ControlOutput(speeds, allocation, self._force, attitude_target, thrust, u_a, pitch)


_TWO_PI = 2 * math.pi


def _force_rows(force_axes) -> slice | list[int]:
    """The rows of a world (x, y, z) vector along ``force_axes``: a slice where they follow each other (("y", "z"):
    rows 1:3), else their list.
    """
    rows = ["xyz".index(a) for a in force_axes]
    return slice(rows[0], rows[-1] + 1) if rows == list(range(rows[0], rows[-1] + 1)) else rows
