"""The native allocation tick (fpr/_native/alloc.c, the part ``allocation``) against its reference, the Python path
of :class:`controllers.allocation.Allocator` (the part switched off), and the plumbing around it.

* Along long warm-started sequences of random states (both robots, thrusts from 0.2 to 3.5 times hover, so
  that rotors sit at their lower and at their upper bound, and the weights not all 1) the two paths give the
  same w^2, thrusts, torques, saturation masks, iteration counts and routes.
* The C active-set solver alone gives ``solve_box_qp_state``'s x, final guess and iterations on random QPs.
* When the C tick declines (A_tau rank deficient) the Python path decides, with the same answer; the active
  bounds are handed between the two representations (a declined tick, pickling).
* With the part off, or not built, the Python path runs; ``FPR_NATIVE=require`` says what is missing; the one
  switch refuses what is not a setting.

The native tests fail when the part is not built, and skip under FPR_NATIVE=0 (tests/native_parts.py).
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from helpers import hover_thrusts
from native_parts import native_module, needs_native

import fpr
from controllers.allocation import Allocator
from controllers.box_qp import AT_LOWER, AT_UPPER, FREE, solve_box_qp_state
from fpr import _native as native
from fpr.model.robot import AttitudeModel

needs_kernel = needs_native


def _allocators(robot, *args):
    """(the native allocator, the Python one) of the same settings."""
    native_module("allocation")
    with native.switched(allocation=True):
        fast = Allocator(robot, *args)
    with native.switched(allocation=False):
        reference = Allocator(robot, *args)
    return fast, reference


#: u_a's spread of a robot whose attitude rows are its drones' ball angles alone (the spatial FPR: small inertias, so
#: the same angular accelerations ask little torque; a larger spread reaches the rotors' lower bound) [rad/s^2].
SPREAD = {"fpr3": 3.0}


def _walk(name, count, seed, spread=None):
    """(robot, [(attitude, thrust, u_a)]): a random walk of states near hover and of the thrust factor within
    [0.2, 3.5] (the ticks warm-start each other as in a loop, bounds come and go), u_a of about ``spread``
    rad/s^2.
    """
    robot = fpr.load(name)
    spread = SPREAD.get(name, 0.5) if spread is None else spread
    rng = np.random.default_rng(seed)
    q0, hover = hover_thrusts(robot)
    n_a = len(robot.layout.attitude)
    q, v, factor, u_a = q0.copy(), np.zeros(robot.nq), 1.0, np.zeros(n_a)
    calls = []
    for _ in range(count):
        q = q0 + 0.9 * (q - q0) + 0.02 * rng.normal(size=robot.nq)
        v = 0.9 * v + 0.1 * rng.normal(size=robot.nq)
        factor = float(np.clip(factor + 0.3 * rng.normal(), 0.2, 3.5))
        u_a = 0.8 * u_a + 0.6 * spread * rng.normal(size=n_a)
        thrust = factor * hover * (1 + 0.2 * rng.normal(size=hover.size))
        calls.append((robot.attitude_model(q, v), thrust, u_a.copy()))
    return robot, calls


def _assert_same(a, b, scale):
    """Two AllocationResults: equal to round-off (w^2 relative to w_max^2), the same mask and iterations."""
    np.testing.assert_allclose(a.speeds_squared, b.speeds_squared, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(a.thrust, b.thrust, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(a.torque, b.torque, rtol=1e-9, atol=1e-10)
    np.testing.assert_array_equal(a.saturated, b.saturated)
    assert a.iterations == b.iterations


@needs_kernel
@pytest.mark.parametrize("name", fpr.ROBOTS)
@pytest.mark.parametrize("weights", [(1.0, 1.0, 100.0), (2.5, 0.4, 30.0)])
def test_compiled_tick_is_the_python_path(name, weights):
    robot, calls = _walk(name, 600, 13)
    attitude_weight, thrust_weight, regularisation = weights
    fast, reference = _allocators(robot, attitude_weight, thrust_weight, regularisation)
    assert fast.compiled and not reference.compiled
    at_lower = at_upper = 0
    for attitude, thrust, u_a in calls:
        a, b = fast.solve(attitude, thrust, u_a), reference.solve(attitude, thrust, u_a)
        _assert_same(a, b, fast.scale)
        z = a.speeds_squared
        assert z.min() >= 0.0 and z.max() <= fast.scale
        at_lower += int((a.saturated & (z < 0.5 * fast.scale)).any())
        at_upper += int((a.saturated & (z > 0.5 * fast.scale)).any())
        np.testing.assert_allclose(a.attitude_error, b.attitude_error, rtol=0, atol=1e-6)
        np.testing.assert_allclose(a.thrust_error, b.thrust_error, rtol=0, atol=1e-8)
    assert fast.routes == reference.routes
    assert fast.routes["closed form"] > 20 and fast.routes["active set"] > 20  # both routes, warm
    assert at_lower > 20 and at_upper > 20  # both bounds met


@needs_kernel
def test_weights_changed_after_construction_reach_the_compiled_tick():
    robot, calls = _walk("fpr", 200, 5)
    fast, reference = _allocators(robot)
    for allocator in (fast, reference):
        allocator.regularisation = 7.0
        allocator.attitude_weight = np.array([1.0, 2.0, 0.5, 3.0])
        allocator.thrust_weight = 0.3
    for call in calls:
        _assert_same(fast.solve(*call), reference.solve(*call), fast.scale)
    assert fast.routes == reference.routes and fast.routes["active set"] > 20


@needs_kernel
def test_c_active_set_is_solve_box_qp_state():
    """Random positive definite QPs of 1 to 12 variables, random (mostly wrong) first guesses."""
    rng = np.random.default_rng(3)
    compared = 0
    for _ in range(500):
        n = int(rng.integers(1, 13))
        a = rng.normal(size=(n, n))
        h = a @ a.T + 0.1 * np.eye(n)
        g = (0.5 + 10.0 * rng.random()) * rng.normal(size=n) - 0.5 * h.sum(axis=1) * rng.random()
        state = tuple(int(s) for s in rng.integers(0, 3, size=n))
        expected = solve_box_qp_state(h, g, state, 30)
        found = native_module("allocation").box_qp(h, g, state, 30)
        assert (found is None) == (expected is None)
        if expected is None:
            continue
        compared += 1
        np.testing.assert_allclose(found[0], expected[0], rtol=0, atol=1e-10)
        assert found[1] == expected[1] and found[2] == expected[2]
        assert set(found[1]) <= {FREE, AT_LOWER, AT_UPPER}
    assert compared > 400


@needs_kernel
def test_declined_tick_is_decided_by_the_python_path():
    """A_tau with a zero row (rank deficient): the C tick declines (returns None), the Python path's pinv
    builder and its active-set route decide, with the reference's answer; the bounds it leaves active are
    handed to the compiled tick.
    """
    robot, calls = _walk("fpr", 40, 8)
    fast, reference = _allocators(robot)
    declined = []
    tick = fast._kernel

    def counting(*args):
        found = tick(*args)
        declined.append(found is None)
        return found

    fast._kernel = counting
    for k, (attitude, thrust, u_a) in enumerate(calls):
        if k % 4 == 3:
            a_tau = attitude.a_tau.copy()
            a_tau[1] = 0.0
            attitude = AttitudeModel(m_inv_a=attitude.m_inv_a, j_tau=attitude.j_tau, j_f=attitude.j_f,
                                     a_tau=a_tau, c=attitude.c)
        a, b = fast.solve(attitude, thrust, u_a), reference.solve(attitude, thrust, u_a)
        _assert_same(a, b, fast.scale)
        assert fast._active is None  # the Python path's representation stays empty on the compiled path
        np.testing.assert_array_equal(fast._state, reference._active or np.zeros(fast.n))
    assert declined.count(True) == 10 and fast.routes == reference.routes


@needs_kernel
@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_pickled_allocator_continues_warm(name):
    """Pickled in the middle of a saturating sequence: the copy continues as the original does, natively, and
    where the part is off (the Python path takes the active bounds over).
    """
    robot, calls = _walk(name, 120, 21)
    allocator = Allocator(robot)
    start = 30
    for call in calls[:start]:
        allocator.solve(*call)
    while not allocator._state.any():  # until a bound is active: the warm start is carried over
        allocator.solve(*calls[start])
        start += 1
    data = pickle.dumps(allocator)
    copy = pickle.loads(data)
    assert copy.compiled
    with native.switched(allocation=False):
        python_copy = pickle.loads(data)
    assert not python_copy.compiled and python_copy._active is not None and not python_copy._state.any()
    for call in calls[start:]:
        a = allocator.solve(*call)
        _assert_same(copy.solve(*call), a, allocator.scale)
        _assert_same(python_copy.solve(*call), a, allocator.scale)


@needs_kernel
@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_without_the_part_the_python_path_is_used(name, monkeypatch):
    """A part not built runs its Python path (one warning); FPR_NATIVE=require makes it an error."""
    monkeypatch.setitem(native._modules, "_alloc", None)  # as on a machine where it was not built
    monkeypatch.setattr(native, "_warned", set())
    with native.switched():
        assert native.use("allocation") is None and native.use("inner") is None
        robot, calls = _walk(name, 60, 2)
        allocator = Allocator(robot)
        assert not allocator.compiled
        with native.switched(allocation=False):
            reference = Allocator(robot)
        for call in calls:
            _assert_same(allocator.solve(*call), reference.solve(*call), allocator.scale)
        assert allocator.routes["active set"] > 0
    with pytest.raises(native.NativeError, match="FPR_NATIVE=require: the native part 'allocation' is not built"):
        native.configure("require")


@needs_kernel
def test_non_finite_input_is_decided_by_the_python_path():
    """A NaN attitude acceleration, an infinite thrust: the C tick declines, the answer is the reference's
    (NaN speeds, the same route and iterations).
    """
    robot, calls = _walk("fpr", 3, 1)
    attitude, thrust, u_a = calls[0]
    u_nan = u_a.copy()
    u_nan[1] = np.nan
    thrust_inf = thrust.copy()
    thrust_inf[0] = np.inf
    for case in ((attitude, thrust, u_nan), (attitude, thrust_inf, u_a)):
        fast, reference = _allocators(robot)
        assert fast._kernel(case[0].m_inv_a, case[0].j_f, case[0].a_tau, case[0].c, case[1], case[2],
                            fast._kernel_constants, fast._state) is None
        with np.errstate(invalid="ignore"):
            a, b = fast.solve(*case), reference.solve(*case)
        assert np.isnan(a.speeds_squared).all() and np.isnan(b.speeds_squared).all()
        assert a.iterations == b.iterations and fast.routes == reference.routes


def test_the_switch_refuses_what_is_not_a_setting():
    """One switch (FPR_NATIVE, native.configure, native.switched): an unknown part or value is refused in one line
    naming the parts; the switch is unchanged.
    """
    before = native.parts()
    for value in ("yes", "plant,wheels", ["plnt"]):
        with pytest.raises(ValueError, match="FPR_NATIVE = .*: unknown part") as error:
            native.configure(value)
        assert "\n" not in str(error.value) and "plant" in str(error.value)
    with pytest.raises(ValueError, match="unknown part"):
        with native.switched(alloc=False):
            pass
    assert native.parts() == before
    with native.switched(watch=False):
        assert native.use("watch") is None
    assert native.parts() == before
