"""The simulator's fast paths against the references they replace.

Each fast path is held equal to a slower, independent computation of the same quantity:

* the plant step without wind (:meth:`fpr.sim.plant.Plant._python_steps`: one constant rotor-force map, the
  step's constants cached; and the native steps) against :func:`fpr.sim.plant.rkmk4_step` driven by Pinocchio's
  frame Jacobians and the lag solution through ``np.exp``: the same RKMK4 step, so equal to round-off;
* :meth:`fpr.sim.plant.Plant.observe` against :meth:`~fpr.sim.plant.Plant.measure` and
  :meth:`~fpr.sim.plant.Plant.drone_positions_and_closure_error` (their own kinematics pass);
* the allocation's closed form (the thesis' law 2.24, used when no rotor bound is active) against ProxQP
  solving the built QP from scratch, and the bounded route's lean H, g against :func:`allocation_qp`;
* the attitude model (M^-1 rows from Pinocchio's upper triangle) against the full inverse of ``mass_matrix``,
  and ``mass_matrix`` (T^T M_p T on the whole matrix CRBA returns) against T^T M_p T with M_p mirrored from
  its upper triangle by ``np.triu`` (so the Python binding must return M_p whole, as it does).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from helpers import hover_thrusts, near_hover, saturating_factor

import fpr
from controllers.allocation import Allocator, allocation_qp, selectors
from controllers.box_qp import solve_box_qp
from fpr import _native as native
from fpr.model.qp import proxsuite_module
from fpr.sim.plant import Plant, hover_configuration, rkmk4_step

proxsuite = proxsuite_module()
DT = 1e-3


def _moving_plant(name, seed):
    """A plant near hover with a random velocity, and rotor speeds 5 % off hover (all within bounds)."""
    robot = fpr.load(name)
    q, v, w, command, rng = near_hover(robot, seed)
    return robot, Plant.from_minimal(robot, q, v, w=w), command, rng


@pytest.mark.parametrize("native_step", [False, None])
@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_lean_step_is_the_reference_rkmk4_step(name, native_step):
    """20 steps of 1 ms: the lean step (the Python steps, and the native ones when on) and rkmk4_step on
    Pinocchio's Jacobians agree to 1e-12 (relative).
    """
    robot, plant, command, _ = _moving_plant(name, 1)
    on = {} if native_step is None else {"plant": native_step}
    lag = robot.rotor_constants.time_constant
    closed = plant.closed
    qc, vc, w0 = plant.qc.copy(), plant.vc.copy(), plant.rotor_speeds
    for _ in range(20):
        def speeds(t, w0=w0):
            return command + (w0 - command) * np.exp(-t / lag)

        def acceleration(q, v, t, speeds=speeds):
            return closed.forward_dynamics(q, v, plant.generalized_force(q, speeds(t))).copy()

        qc, vc = rkmk4_step(closed.model, qc, vc, DT, acceleration)
        w0 = speeds(DT)
        with native.switched(**on):
            plant.step(command, DT)
    assert np.abs(plant.qc - qc).max() <= 1e-12 * max(1.0, np.abs(qc).max())
    assert np.abs(plant.vc - vc).max() <= 1e-12 * max(1.0, np.abs(vc).max())
    np.testing.assert_allclose(plant.rotor_speeds, w0, rtol=1e-14)
    assert np.abs(vc).max() > 0.1  # it did move


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_observe_is_measure_and_the_logged_kinematics(name):
    robot, plant, command, _ = _moving_plant(name, 2)
    for _ in range(5):
        plant.step(command, DT)
    twin = Plant(plant.closed, plant.qc, plant.vc, plant.rotor_speeds, reference=plant.measure()[0])
    plant._reference = twin._reference.copy()
    q, v, positions, closure = plant.observe()
    q_ref, v_ref = twin.measure()
    positions_ref, closure_ref = twin.drone_positions_and_closure_error()
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-15)
    np.testing.assert_allclose(v, v_ref, rtol=0, atol=1e-14)
    np.testing.assert_allclose(positions, positions_ref, rtol=0, atol=1e-15)
    np.testing.assert_allclose(positions, twin.drone_positions(), rtol=0, atol=1e-15)
    assert closure == pytest.approx(twin.closure_error(), abs=1e-15)
    assert closure == pytest.approx(closure_ref, abs=1e-15)


def _allocation_cases(name, thrust_factor, count, seed, spread=0.3):
    """(robot, [(attitude, thrust, u_a)]) near hover, u_a of standard deviation ``spread`` [rad/s^2];
    thrust_factor 3 makes rotors saturate (raised to past the drones' full thrust where it does not:
    :func:`helpers.saturating_factor`).
    """
    robot = fpr.load(name)
    rng = np.random.default_rng(seed)
    q0, hover = hover_thrusts(robot)
    if thrust_factor == 3.0:
        thrust_factor = saturating_factor(robot, hover)
    n_a = len(robot.layout.attitude)
    cases = []
    for _ in range(count):
        q, v = q0 + 0.02 * rng.normal(size=robot.nq), 0.02 * rng.normal(size=robot.nq)
        attitude = robot.attitude_model(q, v)
        thrust = thrust_factor * hover * (1 + 0.02 * rng.normal(size=hover.size))
        cases.append((attitude, thrust, spread * rng.normal(size=n_a)))
    return robot, cases


def _cold(allocator, attitude, thrust, u_a):
    """ProxQP from scratch on the allocator's built QP (scaled to z / w_max^2): w^2, shape (n,)."""
    h, g = allocator.build(attitude, thrust, u_a)
    s = allocator.scale
    n = allocator.n
    out = proxsuite.proxqp.dense.solve(h * s**2, g * s, l_box=np.zeros(n), u_box=np.ones(n),
                                       eps_abs=1e-11, eps_rel=0.0, verbose=False)
    return np.asarray(out.x) * s


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_closed_form_allocation_is_the_qp_minimiser(name):
    """No bound active: the closed form is taken, its w^2 is ProxQP's (cold, tight tolerance) and the QP's
    gradient vanishes there.
    """
    robot, cases = _allocation_cases(name, 1.0, 20, 3, spread=0.05)
    allocator = Allocator(robot)
    for attitude, thrust, u_a in cases:
        result = allocator.solve(attitude, thrust, u_a)
        z = result.speeds_squared.reshape(-1)
        assert not result.any_saturated and result.iterations == 0
        cold = _cold(allocator, attitude, thrust, u_a)
        np.testing.assert_allclose(z, cold, rtol=0, atol=1e-6 * allocator.scale)
        h, g = allocator.build(attitude, thrust, u_a)
        assert np.abs(h @ z + g).max() <= 1e-9 * np.abs(g).max()
        np.testing.assert_allclose(result.attitude_error, 0.0, atol=1e-9)
        np.testing.assert_allclose(result.thrust_error, 0.0, atol=1e-12)
    assert allocator.routes == {"closed form": 20, "active set": 0, "proxqp": 0}


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_bounded_allocation_is_the_qp_minimiser(name):
    """Three times the hover thrust: the QP route, the lean H, g equal the built ones, and its warm-started
    w^2 equal ProxQP's from scratch.
    """
    robot, cases = _allocation_cases(name, 3.0, 20, 4)
    allocator = Allocator(robot)
    s_f, s_tau = selectors(robot)
    for attitude, thrust, u_a in cases:
        h, g = allocation_qp(attitude, s_f, s_tau, thrust, u_a, 1.0, 1.0, allocator.regularisation)
        gram = attitude.a_tau @ attitude.a_tau.T
        h_lean, g_lean = allocator._lean_qp(attitude, thrust, u_a, gram)
        s = allocator.scale
        np.testing.assert_allclose(h_lean, h * s**2, rtol=0, atol=1e-12 * np.abs(h * s**2).max())
        np.testing.assert_allclose(g_lean, g * s, rtol=0, atol=1e-12 * np.abs(g * s).max())
        result = allocator.solve(attitude, thrust, u_a)
        assert result.any_saturated
        np.testing.assert_allclose(result.speeds_squared.reshape(-1), _cold(allocator, attitude, thrust, u_a),
                                   rtol=0, atol=1e-6 * s)
    assert allocator.routes == {"closed form": 0, "active set": 20, "proxqp": 0}


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_proxqp_fallback_gives_the_active_set_answer(name, monkeypatch):
    """With the active-set method made to fail, the warm ProxQP workspace takes over, with the same w^2."""
    import controllers.allocation as allocation
    robot, cases = _allocation_cases(name, 3.0, 5, 6)
    exact = [Allocator(robot).solve(*case).speeds_squared for case in cases]
    monkeypatch.setattr(allocation, "solve_box_qp_state", lambda *args, **kwargs: None)
    with native.switched(allocation=False):  # the Python path (the native tick has its own fallback)
        allocator = Allocator(robot)
    for case, z in zip(cases, exact, strict=True):
        again = allocator.solve(*case).speeds_squared
        np.testing.assert_allclose(again, z, rtol=0, atol=1e-6 * allocator.scale)
    assert allocator.routes == {"closed form": 0, "active set": 0, "proxqp": 5}


