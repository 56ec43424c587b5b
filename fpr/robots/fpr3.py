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

from fpr.model.constrained import ClosureTree
from fpr.model.description import URDF_DIR
from fpr.model.robot import Layout
from fpr.robots import fpr3_control
from fpr.robots.base import RobotKind
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
    """The spatial FPR (three drones, a platform in 6 DOF)."""

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

    # ---- control and simulation (fpr3_control)
    @cached_property
    def _control(self) -> fpr3_control.Fpr3Control:
        """The control constants read from the model (:class:`fpr.robots.fpr3_control.Fpr3Control`)."""
        return fpr3_control.Fpr3Control(self)

    @property
    def ground_height(self) -> float:
        """z of the ground [m]: 0 (the drones sit on their balls at the legs' tips, no link below them)."""
        return 0.0

    def closed_chain(self, model, axis_offset: float) -> ClosureTree:
        """The platform a free flyer, the legs a tree on it, three free drones, three point closures
        (:func:`fpr.robots.fpr3_control.closed_chain`)."""
        return fpr3_control.closed_chain(self, model, axis_offset)

    def closure_reader(self, closed) -> fpr3_control.Fpr3Reader:
        """The platform's pose and the ball angles off the closed chain (:class:`fpr.robots.fpr3_control.Fpr3Reader`)."""
        return fpr3_control.Fpr3Reader(closed)

    def force_attitude(self, force, q=None) -> np.ndarray:
        """The ball angles (``layout.drone_attitude`` flattened, (9,)) of drones whose thrust axes lie along
        ``force`` (3, 3) [N] by the yaw rule, relative to the platform and legs of ``q`` (the reference pose
        without it) [rad]."""
        if q is None:
            q = np.zeros(self.robot.nq)
            q[self.robot.indices(self.layout.chain)] = self.reference_chain
        return self._control.ball_angles(q, force).reshape(-1)

    def attitude_targets(self, q, v, force, reference, settings) -> AttitudeTargets:
        """Thrusts along the measured thrust axes, the ball angles of F_i relative to the measured platform and
        legs, the plan's ball-angle rates and accelerations (:meth:`fpr.robots.fpr3_control.Fpr3Control.targets`)."""
        return self._control.targets(q, v, force, reference)

    def level_attitude(self, q) -> np.ndarray:
        """``q`` with each drone level in the world, yaw by the rule (:meth:`fpr.robots.fpr3_control.Fpr3Control.level`)."""
        return self._control.level(q)


__all__ = ["LAYOUT", "LEG_ANGLES", "Fpr3", "ball_angles"]
