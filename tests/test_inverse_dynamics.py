"""Inverse dynamics of a motion, the prototype's model against a hand derivation, and the p_i question."""

import numpy as np
import pytest

import fpr
from fpr.model.inverse_dynamics import inverse_dynamics, thrust_vectors
from fpr.model.jets import Jet
from fpr.model.parameters import load_parameters
from fpr.robots.prototype import prototype_jacobian

SEED = 7


def sine_motion(t, centre, amplitude, omega, phase):
    """s(t) = centre + A sin(w t + p) and its derivatives 0..4, shape (5, N, n)."""
    arg = omega * t[:, None] + phase
    return np.array([centre * (k == 0) + amplitude * omega**k * np.sin(arg + k * np.pi / 2) for k in range(5)])


REFERENCE = {"fpr": np.array([0.0, 0.0, 5 * np.pi / 4, np.pi / 2]), "prototype": np.array([0.3, 1.2])}


def smooth_motion(name, t):
    centre = REFERENCE.get(name, np.array(fpr.robots.get(name).reference_chain))
    n = len(centre)
    return sine_motion(t, centre, 0.2 * np.ones(n), np.linspace(1.0, 2.0, n), np.linspace(0.0, 1.0, n))


#: The robots whose drones have one roll each, the torques giving the rolls exactly in the full model (seed 2.24);
#: the spatial FPR's drones (on balls) are tested in tests/test_fpr3_kind.py.
PLANAR = tuple(name for name in fpr.ROBOTS if len(fpr.robots.get(name).force_axes) == 2)


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_round_trip_is_exact_without_hinge_offset(name):
    """d = 0: the planning model is exact, so the computed inputs give back the motion in the full 3D model."""
    robot = fpr.load(name, hinge_offset=0.0)
    t = np.linspace(0.0, 3.0, 13)
    inputs = inverse_dynamics(robot, smooth_motion(name, t))
    q, v, a = inputs.full_state(robot)
    for k in range(len(t)):
        acc = robot.forward_dynamics(q[k], v[k], inputs.thrust[k], inputs.torque[k])
        np.testing.assert_allclose(acc, a[k], atol=1e-9)


@pytest.mark.parametrize("name", PLANAR)
def test_round_trip_with_hinge_offset_differs_by_the_perturbation(name):
    """d > 0: the roll rows are exact (seed 2.24); the chain rows differ by the p_i perturbation of eq. 2.8,
    which vanishes with d: the residual scales with d.
    """
    t = np.linspace(0.0, 3.0, 9)
    residuals = []
    for d in (0.05, 0.1):
        robot = fpr.load(name, hinge_offset=d)
        inputs = inverse_dynamics(robot, smooth_motion(name, t))
        q, v, a = inputs.full_state(robot)
        rolls = robot.indices(robot.layout.rolls)
        worst = 0.0
        for k in range(len(t)):
            acc = robot.forward_dynamics(q[k], v[k], inputs.thrust[k], inputs.torque[k])
            np.testing.assert_allclose(acc[rolls], a[k][rolls], atol=1e-9)
            worst = max(worst, np.abs(acc - a[k]).max())
        residuals.append(worst)
    assert residuals[0] > 1e-4  # the approximation is real ...
    assert residuals[1] / residuals[0] == pytest.approx(2.0, rel=0.25)  # ... and first order in d


def test_planar_torques_equal_the_full_pseudo_inverse_law():
    """Seed 2.24 on the full 3D model (psi'' = theta'' = 0) gives the planar roll torques and zero pitch/yaw torques."""
    robot = fpr.load("fpr")
    t = np.linspace(0.0, 2.0, 5)
    inputs = inverse_dynamics(robot, smooth_motion("fpr", t))
    q, v, a = inputs.full_state(robot)
    for k in range(len(t)):
        att = robot.attitude_model(q[k], v[k])
        u_a = a[k][robot.indices(robot.layout.attitude)]
        tau = np.linalg.pinv(att.a_tau) @ (u_a + att.m_inv_a @ att.c - att.m_inv_a @ att.j_f.T @ inputs.thrust[k])
        np.testing.assert_allclose(tau, inputs.torque[k].reshape(-1), atol=1e-9)


def test_fpr_hover_balances_the_weight():
    """At rest the thrust vectors carry the whole robot: sum of vertical parts = m g, horizontal parts cancel."""
    robot = fpr.load("fpr")
    motion = np.zeros((5, 1, 4))
    motion[0, 0] = REFERENCE["fpr"]
    inputs = inverse_dynamics(robot, motion)
    total = inputs.thrust_vector[0].sum(axis=0)
    np.testing.assert_allclose(total, [0.0, robot.total_mass * 9.81], atol=1e-10)
    assert inputs.roll[0, 0] == pytest.approx(-inputs.roll[0, 1])  # symmetric pose, mirrored drones
    np.testing.assert_allclose(inputs.roll_rate, 0.0, atol=1e-12)
    np.testing.assert_allclose(robot.rotors[0].wrench(inputs.rotor_speed_squared[0, 0])[0], inputs.thrust[0, 0])


