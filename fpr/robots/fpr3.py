"""The spatial FPR: three quadrotors carrying a platform in 6 DOF through three legs (Six et al., RA-L 2018).

Everything specific to it, for generic code to ask through ``robot.kind`` (:class:`Fpr3`):

* coordinates: ``q = [x y z psi theta phi q1 q2 q3 pitch1 yaw1 roll1 ... roll3]``: the platform's position (world)
  and its Z-Y-X angles (R_p = Rz(psi) Ry(theta) Rx(phi), roll-pitch-yaw), the legs' angles (q_i > 0: leg i below
  the platform's plane), each drone's ball angles relative to its leg (drone i's attitude in the platform frame is
  Rz(a_i) Ry(q_i + pitch_i) Rz(yaw_i) Rx(roll_i)). The planning vector is the chain s = q[:9];
* the drones' thrust vectors F_i are 3-vectors in world axes (``force_axes`` x, y, z);
* a drone's attitude from its thrust vector (:func:`ball_angles`, the one formula the planner and the controller
  share): z_d along F_i, x_d normal to leg i's hinge axis t_i = R_p Rz(a_i) e_y, i.e. in the vertical plane of
  leg i fixed in the platform (x_d = t_i x z_d / |t_i x z_d|, y_d = z_d x x_d). Its ball yaw is then 0 exactly.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import pinocchio as pin

from fpr.model import jets
from fpr.model.constrained import ClosureTree
from fpr.model.description import URDF_DIR
from fpr.model.inverse_dynamics import MotionInputs
from fpr.model.jets import Jet
from fpr.model.kinematics import last_axis
from fpr.model.robot import Layout
from fpr.model.spatial import SpatialChain
from fpr.robots import fpr3_control
from fpr.robots.base import GROUND_KIND, RobotKind
from fpr.robots.fpr3_geometry import LEGS, Fpr3Geometry
from fpr.robots.fpr3_motion import spatial_motion_inputs
from fpr.robots.planar_control import AttitudeTargets

_BALL = ("pitch", "yaw", "roll")

LEG_ANGLES = (0.0, 2 * np.pi / 3, 4 * np.pi / 3)
"""a_i: the directions of the legs' hinges in the platform's plane, leg i's hinge at Rz(a_i) [r_p 0 0] [rad]."""


