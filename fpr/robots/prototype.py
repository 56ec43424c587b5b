"""The lab prototype of the FPR: one quadrotor, the other end of the passive chain pinned at a fixed point (seed 3.3).

Everything specific to the prototype, for generic code to ask through ``robot.kind`` (:class:`Prototype`):

* coordinates: ``q = [psi theta q1 q2 phi1]``; the planning vector is xi = [q1 q2] [rad]; a task-space
  way point is the drone joint (y, z) [m];
* kinematics (DESIGN.md, seed 3.35): fixed joint at the origin, joint 2 = L u(q1), drone joint
  (joint 3) = L u(q1) + L u(q1 + q2), both links of length L. Two assembly modes: "arm down" is
  q2 > 0, "up" q2 < 0. Type-2 singularity: sin(q2) = 0, null(J_pr) = span([-1, 2]) at q2 = 0;
* workspace margins (seed 3.40-3.46) in either mode, and across q2 = 0 for a singularity crossing;
* thrust from motion exact through q2 = 0 and the controller's regularised tension there
  (:mod:`fpr.robots.prototype_thrust`), the closure of the plant (the chain's end held at the fixed point),
  figure titles.

The functions accept a trailing coordinate axis with any leading batch shape.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import pinocchio as pin

from fpr.model.constrained import ClosureTree, add_free_drone, euler_zyx
from fpr.model.description import URDF_DIR
from fpr.model.errors import ModelArgumentError, NotUniformError, SingularityError, WorkspaceError
from fpr.model.jets import Jet
from fpr.model.kinematics import check_margins, last_axis, singularity_margin, u, u_perp
from fpr.model.parameters import Margins
from fpr.model.robot import Layout
from fpr.robots import prototype_thrust
from fpr.robots.base import GROUND_KIND, ROLL_KIND, RobotKind

LAYOUT = Layout(
    coordinates=("psi", "theta", "q1", "q2", "phi1"),
    joints={
        "pivot_yaw": {"psi": 1.0},
        "pivot_pitch": {"theta": 1.0},
        "q1": {"q1": 1.0},
        "q2": {"q2": 1.0},
        "drone_1_hinge": {"phi1": 1.0, "q1": -1.0, "q2": -1.0},
    },
    drones=("drone_1",),
    chain=("q1", "q2"),
    attitude=("psi", "theta", "phi1"),
    drone_attitude=(("phi1",),),
    euler_root=False,
)
"""The prototype's coordinates and their Pinocchio joints (the drone hinge is relative to link 2)."""

ARMS = ("down", "up")
"""The prototype's assembly modes: "down" (q2 > 0) and "up" (q2 < 0)."""


def _check_arm(arm: str) -> None:
    if arm not in ARMS:
        raise ModelArgumentError("arm", arm, f"arm={arm!r}: use 'down' (q2 > 0) or 'up' (q2 < 0)")


def prototype_joints(xi, link_length: float) -> np.ndarray:
    """Joint 2 and drone joint 3 of the prototype, shape (..., 2, 2): [r2, r3] (direct kinematics) [m].

    Args:
        xi: [q1, q2], shape (..., 2) [rad].
        link_length: L [m].
    """
    xi = last_axis(xi, 2, "xi")
    r2 = link_length * u(xi[..., 0])
    r3 = r2 + link_length * u(xi[..., 0] + xi[..., 1])
    return np.stack([r2, r3], axis=-2)


def prototype_jacobian(xi, link_length: float) -> np.ndarray:
    r"""J_pr: d r3 / d xi, shape (..., 2, 2) (seed 3.35, with the sign convention of DESIGN.md).

    .. math:: J_{pr} = L \begin{bmatrix} -\sin q_1 - \sin(q_1+q_2) & -\sin(q_1+q_2) \\
              \cos q_1 + \cos(q_1+q_2) & \cos(q_1+q_2) \end{bmatrix}, \quad \det J_{pr} = L^2 \sin q_2
    """
    xi = last_axis(xi, 2, "xi")
    a = link_length * u_perp(xi[..., 0])
    b = link_length * u_perp(xi[..., 0] + xi[..., 1])
    return np.stack([a + b, b], axis=-1)


