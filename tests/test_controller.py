"""The cascaded CTC and its rotor allocation QP (seed 2.14-2.24)."""

from __future__ import annotations

import numpy as np
from helpers import HOVER_POSES

from controllers.allocation import Allocator, allocation_qp, pseudo_inverse_law, selectors
from controllers.ctc import CascadedController, ControllerSettings, Reference
from fpr.model.inverse_dynamics import inverse_dynamics


def _random_state(robot, q0, rng, spread=0.05):
    return q0 + spread * rng.normal(size=robot.nq), 0.2 * spread * rng.normal(size=robot.nq)


def test_qp_built_without_solver_is_minimised_by_the_thesis_law(hover):
    """The pseudo-inverse law (2.24) makes the gradient H z + g of the built QP vanish."""
    robot, q0, inputs, _ = hover
    rng = np.random.default_rng(3)
    s_f, s_tau = selectors(robot)
    for _ in range(5):
        q, v = _random_state(robot, q0, rng)
        attitude = robot.attitude_model(q, v)
        thrust = inputs.thrust[0] * (1 + 0.05 * rng.normal(size=robot.n_drones))
        u_a = rng.normal(size=len(robot.layout.attitude))
        tau = pseudo_inverse_law(attitude, thrust, u_a)
        z = np.concatenate([rotor.speeds_squared(thrust[i], tau[i]) for i, rotor in enumerate(robot.rotors)])
        h, g = allocation_qp(attitude, s_f, s_tau, thrust, u_a, 1.0, 1.0, 100.0)
        assert np.allclose(h, h.T) and np.linalg.eigvalsh(h).min() > -1e-9 * np.abs(h).max()
        np.testing.assert_allclose(h @ z + g, 0.0, atol=1e-9 * np.abs(g).max())
        # and the law does give the wanted accelerations and thrusts (2.13)
        np.testing.assert_allclose(attitude.attitude_acceleration(thrust, tau), u_a, atol=1e-9)


def test_qp_equals_pseudo_inverse_when_no_bound_is_active(hover):
    """Wherever the thesis' law (2.24) keeps every rotor within its bounds, the QP returns that law."""
    robot, q0, inputs, _ = hover
    rng = np.random.default_rng(4)
    allocator = Allocator(robot)
    w_max2 = robot.rotor_constants.max_speed**2
    checked = 0
    for _ in range(40):
        q, v = _random_state(robot, q0, rng, spread=0.02)
        attitude = robot.attitude_model(q, v)
        thrust = inputs.thrust[0] * (1 + 0.05 * rng.normal(size=robot.n_drones))
        u_a = rng.normal(size=len(robot.layout.attitude)) * np.r_[0.02, 0.02, np.ones(robot.n_drones)]
        tau = pseudo_inverse_law(attitude, thrust, u_a)
        z = np.concatenate([rotor.speeds_squared(thrust[i], tau[i]) for i, rotor in enumerate(robot.rotors)])
        result = allocator.solve(attitude, thrust, u_a)
        if z.min() < 1e-3 * w_max2 or z.max() > (1 - 1e-3) * w_max2:
            continue  # a bound is (nearly) active: not this test's case
        checked += 1
        assert not result.any_saturated
        np.testing.assert_allclose(result.torque, tau, atol=1e-8 * max(1.0, np.abs(tau).max()))
        np.testing.assert_allclose(result.thrust, thrust, atol=1e-8)
        np.testing.assert_allclose(result.attitude_error, 0.0, atol=1e-7)
    assert checked >= 10


