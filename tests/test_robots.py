"""The registry of robots and their Pinocchio models in thesis coordinates, checked against physics they did not
compute themselves.
"""

import numpy as np
import pinocchio as pin
import pytest
from helpers import random_state

import fpr
import fpr.robots
from fpr.model.errors import RobotDefinitionError, ShapeError, UnknownRobotError
from fpr.robots.fpr import Fpr
from fpr.robots.prototype import Prototype

RNG_SEED = 20261122
FD_STEP = 1e-6
FD_TOL = 1e-6  # central differences with h = 1e-6: truncation ~1e-12, round-off ~1e-10 relative


@pytest.fixture(scope="module")
def robots():
    return {name: fpr.load(name) for name in fpr.ROBOTS}


def _planar(robots):
    """The robots whose chain moves in the y-z plane (the planar closed-form model applies to them)."""
    return [r for r in robots.values() if len(r.kind.force_axes) == 2]


def test_unknown_robot_and_bad_shapes(robots):
    with pytest.raises(UnknownRobotError, match="'fpr', 'prototype'"):
        fpr.load("hexapod")
    with pytest.raises(ShapeError, match=r"q.shape=\(3,\), expected \(9,\)"):
        robots["fpr"].mass_matrix(np.zeros(3))
    with pytest.raises(ShapeError, match="thrust"):
        robots["fpr"].input_wrenches([1.0], np.zeros((2, 3)))


def test_registry_maps_names_to_kinds():
    assert fpr.ROBOTS == fpr.robots.BUILTIN == ("fpr", "prototype", "fpr3")
    assert fpr.robots.names()[:3] == ("fpr", "prototype", "fpr3")
    assert fpr.robots.get("fpr") is Fpr and fpr.robots.get("prototype") is Prototype
    with pytest.raises(UnknownRobotError, match="'fpr', 'prototype'"):
        fpr.robots.get("hexapod")
    with pytest.raises(RobotDefinitionError, match="RobotKind"):
        fpr.robots.register(object)
    twin = type("Twin", (Fpr,), {})  # a second kind under a taken name

    with pytest.raises(RobotDefinitionError, match="taken"):
        fpr.robots.register(twin)


def test_a_registered_kind_is_loaded_and_bound(robots):
    """register() one line, load() by name; the robot holds its kind bound to it, also in its variants."""
    renamed = type("Renamed", (Fpr,), {"name": "fpr_renamed"})
    fpr.robots.register(renamed)
    try:
        robot = fpr.load("fpr_renamed", hinge_offset=0.0)
        assert isinstance(robot.kind, renamed) and robot.kind.robot is robot and robot.name == "fpr_renamed"
        assert type(robot.with_drones_as("point").kind) is renamed
        assert robot.hinge_offset == 0.0 and robot.link_length == robots["fpr"].link_length
    finally:
        fpr.robots.unregister("fpr_renamed")
    assert "fpr_renamed" not in fpr.robots.names()


