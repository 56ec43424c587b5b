"""The watch's screen natively (fpr._native's part ``watch``, ``fpr/_native/watch.c``) against its Python reference
(``Watch._may_be_lost_python``): the same answer on states scattered across every bound (and on the bounds'
edges), with and without the tilt screen, on non-finite states; the switch selects it.
"""

import math

import numpy as np
import pytest
from native_parts import native_module, needs_native
from test_watch import state

import fpr
from fpr import _native as native
from fpr.sim.closed_loop import SimulationSettings
from fpr.sim.watch import Watch

needs_kernel = needs_native
BOUNDS = dict(max_drone_speed=0.5, max_drone_rate=0.5, max_tilt=0.3, max_tracking_error=0.2, ground_tolerance=0.0,
              max_closure_error=1e-3)


@needs_kernel
@pytest.mark.parametrize("name", fpr.ROBOTS)
@pytest.mark.parametrize("max_tilt", [0.3, math.pi])
def test_compiled_screen_is_the_python_screen(name, max_tilt):
    robot, plant, q, positions, closure, planned = state(name)
    watch = Watch(robot, SimulationSettings(**{**BOUNDS, "max_tilt": max_tilt}))
    watch._build_screen(plant)
    floor, closure_bound = watch._bounds[:2]
    rng = np.random.default_rng(8)
    qc0, vc0 = plant.qc.copy(), plant.vc.copy()
    answers = []
    for k in range(600):
        plant.qc = qc0 + rng.normal(scale=0.1, size=qc0.shape) * (rng.random(qc0.shape) < 0.15)
        plant.vc = vc0 + rng.normal(scale=0.2, size=vc0.shape) * (rng.random(vc0.shape) < 0.2)
        low = positions.copy()
        low[:, 2] += rng.normal(scale=0.5)
        error = closure + rng.normal(scale=1e-3) ** 2 * 1e3
        v = 0.1 * rng.normal(size=robot.nq)
        qm = q.copy()
        target = planned + rng.normal(scale=0.08, size=planned.shape)
        if k % 10 == 1:  # on the edges: exactly at the moved bounds, and a last bit past them
            low[:, 2] = np.maximum(low[:, 2], floor)
            low[k % robot.n_drones, 2] = np.nextafter(floor, -np.inf) if k % 20 == 1 else floor
            error = closure_bound if k % 20 == 1 else np.nextafter(closure_bound, np.inf)
        if k % 50 == 7:  # a non-finite entry somewhere
            (plant.qc, plant.vc, qm, v)[k % 4][k % 3] = (np.nan, np.inf, -np.inf)[k % 3]
        args = (plant, qm, v, low, error, target)
        with native.switched(watch=False):
            expected = watch._may_be_lost(*args)
        answers.append(expected)
        assert watch._may_be_lost(*args) is expected, k
    assert 100 < sum(answers) < 550  # both answers reached


@needs_kernel
def test_switch_selects_the_screen(monkeypatch):
    robot, plant, q, positions, closure, planned = state("fpr")
    watch = Watch(robot, SimulationSettings())
    calls = []
    real = Watch._may_be_lost_python
    monkeypatch.setattr(Watch, "_may_be_lost_python", lambda self, *a: calls.append(1) or real(self, *a))
    args = (0.0, plant, q, np.zeros(robot.nq), positions, closure, planned)
    native_module("watch")
    assert watch.check(*args) is None and calls == []  # native when on
    with native.switched(watch=False):
        assert watch.check(*args) is None and calls == [1]
    with pytest.raises(ValueError):  # constants that do not fit the state
        native_module("watch").may_be_lost(plant.qc, plant.vc, q, q, positions, closure, planned[:-1],
                                                watch._screen_constants)


def test_switched_off_the_python_screen_runs():
    robot, plant, q, positions, closure, planned = state("prototype")
    watch = Watch(robot, SimulationSettings())
    args = (0.0, plant, q, np.zeros(robot.nq), positions, closure, planned)
    with native.switched(watch=False):
        assert watch.check(*args) is None  # the Python screen
        assert watch.check(*args[:-1], planned + 2.0).startswith("tracking lost")


@needs_kernel
def test_a_zero_quaternion_goes_to_the_full_check():
    """A drone quaternion of zeros gives a NaN tilt cosine: the C screen answers "may be lost" (the full check
    then decides), where the Python screen divides by zero.
    """
    robot, plant, q, positions, closure, planned = state("fpr")
    watch = Watch(robot, SimulationSettings(**BOUNDS))
    watch._build_screen(plant)
    args = (plant, q, np.zeros(robot.nq), positions, closure, planned)
    assert watch._may_be_lost(*args) is False  # the state as it is passes the screen
    iq = plant._freeflyers[0][0]
    plant.qc = plant.qc.copy()
    plant.qc[iq + 3 : iq + 7] = 0.0
    assert watch._may_be_lost(*args) is True
    with native.switched(watch=False), pytest.raises(ZeroDivisionError):
        watch._may_be_lost(*args)


@needs_kernel
def test_constants_must_be_native_aligned_float64():
    robot, plant, q, positions, closure, planned = state("fpr")
    watch = Watch(robot, SimulationSettings(**BOUNDS))
    watch._build_screen(plant)
    swapped = watch._screen_constants.astype(">f8")
    with pytest.raises(TypeError):
        native_module("watch").may_be_lost(plant.qc, plant.vc, q, np.zeros(robot.nq), positions, closure,
                                           planned, swapped)
