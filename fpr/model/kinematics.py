"""Planar kinematics of the passive chain, closed form and vectorised (seed 2.1, 3.3, fig. 3.5).

Conventions (DESIGN.md): u(a) = (cos a, sin a) in the world (y, z) plane.

* FPR, s = [y z phi q21]: drone joints r1 = p - L u(phi), r2 = p - L u(phi + q21), p = (y, z).
  The inverse kinematics (pose -> drone joints) is unique; the direct kinematics (drone joints ->
  pose) has two assembly modes, ``mode = sign(sin q21)`` (+1: the end-effector hangs below the
  drones, as in the reference pose s0 = [0 0 5pi/4 pi/2]). Type-2 singularity: sin(q21) = 0.
* Prototype, xi = [q1 q2]: joint 2 = L u(q1), drone joint 3 = L u(q1) + L u(q1 + q2).
  "Arm down" is q2 > 0. Type-2 singularity: sin(q2) = 0, null(J_pr) = span([-1, 2]) at q2 = 0.

All functions accept a trailing coordinate axis and any leading batch shape.
"""

from __future__ import annotations

import numpy as np

from fpr.model.errors import ShapeError, SingularityError, WorkspaceError
from fpr.model.jets import inexact
from fpr.model.parameters import Margins
from fpr.model.parameters import margins as default_margins


def u(a) -> np.ndarray:
    """Unit vector (cos a, sin a), shape (..., 2)."""
    a = inexact(a)
    return np.stack([np.cos(a), np.sin(a)], axis=-1)


def u_perp(a) -> np.ndarray:
    """du/da = (-sin a, cos a), shape (..., 2)."""
    a = inexact(a)
    return np.stack([-np.sin(a), np.cos(a)], axis=-1)


def _last(x, n: int, name: str) -> np.ndarray:
    x = inexact(x)
    if x.ndim == 0 or x.shape[-1] != n:
        raise ShapeError(name, x.shape, f"(..., {n})")
    return x


def singularity_margin(angle) -> np.ndarray:
    """Angular distance of q21 (FPR) or q2 (prototype) to the Type-2 singular set {k pi} [rad]."""
    r = np.mod(np.asarray(angle, dtype=float), np.pi)
    return np.minimum(r, np.pi - r)


# ---------------------------------------------------------------------------------------------- FPR
def fpr_drone_joints(s, link_length: float) -> np.ndarray:
    """Drone joint positions r_i of the FPR (inverse kinematics), shape (..., 2, 2): [r1, r2].

    Args:
        s: chain coordinates [y z phi q21], shape (..., 4) [m, m, rad, rad].
        link_length: L [m].
    """
    s = _last(s, 4, "s")
    p = s[..., :2]
    r1 = p - link_length * u(s[..., 2])
    r2 = p - link_length * u(s[..., 2] + s[..., 3])
    return np.stack([r1, r2], axis=-2)


def fpr_drone_joint_velocities(s, s_dot, link_length: float) -> np.ndarray:
    """Velocities of the drone joints, shape (..., 2, 2): [dr1/dt, dr2/dt] [m/s]."""
    s, s_dot = _last(s, 4, "s"), _last(s_dot, 4, "s_dot")
    v = s_dot[..., :2]
    v1 = v - link_length * u_perp(s[..., 2]) * s_dot[..., 2:3]
    v2 = v - link_length * u_perp(s[..., 2] + s[..., 3]) * (s_dot[..., 2:3] + s_dot[..., 3:4])
    return np.stack([v1, v2], axis=-2)


def fpr_chain_jacobian(s, link_length: float) -> np.ndarray:
    """J_p: d[r1; r2]/ds, shape (..., 4, 4) (seed 2.6). det J_p = -L^2 sin(q21)."""
    s = _last(s, 4, "s")
    jac = np.zeros(s.shape[:-1] + (4, 4))
    jac[..., 0, 0] = jac[..., 1, 1] = jac[..., 2, 0] = jac[..., 3, 1] = 1.0
    jac[..., 0:2, 2] = -link_length * u_perp(s[..., 2])
    w = -link_length * u_perp(s[..., 2] + s[..., 3])
    jac[..., 2:4, 2] = w
    jac[..., 2:4, 3] = w
    return jac


