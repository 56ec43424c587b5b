"""The shortcuts of the complex-step evaluation (the planner's reference derivatives) give the same bits as the
plain code.
"""

import numpy as np
import pytest

from fpr.model import jets
from fpr.model.jets import Jet
from planners.missions.mission import load_mission


@pytest.fixture(scope="module", params=["square", "prototype-tour"])
def robot(request):
    return load_mission(request.param).load_robot()


def _complex_step(rng, shape, scale=3.0):
    return rng.uniform(-scale, scale, shape) + 1j * 1e-30 * rng.standard_normal(shape)


def test_complex_step_sin_cos_is_numpys_bit_for_bit():
    rng = np.random.default_rng(3)
    z = _complex_step(rng, (500, 3), scale=40.0)
    sin, cos = jets.sin_cos_value(z)
    assert sin.tobytes() == np.sin(z).tobytes() and cos.tobytes() == np.cos(z).tobytes()
    # and the complex step it carries is the derivative: Im(sin(x + i h b)) / h = cos(x) b
    np.testing.assert_allclose(sin.imag / 1e-30, np.cos(z.real) * (z.imag / 1e-30), rtol=1e-15)
    real = z.real
    assert all(a.tobytes() == b.tobytes()
               for a, b in zip(jets.sin_cos_value(real), (np.sin(real), np.cos(real)), strict=True))


def test_sincos_of_a_jet_uses_the_shortcut_bit_for_bit():
    rng = np.random.default_rng(4)
    a = Jet(_complex_step(rng, (4, 50)))
    s, c = jets.sincos(a)
    # the plain recurrence with numpy's complex sine and cosine for the values
    d, s0, c0 = a.d, np.empty_like(a.d), np.empty_like(a.d)
    s0[0], c0[0] = np.sin(d[0]), np.cos(d[0])
    for n in range(1, 4):
        w, dn = jets._B[n - 1, :n], d[n:0:-1]
        s0[n], c0[n] = jets._wsum(w, c0[:n] * dn), -jets._wsum(w, s0[:n] * dn)
    assert s.d.tobytes() == s0.tobytes() and c.d.tobytes() == c0.tobytes()


def test_truncations_share_the_cache_and_a_cached_result_serves_lower_orders(robot):
    """A point's position (order 2) after the body Jacobians (order 4) used the cached sin/cos: same bits as
    a fresh computation, and the cache is not shared with an unrelated Jet.
    """
    rng = np.random.default_rng(5)
    n = len(robot.layout.chain)
    motion = rng.uniform(-0.3, 0.3, (5, 40, n))
    point = robot.planar("point")
    s = Jet(motion.astype(complex) + 1j * 1e-30 * rng.standard_normal(motion.shape))
    for body in point.bodies:
        body.com.position_and_jacobian_jet(s, 2)
    assert s.truncate(2).shared_cache() is s.shared_cache() and s.shared_cache()
    assert s.derivative().shared_cache() is not s.shared_cache()
    for hinge in point.hinges:
        cached = hinge.position_jet(s.truncate(2))
        fresh = hinge.position_jet(Jet(s.d[:3].copy()))
        assert cached.d.tobytes() == fresh.d.tobytes()
        assert cached.order == 2


def test_signed_rotor_speeds_carry_a_complex_step_derivative_and_keep_their_real_bits():
    """sign(w^2) sqrt(|w^2|): the same bits as before for real input (both signs and 0), and Im(f(w2 + ih))/h
    equal to the analytic derivative 1 / (2 sqrt(|w^2|)) (numpy's complex sign/abs would lose it).
    """
    from fpr.model.rotors import signed_speeds

    w2 = np.array([-3.0e5, -1.0, 0.0, 2.5e-3, 4.2e5])
    assert signed_speeds(w2).tobytes() == (np.sign(w2) * np.sqrt(np.abs(w2))).tobytes()
    h = 1e-20
    nonzero = w2[w2 != 0.0]
    derivative = signed_speeds(nonzero + 1j * h).imag / h
    np.testing.assert_allclose(derivative, 0.5 / np.sqrt(np.abs(nonzero)), rtol=1e-12)
    assert np.all(derivative > 0)  # w grows with w^2 on both sides of 0
    # the real square roots give numpy's complex ones (sign * sqrt(sign * w2)) to round-off, 0 included
    z = w2 + 1j * h * np.array([2.0, -1.0, 3.0, 0.5, -4.0])
    sign = np.sign(z.real)
    plain = sign * np.sqrt(sign * z)
    np.testing.assert_allclose(signed_speeds(z).real, plain.real, rtol=1e-15, atol=0)
    np.testing.assert_allclose(signed_speeds(z).imag / h, plain.imag / h, rtol=1e-14, atol=0)


