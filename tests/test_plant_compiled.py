"""The compiled plant step (fpr/model/_multibody.c) against Pinocchio and against the Python steps, its reference.

Its parts are checked one by one against Pinocchio's own algorithms (CRBA, RNEA, constraintDynamics, integrate,
dIntegrate), and whole runs against ``Plant.compiled_step = False``, which steps on Pinocchio's
``constraintDynamics``.
"""

import types

import numpy as np
import pinocchio as pin
import pytest

import fpr
from fpr.model.constrained import build_closed_chain
from fpr.model.errors import ModelArgumentError
from fpr.sim.plant import Plant, PlantDivergedError, hover_configuration, hover_speeds
from fpr.model.multibody import kernel, model_constants, plant_constants

pytestmark = pytest.mark.skipif(kernel is None, reason="fpr.model._multibody is not built (no C compiler)")

ROBOTS = ("fpr", "prototype")
DT = 1e-3


def closed_state(name, seed, spread=0.05):
    """A robot's closed chain (as the plant builds it) and a state on the closure near its reference pose:
    a random minimal-coordinate state mapped to the closed chain (a consistent q, v)."""
    robot = fpr.load(name)
    rng = np.random.default_rng(seed)
    q = hover_configuration(robot, robot.kind.reference_chain) + spread * rng.normal(size=robot.nq)
    v = rng.normal(size=robot.nq)
    plant = Plant.from_minimal(robot, q, v)
    return plant.closed, plant.qc, plant.vc, rng


