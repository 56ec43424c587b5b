r"""The spatial FPR's geometry in closed form: the legs' tips, the workspace margins, the singular set.

Read from the Pinocchio model (:meth:`Fpr3Geometry.from_model`): each leg's hinge at Rz(a_i) [r_p 0 0] in the
platform frame, its frame there Rz(a_i) Rx(-pi/2) (the hinge turns about the frame's z, which is the platform's
Rz(a_i) e_y: q_i > 0 lowers the leg), its tip l_i along the leg. In the platform frame the tip is

.. math:: c_i = R_z(a_i) \, [r_p + l_i \cos q_i, \; 0, \; -l_i \sin q_i]^T,

and in the world p + R_p c_i, R_p = Rz(psi) Ry(theta) Rx(phi).

**Singular set.** With the tips held, leg i (a hinge on the platform, a ball at the tip) transmits to the
platform the forces through its tip c_i normal to t_i = dc_i/dq_i: along the leg l_i and along the hinge axis
h_i. The tips' Jacobian (velocities [v_p world, w_p platform frame, q'] -> tips, LS2N's) is singular exactly
where these six lines are dependent: rotating each tip's rows onto (t_i / l_i, l_i, h_i),

.. math:: \det J_{LS2N} = \pm\, l_1 l_2 l_3 \det K, \qquad
          K = \begin{bmatrix} d_k^T & (c_k \times d_k)^T \end{bmatrix}_{k = 1..6},

K the 6 x 6 matrix of the lines' Plücker coordinates (directions d_k among l_i, h_i, platform frame): it depends
on the leg angles alone, not on the platform's pose. For three legs at one angle q it is
-(27/4) sin^3 q (r_p + l cos q)^3 (tested against Pinocchio's Jacobian): zero with the legs in the platform's
plane and where r_p + l cos q = 0 (the tips on the platform's axis). In the planning chart det J_chart =
-cos(theta) det J_LS2N (the chart's own singularity, theta = +-pi/2, has its own margin).

All functions take a trailing coordinate axis with any leading batch shape and use elementwise operations only,
so that the values may be complex (complex step) or :class:`~fpr.model.dual.Dual` numbers (the planner's
derivatives).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np
import pinocchio as pin

from fpr.model.errors import RobotDefinitionError

LEGS = (1, 2, 3)


@dataclass(frozen=True)
class Fpr3Geometry:
    """The numbers of the spatial FPR's legs, read from its model.

    Attributes:
        radius: r_p of each leg, the platform centre to its hinge, shape (3,) [m].
        directions: a_i, the direction of each hinge in the platform's plane, shape (3,) [rad].
        lengths: l_i, hinge to tip, shape (3,) [m].
    """

    radius: np.ndarray
    directions: np.ndarray
    lengths: np.ndarray

    @classmethod
    def from_model(cls, model: pin.Model, name: str = "fpr3") -> "Fpr3Geometry":
        """Read the legs off a Pinocchio model with joints ``q<i>`` (the hinges) and ``drone_<i>_ball_pitch``.

        Raises:
            RobotDefinitionError: a hinge is not where the convention puts it (frame Rz(a_i) Rx(-pi/2) at
                Rz(a_i) [r_p 0 0]) or a tip is not on the leg's x axis.
        """
        radius, directions, lengths = [], [], []
        for i in LEGS:
            hinge = model.jointPlacements[model.getJointId(f"q{i}")]
            ball = model.jointPlacements[model.getJointId(f"drone_{i}_ball_pitch")]
            a = float(np.arctan2(hinge.translation[1], hinge.translation[0]))
            expected = pin.rpy.rpyToMatrix(0.0, 0.0, a) @ pin.rpy.rpyToMatrix(-np.pi / 2, 0.0, 0.0)
            if (abs(hinge.translation[2]) > 1e-12 or np.abs(hinge.rotation - expected).max() > 1e-9
                    or np.abs(ball.translation[1:]).max() > 1e-12):
                raise RobotDefinitionError(name, f"leg {i}'s hinge or tip is not where the spatial FPR's "
                                                 "convention puts it (urdf/leg.xacro)")
            radius.append(float(np.hypot(hinge.translation[0], hinge.translation[1])))
            directions.append(a)
            lengths.append(float(ball.translation[0]))
        return cls(np.array(radius), np.array(directions), np.array(lengths))

    @property
    def highest_leg_angle(self) -> np.ndarray:
        """arccos(-r_p / l_i): the leg angle that puts tip i on the platform's axis (a singular set) [rad]."""
        return np.arccos(-self.radius / self.lengths)

    # ------------------------------------------------------------------ kinematics
    def platform_tips(self, legs):
        """The tips c_i in the platform frame, three arrays (x, y, z) of shape (..., 3) [m].

        Args:
            legs: q_i, shape (..., 3) [rad].
        """
        s, c = np.sin(legs), np.cos(legs)
        reach = self.radius + self.lengths * c
        return reach * np.cos(self.directions), reach * np.sin(self.directions), -self.lengths * s

    def tips(self, s):
        """The tips in the world, shape (..., 3, 3) (tip i in row i) [m].

        Args:
            s: the planning vector [x y z psi theta phi q1 q2 q3], shape (..., 9).
        """
        x, y, z = self.platform_tips(s[..., 6:9])
        x, y, z = _rotate(s[..., 3:4], s[..., 4:5], s[..., 5:6], x, y, z)
        return np.stack([x + s[..., 0:1], y + s[..., 1:2], z + s[..., 2:3]], axis=-1)

    # ------------------------------------------------------------------ singular set
    def lines(self, legs) -> list[list]:
        """K: the Plücker coordinates [d, c x d] of the six lines along which the legs hold the platform (two
        per tip: along the leg, along its hinge axis), platform frame; a 6 x 6 nested list of arrays (...).
        """
        x, y, z = self.platform_tips(legs)
        s, c = np.sin(legs), np.cos(legs)
        ca, sa = np.cos(self.directions), np.sin(self.directions)
        rows = []
        for i in range(3):
            tip = (x[..., i], y[..., i], z[..., i])
            along = (c[..., i] * ca[i], c[..., i] * sa[i], -s[..., i])  # Rz(a) Ry(q) e_x
            hinge = (-sa[i] + 0.0 * c[..., i], ca[i] + 0.0 * c[..., i], 0.0 * c[..., i])  # Rz(a) e_y
            for d in (along, hinge):
                rows.append(list(d) + list(_cross(tip, d)))
        return rows

    def line_determinant(self, legs):
        """det K (:meth:`lines`), shape (...): zero on the singular set, its sign constant between [m^3]."""
        return _det6(self.lines(legs))


