"""The closed-chain formulation (free-flying drones + loop closure) against the minimal model."""

import numpy as np
import pinocchio as pin
import pytest

import fpr
from helpers import random_state
from fpr.constrained import build_closed_chain

SEED = 11


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_same_accelerations_as_the_minimal_model(name):
    """Same state, same thrusts and torques: pin.constraintDynamics on the closed chain gives the motion of
    the minimal model (drone twists' derivatives and joint accelerations), for random states and inputs."""
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
    millimetre; without it the closure drifts an order of magnitude further."""
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
