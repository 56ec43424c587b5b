"""The spatial FPR: three quadrotors carrying a platform in 6 DOF through three legs (Six et al., RA-L 2018).

Everything specific to it, for generic code to ask through ``robot.kind`` (:class:`Fpr3`):

* coordinates: ``q = [x y z psi theta phi q1 q2 q3 pitch1 yaw1 roll1 ... roll3]``: the platform's position (world)
  and its Z-Y-X angles (R_p = Rz(psi) Ry(theta) Rx(phi), roll-pitch-yaw), the legs' angles (q_i > 0: leg i below
  the platform's plane), each drone's ball angles relative to its leg (drone i's attitude in the platform frame is
  Rz(a_i) Ry(q_i + pitch_i) Rz(yaw_i) Rx(roll_i)). The planning vector is the chain s = q[:9];
* the drones' thrust vectors F_i are 3-vectors in world axes (``force_axes`` x, y, z).
"""

from __future__ import annotations

import numpy as np

from fpr.model.description import URDF_DIR
from fpr.model.robot import Layout
from fpr.robots.base import RobotKind

_BALL = ("pitch", "yaw", "roll")

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


__all__ = ["LAYOUT", "Fpr3"]
