"""The Flying Parallel Robot: two quadrotors carrying an end-effector through a passive planar chain (seed ch. 2-3).

Everything specific to the FPR, for generic code to ask through ``robot.kind`` (:class:`Fpr`):

* coordinates (seed 2.1): ``q = [x y z psi theta phi q21 phi1 phi2]``; the planning vector is the
  passive chain s = [y z phi q21] [m, m, rad, rad], in task and joint space alike;
* kinematics (DESIGN.md): p = (y, z) is the end-effector, the drone joints are
  r1 = p - L1 u(phi), r2 = p - L2 u(phi + q21). The inverse kinematics (pose -> drone joints) is
  unique; the direct kinematics (drone joints -> pose) has two assembly modes, ``mode = sign(sin q21)``
  (+1: the end-effector hangs below the drones, as in the reference pose s0 = [0 0 5pi/4 pi/2]).
  Type-2 singularity: sin(q21) = 0;
* workspace margins (seed 3.27-3.29), figure titles, the closure of the plant (drone 2 held on link 2).

The functions take the link length L (both links) or the pair (L1, L2) of a chain with unequal links,
and accept a trailing coordinate axis with any leading batch shape.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import pinocchio as pin

from fpr.model.constrained import ClosureTree, add_free_drone, euler_zyx, wrap_angle
from fpr.model.description import URDF_DIR
from fpr.model.errors import ModelArgumentError, WorkspaceError
from fpr.model.kinematics import last_axis, u, u_perp
from fpr.model.parameters import Margins
from fpr.model.robot import EULER_ROOT_NAME, Layout
from fpr.robots.base import GROUND_KIND, ROLL_KIND, RobotKind

LAYOUT = Layout(
    coordinates=("x", "y", "z", "psi", "theta", "phi", "q21", "phi1", "phi2"),
    joints={
        "q21": {"q21": 1.0},
        "drone_1_hinge": {"phi1": 1.0, "phi": -1.0},
        "drone_2_hinge": {"phi2": 1.0, "phi": -1.0, "q21": -1.0},
    },
    drones=("drone_1", "drone_2"),
    chain=("y", "z", "phi", "q21"),
    attitude=("psi", "theta", "phi1", "phi2"),
    drone_attitude=(("phi1",), ("phi2",)),
    euler_root=True,
)
"""The FPR's coordinates and their Pinocchio joints (the drone hinges are relative to their link)."""

#: Roll of the end-effector at the reference pose s0 = [0 0 5pi/4 pi/2] (DESIGN.md) [rad]: without a
#: reference, the closed chain's reading of the state returns the root roll phi within pi of it.
NOMINAL_ROOT_ROLL = 5 * np.pi / 4


def _lengths(link_length) -> tuple[float, float]:
    """(L1, L2) from L (both links) or from the pair."""
    lengths = np.broadcast_to(np.asarray(link_length, dtype=float), (2,))
    return float(lengths[0]), float(lengths[1])


def fpr_drone_joints(s, link_length) -> np.ndarray:
    """Drone joint positions r_i of the FPR (inverse kinematics), shape (..., 2, 2): [r1, r2].

    Args:
        s: chain coordinates [y z phi q21], shape (..., 4) [m, m, rad, rad].
        link_length: L, or (L1, L2) [m].
    """
    s = last_axis(s, 4, "s")
    l1, l2 = _lengths(link_length)
    p = s[..., :2]
    r1 = p - l1 * u(s[..., 2])
    r2 = p - l2 * u(s[..., 2] + s[..., 3])
    return np.stack([r1, r2], axis=-2)


def fpr_drone_joint_velocities(s, s_dot, link_length) -> np.ndarray:
    """Velocities of the drone joints, shape (..., 2, 2): [dr1/dt, dr2/dt] [m/s].

    Args:
        s: chain coordinates, shape (..., 4) [m, m, rad, rad].
        s_dot: their rates, shape (..., 4) [m/s, m/s, rad/s, rad/s].
        link_length: L, or (L1, L2) [m].
    """
    s, s_dot = last_axis(s, 4, "s"), last_axis(s_dot, 4, "s_dot")
    l1, l2 = _lengths(link_length)
    v = s_dot[..., :2]
    v1 = v - l1 * u_perp(s[..., 2]) * s_dot[..., 2:3]
    v2 = v - l2 * u_perp(s[..., 2] + s[..., 3]) * (s_dot[..., 2:3] + s_dot[..., 3:4])
    return np.stack([v1, v2], axis=-2)


