"""The robots as free-flying quadrotors closed by the passive chain: Pinocchio constraint dynamics.

This is the second, independent formulation of the dynamics and the plant of the simulator. It is
built from the same rigid bodies as the minimal model (inertias and joint placements are read from
the :class:`~fpr.robots.Robot`'s Pinocchio model), but with another tree and a loop closure:

* FPR: drone 1 is a free flyer; the chain hangs from it (hinge 1 reversed, the end-effector with
  link 1, the joint q21, link 2); drone 2 is a second free flyer. The revolute closure "drone 2
  turns about hinge 2" (pin 4 has no 5D revolute constraint) is made of two 3D point constraints:
  the hinge point and a second point on the hinge axis coincide on link 2 and on drone 2. Their 6
  rows have rank 5, which the proximal solver of pin.constraintDynamics handles;
  14 velocities - 5 = 9 degrees of freedom, as the minimal model. (A 6D weld onto a massless stub
  carrying the hinge in the tree is the other option; its zero inertia makes the solve singular.)
* Prototype: the drone is a free flyer; the chain hangs from it (hinge reversed, link 2 with the
  end-effector, joint 2 reversed, link 1); the end of link 1 is held at the fixed point by a 3D
  point constraint (a ball joint): 8 - 3 = 5 degrees of freedom.

Each free flyer's frame is the drone's hinge frame (drone axes, at the joint), so the free-flyer
velocity is the drone body twist there. Closure drift is held by Baumgarte stabilisation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from fpr.errors import check_shape


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
        for fly, hinge in zip(self.freeflyer_ids, r.hinge_joint_ids):
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
        """Norm of the loop-closure error (placement log for a weld, distance for a point) [m, rad]."""
        pin.framesForwardKinematics(self.model, self.data, qc)
        err = 0.0
        for cm in self.constraints:
            m1 = self.data.oMi[cm.joint1_id] * cm.joint1_placement
            m2 = self.data.oMi[cm.joint2_id] * cm.joint2_placement
            if cm.type == pin.ContactType.CONTACT_6D:
                err = max(err, float(np.linalg.norm(pin.log6(m1.inverse() * m2).vector)))
            else:
                err = max(err, float(np.linalg.norm(m1.translation - m2.translation)))
        return err

    def energy(self, qc, vc) -> float:
        """Kinetic plus potential energy [J]."""
        return float(pin.computeKineticEnergy(self.model, self.data, qc, vc)
                     + pin.computePotentialEnergy(self.model, self.data, qc))

    def set_baumgarte(self, kp: float, kd: float) -> None:
        """Set the closure stabilisation gains of every constraint [1/s^2, 1/s]."""
        for cm in self.constraints:
            cm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(kp, kd))


def _add_drone(model: pin.Model, robot, index: int) -> tuple[int, int]:
    """A free-flying drone whose joint frame is the minimal model's hinge frame."""
    name = robot.layout.drones[index]
    hinge = robot.hinge_joint_ids[index]
    jid = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), f"{name}_freeflyer")
    model.appendBodyToJoint(jid, robot.model.inertias[hinge], pin.SE3.Identity())
    centre = robot.model.frames[robot.drone_frame_ids[index]]
    fid = model.addFrame(pin.Frame(f"{name}_center", jid, centre.placement, pin.FrameType.OP_FRAME))
    return jid, fid


def build_closed_chain(robot, baumgarte: tuple[float, float] = (400.0, 40.0),
                       accuracy: float = 1e-12, mu: float = 1e-9, max_iter: int = 50,
                       axis_offset: float = 0.1) -> ClosedChainModel:
    """Build the closed-chain formulation of an FPR or prototype :class:`~fpr.robots.Robot`.

    Args:
        robot: the minimal-coordinate robot (its bodies are reused).
        baumgarte: (Kp, Kd) closure stabilisation gains [1/s^2, 1/s].
        accuracy: proximal solver accuracy.
        mu: proximal regularisation (the FPR's closure rows are redundant: 6 rows of rank 5).
        max_iter: proximal solver iterations.
        axis_offset: distance between the two closure points on hinge 2's axis (FPR) [m].
    """
    src = robot.model
    jp = src.jointPlacements
    inertias = src.inertias
    model = pin.Model()
    model.gravity = src.gravity
    ff1, fc1 = _add_drone(model, robot, 0)
    h1 = robot.hinge_joint_ids[0]
    constraints = pin.StdVec_RigidConstraintModel()
    if robot.name == "fpr":
        root = src.getJointId("end_effector_root")
        q21 = src.getJointId("q21")
        h2 = robot.hinge_joint_ids[1]
        r1 = model.addJoint(ff1, pin.JointModelRX(), pin.SE3.Identity(), "drone_1_hinge_reversed")
        model.appendBodyToJoint(r1, inertias[root], jp[h1].inverse())
        j21 = model.addJoint(r1, pin.JointModelRX(), jp[h1].inverse() * jp[q21], "q21")
        model.appendBodyToJoint(j21, inertias[q21], pin.SE3.Identity())
        ff2, fc2 = _add_drone(model, robot, 1)
        # revolute closure at hinge 2: the hinge point and a point on its axis coincide (rank 5 of 6 rows)
        on_axis = pin.SE3(np.eye(3), np.array([axis_offset, 0.0, 0.0]))
        for offset in (pin.SE3.Identity(), on_axis):
            constraints.append(pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, j21, jp[h2] * offset,
                                                        ff2, offset, pin.LOCAL))
        freeflyers, frames = (ff1, ff2), (fc1, fc2)
        reversed_ids = {"drone_1_hinge_reversed": ("drone_1_hinge", -1.0), "q21": ("q21", 1.0)}
    elif robot.name == "prototype":
        j2 = src.getJointId("q2")
        j1 = src.getJointId("q1")
        r1 = model.addJoint(ff1, pin.JointModelRX(), pin.SE3.Identity(), "drone_1_hinge_reversed")
        model.appendBodyToJoint(r1, inertias[j2], jp[h1].inverse())
        r2 = model.addJoint(r1, pin.JointModelRX(), jp[h1].inverse(), "q2_reversed")
        model.appendBodyToJoint(r2, inertias[j1], jp[j2].inverse())
        pivot = pin.SE3.Identity()
        for name in ("pivot_yaw", "pivot_pitch", "q1"):
            pivot = pivot * jp[src.getJointId(name)]
        # joint 1 of the constraint is the world: its frame is fixed, so the LOCAL error and velocity agree
        constraints.append(pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, 0, pivot,
                                                    r2, jp[j2].inverse(), pin.LOCAL))
        freeflyers, frames = (ff1,), (fc1,)
        reversed_ids = {"drone_1_hinge_reversed": ("drone_1_hinge", -1.0), "q2_reversed": ("q2", -1.0)}
    else:  # pragma: no cover - Robot() already refuses other names
        raise ValueError(robot.name)
    data = model.createData()
    datas = pin.StdVec_RigidConstraintData()
    for cm in constraints:
        datas.append(cm.createData())
    settings = pin.ProximalSettings(accuracy, mu, max_iter)
    closed = ClosedChainModel(robot, model, data, constraints, datas, frames, freeflyers, reversed_ids, settings)
    closed.set_baumgarte(*baumgarte)
    pin.initConstraintDynamics(model, data, constraints, datas)
    return closed