def test_geometry_read_from_urdf(robots):
    r = robots["fpr"]
    p = r.parameters
    assert r.link_length == pytest.approx(p["link_length"])
    assert r.hinge_offset == pytest.approx(p["hinge_offset"])
    assert r.drone_mass == pytest.approx(p["drone_mass"])
    np.testing.assert_allclose(r.drone_masses, [p["drone_mass"]] * 2)
    np.testing.assert_allclose(r.hinge_offsets, [p["hinge_offset"]] * 2)
    assert r.kind.link_lengths == pytest.approx((p["link_length"],) * 2)
    assert robots["prototype"].kind.link_lengths == pytest.approx((p["link_length"],) * 2)
    assert r.total_mass == pytest.approx(2 * p["drone_mass"] + 2 * p["link_mass"] + p["end_effector_mass"])
    other = fpr.load("fpr", link_length=1.0, hinge_offset=0.0)
    assert other.link_length == pytest.approx(1.0)
    assert other.hinge_offset == pytest.approx(0.0)


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_drone_jacobians_against_finite_differences(robots, name):
    """J qdot is the drone body twist: compare with log6 of the frame displacement along qdot."""
    r = robots[name]
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(5):
        q, v = random_state(r, rng)
        jac = r.drone_jacobians(q)
        plus, minus = r.frame_placements(q + FD_STEP * v), r.frame_placements(q - FD_STEP * v)
        for i in range(r.n_drones):
            twist = pin.log6(minus[i].inverse() * plus[i]).vector / (2 * FD_STEP)
            np.testing.assert_allclose(jac[i] @ v, twist, atol=FD_TOL * (1 + np.abs(twist).max()))


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_gravity_is_gradient_of_potential_energy(robots, name):
    r = robots[name]
    rng = np.random.default_rng(RNG_SEED + 1)
    q, _ = random_state(r, rng)
    fd = np.array([(r.potential_energy(q + FD_STEP * e) - r.potential_energy(q - FD_STEP * e)) / (2 * FD_STEP)
                   for e in np.eye(r.nq)])
    np.testing.assert_allclose(r.gravity_terms(q), fd, atol=FD_TOL * 10)


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_mass_matrix_and_coriolis_from_lagrangian(robots, name):
    """M from the kinetic energy; c - g = Mdot qdot - d(qdot^T M qdot / 2)/dq by finite differences of M."""
    r = robots[name]
    rng = np.random.default_rng(RNG_SEED + 2)
    for _ in range(3):
        q, v = random_state(r, rng)
        m = r.mass_matrix(q)
        assert np.allclose(m, m.T)
        assert np.linalg.eigvalsh(m).min() > 0
        assert 0.5 * v @ m @ v == pytest.approx(r.kinetic_energy(q, v), rel=1e-12)
        m_dot = (r.mass_matrix(q + FD_STEP * v) - r.mass_matrix(q - FD_STEP * v)) / (2 * FD_STEP)
        grad = np.array([(v @ r.mass_matrix(q + FD_STEP * e) @ v - v @ r.mass_matrix(q - FD_STEP * e) @ v)
                         / (4 * FD_STEP) for e in np.eye(r.nq)])
        expected = m_dot @ v - grad
        np.testing.assert_allclose(r.nonlinear_effects(q, v) - r.gravity_terms(q), expected,
                                   atol=FD_TOL * (1 + np.abs(expected).max()))


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_forward_dynamics_aba_equals_mass_matrix_formula(robots, name):
    """qddot = M^-1 (J^T w - c) (seed 2.11): Pinocchio's ABA against CRBA + RNEA + Jacobians."""
    r = robots[name]
    rng = np.random.default_rng(RNG_SEED + 3)
    for _ in range(5):
        q, v = random_state(r, rng)
        thrust, torque = rng.uniform(3, 15, r.n_drones), 0.2 * rng.normal(size=(r.n_drones, 3))
        expected = np.linalg.solve(r.mass_matrix(q), r.generalized_input(q, thrust, torque) - r.nonlinear_effects(q, v))
        np.testing.assert_allclose(r.forward_dynamics(q, v, thrust, torque), expected, atol=1e-10)


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_attitude_model_predicts_attitude_accelerations(robots, name):
    """Seed 2.12-2.13: A_tau tau + M_inv_a (J_f^T f - c) equals the attitude rows of the forward dynamics."""
    r = robots[name]
    rng = np.random.default_rng(RNG_SEED + 4)
    q, v = random_state(r, rng)
    thrust, torque = rng.uniform(3, 15, r.n_drones), 0.2 * rng.normal(size=(r.n_drones, 3))
    att = r.attitude_model(q, v)
    expected = r.forward_dynamics(q, v, thrust, torque)[r.indices(r.layout.attitude)]
    np.testing.assert_allclose(att.attitude_acceleration(thrust, torque), expected, atol=1e-10)
    np.testing.assert_allclose(att.a_tau @ torque.reshape(-1) + att.m_inv_a @ (att.j_f.T @ thrust - att.c), expected,
                               atol=1e-10)


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_passive_robot_conserves_energy(robots, name):
    """No thrust, gravity on: RK4 on the minimal model keeps kinetic + potential energy over 2 s."""
    r = robots[name]
    rng = np.random.default_rng(RNG_SEED + 5)
    q, v = random_state(r, rng)
    zero_f, zero_tau = np.zeros(r.n_drones), np.zeros((r.n_drones, 3))

    def f(x):
        return np.concatenate([x[r.nq:], r.forward_dynamics(x[:r.nq], x[r.nq:], zero_f, zero_tau)])

    x = np.concatenate([q, v])
    e0 = r.kinetic_energy(q, v) + r.potential_energy(q)
    # (a step of 0.5 ms resolves the spatial FPR's spinning drones near their ball chart's lock, yaw +-pi/2, where
    # the random state takes them: 1 ms drifts by 3e-7 there, and the drift falls as dt^4)
    dt, drift = 5e-4, 0.0
    for _ in range(4000):
        k1 = f(x)
        k2 = f(x + dt / 2 * k1)
        k3 = f(x + dt / 2 * k2)
        k4 = f(x + dt * k3)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        e = r.kinetic_energy(x[:r.nq], x[r.nq:]) + r.potential_energy(x[:r.nq])
        drift = max(drift, abs(e - e0))
    scale = abs(e0) + r.total_mass * 9.81 * r.link_length  # an energy scale of the motion [J]
    assert drift / scale < 1e-7, drift


