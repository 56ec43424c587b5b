"""Planar kinematics of the FPR and of the prototype (fpr.robots.fpr, fpr.robots.prototype, fpr.model.kinematics)
against the DESIGN.md formulas (seed 2.1, 3.3, ch. 4).

Tolerances: closed-form identities at 1e-12; inverse/direct round trips (kept >= 0.1 rad from the
singular set) at 1e-9; central finite differences (h = 1e-6) at 1e-8.
"""

import numpy as np
import pytest

from fpr.model.errors import SingularityError, WorkspaceError
from fpr.model.kinematics import check_margins, singularity_margin
from fpr.model.parameters import load_parameters, margins
from fpr.robots.fpr import (
    fpr_chain_jacobian,
    fpr_direct_kinematics,
    fpr_drone_joint_velocities,
    fpr_drone_joints,
    fpr_workspace_margins,
)
from fpr.robots.prototype import (
    prototype_inverse_kinematics,
    prototype_jacobian,
    prototype_joints,
    prototype_workspace_margins,
)

SEED = 20240611
L = float(load_parameters()["link_length"])
M = margins()
S0 = np.array([0.0, 0.0, 5 * np.pi / 4, np.pi / 2])
XI_NOMINAL = np.array([0.3, 1.2])
FD_STEP, FD_TOL = 1e-6, 1e-8


def wrap(a):
    """Angle difference wrapped to (-pi, pi]."""
    return np.angle(np.exp(1j * np.asarray(a)))


def random_fpr_poses(rng, n, mode):
    """Poses with sign(sin q21) = mode, at least 0.1 rad from the singular set."""
    return np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(0, 2 * np.pi, n),
                            mode * rng.uniform(0.1, np.pi - 0.1, n)])