def test_qp_respects_bounds_and_is_optimal_when_they_bind(hover):
    """Asking for 3x the hover thrust saturates rotors: bounds hold exactly and the KKT conditions hold."""
    robot, q0, inputs, _ = hover
    allocator = Allocator(robot)
    attitude = robot.attitude_model(q0, np.zeros(robot.nq))
    u_a = np.zeros(len(robot.layout.attitude))
    u_a[-1] = 30.0
    thrust = 3.0 * inputs.thrust[0]
    result = allocator.solve(attitude, thrust, u_a)
    z = result.speeds_squared.reshape(-1)
    w_max2 = robot.rotor_constants.max_speed**2
    assert result.any_saturated
    assert z.min() >= 0.0 and z.max() <= w_max2
    assert np.abs(result.thrust_error).max() > 1.0  # it could not be met
    # KKT of the box QP: gradient >= 0 at the lower bound, <= 0 at the upper, 0 in between
    h, g = allocator.build(attitude, thrust, u_a)
    grad = (h @ z + g) * w_max2  # per unit of the scaled variable z / w_max^2
    tol = 1e-5 * np.abs(g * w_max2).max()
    at_low, at_high = z <= 1e-6 * w_max2, z >= (1 - 1e-6) * w_max2
    assert np.all(grad[at_low] >= -tol) and np.all(grad[at_high] <= tol)
    assert np.all(np.abs(grad[~at_low & ~at_high]) <= tol)
    # the same request once more: the warm-started workspace gives the same answer
    again = allocator.solve(attitude, thrust, u_a)
    np.testing.assert_allclose(again.speeds_squared, result.speeds_squared, atol=1e-6 * w_max2)


def test_hover_is_an_equilibrium_of_the_controller(hover):
    """At the planned hover state the controller commands the plan's rotor speeds: no acceleration."""
    robot, q0, inputs, reference = hover
    controller = CascadedController(robot)
    out = controller.update(0.0, q0, np.zeros(robot.nq), reference)
    np.testing.assert_allclose(out.speeds, inputs.rotor_speed[0], rtol=1e-8)
    np.testing.assert_allclose(out.roll_desired, inputs.roll[0], atol=1e-12)
    a = robot.forward_dynamics(q0, np.zeros(robot.nq), out.allocation.thrust, out.allocation.torque)
    np.testing.assert_allclose(a, 0.0, atol=1e-9)


def test_outer_loop_force_is_the_planning_inverse_dynamics(hover):
    """On the reference, F of the outer loop equals the planned thrust vectors (2.16 with zero error)."""
    robot, q0, _, _ = hover
    rng = np.random.default_rng(5)
    n_s = len(robot.layout.chain)
    motion = np.zeros((5, 1, n_s))
    motion[0, 0] = np.array(HOVER_POSES[robot.name])
    motion[1:3, 0] = 0.3 * rng.normal(size=(2, n_s))
    planned = inverse_dynamics(robot, motion)
    q, v = (state[0] for state in planned.full_state(robot)[:2])  # the rolls and their rates on the plan too
    reference = Reference(motion[:, 0], planned.roll_rate[0], planned.roll_acceleration[0], planned.thrust_vector[0])
    for feedback in (True, False):
        controller = CascadedController(robot, ControllerSettings(momentum_feedback=feedback))
        np.testing.assert_allclose(controller.outer(q, v, reference), planned.thrust_vector[0], atol=1e-10)


def test_roll_torques_leave_the_fed_back_chain_acceleration_alone(hover):
    """The momentum feedback's chain velocity s' + K q_o', K = M_ss^-1 M_so: its acceleration from the forward
    dynamics (Pinocchio's ABA, independent of the CRBA that gives K) does not change with the drones' roll
    torques, while s'' alone does (the roll torque pushes the joint, and the chain, the other way).
    """
    robot, q0, inputs, _ = hover
    rng = np.random.default_rng(11)
    controller = CascadedController(robot)
    chain, others = controller.chain, controller._others
    for _ in range(3):
        q, v = _random_state(robot, q0, rng)
        mass = robot.mass_matrix(q)
        gain = np.linalg.solve(mass[np.ix_(chain, chain)], mass[np.ix_(chain, others)])
        torque = np.zeros((robot.n_drones, 3))
        torque[:, 0] = 0.3 * rng.normal(size=robot.n_drones)  # body roll torques [N m]
        still = robot.forward_dynamics(q, v, inputs.thrust[0], np.zeros((robot.n_drones, 3)))
        turned = robot.forward_dynamics(q, v, inputs.thrust[0], torque)
        delta = turned - still
        assert np.abs(delta[chain]).max() > 1e-2  # the torque moves the chain at once ...
        np.testing.assert_allclose(delta[chain] + gain.dot(delta[others]), 0.0, atol=1e-9)  # ... not its momentum