def fpr_chain_jacobian(s, link_length) -> np.ndarray:
    """J_p: d[r1; r2]/ds, shape (..., 4, 4) (seed 2.6). det J_p = -L1 L2 sin(q21).

    Args:
        s: chain coordinates, shape (..., 4).
        link_length: L, or (L1, L2) [m].
    """
    s = last_axis(s, 4, "s")
    l1, l2 = _lengths(link_length)
    jac = np.zeros(s.shape[:-1] + (4, 4))
    jac[..., 0, 0] = jac[..., 1, 1] = jac[..., 2, 0] = jac[..., 3, 1] = 1.0
    jac[..., 0:2, 2] = -l1 * u_perp(s[..., 2])
    w = -l2 * u_perp(s[..., 2] + s[..., 3])
    jac[..., 2:4, 2] = w
    jac[..., 2:4, 3] = w
    return jac


def fpr_direct_kinematics(r1, r2, link_length, mode: int = 1) -> np.ndarray:
    """End-effector pose s = [y z phi q21] from the drone joints, for one assembly mode.

    p is where the circles of radius L1 about r1 and L2 about r2 meet, on the side ``mode`` of the
    line r1 -> r2.

    Args:
        r1: (y, z) of the first drone's joint, the centre of the circle of radius L1, shape (..., 2) [m].
        r2: (y, z) of the second drone's joint, the centre of the circle of radius L2, shape (..., 2) [m].
        link_length: L, or (L1, L2) [m].
        mode: +1 for sin(q21) > 0 (end-effector below the drones, the reference mode), -1 otherwise.

    Returns:
        s, shape (..., 4), with phi in [0, 2 pi) and q21 in (-pi, pi].

    Raises:
        WorkspaceError: the joints are further apart than L1 + L2, closer than |L1 - L2|, or equal.
        ModelArgumentError: a mode other than +1 or -1.
    """
    r1, r2 = last_axis(r1, 2, "r1"), last_axis(r2, 2, "r2")
    if mode not in (1, -1):
        raise ModelArgumentError("mode", mode, f"mode={mode!r}: use +1 (sin q21 > 0) or -1")
    l1, l2 = _lengths(link_length)
    delta = r2 - r1
    dist = np.linalg.norm(delta, axis=-1)
    far, near = dist > l1 + l2, (dist == 0) | (dist < abs(l1 - l2))
    if np.any(far) or np.any(near):
        flat = dist.reshape(-1)
        i = int(np.argmax(flat)) if np.any(far) else int(np.argmin(flat))
        r1b, r2b = np.broadcast_to(r1, delta.shape), np.broadcast_to(r2, delta.shape)
        raise WorkspaceError(
            np.concatenate([r1b.reshape(-1, 2)[i], r2b.reshape(-1, 2)[i]]),
            f"drone joints {flat[i]:.4g} m apart; they must be closer than L1 + L2 = {l1 + l2:.4g} m, "
            f"further than |L1 - L2| = {abs(l1 - l2):.4g} m, and distinct",
        )
    e = delta / dist[..., None]
    normal = np.stack([-e[..., 1], e[..., 0]], axis=-1)
    along = (dist**2 + l1**2 - l2**2) / (2 * dist)  # from r1, along e
    h = np.sqrt(np.maximum(l1**2 - along**2, 0.0))
    p = r1 + along[..., None] * e + mode * h[..., None] * normal
    a1 = p - r1
    a2 = p - r2
    phi = np.mod(np.arctan2(a1[..., 1], a1[..., 0]), 2 * np.pi)
    q21 = np.angle(np.exp(1j * (np.arctan2(a2[..., 1], a2[..., 0]) - phi)))
    return np.concatenate([p, phi[..., None], q21[..., None]], axis=-1)


