"""The native attitude model (fpr._native's part ``attitude``) against its Python reference.

:meth:`fpr.model.robot.Robot.attitude_model` runs Pinocchio (CRBA, RNEA, the frame Jacobians; natively, the same
algorithms called from C++, ``fpr/_native/cpp/minimal.cpp``), then turns its outputs into the thesis' quantities
either in C (``fpr/_native/attitude.c``) or with numpy and LAPACK (``Robot._attitude_python``, the reference).
Both are held equal on the same Pinocchio outputs, at states near hover and far from it, for both robots; the C
part declines (None) a matrix that is not positive definite, and the switch selects the path.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
from native_parts import native_module, needs_native

import fpr
from fpr import _native as native
from fpr.model import robot as robot_module
from fpr.model.robot import AttitudeModel
from fpr.sim.plant import hover_configuration

FIELDS = ("m_inv_a", "j_tau", "j_f", "a_tau", "c")
needs_kernel = needs_native


def _pinocchio_outputs(robot, q, v):
    """M_p, nle_p and the drones' LOCAL frame Jacobians at (q, v), as attitude_model computes them."""
    model, data = robot.model, robot.data
    qp, vp = robot.to_pinocchio(q), robot.to_pinocchio(v)
    m = pin.crba(model, data, qp).copy()
    nle = pin.nonLinearEffects(model, data, qp, vp).copy()
    pin.computeJointJacobians(model, data, qp)
    pin.updateFramePlacements(model, data)
    return m, nle, tuple(pin.getFrameJacobian(model, data, f, pin.LOCAL) for f in robot.drone_frame_ids)


def _states(robot, rng, count, spread):
    centre = hover_configuration(robot, robot.kind.reference_chain)
    return [(centre + spread * rng.normal(size=robot.nq), spread * rng.normal(size=robot.nq))
            for _ in range(count)]


@needs_kernel
@pytest.mark.parametrize("name", fpr.ROBOTS)
@pytest.mark.parametrize("spread", [0.01, 1.0])
def test_compiled_attitude_model_is_the_python_path(name, spread):
    robot = fpr.load(name)
    kernel = native_module("attitude")
    rng = np.random.default_rng(11)
    for q, v in _states(robot, rng, 50, spread):
        compiled = robot.attitude_model(q, v)
        reference = robot._attitude_python(*_pinocchio_outputs(robot, q, v))
        m = robot.mass_matrix(q)
        scale = np.linalg.cond(m)  # the solve's round-off grows with M's condition number
        for field in FIELDS:
            a, b = getattr(compiled, field), getattr(reference, field)
            assert a.shape == b.shape, field
            tol = 1e-15 * scale * max(1.0, np.abs(b).max())
            np.testing.assert_allclose(a, b, rtol=0, atol=tol, err_msg=field)
        # the native terms' Jacobians are Pinocchio's (the same algorithm from C++); on Pinocchio's own outputs
        # the C products of Jacobians and T are the same sums as numpy's, to round-off (numpy's BLAS may sum in
        # another order, with FMA, on another CPU)
        np.testing.assert_allclose(compiled.j_f, reference.j_f, rtol=0, atol=1e-15)
        np.testing.assert_allclose(compiled.j_tau, reference.j_tau, rtol=0, atol=1e-15)
        outputs = kernel.post(*_pinocchio_outputs(robot, q, v), robot._build_attitude_constants()[-1])
        own = dict(zip(robot_module._ATTITUDE_FIELDS, outputs, strict=True))
        for name in ("j_f", "j_tau"):
            want = getattr(reference, name)
            np.testing.assert_allclose(own[name], want, rtol=1e-13, atol=1e-13 * np.abs(want).max(), err_msg=name)
        # and the dynamics they describe: qddot_a for some inputs, the same to the solve's round-off
        f, tau = rng.normal(size=robot.n_drones), rng.normal(size=(robot.n_drones, 3))
        force = reference.j_tau.T.dot(tau.reshape(-1)) + reference.j_f.T.dot(f) - reference.c
        tol = 1e-15 * scale * np.abs(reference.m_inv_a).max() * np.abs(force).sum()
        np.testing.assert_allclose(compiled.attitude_acceleration(f, tau), reference.attitude_acceleration(f, tau),
                                   rtol=0, atol=tol)


