"""The stacked planar model (fpr.model.stacked): one table of sines and cosines and products of features give
the per-body formulation's M, c, Jacobians and inverse dynamics to round-off, values and complex steps.
"""

import numpy as np
import pytest

from fpr.model import jets
from fpr.model.inverse_dynamics import _roll_rows, roll_torques
from fpr.model.jets import Jet
from fpr.model.stacked import _Linear
from planners.missions.mission import load_mission

RTOL = 1e-13


@pytest.fixture(scope="module", params=["square", "prototype-tour"])
def robot(request):
    return load_mission(request.param).load_robot()


def _complex_step(rng, shape, scale=2.0):
    return rng.uniform(-scale, scale, shape) + 1j * 1e-30 * rng.standard_normal(shape)


def _close(new, ref):
    """Equal to RTOL of the reference's size, for the values and (scaled back) the complex steps."""
    new, ref = np.asarray(new), np.asarray(ref)
    for part in (np.real, np.imag):
        a, b = part(new), part(ref)
        scale = max(np.max(np.abs(b)), 1e-300)
        assert np.max(np.abs(a - b)) <= RTOL * scale, (part.__name__, np.max(np.abs(a - b)) / scale)


def _reference(model, q, v):
    """M and c by the per-body sums of the module docstring of fpr.model.planar (the formulation before)."""
    jac = [b.com.jacobian(q) for b in model.bodies]
    m = sum(b.mass * np.swapaxes(j, -1, -2) @ j + b.inertia * np.outer(b.angle_row, b.angle_row)
            for b, j in zip(model.bodies, jac, strict=True))
    g = np.array([0.0, -model.gravity])
    c = sum(b.mass * np.einsum("...in,...i->...n", j, b.com.bias(q, v) - g)
            for b, j in zip(model.bodies, jac, strict=True))
    return m, c


@pytest.mark.parametrize("drones", ["rigid", "point"])
@pytest.mark.parametrize("complex_step", [False, True])
def test_mass_matrix_bias_and_jacobians_equal_the_per_body_sums(robot, drones, complex_step):
    rng = np.random.default_rng(11)
    model = robot.planar(drones)
    shape = (40, model.n)
    q, v = ((_complex_step(rng, shape), _complex_step(rng, shape)) if complex_step
            else (rng.uniform(-2, 2, shape), rng.uniform(-2, 2, shape)))
    m_ref, c_ref = _reference(model, q, v)
    m, c, centres = model.dynamics_and_centre_jacobians(q, v)
    _close(m, m_ref)
    _close(c, c_ref)
    _close(model.mass_matrix(q), m_ref)
    _close(model.bias(q, v), c_ref)
    for centre, jac in zip(model.drone_centres, np.moveaxis(centres, -3, 0), strict=True):
        _close(jac, centre.jacobian(q))
    # one sample without a batch axis
    _close(model.mass_matrix(q[0]), m_ref[0])
    _close(model.bias(q[0], v[0]), c_ref[0])


@pytest.mark.parametrize("order", [4, 6])
def test_inverse_dynamics_jet_hinges_equal_the_per_body_jets(robot, order):
    rng = np.random.default_rng(12)
    point = robot.planar("point")
    motion = rng.uniform(-0.5, 0.5, (order + 1, 30, point.n))
    s = Jet(motion.astype(complex) + 1j * 1e-30 * rng.standard_normal(motion.shape))
    k = order - 2
    ref = None
    g = np.array([0.0, -point.gravity])
    for b in point.bodies:  # the per-body jet formulation (before the stacked model)
        position, jac = b.com.position_and_jacobian_jet(Jet(s.d.copy()), k)
        term = jets.matmul(jac.mT, (position.derivative().derivative() - g)[..., None])[..., 0] * b.mass
        if b.inertia != 0:
            qdd = s.d[2:] @ b.angle_row
            term = term + Jet(np.multiply.outer(qdd, b.angle_row)) * b.inertia
        ref = term if ref is None else ref + term
    new = point.inverse_dynamics_jet(s)
    assert new.order == k
    _close(new.d, ref.d)
    fresh = Jet(s.d.copy())
    _close(point.hinge_jacobian_jet(s).d, jets.concatenate([h.jacobian_jet(fresh) for h in point.hinges], -2).d)
    _close(point.hinge_positions_jet(s.truncate(2)).d,
           jets.stack([h.position_jet(Jet(s.d[:3].copy())) for h in point.hinges], axis=-2).d)


def test_roll_torques_partition_equals_the_full_formula(robot):
    """tau = (S M^-1 S^T)^-1 (phi'' - S M^-1 g) as written (the general branch) and by the chain/roll partition."""
    rng = np.random.default_rng(13)
    rigid = robot.planar("rigid")
    q, v = _complex_step(rng, (25, rigid.n)), _complex_step(rng, (25, rigid.n))
    thrust = 10.0 + _complex_step(rng, (25, robot.n_drones))
    acc = _complex_step(rng, (25, robot.n_drones))
    tau = roll_torques(robot, q, v, thrust, acc)
    m, c, centres = rigid.dynamics_and_centre_jacobians(q, v)
    sel = np.array(rigid.drone_angles)
    gen = -c
    for i, jac in enumerate(np.moveaxis(centres, -3, 0)):
        sin, cos = jets.sin_cos_value(q @ sel[i])
        gen = gen + np.einsum("...in,...i->...n", jac, np.stack([-sin, cos], -1)) * thrust[..., i:i + 1]
    minv = np.linalg.inv(m)
    a_tau = sel @ minv @ sel.T
    full = np.linalg.solve(a_tau, (acc - np.einsum("ij,...jk,...k->...i", sel, minv, gen))[..., None])[..., 0]
    _close(tau, full)
    # the rolls first (a partition by index arrays, not slices): the same torques
    perm = np.concatenate([np.flatnonzero(sel.any(0)), np.flatnonzero(~sel.any(0))])
    _close(_roll_rows(m[..., perm[:, None], perm], gen[..., perm], sel[:, perm], acc), tau)
    # a selection the partition does not recognise (S' = 2 S) takes the formula as written
    scaled = _roll_rows(m, gen, 2.0 * sel, 2.0 * acc)  # S' = 2 S: tau' = tau / 2 for phi'' = S' a
    _close(2.0 * scaled, tau)


def test_sparse_linear_map_is_the_dense_product():
    rng = np.random.default_rng(14)
    k = rng.standard_normal((7, 5))
    k[[1, 4]] = 0.0
    k[:, 2] = 0.0
    k0 = rng.standard_normal(5)
    lin = _Linear(k, k0)
    x = _complex_step(rng, (9, 3, 7))
    _close(lin(x), x @ k + k0)
    jet = Jet(_complex_step(rng, (3, 9, 7)))
    ref = jet.d @ k
    ref[0] += k0
    _close(lin(jet).d, ref)


def test_features_of_a_motion_are_cached_for_its_truncations(robot):
    """The hinges' Jacobian after the inverse dynamics reuses the motion's features (truncated): same bits as
    from a fresh Jet, and a fresh Jet does not see the cache.
    """
    rng = np.random.default_rng(15)
    point = robot.planar("point")
    s = Jet(_complex_step(rng, (5, 20, point.n), scale=0.5))
    points = point.stacked.points
    full = points.features_jet(s)
    assert points.features_jet(s.truncate(2)).d.tobytes() == full.d[:3].tobytes()
    fresh = Jet(s.d[:3].copy())
    assert not fresh.shared_cache()
    assert point.hinge_jacobian_jet(s.truncate(2)).d.tobytes() == point.hinge_jacobian_jet(fresh).d.tobytes()