@pytest.mark.parametrize("name", ROBOTS)
def test_mass_matrix_and_bias_forces_are_pinocchio_s(name):
    """M (CRBA) and nle (RNEA with gravity) of the C code against Pinocchio's at random configurations, also far
    off the closure (these do not need it)."""
    closed, qc, _, rng = closed_state(name, 1)
    model, data = closed.model, closed.data
    constants = plant_constants(closed)
    for _ in range(5):
        q = pin.integrate(model, qc, rng.normal(size=model.nv))
        v = 3.0 * rng.normal(size=model.nv)
        mass, nle = kernel.rigid_terms(constants, q, v)
        reference = pin.crba(model, data, q)
        reference = np.triu(reference) + np.triu(reference, 1).T
        np.testing.assert_allclose(mass, reference, rtol=0, atol=1e-14 * np.abs(reference).max())
        np.testing.assert_allclose(nle, pin.nonLinearEffects(model, data, q, v), rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", ROBOTS)
def test_constrained_acceleration_is_pinocchio_s(name):
    """The acceleration under a random generalised force, on states that hold the closure: equal to
    constraintDynamics' (proximal, Baumgarte) to 1e-11 of its size."""
    for seed in range(4):
        closed, qc, vc, rng = closed_state(name, 10 + seed)
        model = closed.model
        tau = 5.0 * rng.normal(size=model.nv)
        reference = pin.constraintDynamics(model, closed.data, qc, vc, tau, closed.constraints,
                                           closed.constraint_datas, closed.settings).copy()
        a = kernel.dynamics(plant_constants(closed), qc, vc, tau)
        np.testing.assert_allclose(a, reference, rtol=0, atol=1e-11 * np.abs(reference).max())


def _right_jacobian(twist):
    """SE(3)'s right Jacobian of exp at a twist [linear, angular], sum_k (-ad)^k / (k+1)! to 30 terms."""
    def skew(a):
        return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    ad = np.zeros((6, 6))
    ad[:3, :3] = ad[3:, 3:] = skew(twist[3:])
    ad[:3, 3:] = skew(twist[:3])
    term, total = np.eye(6), np.eye(6)
    for k in range(1, 30):
        term = -term @ ad / (k + 1)
        total += term
    return total


@pytest.mark.parametrize("name", ROBOTS)
def test_group_exponential_and_its_inverse_differential(name):
    """q (+) theta equals pin.integrate; dexp^-1_theta(v) equals the inverse of SE(3)'s right Jacobian summed
    as a matrix series on each free flyer (identity on the revolute joints) to 1e-14, for rotations up to the
    series' limit; beyond it the C code declines (None).

    Pinocchio's dIntegrate (the Python steps' route) agrees only to 1e-8: its closed form loses digits near
    1e-3 rad (measured against the same series: 6e-9 at 3e-4 rad, 1e-14 at 0.1 rad)."""
    closed, qc, _, rng = closed_state(name, 2)
    model = closed.model
    constants = plant_constants(closed)
    flyers = [model.joints[j].idx_v for j in closed.freeflyer_ids]
    for size in (1e-6, 3e-4, 1e-3, 0.05, 0.45):
        theta = rng.normal(size=model.nv)
        theta *= size / np.linalg.norm(theta)
        v = rng.normal(size=model.nv)
        np.testing.assert_allclose(kernel.integrate(constants, qc, theta), pin.integrate(model, qc, theta),
                                   rtol=0, atol=1e-15)
        expected = v.copy()
        for iv in flyers:
            expected[iv:iv + 6] = np.linalg.solve(_right_jacobian(theta[iv:iv + 6]), v[iv:iv + 6])
        x = kernel.dexp_inverse(constants, theta, v)
        np.testing.assert_allclose(x, expected, rtol=0, atol=1e-14)
        jacobian = pin.dIntegrate(model, qc, theta, pin.ArgumentPosition.ARG1)
        np.testing.assert_allclose(x, np.linalg.solve(jacobian, v), rtol=0, atol=1e-8)
    theta = np.zeros(model.nv)
    theta[flyers[0] + 3] = 0.6
    assert kernel.dexp_inverse(constants, theta, v) is None


def _run(robot, q, w, compiled, ticks, steps_per_tick=2, v=None):
    plant = Plant.from_minimal(robot, q, v, w=w)
    plant.compiled_step = compiled
    phases = np.arange(w.size).reshape(w.shape)
    for k in range(ticks):
        plant.advance(w * (1.0 + 0.03 * np.sin(0.02 * k + phases)), DT, steps_per_tick)
    return plant


@pytest.mark.parametrize("name", ROBOTS)
def test_compiled_steps_follow_the_python_steps(name):
    """1 s of varying rotor commands: the compiled steps and the Python steps (on Pinocchio's
    constraintDynamics) end at the same state to 1e-10 and the same clock; the robot moved."""
    robot = fpr.load(name)
    q = hover_configuration(robot, robot.kind.reference_chain)
    w = hover_speeds(robot, q)
    python, compiled = (_run(robot, q, w, flag, 500) for flag in (False, True))
    assert compiled.time == python.time
    np.testing.assert_allclose(compiled.qc, python.qc, rtol=0, atol=1e-10)
    np.testing.assert_allclose(compiled.vc, python.vc, rtol=0, atol=1e-9)
    np.testing.assert_allclose(compiled.rotor_speeds, python.rotor_speeds, rtol=1e-12)
    assert np.abs(python.vc).max() > 0.1


def test_a_fast_turn_is_stepped_in_python():
    """A drone spinning at 1500 rad/s turns by more than the C series covers in half a step: that step runs in
    Python, and the result equals the Python steps'."""
    robot = fpr.load("fpr")
    q = hover_configuration(robot, robot.kind.reference_chain)
    v = np.zeros(robot.nq)
    v[robot.index["psi"]] = 1500.0
    w = hover_speeds(robot, q)
    plants = [Plant.from_minimal(robot, q, v, w=w) for _ in range(2)]
    plants[0].compiled_step, plants[1].compiled_step = False, True
    constants = plant_constants(plants[1].closed)
    theta = 0.5 * DT * plants[1].vc
    assert kernel.dexp_inverse(constants, theta, plants[1].vc) is None  # the C series declines this state
    for plant in plants:
        plant.advance(w, DT, 1)
    np.testing.assert_array_equal(plants[1].qc, plants[0].qc)
    np.testing.assert_array_equal(plants[1].vc, plants[0].vc)


def test_a_non_finite_state_stops_the_compiled_steps_at_the_last_finite_one():
    robot = fpr.load("fpr")
    q = hover_configuration(robot, robot.kind.reference_chain)
    w = hover_speeds(robot, q)
    plant = Plant.from_minimal(robot, q, w=w)
    plant.compiled_step = True
    plant.advance(w, DT, 3)
    plant.vc = plant.vc.copy()
    plant.vc[0] = np.nan
    before = plant.qc.copy()
    with pytest.raises(PlantDivergedError) as error:
        plant.advance(w, DT, 5)
    assert error.value.time == pytest.approx(3 * DT)
    np.testing.assert_array_equal(plant.qc, before)


def test_the_switch():
    robot = fpr.load("prototype")
    q = hover_configuration(robot, robot.kind.reference_chain)
    plant = Plant.from_minimal(robot, q)
    plant.compiled_step = "yes"
    with pytest.raises(ModelArgumentError, match="compiled_step"):
        plant.advance(np.zeros((1, 4)), DT, 1)
    # a model the C code does not know (a spherical joint): no constants; True then says so
    model = pin.Model()
    model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    fake = types.SimpleNamespace(model=model, constraints=[], settings=pin.ProximalSettings(1e-12, 1e-9, 3))
    assert plant_constants(fake) is None
    plant.compiled_step = True
    plant._plant_constants = None  # as _export leaves it for such a model
    with pytest.raises(RuntimeError, match="plant step"):
        plant.advance(np.zeros((1, 4)), DT, 1)


def test_constants_refuse_what_the_c_code_does_not_know():
    closed = build_closed_chain(fpr.load("fpr"), max_iter=3)
    good = plant_constants(closed)
    assert good is not None and good.dtype == float and good.flags.c_contiguous
    with pytest.raises(ValueError, match="constants"):
        kernel.dynamics(good[:-1], pin.neutral(closed.model),
                        np.zeros(closed.model.nv), np.zeros(closed.model.nv))


@pytest.mark.parametrize("settings", [{"mu": 0.0}, {"max_iter": 0}])
def test_proximal_settings_the_c_code_does_not_take_run_the_python_steps(settings):
    """A closed chain built with mu = 0 or max_iter = 0 (Pinocchio takes both): no constants, so the default
    plant runs its Python steps (not a ValueError from the C code's checks at every step)."""
    robot = fpr.load("prototype")
    q = hover_configuration(robot, robot.kind.reference_chain)
    w = hover_speeds(robot, q)
    closed = build_closed_chain(robot, **settings)
    assert plant_constants(closed) is None
    plants = [Plant(closed, Plant.from_minimal(robot, q).qc, w=w) for _ in range(2)]
    plants[1].compiled_step = False
    for plant in plants:
        plant.advance(w, DT, 3)
    np.testing.assert_array_equal(plants[0].qc, plants[1].qc)

@pytest.mark.parametrize("name", ROBOTS)
def test_observed_positions_and_closure_error_are_the_python_ones(name):
    """observe() with the compiled plant: the drones' centres and the closure error equal the Python path's (one
    Pinocchio kinematics pass) to 1e-15 m, on a plant that flew 0.2 s (a closure error of its own)."""
    robot = fpr.load(name)
    q = hover_configuration(robot, robot.kind.reference_chain)
    w = hover_speeds(robot, q)
    plant = _run(robot, q, w, True, 100)
    _, _, positions, closure = plant.observe()
    plant.compiled_step = False
    _, _, reference_positions, reference_closure = plant.observe()
    np.testing.assert_allclose(positions, reference_positions, rtol=0, atol=1e-15)
    assert abs(closure - reference_closure) < 1e-15
    assert 0 < reference_closure < 1e-6


@pytest.mark.parametrize("name", ROBOTS)
def test_a_nan_configuration_has_a_nan_closure_error_on_every_path(name):
    """A NaN in the closed chain's configuration: the closure error is NaN from the compiled points() and from
    both Python paths (closure_error, drone_positions_and_closure_error), not 0.0 (max(0.0, nan))."""
    robot = fpr.load(name)
    plant = Plant.from_minimal(robot, hover_configuration(robot, robot.kind.reference_chain))
    plant._export()
    plant.qc = plant.qc.copy()
    plant.qc[:] = np.nan
    assert np.isnan(kernel.points(plant._plant_constants, plant.qc, plant._point_spec)[1])
    assert np.isnan(plant.closure_error())
    assert np.isnan(plant.drone_positions_and_closure_error()[1])


@pytest.mark.parametrize("name", ROBOTS)
def test_minimal_model_terms_are_pinocchio_s(name):
    """The minimal model exported (the FPR's root a composite of 3 prismatic and 3 revolute joints, split into
    massless parts): M and nle equal Pinocchio's CRBA and RNEA."""
    robot = fpr.load(name)
    constants, ids = model_constants(robot.model)
    rng = np.random.default_rng(5)
    for _ in range(3):
        q = rng.normal(size=robot.model.nq)
        v = rng.normal(size=robot.model.nv)
        mass, nle = kernel.rigid_terms(constants, q, v)
        reference = pin.crba(robot.model, robot.data, q)
        reference = np.triu(reference) + np.triu(reference, 1).T
        np.testing.assert_allclose(mass, reference, rtol=0, atol=1e-14 * np.abs(reference).max())
        np.testing.assert_allclose(nle, pin.nonLinearEffects(robot.model, robot.data, q, v), rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", ROBOTS)
def test_measured_velocity_is_the_python_one(name):
    """to_minimal's velocity by the compiled least squares equals the Python path's (LAPACK's posv on K built
    from Pinocchio's Jacobians) to 1e-12, at states on and off the closure; the configuration is the same."""
    closed, qc, vc, rng = closed_state(name, 7)
    for k in range(3):
        v_closed = vc if k == 0 else vc + 0.01 * rng.normal(size=vc.size)  # off the closure: least squares
        q, v = closed.to_minimal(qc, v_closed)
        closed.compiled_velocity = False
        try:
            q_reference, v_reference = closed.to_minimal(qc, v_closed)
        finally:
            closed.compiled_velocity = None
        np.testing.assert_array_equal(q, q_reference)
        np.testing.assert_allclose(v, v_reference, rtol=0, atol=1e-12 * np.abs(v_reference).max())
    closed.compiled_velocity = 2
    with pytest.raises(ModelArgumentError, match="compiled_velocity"):
        closed.to_minimal(qc, vc)


@pytest.mark.parametrize("name", ROBOTS)
def test_attitude_model_from_the_compiled_terms_is_pinocchio_s(name):
    """Robot.attitude_model with the compiled terms (M_p, nle and the drones' LOCAL frame Jacobians from
    fpr/model/_multibody.c) equals the model from Pinocchio's pass, field by field, to 1e-12 of each field."""
    robot = fpr.load(name)
    rng = np.random.default_rng(11)
    q = hover_configuration(robot, robot.kind.reference_chain) + 0.1 * rng.normal(size=robot.nq)
    v = rng.normal(size=robot.nq)
    compiled = robot.attitude_model(q, v)
    assert robot.__dict__.get("_attitude_terms") is not None
    terms = robot.__dict__.pop("_attitude_terms")
    robot.__dict__["_attitude_terms"] = None  # the Pinocchio pass, the same C post-processing
    try:
        reference = robot.attitude_model(q, v)
    finally:
        robot.__dict__["_attitude_terms"] = terms
    for field in compiled.__dict__:
        a, b = np.asarray(getattr(compiled, field)), np.asarray(getattr(reference, field))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * max(1.0, np.abs(b).max()), err_msg=field)


@pytest.mark.parametrize("name", ROBOTS)
def test_compiled_steps_in_a_wind_follow_the_python_steps(name):
    """0.5 s in a wind (a different force on each drone): the compiled steps, which add each drone centre's
    J^T F at every stage, and the Python step on Pinocchio's frame Jacobians end 1e-10 apart; the wind moved
    the robot (against the same run without it)."""
    robot = fpr.load(name)
    q = hover_configuration(robot, robot.kind.reference_chain)
    w = hover_speeds(robot, q)
    wind = np.array([[0.8, -1.5, 0.4], [-0.6, 1.1, 0.2]])[:robot.n_drones]
    ends = {}
    for compiled, force in ((False, wind), (True, wind), (True, None)):
        plant = Plant.from_minimal(robot, q, w=w)
        plant.compiled_step = compiled
        for _ in range(250):
            plant.advance(w, DT, 2, wind=force)
        ends[compiled, force is None] = plant
    python, compiled, calm = ends[False, False], ends[True, False], ends[True, True]
    assert compiled.time == python.time
    np.testing.assert_allclose(compiled.qc, python.qc, rtol=0, atol=1e-10)
    np.testing.assert_allclose(compiled.vc, python.vc, rtol=0, atol=1e-9)
    assert np.abs(compiled.qc - calm.qc).max() > 1e-3


def _hand_built_model(inner=None):
    """A model of every joint the C code knows, in depth-first order (Pinocchio's CRBA needs it): RZ on the
    universe, PX on it, a composite (RX, RY) on that (``inner``: the RY's placement inside it), RY on the
    composite, a free flyer on the universe and PZ on it; random placements, inertias and armature."""
    rng = np.random.default_rng(3)
    pin.seed(3)  # pin.Inertia.Random, pin.SE3.Random
    model = pin.Model()
    parent = 0
    for kind, on_universe in ((pin.JointModelRZ(), True), (pin.JointModelPX(), False), ("composite", False),
                              (pin.JointModelRY(), False), (pin.JointModelFreeFlyer(), True),
                              (pin.JointModelPZ(), False)):
        if kind == "composite":
            kind = pin.JointModelComposite()
            kind.addJoint(pin.JointModelRX())
            kind.addJoint(pin.JointModelRY(), pin.SE3.Identity() if inner is None else inner)
        placement = pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3))
        parent = model.addJoint(0 if on_universe else parent, kind, placement, f"j{model.njoints}")
        model.appendBodyToJoint(parent, pin.Inertia.Random(), pin.SE3.Identity())
    model.armature = 0.1 * np.abs(rng.normal(size=model.nv))
    return model, rng