def _rz(angle) -> np.ndarray:
    """Rz(angle), shape (..., 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    zero, one = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1), np.stack([zero, zero, one], -1)], -2)


def ball_angles(platform_rotation, legs, force, leg_angles=LEG_ANGLES) -> np.ndarray:
    r"""Each drone's ball angles (pitch_i, yaw_i, roll_i) whose thrust axis lies along its thrust vector F_i.

    The attitude rule: z_d = F_i / |F_i|, x_d normal to leg i's hinge axis t_i = R_p Rz(a_i) e_y (x_d = t_i x z_d /
    |t_i x z_d|, in the vertical plane of leg i fixed in the platform), y_d = z_d x x_d. In leg i's radial frame
    P_i = R_p Rz(a_i), with f = P_i^T F_i,

    .. math:: \mathrm{yaw}_i = 0, \quad q_i + \mathrm{pitch}_i = \operatorname{atan2}(f_x, f_z), \quad
              \mathrm{roll}_i = \operatorname{atan2}(-f_y, \sqrt{f_x^2 + f_z^2})

    (the drone's attitude in the platform frame being Rz(a_i) Ry(q_i + pitch_i) Rz(yaw_i) Rx(roll_i)). The rule is
    singular where F_i is parallel to t_i (a drone tilted 90 degrees from the platform's plane: the tilt bound
    excludes it). The pitch is unwrapped to within pi of -q_i (the drone level with the platform).

    Args:
        platform_rotation: R_p, shape (..., 3, 3).
        legs: leg angles q_i, shape (..., n_d) [rad].
        force: thrust vectors F_i in world axes, shape (..., n_d, 3) [N].
        leg_angles: a_i, shape (n_d,) [rad].

    Returns:
        (pitch_i, yaw_i, roll_i) of each drone, shape (..., n_d, 3) [rad].
    """
    radial = np.asarray(platform_rotation, float)[..., None, :, :] @ _rz(np.asarray(leg_angles, float))
    f = np.einsum("...ji,...j->...i", radial, np.asarray(force, float))  # P_i^T F_i
    legs = np.asarray(legs, float)
    beta = np.arctan2(f[..., 0], f[..., 2])  # q_i + pitch_i in (-pi, pi]
    pitch = np.remainder(beta - legs + np.pi, 2 * np.pi) - np.pi  # relative to level with the platform
    roll = np.arctan2(-f[..., 1], np.hypot(f[..., 0], f[..., 2]))
    return np.stack([pitch, np.zeros_like(pitch), roll], axis=-1)

LAYOUT = Layout(
    coordinates=("x", "y", "z", "psi", "theta", "phi", "q1", "q2", "q3")
    + tuple(f"{a}{i}" for i in (1, 2, 3) for a in _BALL),
    joints={
        **{f"q{i}": {f"q{i}": 1.0} for i in (1, 2, 3)},
        **{f"drone_{i}_ball_pitch": {f"pitch{i}": 1.0} for i in (1, 2, 3)},
        **{f"drone_{i}_ball_yaw": {f"yaw{i}": 1.0} for i in (1, 2, 3)},
        **{f"drone_{i}_hinge": {f"roll{i}": 1.0} for i in (1, 2, 3)},
    },
    drones=("drone_1", "drone_2", "drone_3"),
    chain=("x", "y", "z", "psi", "theta", "phi", "q1", "q2", "q3"),
    attitude=tuple(f"{a}{i}" for i in (1, 2, 3) for a in _BALL),
    drone_attitude=tuple(tuple(f"{a}{i}" for a in _BALL) for i in (1, 2, 3)),
    euler_root=True,
)
"""The spatial FPR's coordinates and their Pinocchio joints (the ball angles relative to the leg)."""


class Fpr3(RobotKind):
    """The spatial FPR (registry name "fpr3"): see the module docstring and :class:`~fpr.robots.base.RobotKind`."""

    name = "fpr3"
    xacro = URDF_DIR / "fpr3.urdf.xacro"
    urdf = URDF_DIR / "fpr3.urdf"
    layout = LAYOUT
    chain_units = ("m", "m", "m", "rad", "rad", "rad", "rad", "rad", "rad")
    reference_chain = (0.0, 0.0, 1.0, 0.0, 0.0, 0.0, np.pi / 4, np.pi / 4, np.pi / 4)
    mass_parameters = ("drone_mass", "leg_mass", "platform_mass")
    task_point_labels = ("platform", "leg tips")
    task_frame = "platform"
    force_axes = ("x", "y", "z")
    out_of_plane = ()
    constraint_kinds = {
        "ground": GROUND_KIND,
        "leg": ("rad", "leg angle m_ga <= q_i <= arccos(-r_p / l) - m_ga (legs out of the platform's plane; "
                       "tips off the platform's axis)"),
        "distance": ("m", "distance between two drones (leg tips) >= 2 (rotor arm + rotor disc radius) + m_gd"),
        "chart": ("rad", "platform pitch |theta| <= pi/2 - m_ga (the Z-Y-X chart's singularity)"),
        "singular": ("1", "det J (the legs' six lines) at least its value with every leg at m_ga, relative to the "
                          "reference pose's"),
        "tilt": ("rad", "drone tilt from the vertical <= pi/2 - m_ga"),
        "ball_roll": ("rad", "drone ball roll |roll_i| <= pi/2 - m_ga (the attitude rule's lock: the thrust along "
                             "the leg's hinge axis)"),
    }
    attitude_kinds = ("tilt", "ball_roll")
    drone_angle_column = "tilt"
    margin_hints = {
        "leg": "keep every leg angle between m_ga and arccos(-r_p / l) - m_ga",
        "distance": "move the legs' tips apart (open the legs towards the platform's plane)",
        "chart": "keep the platform's pitch theta within pi/2 - m_ga of level",
        "singular": "move away from the singular poses: legs in the platform's plane, tips on its axis",
    }
    titles = {
        "path": "Path of the platform and of the legs' tips (projections)",
        "coordinates": "Coordinates of the platform and of the legs",
        "energy": "Energy index $J_e$",
        "perturbation": r"Perturbation index $J_\omega$ (the drones' angular speeds)",
        "thrust": "Thrust of each drone",
        "roll": "Tilt of each drone from the vertical",
        "rotor_speeds": "Rotor speeds of each drone",
        "rotor_forces": r"Rotor forces $c_T \omega^2$ of each drone",
        "sim_path": "Platform and legs' tips, planned and simulated",
        "sim_coordinates": "Tracking of the platform's pose and of the legs",
        "sim_out_of_plane": "The spatial FPR tracks all of its coordinates",
        "sim_roll": "Tilt of each drone in simulation",
        "sim_heights": "Height of each leg's tip in simulation",
        "sim_rotor_speeds": "Rotor speeds of each drone in simulation",
        "sim_rotor_forces": r"Rotor forces $c_T \omega^2$ of each drone in simulation",
        "sim_energy": r"Energy $J_e$ and perturbation $J_\omega$ in planning and simulation",
    }

    # ------------------------------------------------------------------ geometry read from the model
    @cached_property
    def geometry(self) -> Fpr3Geometry:
        """The legs' hinges, directions and lengths (:class:`~fpr.robots.fpr3_geometry.Fpr3Geometry`)."""
        return Fpr3Geometry.from_model(self.robot.model, self.name)

    @cached_property
    def link_lengths(self) -> tuple[float, float, float]:
        """(l_1, l_2, l_3): each leg's hinge to its tip [m]."""
        return tuple(float(v) for v in self.geometry.lengths)

    @property
    def ground_height(self) -> float:
        """z of the ground: 0 [m] (the world's origin is on the ground; the tour takes off m_gd above it)."""
        return 0.0

    @cached_property
    def point_model(self) -> pin.Model:
        """The planning model: the platform and the legs, each drone a point mass at its leg's tip (its ball
        joint locked at 0, its rings on the leg), coordinates the planning vector s (Pinocchio's order).
        """
        model = pin.Model(self.robot.model)
        for j in self.robot.hinge_joint_ids:
            model.inertias[j] = pin.Inertia(model.inertias[j].mass, np.zeros(3), np.zeros((3, 3)))
        locked = [model.getJointId(f"drone_{i}_{part}") for i in LEGS for part in ("ball_pitch", "ball_yaw", "hinge")]
        reduced = pin.buildReducedModel(model, locked, pin.neutral(model))
        reduced.gravity = model.gravity
        return reduced

    @cached_property
    def spatial_chain(self) -> SpatialChain:
        """The jets model of :attr:`point_model` with the legs' tips (:class:`fpr.model.spatial.SpatialChain`)."""
        return SpatialChain(self.point_model, [f"leg_{i}_tip" for i in LEGS])

    @cached_property
    def drone_inertias(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(m_i (n_d,), centre of mass c_i in the drone's axes from its ball (n_d, 3), inertia about the ball
        I_o (n_d, 3, 3)) of each drone, from the model [kg, m, kg m^2].
        """
        masses, levers, inertias = [], [], []
        for j in self.robot.hinge_joint_ids:
            body = self.robot.model.inertias[j]
            c = np.asarray(body.lever, float)
            masses.append(body.mass)
            levers.append(c)
            inertias.append(body.inertia + body.mass * (c @ c * np.eye(3) - np.outer(c, c)))
        return np.array(masses), np.array(levers), np.array(inertias)

    @cached_property
    def _singular_scale(self) -> tuple[float, float]:
        """(det K at the reference pose, the singular margin's floor: det K with every leg at m_ga over it)."""
        reference = float(self.geometry.line_determinant(np.array(self.reference_chain[6:9])))
        floor = float(self.geometry.line_determinant(np.full(3, self.robot.margins.angle))) / reference
        return reference, floor

    # ------------------------------------------------------------------ kinematics
    def drone_joints(self, s) -> np.ndarray:
        """The legs' tips (the drones' balls) in the world, shape (..., 3, 3), tip i in row i, (x, y, z) [m]."""
        return self.geometry.tips(last_axis(s, 9, "s"))

    def drone_joint_velocities(self, s, s_dot) -> np.ndarray:
        """The tips' velocities J s', shape (..., 3, 3) [m/s]."""
        s, s_dot = last_axis(s, 9, "s"), last_axis(s_dot, 9, "s_dot")
        v = np.einsum("...ij,...j->...i", self.chain_jacobian(s), s_dot)
        return v.reshape(v.shape[:-1] + (3, 3))

    def chain_jacobian(self, s) -> np.ndarray:
        """J = d[tip_1; tip_2; tip_3]/ds in world axes, shape (..., 9, 9) (the planning model's)."""
        s = np.real(last_axis(s, 9, "s"))
        return self.spatial_chain.tip_jacobian(s)

    def task_points(self, s) -> tuple[np.ndarray, np.ndarray]:
        """(the platform's centre (..., 3), the legs' tips (..., 3, 3)) [m]."""
        s = last_axis(s, 9, "s")
        return s[..., :3], self.drone_joints(s)

    def joint_legends(self) -> tuple[tuple[str, str], ...]:
        """The legs' tips: ("tip 1 (drone 1)", "tip1"), ..."""
        return tuple((f"tip {i} (drone {i})", f"tip{i}") for i in LEGS)

    def height_panels(self) -> tuple[tuple[str, str, str, int, int | None], ...]:
        """z of each leg's tip, with its drone."""
        return tuple((rf"$z_{i}$ [m]", f"tip {i} (drone {i})", "joint", i - 1, i - 1) for i in LEGS)

    # ------------------------------------------------------------------ workspace
    def workspace_margins(self, s, mode: str | None = None) -> dict[str, np.ndarray]:
        """Signed margins (>= 0 where satisfied), each of shape (...): ``ground_<i>`` (tip i's height above
        m_gd [m]), ``leg_<i>_low`` / ``leg_<i>_high`` (m_ga <= q_i <= arccos(-r_p / l) - m_ga [rad]),
        ``distance_<ij>`` (tips i and j at least 2 (rotor arm + rotor disc radius) + m_gd apart [m]),
        ``chart_low`` / ``chart_high`` (|theta| <= pi/2 - m_ga [rad]) and ``singular`` (det K / det K_ref minus
        its value with every leg at m_ga, :mod:`fpr.robots.fpr3_geometry` [1]). ``mode`` is ignored (one
        assembly mode).
        """
        s = last_axis(s, 9, "s")
        margins, geometry = self.robot.margins, self.geometry
        tips = geometry.tips(s)
        out = {f"ground_{i}": tips[..., i - 1, 2] - (self.ground_height + margins.ground) for i in LEGS}
        high = geometry.highest_leg_angle - margins.angle
        for i in LEGS:
            out[f"leg_{i}_low"] = s[..., 5 + i] - margins.angle
            out[f"leg_{i}_high"] = high[i - 1] - s[..., 5 + i]
        least = 2 * self.drone_radius + margins.ground
        for i, j in ((1, 2), (1, 3), (2, 3)):
            gap = tips[..., i - 1, :] - tips[..., j - 1, :]
            out[f"distance_{i}{j}"] = np.sqrt(np.sum(gap * gap, axis=-1)) - least
        out["chart_low"] = s[..., 4] + (np.pi / 2 - margins.angle)
        out["chart_high"] = (np.pi / 2 - margins.angle) - s[..., 4]
        reference, floor = self._singular_scale
        out["singular"] = geometry.line_determinant(s[..., 6:9]) / reference - floor
        return out

    def singularity_distance(self, s) -> np.ndarray:
        """The legs' least angular distance to the singular sets their angles alone reach: a leg in the platform's
        plane (q_i = 0) or its tip on the platform's axis (q_i = arccos(-r_p / l)), shape (...) [rad].
        """
        legs = np.asarray(s, dtype=float)[..., 6:9]
        return np.min(np.minimum(legs, self.geometry.highest_leg_angle - legs), axis=-1)

    @cached_property
    def drone_radius(self) -> float:
        """A drone's reach from its centre: the rotor arm plus the rotor disc's radius of the quadrotor's drawing
        (``urdf/quadrotor.xacro``: discs of 0.133 m on a 0.263 m arm, scaled to the rotor arm) [m].
        """
        arm = float(np.max([np.linalg.norm(r.positions, axis=1).max() for r in self.robot.rotors]))
        return arm * (1.0 + 0.133 / 0.263)

    def mission_region(self, space: str, mode: str | None) -> tuple[np.ndarray, np.ndarray]:
        """Way points of random missions: the platform within 1 m of the reference pose's centre horizontally and
        0.8..1.8 m high, yaw within 60 degrees, tilts within 0.3 rad, legs 0.5..1.2 rad (joint and task space
        alike: the task coordinates are the planning ones) [m, rad].
        """
        low = np.array([-1.0, -1.0, 0.8, -np.pi / 3, -0.3, -0.3, 0.5, 0.5, 0.5])
        high = np.array([1.0, 1.0, 1.8, np.pi / 3, 0.3, 0.3, 1.2, 1.2, 1.2])
        return low, high

    def coordinate_axes(self) -> list[tuple[str, tuple[float, float] | None]]:
        """x, y, z, psi, phi unbounded; theta within pi/2 - m_ga; each leg in [m_ga, arccos(-r_p / l) - m_ga]."""
        m = self.robot.margins.angle
        high = self.geometry.highest_leg_angle - m
        return ([("x [m]", None), ("y [m]", None), ("z [m]", None), (r"$\psi$ [rad]", None),
                 (r"$\theta$ [rad]", (-(np.pi / 2 - m), np.pi / 2 - m)), (r"$\varphi$ [rad]", None)]
                + [(rf"$q_{i}$ [rad]", (m, float(high[i - 1]))) for i in LEGS])

    # ------------------------------------------------------------------ what the drones must do along a motion
    def motion_inputs(self, motion, external=None) -> MotionInputs:
        """Thrust vectors, ball angles, torques and rotor speeds along a motion
        (:func:`fpr.robots.fpr3_motion.spatial_motion_inputs`). ``attitude`` holds each drone's (pitch_i, yaw_i,
        roll_i), ``attitude_rate_squared`` |w_i|^2, ``angular_velocity`` w_i in the drone's axes; the planar
        ``roll`` fields hold each drone's tilt from the vertical [rad], its angular speed |w_i| [rad/s] and the
        magnitude of its angular acceleration [rad/s^2] (for files and figures).
        """
        return spatial_motion_inputs(self, motion, external)

    def generalized_forces(self, motion: Jet) -> Jet:
        """b = M s'' + c of the planning model (:attr:`point_model`) along a motion, by the spatial jets."""
        return self.spatial_chain.generalized_forces(motion)

    def thrust_vectors(self, motion: Jet, generalized: Jet, order: int | None = None) -> Jet:
        """F from J^T F = b, J the tips' Jacobian (world axes) along the motion, Jet of shape (N, 3, 3) [N]."""
        if order is not None:
            generalized = generalized.truncate(order)
        jacobian = self.spatial_chain.evaluate(motion.truncate(generalized.order + 2), forces=False).jacobian
        force = jets.solve(jacobian.mT, generalized)
        return force.reshape(force.shape[:-1] + (self.robot.n_drones, 3))

    def attitude_margins(self, inputs, scaled: bool) -> list[list[tuple[str, str, np.ndarray]]]:
        """Each drone's tilt from the vertical at most pi/2 - m_ga: ``tilt_<i>``; scaled, the smooth
        F_z / |F| - sin(m_ga) (the cosine of the tilt minus that of its bound) [1]; unscaled, the angle's margin
        pi/2 - m_ga - tilt [rad]. And its ball roll within pi/2 - m_ga, away from the attitude rule's lock (the
        thrust along the leg's hinge axis, where the rule's pitch is undefined): ``ball_roll_<i>`` "negative" and
        "positive" [rad], scaled or not.
        """
        m = self.robot.margins.angle
        force = inputs.thrust_vector
        rows = []
        for i in range(self.robot.n_drones):
            f = force[:, i]
            if scaled:
                norm = np.sqrt(f[:, 0] * f[:, 0] + f[:, 1] * f[:, 1] + f[:, 2] * f[:, 2])
                rows.append([(f"tilt_{i + 1}", "", f[:, 2] / norm - np.sin(m))])
            else:
                tilt = np.arctan2(np.hypot(f[:, 0], f[:, 1]), f[:, 2])
                rows.append([(f"tilt_{i + 1}", "", (np.pi / 2 - m) - tilt)])
            roll = inputs.attitude[:, i, 2]
            rows[-1] += [(f"ball_roll_{i + 1}", "negative", (np.pi / 2 - m) + roll),
                         (f"ball_roll_{i + 1}", "positive", (np.pi / 2 - m) - roll)]
        return rows

    # ---- control and simulation (fpr3_control)
    @cached_property
    def _control(self) -> fpr3_control.Fpr3Control:
        """The control constants read from the model (:class:`fpr.robots.fpr3_control.Fpr3Control`)."""
        return fpr3_control.Fpr3Control(self, ball_angles)

    def closed_chain(self, model, axis_offset: float) -> ClosureTree:
        """The platform a free flyer, the legs a tree on it, three free drones, three point closures
        (:func:`fpr.robots.fpr3_control.closed_chain`).
        """
        return fpr3_control.closed_chain(self, model, axis_offset)

    def closure_reader(self, closed) -> fpr3_control.Fpr3Reader:
        """The platform's pose and the ball angles off the closed chain
        (:class:`fpr.robots.fpr3_control.Fpr3Reader`).
        """
        return fpr3_control.Fpr3Reader(closed)

    def force_attitude(self, force, q=None) -> np.ndarray:
        """The ball angles (``layout.drone_attitude`` flattened, (9,)) of drones whose thrust axes lie along
        ``force`` (3, 3) [N] by the yaw rule, relative to the platform and legs of ``q`` (the reference pose
        without it) [rad].
        """
        if q is None:
            q = np.zeros(self.robot.nq)
            q[self.robot.indices(self.layout.chain)] = self.reference_chain
        return self._control.ball_angles(q, force).reshape(-1)

    def attitude_targets(self, q, v, force, reference, settings) -> AttitudeTargets:
        """Thrusts along the measured thrust axes, the ball angles of F_i relative to the measured platform and
        legs, the plan's ball-angle rates and accelerations (:meth:`fpr.robots.fpr3_control.Fpr3Control.targets`).
        """
        return self._control.targets(q, v, force, reference)

    def level_attitude(self, q) -> np.ndarray:
        """``q`` with each drone level in the world, yaw by the rule
        (:meth:`fpr.robots.fpr3_control.Fpr3Control.level`).
        """
        return self._control.level(q)


__all__ = ["LAYOUT", "LEG_ANGLES", "Fpr3", "ball_angles"]