def fpr_workspace_margins(s, link_length, margins: Margins) -> dict[str, np.ndarray]:
    """Signed margins of the FPR's geometric constraints (>= 0 where satisfied) (seed 3.27-3.29).

    Args:
        s: chain coordinates, shape (..., 4) (complex allowed).
        link_length: L, or (L1, L2) [m]; the ground is z = -L1.
        margins: the planning margins.

    Returns:
        ``{"ground_1", "ground_2"}`` drone joint heights above -L1 + m_gd [m];
        ``{"phi_low", "phi_high"}`` for pi + m_ga <= phi <= 2 pi - m_ga [rad];
        ``{"q21_low", "q21_high"}`` for m_ga <= q21 <= pi - m_ga [rad].
    """
    s = last_axis(s, 4, "s")
    r = fpr_drone_joints(s, link_length)
    ground = -_lengths(link_length)[0] + margins.ground
    return {
        "ground_1": r[..., 0, 1] - ground,
        "ground_2": r[..., 1, 1] - ground,
        "phi_low": s[..., 2] - (np.pi + margins.angle),
        "phi_high": (2 * np.pi - margins.angle) - s[..., 2],
        "q21_low": s[..., 3] - margins.angle,
        "q21_high": (np.pi - margins.angle) - s[..., 3],
    }


class _FprReader:
    """Reads the FPR's root joint and drone 2's hinge off the closed chain (``closure_reader``).

    The end-effector placement is drone 1's free flyer times the reversed hinge 1 and the inverse of
    hinge 1's joint placement; it gives x, y, z and the Z-Y-X Euler angles psi, theta, phi of the root
    joint. Hinge 2's angle is the rotation about x between link 2's hinge frame and drone 2's free flyer.
    """

    def __init__(self, closed):
        r, model = closed.robot, closed.model
        src, jp = r.model, r.model.jointPlacements
        root = src.getJointId(EULER_ROOT_NAME)
        h1, h2 = r.hinge_joint_ids
        self.reversed_1 = model.getJointId("drone_1_hinge_reversed")
        self.root_placement_inv = jp[root].inverse()
        self.hinge_1_inv = jp[h1].inverse()
        self.root_q = src.joints[root].idx_q
        self.euler_coordinates = r.indices(("psi", "theta", "phi"))
        self.q21 = model.getJointId("q21")
        self.hinge_2 = jp[h2]
        self.hinge_2_q = src.joints[h2].idx_q
        self.freeflyer_2 = closed.freeflyer_ids[1]
        self.phi2 = r.index["phi2"]

    def read(self, qp, omi, reference) -> None:
        """Fill the root joint and hinge 2 into the Pinocchio coordinates ``qp`` (in place)."""
        motion = self.root_placement_inv * omi[self.reversed_1] * self.hinge_1_inv  # composite joint
        i0 = self.root_q
        ref = None if reference is None else reference[self.euler_coordinates]
        placement = motion.homogeneous  # one conversion for the rotation and the translation (the simulator's
        euler = euler_zyx(placement[:3, :3], ref)  # measurement runs this at every tick)
        if ref is None:
            euler[2] = NOMINAL_ROOT_ROLL + wrap_angle(euler[2] - NOMINAL_ROOT_ROLL)
        qp[i0:i0 + 3] = placement[:3, 3]
        qp[i0 + 3:i0 + 6] = euler
        hinge_frame = omi[self.q21] * self.hinge_2
        rel = hinge_frame.rotation.T @ omi[self.freeflyer_2].rotation
        qp[self.hinge_2_q] = np.arctan2(rel[2, 1], rel[1, 1])

    def native_reads(self) -> tuple[list, list]:
        """:meth:`read` as the native measurement takes it (``fpr/_native/cpp/native.hpp``: EulerRead,
        AngleRead): the root joint's translation and Euler angles off the end-effector placement, hinge 2's
        angle about x.
        """
        i0 = self.root_q
        eulers = [(self.reversed_1, self.root_placement_inv.homogeneous, self.hinge_1_inv.homogeneous,
                   (i0, i0 + 1, i0 + 2), (i0 + 3, i0 + 4, i0 + 5), tuple(int(i) for i in self.euler_coordinates))]
        angles = [(self.q21, self.hinge_2.homogeneous, self.freeflyer_2, self.hinge_2_q)]
        return eulers, angles

    def wrap(self, q) -> None:
        """Drone 2's absolute roll phi2 within pi of level (in place)."""
        q[self.phi2] = wrap_angle(q[self.phi2])