def fpr_direct_kinematics(r1, r2, link_length: float, mode: int = 1) -> np.ndarray:
    """End-effector pose s = [y z phi q21] from the drone joints, for one assembly mode.

    Args:
        r1, r2: drone joint positions, shape (..., 2) [m].
        link_length: L [m].
        mode: +1 for sin(q21) > 0 (end-effector below the drones, the reference mode), -1 otherwise.

    Returns:
        s, shape (..., 4), with phi in [0, 2 pi) and q21 in (-pi, pi].

    Raises:
        WorkspaceError: the joints are further apart than 2 L.
    """
    r1, r2 = _last(r1, 2, "r1"), _last(r2, 2, "r2")
    if mode not in (1, -1):
        raise ValueError(f"mode={mode!r}: use +1 (sin q21 > 0) or -1")
    delta = r2 - r1
    dist = np.linalg.norm(delta, axis=-1)
    if np.any(dist > 2 * link_length) or np.any(dist == 0):
        flat = dist.reshape(-1)
        i = int(np.argmax(flat)) if np.any(flat > 2 * link_length) else int(np.argmin(flat))
        r1b, r2b = np.broadcast_to(r1, delta.shape), np.broadcast_to(r2, delta.shape)
        raise WorkspaceError(
            np.concatenate([r1b.reshape(-1, 2)[i], r2b.reshape(-1, 2)[i]]),
            f"drone joints {flat[i]:.4g} m apart; they must be closer than 2 L = {2 * link_length:.4g} m "
            "and distinct",
        )
    e = delta / dist[..., None]
    normal = np.stack([-e[..., 1], e[..., 0]], axis=-1)
    h = np.sqrt(np.maximum(link_length**2 - (dist / 2) ** 2, 0.0))
    p = (r1 + r2) / 2 + mode * h[..., None] * normal
    a1 = p - r1
    a2 = p - r2
    phi = np.mod(np.arctan2(a1[..., 1], a1[..., 0]), 2 * np.pi)
    q21 = np.angle(np.exp(1j * (np.arctan2(a2[..., 1], a2[..., 0]) - phi)))
    return np.concatenate([p, phi[..., None], q21[..., None]], axis=-1)


def fpr_workspace_margins(s, link_length: float, margins: Margins) -> dict[str, np.ndarray]:
    """Signed margins of the FPR's geometric constraints (>= 0 where satisfied) (seed 3.27-3.29).

    Returns:
        ``{"ground_1", "ground_2"}`` drone joint heights above -L + m_gd [m];
        ``{"phi_low", "phi_high"}`` for pi + m_ga <= phi <= 2 pi - m_ga [rad];
        ``{"q21_low", "q21_high"}`` for m_ga <= q21 <= pi - m_ga [rad].
    """
    s = _last(s, 4, "s")
    r = fpr_drone_joints(s, link_length)
    ground = -link_length + margins.ground
    return {
        "ground_1": r[..., 0, 1] - ground,
        "ground_2": r[..., 1, 1] - ground,
        "phi_low": s[..., 2] - (np.pi + margins.angle),
        "phi_high": (2 * np.pi - margins.angle) - s[..., 2],
        "q21_low": s[..., 3] - margins.angle,
        "q21_high": (np.pi - margins.angle) - s[..., 3],
    }


# ---------------------------------------------------------------------------------------- prototype
def prototype_joints(xi, link_length: float) -> np.ndarray:
    """Joint 2 and drone joint 3 of the prototype, shape (..., 2, 2): [r2, r3] (direct kinematics)."""
    xi = _last(xi, 2, "xi")
    r2 = link_length * u(xi[..., 0])
    r3 = r2 + link_length * u(xi[..., 0] + xi[..., 1])
    return np.stack([r2, r3], axis=-2)


