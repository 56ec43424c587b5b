"""The planar robots' part of the controller's inner loop: the default of :meth:`RobotKind.attitude_targets
<fpr.robots.base.RobotKind.attitude_targets>` and of the kind's other control hooks.

For drones that each have one roll phi_i about the world x axis and thrust vectors F_i in the world's y-z
plane (``force_axes = ("y", "z")``), from the outer loop's F_i and the measured state (seed 2.15, 2.20):

* the desired roll is the direction of F_i, phi_d,i = atan2(-F_iy, F_iz);
* the thrust is F_i's component on the drone's measured thrust axis b_z(phi_i) = (-sin phi_i, cos phi_i),
  corrected for the drone's offset d_i: f_i = b_z . F_i - m_i d_i phi_i'^2 (:mod:`controllers.ctc`);
* the attitude targets q_a,d = [psi_d, theta_d, phi_d,1, ...] in the order of ``layout.attitude`` (psi and
  theta first), with the plan's roll rates and accelerations as feed-forward and 0 for psi and theta;
* the lateral loop (a robot with ``"x"`` among its ``out_of_plane`` coordinates, the FPR): the pitch theta tilts
  every thrust out of the plane, so x is held by theta_d = (-k_px x - k_dx x') / (d x'' / d theta), clamped to
  +- ``max_pitch``, the sensitivity taken from the model at the hover pose ``kind.reference_chain``; psi_d = 0.
  A robot without x (the prototype's pinned chain): psi_d = theta_d = 0.

The compiled inner loop (``fpr/_native/alloc.c``'s ``inner``) performs the same operations in the same order;
:func:`compiled_constants` gives the robot's part of its constants.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np


class AttitudeTargets(NamedTuple):
    """What the inner loop tracks at one tick, from the outer loop's forces (:meth:`RobotKind.attitude_targets
    <fpr.robots.base.RobotKind.attitude_targets>`), as Python floats.

    Attributes:
        thrust: f_i each drone's thrust must give, n_d entries [N].
        target: q_a,d, the attitude loop's targets, one per coordinate of ``layout.attitude`` [rad].
        rate: q_a,d', their rates (feed-forward) [rad/s].
        acceleration: q_a,d'', their accelerations (feed-forward) [rad/s^2].
        pitch: the lateral loop's desired pitch theta_d [rad] (0.0 for a robot without that loop).
    """

    thrust: list
    target: list
    rate: list
    acceleration: list
    pitch: float


@dataclass(frozen=True)
class PlanarInner:
    """The robot's constants of the planar inner loop (:func:`planar_inner`).

    Attributes:
        rolls: positions of the rolls (``layout.rolls``) in q.
        attitude: positions of ``layout.attitude`` in q.
        mass_offset: m_i d_i of each drone [kg m].
        lateral: position of x in q when the lateral loop runs, else None.
        pitch_gain: d x'' / d theta at the hover pose [m/s^2/rad] (1.0 without the lateral loop).
    """

    rolls: list
    attitude: list
    mass_offset: list
    lateral: int | None
    pitch_gain: float


def planar_inner(kind) -> PlanarInner:
    """The constants of the planar inner loop of ``kind``'s robot (the lateral loop's sensitivity from its model)."""
    r = kind.robot
    mass_offset = (np.array(r.drone_masses) * np.array(r.hinge_offsets)).tolist()
    lateral = r.index["x"] if "x" in kind.out_of_plane else None
    pitch_gain = lateral_sensitivity(kind) if lateral is not None else 1.0
    return PlanarInner(r.indices(r.layout.rolls).tolist(), r.indices(r.layout.attitude).tolist(), mass_offset,
                       lateral, pitch_gain)


def lateral_sensitivity(kind) -> float:
    """d x'' / d theta at the hover pose s0 = ``kind.reference_chain`` with hover thrusts (rolls from the
    robot's inverse dynamics, a pitch of 1e-6 rad, Pinocchio's forward dynamics).
    """
    r = kind.robot
    s0 = np.array(kind.reference_chain, dtype=float)
    n_s = s0.size
    hover = kind.motion_inputs(np.concatenate([s0[None, None], np.zeros((4, 1, n_s))]))
    q = np.zeros(r.nq)
    q[r.indices(r.layout.chain)] = s0
    q[r.indices(r.layout.rolls)] = hover.roll[0]
    delta = 1e-6
    q[r.index["theta"]] = delta
    a = r.forward_dynamics(q, np.zeros(r.nq), hover.thrust[0], hover.torque[0])
    return float(a[r.index["x"]] / delta)


def planar_attitude_targets(inner: PlanarInner, q, v, force, reference, settings) -> AttitudeTargets:
    """The planar inner loop's targets (module docstring) at the measured (q, v) for the outer loop's ``force``
    (n_d, 2) [N], the ``reference``'s attitude feed-forward and the controller's ``settings``.
    """
    st = settings
    # on floats: a few numbers each, where every numpy call costs a microsecond or more
    ql, vl = q.tolist(), v.tolist()
    force = force.tolist()
    roll_desired = [math.atan2(-fy, fz) for fy, fz in force]  # (2.20)
    # f_i = b_z(phi_i) . F_i - m_i d_i phi_i'^2, b_z = (-sin phi, cos phi)
    thrust = [-math.sin(ql[i]) * fy + math.cos(ql[i]) * fz - md * vl[i] ** 2
              for i, (fy, fz), md in zip(inner.rolls, force, inner.mass_offset, strict=True)]
    # attitude references [psi, theta, rolls...]
    pitch = 0.0
    if inner.lateral is not None:
        kp, kd = st.lateral_frequency**2, 2 * st.lateral_damping * st.lateral_frequency
        pitch = (-kp * ql[inner.lateral] - kd * vl[inner.lateral]) / inner.pitch_gain
        pitch = min(max(pitch, -st.max_pitch), st.max_pitch)  # np.clip, cheaper on a float
    target = [0.0, pitch] + roll_desired
    rate = [0.0, 0.0] + reference.attitude_rate.tolist()
    acc = [0.0, 0.0] + reference.attitude_acceleration.tolist()
    return AttitudeTargets(thrust, target, rate, acc, pitch)


def compiled_constants(inner: PlanarInner, settings) -> list[float]:
    """The robot's part of the compiled inner loop's constants (``fpr/_native/alloc.c``'s ``inner``): n_d, the
    lateral loop (on, x's position or -1, its K_p, K_d, sensitivity, ``max_pitch``), the rolls' and the attitude
    coordinates' positions in q, m_i d_i; the controller appends K_pa and K_da.
    """
    st = settings
    lateral = inner.lateral is not None
    return [len(inner.rolls), float(lateral), inner.lateral if lateral else -1, st.lateral_frequency**2,
            2 * st.lateral_damping * st.lateral_frequency, inner.pitch_gain, st.max_pitch,
            *inner.rolls, *inner.attitude, *inner.mass_offset]


__all__ = ["AttitudeTargets", "PlanarInner", "compiled_constants", "lateral_sensitivity", "planar_attitude_targets",
           "planar_inner"]