def test_box_qp_meets_the_kkt_conditions_from_any_guess():
    """Random positive definite box QPs (n = 8, the allocation's size), every start guess tried being wrong:
    x in the box, gradient 0 where free, >= 0 at 0, <= 0 at 1; x equal to ProxQP's.
    """
    rng = np.random.default_rng(7)
    solved = 0
    for _ in range(200):
        a = rng.normal(size=(8, 8))
        h = a @ a.T + 0.1 * np.eye(8)
        g = 3.0 * rng.normal(size=8)
        lower = list(rng.random(8) < 0.3)
        upper = [not lo and bool(rng.random() < 0.3) for lo in lower]
        found = solve_box_qp(h, g, lower, upper, max_iterations=30)
        if found is None:
            continue  # may cycle: the allocator falls back to ProxQP then
        solved += 1
        x = found[0]
        grad = h @ x + g
        tol = 1e-9 * max(1.0, np.abs(g).max())
        assert x.min() >= 0.0 and x.max() <= 1.0
        free = (x > 1e-12) & (x < 1 - 1e-12)
        assert np.abs(grad[free]).max(initial=0.0) <= tol
        assert np.all(grad[x <= 1e-12] >= -tol) and np.all(grad[x >= 1 - 1e-12] <= tol)
        reference = proxsuite.proxqp.dense.solve(h, g, l_box=np.zeros(8), u_box=np.ones(8), eps_abs=1e-12,
                                                 eps_rel=0.0, verbose=False)
        np.testing.assert_allclose(x, reference.x, rtol=0, atol=1e-7)
    assert solved >= 180


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_attitude_model_rows_of_the_inverse_mass_matrix(name):
    robot = fpr.load(name)
    rng = np.random.default_rng(5)
    centre = hover_configuration(robot, robot.kind.reference_chain)
    attitude_rows = robot.indices(robot.layout.attitude)
    for _ in range(5):
        q, v = centre + 0.3 * rng.normal(size=robot.nq), rng.normal(size=robot.nq)
        m = robot.mass_matrix(q)
        upper = np.triu(pin.crba(robot.model, robot.data, robot.to_pinocchio(q)))  # CRBA's triangle, mirrored
        reference = robot.T.T @ (upper + np.triu(upper, 1).T) @ robot.T
        np.testing.assert_allclose(m, reference, rtol=0, atol=1e-14 * np.abs(reference).max())
        np.testing.assert_allclose(m, m.T, rtol=0, atol=1e-15 * np.abs(m).max())  # T^T M_p T: round-off
        model = robot.attitude_model(q, v)
        inverse = np.linalg.inv(m)
        tol = 1e-13 * np.abs(inverse).max()
        np.testing.assert_allclose(model.m_inv_a, inverse[attitude_rows], rtol=0, atol=tol)
        jac = robot.drone_jacobians(q)
        # the Jacobians and c natively when on: Pinocchio's to round-off
        np.testing.assert_allclose(model.j_f, jac[:, 2], rtol=0, atol=1e-15)
        np.testing.assert_allclose(model.j_tau, jac[:, 3:].reshape(-1, robot.nq), rtol=0, atol=1e-15)
        np.testing.assert_allclose(model.c, robot.nonlinear_effects(q, v), rtol=0, atol=1e-14)