def prototype_inverse_kinematics(r3, link_length: float, arm: str = "down", min_margin: float = 0.0) -> np.ndarray:
    """[q1, q2] that put the drone joint at r3.

    Args:
        r3: drone joint position (y, z), shape (..., 2) [m].
        link_length: L [m].
        arm: "down" (q2 > 0) or "up" (q2 < 0).
        min_margin: least accepted distance of q2 to the singular set [rad].

    Raises:
        WorkspaceError: r3 is further than 2 L from the fixed point.
        SingularityError: the solution is closer than ``min_margin`` to q2 = 0 or pi.
        ModelArgumentError: ``arm`` is neither "down" nor "up".
    """
    r3 = last_axis(r3, 2, "r3")
    _check_arm(arm)
    rho2 = np.sum(r3**2, axis=-1)
    c2 = (rho2 - 2 * link_length**2) / (2 * link_length**2)
    if np.any(c2 > 1 + 1e-12) or np.any(c2 < -1 - 1e-12):
        raise WorkspaceError(r3, f"the drone joint must be within 2 L = {2 * link_length:.4g} m of the fixed point "
                                 f"(it is {np.sqrt(rho2).max():.4g} m away)")
    q2 = np.arccos(np.clip(c2, -1.0, 1.0)) * (1.0 if arm == "down" else -1.0)
    q1 = np.arctan2(r3[..., 1], r3[..., 0]) - np.arctan2(np.sin(q2), 1.0 + np.cos(q2))
    xi = np.stack([q1, q2], axis=-1)
    margin = singularity_margin(q2)
    if np.any(margin < min_margin):
        near, far = 2 * link_length * np.sin(min_margin / 2), 2 * link_length * np.cos(min_margin / 2)
        raise SingularityError(
            xi.reshape(-1, 2)[np.argmin(margin.reshape(-1))], float(margin.min()), min_margin,
            f"keep the drone joint between {near:.4g} m and {far:.4g} m from the fixed point",
        )
    return xi


def prototype_workspace_margins(xi, link_length: float, margins: Margins, arm: str = "down") -> dict[str, np.ndarray]:
    """Signed margins of the prototype's geometric constraints (>= 0 where satisfied) (seed 3.40-3.46).

    ``arm`` is the assembly mode: "down" keeps m_ga <= q2 <= pi - m_ga (3.46), "up" the mirror
    -pi + m_ga <= q2 <= -m_ga; ``q2_low`` is then the margin to the singularity q2 = 0 and
    ``q2_high`` the one to q2 = -pi. Ground z = -L [m], fixed point's vertical y = 0 [m].
    """
    xi = last_axis(xi, 2, "xi")
    _check_arm(arm)
    q2 = xi[..., 1] if arm == "down" else -xi[..., 1]
    r = prototype_joints(xi, link_length)
    ground = -link_length + margins.ground
    return {
        "ground_2": r[..., 0, 1] - ground,
        "ground_3": r[..., 1, 1] - ground,
        "fixed_point_2": r[..., 0, 0] - margins.ground,
        "fixed_point_3": r[..., 1, 0] - margins.ground,
        "q1_low": xi[..., 0] + (np.pi / 2 - margins.angle),
        "q1_high": (np.pi / 2 - margins.angle) - xi[..., 0],
        "q2_low": q2 - margins.angle,
        "q2_high": (np.pi - margins.angle) - q2,
    }