class Fpr(RobotKind):
    """The FPR (registry name "fpr"): see the module docstring and :class:`~fpr.robots.base.RobotKind`."""

    name = "fpr"
    xacro = URDF_DIR / "fpr.urdf.xacro"
    urdf = URDF_DIR / "fpr.urdf"
    layout = LAYOUT
    chain_units = ("m", "m", "rad", "rad")
    reference_chain = (0.0, 0.0, 5 * np.pi / 4, np.pi / 2)
    singular_margins = ("q21",)
    out_of_plane = ("x", "psi", "theta")
    constraint_kinds = {
        "ground": GROUND_KIND,
        "phi": ("rad", "end-effector orientation pi + m_ga <= phi <= 2 pi - m_ga (3.28)"),
        "q21": ("rad", "Type-2 singularity m_ga <= q21 <= pi - m_ga (3.29)"),
        "roll": ROLL_KIND,
    }
    attitude_kinds = ("roll",)
    margin_hints = {"phi": "keep pi + m_ga <= phi <= 2 pi - m_ga (end-effector below the first drone)"}
    task_point_labels = ("end-effector", "drone joints")
    task_frame = "end_effector"
    titles = {
        "path": "Fig. 3.11 — path of the end-effector in the task space",
        "coordinates": "Fig. 3.12 — coordinates of the passive chain",
        "energy": "Fig. 3.13 — energy index $J_e$",
        "perturbation": r"Fig. 3.14 — perturbation index $J_\varphi$",
        "thrust": "Fig. 3.15-3.16 — thrust of each drone",
        "roll": "Fig. 3.17-3.18 — roll angle of each drone",
        "rotor_speeds": "Eq. 3.48 — rotor speeds of each drone",
        "rotor_forces": r"Eq. 3.48 — rotor forces $c_T \omega^2$ of each drone",
        "sim_path": "Fig. 3.19 — end-effector and drone joints, planned and simulated",
        "sim_coordinates": r"Fig. 3.21-3.22, 3.25-3.26 — tracking of y, z, $\varphi$, $q_{21}$",
        "sim_out_of_plane": r"Fig. 3.20, 3.23-3.24 — motion out of the plane: x, pitch $\theta$, yaw $\psi$",
        "sim_roll": "Fig. 3.27-3.28 — roll angle of each drone in simulation",
        "sim_heights": "Fig. 3.29-3.30 — height of each drone in simulation",
        "sim_rotor_speeds": "Eq. 3.48 — rotor speeds of each drone in simulation",
        "sim_rotor_forces": r"Fig. 3.31-3.32 — rotor forces $c_T \omega^2$ of each drone in simulation",
        "sim_energy": r"Energy $J_e$ and perturbation $J_\varphi$ in planning and simulation",
    }

    @cached_property
    def link_lengths(self) -> tuple[float, float]:
        """(L1, L2): each drone's hinge position in the frame of its link [m]."""
        model = self.robot.model
        return tuple(float(np.linalg.norm(model.jointPlacements[j].translation)) for j in self.robot.hinge_joint_ids)

    # ------------------------------------------------------------------ kinematics
    def drone_joints(self, s) -> np.ndarray:
        """[r1, r2], shape (..., 2, 2) [m] (:func:`fpr_drone_joints`)."""
        return fpr_drone_joints(s, self.link_lengths)

    def drone_joint_velocities(self, s, s_dot) -> np.ndarray:
        """[r1', r2'], shape (..., 2, 2) [m/s] (:func:`fpr_drone_joint_velocities`)."""
        return fpr_drone_joint_velocities(s, s_dot, self.link_lengths)

    def chain_jacobian(self, s) -> np.ndarray:
        """J_p = d[r1; r2]/ds, shape (..., 4, 4) (:func:`fpr_chain_jacobian`)."""
        return fpr_chain_jacobian(s, self.link_lengths)

    def task_points(self, s) -> tuple[np.ndarray, np.ndarray]:
        """(end-effector p (..., 2), drone joints [r1, r2] (..., 2, 2)) [m]."""
        s = last_axis(s, 4, "s")
        return s[..., :2], self.drone_joints(s)

    # ------------------------------------------------------------------ workspace
    def workspace_margins(self, s, mode: str | None = None) -> dict[str, np.ndarray]:
        """:func:`fpr_workspace_margins` (one assembly mode: ``mode`` is ignored)."""
        return fpr_workspace_margins(s, self.link_lengths, self.robot.margins)

    def mission_region(self, space: str, mode: str | None) -> tuple[np.ndarray, np.ndarray]:
        """The square mission's 1 m x 1 m square for the end-effector (task and joint space alike), phi and
        q21 within 0.3 rad of the reference pose's 5 pi/4 and pi/2 [m, m, rad, rad].
        """
        centre = np.array(self.reference_chain[2:])
        return np.concatenate([[0.0, 0.0], centre - 0.3]), np.concatenate([[1.0, 1.0], centre + 0.3])

    def coordinate_axes(self) -> list[tuple[str, tuple[float, float] | None]]:
        """y, z (unbounded), phi in [pi + m_ga, 2 pi - m_ga], q21 in [m_ga, pi - m_ga] (seed 3.28-3.29)."""
        m = self.robot.margins.angle
        return [("y [m]", None), ("z [m]", None), (r"$\varphi$ [rad]", (np.pi + m, 2 * np.pi - m)),
                (r"$q_{21}$ [rad]", (m, np.pi - m))]

    # ------------------------------------------------------------------ closure
    def closed_chain(self, model, axis_offset: float) -> ClosureTree:
        """Drone 1 a free flyer; the chain hangs from it (hinge 1 reversed, the end-effector with link 1,
        the joint q21, link 2); drone 2 a second free flyer.

        The revolute closure "drone 2 turns about hinge 2" (pin 4 has no 5D revolute constraint) is made
        of two 3D point constraints: the hinge point and a second point on the hinge axis
        (``axis_offset`` away) coincide on link 2 and on drone 2. Their 6 rows have rank 5, which the
        proximal solver of pin.constraintDynamics handles; 14 velocities - 5 = 9 degrees of freedom, as
        the minimal model. (A 6D weld onto a massless stub carrying the hinge in the tree is the other
        option; its zero inertia makes the solve singular.)
        """
        robot = self.robot
        src = robot.model
        jp, inertias = src.jointPlacements, src.inertias
        ff1, fc1 = add_free_drone(model, robot, 0)
        h1, h2 = robot.hinge_joint_ids
        root = src.getJointId(EULER_ROOT_NAME)
        q21 = src.getJointId("q21")
        r1 = model.addJoint(ff1, pin.JointModelRX(), pin.SE3.Identity(), "drone_1_hinge_reversed")
        model.appendBodyToJoint(r1, inertias[root], jp[h1].inverse())
        j21 = model.addJoint(r1, pin.JointModelRX(), jp[h1].inverse() * jp[q21], "q21")
        model.appendBodyToJoint(j21, inertias[q21], pin.SE3.Identity())
        ff2, fc2 = add_free_drone(model, robot, 1)
        # revolute closure at hinge 2: the hinge point and a point on its axis coincide (rank 5 of 6 rows)
        constraints = pin.StdVec_RigidConstraintModel()
        on_axis = pin.SE3(np.eye(3), np.array([axis_offset, 0.0, 0.0]))
        for offset in (pin.SE3.Identity(), on_axis):
            constraints.append(pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, j21, jp[h2] * offset,
                                                        ff2, offset, pin.LOCAL))
        return ClosureTree(constraints, (ff1, ff2), (fc1, fc2),
                           {"drone_1_hinge_reversed": ("drone_1_hinge", -1.0), "q21": ("q21", 1.0)})

    def closure_reader(self, closed) -> _FprReader:
        """The root joint from the end-effector placement, hinge 2 from drone 2's (:class:`_FprReader`)."""
        return _FprReader(closed)


__all__ = ["Fpr", "LAYOUT", "NOMINAL_ROOT_ROLL", "fpr_chain_jacobian", "fpr_direct_kinematics",
           "fpr_drone_joint_velocities", "fpr_drone_joints", "fpr_workspace_margins"]