def central_difference(f, x, h=FD_STEP):
    """d f / d x column by column, f: (n,) -> (m,)."""
    return np.column_stack([(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(len(x))])


# ---------------------------------------------------------------------------------------------- FPR
def test_reference_pose_drones_above_and_symmetric():
    r = fpr_drone_joints(S0, L)
    c = L / np.sqrt(2)
    np.testing.assert_allclose(r, [[c, c], [-c, c]], atol=1e-12)  # r_i = p - L u(.), DESIGN.md
    np.testing.assert_allclose(np.linalg.norm(r, axis=-1), [L, L], atol=1e-12)


def test_drone_joints_formula_random_batch():
    s = random_fpr_poses(np.random.default_rng(SEED), 50, 1).reshape(5, 10, 4)
    r = fpr_drone_joints(s, L)
    assert r.shape == (5, 10, 2, 2)
    phi, q21 = s[..., 2], s[..., 3]
    np.testing.assert_allclose(r[..., 0, 0], s[..., 0] - L * np.cos(phi), atol=1e-12)
    np.testing.assert_allclose(r[..., 0, 1], s[..., 1] - L * np.sin(phi), atol=1e-12)
    np.testing.assert_allclose(r[..., 1, 0], s[..., 0] - L * np.cos(phi + q21), atol=1e-12)
    np.testing.assert_allclose(r[..., 1, 1], s[..., 1] - L * np.sin(phi + q21), atol=1e-12)


UNEQUAL = (0.9, 0.6)  # (L1, L2) of a chain with unequal links [m]


@pytest.mark.parametrize("lengths", [L, UNEQUAL])
@pytest.mark.parametrize("mode", [1, -1])
def test_direct_kinematics_inverts_drone_joints(mode, lengths):
    s = random_fpr_poses(np.random.default_rng(SEED + mode), 200, mode)
    r = fpr_drone_joints(s, lengths)
    back = fpr_direct_kinematics(r[:, 0], r[:, 1], lengths, mode)
    np.testing.assert_allclose(back[:, :2], s[:, :2], atol=1e-9)
    np.testing.assert_allclose(wrap(back[:, 2:] - s[:, 2:]), 0.0, atol=1e-9)
    assert np.all((back[:, 2] >= 0) & (back[:, 2] < 2 * np.pi))
    other = fpr_direct_kinematics(r[:, 0], r[:, 1], lengths, -mode)  # the other assembly mode
    assert np.all(np.sign(np.sin(other[:, 3])) == -mode)
    np.testing.assert_allclose(fpr_drone_joints(other, lengths), r, atol=1e-9)


def test_unequal_links_drone_joints_formula():
    """r1 = p - L1 u(phi), r2 = p - L2 u(phi + q21) (DESIGN.md with one length per link)."""
    s = random_fpr_poses(np.random.default_rng(SEED), 20, 1)
    r = fpr_drone_joints(s, UNEQUAL)
    phi, q21 = s[:, 2], s[:, 3]
    np.testing.assert_allclose(r[:, 0, 1], s[:, 1] - UNEQUAL[0] * np.sin(phi), atol=1e-12)
    np.testing.assert_allclose(r[:, 1, 0], s[:, 0] - UNEQUAL[1] * np.cos(phi + q21), atol=1e-12)
    with pytest.raises(WorkspaceError, match=r"\|L1 - L2\| = 0\.3 m"):
        fpr_direct_kinematics([0.0, 0.0], [0.2, 0.0], UNEQUAL)  # closer than |L1 - L2|


def test_direct_kinematics_reference_mode_is_end_effector_below():
    r = fpr_drone_joints(S0, L)
    np.testing.assert_allclose(fpr_direct_kinematics(r[0], r[1], L, 1), S0, atol=1e-12)


@pytest.mark.parametrize("lengths", [L, UNEQUAL])
def test_chain_jacobian_finite_differences_and_determinant(lengths):
    s = random_fpr_poses(np.random.default_rng(SEED), 20, 1)
    s[10:, 3] *= -1
    jac = fpr_chain_jacobian(s, lengths)
    for k in range(len(s)):
        fd = central_difference(lambda x: fpr_drone_joints(x, lengths).reshape(4), s[k])
        np.testing.assert_allclose(jac[k], fd, atol=FD_TOL)
    l1, l2 = np.broadcast_to(lengths, 2)
    np.testing.assert_allclose(np.linalg.det(jac), -l1 * l2 * np.sin(s[:, 3]), atol=1e-12)


def test_drone_joint_velocities_are_jacobian_times_rate():
    rng = np.random.default_rng(SEED)
    s, s_dot = random_fpr_poses(rng, 30, 1), rng.normal(size=(30, 4))
    v = fpr_drone_joint_velocities(s, s_dot, L)
    np.testing.assert_allclose(v.reshape(30, 4), np.einsum("nij,nj->ni", fpr_chain_jacobian(s, L), s_dot),
                               atol=1e-12)
    h = FD_STEP  # independent check: d/dt r(s + t s_dot) at t = 0
    fd = (fpr_drone_joints(s + h * s_dot, L) - fpr_drone_joints(s - h * s_dot, L)) / (2 * h)
    np.testing.assert_allclose(v, fd, atol=FD_TOL)


def test_unreachable_drone_joints_raise_workspace_error():
    far = 2 * L + 0.01
    with pytest.raises(WorkspaceError, match=rf"{far:.4g} m apart.*L1 \+ L2 = {2 * L:.4g} m"):
        fpr_direct_kinematics([0.0, 0.0], [far, 0.0], L)
    r1 = np.zeros((3, 2))
    r2 = np.array([[1.0, 0.0], [0.0, far], [0.5, 0.5]])
    with pytest.raises(WorkspaceError) as info:
        fpr_direct_kinematics(r1, r2, L)
    np.testing.assert_allclose(info.value.pose, [0.0, 0.0, 0.0, far])  # the offending pair


# ---------------------------------------------------------------------------------------- prototype
def test_prototype_joints_formula():
    xi = np.random.default_rng(SEED).uniform(-np.pi, np.pi, (40, 2))
    r = prototype_joints(xi, L)
    q1, q12 = xi[:, 0], xi[:, 0] + xi[:, 1]
    np.testing.assert_allclose(r[:, 0], L * np.column_stack([np.cos(q1), np.sin(q1)]), atol=1e-12)
    r3 = L * np.column_stack([np.cos(q1) + np.cos(q12), np.sin(q1) + np.sin(q12)])
    np.testing.assert_allclose(r[:, 1], r3, atol=1e-12)


@pytest.mark.parametrize("arm, sign", [("down", 1.0), ("up", -1.0)])
def test_prototype_inverse_kinematics_round_trip(arm, sign):
    rng = np.random.default_rng(SEED)
    xi = np.column_stack([rng.uniform(-np.pi, np.pi, 200), sign * rng.uniform(0.1, np.pi - 0.1, 200)])
    r3 = prototype_joints(xi, L)[:, 1]
    back = prototype_inverse_kinematics(r3, L, arm)
    np.testing.assert_allclose(back[:, 1], xi[:, 1], atol=1e-9)
    np.testing.assert_allclose(wrap(back[:, 0] - xi[:, 0]), 0.0, atol=1e-9)
    np.testing.assert_allclose(prototype_joints(back, L)[:, 1], r3, atol=1e-9)


def test_prototype_jacobian_finite_differences_and_determinant():
    xi = np.random.default_rng(SEED).uniform(-np.pi, np.pi, (20, 2))
    jac = prototype_jacobian(xi, L)
    for k in range(len(xi)):
        fd = central_difference(lambda x: prototype_joints(x, L)[1], xi[k])
        np.testing.assert_allclose(jac[k], fd, atol=FD_TOL)
    np.testing.assert_allclose(np.linalg.det(jac), L**2 * np.sin(xi[:, 1]), atol=1e-12)


@pytest.mark.parametrize("q1", [-1.2, -0.3, 0.0, 0.7, 1.5])
def test_prototype_singular_null_space_is_minus1_2(q1):
    """Seed eq. 4.3: at q2 = 0, null(J_pr) = span([-1, 2])."""
    _, sv, vt = np.linalg.svd(prototype_jacobian([q1, 0.0], L))
    assert sv[1] < 1e-12 * sv[0]
    assert abs(vt[1] @ np.array([-1.0, 2.0]) / np.sqrt(5)) == pytest.approx(1.0, abs=1e-12)


def test_chapter4_task_is_one_drone_position_in_both_assembly_modes():
    """xi1 and xi2 put the drone joint at the same point; the seed prints 4 decimals, hence 1e-3."""
    xi1, xi2 = np.array([-0.9470, 1.8940]), np.array([0.9470, -1.8940])
    r3 = prototype_joints(np.stack([xi1, xi2]), L)[:, 1]
    np.testing.assert_allclose(r3[0], r3[1], atol=1e-3)
    np.testing.assert_allclose(prototype_inverse_kinematics(r3[0], L, "down"), xi1, atol=1e-3)
    np.testing.assert_allclose(prototype_inverse_kinematics(r3[0], L, "up"), xi2, atol=1e-3)


def test_prototype_unreachable_and_near_singular_targets():
    with pytest.raises(WorkspaceError, match=rf"2 L = {2 * L:.4g} m"):
        prototype_inverse_kinematics([2 * L + 0.01, 0.0], L)
    for q2 in (0.05, np.pi - 0.05):  # near full extension and near folded
        r3 = prototype_joints([0.2, q2], L)[1]
        prototype_inverse_kinematics(r3, L, min_margin=0.0)
        with pytest.raises(SingularityError) as info:
            prototype_inverse_kinematics(r3, L, min_margin=M.angle)
        assert info.value.margin == pytest.approx(0.05, abs=1e-9)
        assert info.value.required == M.angle


def test_singularity_margin_values():
    angles = [0.0, np.pi / 2, np.pi, -0.1, 3 * np.pi + 0.2]
    np.testing.assert_allclose(singularity_margin(angles), [0.0, np.pi / 2, 0.0, 0.1, 0.2], atol=1e-12)


# ----------------------------------------------------------------------------------- workspace margins
FPR_VIOLATIONS = [  # pose, the margins expected negative
    ([0.0, -0.9, np.pi + 0.3, np.pi / 2 - 0.3], {"ground_1"}),
    ([0.0, -0.9, 3 * np.pi / 2, np.pi / 2 - 0.3], {"ground_2"}),
    ([0.0, -1.3, 5 * np.pi / 4, np.pi / 2], {"ground_1", "ground_2"}),  # s0 lowered
    ([0.0, 0.0, np.pi + 0.1, np.pi / 2], {"phi_low"}),
    ([0.0, 0.0, 2 * np.pi - 0.1, 0.5], {"phi_high"}),
    ([0.0, 0.0, 3 * np.pi / 2 - 0.05, 0.1], {"q21_low"}),
    ([0.0, 0.0, np.pi + 0.3, np.pi - 0.1], {"q21_high"}),
]
PROTOTYPE_VIOLATIONS = [
    ([-1.2, 2.0], {"ground_2"}),
    ([-0.9, 0.25], {"ground_3"}),
    ([1.5, 0.5], {"fixed_point_2", "fixed_point_3", "q1_high"}),  # y_2 < m_gd needs |q1| > pi/2 - m_ga
    ([0.3, 2.5], {"fixed_point_3"}),
    ([1.38, 0.21], {"q1_high"}),
    ([0.3, 0.1], {"q2_low"}),
    ([-1.0, 2.98], {"q2_high"}),
]


@pytest.mark.parametrize("pose, expected", FPR_VIOLATIONS)
def test_fpr_margins_each_constraint(pose, expected):
    assert all(v > 0 for v in fpr_workspace_margins(S0, L, M).values())
    values = fpr_workspace_margins(np.array(pose), L, M)
    assert {k for k, v in values.items() if v < 0} == expected


@pytest.mark.parametrize("pose, expected", PROTOTYPE_VIOLATIONS)
def test_prototype_margins_each_constraint(pose, expected):
    assert all(v > 0 for v in prototype_workspace_margins(XI_NOMINAL, L, M).values())
    values = prototype_workspace_margins(np.array(pose), L, M)
    assert {k for k, v in values.items() if v < 0} == expected


def test_margin_values_are_the_seed_inequalities():
    """Seed 3.27-3.29 and 3.44, 3.46 as signed slacks, written out with cos/sin."""
    rng = np.random.default_rng(SEED)
    s = random_fpr_poses(rng, 20, 1)
    y, z, phi, q21 = s.T
    got = fpr_workspace_margins(s, L, M)
    floor = -L + M.ground
    np.testing.assert_allclose(got["ground_1"], z - L * np.sin(phi) - floor, atol=1e-12)
    np.testing.assert_allclose(got["ground_2"], z - L * np.sin(phi + q21) - floor, atol=1e-12)
    np.testing.assert_allclose(got["q21_low"], q21 - M.angle, atol=1e-12)
    xi = rng.uniform(-np.pi, np.pi, (20, 2))
    q1, q2 = xi.T
    got = prototype_workspace_margins(xi, L, M)
    np.testing.assert_allclose(got["ground_3"], L * (np.sin(q1) + np.sin(q1 + q2)) - floor, atol=1e-12)
    y3 = L * (np.cos(q1) + np.cos(q1 + q2))
    np.testing.assert_allclose(got["fixed_point_3"], y3 - M.ground, atol=1e-12)
    np.testing.assert_allclose(np.minimum(got["q1_low"], got["q1_high"]), np.pi / 2 - M.angle - np.abs(q1),
                               atol=1e-12)
    np.testing.assert_allclose(got["q2_high"], np.pi - M.angle - q2, atol=1e-12)


def test_check_margins_errors():
    check_margins(fpr_workspace_margins(S0, L, M), S0)  # nominal: no error
    low = S0 + [0.0, -1.3, 0.0, 0.0]
    with pytest.raises(WorkspaceError, match="ground_1"):
        check_margins(fpr_workspace_margins(low, L, M), low, margins=M)
    batch = np.stack([S0, [0.0, 0.0, 3 * np.pi / 2 - 0.05, 0.1], S0])
    with pytest.raises(SingularityError, match=r"q21_low.*0\.2 <= q21") as info:
        check_margins(fpr_workspace_margins(batch, L, M), batch, margins=M, singular=("q21",))
    assert (info.value.margin, info.value.required) == (pytest.approx(0.1), M.angle)
    np.testing.assert_allclose(info.value.configuration, batch[1])
    for xi, margin in (([0.3, 0.1], 0.1), ([0.9, -0.5], 0.5)):  # the second is arm up: q2 < m_ga but far
        with pytest.raises(SingularityError, match="q2_low") as info:
            check_margins(prototype_workspace_margins(np.array(xi), L, M), xi, margins=M, singular_angle=1,
                          singular=("q2_",))
        assert (info.value.margin, info.value.required) == (pytest.approx(margin), M.angle)
