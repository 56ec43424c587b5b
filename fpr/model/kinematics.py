"""Planar kinematics shared by every robot: unit vectors, distance to a Type-2 singularity, margin checks.

Conventions (DESIGN.md): u(a) = (cos a, sin a) in the world (y, z) plane. Each robot's own closed-form
kinematics (drone joints, chain Jacobian, direct / inverse kinematics, workspace margins) lives in its
robot module: :mod:`fpr.robots.fpr` (seed 2.1), :mod:`fpr.robots.prototype` (seed 3.3).

All functions accept a trailing coordinate axis and any leading batch shape.
"""

from __future__ import annotations

import numpy as np

from fpr.model.errors import ShapeError, SingularityError, WorkspaceError
from fpr.model.jets import inexact, sin_cos_value
from fpr.model.parameters import Margins
from fpr.model.parameters import margins as default_margins


def u(a) -> np.ndarray:
    """Unit vector (cos a, sin a), shape (..., 2) (complex-step arguments: :func:`fpr.model.jets.sin_cos_value`,
    numpy's values bit for bit without its complex sine and cosine).
    """
    sin, cos = sin_cos_value(inexact(a))
    return np.stack([cos, sin], axis=-1)


def u_perp(a) -> np.ndarray:
    """du/da = (-sin a, cos a), shape (..., 2) (complex-step arguments as :func:`u`)."""
    sin, cos = sin_cos_value(inexact(a))
    return np.stack([-sin, cos], axis=-1)


def last_axis(x, n: int, name: str) -> np.ndarray:
    """``x`` as an inexact array after checking that its last axis has n entries.

    Raises:
        ShapeError: ``x`` is a scalar or its last axis is not of size n.
    """
    x = inexact(x)
    if x.ndim == 0 or x.shape[-1] != n:
        raise ShapeError(name, x.shape, f"(..., {n})")
    return x


def singularity_margin(angle) -> np.ndarray:
    """Angular distance of q21 (FPR) or q2 (prototype) to the Type-2 singular set {k pi} [rad]."""
    r = np.mod(np.asarray(angle, dtype=float), np.pi)
    return np.minimum(r, np.pi - r)


GROUND_HINT = "raise the drone joint: it must stay at least m_gd above the ground"
"""Hint of :func:`check_margins` for a violated ``ground*`` margin."""


def check_margins(values: dict[str, np.ndarray], pose, what: str = "pose", *,
                  margins: Margins | None = None, singular_angle: int = -1, singular: tuple[str, ...] = (),
                  hints: dict[str, str] | None = None) -> None:
    """Raise a :class:`WorkspaceError` / :class:`SingularityError` naming the first violated margin.

    Args:
        values: signed margins (>= 0 where satisfied), e.g. from a robot kind's ``workspace_margins``.
        pose: the pose(s) they were computed at, shape (..., n) (planning coordinates).
        what: a name for the pose, used in the message.
        margins: planning margins; the angle margin m_ga is the required singularity margin
            (default: :func:`fpr.model.parameters.margins`).
        singular_angle: index in ``pose`` of the angle whose sine vanishes at the Type-2 singularity.
        singular: prefixes of the margin names that bound that angle away from the singularity
            (e.g. ``("q21",)``): their violation is a :class:`SingularityError`.
        hints: what to do, by prefix of margin name (e.g. ``{"phi": "keep pi + m_ga <= phi ..."}``);
            ``ground*`` margins have :data:`GROUND_HINT` by default.

    Raises:
        SingularityError: a ``singular`` bound is violated; ``margin`` is the distance of the singular
            angle to {k pi} at the worst pose, ``required`` is m_ga.
        WorkspaceError: any other bound is violated.
    """
    hints = {"ground": GROUND_HINT, **(hints or {})}
    pose = np.asarray(pose, dtype=float)
    for name, value in values.items():
        value = np.asarray(value, dtype=float)
        worst = float(np.min(value))
        if worst >= 0:
            continue
        k = int(np.argmin(value.reshape(-1)))
        bad_pose = np.broadcast_to(pose, value.shape + pose.shape[-1:]).reshape(-1, pose.shape[-1])[k]
        if singular and name.startswith(tuple(singular)):
            m = (margins or default_margins()).angle
            angle_name = name.split("_")[0]
            angle = float(bad_pose[singular_angle])
            raise SingularityError(
                bad_pose, float(singularity_margin(angle)), m,
                f"{what}: bound {name} violated by {-worst:.4g} rad ({angle_name} = {angle:.4g}); change the "
                f"pose so that {m:.4g} <= {angle_name} <= pi - {m:.4g} = {np.pi - m:.4g} rad",
            )
        hint = next((h for key, h in hints.items() if name.startswith(key)), f"make {name} >= 0")
        raise WorkspaceError(bad_pose, f"{what}: bound {name} violated by {-worst:.4g}; {hint}")