def hand_prototype_model(q, v, p):
    """M_pt, c_pt of a 2R arm with uniform rods, the end-effector sphere at joint 2 and the drone as a point
    mass at joint 3 (seed 3.37), derived by hand with parameters straight from parameters.yaml.
    """
    L, ml, r = p["link_length"], p["link_mass"], p["link_radius"]
    me, re, md, g = p["end_effector_mass"], p["end_effector_radius"], p["drone_mass"], p["gravity"]
    il = ml * (3 * r**2 + L**2) / 12  # rod about a transverse axis through its middle
    ie = 0.4 * me * re**2
    c1, c2, c12 = np.cos(q[0]), np.cos(q[1]), np.cos(q[0] + q[1])
    m11 = ((ml * L**2 / 4 + il) + (ml * (5 * L**2 / 4 + L**2 * c2) + il) + (me * L**2 + ie)
           + md * (2 * L**2 + 2 * L**2 * c2))
    m12 = ml * (L**2 / 4 + L**2 * c2 / 2) + il + ie + md * (L**2 + L**2 * c2)
    m22 = ml * L**2 / 4 + il + ie + md * L**2
    h = (ml / 2 + md) * L**2 * np.sin(q[1])
    coriolis = np.array([-h * (2 * v[0] * v[1] + v[1] ** 2), h * v[0] ** 2])
    gravity = g * np.array([(1.5 * ml + me + md) * L * c1 + (ml / 2 + md) * L * c12, (ml / 2 + md) * L * c12])
    return np.array([[m11, m12], [m12, m22]]), coriolis + gravity


def test_prototype_model_against_hand_derivation():
    robot = fpr.load("prototype")
    params = load_parameters()
    planar = robot.planar("point")
    rng = np.random.default_rng(SEED)
    for _ in range(10):
        q, v, a = rng.uniform(-np.pi, np.pi, 2), rng.normal(size=2), rng.normal(size=2)
        m_hand, c_hand = hand_prototype_model(q, v, params)
        np.testing.assert_allclose(planar.mass_matrix(q), m_hand, atol=1e-9)
        np.testing.assert_allclose(planar.bias(q, v), c_hand, atol=1e-9)
        np.testing.assert_allclose(planar.hinge_jacobian(q), prototype_jacobian(q, params["link_length"]), atol=1e-12)
        # J_pr^T F = M_pt xi'' + c_pt (seed 3.37): the drone's thrust vector from the inverse dynamics
        force = thrust_vectors(robot, Jet(np.stack([q, v, a])[:, None, :])).value[0, 0]
        np.testing.assert_allclose(prototype_jacobian(q, params["link_length"]).T @ force, m_hand @ a + c_hand,
                                   atol=1e-9)


def test_drone_translation_settles_the_p_i_question():
    """Which p_i is right in seed eq. 2.7-2.8?  Take the exact multibody model (d > 0), random state and inputs;
    get the chain forces f_pi from the passive chain alone (seed 2.6, J_p^T f_p = M_p s'' + c_p), and check
    [0; f_i] = R_i [f_pi + m (r_i'' - g)] + p_i. The exact derivation, p_i = [-m d phi''; -m d phi'^2], holds to
    round-off; the seed's printed p_i = [-m d phi'^2; m d phi''] does not.
    """
    robot = fpr.load("fpr")
    chain = robot.planar("none")
    m, d = robot.drone_mass, robot.hinge_offset
    gravity = np.array([0.0, -9.81])
    rng = np.random.default_rng(SEED + 1)
    k = robot.indices(robot.layout.chain)
    rolls = robot.indices(["phi1", "phi2"])
    for _ in range(5):
        q = robot.configuration(y=rng.normal(), z=rng.normal(), phi=5 * np.pi / 4 + 0.3 * rng.normal(),
                                q21=np.pi / 2 + 0.3 * rng.normal(), phi1=0.3 * rng.normal(), phi2=0.3 * rng.normal())
        v = robot.configuration(y=rng.normal(), z=rng.normal(), phi=rng.normal(), q21=rng.normal(),
                                phi1=rng.normal(), phi2=rng.normal())
        thrust, torque = rng.uniform(5, 15, 2), np.column_stack([0.3 * rng.normal(size=2), np.zeros((2, 2))])
        acc = robot.forward_dynamics(q, v, thrust, torque)
        s, sd, sdd = q[k], v[k], acc[k]
        jac = chain.hinge_jacobian(s)
        f_p = np.linalg.solve(jac.T, chain.inverse_dynamics(s, sd, sdd)).reshape(2, 2)
        r_dd = (jac @ sdd).reshape(2, 2) + np.array([h.bias(s, sd) for h in chain.hinges])
        for i in range(2):
            phi, phi_d, phi_dd = q[rolls[i]], v[rolls[i]], acc[rolls[i]]
            rot = np.array([[np.cos(phi), np.sin(phi)], [-np.sin(phi), np.cos(phi)]])  # R_i of seed 2.7
            base = rot @ (f_p[i] + m * (r_dd[i] - gravity))
            exact = base + np.array([-m * d * phi_dd, -m * d * phi_d**2])
            printed = base + np.array([-m * d * phi_d**2, m * d * phi_dd])
            np.testing.assert_allclose(exact, [0.0, thrust[i]], atol=1e-9)
            assert np.abs(printed - [0.0, thrust[i]]).max() > 1e-3