@needs_kernel
def test_compiled_result_is_a_whole_attitude_model():
    """Built without the dataclass' __init__: the same fields, frozen, and dataclasses.replace works on it (the
    controller's wind term replaces c).
    """
    assert tuple(f.name for f in dataclasses.fields(AttitudeModel)) == robot_module._ATTITUDE_FIELDS
    robot = fpr.load("fpr")
    q, v = _states(robot, np.random.default_rng(9), 1, 0.1)[0]
    model = robot.attitude_model(q, v)
    assert type(model) is AttitudeModel and set(vars(model)) == set(robot_module._ATTITUDE_FIELDS)
    with pytest.raises(dataclasses.FrozenInstanceError):
        model.c = model.c
    other = dataclasses.replace(model, c=model.c + 1.0)
    np.testing.assert_array_equal(other.c, model.c + 1.0)
    np.testing.assert_array_equal(other.a_tau, model.a_tau)


@needs_kernel
@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_switch_selects_the_path(name, monkeypatch):
    robot = fpr.load(name)
    q, v = _states(robot, np.random.default_rng(3), 1, 0.1)[0]
    calls = []
    real = robot_module.Robot._attitude_python
    monkeypatch.setattr(robot_module.Robot, "_attitude_python",
                        lambda self, *a: calls.append(1) or real(self, *a))
    native_module("attitude")
    with native.switched(attitude=True):
        robot.attitude_model(q, v)
    assert calls == []  # native when on
    with native.switched(attitude=False):
        robot.attitude_model(q, v)
    assert calls == [1]


@needs_kernel
def test_compiled_part_declines_a_matrix_that_is_not_positive_definite():
    robot = fpr.load("fpr")
    kernel = native_module("attitude")
    q, v = _states(robot, np.random.default_rng(4), 1, 0.1)[0]
    m, nle, jacobians = _pinocchio_outputs(robot, q, v)
    constants = robot._build_attitude_constants()[-1]
    assert kernel.post(m, nle, jacobians, constants) is not None
    for bad in (-m, np.where(np.eye(robot.nq, dtype=bool), np.nan, m)):
        assert kernel.post(bad, nle, jacobians, constants) is None
    with pytest.raises(ValueError):
        kernel.post(m, nle, jacobians[:1], constants)  # a drone's Jacobian missing
    with pytest.raises(ValueError):
        kernel.post(m[:-1], nle, jacobians, constants)
    with pytest.raises(ValueError):
        kernel.post(m, nle, jacobians, constants[:-1])


@needs_kernel
def test_native_terms_are_pinocchios():
    """M_p (both triangles), nle and the frame Jacobians from C++ equal Pinocchio's Python calls' to round-off."""
    native_module("attitude")
    for name in fpr.ROBOTS:
        robot = fpr.load(name)
        for q, v in _states(robot, np.random.default_rng(8), 10, 1.0):
            m, nle, jacobians = robot._native_terms().frame_terms(q, v)
            m_ref, nle_ref, jac_ref = _pinocchio_outputs(robot, q, v)
            np.testing.assert_allclose(m, m_ref, rtol=0, atol=1e-13 * np.abs(m_ref).max())
            np.testing.assert_allclose(nle, nle_ref, rtol=0, atol=1e-13 * max(1.0, np.abs(nle_ref).max()))
            for j, j_ref in zip(jacobians, jac_ref, strict=True):
                np.testing.assert_allclose(j, j_ref, rtol=0, atol=1e-14)


def test_switched_off_the_python_path_runs():
    robot = fpr.load("prototype")
    q, v = _states(robot, np.random.default_rng(6), 1, 0.1)[0]
    with native.switched(attitude=False):
        model = robot.attitude_model(q, v)  # the Python path
    reference = robot._attitude_python(*_pinocchio_outputs(robot, q, v))
    for field in FIELDS:
        np.testing.assert_array_equal(getattr(model, field), getattr(reference, field))
