"""The spatial FPR's control and simulation: its plant's closed chain, the reader of its minimal coordinates, and
its controller's hooks (:class:`fpr.robots.fpr3.Fpr3` delegates to this module).

**The plant's closed chain** (:func:`closed_chain`): the platform is a free flyer (no chart singularity in the
simulator: the Z-Y-X angles of the minimal model are read off its placement), the three legs hang from it as a
tree (their hinges, bodies and placements copied from the minimal model), each drone is a free flyer of its own
(:func:`fpr.model.constrained.add_free_drone`: its frame at the ball, drone axes), and each drone is held on its
leg's tip by a 3D point constraint (pin's ``CONTACT_3D``: a ball joint). 6 + 3 + 3 x 6 = 27 velocities minus
9 closure rows: 18 degrees of freedom, as the minimal model. The ball's two rings (``ball_ring_mass``, 1e-6 kg;
``ball_ring_inertia``, 1e-12 kg m^2) are put on the leg at the ball: their rotation with the ball angles is
left out (an inertia of 1e-12 kg m^2).

**The reader** (:class:`Fpr3Reader`): the platform's position and Z-Y-X angles from its free flyer (the Euler
solution nearer the reference), the legs copied, each drone's ball angles from R_tip^T R_drone = Ry(pitch)
Rz(yaw) Rx(roll) (:func:`ball_angles_of`, the solution nearer the reference).

**The drones' attitude from a thrust vector** (:func:`fpr.robots.fpr3.ball_angles`, the one formula the planner
shares): in leg i's radial frame P_i =
R_p Rz(a_i), with f = P_i^T F_i, the drone's thrust axis is along F_i with its x axis normal to the leg's
hinge axis P_i e_y: yaw_i = 0, q_i + pitch_i = atan2(f_x, f_z), roll_i = atan2(-f_y, hypot(f_x, f_z)) (the
planning side's formula; singular only for F_i along the hinge axis, a drone tilted 90 degrees from the
platform's plane).

**The inner loop's targets** (:func:`attitude_targets`): each drone's target attitude is that of the outer
loop's F_i relative to the *measured* platform and leg (so the target is where the thrust axis must point now,
not where the plan expected the leg to be), its thrust F_i's component on the measured thrust axis, corrected
for an offset d_i of the centre of mass above the ball (f_i = z_i . F_i - m_i d_i |w_perp|^2; d_i = 0 on the
built-in robot), the rates and accelerations of the ball angles from the plan.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from fpr.model.constrained import ClosureTree, add_free_drone, euler_zyx, wrap_angle
from fpr.model.robot import EULER_ROOT_NAME
from fpr.robots.planar_control import AttitudeTargets

_TWO_PI = 2 * math.pi


def _single_dof(joint) -> pin.JointModel:
    """A fresh 1-DoF joint model of the same type as ``joint`` (RX, RY, RZ, PX, PY, PZ, or a revolute about any
    axis).
    """
    name = joint.shortname()
    simple = {"JointModelRX": pin.JointModelRX, "JointModelRY": pin.JointModelRY, "JointModelRZ": pin.JointModelRZ,
              "JointModelPX": pin.JointModelPX, "JointModelPY": pin.JointModelPY, "JointModelPZ": pin.JointModelPZ}
    if name in simple:
        return simple[name]()
    if name == "JointModelRevoluteUnaligned":
        return pin.JointModelRevoluteUnaligned(joint.axis)
    raise NotImplementedError(f"a leg hinge of type {name}")


def leg_joint_ids(robot) -> tuple[tuple[int, int], ...]:
    """(leg hinge, drone's first ball joint) of each drone, joint ids of the minimal model: the leg is the parent
    of the ball's first joint, which is the third parent of the drone's hinge (pitch, yaw, hinge).
    """
    model = robot.model
    out = []
    for hinge in robot.hinge_joint_ids:
        pitch = model.parents[model.parents[hinge]]
        out.append((model.parents[pitch], pitch))
    return tuple(out)


def closed_chain(kind, model: pin.Model, axis_offset: float) -> ClosureTree:
    """The spatial FPR's plant (module docstring): the platform a free flyer, the legs a tree on it, three free
    drones, three point closures tip <-> ball. ``axis_offset`` is not used.
    """
    robot = kind.robot
    src = robot.model
    jp, inertias = src.jointPlacements, src.inertias
    root = src.getJointId(EULER_ROOT_NAME)
    platform = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "platform_freeflyer")
    model.appendBodyToJoint(platform, inertias[root], pin.SE3.Identity())
    legs = []
    for leg, pitch in leg_joint_ids(robot):
        name = src.names[leg]
        jid = model.addJoint(platform, _single_dof(src.joints[leg]), jp[root].inverse() * jp[leg], name)
        model.appendBodyToJoint(jid, inertias[leg], pin.SE3.Identity())
        # the ball's rings (pitch and yaw joints' bodies) ride on the leg at the ball (module docstring)
        ring = jp[pitch]
        for part in (pitch, model_next(src, pitch)):  # the pitch ring, then the yaw ring
            model.appendBodyToJoint(jid, inertias[part], ring)
        legs.append((jid, jp[pitch]))
    drones = [add_free_drone(model, robot, i) for i in range(robot.n_drones)]
    constraints = pin.StdVec_RigidConstraintModel()
    for (leg, ball), (drone, _) in zip(legs, drones, strict=True):
        constraints.append(pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, leg, ball, drone,
                                                    pin.SE3.Identity(), pin.LOCAL))
    return ClosureTree(constraints, tuple(d for d, _ in drones), tuple(f for _, f in drones),
                       {src.names[leg]: (src.names[leg], 1.0) for leg, _ in leg_joint_ids(robot)},
                       ((platform, root),))


def ball_angles_of(rel, reference=None) -> list[float]:
    """(pitch, yaw, roll) of a rotation rel = Ry(pitch) Rz(yaw) Rx(roll) [rad].

    Of the two solutions (yaw in [-pi/2, pi/2] and (pitch + pi, pi - yaw, roll + pi)) the first is returned,
    or, given a ``reference`` (pitch, yaw, roll), the one nearer to it modulo 2 pi.
    """
    (r00, _, _), (r10, r11, r12), (r20, _, _) = rel.tolist() if isinstance(rel, np.ndarray) else rel
    yaw = math.atan2(r10, math.hypot(r11, r12))
    pitch = math.atan2(-r20, r00)
    roll = math.atan2(-r12, r11)
    if reference is None:
        return [pitch, yaw, roll]
    pi = math.pi

    def distance(values):
        return sum(((v - r + pi) % _TWO_PI - pi) ** 2 for v, r in zip(values, reference, strict=True))

    other = [pitch + pi, pi - yaw, roll + pi]
    return other if distance(other) < distance([pitch, yaw, roll]) else [pitch, yaw, roll]


def _rotation_zyx(psi, theta, phi) -> np.ndarray:
    """R = Rz(psi) Ry(theta) Rx(phi)."""
    return pin.rpy.rpyToMatrix(phi, theta, psi)


class Fpr3Reader:
    """Reads the spatial FPR's platform and ball angles off its closed chain (``closure_reader``, module docstring)."""

    def __init__(self, closed):
        r, model = closed.robot, closed.model
        src = r.model
        root = src.getJointId(EULER_ROOT_NAME)
        (self.platform, _), = closed.placed_freeflyers
        self.root_placement_inv = src.jointPlacements[root].inverse()
        self.root_q = src.joints[root].idx_q
        self.euler_coordinates = r.indices(("psi", "theta", "phi"))
        self.balls = []
        for (leg, pitch), drone, hinge in zip(leg_joint_ids(r), closed.freeflyer_ids, r.hinge_joint_ids, strict=True):
            closed_leg = model.getJointId(src.names[leg])
            qs = [src.joints[pitch].idx_q, src.joints[model_next(src, pitch)].idx_q, src.joints[hinge].idx_q]
            names = r.layout.drone_attitude[len(self.balls)]
            self.balls.append((closed_leg, src.jointPlacements[pitch].rotation.copy(), drone, qs, r.indices(names)))
        self.wrapped = r.indices(("psi", "phi") + tuple(c for d in r.layout.drone_attitude for c in d))

    def read(self, qp, omi, reference) -> None:
        """Fill the platform's joint and the ball joints into the Pinocchio coordinates ``qp`` (in place)."""
        placement = (self.root_placement_inv * omi[self.platform]).homogeneous
        ref = None if reference is None else reference[self.euler_coordinates]
        i0 = self.root_q
        qp[i0:i0 + 3] = placement[:3, 3]
        qp[i0 + 3:i0 + 6] = euler_zyx(placement[:3, :3], ref)
        for leg, ball, drone, qs, names in self.balls:
            rel = (omi[leg].rotation.dot(ball)).T.dot(omi[drone].rotation)
            angles = ball_angles_of(rel, None if reference is None else reference[names].tolist())
            qp[qs] = angles

    def wrap(self, q) -> None:
        """The platform's yaw and roll and the ball angles in [-pi, pi) (in place)."""
        q[self.wrapped] = wrap_angle(q[self.wrapped])


def model_next(model, joint: int) -> int:
    """The joint whose parent is ``joint`` (the ball's next joint; the first such)."""
    return next(j for j in range(1, model.njoints) if model.parents[j] == joint)


class Fpr3Control:
    """The spatial FPR's control constants, read once from the model (:class:`fpr.robots.fpr3.Fpr3` builds it)."""

    def __init__(self, kind, ball_angles):
        """Args: kind: the bound :class:`fpr.robots.fpr3.Fpr3`; ball_angles: the kind's attitude rule
        (:func:`fpr.robots.fpr3.ball_angles`, the one the planner uses).
        """
        r = kind.robot
        self.euler = r.indices(("psi", "theta", "phi")).tolist()
        src = r.model
        # each leg's coordinate q_i: the one its hinge joint reads (Layout.joints)
        legs = tuple(next(iter(r.layout.joints[src.names[leg]])) for leg, _ in leg_joint_ids(r))
        self.legs = r.indices(legs).tolist()
        self.balls = [r.indices(names).tolist() for names in r.layout.drone_attitude]
        # the legs' a_i from their hinges' placements: the hinge at R_p Rz(a_i) [r_p 0 0]
        self.leg_angles = [math.atan2(*src.jointPlacements[leg].translation[[1, 0]]) for leg, _ in leg_joint_ids(r)]
        self.mass_offset = (np.array(r.drone_masses) * np.array(r.hinge_offsets)).tolist()
        self._robot = r
        self._ball_angles = ball_angles

    def platform_rotation(self, q) -> np.ndarray:
        """R_p of a configuration."""
        return _rotation_zyx(*(q[i] for i in self.euler))

    def ball_angles(self, q, force) -> np.ndarray:
        """The ball angles (3, 3) along ``force`` (3, 3) relative to the platform and legs of ``q``."""
        return self._ball_angles(self.platform_rotation(q), np.array([q[i] for i in self.legs]), force,
                                 self.leg_angles)

    def thrust_axes(self, q) -> np.ndarray:
        """Each drone's thrust axis (its z) in world axes at ``q``, shape (3, 3)."""
        rp = self.platform_rotation(q)
        out = np.empty((3, 3))
        for i, (a, leg, (p, y, r)) in enumerate(zip(self.leg_angles, self.legs, self.balls, strict=True)):
            rot = pin.utils.rotate("z", a) @ pin.utils.rotate("y", q[leg] + q[p]) @ pin.utils.rotate("z", q[y]) \
                @ pin.utils.rotate("x", q[r])
            out[i] = rp.dot(rot[:, 2])
        return out

    def targets(self, q, v, force, reference) -> AttitudeTargets:
        """The inner loop's targets (module docstring)."""
        force = np.asarray(force, dtype=float)
        axes = self.thrust_axes(q)
        thrust = np.einsum("ij,ij->i", axes, force)
        if any(self.mass_offset):  # f_i -= m_i d_i |w_perp|^2, w the drone's angular velocity (body axes)
            thrust = thrust - np.array(self.mass_offset) * self._perpendicular_rates(q, v)
        target = self.ball_angles(q, force).reshape(-1)
        return AttitudeTargets(thrust.tolist(), target.tolist(), np.asarray(reference.attitude_rate).tolist(),
                               np.asarray(reference.attitude_acceleration).tolist(), 0.0)

    def _perpendicular_rates(self, q, v) -> np.ndarray:
        """|w_perp|^2 of each drone: its angular velocity across its thrust axis, squared [rad^2/s^2]."""
        r = self._robot
        pin.forwardKinematics(r.model, r.data, r.T.dot(q), r.T.dot(v))
        out = []
        for hinge in r.hinge_joint_ids:
            w = r.data.v[hinge].angular
            out.append(w[0] ** 2 + w[1] ** 2)
        return np.array(out)

    def level(self, q) -> np.ndarray:
        """``q`` with each drone level in the world (thrust axis up, yaw by the rule), on a copy."""
        q = np.array(q, dtype=float)
        angles = self.ball_angles(q, np.tile([0.0, 0.0, 1.0], (3, 1)))
        for ids, value in zip(self.balls, angles, strict=True):
            q[ids] = value
        return q


__all__ = ["Fpr3Control", "Fpr3Reader", "ball_angles_of", "closed_chain", "leg_joint_ids"]