class _PrototypeReader:
    """Reads the prototype's pivot off the closed chain (``closure_reader``): yaw, pitch and q1 are the
    Z-Y-X Euler angles of link 1 (the pivot joints turn about z, y, x at the fixed point, without rotation
    in their placements); q2 and the hinge are the closed chain's reversed joints.
    """

    def __init__(self, closed):
        r, model, src = closed.robot, closed.model, closed.robot.model
        self.q2_reversed = model.getJointId("q2_reversed")
        self.q2_placement_inv = src.jointPlacements[src.getJointId("q2")].inverse()
        self.euler_coordinates = r.indices(("psi", "theta", "q1"))
        self.pivot_q = np.array([src.joints[src.getJointId(n)].idx_q for n in ("pivot_yaw", "pivot_pitch", "q1")],
                                dtype=int)

    def read(self, qp, omi, reference) -> None:
        """Fill pivot_yaw, pivot_pitch and q1 into the Pinocchio coordinates ``qp`` (in place)."""
        link_1 = omi[self.q2_reversed] * self.q2_placement_inv
        ref = None if reference is None else reference[self.euler_coordinates]
        qp[self.pivot_q] = euler_zyx(link_1.rotation, ref)

    def native_reads(self) -> tuple[list, list]:
        """:meth:`read` as the native measurement takes it (``fpr/_native/cpp/native.hpp``: EulerRead): the
        pivot's Euler angles off link 1's placement.
        """
        eulers = [(self.q2_reversed, np.eye(4), self.q2_placement_inv.homogeneous, (-1, -1, -1),
                   tuple(int(i) for i in self.pivot_q), tuple(int(i) for i in self.euler_coordinates))]
        return eulers, []

    def wrap(self, q) -> None:
        """Nothing to do: q1 is in [-pi, pi) already, q2 and phi1 continuous."""