def test_a_hand_built_model_and_its_closures_are_pinocchio_s():
    """Joints on the universe and on other joints, prismatic joints, a composite, a free flyer: M, nle and
    the group's exponential equal Pinocchio's; 3D closures with joint1 the universe (as the prototype's),
    joint2 the universe, both on bodies, and two at once: the constrained acceleration equals
    constraintDynamics' at random states off the closures. A composite with a non-identity inner placement
    is refused."""
    model, rng = _hand_built_model()
    assert model_constants(_hand_built_model(pin.SE3.Random())[0]) is None
    data = model.createData()
    settings = pin.ProximalSettings(1e-12, 1e-12, 1e-9, 200)

    def closure(j1, j2):
        p1, p2 = (pin.SE3(np.eye(3), rng.normal(size=3)) for _ in range(2))
        cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, j1, p1, j2, p2,
                                      pin.ReferenceFrame.LOCAL)
        cm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(10.0, 3.0))
        return cm

    for pairs in ((), ((0, 4),), ((6, 0),), ((4, 6),), ((4, 6), (0, 6))):
        constraints = pin.StdVec_RigidConstraintModel()
        datas = pin.StdVec_RigidConstraintData()
        for j1, j2 in pairs:
            constraints.append(closure(j1, j2))
            datas.append(constraints[-1].createData())
        constants, _ = model_constants(model, constraints, settings)
        q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
        v, tau, theta = rng.normal(size=model.nv), rng.normal(size=model.nv), 0.1 * rng.normal(size=model.nv)
        mass, nle = kernel.rigid_terms(constants, q, v)
        reference = pin.crba(model, data, q)
        reference = np.triu(reference) + np.triu(reference, 1).T
        np.testing.assert_allclose(mass, reference, rtol=0, atol=1e-14 * np.abs(reference).max())
        reference = pin.nonLinearEffects(model, data, q, v)
        np.testing.assert_allclose(nle, reference, rtol=0, atol=1e-14 * np.abs(reference).max())
        reference = pin.integrate(model, q, theta)
        np.testing.assert_allclose(kernel.integrate(constants, q, theta), reference, rtol=0, atol=1e-15)
        if pairs:
            pin.initConstraintDynamics(model, data, constraints, datas)
            reference = pin.constraintDynamics(model, data, q, v, tau, constraints, datas, settings)
        else:
            reference = pin.aba(model, data, q, v, tau)
        np.testing.assert_allclose(kernel.dynamics(constants, q, v, tau), reference, rtol=0,
                                   atol=1e-12 * np.abs(reference).max())
