"""What a robot must say about itself: the :class:`RobotKind` protocol.

Generic code (the model, the planners, the controller, the simulator, the views) never tests a robot's
name; it asks the robot's *kind*, ``robot.kind``, an instance of a :class:`RobotKind` subclass bound to
one :class:`~fpr.model.robot.Robot` (its ``robot`` attribute). A subclass is one robot module
(:mod:`fpr.robots.fpr`, :mod:`fpr.robots.prototype`, or a module of your own) registered by name in
:mod:`fpr.robots` (``register(MyRobot)``).

The members come in two groups, in the manner of Pink's ``Task`` or Crocoddyl's abstract action models:

* **class attributes**, known without a model (the registry, missions and file columns use them):
  ``name``, ``xacro``, ``urdf``, ``layout``, ``chain_units``, ``task_coordinates``, ``assembly_modes``,
  ``crosses_singularity``, ``singular_margins``, ``margin_hints``, ``reference_chain``,
  ``mass_parameters``, ``titles``, ``task_point_labels``, ``task_frame``, ``fixed_point``, ``force_axes``,
  ``out_of_plane``, ``constraint_kinds``, ``attitude_kinds``, ``drone_angle_column``;
* **methods** of the bound instance, which read the robot's geometry from its model: link lengths and
  ground, kinematics (``drone_joints``, ``drone_joint_velocities``, ``chain_jacobian``,
  ``task_points``; for figures ``joint_legends``, ``height_panels``), workspace and assembly modes
  (``workspace_margins``, ``crossing_margins``, ``planning_pose``, ``check_pose``, ``assembly_mode``,
  ``coordinate_axes``, ``mission_region``), what the drones must do along a motion (``motion_inputs``,
  ``generalized_forces``, ``thrust_vectors``, ``needs_high_derivatives``, ``attitude_margins``,
  ``full_state``, ``singularity_distance``), the closure of the plant (``closed_chain``, ``closure_reader``) and
  the simulator's take-off (``level_attitude``), the controller's outer-loop solve (``outer_loop_forces``), the
  attitude of a thrust vector (``force_attitude``) and its inner loop's targets (``attitude_targets``,
  ``lateral_loop``, ``compiled_inner_constants``).

Members marked *required* must be given by every robot; the others have defaults here that suit a
robot whose planning coordinates are its task coordinates and whose drone-joint Jacobian is invertible
in its workspace. Shapes: ``s`` is the planning vector (``layout.chain``, n_s entries) with any leading
batch shape, n_d is the number of drones, N a number of samples.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cached_property
from pathlib import Path
from typing import ClassVar

import numpy as np

from fpr.model import inverse_dynamics
from fpr.model.errors import FprError, ModelArgumentError, RobotDefinitionError
from fpr.model.jets import Jet
from fpr.model.kinematics import check_margins, last_axis, singularity_margin
from fpr.model.robot import Layout
from fpr.robots import planar_control

#: The constraint kinds of a robot whose drone joints stay above a ground and whose drones have one roll
#: each (the built-in robots): entries of ``RobotKind.constraint_kinds``.
GROUND_KIND = ("m", "drone joint height above the ground margin z >= -L + m_gd (3.27, 3.40-3.41)")
ROLL_KIND = ("rad", "drone roll |phi_i| <= pi/2 - m_ga (3.33, 3.45)")


class RobotKind:
    """The robot-specific part of a :class:`~fpr.model.robot.Robot` (see the module docstring).

    Subclass it, fill in the class attributes and the required methods, and register the subclass
    (:func:`fpr.robots.register`). The robot builds its kind with ``kind_class(robot)``.

    Class attributes:
        name: the registry name, e.g. "fpr" (required).
        xacro: the robot's top-level xacro file, anywhere on disk (required).
        urdf: its generated URDF, read by :func:`fpr.robots.load`; None to run xacro at every load.
        layout: thesis coordinates -> Pinocchio joints, drones, planning coordinates
            (:class:`~fpr.model.robot.Layout`, required).
        chain_units: unit of each planning coordinate ``layout.chain``, e.g. ("m", "m", "rad", "rad")
            (required; CSV columns, mission labels, figure axes).
        task_coordinates: (name, unit) of the coordinates of a task-space way point; None when they
            are the planning coordinates (then ``planning_pose`` copies task-space way points).
        assembly_modes: the assembly modes a mission may name (``arm``), e.g. ("down", "up"); empty
            when the mission's ``arm`` is ignored.
        crosses_singularity: whether :mod:`planners.crossing.solve` can plan a crossing of the robot's
            Type-2 singularity (then ``crossing_margins`` is given).
        singular_margins: prefixes of the names of the workspace margins that keep the last planning
            coordinate away from the Type-2 singularity (e.g. ("q21",)): violated, they raise a
            SingularityError.
        margin_hints: what to do when a workspace margin is violated, by prefix of its name.
        reference_chain: a static pose of the chain inside the workspace, the robot's default
            configuration (hover tests, timing, the controller's hover linearisation, drawings) [m, rad].
        mass_parameters: the xacro arguments that are masses (a controller that believes the robot
            heavier scales them, :mod:`fpr.sim.closed_loop`).
        titles: figure titles by figure name ("path", "coordinates", ..., "sim_path", ..., see
            :mod:`fpr.views.figures`).
        task_point_labels: (the main task-space point, the other joints) of ``task_points``, for legends.
        task_frame: the Pinocchio frame of the main task-space point (3D scenes).
        fixed_point: the coordinates along ``force_axes`` of a point of the chain fixed in the world [m], or
            None.
        force_axes: the world axes of the thrust vectors F_i, the drone joints r_i and their velocities, the
            points of ``task_points`` and ``fixed_point``: ("y", "z") for a robot that moves in the world's
            y-z plane. Arrays of such vectors have ``len(force_axes)`` entries in their last axis.
        out_of_plane: the coordinates that a plan keeps at 0 and a simulation may move (the simulation's
            summary and the out-of-plane figure report them), e.g. ("x", "psi", "theta"); empty for a robot
            that tracks all of its coordinates.
        constraint_kinds: the kinds of the robot's own constraints, by the prefix of their names, each with
            its (unit, what it bounds): its workspace margins' kinds (``workspace_margins``,
            ``crossing_margins``) and its drones' attitude margins' (``"roll"`` for drones with one roll
            each). They join the generic kinds of :data:`planners.problem.motion.CONSTRAINT_KINDS`; a kind
            named by two robots has one unit.
        attitude_kinds: which of ``constraint_kinds`` bound the drones' attitude (the others bound the
            workspace, a function of the planning coordinates alone).
        drone_angle_column: the name (followed by the drone's number) of the ``trajectory.csv`` columns that hold
            the ``roll`` and ``roll_rate`` fields of :class:`~fpr.model.inverse_dynamics.MotionInputs` ("phi":
            phi1, phi1_d...).
    """

    name: ClassVar[str]
    xacro: ClassVar[Path]
    urdf: ClassVar[Path | None] = None
    layout: ClassVar[Layout]
    chain_units: ClassVar[tuple[str, ...]]
    task_coordinates: ClassVar[tuple[tuple[str, str], ...] | None] = None
    assembly_modes: ClassVar[tuple[str, ...]] = ()
    crosses_singularity: ClassVar[bool] = False
    singular_margins: ClassVar[tuple[str, ...]] = ()
    margin_hints: ClassVar[Mapping[str, str]] = {}
    reference_chain: ClassVar[tuple[float, ...]]
    mass_parameters: ClassVar[tuple[str, ...]] = ("drone_mass", "link_mass", "end_effector_mass")
    titles: ClassVar[Mapping[str, str]] = {}
    task_point_labels: ClassVar[tuple[str, str]] = ("end-effector", "drone joints")
    task_frame: ClassVar[str] = "end_effector"
    fixed_point: ClassVar[tuple[float, ...] | None] = None
    force_axes: ClassVar[tuple[str, ...]] = ("y", "z")
    out_of_plane: ClassVar[tuple[str, ...]] = ()
    constraint_kinds: ClassVar[Mapping[str, tuple[str, str]]] = {}
    attitude_kinds: ClassVar[tuple[str, ...]] = ()
    drone_angle_column: ClassVar[str] = "phi"

    def __init__(self, robot):
        """Bind the kind to ``robot`` (a :class:`~fpr.model.robot.Robot` built from this kind's layout)."""
        self.robot = robot

    # ------------------------------------------------------------------ static information
    @classmethod
    def planning_columns(cls) -> tuple[tuple[str, str], ...]:
        """(name, unit) of each planning coordinate, e.g. (("y", "m"), ..., ("q21", "rad"))."""
        return tuple(zip(cls.layout.chain, cls.chain_units, strict=True))

    @classmethod
    def mission_coordinates(cls, space: str) -> tuple[str, ...]:
        """Labels "name [unit]" of a way point's entries in ``space`` ("task" or "joint")."""
        pairs = cls.task_coordinates if space == "task" and cls.task_coordinates is not None \
            else cls.planning_columns()
        return tuple(f"{n} [{u}]" for n, u in pairs)

    @classmethod
    def assembly_mode(cls, pose) -> str | None:
        """The assembly mode of a planning pose, one of ``assembly_modes``, or None (none or undecided).

        Args:
            pose: planning coordinates, shape (n_s,).
        """
        return None

    @classmethod
    def describe_mode(cls, mode: str) -> str:
        """A mode in words for messages, e.g. "up (q2 < 0)"."""
        return mode

    # ------------------------------------------------------------------ geometry read from the model
    @cached_property
    def link_lengths(self) -> tuple[float, ...]:
        """Joint-to-joint length of each link of the chain [m] (required)."""
        raise NotImplementedError

    @property
    def ground_height(self) -> float:
        """z of the ground [m]: -L, with L the link length of the first drone's link (DESIGN.md).

        Required of a robot whose first drone does not hang on a link (its hinge at the origin of the body
        that carries it: L = 0 says nothing of the ground).

        Raises:
            RobotDefinitionError: the robot's first drone hinge has no offset from its parent body.
        """
        length = self.robot.link_length
        if length == 0.0:
            raise RobotDefinitionError(self.name, "its first drone's hinge sits at the origin of the body that "
                                                  "carries it (no link): give the kind a ground_height")
        return -length

    # ------------------------------------------------------------------ kinematics
    def drone_joints(self, s) -> np.ndarray:
        """Drone joint positions r_i (along ``force_axes``: world y, z), shape (..., n_d, 2) [m].

        Default: from the point-drone planar model (exact, not closed form).
        """
        s = last_axis(s, len(self.layout.chain), "s")
        return np.stack([h.position(s) for h in self.robot.planar("point").hinges], axis=-2)

    def drone_joint_velocities(self, s, s_dot) -> np.ndarray:
        """Drone joint velocities r_i', shape (..., n_d, 2) [m/s], for s' [m/s, rad/s] of the same shape as s."""
        jac = self.chain_jacobian(s)
        v = np.einsum("...ij,...j->...i", jac, last_axis(s_dot, len(self.layout.chain), "s_dot"))
        return v.reshape(v.shape[:-1] + (-1, len(self.force_axes)))

    def chain_jacobian(self, s) -> np.ndarray:
        """J_h = d[r_1; ...; r_nd]/ds, shape (..., 2 n_d, n_s) (seed 2.6, 3.35).

        Default: from the point-drone planar model.
        """
        return self.robot.planar("point").hinge_jacobian(last_axis(s, len(self.layout.chain), "s"))

    def task_points(self, s) -> tuple[np.ndarray, np.ndarray]:
        """The points a path figure draws: (the main point (..., 2), the other joints (..., k, 2)) [m].

        Labelled by ``task_point_labels``. Default: the end-effector p = s[..., :2] and the drone joints.
        """
        s = last_axis(s, len(self.layout.chain), "s")
        return s[..., :2], self.drone_joints(s)

    def joint_legends(self) -> tuple[tuple[str, str], ...]:
        """(legend, figure id) of each of the other joints of :meth:`task_points`, for path figures.

        Default: the drone joints, ("r1 (drone 1 joint)", "r1"), ...
        """
        return tuple((f"r{i + 1} (drone {i + 1} joint)", f"r{i + 1}") for i in range(self.robot.n_drones))

    def height_panels(self) -> tuple[tuple[str, str, str, int, int | None], ...]:
        """The panels of the heights figure (seed Fig. 3.29-3.30, 3.46-3.47), one per point whose z is drawn.

        Each is (axis label, legend, "main" or "joint", index among the other joints of :meth:`task_points`
        (0 for "main"), the drone whose centre of mass is drawn beside it or None). Default: z of each drone
        joint r_i, with drone i.
        """
        return tuple((rf"$z_{i + 1}$ [m]", f"drone {i + 1} joint", "joint", i, i) for i in range(self.robot.n_drones))

    # ------------------------------------------------------------------ workspace and assembly modes
    def workspace_margins(self, s, mode: str | None = None) -> dict[str, np.ndarray]:
        """Signed margins of the geometric constraints (>= 0 where satisfied), each of shape (...) (required).

        Names start with the constraint kind (:data:`planners.problem.motion.CONSTRAINT_KINDS`: ``ground_1``,
        ``q21_low``...). Units: m or rad.

        Args:
            s: planning coordinates, shape (..., n_s) (complex allowed: the planner differentiates by
                complex step).
            mode: the assembly mode whose bounds apply; None: the mode of the first sample.
        """
        raise NotImplementedError

    def crossing_margins(self, s, crossing_sign) -> dict[str, np.ndarray]:
        """The workspace margins of a motion that crosses the Type-2 singularity once (``crosses_singularity``).

        Args:
            s: planning coordinates, shape (N, n_s).
            crossing_sign: per sample +1 before the crossing, -1 after it, 0 at it, shape (N,).
        """
        raise FprError(f"the {self.name} cannot plan a crossing of its Type-2 singularity")

    def singularity_distance(self, s) -> np.ndarray:
        """The angular distance of planning poses to the robot's Type-2 singular set, shape (...) [rad] (reports).

        Default: the last planning coordinate's distance to {k pi} (the FPR's q21, the prototype's q2).
        """
        return singularity_margin(np.asarray(s)[..., -1])

    def check_pose(self, pose, mode: str | None, what: str) -> None:
        """Raise a WorkspaceError / SingularityError naming the first violated margin at a planning pose.

        Args:
            pose: planning coordinates, shape (n_s,).
            mode: the assembly mode the pose must be in (one of ``assembly_modes``), or None.
            what: the pose's name in messages (e.g. "way_points[2] = [...] of mission 'square'").
        """
        check_margins(self.workspace_margins(pose, mode), pose, what, margins=self.robot.margins,
                      singular=self.singular_margins, hints=dict(self.margin_hints))

    def planning_pose(self, point, space: str, mode: str | None, what: str) -> np.ndarray:
        """A way point in planning coordinates (the inverse kinematics of a task-space point).

        Args:
            point: the way point in ``space`` coordinates, shape (n,).
            space: "task" or "joint".
            mode: the assembly mode to solve in (one of ``assembly_modes``), or None.
            what: the way point's name in messages.

        Returns:
            s, shape (n_s,).

        Raises:
            WorkspaceError, SingularityError: the point is out of reach, or on a singularity.
        """
        if space == "task" and self.task_coordinates is not None:
            raise ModelArgumentError("space", space, f"{what}: the {self.name} has no inverse kinematics "
                                                     "for task-space way points: write them in joint space")
        return np.array(point, dtype=float)

    def mission_region(self, space: str, mode: str | None) -> tuple[np.ndarray, np.ndarray] | None:
        """(lower, upper) corners of the box of way points a random mission of this robot may visit, in
        ``space`` coordinates ("task" or "joint"; in ``mode``, one of ``assembly_modes`` or None), for
        :func:`fpr.bench.missions.random_mission`. Its way points are drawn inside it and kept only where
        :meth:`check_pose` holds, so the box may overlap the workspace's borders. Default: None (no
        region: give one to the generator).
        """
        return None

    def coordinate_axes(self) -> list[tuple[str, tuple[float, float] | None]]:
        """(axis label, (lower, upper) bound or None) of each planning coordinate, for figures [m, rad].

        Default: "name [unit]" and no bound.
        """
        return [(f"{n} [{u}]", None) for n, u in self.planning_columns()]

    # ------------------------------------------------------------------ what the drones must do along a motion
    def motion_inputs(self, motion, external=None) -> inverse_dynamics.MotionInputs:
        """Thrusts, attitudes, torques and rotor speeds along a motion of the chain
        (:func:`fpr.model.inverse_dynamics.inverse_dynamics` asks this).

        Args:
            motion: s and its time derivatives 0..4, shape (5, N, n_s) (or (5, n_s) for one sample); rows 5
                and 6 are used where ``needs_high_derivatives`` says so.
            external: generalised force Q_ext [N or N m] of known external forces on the chain coordinates,
                shape (N, n_s), or a Jet of it with its time derivatives, or None.

        Returns:
            the :class:`~fpr.model.inverse_dynamics.MotionInputs` at the N samples. Default: the planar
            robots' (:func:`fpr.model.inverse_dynamics.planar_inverse_dynamics`).
        """
        return inverse_dynamics.planar_inverse_dynamics(self.robot, motion, external)

    def attitude_margins(self, inputs, scaled: bool) -> list[list[tuple[str, str, np.ndarray]]]:
        """The planner's margins (>= 0 where satisfied) on the drones' attitude, per drone: (constraint name,
        detail, margin (N,)) of each row, the names' kinds among ``attitude_kinds``.

        Args:
            inputs: the :class:`~fpr.model.inverse_dynamics.MotionInputs` of a motion (or an object with the
                attributes the kind reads: a simulation's measured rolls, :mod:`fpr.sim.margins`).
            scaled: True for the optimiser's smooth, O(1) rows, False for natural units.

        Returns:
            one list of rows per drone. Default: the roll bound ``|phi_i| <= pi/2 - m_ga`` (seed 3.33, 3.45),
            ``roll_<i>`` "negative" and "positive", the same rows scaled or not [rad].
        """
        limit = np.pi / 2 - self.robot.margins.angle
        rows = []
        for i in range(self.robot.n_drones):
            roll = inputs.roll[:, i]
            rows.append([(f"roll_{i + 1}", "negative", limit + roll), (f"roll_{i + 1}", "positive", limit - roll)])
        return rows

    def full_state(self, inputs) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Configurations, velocities and accelerations of the full model along a motion, each of shape (N, n).

        Args:
            inputs: the :class:`~fpr.model.inverse_dynamics.MotionInputs` of the motion.

        Returns:
            (q, q', q''). Default: the chain coordinates from the motion, each drone's attitude coordinates
            (``layout.drone_attitude``) from ``inputs.attitude`` and its derivatives, the others (the
            ``out_of_plane`` ones) 0.
        """
        robot = self.robot
        n = inputs.motion.shape[1]
        out = [np.zeros((n, robot.nq)) for _ in range(3)]
        chain = robot.indices(robot.layout.chain)
        attitude = robot.indices(robot.layout.rolls)  # drone_attitude flattened, drone after drone
        for k, value in enumerate((inputs.attitude, inputs.attitude_rate, inputs.attitude_acceleration)):
            out[k][:, chain] = inputs.motion[k]
            out[k][:, attitude] = value.reshape(n, -1)
        return tuple(out)

    # ------------------------------------------------------------------ thrust from motion
    def generalized_forces(self, motion: Jet) -> Jet:
        """b = M_s s'' + c_s of the point-drone model (each drone a point mass at its joint) along a motion.

        Args:
            motion: s as a Jet of order K >= 2, shape (N, n_s).

        Returns:
            b, Jet of order K - 2, shape (N, n_s) [N or N m]. Default: the planar point model's
            (``robot.planar("point").inverse_dynamics_jet``).
        """
        return self.robot.planar("point").inverse_dynamics_jet(motion)

    def thrust_vectors(self, motion: Jet, generalized: Jet, order: int | None = None) -> Jet:
        """Thrust vectors F_i from J_h(s)^T F = b along a motion (seed 2.16, 3.12, 3.37).

        Args:
            motion: s as a Jet of order K >= 2, shape (N, n_s).
            generalized: b = M_s s'' + c_s of the point-drone model, Jet of order K - 2, shape (N, n_s).
            order: derivative order of the result (default: that of ``generalized``).

        Returns:
            F in world (y, z), Jet of shape (N, n_d, 2) [N]. Default: a plain solve
            (:func:`fpr.model.inverse_dynamics.solve_thrust_vectors`).
        """
        return inverse_dynamics.solve_thrust_vectors(self.robot, motion, generalized, order)

    def needs_high_derivatives(self, s) -> bool:
        """Whether the inverse dynamics at these poses needs the motion's 5th and 6th derivatives.

        Args:
            s: planning coordinates of the samples, shape (N, n_s).
        """
        return False

    # ------------------------------------------------------------------ closure of the plant
    def closed_chain(self, model, axis_offset: float):
        """Build the robot as free-flying drones plus the chain and its loop closure (required).

        Add the drones with :func:`fpr.model.constrained.add_free_drone` (drone 1 first), the chain's
        bodies as a tree hanging from them, and the closure constraints.

        Args:
            model: an empty ``pin.Model`` (gravity set) to fill.
            axis_offset: distance between two closure points on a hinge axis [m], if the closure needs it.

        Returns:
            a :class:`fpr.model.constrained.ClosureTree`.
        """
        raise NotImplementedError

    def closure_reader(self, closed):
        """The reader of the minimal coordinates the closed chain's shared joints do not give (required).

        Args:
            closed: the :class:`fpr.model.constrained.ClosedChainModel` built by :meth:`closed_chain`.

        Returns:
            an object with ``read(q_pin, oMi, reference)``, which fills in the Pinocchio coordinates
            (of the minimal model, shape (n,)) that are not copies of the closed chain's joints from the
            closed chain's joint placements ``oMi`` (``reference``: thesis configuration to unwrap the
            angles to, or None), and ``wrap(q)``, which puts the angles of a thesis configuration read
            without reference into their default ranges (in place).
        """
        raise NotImplementedError

    # ------------------------------------------------------------------ control
    def outer_loop_forces(self, s, b, jacobian, planned_force, singular_band: float) -> np.ndarray:
        """F_i the controller's outer loop asks of the drones: J_h^T F = b at one state (seed 2.16).

        Args:
            s: measured planning coordinates, shape (n_s,).
            b: M_s u_p + c_s, shape (n_s,) [N or N m].
            jacobian: J_h(s), shape (2 n_d, n_s).
            planned_force: the plan's F_i at this instant, shape (n_d, 2) [N], or None.
            singular_band: the controller's regularisation angle near a Type-2 singularity [rad].

        Returns:
            F, shape (n_d, len(force_axes)) [N]. Default: the plain solve.
        """
        return np.linalg.solve(jacobian.T, b).reshape(-1, len(self.force_axes))

    def compiled_outer_constants(self, settings) -> list[float] | None:
        """How the native closed loop (``fpr/_native/cpp/outer.cpp``) performs this kind's :meth:`outer_loop_forces`
        and :meth:`force_attitude`: [solve, parameter], or None when it cannot (then the controller's outer-loop
        updates run in Python).

        Default: [0, 0] (the plain solve J_h^T F = b, the planar roll atan2(-F_y, F_z)) for a kind that keeps both
        defaults with two force axes, None otherwise.
        """
        if (type(self).outer_loop_forces is not RobotKind.outer_loop_forces
                or type(self).force_attitude is not RobotKind.force_attitude or len(self.force_axes) != 2):
            return None
        return [0.0, 0.0]

    def force_attitude(self, force, q=None) -> np.ndarray:
        """The drones' attitude coordinates (``layout.drone_attitude`` flattened) whose thrust axes lie along the
        thrust vectors ``force`` (n_d, len(force_axes)) [N]: the references of the controller's momentum feedback.
        ``q``: the measured configuration (n,), for a kind whose drones' attitude coordinates are relative to the
        chain (the spatial FPR's ball angles), or None.

        Default: the planar robots' roll phi_i = atan2(-F_iy, F_iz) (seed 2.20), shape (n_d,) [rad].
        """
        return np.arctan2(-force[:, 0], force[:, 1])

    @cached_property
    def _planar_inner(self) -> planar_control.PlanarInner:
        """The robot's constants of the planar inner loop (:func:`fpr.robots.planar_control.planar_inner`)."""
        return planar_control.planar_inner(self)

    @property
    def lateral_loop(self) -> tuple[int, float] | None:
        """(position of x in q, d x'' / d theta at the hover pose [m/s^2/rad]) of the inner loop's lateral loop,
        which holds an out-of-plane position with the pitch, or None (no such loop).

        Default: the loop runs for a robot with ``"x"`` among its ``out_of_plane`` coordinates (the FPR), its
        sensitivity from the model (:func:`fpr.robots.planar_control.lateral_sensitivity`).
        """
        inner = self._planar_inner
        return None if inner.lateral is None else (inner.lateral, inner.pitch_gain)

    def attitude_targets(self, q, v, force, reference, settings) -> planar_control.AttitudeTargets:
        """The float part of the controller's inner loop at one tick: the drones' thrusts and the attitude loop's
        targets with their feed-forward (seed 2.15, 2.20).

        Args:
            q: measured configuration in thesis coordinates, shape (n,) [m, rad].
            v: measured velocity, shape (n,) [m/s, rad/s].
            force: the outer loop's F_i (:meth:`outer_loop_forces`), shape (n_d, len(force_axes)) [N].
            reference: the controller's :class:`~controllers.ctc.Reference` at this instant (its
                ``attitude_rate`` and ``attitude_acceleration``, the drones' attitude coordinates'
                feed-forward, ``layout.drone_attitude`` flattened).
            settings: the controller's :class:`~controllers.ctc.ControllerSettings` (the lateral loop's
                gains and ``max_pitch``).

        Returns:
            the :class:`~fpr.robots.planar_control.AttitudeTargets` (floats): thrusts f_i (n_d), targets, rates
            and accelerations of the coordinates ``layout.attitude`` (n_a), the lateral loop's pitch. The
            controller closes the attitude loop on them, the drones' attitude coordinates' errors taken as the
            shortest angle. Default: the planar robots' (:mod:`fpr.robots.planar_control`): the roll along F_i,
            the thrust along the measured thrust axis, psi_d = 0 and theta_d from the lateral loop.
        """
        return planar_control.planar_attitude_targets(self._planar_inner, q, v, force, reference, settings)

    def compiled_inner_constants(self, settings) -> list[float] | None:
        """The robot's part of the compiled inner loop's constants (``fpr/_native/alloc.c``'s ``inner``, which
        performs the default :meth:`attitude_targets` and the attitude loop in C), or None when it does not fit
        the robot (then the controller runs :meth:`attitude_targets` in Python).

        Default: :func:`fpr.robots.planar_control.compiled_constants` for a kind that keeps the default
        :meth:`attitude_targets`, None for one that overrides it.
        """
        if type(self).attitude_targets is not RobotKind.attitude_targets:
            return None
        return planar_control.compiled_constants(self._planar_inner, settings)

    # ------------------------------------------------------------------ simulation
    def level_attitude(self, q) -> np.ndarray:
        """The configuration ``q`` (shape (n,)) with the drones level: the take-off pose, at rest on the ground.

        Default: the drones' attitude coordinates (``layout.drone_attitude``, the rolls) set to 0, on a copy.
        """
        q = np.array(q, dtype=float)
        q[self.robot.indices(self.layout.rolls)] = 0.0
        return q


__all__ = ["GROUND_KIND", "ROLL_KIND", "RobotKind"]