def prototype_jacobian(xi, link_length: float) -> np.ndarray:
    """J_pr: d r3 / d xi, shape (..., 2, 2) (seed 3.35, with the sign convention of DESIGN.md).

    .. math:: J_{pr} = L \\begin{bmatrix} -\\sin q_1 - \\sin(q_1+q_2) & -\\sin(q_1+q_2) \\\\
              \\cos q_1 + \\cos(q_1+q_2) & \\cos(q_1+q_2) \\end{bmatrix}, \\quad \\det J_{pr} = L^2 \\sin q_2
    """
    xi = _last(xi, 2, "xi")
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
    """
    r3 = _last(r3, 2, "r3")
    if arm not in ("down", "up"):
        raise ValueError(f"arm={arm!r}: use 'down' (q2 > 0) or 'up' (q2 < 0)")
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
    ``q2_high`` the one to q2 = -pi.
    """
    xi = _last(xi, 2, "xi")
    if arm not in ("down", "up"):
        raise ValueError(f"arm={arm!r}: use 'down' (q2 > 0) or 'up' (q2 < 0)")
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


_WORKSPACE_HINTS = {
    "ground": "raise the drone joint: it must stay at least m_gd above the ground z = -L",
    "fixed_point": "move the joint away from the fixed point: its y must be at least m_gd",
    "phi": "keep pi + m_ga <= phi <= 2 pi - m_ga (end-effector below the first drone)",
    "q1": "keep |q1| <= pi/2 - m_ga",
}


def check_margins(values: dict[str, np.ndarray], pose, what: str = "pose", *,
                  margins: Margins | None = None, singular_angle: int = -1) -> None:
    """Raise a :class:`WorkspaceError` / :class:`SingularityError` naming the first violated margin.

    Args:
        values: signed margins, from :func:`fpr_workspace_margins` or :func:`prototype_workspace_margins`.
        pose: the pose(s) they were computed at, shape (..., n): s for the FPR, xi for the prototype.
        what: a name for the pose, used in the message.
        margins: planning margins; the angle margin m_ga is the required singularity margin
            (default: :func:`fpr.model.parameters.margins`).
        singular_angle: index in ``pose`` of the angle whose sine vanishes at the Type-2 singularity
            (q21 = s[..., 3] for the FPR, q2 = xi[..., 1] for the prototype: the last entry in both).

    Raises:
        SingularityError: a ``q21_*`` / ``q2_*`` bound is violated; ``margin`` is the distance of the
            singular angle to {k pi} at the worst pose, ``required`` is m_ga.
        WorkspaceError: any other bound is violated.
    """
    pose = np.asarray(pose, dtype=float)
    for name, value in values.items():
        value = np.asarray(value, dtype=float)
        worst = float(np.min(value))
        if worst >= 0:
            continue
        k = int(np.argmin(value.reshape(-1)))
        bad_pose = np.broadcast_to(pose, value.shape + pose.shape[-1:]).reshape(-1, pose.shape[-1])[k]
        if name.startswith(("q21", "q2_")):
            m = (margins or default_margins()).angle
            angle_name = name.split("_")[0]
            angle = float(bad_pose[singular_angle])
            raise SingularityError(
                bad_pose, float(singularity_margin(angle)), m,
                f"{what}: bound {name} violated by {-worst:.4g} rad ({angle_name} = {angle:.4g}); change the "
                f"pose so that {m:.4g} <= {angle_name} <= pi - {m:.4g} = {np.pi - m:.4g} rad",
            )
        hint = next((h for key, h in _WORKSPACE_HINTS.items() if name.startswith(key)), f"make {name} >= 0")
        raise WorkspaceError(bad_pose, f"{what}: bound {name} violated by {-worst:.4g}; {hint}")
