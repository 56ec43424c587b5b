"""The closed-chain formulation (free-flying drones + loop closure) against the minimal model."""

import numpy as np
import pinocchio as pin
import pytest
from helpers import random_state

import fpr
from fpr.model.constrained import build_closed_chain

SEED = 11


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_same_accelerations_as_the_minimal_model(name):
    """Same state, same thrusts and torques: pin.constraintDynamics on the closed chain gives the motion of
    the minimal model (drone twists' derivatives and joint accelerations), for random states and inputs.
    """
    robot = fpr.load(name)
    closed = build_closed_chain(robot)
    assert closed.model.nv - sum(c.residualSize() for c in closed.constraints) <= robot.nq
    rng = np.random.default_rng(SEED)
    for _ in range(10):
        q, v = random_state(robot, rng)
        thrust, torque = rng.uniform(3, 15, robot.n_drones), 0.3 * rng.normal(size=(robot.n_drones, 3))
        a = robot.forward_dynamics(q, v, thrust, torque)
        qc, vc, expected = closed.from_minimal(q, v, a)
        assert closed.closure_error(qc) < 1e-12
        ac = closed.forward_dynamics(qc, vc, closed.generalized_input(qc, thrust, torque))
        np.testing.assert_allclose(ac, expected, atol=1e-9 * (1 + np.abs(expected).max()))


def simulate_passive(closed, qc, vc, seconds, dt=1e-3):
    """Semi-implicit Euler on the Lie group, no thrust; returns the largest closure error seen."""
    zero = np.zeros(closed.model.nv)
    worst = 0.0
    for k in range(int(round(seconds / dt))):
        vc = vc + dt * closed.forward_dynamics(qc, vc, zero)
        qc = pin.integrate(closed.model, qc, vc * dt)
        if k % 20 == 0:
            worst = max(worst, closed.closure_error(qc))
    return worst


def test_fpr_closure_drift_stays_bounded():
    """10 s of falling and flailing at 1 kHz: Baumgarte stabilisation holds the loop closed to about a
    millimetre; without it the closure drifts an order of magnitude further.
    """
    robot = fpr.load("fpr")
    rng = np.random.default_rng(SEED + 1)
    q, v = random_state(robot, rng, scale=0.3)
    for c in ("x", "psi", "theta"):
        q[robot.index[c]] = v[robot.index[c]] = 0.0
    held = build_closed_chain(robot, baumgarte=(400.0, 40.0))
    free = build_closed_chain(robot, baumgarte=(0.0, 0.0))
    drift_held = simulate_passive(held, *held.from_minimal(q, v), seconds=10.0)
    drift_free = simulate_passive(free, *free.from_minimal(q, v), seconds=10.0)
    assert drift_held < 5e-3
    assert drift_free > 10 * drift_held


# ---------------------------------------------------------------------------------------------- to_minimal
def _poses(robot, rng, count):
    """Random states near the reference pose, then one with phi near 5pi/4 and large x, psi, theta."""
    for _ in range(count):
        yield random_state(robot, rng)
    q, v = random_state(robot, rng)
    q[robot.index["psi"]], q[robot.index["theta"]] = 1.2, -0.8
    if robot.name == "fpr":
        q[robot.index["x"]], q[robot.index["phi"]] = 0.7, 5 * np.pi / 4 + 0.01
    yield q, v


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_to_minimal_inverts_from_minimal(name):
    """to_minimal(from_minimal(q, v)) = (q, v) to 1e-10 near the reference pose, without a reference (the
    root roll is read within pi of 5pi/4), and the velocity map K is the derivative of from_minimal in v.
    """
    robot = fpr.load(name)
    closed = build_closed_chain(robot)
    rng = np.random.default_rng(SEED + 2)
    for q, v in _poses(robot, rng, 40):
        qc, vc = closed.from_minimal(q, v)
        q_back, v_back = closed.to_minimal(qc, vc)
        np.testing.assert_allclose(q_back, q, rtol=0, atol=1e-10)
        np.testing.assert_allclose(v_back, v, rtol=0, atol=1e-10)
        np.testing.assert_allclose(closed.to_minimal(qc), q, rtol=0, atol=1e-10)
        columns = np.array([closed.from_minimal(q, e)[1] for e in np.eye(robot.nq)]).T
        np.testing.assert_allclose(closed.velocity_map(q), columns, rtol=0, atol=1e-14)


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_to_minimal_unwraps_angles_to_the_reference(name):
    """With a reference, every angle comes back within pi of it: whole turns added to any angle, and
    theta beyond pi/2 (the second Z-Y-X Euler solution), are recovered exactly.
    """
    robot = fpr.load(name)
    closed = build_closed_chain(robot)
    angular = [i for i, c in enumerate(robot.layout.coordinates) if c not in ("x", "y", "z")]
    rng = np.random.default_rng(SEED + 3)
    for k, (q, v) in enumerate(_poses(robot, rng, 30)):
        q[angular] += 2 * np.pi * rng.integers(-2, 3, len(angular))
        if k % 3 == 0:
            q[robot.index["theta"]] = np.pi - q[robot.index["theta"]]  # beyond pi/2: the other Euler branch
        reference = q + rng.uniform(-1.0, 1.0, robot.nq)
        q_back, v_back = closed.to_minimal(*closed.from_minimal(q, v), reference=reference)
        np.testing.assert_allclose(q_back, q, rtol=0, atol=1e-10)
        np.testing.assert_allclose(v_back, v, rtol=0, atol=1e-10)


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_to_minimal_follows_a_passive_simulation(name):
    """400 steps of a passive simulation (semi-implicit Euler, so the loop drifts open by up to a few 1e-4 m):
    measured with the previous measurement as reference, q moves continuously, the minimal model at the
    measured q puts the drones where the closed chain has them to within the closure error, and K v
    reproduces vc to within the closure's velocity error.
    """
    robot = fpr.load(name)
    closed = build_closed_chain(robot)
    q, v = random_state(robot, np.random.default_rng(SEED + 4), scale=0.5)
    qc, vc = closed.from_minimal(q, v)
    zero, dt, previous = np.zeros(closed.model.nv), 1e-3, q
    for _ in range(400):
        vc = vc + dt * closed.forward_dynamics(qc, vc, zero)
        qc = pin.integrate(closed.model, qc, vc * dt)
        q, v = closed.to_minimal(qc, vc, reference=previous)
        assert np.abs(q - previous).max() < 0.05  # no 2 pi jump
        previous = q
        closure = closed.closure_error(qc)
        pin.framesForwardKinematics(closed.model, closed.data, qc)
        flyers = np.array([closed.data.oMf[f].translation for f in closed.drone_frame_ids])
        assert np.abs(robot.drone_positions(q) - flyers).max() <= 1.01 * closure + 1e-12
    assert closure > 1e-5  # the check above was not trivial
    assert np.abs(closed.velocity_map(q) @ v - vc).max() < 1e-2


def test_to_minimal_checks_shapes():
    robot = fpr.load("prototype")
    closed = build_closed_chain(robot)
    qc = closed.from_minimal(robot.configuration(q1=0.3, q2=1.2))
    with pytest.raises(fpr.ShapeError, match="qc"):
        closed.to_minimal(qc[:-1])
    with pytest.raises(fpr.ShapeError, match="reference"):
        closed.to_minimal(qc, reference=np.zeros(3))
