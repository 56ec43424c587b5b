"""The jets model of a spatial chain (fpr.model.spatial) against Pinocchio and finite differences.

* order 0: b = M q'' + c equals ``pin.rnea`` and the tips' Jacobian equals Pinocchio's frame Jacobians (world axes)
  at random states, on the spatial FPR's point-drone chain (urdf/fpr3.urdf, its Z-Y-X composite root), on the
  planar FPR's model (its rigid drones on hinges: the model is dimension independent) and on a random tree of
  unaligned revolute, prismatic and composite joints; F = J^-T b equals Pinocchio's;
* orders 1 and 2: F', F'' (and the planar FPR's and the tree's b', b'') equal central differences of the order-0
  values along a smooth random motion, within the differences' own error (truncation from the jet's higher
  derivatives, rounding from the values' size), not a fitted constant. Pinocchio's RNEA derivatives are no
  reference here: pin 4.1's are wrong on a composite joint with two or more rotations (the root);
* complex step and dual numbers through the model give the same directional derivative of F, F', F'' as central
  differences.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import fpr
from fpr.model import description
from fpr.model.dual import Dual
from fpr.model.errors import ModelArgumentError, RobotDefinitionError
from fpr.model.jets import Jet
from fpr.model.robot import euler_root_joint
from fpr.model.spatial import SpatialChain

LEGS = (1, 2, 3)
TIPS = tuple(f"leg_{i}_tip" for i in LEGS)
SEED = 2031
EPS = np.finfo(float).eps


def _fpr3_point_model() -> pin.Model:
    """The spatial FPR's planning chain from urdf/fpr3.urdf: the Z-Y-X root, the legs, each drone a point mass
    at its ball (the ball joints locked, their rings and the drone's mass on the leg).
    """
    text = description.single_angle_urdf(description.urdf_path("fpr3").read_text(encoding="utf-8"))
    model = pin.buildModelFromXML(text, euler_root_joint())
    balls = []
    for i in LEGS:
        hinge = model.getJointId(f"drone_{i}_hinge")
        model.inertias[hinge] = pin.Inertia(model.inertias[hinge].mass, np.zeros(3), np.zeros((3, 3)))
        balls += [model.getJointId(f"drone_{i}_{n}") for n in ("ball_pitch", "ball_yaw", "hinge")]
    return pin.buildReducedModel(model, balls, pin.neutral(model))


def _random_tree() -> pin.Model:
    """A branching tree of unaligned revolute, prismatic and composite joints, random placements and inertias."""
    rng = np.random.default_rng(SEED)
    model = pin.Model()
    def composite(axis):  # a rotation about ``axis`` then, placed elsewhere, a slide along z and a turn about y
        joint = pin.JointModelComposite(pin.JointModelRevoluteUnaligned(axis))
        joint.addJoint(pin.JointModelPZ(), pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3)))
        joint.addJoint(pin.JointModelRY(), pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3)))
        return joint

    kinds = [lambda a: pin.JointModelRevoluteUnaligned(a), lambda a: pin.JointModelPrismaticUnaligned(a),
             lambda a: pin.JointModelPY(), composite]
    parents = [0, 1, 2, 2, 1, 5]
    for k, parent in enumerate(parents):
        axis = rng.normal(size=3)
        placement = pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3))
        jid = model.addJoint(parent, kinds[k % 4](axis / np.linalg.norm(axis)), placement, f"j{k}")
        a = rng.normal(size=(3, 3))
        model.appendBodyToJoint(jid, pin.Inertia(rng.uniform(0.5, 2), rng.normal(size=3), a @ a.T + np.eye(3)),
                                pin.SE3.Identity())
        model.addFrame(pin.Frame(f"tip{k}", jid, 0, pin.SE3(np.eye(3), rng.normal(size=3)), pin.FrameType.OP_FRAME))
    return model


def _frame_jacobian(model, data, q, tips) -> np.ndarray:
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    return np.vstack([pin.getFrameJacobian(model, data, model.getFrameId(t), pin.LOCAL_WORLD_ALIGNED)[:3]
                      for t in tips])


def _cases():
    planar = fpr.load("fpr").model
    return {"fpr3": (_fpr3_point_model(), TIPS),
            "fpr": (planar, ("drone_1_hinge", "drone_2_hinge")),
            "tree": (_random_tree(), ("tip2", "tip3", "tip5"))}


CASES = _cases()


def _motion(nv, times, order, seed=SEED, centre=None):
    """A smooth random motion q(t) = q0 + sum_k A_k sin(w_k t + p_k) and its derivatives 0..order at ``times``:
    an array (order + 1, len(times), nv) (derivatives exact, in closed form).
    """
    rng = np.random.default_rng(seed)
    q0 = rng.normal(scale=0.3, size=nv) if centre is None else centre
    amp, freq, phase = rng.normal(scale=0.2, size=(3, nv)), rng.uniform(0.5, 2.0, (3, nv)), rng.uniform(0, 6, (3, nv))
    t = np.asarray(times, float)[:, None, None]
    out = np.zeros((order + 1, t.shape[0], nv))
    for r in range(order + 1):
        out[r] = (amp * freq**r * np.sin(freq * t + phase + r * np.pi / 2)).sum(axis=1)
    out[0] += q0
    return out


def _fpr3_centre():
    """The spatial FPR near its take-off pose (legs at 45 degrees: J far from its singular sets)."""
    return np.array([0.0, 0.0, 0.74, 0.2, 0.1, -0.1, 0.8, 0.7, 0.9])


@pytest.mark.parametrize("case", sorted(CASES))
def test_order_zero_equals_pinocchio(case):
    """b = pin.rnea and J = Pinocchio's frame Jacobians at random states, to 1e-12 relative."""
    model, tips = CASES[case]
    chain = SpatialChain(model, tips)
    data = model.createData()
    rng = np.random.default_rng(SEED)
    states = rng.normal(size=(3, 8, model.nv))
    out = chain.evaluate(Jet(states), forces=False)
    assert out.b.order == 0 and out.b.shape == (8, model.nv)
    for n in range(8):
        q, v, a = states[:, n]
        b = pin.rnea(model, data, q, v, a)
        jac = _frame_jacobian(model, data, q, tips)
        assert np.abs(out.b.value[n] - b).max() <= 1e-12 * np.abs(b).max()
        assert np.abs(out.jacobian.value[n] - jac).max() <= 1e-12 * np.abs(jac).max()
        assert np.allclose(chain.tip_jacobian(q), jac, rtol=0, atol=1e-12 * np.abs(jac).max())


def test_fpr3_thrusts_equal_pinocchio_and_hold_the_weight():
    """F = J^-T b equals Pinocchio's solve; at rest the forces' sum is the robot's weight."""
    model, tips = CASES["fpr3"]
    chain, data = SpatialChain(model, tips), model.createData()
    d = _motion(model.nv, np.linspace(0, 3, 7), 2, centre=_fpr3_centre())
    forces = chain.thrusts(Jet(d))
    assert forces.shape == (7, 3, 3) and forces.order == 0
    for n in range(7):
        q, v, a = d[:, n]
        ref = np.linalg.solve(_frame_jacobian(model, data, q, tips).T, pin.rnea(model, data, q, v, a))
        assert np.abs(forces.value[n].ravel() - ref).max() <= 1e-12 * np.linalg.cond(
            _frame_jacobian(model, data, q, tips)) * np.abs(ref).max()
    rest = d.copy()
    rest[1:] = 0.0
    weight = sum(i.mass for i in model.inertias) * 9.81
    total = chain.thrusts(Jet(rest)).value.sum(axis=1)
    assert np.allclose(total[:, :2], 0.0, atol=1e-10) and np.allclose(total[:, 2], weight, rtol=1e-3)


def _central_differences(evaluate, d6, times, h):
    """Central first and second differences in time of ``evaluate`` (a motion of order 2 -> its order-0 value)."""
    plus, minus = (evaluate(_motion_at(d6, times, s)) for s in (h, -h))
    mid = evaluate(_motion_at(d6, times, 0.0))
    return (plus - minus) / (2 * h), (plus - 2 * mid + minus) / h**2


def _motion_at(motion, times, shift):
    return motion(np.asarray(times) + shift, 2)


@pytest.mark.parametrize("case", ["fpr3", "fpr", "tree"])
def test_orders_one_and_two_equal_central_differences(case):
    """F' and F'' (fpr3) or b' and b'' (the planar FPR, the random tree) against central differences with h = 1e-4.

    The differences' error bound, from the jets' own higher orders (taken to order 4) and the values' rounding:
    (x(t+h) - x(t-h)) / 2h = x' + h^2/6 x''' + O(h^4), rounding <= 2 delta / (2h); (x(t+h) - 2x + x(t-h)) / h^2 =
    x'' + h^2/12 x'''' + O(h^4), rounding <= 4 delta / h^2, with delta = 16 eps max|x| the values' rounding (a
    few eps of their scale: the order-0 values agree with Pinocchio to about one eps relative). The bounds are
    doubled for the higher derivatives' change over [t-h, t+h]. With h = 1e-4 they come to about 1e-7 (first)
    and 1e-5 to 1e-4 (second, rounding-dominated) of values of size 10 to 100.
    """
    model, tips = CASES[case]
    chain = SpatialChain(model, tips)
    times, h = np.linspace(0.1, 2.9, 15), 1e-4
    centre = _fpr3_centre() if case == "fpr3" else None
    motion = lambda t, order: _motion(model.nv, t, order, centre=centre)  # noqa: E731
    if case == "fpr3":
        value = lambda d: chain.thrusts(Jet(d)).value  # noqa: E731
        jet = chain.thrusts(Jet(motion(times, 6))).d
    else:
        value = lambda d: chain.generalized_forces(Jet(d)).value  # noqa: E731
        jet = chain.generalized_forces(Jet(motion(times, 6))).d
    first, second = _central_differences(value, motion, times, h)
    scale = np.abs(jet[0]).max()
    delta = 16 * EPS * scale
    bound1 = 2 * (h**2 / 6 * np.abs(jet[3]).max() + delta / h)
    bound2 = 2 * (h**2 / 12 * np.abs(jet[4]).max() + 4 * delta / h**2)
    err1, err2 = np.abs(jet[1] - first).max(), np.abs(jet[2] - second).max()
    assert err1 <= bound1 and err2 <= bound2, (err1, bound1, err2, bound2)
    assert bound1 < 1e-5 * np.abs(jet[1]).max() and bound2 < 1e-3 * np.abs(jet[2]).max()  # the check has teeth


def test_complex_step_and_dual_numbers_give_the_directional_derivative():
    """d/de of F, F', F'' along a perturbation e dq(t) of the motion: complex step, dual numbers and central
    differences in e agree (the first two to round-off, the last within its truncation and rounding).
    """
    model, tips = CASES["fpr3"]
    chain = SpatialChain(model, tips)
    times = np.linspace(0.2, 2.8, 6)
    d = _motion(model.nv, times, 4, centre=_fpr3_centre())
    dq = _motion(model.nv, times, 4, seed=SEED + 1, centre=np.zeros(model.nv))
    step = 1e-30
    by_complex = chain.thrusts(Jet(d + 1j * step * dq)).d.imag / step
    seeded = Dual(d, dq[None])
    out = chain.thrusts(Jet(seeded)).d
    assert isinstance(out, Dual)
    # the value is the real path's, to round-off (the Python and the native jet products may sum otherwise)
    real = chain.thrusts(Jet(d)).d
    np.testing.assert_allclose(out.value, real, rtol=0, atol=1e-13 * np.abs(real).max())
    by_dual = out.tangents[0]
    e = 1e-6
    by_differences = (chain.thrusts(Jet(d + e * dq)).d - chain.thrusts(Jet(d - e * dq)).d) / (2 * e)
    scale = np.abs(by_complex).max(axis=(1, 2, 3), keepdims=True)
    assert np.all(np.abs(by_complex - by_dual) <= 1e-12 * scale)
    assert np.all(np.abs(by_complex - by_differences) <= 1e-6 * scale)
    assert np.all(scale > 1e-3)  # a direction that changes F, F' and F''


def test_bad_inputs_are_named():
    """A wrong argument is a ModelArgumentError naming it; a joint that is not made of 1-DoF parts is refused."""
    model, tips = CASES["fpr"]
    chain = SpatialChain(model, tips)
    for call, argument in ((lambda: chain.evaluate(Jet(np.zeros((3, 2, model.nv)))), "forces"),
                           (lambda: chain.evaluate(Jet(np.zeros((3, 2, model.nv + 1)))), "q"),
                           (lambda: chain.evaluate(Jet(np.zeros((2, 2, model.nv))), forces=False), "q"),
                           (lambda: SpatialChain(model, ["no_such_frame"]), "tips")):
        with pytest.raises(ModelArgumentError) as error:
            call()
        assert error.value.argument == argument
    spherical = pin.Model()
    spherical.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    with pytest.raises(RobotDefinitionError, match="JointModelSpherical"):
        SpatialChain(spherical, [])
