"""The native plant's and measurement's entry points (fpr/_native/cpp/module.cpp) on inputs the Python side never
builds: objects of the wrong type, a data or constraint datas of another model, frames and joints out of range,
arrays of the wrong size, shape or type, a bad step. Each is refused with a Python exception (TypeError,
ValueError; TypeError for an object that is not the model's), never a crash; the sanitizer job of CI runs these
under AddressSanitizer and UBSan.
"""

import numpy as np
import pinocchio as pin
import pytest
from native_parts import native_module, needs_native

import fpr
from fpr import _native as native
from fpr.model.constrained import constraint_data
from fpr.sim.plant import Plant, hover_configuration, hover_speeds

pytestmark = needs_native


@pytest.fixture(scope="module")
def plant():
    robot = fpr.load("fpr")
    q = hover_configuration(robot, robot.kind.reference_chain)
    plant = Plant.from_minimal(robot, q, w=hover_speeds(robot, q))
    plant.advance(plant.rotor_speeds, 1e-3, 1)
    assert plant._native_plant is not None
    return plant


def _arguments(plant):
    closed = plant.closed
    data, datas = constraint_data(closed.model, closed.constraints)
    return [closed.model, data, closed.constraints, datas, closed.settings,
            np.ascontiguousarray(plant._rotor_map.T), list(closed.drone_frame_ids)]


@pytest.mark.parametrize("position, bad, error", [
    (0, "a model", TypeError), (0, pin.Data(), TypeError), (1, pin.Model(), TypeError),
    (1, pin.Model().createData(), TypeError),  # a data of another model
    (2, None, TypeError), (3, pin.StdVec_RigidConstraintData(), TypeError),  # constraints without their datas
    (4, 3.0, TypeError), (5, np.zeros((8, 3)), ValueError), (5, np.zeros(8), ValueError),
    (6, [10 ** 6], ValueError), (6, [-1], ValueError), (6, "ab", TypeError)])
def test_the_plant_refuses_what_is_not_its_model(plant, position, bad, error):
    module = native_module("plant")
    args = _arguments(plant)
    args[position] = bad
    with pytest.raises(error):
        module.Plant(*args)


def test_steps_refuse_bad_arrays_and_steps(plant):
    kernel = native_module("plant").Plant(*_arguments(plant))
    q, v, w = plant.qc, plant.vc, plant.rotor_speeds
    decay = np.ones((3, 1))
    good = [q, v, w, w, 1000.0, decay, 1e-3, 2]
    assert kernel.steps(*good)[3:] == (2, 0)
    for position, bad in ((0, q[:-1]), (1, np.zeros(v.size + 1)), (3, w.T.copy()), (3, w[:1]), (5, np.ones(2)),
                          (6, 0.0), (6, -1e-3), (6, np.nan), (7, -1)):
        args = list(good)
        args[position] = bad
        with pytest.raises(ValueError):
            kernel.steps(*args)
    with pytest.raises(TypeError):
        kernel.steps(*good[:7])
    with pytest.raises(TypeError):
        kernel.steps(q, v, w, w, "fast", decay, 1e-3, 2)
    with pytest.raises(ValueError):
        kernel.steps(*good, np.zeros(5))  # the wind: 3 per drone
    # integers and other layouts are converted, not misread
    q_f, v_f, w_f, done, status = kernel.steps(q, v, w.astype(np.float32), np.asfortranarray(w), 1000.0, decay,
                                               1e-3, 1)
    assert (done, status) == (1, 0) and np.isfinite(q_f).all()


def test_the_measurement_refuses_what_does_not_fit(plant):
    module = native_module("measure")
    closed = plant.closed
    robot = closed.robot
    from fpr.model.constrained import _minimal_cache

    cache = _minimal_cache(closed)
    minimal = cache.native_minimal()
    eulers, angles = cache.reader.native_reads()
    good = dict(model=closed.model, data=closed.data, minimal=minimal, nqp=robot.model.nq,
                closed_q=cache.reversed_q.tolist(), source=cache.reversed_q_source.tolist(), sign=cache.reversed_sign,
                eulers=eulers, angles=angles, T_inv=robot.T_inv, angular=cache.angular_list)
    measure = module.Measure(**good)
    q, v = measure.measure(plant.qc, plant.vc, plant.measure()[0])
    assert np.isfinite(q).all() and np.isfinite(v).all()
    for key, bad, error in (("minimal", "no", TypeError), ("nqp", 100, ValueError), ("closed_q", [10 ** 4], ValueError),
                            ("source", [0], ValueError), ("eulers", [(0, np.eye(4))], TypeError),
                            ("eulers", [(10 ** 4,) + tuple(eulers[0][1:])], ValueError),
                            ("angles", [(1, np.eye(3), 2, 0)], ValueError), ("T_inv", np.eye(3), ValueError),
                            ("angular", [99], ValueError)):
        with pytest.raises(error):
            module.Measure(**{**good, key: bad})
    with pytest.raises(ValueError):
        measure.measure(plant.qc[:-1], plant.vc, q)
    with pytest.raises(ValueError):
        measure.measure(plant.qc, plant.vc, q[:-1])


def test_the_minimal_terms_refuse_what_does_not_fit():
    native_module("attitude")
    module = native.module("_pinocchio")
    robot = fpr.load("prototype")
    n = robot.nq
    good = dict(model=robot.model, data=robot.model.createData(), T=robot.T, frames=list(robot.drone_frame_ids),
                constant_rows=np.zeros((0, n)), freeflyer_rows=[], hinges=[])
    terms = module.Minimal(**good)
    m, nle, jacobians = terms.frame_terms(np.zeros(n), np.zeros(n))
    assert m.shape == (n, n) and len(jacobians) == robot.n_drones
    for key, bad in (("T", np.eye(n + 1)), ("frames", [10 ** 5]), ("constant_rows", np.zeros((2, n + 1))),
                     ("hinges", [1]), ("freeflyer_rows", [0])):
        with pytest.raises(ValueError):
            module.Minimal(**{**good, key: bad})
    with pytest.raises(ValueError):
        terms.frame_terms(np.zeros(n + 1), np.zeros(n))
    with pytest.raises(ValueError):
        terms.velocity(np.zeros(n), np.zeros(3))  # no rows: vc of another size