class Prototype(RobotKind):
    """The prototype (registry name "prototype"): see the module docstring and :class:`~fpr.robots.base.RobotKind`."""

    name = "prototype"
    xacro = URDF_DIR / "prototype.urdf.xacro"
    urdf = URDF_DIR / "prototype.urdf"
    layout = LAYOUT
    chain_units = ("rad", "rad")
    task_coordinates = (("y", "m"), ("z", "m"))
    assembly_modes = ARMS
    crosses_singularity = True
    reference_chain = (0.3, 1.2)
    singular_margins = ("q2_",)
    out_of_plane = ("psi", "theta")
    constraint_kinds = {
        "ground": GROUND_KIND,
        "fixed_point": ("m", "joint distance y >= m_gd from the fixed point's vertical (3.42-3.43)"),
        "q1": ("rad", "|q1| <= pi/2 - m_ga (3.44)"),
        "q2": ("rad", "Type-2 singularity m_ga <= q2 <= pi - m_ga (3.46)"),
        "crossing": ("rad", "a singularity crossing: q2 keeps the sign of its side of the single crossing, "
                            "|q2| <= pi - m_ga"),
        "roll": ROLL_KIND,
    }
    attitude_kinds = ("roll",)
    margin_hints = {"fixed_point": "move the joint away from the fixed point: its y must be at least m_gd",
                    "q1": "keep |q1| <= pi/2 - m_ga"}
    task_point_labels = ("drone joint", "elbow joint")
    task_frame = "drone_1_hinge"
    fixed_point = (0.0, 0.0)
    titles = {
        "path": "Fig. 3.36 — path of the drone of the prototype",
        "coordinates": "Fig. 3.37 — joint angles of the prototype",
        "energy": "Fig. 3.38 — energy index $J_e$ of the prototype",
        "perturbation": r"Fig. 3.39 — perturbation index $J_\varphi$ of the prototype",
        "thrust": "Fig. 3.40 — thrust of the drone of the prototype",
        "roll": "Fig. 3.41 — roll angle of the drone of the prototype",
        "rotor_speeds": "Eq. 3.47-3.48 — rotor speeds of the drone of the prototype",
        "rotor_forces": r"Eq. 3.47-3.48 — rotor forces $c_T \omega^2$ of the drone of the prototype",
        "sim_path": "Fig. 3.42 — drone trajectory in planning and simulation",
        "sim_coordinates": r"Fig. 3.43-3.45 — joint angles $q_1$, $q_2$ and their errors in simulation",
        "sim_out_of_plane": r"Motion out of the plane of the prototype: pitch $\theta$, yaw $\psi$",
        "sim_roll": "Fig. 3.48 — roll angle of the drone in simulation",
        "sim_heights": "Fig. 3.46-3.47 — height of joint 2 and of the drone joint 3 in simulation",
        "sim_rotor_speeds": "Eq. 3.47-3.48 — rotor speeds of the drone in simulation",
        "sim_rotor_forces": r"Fig. 3.49 — rotor forces $c_T \omega^2$ of the drone in simulation",
        "sim_energy": r"Fig. 3.50-3.51 — energy $J_e$ and perturbation $J_\varphi$, planned and simulated",
    }

    @classmethod
    def assembly_mode(cls, pose) -> str | None:
        """"down" for q2 > 0, "up" for q2 < 0, None on q2 = 0 (left to the singularity check)."""
        q2 = float(np.asarray(pose, dtype=float)[1])
        return "down" if q2 > 0 else "up" if q2 < 0 else None

    @classmethod
    def describe_mode(cls, mode: str) -> str:
        """The mode in words: "down (q2 > 0: ...)" or "up (q2 < 0: ...)"."""
        where = "below" if mode == "down" else "above"
        return f"{mode} (q2 {'>' if mode == 'down' else '<'} 0: the elbow {where} the line from the fixed point " \
               "to the drone)"

    @cached_property
    def link_lengths(self) -> tuple[float, float]:
        """(L1, L2): joint 2 in link 1's frame, the drone hinge in link 2's [m]."""
        model = self.robot.model
        return tuple(float(np.linalg.norm(model.jointPlacements[j].translation))
                     for j in (model.getJointId("q2"), self.robot.hinge_joint_ids[0]))

    @cached_property
    def _length(self) -> float:
        """L, the length of both links (the prototype's closed forms assume equal links) [m]."""
        lengths = self.link_lengths
        if abs(lengths[0] - lengths[1]) > 1e-12 * lengths[1]:
            raise NotUniformError("link_length", lengths, "the prototype's kinematics need links of equal length")
        return self.robot.link_length

    # ------------------------------------------------------------------ kinematics
    def drone_joints(self, s) -> np.ndarray:
        """[r3], the drone joint, shape (..., 1, 2) [m]."""
        return prototype_joints(s, self._length)[..., 1:, :]

    def drone_joint_velocities(self, s, s_dot) -> np.ndarray:
        """[r3'] = J_pr xi', shape (..., 1, 2) [m/s]."""
        jac = prototype_jacobian(s, self._length)
        return np.einsum("...ij,...j->...i", jac, last_axis(s_dot, 2, "s_dot"))[..., None, :]

    def chain_jacobian(self, s) -> np.ndarray:
        """J_pr = d r3 / d xi, shape (..., 2, 2) (:func:`prototype_jacobian`)."""
        return prototype_jacobian(s, self._length)

    def task_points(self, s) -> tuple[np.ndarray, np.ndarray]:
        """(drone joint r3 (..., 2), elbow [r2] (..., 1, 2)) [m]."""
        joints = prototype_joints(s, self._length)
        return joints[..., 1, :], joints[..., :1, :]

    def joint_legends(self) -> tuple[tuple[str, str], ...]:
        """The elbow (joint 2): ("elbow joint", "elbow")."""
        return (("elbow joint", "elbow"),)

    def height_panels(self) -> tuple[tuple[str, str, str, int, int | None], ...]:
        """Joint 2 (the elbow) and joint 3 (the drone joint, with the drone's centre of mass) (Fig. 3.46-3.47)."""
        return ((r"$z_{j2}$ [m]", "joint 2", "joint", 0, None),
                (r"$z_{j3}$ [m]", "joint 3 (drone joint)", "main", 0, 0))

    # ------------------------------------------------------------------ workspace and assembly modes
    def workspace_margins(self, s, mode: str | None = None) -> dict[str, np.ndarray]:
        """:func:`prototype_workspace_margins` in ``mode``; None: the mode of the first sample (seed 3.46)."""
        if mode is None:
            mode = "up" if np.real(np.reshape(s, (-1, 2))[0, 1]) < 0 else "down"
        return prototype_workspace_margins(s, self._length, self.robot.margins, mode)

    def crossing_margins(self, s, crossing_sign) -> dict[str, np.ndarray]:
        """The margins of a motion crossing q2 = 0 once: those of 3.40-3.45, and ``crossing_side``
        (sign * q2 >= 0) and ``crossing_range`` (sign * q2 <= pi - m_ga) instead of 3.46 [m, rad].
        """
        margins = prototype_workspace_margins(s, self._length, self.robot.margins, "down")
        del margins["q2_low"], margins["q2_high"]
        q2 = s[..., 1] * crossing_sign  # > 0 on the correct side of the crossing
        at_crossing = crossing_sign == 0  # the crossing itself: q2 = 0 there by construction
        margins["crossing_side"] = np.where(at_crossing, 1.0, q2)
        margins["crossing_range"] = np.where(at_crossing, 1.0, (np.pi - self.robot.margins.angle) - q2)
        return margins

    def check_pose(self, pose, mode: str | None, what: str) -> None:
        """The margins of 3.40-3.46 in ``mode`` ("down" by default); arm "up" mirrors the q2 bounds."""
        mode = mode or "down"
        values = self.workspace_margins(pose, mode)
        options = dict(margins=self.robot.margins, singular=self.singular_margins, hints=dict(self.margin_hints))
        if mode == "down":
            check_margins(values, pose, what, **options)
            return
        try:
            check_margins(values, pose, what, **options)
        except SingularityError as error:
            m = self.robot.margins.angle
            raise SingularityError(
                pose, float(singularity_margin(pose[1])), m,
                f"{what}: q2 = {pose[1]:.4g} rad; with arm 'up' keep -pi + {m:.4g} <= q2 <= -{m:.4g} rad",
            ) from error

    def planning_pose(self, point, space: str, mode: str | None, what: str) -> np.ndarray:
        """xi of a way point: a copy in joint space, the inverse kinematics of the drone joint in task space."""
        if space == "joint":
            return np.array(point, dtype=float)
        length, margins = self._length, self.robot.margins
        try:
            return prototype_inverse_kinematics(point, length, mode or "down", min_margin=margins.angle)
        except WorkspaceError as error:
            raise WorkspaceError(point, f"{what}: {error.reason}; move the way point closer to the fixed point "
                                        "(the origin)") from error
        except SingularityError as error:
            near, far = 2 * length * np.sin(margins.angle / 2), 2 * length * np.cos(margins.angle / 2)
            raise SingularityError(
                error.configuration, error.margin, error.required,
                f"{what}: the links are (nearly) aligned; move the way point so that its distance to the fixed "
                f"point is between {near:.4g} m and {far:.4g} m",
            ) from error

    def mission_region(self, space: str, mode: str | None) -> tuple[np.ndarray, np.ndarray]:
        """Task space: the drone joint within the tour's box, y in [0.3, 1.4] m, z in [-0.5, 1.2] m. Joint
        space: q1 within its bounds (3.44), q2 within those of ``mode`` (3.46; "down" by default) [rad].
        """
        if space == "task":
            return np.array([0.3, -0.5]), np.array([1.4, 1.2])
        m = self.robot.margins.angle
        q1, q2 = np.pi / 2 - m, np.array([m, np.pi - m])
        q2 = -q2[::-1] if mode == "up" else q2
        return np.array([-q1, q2[0]]), np.array([q1, q2[1]])

    def coordinate_axes(self) -> list[tuple[str, tuple[float, float] | None]]:
        """q1 in [-(pi/2 - m_ga), pi/2 - m_ga], q2 in [m_ga, pi - m_ga] (seed 3.44, 3.46; arm down)."""
        m = self.robot.margins.angle
        return [(r"$q_1$ [rad]", (-(np.pi / 2 - m), np.pi / 2 - m)), (r"$q_2$ [rad]", (m, np.pi - m))]

    # ------------------------------------------------------------------ thrust from motion, control
    def thrust_vectors(self, motion: Jet, generalized: Jet, order: int | None = None) -> Jet:
        """F exact through q2 = 0 (:func:`fpr.robots.prototype_thrust.thrust_vector`), shape (N, 1, 2) [N]."""
        order = generalized.order if order is None else order
        return prototype_thrust.thrust_vector(motion, generalized, self._length, order)[:, None, :]

    def needs_high_derivatives(self, s) -> bool:
        """True when a sample is within :data:`~fpr.robots.prototype_thrust.SINGULAR_SCREEN` of q2 = 0."""
        return bool(np.any(np.abs(np.sin(np.real(s[..., 1]))) < prototype_thrust.SINGULAR_SCREEN))

    def outer_loop_forces(self, s, b, jacobian, planned_force, singular_band: float) -> np.ndarray:
        """With a planned force, the tension regularised towards the planned one near q2 = 0
        (:func:`fpr.robots.prototype_thrust.regularised_force`); the plain solve without.
        """
        if planned_force is None:
            return super().outer_loop_forces(s, b, jacobian, planned_force, singular_band)
        return prototype_thrust.regularised_force(s, b, planned_force[0], self._length, singular_band)[None, :]

    def compiled_outer_constants(self, settings) -> list[float] | None:
        """The native closed loop's solve 1 (``fpr/_native/cpp/outer.cpp``): the two-link chain's tension regularised
        towards the planned one (:meth:`outer_loop_forces` with a planned force), with the link length.
        """
        return [1.0, float(self._length)]

    # ------------------------------------------------------------------ closure
    def closed_chain(self, model, axis_offset: float) -> ClosureTree:
        """The drone a free flyer; the chain hangs from it (hinge reversed, link 2 with the end-effector,
        joint 2 reversed, link 1); the end of link 1 is held at the fixed point by a 3D point constraint
        (a ball joint): 8 - 3 = 5 degrees of freedom. ``axis_offset`` is not used.
        """
        robot = self.robot
        src = robot.model
        jp, inertias = src.jointPlacements, src.inertias
        ff1, fc1 = add_free_drone(model, robot, 0)
        h1 = robot.hinge_joint_ids[0]
        j2, j1 = src.getJointId("q2"), src.getJointId("q1")
        r1 = model.addJoint(ff1, pin.JointModelRX(), pin.SE3.Identity(), "drone_1_hinge_reversed")
        model.appendBodyToJoint(r1, inertias[j2], jp[h1].inverse())
        r2 = model.addJoint(r1, pin.JointModelRX(), jp[h1].inverse(), "q2_reversed")
        model.appendBodyToJoint(r2, inertias[j1], jp[j2].inverse())
        pivot = pin.SE3.Identity()
        for name in ("pivot_yaw", "pivot_pitch", "q1"):
            pivot = pivot * jp[src.getJointId(name)]
        # joint 1 of the constraint is the world: its frame is fixed, so the LOCAL error and velocity agree
        constraints = pin.StdVec_RigidConstraintModel()
        constraints.append(pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, 0, pivot,
                                                    r2, jp[j2].inverse(), pin.LOCAL))
        return ClosureTree(constraints, (ff1,), (fc1,),
                           {"drone_1_hinge_reversed": ("drone_1_hinge", -1.0), "q2_reversed": ("q2", -1.0)})

    def closure_reader(self, closed) -> _PrototypeReader:
        """The pivot from link 1's placement (:class:`_PrototypeReader`)."""
        return _PrototypeReader(closed)


__all__ = ["ARMS", "LAYOUT", "Prototype", "prototype_inverse_kinematics", "prototype_jacobian", "prototype_joints",
           "prototype_workspace_margins"]