def test_planar_model_equals_pinocchio(robots):
    """The closed-form in-plane model (used by the planner) against Pinocchio's CRBA / RNEA."""
    rng = np.random.default_rng(RNG_SEED + 6)
    for r in _planar(robots):
        for kind in ("rigid", "point", "none"):
            planar = r.planar(kind)
            reference = r if kind == "rigid" else r.with_drones_as(kind)
            k = r.indices(planar.coordinates)
            for _ in range(3):
                q, v = random_state(r, rng)
                for c in ("x", "psi", "theta"):  # in the plane
                    if c in r.index:
                        q[r.index[c]] = v[r.index[c]] = 0.0
                np.testing.assert_allclose(planar.mass_matrix(q[k]), reference.mass_matrix(q)[np.ix_(k, k)], atol=1e-12)
                np.testing.assert_allclose(planar.bias(q[k], v[k]), reference.nonlinear_effects(q, v)[k], atol=1e-11)
                hinges = np.array([h.position(q[k]) for h in planar.hinges])
                np.testing.assert_allclose(hinges, reference.hinge_positions(q)[:, 1:], atol=1e-12)
                # out-of-plane coordinates are decoupled at a planar state
                out = np.setdiff1d(np.arange(r.nq), k)
                out = np.setdiff1d(out, r.indices(r.layout.rolls))
                assert np.abs(reference.mass_matrix(q)[np.ix_(out, k)]).max() < 1e-12
                assert np.abs(reference.nonlinear_effects(q, v)[out]).max() < 1e-11


def test_planar_jacobians_against_finite_differences(robots):
    rng = np.random.default_rng(RNG_SEED + 7)
    for r in _planar(robots):
        planar = r.planar("rigid")
        q = rng.normal(size=planar.n)
        v = rng.normal(size=planar.n)
        for point in [b.com for b in planar.bodies] + list(planar.hinges):
            fd = np.stack([(point.position(q + FD_STEP * e) - point.position(q - FD_STEP * e)) / (2 * FD_STEP)
                           for e in np.eye(planar.n)], axis=-1)
            np.testing.assert_allclose(point.jacobian(q), fd, atol=FD_TOL)
            jdot_v = (point.jacobian(q + FD_STEP * v) - point.jacobian(q - FD_STEP * v)) / (2 * FD_STEP) @ v
            np.testing.assert_allclose(point.bias(q, v), jdot_v, atol=FD_TOL * 10)


def test_rotor_mixing_is_the_seeds_eq_3_10(robots):
    """R_f built from the URDF's rotor frames and the spin senses equals seed eq. 3.10, and inverts."""
    p = robots["fpr"].parameters
    c_t, c_q, d = p["rotor_thrust_coefficient"], p["rotor_drag_coefficient"], p["rotor_arm"]
    seed = np.array([[c_t, c_t, c_t, c_t],
                     [0, d * c_t, 0, -d * c_t],
                     [-d * c_t, 0, d * c_t, 0],
                     [-c_q, c_q, -c_q, c_q]])
    for r in robots.values():
        for rotor in r.rotors:
            np.testing.assert_allclose(rotor.mixing_matrix, seed, rtol=1e-12, atol=1e-15)
            w2 = np.random.default_rng(0).uniform(0, 900**2, (6, 4))
            u = rotor.wrench(w2)
            np.testing.assert_allclose(rotor.speeds_squared(u[:, 0], u[:, 1:]), w2, rtol=1e-9)
            assert rotor.constants.max_rotor_thrust == pytest.approx(9.0, rel=1e-3)  # seed: 9 N per rotor