def _rotate(psi, theta, phi, x, y, z):
    """R_p (x, y, z), R_p = Rz(psi) Ry(theta) Rx(phi), componentwise (broadcast)."""
    sp, cp = np.sin(phi), np.cos(phi)
    y, z = cp * y - sp * z, sp * y + cp * z
    st, ct = np.sin(theta), np.cos(theta)
    x, z = ct * x + st * z, ct * z - st * x
    ss, cs = np.sin(psi), np.cos(psi)
    return cs * x - ss * y, ss * x + cs * y, z


def _cross(a, b):
    """a x b of two 3-tuples of arrays."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _det3(m, rows, cols):
    (a, b, c), (d, e, f), (g, h, k) = ([m[r][j] for j in cols] for r in rows)
    return a * (e * k - f * h) - b * (d * k - f * g) + c * (d * h - e * g)


def _det6(m):
    """Determinant of a 6 x 6 nested list of arrays by Laplace's expansion along its first three rows (20 products
    of complementary 3 x 3 minors): elementwise, for complex and dual values.
    """
    top, bottom = (0, 1, 2), (3, 4, 5)
    total = 0.0
    for cols in combinations(range(6), 3):
        rest = tuple(j for j in range(6) if j not in cols)
        sign = -1.0 if (sum(cols) + sum(top)) % 2 else 1.0
        total = total + sign * _det3(m, top, cols) * _det3(m, bottom, rest)
    return total


__all__ = ["Fpr3Geometry", "LEGS"]
