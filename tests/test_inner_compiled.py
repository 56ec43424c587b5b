"""The inner loop's float part natively (fpr._native's part ``inner``, ``fpr/_native/alloc.c``) against its Python
reference (``CascadedController._inner_python``): the same operations in the same order, the same results to
round-off (1e-12 relative: the C library's and numpy's sums may round otherwise on another CPU) -- thrusts, u_a,
desired rolls, pitch reference -- at random states of both robots (rolls past pi, the pitch clamped on both
sides), after the gains change; and whole controller ticks alike on either path.
"""

import dataclasses

import numpy as np
import pytest
from helpers import near_hover
from native_parts import native_module, needs_native

import fpr
from controllers.ctc import CascadedController, ControllerSettings, Reference
from fpr import _native as native

needs_kernel = needs_native


def _reference(robot, rng):
    n_s, n_a = len(robot.layout.chain), len(robot.layout.rolls)  # the drones' attitude coordinates
    return Reference(rng.normal(size=(5, n_s)), rng.normal(size=n_a), rng.normal(size=n_a))


@needs_kernel
@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_compiled_inner_loop_is_the_python_part_to_round_off(name):
    robot = fpr.load(name)
    native_module("inner")
    rng = np.random.default_rng(12)
    controller = CascadedController(robot)
    kernel = controller._inner_kernel()
    if robot.kind.compiled_inner_constants(controller.settings) is None:  # the kind's inner loop is Python only
        assert kernel is None
        pytest.skip(f"the {name}'s inner loop has no compiled form")
    clamped = set()
    for k in range(400):
        if k == 200:  # other gains: the constants follow
            controller.settings = dataclasses.replace(controller.settings, attitude_frequency=31.0,
                                                      lateral_frequency=2.5, max_pitch=0.1)
        q, v = rng.normal(scale=4.0, size=robot.nq), rng.normal(scale=3.0, size=robot.nq)
        controller._force = rng.normal(scale=10.0, size=(robot.n_drones, len(robot.kind.force_axes)))
        reference = _reference(robot, rng)
        expected = controller._inner_python(q, v, reference)
        controller._attitude_gains()
        found = kernel(q, v, controller._force, reference.roll_rate, reference.roll_acceleration,
                       controller._gains[5])
        for a, b in zip(found[:3], expected[:3], strict=True):
            assert a.dtype == b.dtype and a.shape == b.shape
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * max(1.0, np.abs(b).max()))  # C vs numpy
        assert found[3] == pytest.approx(expected[3], rel=1e-12, abs=1e-15) and type(found[3]) is float
        if controller.lateral:
            clamped.add(np.sign(expected[3]) if abs(expected[3]) == controller.settings.max_pitch else 0.0)
    if controller.lateral:
        assert clamped == {-1.0, 0.0, 1.0}  # clamped on both sides, and inside


@needs_kernel
@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_controller_ticks_alike_on_either_path(name):
    robot = fpr.load(name)
    q, v, *_ = near_hover(robot, 3)
    rng = np.random.default_rng(2)
    native_module("inner")
    compiled, python = CascadedController(robot), CascadedController(robot)
    for k in range(5):
        reference = _reference(robot, rng)
        reference.motion[0] = q[robot.indices(robot.layout.chain)]
        a = compiled.update(0.002 * k, q, v, reference)
        with native.switched(inner=False):
            b = python.update(0.002 * k, q, v, reference)
        for field in ("speeds", "force", "roll_desired", "thrust_desired", "attitude_desired"):
            want = getattr(b, field)  # C vs numpy: the same sums, to round-off (another CPU may order them otherwise)
            np.testing.assert_allclose(getattr(a, field), want, rtol=1e-12, atol=1e-12 * max(1.0, np.abs(want).max()),
                                       err_msg=field)
        assert a.pitch_desired == pytest.approx(b.pitch_desired, rel=1e-12, abs=1e-15)


def test_switched_off_the_python_part_runs():
    robot = fpr.load("prototype")
    controller = CascadedController(robot, ControllerSettings())
    q, v, *_ = near_hover(robot, 4)
    reference = _reference(robot, np.random.default_rng(5))
    with native.switched(inner=False):
        assert controller._inner_kernel() is None
        assert np.isfinite(controller.update(0.0, q, v, reference).speeds).all()  # the Python part


@needs_kernel
def test_a_result_that_is_not_finite_goes_to_the_python_reference():
    """A roll rate whose square overflows: the C part returns None (no inf thrust), and the controller's tick
    then raises what the Python reference raises.
    """
    robot = fpr.load("fpr")
    q, v, *_ = near_hover(robot, 3)
    controller = CascadedController(robot)
    reference = _reference(robot, np.random.default_rng(5))
    controller.update(0.0, q, v, reference)  # the outer loop's force, the kernel, the gains
    fast = v.copy()
    fast[controller.rolls[0]] = 1e200  # drone 1's roll rate
    kernel = controller._inner_kernel()
    assert kernel(q, fast, controller._force, reference.roll_rate, reference.roll_acceleration,
                  controller._gains[5]) is None
    with pytest.raises(OverflowError):
        controller._inner_python(q, fast, reference)
    with pytest.raises(OverflowError):
        controller.update(0.001, q, fast, reference)
